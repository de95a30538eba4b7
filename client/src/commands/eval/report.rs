//! The report: Markdown tables and SVG figures.

use super::*;

/// A Markdown table's header and its alignment row: the first `n_left` columns left, the rest
/// right (numbers).
fn table_head(md: &mut String, columns: &[&str], n_left: usize) {
    let _ = writeln!(md, "| {} |", columns.join(" | "));
    let align: Vec<&str> =
        (0..columns.len()).map(|k| if k < n_left { "---" } else { "---:" }).collect();
    let _ = writeln!(md, "|{}|", align.join("|"));
}

/// The Markdown tables of the whole report.
pub fn markdown(report: &EvalReport) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "ACUTS: d_d = {} px, l_eps = {} px, angle = {}° ({}), {}; \
         guaranteed bound B = d_d + l_eps = {} px (the baselines' tolerance).\n",
        report.tolerance,
        report.resample,
        report.angle_deg,
        if report.angle_near_anchor { "near the anchor too" } else { "beyond d_d from the anchor" },
        match report.pressure {
            penmesh::PressureGate::Interpolation(d) => format!("pressure tolerance = {d}"),
            penmesh::PressureGate::Variance(v) => format!("pressure variance = {v}"),
        },
        report.bound
    );
    for d in &report.data_sets {
        let _ = writeln!(
            md,
            "### {} ({} files, {} strokes, {} samples)\n",
            d.name,
            d.n_files,
            d.n_strokes,
            d.rows.first().map_or(0, |r| r.n)
        );
        table_head(
            &mut md,
            &[
                "algorithm",
                "online",
                "N",
                "C",
                "CR %",
                "SED px",
                "E_max px",
                "mean E_max px",
                "E_l %",
                "P_max",
                "time ms",
                "C / opt at B",
                "C / opt at reached E_max",
            ],
            2,
        );
        for r in &d.rows {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {:.1} | {:.3} | {:.3} | {:.3} | {:.2} | {:.3} | {:.2} | {:.3} | {:.3} |",
                r.algo,
                if r.online { "yes" } else { "no" },
                r.n,
                r.c,
                r.cr,
                r.sed,
                r.e_max,
                r.e_max_mean,
                r.e_l,
                r.p_max,
                r.time_ms,
                r.ratio_at_bound,
                r.ratio_at_reached
            );
        }
        if !d.stage1.is_empty() {
            let _ = writeln!(
                md,
                "\nStage 1 of the clients (ACUTS's setting; stage 2 over what stage 1 sent; \
                 errors over every drawn sample):\n"
            );
            table_head(
                &mut md,
                &["stage 1", "N", "sent", "sent %", "C", "C / opt at B", "E_max px", "P_max"],
                1,
            );
            for r in &d.stage1 {
                let _ = writeln!(
                    md,
                    "| {} | {} | {} | {:.1} | {} | {:.3} | {:.3} | {:.3} |",
                    r.stage1,
                    r.n,
                    r.sent,
                    ratio(r.sent, r.n) * 100.0,
                    r.c,
                    r.ratio_at_bound,
                    r.e_max,
                    r.p_max
                );
            }
        }
        let _ = writeln!(md, "\nMeshes (LRPDP solid, default brush, one GLB per file):\n");
        table_head(
            &mut md,
            &[
                "from",
                "samples",
                "N' vertices",
                "F triangles",
                "S bytes",
                "T ms",
                "eta N' %",
                "eta F %",
                "eta S %",
                "eta T %",
            ],
            1,
        );
        for r in &d.mesh {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {} | {:.2} | {:.1} | {:.1} | {:.1} | {:.1} |",
                r.algo,
                r.samples,
                r.vertices,
                r.triangles,
                r.bytes,
                r.time_ms,
                r.eta_vertices,
                r.eta_triangles,
                r.eta_bytes,
                r.eta_time
            );
        }
        if !d.centreline.is_empty() {
            let _ = writeln!(
                md,
                "\nCentreline of ACUTS's strokes (turns at centreline points where the pen's path \
                 turns < {SMOOTH_TURN_DEG}° within {SMOOTH_REACH_PX} px either side; distances \
                 against the raw samples; one GLB per stroke):\n"
            );
            table_head(
                &mut md,
                &[
                    "centreline",
                    "points",
                    "smooth-path points",
                    "> 10° %",
                    "> 20° %",
                    "median turn °",
                    "max turn °",
                    "raw → centreline px",
                    "strokes over B",
                    "centreline → raw px",
                    "vertices",
                    "triangles",
                    "GLB bytes",
                    "largest GLB (raw samples)",
                    "T ms",
                ],
                1,
            );
            for r in &d.centreline {
                let _ = writeln!(
                    md,
                    "| {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.3} | {} | {:.3} | {} | {} | {} | {} ({}) | {:.2} |",
                    r.centreline,
                    r.points,
                    r.smooth_points,
                    r.over_10_deg,
                    r.over_20_deg,
                    r.median_turn_deg,
                    r.max_turn_deg,
                    r.raw_to_centreline,
                    r.strokes_over_bound,
                    r.centreline_to_raw,
                    r.vertices,
                    r.triangles,
                    r.bytes,
                    r.max_stroke_bytes,
                    r.max_stroke_samples,
                    r.time_ms
                );
            }
        }
        if !d.sweep.is_empty() {
            let algos: Vec<&str> =
                d.sweep.iter().map(|p| p.algo.as_str()).fold(Vec::new(), |mut v, a| {
                    if !v.contains(&a) {
                        v.push(a);
                    }
                    v
                });
            let _ = writeln!(md, "\nSweep: points kept / optimal min-# at each bound B:\n");
            let columns: Vec<&str> = std::iter::once("B px").chain(algos.iter().copied()).collect();
            table_head(&mut md, &columns, 0);
            for &b in &SWEEP_BOUNDS {
                let _ = write!(md, "| {b} |");
                for a in &algos {
                    let p = d.sweep.iter().find(|p| p.bound == b && p.algo == *a);
                    let _ = write!(
                        md,
                        " {} |",
                        p.map_or("".into(), |p| format!("{:.3}", p.ratio_at_bound))
                    );
                }
                let _ = writeln!(md);
            }
        }
        let _ = writeln!(md);
    }
    md
}

