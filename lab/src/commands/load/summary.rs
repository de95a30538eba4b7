//! What a run of `penmesh-lab load` reports: the `--json` summary and its table.

use hdrhistogram::Histogram;
use serde::{Deserialize, Serialize};

/// The whole summary of a run (the `--json` output).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Summary {
    pub label: Option<String>,
    /// `proxy` or `ceiling`.
    pub target: String,
    pub url: String,
    pub machine: Machine,
    pub settings: serde_json::Value,
    pub connections: Connections,
    pub samples: Samples,
    pub strokes: Strokes,
    pub throughput: Throughput,
    pub latency_ms: Latencies,
    pub errors: Errors,
    pub server: Option<ProcessStats>,
    pub load_tool: ProcessStats,
    /// The proxy second by second (not for the ceiling, which has no writer).
    #[serde(default)]
    pub server_by_second: Vec<ServerSecond>,
    /// Where the proxy's CPU went over the steady window, when it counted its stages
    /// (`--stage-timing`, passed with `--proxy-arg`).
    #[serde(default)]
    pub stages: Option<StageTable>,
}

/// Microseconds per sample received, by stage of the ingest path and by thread, between two
/// readings of the proxy inside the steady window.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct StageTable {
    /// The readings' times, seconds from the run's start.
    pub from_s: f64,
    pub to_s: f64,
    /// Samples the proxy received between them.
    pub samples: u64,
    /// The whole server's CPU per sample (from `/proc`).
    pub server_cpu_us_per_sample: f64,
    /// The stages (`proxy/src/stages.rs`); the connection task's stages are parts of
    /// `connection_task`.
    pub stages: Vec<StageRow>,
    /// The server's threads by what they do (from `/proc`).
    pub threads: Vec<StageRow>,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct StageRow {
    pub name: String,
    pub us_per_sample: f64,
}

