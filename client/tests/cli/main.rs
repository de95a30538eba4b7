//! End-to-end tests of the `penmesh` binary: concurrent drawers, a proxy killed in the middle
//! of a stroke, a recorded tablet, the watcher, and the errors a person sees.
//!
//! The proxy is the proxy's own `Application` on an embedded SQLite file, in a runtime of its
//! own (`helpers::Proxy`: the server is a dependency of these tests only, not of `penmesh`);
//! the tests read that file afterwards.

mod draw;
mod errors;
mod evdev;
mod export;
mod helpers;
mod mesh;
mod resume;
mod solids;
mod watch;
