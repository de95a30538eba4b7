//! The summary of a drawing session: a table for people, JSON for programs.

use std::fmt::Write;

use serde::Serialize;

use crate::reconstruct::StrokeReport;

/// Sums over every stroke of a summary.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Totals {
    pub strokes: usize,
    pub n_drawn: usize,
    pub n_resampled: usize,
    pub n_retained: usize,
    /// Compression ratio over all strokes, %.
    pub cr: f64,
    pub vertices: u64,
    pub triangles: u64,
    pub glb_bytes: u64,
    pub latency_ms_mean: f64,
    pub latency_ms_max: f64,
}

impl Totals {
    pub fn of(reports: &[StrokeReport]) -> Totals {
        let mut t = Totals { strokes: reports.len(), ..Totals::default() };
        for r in reports {
            t.n_drawn += r.n_drawn;
            t.n_resampled += r.n_resampled;
            t.n_retained += r.n_retained;
            t.vertices += r.vertices;
            t.triangles += r.triangles;
            t.glb_bytes += r.glb_bytes;
            t.latency_ms_mean += r.latency_ms;
            t.latency_ms_max = t.latency_ms_max.max(r.latency_ms);
        }
        if !reports.is_empty() {
            t.latency_ms_mean /= reports.len() as f64;
        }
        if t.n_drawn > 0 {
            t.cr = (1.0 - t.n_retained as f64 / t.n_drawn as f64) * 100.0;
        }
        t
    }
}

/// The summary table, one line per stroke and a total line.
pub fn table(reports: &[StrokeReport]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{:<8}  {:<10} {:<12} {:>7} {:>9} {:>8} {:>6} {:>7} {:>8} {:>9} {:>9} {:>10}",
        "stroke",
        "person",
        "device",
        "drawn",
        "resampled",
        "retained",
        "CR %",
        "E_max",
        "vertices",
        "triangles",
        "GLB bytes",
        "latency ms"
    );
    for r in reports {
        let id = r.stroke.simple().to_string();
        let device = r.device.rsplit(':').next().unwrap_or(&r.device);
        let _ = writeln!(
            out,
            "{:<8}  {:<10} {:<12} {:>7} {:>9} {:>8} {:>6.1} {:>7.3} {:>8} {:>9} {:>9} {:>10.1}",
            &id[..8],
            truncate(&r.name, 10),
            truncate(device, 12),
            r.n_drawn,
            r.n_resampled,
            r.n_retained,
            r.cr,
            r.e_max,
            r.vertices,
            r.triangles,
            r.glb_bytes,
            r.latency_ms
        );
    }
    let t = Totals::of(reports);
    let _ = writeln!(
        out,
        "{:<8}  {:<10} {:<12} {:>7} {:>9} {:>8} {:>6.1} {:>7} {:>8} {:>9} {:>9} {:>10}",
        "total",
        format!("{} strokes", t.strokes),
        "",
        t.n_drawn,
        t.n_resampled,
        t.n_retained,
        t.cr,
        "",
        t.vertices,
        t.triangles,
        t.glb_bytes,
        format!("mean {:.1}", t.latency_ms_mean)
    );
    out
}

fn truncate(s: &str, n: usize) -> String {
    s.chars().take(n).collect()
}
