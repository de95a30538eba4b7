//! Multi-user sessions: participants see each other's strokes live, late joiners get the
//! history with no gap and no repeat, a slow reader is cut off with `lagged`, and (with
//! PostgreSQL, `PENMESH_TEST_POSTGRES_URL`) two replicas serve one session, one of them
//! killed mid-stroke. The cross-replica tests need PostgreSQL: without
//! `PENMESH_TEST_POSTGRES_URL` they are marked ignored (`tests/build.rs`), with it they run.
//!
//! `fanout_latency` (ignored) measures the numbers of `docs/performance.md`:
//! `cargo test --release -p penmesh-e2e --test sessions -- --ignored --nocapture fanout_latency`.

mod helpers;
mod history_cost;
mod history_messages;
mod history_pool;
mod late_removals;
mod latency;
mod names;
mod placement;
mod placement_latency;
mod placement_replicas;
mod removal;
mod replicas;
mod sessions;
mod shared_meshes;
mod slow_reader;
mod solids;
mod told;
