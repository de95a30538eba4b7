//! Integration tests of the proxy: one binary, one module per area. Each test starts the real
//! application on port 0 with a fresh database (SQLite, or PostgreSQL when
//! `PENMESH_TEST_POSTGRES_URL` is set).

mod auth;
mod bad_input;
mod bundle;
mod costs;
mod deploy;
mod export;
mod http;
mod identity;
mod limits;
mod model_bounds;
mod model_roundtrip;
mod old_database;
mod postgres;
mod protocol_doc;
mod rates;
mod resume;
mod roundtrip_bytes;
mod shutdown;
mod versions;
mod web;
mod write_failures;
mod ws_binary;
mod ws_json;
