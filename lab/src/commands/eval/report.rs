//! The report: Markdown tables and SVG figures.

use super::table::{Table, fixed};
use super::*;

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
        algorithm_table(d).write(&mut md);
        if !d.stage1.is_empty() {
            let _ = writeln!(
                md,
                "\nStage 1 of the clients (ACUTS's setting; stage 2 over what stage 1 sent; \
                 errors over every drawn sample):\n"
            );
            stage1_table(d).write(&mut md);
        }
        let _ = writeln!(md, "\nMeshes (LRPDP solid, default brush, one GLB per file):\n");
        mesh_table(d).write(&mut md);
        if !d.centreline.is_empty() {
            let _ = writeln!(
                md,
                "\nCentreline of ACUTS's strokes (turns at centreline points where the pen's path \
                 turns < {SMOOTH_TURN_DEG}° within {SMOOTH_REACH_PX} px either side; distances \
                 against the raw samples; one GLB per stroke):\n"
            );
            centreline_table(d).write(&mut md);
        }
        if !d.sweep.is_empty() {
            let _ = writeln!(md, "\nSweep: points kept / optimal min-# at each bound B:\n");
            sweep_table(d).write(&mut md);
        }
        let _ = writeln!(md);
    }
    md
}

fn yes_no(yes: bool) -> String {
    (if yes { "yes" } else { "no" }).to_string()
}

fn algorithm_table(d: &DataSetReport) -> Table {
    let mut table = Table::new(
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
        table.row(vec![
            r.algo.clone(),
            yes_no(r.online),
            r.n.to_string(),
            r.c.to_string(),
            fixed(r.cr, 1),
            fixed(r.sed, 3),
            fixed(r.e_max, 3),
            fixed(r.e_max_mean, 3),
            fixed(r.e_l, 2),
            fixed(r.p_max, 3),
            fixed(r.time_ms, 2),
            fixed(r.ratio_at_bound, 3),
            fixed(r.ratio_at_reached, 3),
        ]);
    }
    table
}

fn stage1_table(d: &DataSetReport) -> Table {
    let mut table = Table::new(
        &["stage 1", "N", "sent", "sent %", "C", "C / opt at B", "E_max px", "P_max"],
        1,
    );
    for r in &d.stage1 {
        table.row(vec![
            r.stage1.clone(),
            r.n.to_string(),
            r.sent.to_string(),
            fixed(ratio(r.sent, r.n) * 100.0, 1),
            r.c.to_string(),
            fixed(r.ratio_at_bound, 3),
            fixed(r.e_max, 3),
            fixed(r.p_max, 3),
        ]);
    }
    table
}

fn mesh_table(d: &DataSetReport) -> Table {
    let mut table = Table::new(
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
        table.row(vec![
            r.algo.clone(),
            r.samples.to_string(),
            r.vertices.to_string(),
            r.triangles.to_string(),
            r.bytes.to_string(),
            fixed(r.time_ms, 2),
            fixed(r.eta_vertices, 1),
            fixed(r.eta_triangles, 1),
            fixed(r.eta_bytes, 1),
            fixed(r.eta_time, 1),
        ]);
    }
    table
}

fn centreline_table(d: &DataSetReport) -> Table {
    let mut table = Table::new(
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
        table.row(vec![
            r.centreline.clone(),
            r.points.to_string(),
            r.smooth_points.to_string(),
            fixed(r.over_10_deg, 1),
            fixed(r.over_20_deg, 1),
            fixed(r.median_turn_deg, 1),
            fixed(r.max_turn_deg, 1),
            fixed(r.raw_to_centreline, 3),
            r.strokes_over_bound.to_string(),
            fixed(r.centreline_to_raw, 3),
            r.vertices.to_string(),
            r.triangles.to_string(),
            r.bytes.to_string(),
            format!("{} ({})", r.max_stroke_bytes, r.max_stroke_samples),
            fixed(r.time_ms, 2),
        ]);
    }
    table
}

/// Points kept over optimal min-# at each bound, one column per algorithm of the sweep.
fn sweep_table(d: &DataSetReport) -> Table {
    let mut algos: Vec<&str> = Vec::new();
    for p in &d.sweep {
        if !algos.contains(&p.algo.as_str()) {
            algos.push(&p.algo);
        }
    }
    let head: Vec<&str> = std::iter::once("B px").chain(algos.iter().copied()).collect();
    let mut table = Table::new(&head, 0);
    for &b in &SWEEP_BOUNDS {
        let ratios = algos.iter().map(|a| {
            let p = d.sweep.iter().find(|p| p.bound == b && p.algo == *a);
            p.map_or(String::new(), |p| fixed(p.ratio_at_bound, 3))
        });
        table.row(std::iter::once(b.to_string()).chain(ratios).collect());
    }
    table
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
