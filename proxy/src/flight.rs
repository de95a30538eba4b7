//! An export's work and the requests that wait for it (`crate::export`). The work runs on a
//! task of its own, not in a request, and tells its progress and then its outcome to every
//! request waiting for it ([`Waiter`]), however many join, however late (a finished flight
//! answers at once: that is how a print is kept, `crate::kept_prints`).
//!
//! The work goes on while a request waits for it, or within the retry window of a request
//! answered 408 ([`Waiter::timed_out`]: the client was told to ask again); once neither holds,
//! [`Flight::is_wanted`] says so for good and the work stops at its next step.

use std::collections::VecDeque;
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
    /// The latest report of each stage so far, in order: a waiter slower than the reports
    /// still sees every stage (a later stage's report never hides an earlier stage's last).
    progress: watch::Sender<Vec<Progress>>,
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
            progress: watch::Sender::new(Vec::new()),
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
        self.progress.send_modify(|stages| match stages.last_mut() {
            Some(last) if last.stage == progress.stage => *last = progress,
            _ => stages.push(progress),
        });
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

    /// The work's progress as lines to tell, from the start (every stage so far first).
    pub fn progress(&self) -> ProgressLines {
        let mut reports = self.flight.progress.subscribe();
        reports.mark_changed();
        ProgressLines { reports, told: Vec::new(), pending: VecDeque::new() }
    }

    /// The request was answered 408: its client was told to ask again, so the work stays
    /// wanted for `window` more (the retry's), waiters or not.
    pub fn timed_out(self, window: Duration) {
        let mut wanted = self.flight.wanted.lock().expect("flight lock");
        let until = Instant::now() + window;
        wanted.retry_until = Some(wanted.retry_until.map_or(until, |u| u.max(until)));
    }
}

/// A waiter's progress lines: each stage's latest report not yet told, in stage order, so
/// every stage is told at least once and, within a stage, `done` only grows.
#[derive(Debug)]
pub(crate) struct ProgressLines {
    reports: watch::Receiver<Vec<Progress>>,
    /// The last report told of each stage.
    told: Vec<Progress>,
    pending: VecDeque<Progress>,
}

impl ProgressLines {
    /// The next line to tell, once there is one. Cancel-safe: what was read and not yet
    /// returned stays pending.
    pub async fn next(&mut self) -> Progress {
        loop {
            if let Some(line) = self.pending.pop_front() {
                return line;
            }
            if self.reports.changed().await.is_err() {
                // The flight is gone with its sender: no more reports.
                std::future::pending::<()>().await;
            }
            let stages = self.reports.borrow_and_update().clone();
            for (i, report) in stages.into_iter().enumerate() {
                if self.told.get(i) == Some(&report) {
                    continue;
                }
                self.pending.push_back(report);
                match self.told.get_mut(i) {
                    Some(told) => *told = report,
                    None => self.told.push(report),
                }
            }
        }
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

    #[tokio::test]
    async fn a_waiter_slower_than_the_reports_is_told_every_stage_in_order() {
        let at = |stage, done, total| Progress { stage, done, total };
        let (flight, waiter) = Flight::start();
        let mut lines = waiter.progress();
        flight.report(at("reading", 0, 2));
        assert_eq!(lines.next().await, at("reading", 0, 2));
        // Reports come faster than this waiter reads: each stage's latest is told, none hidden.
        for report in
            [at("reading", 2, 2), at("solids", 1, 2), at("solids", 2, 2), at("union", 1, 1)]
        {
            flight.report(report);
        }
        let told = [lines.next().await, lines.next().await, lines.next().await];
        assert_eq!(told, [at("reading", 2, 2), at("solids", 2, 2), at("union", 1, 1)]);
        // One joining late is told every stage so far.
        let late = flight.join().unwrap();
        let mut late_lines = late.progress();
        let told = [late_lines.next().await, late_lines.next().await, late_lines.next().await];
        assert_eq!(told, [at("reading", 2, 2), at("solids", 2, 2), at("union", 1, 1)]);
    }
}
