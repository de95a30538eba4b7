//! Rate limits, one mechanism ([`Limit`]): a token bucket per key (the `governor` crate),
//! `burst` cells deep, refilled at a rate; a rate of 0 turns a limit off. Past it, HTTP
//! answers 429 `too_many_requests` naming the limit, with `Retry-After`. The limits:
//!
//! - **Session creation** (`POST /v1/sessions`, which needs no token), per client address
//!   ([`SessionLimiter`]): `session_burst`, then `session_rate_per_minute`.
//! - **Moves and solid changes**, per participant ([`Rates::moves`], [`Rates::solids`]): a
//!   stroke placed anew (`set_placement`, `PUT …/placement`; the page sends one per selected
//!   stroke when a drag, a nudge or an undo ends) and a stroke's solid set (`set_solid`, `PUT
//!   …/solid`: a mesh built each). Over the WebSocket the connection waits for its turn
//!   instead (back-pressure, as for batches in flight: it reads nothing meanwhile), so a move
//!   there is paced, never refused nor lost, and the protocol has no new error.
//! - **What a session's duplicates tell its watchers**, per session ([`Rates::duplicated`]):
//!   every watcher is sent a duplicate with its source's retained samples (`peer_retained`),
//!   so a duplicate takes that many cells; the bucket holds what one watcher's event queue
//!   holds (`outgoing_queue_bytes` of samples), refilled at `duplicate_samples_per_second`.
//!   Per session, not per participant: a duplicate's drawer is whatever key its request
//!   names, and a session's watchers receive every participant's duplicates.
//!
//! Each replica keeps its own buckets: N replicas let N times as much through.
//!
//! The client address ([`client_key`], which the per-address WebSocket cap of
//! `max_connections_per_address` counts by too) is the TCP peer's. Behind a reverse proxy or
//! load balancer that is the proxy's, so every client shares one bucket, unless
//! `trust_forwarded_for` is on: then it is the last address of `X-Forwarded-For` (the one the
//! nearest proxy appended: the ones before it are whatever the client wrote), else `X-Real-IP`,
//! else the peer. IPv6 addresses count by their /64, which one client usually holds whole.

use std::hash::Hash;
use std::net::{IpAddr, Ipv6Addr, SocketAddr};
use std::num::NonZeroU32;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use axum::http::HeaderMap;
use governor::clock::{Clock, DefaultClock};
use governor::{DefaultKeyedRateLimiter, Quota};
use penmesh::protocol::ParticipantId;
use uuid::Uuid;

use crate::config::Config;
use crate::http::AppError;

/// How often the buckets that have refilled are forgotten.
const FORGET_EVERY: Duration = Duration::from_secs(60);

/// A token bucket per key, `burst` cells deep (no limit inside when the rate is 0).
#[derive(Debug)]
pub struct Limit<K: Hash + Eq + Clone> {
    limiter: Option<DefaultKeyedRateLimiter<K>>,
    burst: u32,
    /// The limit in words, for a refusal: "200 moves a second per participant after a burst
    /// of 2000 (--move-rate-per-second, --move-burst)".
    says: String,
    last_forget: Mutex<Instant>,
}

impl<K: Hash + Eq + Clone> Limit<K> {
    /// Buckets of `burst` cells (at least one) refilled at `rate` cells every `period`; `says`
    /// what the limit is, in words.
    pub fn new(rate: u32, period: Duration, burst: u32, says: String) -> Limit<K> {
        let burst = NonZeroU32::new(burst).unwrap_or(NonZeroU32::MIN);
        let limiter = NonZeroU32::new(rate).and_then(|rate| {
            let quota = Quota::with_period(period / rate.get())?.allow_burst(burst);
            Some(DefaultKeyedRateLimiter::keyed(quota))
        });
        Limit { limiter, burst: burst.get(), says, last_forget: Mutex::new(Instant::now()) }
    }

    /// Takes `n` cells of `key`'s bucket now (a whole bucket at most: more are never there at
    /// once), else how long until they are there.
    pub fn try_take(&self, key: &K, n: u64) -> Result<(), Duration> {
        let Some(limiter) = &self.limiter else { return Ok(()) };
        self.forget_now_and_then(limiter);
        let n =
            NonZeroU32::new(n.clamp(1, u64::from(self.burst)) as u32).unwrap_or(NonZeroU32::MIN);
        match limiter.check_key_n(key, n) {
            Ok(Ok(())) => Ok(()),
            Ok(Err(not_until)) => Err(not_until.wait_time_from(DefaultClock::default().now())),
            // Only past the bucket's capacity, which `n` is not.
            Err(_) => Err(FORGET_EVERY),
        }
    }

