//! One run: create the sessions, start every pen, watch the counters and the server's CPU over
//! the steady window, then count back what the proxy stored.

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use penmesh::protocol::{NewSession, StrokeList};
use serde::Deserialize;
use tokio::time::Instant;

use super::Plan;
use super::pen::{Counters, PenResult, Shared, pen, stroke_pool};
use super::procstat;
use super::summary::*;

/// The counters and CPU times at one edge of the steady window.
#[derive(Debug, Clone, Copy)]
struct WindowMark {
    /// Seconds since the pens started.
    at_s: f64,
    acked: u64,
    sent: u64,
    server_cpu_s: f64,
    own_cpu_s: f64,
}

/// How often the progress line and the `/proc` sampler look.
const SAMPLE_EVERY: Duration = Duration::from_millis(250);

/// `POST /v1/sessions`'s answer; the ceiling server adds that it stores nothing to count back.
#[derive(Debug, Deserialize)]
struct SessionReply {
    #[serde(flatten)]
    new: NewSession,
    #[serde(default)]
    ceiling: bool,
}

pub(super) async fn drive(plan: &Plan, base: &str, pid: Option<u32>) -> anyhow::Result<Summary> {
    let http = reqwest::Client::builder()
        .timeout(Duration::from_secs(60))
        .build()
        .context("building the HTTP client")?;
    let mut sessions = Vec::with_capacity(plan.sessions);
    for _ in 0..plan.sessions {
        let reply: SessionReply = penmesh_client::api::create_session(&http, base).await?;
        sessions.push(reply);
    }
    let is_ceiling = sessions.first().is_some_and(|s| s.ceiling);
    let pool = stroke_pool(plan)?;
    let (rss_before, _) = pid.map(procstat::memory_kb).unwrap_or((0, 0));
    let cpu_start = pid.map(procstat::cpu_seconds).unwrap_or(0.0);
    let self_cpu_start = procstat::cpu_seconds(std::process::id());

    let start = Instant::now() + Duration::from_millis(200);
    let shared = Arc::new(Shared {
        base_ws: base.replacen("http://", "ws://", 1),
        pool,
        start,
        ramp: Duration::from_secs_f64(plan.ramp_s),
        deadline: start + Duration::from_secs_f64(plan.duration_s),
        drain: Duration::from_secs(plan.drain_s),
        batch: Duration::from_millis(plan.batch_ms),
        pause: Duration::from_millis(plan.pause_ms),
        max_strokes: plan.strokes_per_client.unwrap_or(u64::MAX),
        idle: plan.idle,
        clients: plan.clients,
        counters: Counters::default(),
    });
    // The proxy's commits and CPU second by second (the ceiling has no writer to read).
    let (stop_reading, stop) = tokio::sync::oneshot::channel();
    let reader = (!is_ceiling).then(|| {
        tokio::spawn(super::readings::read_until(http.clone(), base.to_string(), pid, start, stop))
    });
    let mut pens = tokio::task::JoinSet::new();
    for pen_idx in 0..plan.clients {
        let session = &sessions[pen_idx % sessions.len()];
        let (session_id, token) = (session.new.session, session.new.token.clone());
        let shared = shared.clone();
        pens.spawn(async move { pen(pen_idx, session_id, token, shared).await });
    }

    // The progress line, the /proc sampler and the window snapshots.
    let progress = progress_line();
    let window_start = start + shared.ramp;
    let mut window: Option<WindowMark> = None;
    let mut window_end: Option<WindowMark> = None;
    let mut peak_rss = 0;
    let mut rss_connected = 0;
    let mut last = (Instant::now(), 0u64);
    let mut results = Vec::with_capacity(plan.clients);
    let mut ticker = tokio::time::interval(SAMPLE_EVERY);
    loop {
        tokio::select! {
            joined = pens.join_next() => match joined {
                Some(result) => results.push(result.context("a pen task panicked")?),
                None => break,
            },
            _ = ticker.tick() => {
                let now = Instant::now();
                let c = &shared.counters;
                let (acked, sent) = (c.acked.load(Ordering::Relaxed), c.sent.load(Ordering::Relaxed));
                if let Some(pid) = pid {
                    let (rss, hwm) = procstat::memory_kb(pid);
                    peak_rss = peak_rss.max(rss).max(hwm);
                }
                let snapshot = || WindowMark {
                    at_s: now.duration_since(start).as_secs_f64(),
                    acked,
                    sent,
                    server_cpu_s: pid.map(procstat::cpu_seconds).unwrap_or(0.0),
                    own_cpu_s: procstat::cpu_seconds(std::process::id()),
                };
                if window.is_none() && now >= window_start {
                    window = Some(snapshot());
                }
                if now >= window_start && now < shared.deadline {
                    // The last reading before the pens let go: every connection is open.
                    rss_connected = pid.map(|pid| procstat::memory_kb(pid).0).unwrap_or(0);
                }
                if window_end.is_none() && now >= shared.deadline {
                    window_end = Some(snapshot());
                }
                let rate = (acked - last.1) as f64 / now.duration_since(last.0).as_secs_f64();
                last = (now, acked);
                progress.set_message(format!(
                    "pens {}/{} (failed {}) · sent {} · acked {} · {:.0} samples/s · strokes done {} · errors {}",
                    c.connected.load(Ordering::Relaxed),
                    plan.clients,
                    c.failed.load(Ordering::Relaxed),
                    sent,
                    acked,
                    rate,
                    c.done.load(Ordering::Relaxed),
                    c.errors.load(Ordering::Relaxed),
                ));
            }
        }
    }
    progress.finish_and_clear();
    let _ = stop_reading.send(());
    let (server_by_second, stages) = match reader {
        Some(reader) => {
            let readings = reader.await.context("the /metrics reader")?;
            let window = (shared.ramp.as_secs_f64(), plan.duration_s);
            (
                super::readings::by_second(&readings),
                super::readings::stage_table(&readings, window.0, window.1),
            )
        }
        None => (Vec::new(), None),
    };

    let mut total = PenResult::new();
    let mut connections = Connections::default();
    let mut errors = Errors::default();
    for r in results {
        connections.made += u64::from(r.connected);
        connections.failed += u64::from(!r.connected);
        connections.dropped += u64::from(r.dropped);
        total.sent += r.sent;
        total.acked += r.acked;
        total.begun += r.begun;
        total.done += r.done;
        total.ack_us.add(&r.ack_us).expect("same histogram bounds");
        total.done_us.add(&r.done_us).expect("same histogram bounds");
        total.run_end_done_us.add(&r.run_end_done_us).expect("same histogram bounds");
        total.ack_seconds.merge(&r.ack_seconds);
        errors.count += r.errors.len() as u64;
        for e in r.errors {
            if errors.first.len() < 5 && !errors.first.contains(&e) {
                errors.first.push(e);
            }
        }
    }

    let (stored, stored_done) = if is_ceiling {
        (None, None)
    } else {
        let (points, done) = count_stored(&http, base, &sessions).await?;
        (Some(points), Some(done))
    };
    let end = Instant::now();
    let first = window.unwrap_or(WindowMark {
        at_s: 0.0,
        acked: 0,
        sent: 0,
        server_cpu_s: cpu_start,
        own_cpu_s: self_cpu_start,
    });
    let last = window_end.unwrap_or(WindowMark {
        at_s: end.duration_since(start).as_secs_f64(),
        acked: total.acked,
        sent: total.sent,
        server_cpu_s: pid.map(procstat::cpu_seconds).unwrap_or(0.0),
        own_cpu_s: procstat::cpu_seconds(std::process::id()),
    });
    let window_s = (last.at_s - first.at_s).max(1e-9);
    let server = pid.map(|pid| {
        let connected = connections.made.max(1) as f64;
        ProcessStats {
            pid,
            cpu_percent: 100.0 * (last.server_cpu_s - first.server_cpu_s) / window_s,
            cpu_seconds: procstat::cpu_seconds(pid) - cpu_start,
            rss_before_kb: rss_before,
            rss_connected_kb: rss_connected,
            peak_rss_kb: peak_rss,
            kb_per_connection: (rss_connected > 0)
                .then(|| (rss_connected as f64 - rss_before as f64) / connected),
        }
    });
    let (self_rss, self_hwm) = procstat::memory_kb(std::process::id());
    Ok(Summary {
        label: None,
        target: if is_ceiling { "ceiling" } else { "proxy" }.into(),
        url: base.to_string(),
        machine: Machine {
            cores: 0,
            loadavg_before: None,
            loadavg_after: None,
            started_at_unix_s: 0,
        },
        settings: serde_json::to_value(plan)?,
        connections,
        samples: Samples {
            sent: total.sent,
            acknowledged: total.acked,
            stored,
            lost: stored.map(|s| total.sent as i64 - s as i64),
        },
        strokes: Strokes { begun: total.begun, done: total.done, stored_done },
        throughput: Throughput {
            window_s,
            acked_per_s: (last.acked - first.acked) as f64 / window_s,
            sent_per_s: (last.sent - first.sent) as f64 / window_s,
            offered_per_s: plan.clients as f64 * plan.rate_hz,
        },
        latency_ms: Latencies {
            sample_to_ack: Percentiles::of(&total.ack_us),
            pen_up_to_stroke_done: Percentiles::of(&total.done_us),
            run_end_to_stroke_done: Percentiles::of(&total.run_end_done_us),
            sample_to_ack_by_second: total
                .ack_seconds
                .0
                .iter()
                .enumerate()
                .map(|(second, t)| AcksInSecond {
                    second: second as u64,
                    acked: t.acked,
                    slow: t.slow,
                    max_ms: t.max_us as f64 / 1000.0,
                })
                .collect(),
        },
        errors,
        server,
        load_tool: ProcessStats {
            pid: std::process::id(),
            cpu_percent: 100.0 * (last.own_cpu_s - first.own_cpu_s) / window_s,
            cpu_seconds: procstat::cpu_seconds(std::process::id()) - self_cpu_start,
            rss_before_kb: 0,
            rss_connected_kb: self_rss,
            peak_rss_kb: self_hwm,
            kb_per_connection: None,
        },
        server_by_second,
        stages,
    })
}

