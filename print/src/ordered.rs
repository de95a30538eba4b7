//! Work shared out over the machine's cores, its results taken in order on the calling thread.
//! The print's per-stroke geometry is pure Rust and independent stroke by stroke, but Manifold's
//! objects stay on the thread that made them (they are not `Send`), and they are made in stroke
//! order so that the print comes out the same whatever the number of cores.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;

/// Calls `make(i)` for every `i` in `0..n` on worker threads (one per core) and `take(i, result)`
/// on this thread in the order of `i`, while the workers go on with the next ones. The first
/// error from `take` stops the workers and is returned.
pub(crate) fn in_order<R: Send, E>(
    n: usize,
    make: impl Fn(usize) -> R + Sync,
    mut take: impl FnMut(usize, R) -> Result<(), E>,
) -> Result<(), E> {
    let workers = std::thread::available_parallelism().map_or(1, |c| c.get()).min(n);
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    std::thread::scope(|scope| {
        let (sender, results) = mpsc::channel();
        for _ in 0..workers {
            let sender = sender.clone();
            let (next, stop, make) = (&next, &stop, &make);
            scope.spawn(move || {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= n || stop.load(Ordering::Relaxed) {
                        break;
                    }
                    if sender.send((i, make(i))).is_err() {
                        break;
                    }
                }
            });
        }
        drop(sender);
        // Results that came before their turn.
        let mut early = HashMap::new();
        let mut due = 0;
        for (i, result) in results {
            early.insert(i, result);
            while let Some(result) = early.remove(&due) {
                if let Err(err) = take(due, result) {
                    stop.store(true, Ordering::Relaxed);
                    return Err(err);
                }
                due += 1;
            }
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn results_are_taken_in_order_and_an_error_stops_the_work() {
        let mut seen = Vec::new();
        let done: Result<(), ()> = in_order(
            100,
            |i| i * i,
            |i, r| {
                seen.push((i, r));
                Ok(())
            },
        );
        assert_eq!(done, Ok(()));
        assert_eq!(seen, (0..100).map(|i| (i, i * i)).collect::<Vec<_>>());
        let mut taken = 0;
        let failed = in_order(
            100,
            |i| i,
            |i, _| {
                taken += 1;
                if i == 10 { Err(i) } else { Ok(()) }
            },
        );
        assert_eq!((failed, taken), (Err(10), 11));
        assert_eq!(in_order(0, |i| i, |_, _| Err::<(), _>(())), Ok(()));
    }
}
