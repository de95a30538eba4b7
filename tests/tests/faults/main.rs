//! Fault injection: pens draw through the real protocol into the real proxy binary (a child
//! process) while something fails under it, then the checks of `check.rs`: nothing
//! acknowledged is lost, nothing is stored twice, every stroke is readable and finished, and
//! every pen draws again within the stated deadline. `docs/reliability.md` reports the figures
//! (run with `--nocapture` to see the `FIGURES` lines).
//!
//! - `kill.rs`: the proxy killed with SIGKILL mid-load and restarted (SQLite, and PostgreSQL
//!   when `PENMESH_TEST_POSTGRES_URL` is set);
//! - `reset.rs`, `black_hole.rs`: PostgreSQL's connections reset (one kind at a time, then
//!   all), and PostgreSQL cut off for
//!   longer than any timeout, through the TCP forwarder of `forwarder.rs` (PostgreSQL only:
//!   ignored without the URL, see `tests/build.rs`; with it they run and fail when they must);
//! - `bad_record.rs`: records of the append log that cannot be moved, set aside one by one;
//! - `disk_full.rs`: every file write failing under SQLite (`RLIMIT_FSIZE`), then space back.

mod bad_record;
mod black_hole;
mod check;
mod child;
mod client;
mod costs;
mod disk_full;
mod forwarder;
mod kill;
mod pen;
mod reset;

use std::time::{Duration, Instant};

/// How long after a fault ends every pen must be drawing again.
pub const RECOVERY: Duration = Duration::from_secs(10);

/// The load of every scenario: each pen draws a 150 Hz stroke in batches of 4 (about 8 s of
/// drawing without a fault), long enough to span the fault and the recovery.
pub fn plan() -> pen::Plan {
    pen::Plan {
        strokes: 10,
        samples: 120,
        batch: 4,
        every: Duration::from_millis(25),
        stall: Duration::from_secs(2),
        window: 256,
        give_up: Instant::now() + Duration::from_secs(60),
    }
}

/// Pens per scenario.
pub const PENS: usize = 4;

/// The address of the PostgreSQL server of `url` (`postgres://user@host:port/db`).
pub fn postgres_server(url: &str) -> std::net::SocketAddr {
    use std::net::ToSocketAddrs;
    let rest = &url[url.find("://").expect("a URL") + 3..];
    let authority = &rest[..rest.find(['/', '?']).unwrap_or(rest.len())];
    let host = authority.rsplit('@').next().unwrap();
    let host = if host.contains(':') { host.to_string() } else { format!("{host}:5432") };
    host.to_socket_addrs().expect("the PostgreSQL host resolves").next().unwrap()
}
