//! The rate limit on session creation (`POST /v1/sessions`, which needs no token): a token
//! bucket per client address (the `governor` crate), `session_burst` deep, refilled at
//! `session_rate_per_minute`.
//!
//! The client address ([`client_key`], which the per-address WebSocket cap of
//! `max_connections_per_address` counts by too) is the TCP peer's. Behind a reverse proxy or
//! load balancer that is the proxy's, so every client shares one bucket, unless
//! `trust_forwarded_for` is on: then it is the last address of `X-Forwarded-For` (the one the
//! nearest proxy appended: the ones before it are whatever the client wrote), else `X-Real-IP`,
//! else the peer. IPv6 addresses count by their /64, which one client usually holds whole.

use std::net::{IpAddr, Ipv6Addr, SocketAddr};
use std::num::NonZeroU32;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use axum::http::HeaderMap;
use governor::clock::{Clock, DefaultClock};
use governor::{DefaultKeyedRateLimiter, Quota};

/// How often the buckets of addresses that have refilled are forgotten.
const FORGET_EVERY: Duration = Duration::from_secs(60);

/// The session-creation limiter (`None` inside when the rate is 0: no limit).
#[derive(Debug)]
pub struct SessionLimiter {
    limiter: Option<DefaultKeyedRateLimiter<IpAddr>>,
    trust_forwarded_for: bool,
    last_forget: Mutex<Instant>,
}

impl SessionLimiter {
    pub fn new(per_minute: u32, burst: u32, trust_forwarded_for: bool) -> SessionLimiter {
        let limiter = NonZeroU32::new(per_minute).and_then(|rate| {
            let quota = Quota::with_period(Duration::from_secs(60) / rate.get())?
                .allow_burst(NonZeroU32::new(burst).unwrap_or(NonZeroU32::MIN));
            Some(DefaultKeyedRateLimiter::keyed(quota))
        });
        SessionLimiter { limiter, trust_forwarded_for, last_forget: Mutex::new(Instant::now()) }
    }

    /// `Ok` when the client may create a session now, else how long it should wait.
    pub fn check(&self, peer: SocketAddr, headers: &HeaderMap) -> Result<(), Duration> {
        let Some(limiter) = &self.limiter else { return Ok(()) };
        self.forget_now_and_then(limiter);
        let key = client_key(peer, headers, self.trust_forwarded_for);
        limiter.check_key(&key).map_err(|not_until| {
            not_until.wait_time_from(DefaultClock::default().now()).max(Duration::from_secs(1))
        })
    }

    fn forget_now_and_then(&self, limiter: &DefaultKeyedRateLimiter<IpAddr>) {
        let mut last = self.last_forget.lock().expect("limiter lock");
        if last.elapsed() >= FORGET_EVERY {
            *last = Instant::now();
            limiter.retain_recent();
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
        let wait = limiter.check(peer, &HeaderMap::new()).unwrap_err();
        assert!(wait >= Duration::from_secs(1) && wait <= Duration::from_secs(2), "{wait:?}");
        assert!(limiter.check(other, &HeaderMap::new()).is_ok(), "another address has its own");
        let off = SessionLimiter::new(0, 1, false);
        for _ in 0..100 {
            assert!(off.check(peer, &HeaderMap::new()).is_ok());
        }
    }
}