/// The proxy in one second of a run: its writer's commits (from its `/metrics`) and its CPU.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct ServerSecond {
    /// Seconds from the run's start, at the end of this second.
    pub second: u64,
    pub commits: u64,
    pub mean_commit_ms: f64,
    pub samples_per_commit: f64,
    pub requests_per_commit: f64,
    /// Of one core; 0 when the run did not start the proxy.
    pub cpu_percent: f64,
    /// Bytes the load tool sent that the proxy has not read yet (its sockets' receive
    /// queues), at the end of this second, KiB.
    #[serde(default)]
    pub server_unread_kb: f64,
    /// Bytes the proxy wrote that the load tool has not read yet, KiB.
    #[serde(default)]
    pub load_tool_unread_kb: f64,
    /// The proxy's resident memory at the end of this second, KB (0 when not spawned): flat
    /// over a long run, or it grows with what it has taken in.
    #[serde(default)]
    pub rss_kb: u64,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Machine {
    pub cores: usize,
    pub loadavg_before: Option<String>,
    pub loadavg_after: Option<String>,
    pub started_at_unix_s: u64,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Connections {
    pub made: u64,
    pub failed: u64,
    /// Connections that ended before the run did (closed or broken).
    pub dropped: u64,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Samples {
    pub sent: u64,
    pub acknowledged: u64,
    /// Counted back through the HTTP API; `None` for the ceiling, which stores nothing.
    pub stored: Option<u64>,
    /// `sent - stored`.
    pub lost: Option<i64>,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Strokes {
    pub begun: u64,
    pub done: u64,
    /// Strokes the server lists as `done` (proxy only).
    pub stored_done: Option<u64>,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Throughput {
    /// The steady window: from the end of the ramp to the end of the drawing.
    pub window_s: f64,
    pub acked_per_s: f64,
    pub sent_per_s: f64,
    /// `clients * rate`: what the pens would send if they never lifted.
    pub offered_per_s: f64,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Latencies {
    pub sample_to_ack: Percentiles,
    /// Strokes the pen ended by itself.
    pub pen_up_to_stroke_done: Percentiles,
    /// Strokes still being drawn when the run ended, all lifted at once (a burst of every
    /// pen's `StrokeEnd` within one batch interval, which a real session does not make): kept
    /// apart so that it does not pass for the latency of ordinary pen-ups.
    #[serde(default)]
    pub run_end_to_stroke_done: Percentiles,
    /// Sample to `Ack` second by second (by the second each sample was sent in, from the
    /// run's start): where in the run the slow acknowledgements were.
    #[serde(default)]
    pub sample_to_ack_by_second: Vec<AcksInSecond>,
}

/// The samples sent in one second of a run and acknowledged.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct AcksInSecond {
    /// Seconds from the run's start.
    pub second: u64,
    pub acked: u64,
    /// Of those, acknowledged `SLOW_ACK_US` or more after they were sent (`pen.rs`).
    pub slow: u64,
    pub max_ms: f64,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Percentiles {
    pub count: u64,
    pub p50: f64,
    pub p95: f64,
    pub p99: f64,
    pub max: f64,
}

impl Percentiles {
    pub(super) fn of(hist: &Histogram<u64>) -> Percentiles {
        let ms = |us: u64| us as f64 / 1000.0;
        Percentiles {
            count: hist.len(),
            p50: ms(hist.value_at_quantile(0.50)),
            p95: ms(hist.value_at_quantile(0.95)),
            p99: ms(hist.value_at_quantile(0.99)),
            max: ms(hist.max()),
        }
    }
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Errors {
    pub count: u64,
    /// The first few distinct error texts.
    pub first: Vec<String>,
}

/// CPU and memory of a process, from /proc.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct ProcessStats {
    pub pid: u32,
    /// CPU time over the steady window, as a percentage of one core.
    pub cpu_percent: f64,
    /// CPU time over the whole run (ramp, drawing and drain), seconds.
    pub cpu_seconds: f64,
    pub rss_before_kb: u64,
    /// Resident memory with every connection open (at the end of the drawing).
    pub rss_connected_kb: u64,
    pub peak_rss_kb: u64,
    /// `(rss_connected - rss_before) / connections`, in KB.
    pub kb_per_connection: Option<f64>,
}

/// The summary as the table `penmesh-lab load` prints.
pub(super) fn print_table(s: &Summary) {
    let lat = &s.latency_ms;
    println!("target            {} at {}", s.target, s.url);
    println!(
        "pens              {} connected, {} failed, {} dropped",
        s.connections.made, s.connections.failed, s.connections.dropped
    );
    println!(
        "samples           sent {}, acknowledged {}, stored {}, lost {}",
        s.samples.sent,
        s.samples.acknowledged,
        s.samples.stored.map_or("-".into(), |v| v.to_string()),
        s.samples.lost.map_or("-".into(), |v| v.to_string()),
    );
    println!("strokes           begun {}, done {}", s.strokes.begun, s.strokes.done);
    println!(
        "throughput        {:.0} samples/s acknowledged ({:.0} sent, {:.0} offered) over {:.1} s",
        s.throughput.acked_per_s,
        s.throughput.sent_per_s,
        s.throughput.offered_per_s,
        s.throughput.window_s
    );
    for (name, p) in [
        ("sample -> Ack", &lat.sample_to_ack),
        ("pen-up -> Done", &lat.pen_up_to_stroke_done),
        ("run end -> Done", &lat.run_end_to_stroke_done),
    ] {
        println!(
            "{name:<18}p50 {:.2} ms, p95 {:.2} ms, p99 {:.2} ms, max {:.2} ms ({} measured)",
            p.p50, p.p95, p.p99, p.max, p.count
        );
    }
    if let Some(server) = &s.server {
        println!(
            "server            {:.0} % of a core, {:.1} CPU s, RSS {} KB before, {} KB connected, peak {} KB{}",
            server.cpu_percent,
            server.cpu_seconds,
            server.rss_before_kb,
            server.rss_connected_kb,
            server.peak_rss_kb,
            server
                .kb_per_connection
                .map_or(String::new(), |kb| format!(", {kb:.1} KB per connection")),
        );
    }
    println!(
        "load tool         {:.0} % of a core, peak RSS {} KB",
        s.load_tool.cpu_percent, s.load_tool.peak_rss_kb
    );
    println!(
        "machine           {} cores, load average {} before, {} after",
        s.machine.cores,
        s.machine.loadavg_before.as_deref().unwrap_or("?"),
        s.machine.loadavg_after.as_deref().unwrap_or("?")
    );
    if let Some(table) = &s.stages {
        println!(
            "stages            {:.2} us a sample in all, {} samples from {:.0} to {:.0} s",
            table.server_cpu_us_per_sample, table.samples, table.from_s, table.to_s
        );
        for row in table.stages.iter().chain(&table.threads) {
            println!("  {:<22}{:.2} us", row.name, row.us_per_sample);
        }
    }
    if s.errors.count > 0 {
        println!("errors            {}: {}", s.errors.count, s.errors.first.join("; "));
    }
}
