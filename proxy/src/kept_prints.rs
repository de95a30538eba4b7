//! The prints of this replica, being made or kept, by what determines them (issue 49, item 7):
//! a print longer than the request timeout is answered 408 but goes on, and its retry is
//! answered from it; one flight per model at a time, so a retry while it is being made waits
//! for that same work instead of starting another.
//!
//! The key ([`PrintKey`]) is read from the database at each request, so a replica (they share
//! one PostgreSQL) never serves a model that has changed: a done stroke's samples never change,
//! and what can (its placement, its solid, its removal, which strokes are chosen) is in the key.
//! A key that is not here only costs the work. Kept: at most [`MAX_KEPT_PRINTS`] finished
//! prints, [`MAX_KEPT_PRINT_BYTES`] in all, each for [`KEPT_FOR`].

use std::collections::HashMap;
use std::sync::Arc;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use penmesh_print::PrintOptions;
use sha2::Digest as _;
use tokio::time::Instant;
use uuid::Uuid;

use crate::flight::{Flight, Waiter};
use crate::store::StrokeRow;

/// Finished prints kept on one replica.
pub const MAX_KEPT_PRINTS: usize = 4;
/// Bytes of finished prints kept on one replica; a print larger than this is not kept.
pub const MAX_KEPT_PRINT_BYTES: usize = 128 * 1024 * 1024;
/// How long a finished print is kept: long enough for the retries of a request that timed
/// out, and for asking again soon after, not a store of files.
pub const KEPT_FOR: Duration = Duration::from_secs(10 * 60);

/// What determines a print: the session, the format, size and thickness, and each chosen
/// stroke in order with its id (a done stroke's samples never change), brush, placement and
/// solid; a SHA-256 of them.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) struct PrintKey([u8; 32]);

impl PrintKey {
    pub fn of(session: Uuid, extension: &str, options: &PrintOptions, rows: &[StrokeRow]) -> Self {
        let mut hash = sha2::Sha256::new();
        hash.update(session.as_bytes());
        hash.update(extension.as_bytes());
        hash.update(options.size_mm.to_le_bytes());
        hash.update(options.min_thickness_mm.to_le_bytes());
        hash.update((rows.len() as u64).to_le_bytes());
        for row in rows {
            hash.update(row.id.as_bytes());
            let brush = &row.brush;
            for value in [brush.size, brush.pressure_response, brush.min_radius] {
                hash.update(value.to_le_bytes());
            }
            hash.update(row.placement.to_bytes());
            hash.update(row.solid.to_bytes());
        }
        PrintKey(hash.finalize().into())
    }
}

/// How a request for a print was met.
pub(crate) enum Joined {
    /// The print is kept or being made: wait for it.
    Existing(Waiter),
    /// Nothing was: the caller starts the work of this new flight, holding the permit.
    Started(Arc<Flight>, Waiter, tokio::sync::OwnedSemaphorePermit),
}

/// The replica's prints being made or kept.
#[derive(Debug, Default)]
pub struct KeptPrints {
    entries: Mutex<HashMap<PrintKey, Entry>>,
    /// Prints whose work was started on this replica.
    made: AtomicU64,
}

#[derive(Debug)]
struct Entry {
    flight: Arc<Flight>,
    /// When it was kept, and its bytes (`None` while it is being made).
    kept: Option<(Instant, usize)>,
}

impl KeptPrints {
    /// Prints whose work was started on this replica (a kept or joined one is not counted).
    pub fn made(&self) -> u64 {
        self.made.load(Ordering::Relaxed)
    }

    /// The print of `key`: kept or being made, else a new flight if `permit` gives a permit to
    /// make it (`None` when it does not: the replica is busy).
    pub(crate) fn join(
        &self,
        key: PrintKey,
        permit: impl FnOnce() -> Option<tokio::sync::OwnedSemaphorePermit>,
    ) -> Option<Joined> {
        let mut entries = self.entries.lock().expect("kept prints lock");
        if let Some(waiter) = entries.get(&key).and_then(|e| e.flight.join()) {
            metrics::counter!("penmesh_prints_total", "answer" => "existing").increment(1);
            return Some(Joined::Existing(waiter));
        }
        let permit = permit()?;
        let (flight, waiter) = Flight::start();
        entries.insert(key, Entry { flight: flight.clone(), kept: None });
        self.made.fetch_add(1, Ordering::Relaxed);
        metrics::counter!("penmesh_prints_total", "answer" => "made").increment(1);
        Some(Joined::Started(flight, waiter, permit))
    }

    /// `flight`, the print of `key`, has ended: kept if it made a file that fits (the oldest
    /// kept ones make room), else forgotten. Whether it was kept.
    pub(crate) fn finished(&self, key: &PrintKey, flight: &Arc<Flight>) -> bool {
        let mut entries = self.entries.lock().expect("kept prints lock");
        if !entries.get(key).is_some_and(|e| Arc::ptr_eq(&e.flight, flight)) {
            return false;
        }
        let bytes = match flight.outcome() {
            Some(Ok(file)) if file.len() <= MAX_KEPT_PRINT_BYTES => file.len(),
            _ => {
                entries.remove(key);
                return false;
            }
        };
        entries.get_mut(key).expect("checked above").kept = Some((Instant::now(), bytes));
        loop {
            let kept: Vec<(&PrintKey, Instant, usize)> = entries
                .iter()
                .filter_map(|(k, e)| e.kept.map(|(at, bytes)| (k, at, bytes)))
                .collect();
            let total: usize = kept.iter().map(|(_, _, bytes)| bytes).sum();
            if kept.len() <= MAX_KEPT_PRINTS && total <= MAX_KEPT_PRINT_BYTES {
                break;
            }
            let oldest = kept.iter().min_by_key(|(_, at, _)| *at).expect("over a bound").0.clone();
            entries.remove(&oldest);
        }
        entries.contains_key(key)
    }

    /// Forgets the print of `key` if it is still `flight` (its time is up).
    pub(crate) fn forget(&self, key: &PrintKey, flight: &Arc<Flight>) {
        let mut entries = self.entries.lock().expect("kept prints lock");
        if entries.get(key).is_some_and(|e| Arc::ptr_eq(&e.flight, flight)) {
            entries.remove(key);
        }
    }
}
