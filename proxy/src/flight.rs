//! An export's work and the requests that wait for it (`crate::export`). The work runs on a
//! task of its own, not in a request, and tells its progress and then its outcome to every
//! request waiting for it ([`Waiter`]), however many join, however late (a finished flight
//! answers at once: that is how a print is kept, `crate::kept_prints`).
//!
//! The work goes on while a request waits for it, or within the retry window of a request
//! answered 408 ([`Waiter::timed_out`]: the client was told to ask again); once neither holds,
//! [`Flight::is_wanted`] says so for good and the work stops at its next step.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use axum::body::Bytes;
use tokio::sync::watch;
use tokio::time::Instant;

use crate::http::AppError;

/// Where an export is: its `stage` (`reading`, `solids`, `union`), `done` of `total`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Progress {
    pub stage: &'static str,
    pub done: usize,
    pub total: usize,
}

/// A finished export: its file, or the error every waiting request is answered with.
pub(crate) type Outcome = Result<Bytes, Arc<AppError>>;

/// One export's work as its waiters see it.
#[derive(Debug)]
pub(crate) struct Flight {
    wanted: Mutex<Wanted>,
    progress: watch::Sender<Option<Progress>>,
    outcome: watch::Sender<Option<Outcome>>,
}

/// Who still wants a flight's work.
#[derive(Debug, Default)]
struct Wanted {
    /// Requests waiting for it now.
    waiters: usize,
    /// The end of the retry window of the last request answered 408.
    retry_until: Option<Instant>,
    /// Set once nobody wanted it: the work stops, and nobody joins it any more.
    stopped: bool,
}

impl Flight {
    /// A new flight and its first waiter (before the work starts, so the work is wanted).
    pub fn start() -> (Arc<Flight>, Waiter) {
        let flight = Arc::new(Flight {
            wanted: Mutex::new(Wanted::default()),
            progress: watch::Sender::new(None),
            outcome: watch::Sender::new(None),
        });
        let waiter = flight.join().expect("a new flight is not stopped");
        (flight, waiter)
    }

    /// A waiter of this flight, or `None` once it has stopped for want of one.
    pub fn join(self: &Arc<Flight>) -> Option<Waiter> {
        let mut wanted = self.wanted.lock().expect("flight lock");
        if wanted.stopped {
            return None;
        }
        wanted.waiters += 1;
        Some(Waiter { flight: self.clone() })
    }

    /// Whether the work should go on: a request waits for it, or a retry window is open.
    /// Once `false`, always `false`.
    pub fn is_wanted(&self) -> bool {
        let mut wanted = self.wanted.lock().expect("flight lock");
        let retry_open = wanted.retry_until.is_some_and(|until| Instant::now() < until);
        if wanted.waiters == 0 && !retry_open {
            wanted.stopped = true;
        }
        !wanted.stopped
    }

    /// Tells the waiters where the work is.
    pub fn report(&self, progress: Progress) {
        self.progress.send_replace(Some(progress));
    }

    /// Tells the waiters, present and future, how it ended.
    pub fn finish(&self, outcome: Outcome) {
        self.outcome.send_replace(Some(outcome));
    }

    /// The outcome, if the work has ended.
    pub fn outcome(&self) -> Option<Outcome> {
        self.outcome.borrow().clone()
    }
}

/// A request waiting for a flight; the flight counts it until it is dropped.
#[derive(Debug)]
pub(crate) struct Waiter {
    flight: Arc<Flight>,
}

impl Waiter {
    /// The work's outcome, once it has ended.
    pub async fn outcome(&self) -> Outcome {
        let mut outcome = self.flight.outcome.subscribe();
        let ended = outcome.wait_for(Option::is_some).await.expect("the flight holds its sender");
        ended.clone().expect("waited for Some")
    }

    /// The work's progress, each change (the current one first).
    pub fn progress(&self) -> watch::Receiver<Option<Progress>> {
        let mut progress = self.flight.progress.subscribe();
        progress.mark_changed();
        progress
    }

    /// The request was answered 408: its client was told to ask again, so the work stays
    /// wanted for `window` more (the retry's), waiters or not.
    pub fn timed_out(self, window: Duration) {
        let mut wanted = self.flight.wanted.lock().expect("flight lock");
        let until = Instant::now() + window;
        wanted.retry_until = Some(wanted.retry_until.map_or(until, |u| u.max(until)));
    }
}

impl Drop for Waiter {
    fn drop(&mut self) {
        self.flight.wanted.lock().expect("flight lock").waiters -= 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test(start_paused = true)]
    async fn a_flight_is_wanted_while_waited_for_or_within_a_retry_window() {
        let (flight, first) = Flight::start();
        let second = flight.join().unwrap();
        drop(first);
        assert!(flight.is_wanted(), "one request still waits");
        second.timed_out(Duration::from_secs(1));
        assert!(flight.is_wanted(), "within the retry window");
        tokio::time::advance(Duration::from_millis(600)).await;
        let retry = flight.join().unwrap();
        tokio::time::advance(Duration::from_secs(5)).await;
        assert!(flight.is_wanted(), "the retry waits");
        drop(retry);
        assert!(!flight.is_wanted(), "nobody waits, the window has passed");
        assert!(flight.join().is_none(), "a stopped flight is joined by nobody");
    }

    #[tokio::test]
    async fn every_waiter_gets_the_outcome_even_one_joining_after_it() {
        let (flight, first) = Flight::start();
        flight.finish(Ok(Bytes::from_static(b"file")));
        assert_eq!(first.outcome().await.unwrap(), Bytes::from_static(b"file"));
        let late = flight.join().unwrap();
        assert_eq!(late.outcome().await.unwrap(), Bytes::from_static(b"file"));
    }
}
