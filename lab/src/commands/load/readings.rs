//! The proxy's side of a run, second by second: its writer's commits and, when it counts them
//! (`--stage-timing`), the time of each stage of its ingest path (both read from its
//! `/metrics`); its CPU by thread (from `/proc`, when the run spawned it); and the bytes
//! waiting in the loopback sockets on either side (from `/proc/net/tcp`): what the proxy has not
//! read yet, and what it wrote that the load tool has not read yet. Beside the load tool's
//! acknowledgements by second, this shows what the proxy was doing when a slow spell began,
//! and where a backlog sits.

use std::collections::BTreeMap;
use std::time::Duration;

use tokio::sync::oneshot;
use tokio::time::Instant;

use super::procstat;
use super::summary::{ServerSecond, StageRow, StageTable};

/// How often the proxy is read.
const EVERY: Duration = Duration::from_secs(1);

/// The proxy's totals since it started, as `/metrics` gives them.
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct ServerTotals {
    commits: f64,
    seconds: f64,
    samples: f64,
    requests: f64,
    /// `penmesh_samples_in_total`: samples received in batches.
    samples_in: f64,
    /// Nanoseconds by stage (`penmesh_stage_nanoseconds_total`); empty when not counted.
    stage_ns: BTreeMap<String, f64>,
}

/// The totals in a `/metrics` text; all zero before the first commit (the proxy shows a
/// histogram only once it has a value).
pub(super) fn server_totals(metrics: &str) -> ServerTotals {
    let mut totals = ServerTotals::default();
    for line in metrics.lines() {
        let Some((name, value)) = line.split_once(' ') else { continue };
        let Ok(value) = value.trim().parse::<f64>() else { continue };
        if let Some(stage) = name
            .strip_prefix("penmesh_stage_nanoseconds_total{stage=\"")
            .and_then(|rest| rest.strip_suffix("\"}"))
        {
            totals.stage_ns.insert(stage.to_string(), value);
            continue;
        }
        let field = match name {
            "penmesh_commit_seconds_count" => &mut totals.commits,
            "penmesh_commit_seconds_sum" => &mut totals.seconds,
            "penmesh_commit_batch_samples_sum" => &mut totals.samples,
            "penmesh_commit_batch_requests_sum" => &mut totals.requests,
            "penmesh_samples_in_total" => &mut totals.samples_in,
            _ => continue,
        };
        *field = value;
    }
    totals
}

/// CPU seconds of the spawned server's threads, by what they do (`thread_group`).
pub(super) type ThreadCpu = BTreeMap<&'static str, f64>;

/// One reading.
#[derive(Debug, Clone, Default)]
pub(super) struct Reading {
    /// Seconds since the run's start.
    at: f64,
    totals: ServerTotals,
    /// The server's CPU seconds (0 when the run did not spawn it).
    cpu: f64,
    /// Its resident memory, KB (0 when the run did not spawn it).
    rss_kb: u64,
    threads: ThreadCpu,
    /// Bytes in the receive queues of the server's sockets (sent by the load tool, not yet read
    /// by the proxy) and of the load tool's (written by the proxy, not yet read by the tool).
    queued: SocketQueues,
}

/// Bytes waiting in the receive queues of the loopback connections to the server's port.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct SocketQueues {
    pub server_unread: u64,
    pub load_tool_unread: u64,
}

/// Sums the receive queues of `/proc/net/tcp`'s connections on `port`: on the server's side
/// (local port `port`) and on the load tool's (remote port `port`).
fn socket_queues(port: u16) -> SocketQueues {
    let mut queues = SocketQueues::default();
    for entry in procfs::net::tcp().unwrap_or_default() {
        if entry.local_address.port() == port {
            queues.server_unread += u64::from(entry.rx_queue);
        } else if entry.remote_address.port() == port {
            queues.load_tool_unread += u64::from(entry.rx_queue);
        }
    }
    queues
}

/// What a thread of the proxy does, by its name.
fn thread_group(name: &str) -> &'static str {
    if name.starts_with("tokio-r") {
        "connection threads"
    } else if name.starts_with("penmesh-writer") {
        "writer"
    } else if name.starts_with("sqlx-sqlite") {
        "database thread"
    } else {
        "other threads"
    }
}

