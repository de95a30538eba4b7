//! The proxy's side of a run, second by second: its writer's commits (read from its `/metrics`)
//! and its CPU (from `/proc`, when the run spawned it). Beside the load tool's acknowledgements
//! by second, this shows what the proxy was doing when a run's slow spell began.

use std::time::Duration;

use tokio::sync::oneshot;
use tokio::time::Instant;

use super::procstat;
use super::summary::ServerSecond;

/// How often the proxy is read.
const EVERY: Duration = Duration::from_secs(1);

/// The writer's totals since the proxy started, as `/metrics` gives them.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct CommitTotals {
    commits: f64,
    seconds: f64,
    samples: f64,
    requests: f64,
}

/// The commit totals in a `/metrics` text; all zero before the first commit (the proxy shows
/// a histogram only once it has a value).
pub(super) fn commit_totals(metrics: &str) -> CommitTotals {
    let mut totals = CommitTotals::default();
    for line in metrics.lines() {
        let Some((name, value)) = line.split_once(' ') else { continue };
        let Ok(value) = value.trim().parse::<f64>() else { continue };
        let field = match name {
            "penmesh_commit_seconds_count" => &mut totals.commits,
            "penmesh_commit_seconds_sum" => &mut totals.seconds,
            "penmesh_commit_batch_samples_sum" => &mut totals.samples,
            "penmesh_commit_batch_requests_sum" => &mut totals.requests,
            _ => continue,
        };
        *field = value;
    }
    totals
}

/// One reading: seconds since the run's start, the totals, the server's CPU seconds.
type Reading = (f64, CommitTotals, f64);

/// Reads the proxy every [`EVERY`] until `stop` fires; a reading that fails is skipped (the
/// next covers its second).
pub(super) async fn read_until(
    http: reqwest::Client,
    base: String,
    pid: Option<u32>,
    start: Instant,
    mut stop: oneshot::Receiver<()>,
) -> Vec<Reading> {
    let mut readings = Vec::new();
    let mut ticker = tokio::time::interval_at(start, EVERY);
    loop {
        tokio::select! {
            _ = &mut stop => break,
            _ = ticker.tick() => {
                let text = async { http.get(format!("{base}/metrics")).send().await?.text().await };
                let Ok(text) = text.await else { continue };
                let at = Instant::now().saturating_duration_since(start).as_secs_f64();
                readings.push((at, commit_totals(&text), pid.map_or(0.0, procstat::cpu_seconds)));
            }
        }
    }
    readings
}

/// What happened between each two readings.
pub(super) fn by_second(readings: &[Reading]) -> Vec<ServerSecond> {
    readings
        .windows(2)
        .map(|pair| {
            let ((t0, a, cpu0), (t1, b, cpu1)) = (pair[0], pair[1]);
            let commits = b.commits - a.commits;
            let per_commit = |x: f64| if commits > 0.0 { x / commits } else { 0.0 };
            ServerSecond {
                second: t1.round() as u64,
                commits: commits as u64,
                mean_commit_ms: per_commit(1000.0 * (b.seconds - a.seconds)),
                samples_per_commit: per_commit(b.samples - a.samples),
                requests_per_commit: per_commit(b.requests - a.requests),
                cpu_percent: 100.0 * (cpu1 - cpu0) / (t1 - t0).max(1e-9),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const METRICS: &str = "# TYPE penmesh_commit_seconds histogram\n\
        penmesh_commit_seconds_bucket{le=\"0.001\"} 3\n\
        penmesh_commit_seconds_sum 0.004\n\
        penmesh_commit_seconds_count 4\n\
        penmesh_commit_batch_samples_sum 800\n\
        penmesh_commit_batch_samples_count 4\n\
        penmesh_commit_batch_requests_sum 40\n\
        penmesh_samples_in_total 900\n";

    #[test]
    fn the_commit_totals_are_read_and_zero_before_the_first_commit() {
        let totals = commit_totals(METRICS);
        let expected =
            CommitTotals { commits: 4.0, seconds: 0.004, samples: 800.0, requests: 40.0 };
        assert_eq!(totals, expected);
        assert_eq!(commit_totals("penmesh_samples_in_total 5\n"), CommitTotals::default());
    }

    #[test]
    fn each_second_is_the_difference_of_two_readings() {
        let later =
            CommitTotals { commits: 14.0, seconds: 0.024, samples: 2800.0, requests: 140.0 };
        let readings = [(1.0, commit_totals(METRICS), 0.5), (2.0, later, 1.4)];
        let seconds = by_second(&readings);
        assert_eq!(seconds.len(), 1);
        let s = &seconds[0];
        assert_eq!((s.second, s.commits), (2, 10));
        assert!((s.mean_commit_ms - 2.0).abs() < 1e-9, "{s:?}");
        assert!((s.samples_per_commit - 200.0).abs() < 1e-9, "{s:?}");
        assert!((s.requests_per_commit - 10.0).abs() < 1e-9, "{s:?}");
        assert!((s.cpu_percent - 90.0).abs() < 1e-9, "{s:?}");
        // No commit in a second: nothing divided by zero.
        let idle = by_second(&[(1.0, later, 1.0), (2.0, later, 1.0)]);
        assert_eq!((idle[0].commits, idle[0].mean_commit_ms), (0, 0.0));
    }
}
