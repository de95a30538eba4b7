//! Where the ingest path's CPU goes, stage by stage (issue 53): the time spent in each stage
//! of a batch's path, summed over the process's life and read at `/metrics` as
//! `penmesh_stage_nanoseconds_total{stage}` and `penmesh_stage_polls_total{stage}`.
//!
//! Off unless `--stage-timing`: then a stage costs one relaxed atomic load. On, one poll in
//! [`SAMPLE_ONE_IN`], chosen at random, reads its thread's CPU clock before and after, and
//! counts that many times what it read. The thread's CPU clock, not the wall clock: on a
//! pinned core the writer (which runs at a higher priority) preempts the connection threads
//! in the middle of their polls, and a wall clock counted the writer's time in the connection's
//! stages (6.5 µs a sample in a connection task whose threads spent 5.6 µs in all). That clock
//! is a system call (a few hundred nanoseconds), hence the sampling: about 1 % of the proxy's
//! CPU at 600 pens. Only the time inside a poll is counted, never the time a future waits.
//! `penmesh-lab load` turns the totals into microseconds per sample received over its steady
//! window, beside the threads' CPU from `/proc`.

use std::cell::Cell;
use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::task::{Context, Poll};

use futures_util::Stream;

/// A stage of the ingest path. The connection task's stages are parts of
/// [`Stage::ConnectionTask`]; the rest of that task is its loop (`select!`, timers, the
/// commits' answers waited for).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// A connection's task, each poll whole.
    ConnectionTask,
    /// Reading the socket: the WebSocket library's framing and `recvfrom`.
    Read,
    /// Decoding a frame into a message.
    Decode,
    /// Checking a `Points` batch and running ACUTS over it (`StrokeState::push_points`).
    Acuts,
    /// Handing a request to the writer (its queue and the byte budget).
    Submit,
    /// A commit's answer: the `Ack` and retained samples encoded and queued.
    Answer,
    /// A session event passed on to a watcher.
    Events,
    /// The task that writes a connection's queued frames to its socket, each poll whole.
    SenderTask,
    /// The writer's transactions, the writer thread's share (not the database's thread).
    Commit,
    /// The writer telling the requesters and publishing their events.
    Publish,
}

impl Stage {
    pub const ALL: [Stage; 10] = [
        Stage::ConnectionTask,
        Stage::Read,
        Stage::Decode,
        Stage::Acuts,
        Stage::Submit,
        Stage::Answer,
        Stage::Events,
        Stage::SenderTask,
        Stage::Commit,
        Stage::Publish,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Stage::ConnectionTask => "connection_task",
            Stage::Read => "read",
            Stage::Decode => "decode",
            Stage::Acuts => "acuts",
            Stage::Submit => "submit",
            Stage::Answer => "answer",
            Stage::Events => "events",
            Stage::SenderTask => "sender_task",
            Stage::Commit => "commit",
            Stage::Publish => "publish",
        }
    }
}

static ON: AtomicBool = AtomicBool::new(false);
static NANOS: [AtomicU64; Stage::ALL.len()] = [const { AtomicU64::new(0) }; Stage::ALL.len()];
static POLLS: [AtomicU64; Stage::ALL.len()] = [const { AtomicU64::new(0) }; Stage::ALL.len()];

/// What one reading of the thread's clock adds to a timed poll, nanoseconds: taken off each.
static CLOCK_COST: AtomicU64 = AtomicU64::new(0);

/// Starts counting (`--stage-timing`); there is no way back, a process counts or it does not.
/// First measures what a reading of the clock costs: a timed poll's reading includes about one
/// (the end of the first and the start of the second), a few hundred nanoseconds in a VM
/// against stages of a microsecond or two.
pub fn enable() {
    const READS: u64 = 10_000;
    let first = thread_cpu_ns();
    let mut last = first;
    for _ in 0..READS {
        last = thread_cpu_ns();
    }
    CLOCK_COST.store((last - first) / READS, Ordering::Relaxed);
    ON.store(true, Ordering::Relaxed);
}

/// One poll in this many is timed, and counts this many times.
pub const SAMPLE_ONE_IN: u64 = 8;

/// The calling thread's CPU time, nanoseconds.
fn thread_cpu_ns() -> u64 {
    #[cfg(target_os = "linux")]
    {
        let t = rustix::time::clock_gettime(rustix::time::ClockId::ThreadCPUTime);
        t.tv_sec as u64 * 1_000_000_000 + t.tv_nsec as u64
    }
    #[cfg(not(target_os = "linux"))]
    {
        // No thread clock at hand: the wall clock, which also counts what preempts the thread.
        static EPOCH: std::sync::OnceLock<std::time::Instant> = std::sync::OnceLock::new();
        EPOCH.get_or_init(std::time::Instant::now).elapsed().as_nanos() as u64
    }
}

thread_local! {
    /// xorshift64 state: which polls are timed.
    static DICE: Cell<u64> = const { Cell::new(0x9e37_79b9_7f4a_7c15) };
}

/// True for one call in [`SAMPLE_ONE_IN`], at random (a fixed period would time only one kind
/// of poll of a task whose polls alternate).
fn sampled() -> bool {
    DICE.with(|dice| {
        let mut x = dice.get();
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        dice.set(x);
        x % SAMPLE_ONE_IN == 0
    })
}

