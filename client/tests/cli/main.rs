//! End-to-end tests of the `penmesh` binary: the demo, concurrent drawers, a proxy killed in
//! the middle of a stroke, a recorded tablet, and the errors a person sees.
//!
//! The proxy runs as a real process too: `penmesh demo --people 0 --keep-serving` serves a
//! fresh session on an embedded SQLite file, and the tests read that file afterwards.

mod demo;
mod draw;
mod errors;
mod evdev;
mod helpers;
mod resume;
mod watch;