/// CPU seconds of `pid`'s threads by group.
fn thread_cpu(pid: u32) -> ThreadCpu {
    let mut cpu = ThreadCpu::new();
    let Ok(tasks) = procfs::process::Process::new(pid as i32).and_then(|p| p.tasks()) else {
        return cpu;
    };
    let ticks = procfs::ticks_per_second() as f64;
    for task in tasks.flatten() {
        if let Ok(stat) = task.stat() {
            *cpu.entry(thread_group(&stat.comm)).or_default() +=
                (stat.utime + stat.stime) as f64 / ticks;
        }
    }
    cpu
}

/// Reads the proxy every [`EVERY`] until `stop` fires; a reading that fails is skipped (the
/// next covers its second).
pub(super) async fn read_until(
    http: reqwest::Client,
    base: String,
    pid: Option<u32>,
    start: Instant,
    mut stop: oneshot::Receiver<()>,
) -> Vec<Reading> {
    let port = reqwest::Url::parse(&base).ok().and_then(|u| u.port_or_known_default()).unwrap_or(0);
    let mut readings = Vec::new();
    let mut ticker = tokio::time::interval_at(start, EVERY);
    loop {
        tokio::select! {
            _ = &mut stop => break,
            _ = ticker.tick() => {
                let text = async { http.get(format!("{base}/metrics")).send().await?.text().await };
                let Ok(text) = text.await else { continue };
                let at = Instant::now().saturating_duration_since(start).as_secs_f64();
                readings.push(Reading {
                    at,
                    totals: server_totals(&text),
                    cpu: pid.map_or(0.0, procstat::cpu_seconds),
                    rss_kb: pid.map_or(0, |pid| procstat::memory_kb(pid).0),
                    threads: pid.map(thread_cpu).unwrap_or_default(),
                    queued: socket_queues(port),
                });
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
            let (a, b) = (&pair[0], &pair[1]);
            let (ta, tb) = (&a.totals, &b.totals);
            let commits = tb.commits - ta.commits;
            let per_commit = |x: f64| if commits > 0.0 { x / commits } else { 0.0 };
            ServerSecond {
                second: b.at.round() as u64,
                commits: commits as u64,
                mean_commit_ms: per_commit(1000.0 * (tb.seconds - ta.seconds)),
                samples_per_commit: per_commit(tb.samples - ta.samples),
                requests_per_commit: per_commit(tb.requests - ta.requests),
                cpu_percent: 100.0 * (b.cpu - a.cpu) / (b.at - a.at).max(1e-9),
                server_unread_kb: b.queued.server_unread as f64 / 1024.0,
                load_tool_unread_kb: b.queued.load_tool_unread as f64 / 1024.0,
                rss_kb: b.rss_kb,
            }
        })
        .collect()
}

/// Microseconds per sample received, by stage and by thread group, between the first reading
/// at or after `from` seconds and the last at or before `to`: `None` without two such readings
/// or without stage totals (a proxy run without `--stage-timing`).
pub(super) fn stage_table(readings: &[Reading], from: f64, to: f64) -> Option<StageTable> {
    let first = readings.iter().find(|r| r.at >= from)?;
    let last = readings.iter().rev().find(|r| r.at <= to)?;
    let samples = last.totals.samples_in - first.totals.samples_in;
    if last.at <= first.at || samples <= 0.0 || last.totals.stage_ns.is_empty() {
        return None;
    }
    let per_sample = |seconds: f64| seconds * 1e6 / samples;
    let stages = last
        .totals
        .stage_ns
        .iter()
        .map(|(stage, ns)| {
            let before = first.totals.stage_ns.get(stage).copied().unwrap_or(0.0);
            StageRow { name: stage.clone(), us_per_sample: per_sample((ns - before) / 1e9) }
        })
        .collect();
    let threads = last
        .threads
        .iter()
        .map(|(group, cpu)| StageRow {
            name: group.to_string(),
            us_per_sample: per_sample(cpu - first.threads.get(group).copied().unwrap_or(0.0)),
        })
        .collect();
    Some(StageTable {
        from_s: first.at,
        to_s: last.at,
        samples: samples as u64,
        server_cpu_us_per_sample: per_sample(last.cpu - first.cpu),
        stages,
        threads,
    })
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
        penmesh_samples_in_total 900\n\
        penmesh_stage_nanoseconds_total{stage=\"read\"} 1000000\n\
        penmesh_stage_polls_total{stage=\"read\"} 10\n";

    fn reading(at: f64, totals: ServerTotals, cpu: f64) -> Reading {
        Reading { at, totals, cpu, ..Reading::default() }
    }

    #[test]
    fn the_totals_are_read_and_zero_before_the_first_commit() {
        let totals = server_totals(METRICS);
        let expected = ServerTotals {
            commits: 4.0,
            seconds: 0.004,
            samples: 800.0,
            requests: 40.0,
            samples_in: 900.0,
            stage_ns: BTreeMap::from([("read".to_string(), 1e6)]),
        };
        assert_eq!(totals, expected);
        let before = server_totals("penmesh_samples_in_total 5\n");
        assert_eq!(before, ServerTotals { samples_in: 5.0, ..ServerTotals::default() });
    }

    #[test]
    fn each_second_is_the_difference_of_two_readings() {
        let later = ServerTotals {
            commits: 14.0,
            seconds: 0.024,
            samples: 2800.0,
            requests: 140.0,
            ..ServerTotals::default()
        };
        let mut second = reading(2.0, later.clone(), 1.4);
        second.queued = SocketQueues { server_unread: 2048, load_tool_unread: 512 };
        second.rss_kb = 40_960;
        let seconds = by_second(&[reading(1.0, server_totals(METRICS), 0.5), second]);
        assert_eq!(seconds.len(), 1);
        let s = &seconds[0];
        assert_eq!((s.second, s.commits), (2, 10));
        assert!((s.mean_commit_ms - 2.0).abs() < 1e-9, "{s:?}");
        assert!((s.samples_per_commit - 200.0).abs() < 1e-9, "{s:?}");
        assert!((s.requests_per_commit - 10.0).abs() < 1e-9, "{s:?}");
        assert!((s.cpu_percent - 90.0).abs() < 1e-9, "{s:?}");
        assert_eq!((s.server_unread_kb, s.load_tool_unread_kb), (2.0, 0.5));
        assert_eq!(s.rss_kb, 40_960, "the memory at the second's end");
        // No commit in a second: nothing divided by zero.
        let idle = by_second(&[reading(1.0, later.clone(), 1.0), reading(2.0, later, 1.0)]);
        assert_eq!((idle[0].commits, idle[0].mean_commit_ms), (0, 0.0));
    }

    #[test]
    fn the_stage_table_divides_the_window_by_the_samples_received_in_it() {
        let totals = |samples_in: f64, read_ns: f64| ServerTotals {
            samples_in,
            stage_ns: BTreeMap::from([("read".to_string(), read_ns)]),
            ..ServerTotals::default()
        };
        let mut readings = vec![
            reading(1.0, totals(0.0, 0.0), 0.0),
            reading(2.0, totals(1_000.0, 1e6), 0.5),
            reading(4.0, totals(101_000.0, 201e6), 1.5),
            reading(5.0, totals(102_000.0, 500e6), 9.0),
        ];
        readings[1].threads = ThreadCpu::from([("writer", 0.1)]);
        readings[2].threads = ThreadCpu::from([("writer", 0.3)]);
        // The window (1.5 s to 4.5 s) takes the readings at 2 and 4 s.
        let table = stage_table(&readings, 1.5, 4.5).expect("two readings with stages");
        assert_eq!((table.from_s, table.to_s, table.samples), (2.0, 4.0, 100_000));
        // 1 CPU second over 100,000 samples: 10 us each; read 200 ms: 2 us; writer 0.2 s: 2 us.
        assert!((table.server_cpu_us_per_sample - 10.0).abs() < 1e-9, "{table:?}");
        assert_eq!(table.stages[0].name, "read");
        assert!((table.stages[0].us_per_sample - 2.0).abs() < 1e-9, "{table:?}");
        assert!((table.threads[0].us_per_sample - 2.0).abs() < 1e-9, "{table:?}");
        // Without stage totals (no --stage-timing), no table.
        let plain: Vec<Reading> = readings
            .iter()
            .map(|r| Reading { totals: ServerTotals::default(), ..r.clone() })
            .collect();
        assert!(stage_table(&plain, 1.5, 4.5).is_none());
    }
}