/// A clock started when counting is on and this poll is one of those timed.
#[must_use]
pub struct Started(Option<u64>);

/// Starts timing a stage (nothing when counting is off).
#[inline]
pub fn start() -> Started {
    Started((ON.load(Ordering::Relaxed) && sampled()).then(thread_cpu_ns))
}

impl Started {
    /// Adds the thread's CPU time since [`start`] to `stage`.
    #[inline]
    pub fn stop(self, stage: Stage) {
        if let Some(at) = self.0 {
            let spent = thread_cpu_ns()
                .saturating_sub(at)
                .saturating_sub(CLOCK_COST.load(Ordering::Relaxed));
            NANOS[stage as usize].fetch_add(spent * SAMPLE_ONE_IN, Ordering::Relaxed);
            POLLS[stage as usize].fetch_add(SAMPLE_ONE_IN, Ordering::Relaxed);
        }
    }
}

/// `inner` (a future or a stream), its polls counted as `stage`.
pub fn timed<F>(stage: Stage, inner: F) -> Timed<F> {
    Timed { stage, inner }
}

pin_project_lite::pin_project! {
    /// A future or stream whose polls are counted as its stage ([`timed`]).
    pub struct Timed<F> {
        stage: Stage,
        #[pin]
        inner: F,
    }
}

impl<F: Future> Future for Timed<F> {
    type Output = F::Output;

    fn poll(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<F::Output> {
        let this = self.project();
        let started = start();
        let polled = this.inner.poll(cx);
        started.stop(*this.stage);
        polled
    }
}

impl<S: Stream> Stream for Timed<S> {
    type Item = S::Item;

    fn poll_next(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<S::Item>> {
        let this = self.project();
        let started = start();
        let polled = this.inner.poll_next(cx);
        started.stop(*this.stage);
        polled
    }
}

/// The totals in Prometheus' text form (appended to `/metrics` when counting is on).
pub fn render() -> Option<String> {
    use std::fmt::Write;
    if !ON.load(Ordering::Relaxed) {
        return None;
    }
    let mut out = String::from(
        "# HELP penmesh_stage_nanoseconds_total Time spent in each stage of the ingest path (--stage-timing)\n\
         # TYPE penmesh_stage_nanoseconds_total counter\n",
    );
    for stage in Stage::ALL {
        let nanos = NANOS[stage as usize].load(Ordering::Relaxed);
        let _ =
            writeln!(out, "penmesh_stage_nanoseconds_total{{stage=\"{}\"}} {nanos}", stage.name());
    }
    out.push_str(
        "# HELP penmesh_stage_polls_total Polls in each stage, estimated from those timed (--stage-timing)\n\
         # TYPE penmesh_stage_polls_total counter\n",
    );
    let cost = CLOCK_COST.load(Ordering::Relaxed);
    let _ = writeln!(
        out,
        "# HELP penmesh_stage_clock_cost_nanoseconds One reading of the thread clock, taken off each timed poll\n\
         # TYPE penmesh_stage_clock_cost_nanoseconds gauge\n\
         penmesh_stage_clock_cost_nanoseconds {cost}"
    );
    for stage in Stage::ALL {
        let polls = POLLS[stage as usize].load(Ordering::Relaxed);
        let _ = writeln!(out, "penmesh_stage_polls_total{{stage=\"{}\"}} {polls}", stage.name());
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Off, nothing is counted; on, a timed future's polls are, estimated from those sampled.
    #[tokio::test]
    async fn a_stage_counts_the_cpu_of_its_polls_once_counting_is_on() {
        let before = NANOS[Stage::Publish as usize].load(Ordering::Relaxed);
        // The only test that enables counting in this binary: before it, nothing is counted.
        // (Once on, the writers of other tests running beside it may add to `Publish`: a few
        // microseconds, which the bounds below allow.)
        timed(Stage::Publish, async {}).await;
        assert_eq!(NANOS[Stage::Publish as usize].load(Ordering::Relaxed), before);
        assert!(render().is_none());

        enable();
        let polls = POLLS[Stage::Publish as usize].load(Ordering::Relaxed);
        // 4,000 polls, each burning 20 µs of this thread's CPU: 80 ms in all.
        let (n, burn) = (4_000u64, 20_000u64);
        let mut left = n;
        timed(
            Stage::Publish,
            std::future::poll_fn(|cx| {
                let until = thread_cpu_ns() + burn;
                while thread_cpu_ns() < until {}
                left -= 1;
                if left == 0 {
                    return Poll::Ready(());
                }
                cx.waker().wake_by_ref();
                Poll::Pending
            }),
        )
        .await;
        let nanos = NANOS[Stage::Publish as usize].load(Ordering::Relaxed) - before;
        let spent = n * burn;
        // About 500 polls sampled: the estimate is within a few per cent, and never off by
        // a quarter.
        assert!(nanos > spent * 3 / 4 && nanos < spent * 3 / 2, "{nanos} ns for {spent}");
        let counted = POLLS[Stage::Publish as usize].load(Ordering::Relaxed) - polls;
        assert!(counted > n * 3 / 4 && counted < n * 5 / 4, "{counted} polls for {n}");
        let text = render().expect("on");
        assert!(text.contains("penmesh_stage_nanoseconds_total{stage=\"publish\"} "), "{text}");
    }
}