pub(super) fn write_plots(
    dir: &Path,
    data_set: &DataSet,
    report: &DataSetReport,
    algos: &[Algo],
    bound: f64,
) -> anyhow::Result<()> {
    fs_err::create_dir_all(dir)?;
    if !report.sweep.is_empty() {
        for (metric, label) in [("emax", "mean E_max per stroke (px)"), ("sed", "SED (px)")] {
            let path = dir.join(format!("rd_{metric}_{}.svg", report.name));
            rate_distortion_plot(&path, report, metric, label)?;
        }
    }
    // Figure 12: one signature (the first file) and each algorithm's simplification at B.
    if let Some(file) = data_set.files.first() {
        for algo in algos {
            let kept: Vec<Vec<usize>> = file.strokes.iter().map(|s| algo.run(s, bound)).collect();
            let pictures: Vec<SvgStroke<'_>> = file
                .strokes
                .iter()
                .zip(&kept)
                .map(|(s, k)| SvgStroke { original: s, kept: k })
                .collect();
            let path = dir.join(format!("overlay_{}_{}.svg", report.name, algo.name));
            io::write_file(&path, penmesh::strokes_svg(&pictures))?;
        }
    }
    Ok(())
}

/// Figure 11: points kept against `metric` for every algorithm of the sweep.
pub(super) fn rate_distortion_plot(
    path: &Path,
    report: &DataSetReport,
    metric: &str,
    label: &str,
) -> anyhow::Result<()> {
    let value = |p: &SweepPoint| if metric == "sed" { p.sed } else { p.e_max_mean };
    let mut series: Vec<Series> = Vec::new();
    for p in &report.sweep {
        let point = (p.kept_percent, value(p));
        match series.iter_mut().find(|s| s.name == p.algo) {
            Some(line) => line.points.push(point),
            None => series.push(Series { name: p.algo.clone(), points: vec![point] }),
        }
    }
    LineChart {
        caption: &format!("{}: points kept vs {label}", report.name),
        x_label: "points kept (% of N)",
        y_label: label,
        series: &series,
        log_y: false,
        legend: SeriesLabelPosition::UpperRight,
        size: (800, 560),
    }
    .write_svg(path)
}
