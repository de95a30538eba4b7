//! CPU time and memory of a process, and the machine's load, from /proc (the `procfs` crate).
//! A process that is gone reads as zero: the run still reports what it measured.

use procfs::process::Process;

/// User plus system CPU time of a process, seconds.
pub(super) fn cpu_seconds(pid: u32) -> f64 {
    let Ok(stat) = Process::new(pid as i32).and_then(|p| p.stat()) else { return 0.0 };
    (stat.utime + stat.stime) as f64 / procfs::ticks_per_second() as f64
}

/// Resident memory now and at its peak (VmRSS, VmHWM), KB.
pub(super) fn memory_kb(pid: u32) -> (u64, u64) {
    match Process::new(pid as i32).and_then(|p| p.status()) {
        Ok(status) => (status.vmrss.unwrap_or(0), status.vmhwm.unwrap_or(0)),
        Err(_) => (0, 0),
    }
}

/// The load average line, as /proc/loadavg has it.
pub(super) fn loadavg() -> Option<String> {
    use procfs::Current;
    let l = procfs::LoadAverage::current().ok()?;
    Some(format!("{} {} {} {}/{} {}", l.one, l.five, l.fifteen, l.cur, l.max, l.latest_pid))
}
