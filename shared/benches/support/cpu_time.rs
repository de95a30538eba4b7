//! A criterion measurement of the benchmark thread's CPU time instead of wall-clock time.
//!
//! The development and CI machines are shared: another process's work stretches wall-clock
//! time but not the CPU time our thread spends, so this is the per-core cost we set goals on.
//! Page faults and other kernel time spent for the thread are included.

use std::time::Duration;

use criterion::measurement::{Measurement, ValueFormatter, WallTime};

/// Thread CPU time (user + system), read with `clock_gettime(CLOCK_THREAD_CPUTIME_ID)`.
#[derive(Debug, Clone, Copy, Default)]
pub struct ThreadCpuTime;

static WALL_TIME: WallTime = WallTime;

impl Measurement for ThreadCpuTime {
    type Intermediate = cpu_time::ThreadTime;
    type Value = Duration;

    fn start(&self) -> cpu_time::ThreadTime {
        cpu_time::ThreadTime::now()
    }

    fn end(&self, started: cpu_time::ThreadTime) -> Duration {
        started.elapsed()
    }

    fn add(&self, v1: &Duration, v2: &Duration) -> Duration {
        *v1 + *v2
    }

    fn zero(&self) -> Duration {
        Duration::ZERO
    }

    fn to_f64(&self, value: &Duration) -> f64 {
        value.as_nanos() as f64
    }

    fn formatter(&self) -> &dyn ValueFormatter {
        // Durations print the same whichever clock measured them.
        WALL_TIME.formatter()
    }
}
