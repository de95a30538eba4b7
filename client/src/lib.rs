//! The penmesh client library.