    /// Takes `n` cells of `key`'s bucket now, else 429 naming the limit and when to try again.
    pub fn take(&self, key: &K, n: u64) -> Result<(), AppError> {
        self.try_take(key, n).map_err(|wait| AppError::TooManyRequests {
            wait,
            message: format!(
                "past the limit of {}; try again in {} s",
                self.says,
                retry_after_secs(wait)
            ),
        })
    }

    /// Takes one cell of `key`'s bucket, waiting until there is one.
    pub async fn wait(&self, key: &K) {
        while let Err(wait) = self.try_take(key, 1) {
            tokio::time::sleep(wait).await;
        }
    }

    fn forget_now_and_then(&self, limiter: &DefaultKeyedRateLimiter<K>) {
        let mut last = self.last_forget.lock().expect("limiter lock");
        if last.elapsed() >= FORGET_EVERY {
            *last = Instant::now();
            limiter.retain_recent();
        }
    }
}

/// The seconds of a `Retry-After` for a wait: rounded up, at least 1.
pub fn retry_after_secs(wait: Duration) -> u64 {
    (wait.as_secs_f64().ceil() as u64).max(1)
}

/// The session-creation limit, per client address.
#[derive(Debug)]
pub struct SessionLimiter {
    limit: Limit<IpAddr>,
    trust_forwarded_for: bool,
}

impl SessionLimiter {
    pub fn new(per_minute: u32, burst: u32, trust_forwarded_for: bool) -> SessionLimiter {
        let says = format!(
            "{per_minute} sessions a minute per client address after a burst of {burst} \
             (--session-rate-per-minute, --session-burst)"
        );
        let limit = Limit::new(per_minute, Duration::from_secs(60), burst, says);
        SessionLimiter { limit, trust_forwarded_for }
    }

    /// `Ok` when the client may create a session now, else 429.
    pub fn check(&self, peer: SocketAddr, headers: &HeaderMap) -> Result<(), AppError> {
        self.limit.take(&client_key(peer, headers, self.trust_forwarded_for), 1)
    }
}

/// The limits of a token holder's requests (see the module documentation).
#[derive(Debug)]
pub struct Rates {
    /// Placements, per participant.
    pub moves: Limit<ParticipantId>,
    /// Solid changes, per participant.
    pub solids: Limit<ParticipantId>,
    /// Retained samples of the duplicates told to a session's watchers, per session.
    pub duplicated: Limit<Uuid>,
}

impl Rates {
    pub fn new(config: &Config) -> Rates {
        let second = Duration::from_secs(1);
        let (moves, move_burst) = (config.move_rate_per_second, config.move_burst);
        let (solids, solid_burst) = (config.solid_rate_per_second, config.solid_burst);
        let samples = config.duplicate_samples_per_second;
        // What one watcher's queue of the session's events holds.
        let queue = config.outgoing_queue_bytes / std::mem::size_of::<penmesh::Sample>();
        let queue = u32::try_from(queue).unwrap_or(u32::MAX);
        Rates {
            moves: Limit::new(
                moves,
                second,
                move_burst,
                format!(
                    "{moves} moves a second per participant after a burst of {move_burst} \
                 (--move-rate-per-second, --move-burst)"
                ),
            ),
            solids: Limit::new(
                solids,
                second,
                solid_burst,
                format!(
                    "{solids} solid changes a second per participant after a burst of \
                 {solid_burst} (--solid-rate-per-second, --solid-burst)"
                ),
            ),
            duplicated: Limit::new(
                samples,
                second,
                queue,
                format!(
                    "{samples} retained samples of duplicates a second per session, told to \
                 every watcher, after a burst of {queue} (--duplicate-samples-per-second; the \
                 burst is what a watcher's queue holds, --outgoing-queue-bytes)"
                ),
            ),
        }
    }
}

