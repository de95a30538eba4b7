//! The penmesh simplification proxy.