/// Sums `n_points` (and counts `done` strokes) over the run's sessions, 16 requests at a time.
async fn count_stored(
    http: &reqwest::Client,
    base: &str,
    sessions: &[SessionReply],
) -> anyhow::Result<(u64, u64)> {
    let mut points = 0;
    let mut done = 0;
    for chunk in sessions.chunks(16) {
        let replies = futures_util::future::join_all(chunk.iter().map(|s| async move {
            let url = format!("{base}{}", penmesh_client::api::session_strokes(s.new.session));
            let rows: StrokeList = http
                .get(&url)
                .bearer_auth(&s.new.token)
                .send()
                .await
                .and_then(|r| r.error_for_status())
                .with_context(|| format!("cannot count the stored samples: GET {url}"))?
                .json()
                .await
                .with_context(|| format!("GET {url}: not a stroke list"))?;
            anyhow::Ok(rows)
        }))
        .await;
        for rows in replies {
            for row in rows?.strokes {
                points += row.n_points;
                done += u64::from(row.status == penmesh::protocol::StrokeStatus::Done);
            }
        }
    }
    Ok((points, done))
}

fn progress_line() -> ProgressBar {
    let bar = ProgressBar::new_spinner().with_style(
        ProgressStyle::with_template("{spinner} {elapsed} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar.enable_steady_tick(Duration::from_millis(250));
    bar
}