/// The address a client is counted under (see the module documentation).
pub fn client_key(peer: SocketAddr, headers: &HeaderMap, trust_forwarded_for: bool) -> IpAddr {
    let forwarded = || {
        let last_forwarded = headers
            .get_all("x-forwarded-for")
            .iter()
            .filter_map(|v| v.to_str().ok())
            .flat_map(|v| v.split(','))
            .next_back()
            .and_then(|a| a.trim().parse::<IpAddr>().ok());
        last_forwarded
            .or_else(|| headers.get("x-real-ip")?.to_str().ok()?.trim().parse::<IpAddr>().ok())
    };
    let ip = if trust_forwarded_for { forwarded() } else { None }.unwrap_or(peer.ip());
    match ip {
        IpAddr::V6(v6) if v6.to_ipv4_mapped().is_none() => {
            let prefix = u128::from(v6) & !((1u128 << 64) - 1);
            IpAddr::V6(Ipv6Addr::from(prefix))
        }
        IpAddr::V6(v6) => IpAddr::V4(v6.to_ipv4_mapped().expect("checked")),
        v4 => v4,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_client_address_is_the_peer_unless_forwarded_headers_are_trusted() {
        let peer: SocketAddr = "10.0.0.1:5000".parse().unwrap();
        let mut headers = HeaderMap::new();
        headers.insert("x-forwarded-for", "1.2.3.4, 5.6.7.8".parse().unwrap());
        let ip = |s: &str| s.parse::<IpAddr>().unwrap();
        for (trust, headers, expected) in [
            (false, headers.clone(), ip("10.0.0.1")),
            // The last entry is the one the trusted proxy appended; the first is the client's word.
            (true, headers.clone(), ip("5.6.7.8")),
            (true, HeaderMap::new(), ip("10.0.0.1")),
        ] {
            assert_eq!(client_key(peer, &headers, trust), expected, "trust {trust}");
        }
        let a: SocketAddr = "[2001:db8::1]:1".parse().unwrap();
        let b: SocketAddr = "[2001:db8::ffff:2]:1".parse().unwrap();
        assert_eq!(
            client_key(a, &HeaderMap::new(), false),
            client_key(b, &HeaderMap::new(), false)
        );
    }

    #[test]
    fn a_burst_then_the_rate() {
        let limiter = SessionLimiter::new(60, 3, false);
        let peer: SocketAddr = "10.0.0.1:5000".parse().unwrap();
        let other: SocketAddr = "10.0.0.2:5000".parse().unwrap();
        for _ in 0..3 {
            assert!(limiter.check(peer, &HeaderMap::new()).is_ok());
        }
        match limiter.check(peer, &HeaderMap::new()) {
            Err(AppError::TooManyRequests { wait, message }) => {
                assert!(wait <= Duration::from_secs(1), "{wait:?}");
                assert!(message.contains("--session-rate-per-minute"), "{message}");
            }
            other => panic!("{other:?}"),
        }
        assert!(limiter.check(other, &HeaderMap::new()).is_ok(), "another address has its own");
        let off = SessionLimiter::new(0, 1, false);
        for _ in 0..100 {
            assert!(off.check(peer, &HeaderMap::new()).is_ok());
        }
    }
}

#[cfg(test)]
mod limit_tests {
    use super::*;

    // A take of more cells than the bucket holds takes the whole bucket; the next waits for
    // the rate; a rate of 0 is no limit.
    #[tokio::test]
    async fn a_take_past_the_burst_waits_for_the_rate() {
        let limit: Limit<u8> = Limit::new(10, Duration::from_secs(1), 5, "ten a second".into());
        assert!(limit.try_take(&1, 1_000).is_ok(), "a whole bucket at most");
        let wait = limit.try_take(&1, 1).unwrap_err();
        assert!(wait > Duration::ZERO && wait <= Duration::from_millis(100), "{wait:?}");
        assert!(limit.try_take(&2, 5).is_ok(), "another key has its own");
        let started = std::time::Instant::now();
        limit.wait(&1).await;
        let waited = started.elapsed();
        assert!(
            waited >= Duration::from_millis(50) && waited < Duration::from_secs(1),
            "{waited:?}"
        );
        match limit.take(&1, 1) {
            Err(AppError::TooManyRequests { message, .. }) => {
                assert!(message.contains("ten a second"), "{message}")
            }
            other => panic!("{other:?}"),
        }
        let off: Limit<u8> = Limit::new(0, Duration::from_secs(1), 1, String::new());
        for _ in 0..100 {
            assert!(off.try_take(&1, 1_000).is_ok());
        }
    }
}
