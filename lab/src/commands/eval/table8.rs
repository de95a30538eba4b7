//! `penmesh-lab eval --meshes`: the paper's table 8 in one run, with both meshers.
//!
//! For each curve (the paper's four classic contours from the generator at 300 px/s, one stroke
//! each, and each data set of real recordings, summed over its strokes), each simplifier and the
//! unsimplified stroke ("original"), and each mesher (the paper's screened Poisson of the layered
//! point cloud, and the direct solid): the vertices N', the triangles F, the GLB bytes S (one
//! GLB per stroke), the time T (outline, mesh and GLB), and the reductions against the BQS
//! Poisson mesh of the same curve as the paper's table 7 defines them, `(1 - x / x_BQS) × 100 %`.
//! Each mesh is measured against the mesh of the unsimplified stroke by the same mesher (the
//! paper's reference mesh): the Hausdorff distance both ways, the largest over the curve's
//! strokes. Both meshers build on the same outline (the default smooth centreline, checked
//! against the raw samples), so the meshers are the only difference between a curve's halves.

use super::table::{Table, fixed};
use super::*;
use penmesh::Outline;
use penmesh_client::commands::mesh::{Mesher, build_mesh};
use penmesh_client::mesh_distance::{Hausdorff, SAMPLE_STEP, SampledMesh};
use penmesh_client::poisson::PoissonOptions;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};

/// The simplifiers of `--meshes` unless `--algos` says otherwise: the paper's five (BQS, IDP as
/// Douglas–Peucker, ISWTC as the opening window, PSQUISH-E as SQUISH-E, ODPTS as DPTS), ACUTS
/// in the paper's setting and in the default one, and the optimum.
pub(super) const MESH_ALGOS: &str = "bqs,dp,window,squish-e,dpts,acuts-paper,acuts,optimal";
/// The paper's four classic contours (table 8), generated at its typical speed.
pub(super) const CURVES: [penmesh::Shape; 4] = [
    penmesh::Shape::Figure8,
    penmesh::Shape::Semicircles,
    penmesh::Shape::Chromosome,
    penmesh::Shape::Leaf,
];
const CURVE_SPEED_PX_PER_S: f64 = 300.0;
/// The row every `eta` is measured against.
const ETA_ALGO: &str = "bqs";
const ETA_MESHER: Mesher = Mesher::Poisson;
/// The Hausdorff columns' sampling step of the Poisson meshes, px: their balloons are thousands
/// of px² (the direct solids' step, [`SAMPLE_STEP`], would cost seconds a pair), and their
/// distances to the reference tens of px, so a 1-px bound on the error is small beside them.
pub(super) const POISSON_HAUSDORFF_STEP: f64 = 1.0;

/// One row of table 8: a curve, a simplifier (or "original") and a mesher.
#[derive(Debug, Clone, Serialize)]
pub struct MeshEvalRow {
    pub curve: String,
    pub algo: String,
    pub mesher: Mesher,
    /// Samples the meshes are built from (C; N for "original").
    pub samples: usize,
    pub vertices: usize,
    pub faces: usize,
    pub bytes: usize,
    /// The same meshes' GLB as plain floats (`GlbEncoding::Plain`, uncompressed as the paper's
    /// meshes are); `bytes` is the default encoding (quantised and meshopt-compressed).
    pub plain_bytes: usize,
    pub seconds: f64,
    /// Reductions against the BQS Poisson mesh of the same curve, % (`None` without `bqs`).
    pub eta_vertices: Option<f64>,
    pub eta_faces: Option<f64>,
    pub eta_bytes: Option<f64>,
    pub eta_seconds: Option<f64>,
    /// Against the same mesher's mesh of the unsimplified strokes, px, the largest over the
    /// curve's strokes (`None` when a mesh is empty).
    pub hausdorff: Option<Hausdorff>,
}

/// The curves of table 8: the generated contours, then the data sets given.
pub(super) fn curves(
    shapes: &[penmesh::Shape],
    mut data_sets: Vec<DataSet>,
) -> anyhow::Result<Vec<DataSet>> {
    let mut curves = Vec::with_capacity(shapes.len() + data_sets.len());
    for &shape in shapes {
        let params = penmesh::GeneratorParams {
            shape,
            speed: CURVE_SPEED_PX_PER_S,
            ..penmesh::GeneratorParams::default()
        };
        let stroke =
            penmesh::generate_stroke(&params).map_err(|e| anyhow::anyhow!("generator: {e}"))?;
        let file = DataFile { name: shape.name().into(), strokes: vec![stroke.into_samples()] };
        curves.push(DataSet { name: shape.name().into(), files: vec![file] });
    }
    curves.append(&mut data_sets);
    Ok(curves)
}

/// The meshers of each curve's rows, in the rows' order.
const MESHERS: [Mesher; 2] = [Mesher::Poisson, Mesher::Direct];

/// One stroke's mesh by one method and mesher, measured.
#[derive(Debug, Clone, Copy)]
struct StrokeMeasure {
    vertices: usize,
    faces: usize,
    bytes: usize,
    plain_bytes: usize,
    seconds: f64,
    /// Against the same mesher's mesh of the unsimplified stroke (`None`: a mesh is empty).
    hausdorff: Option<Hausdorff>,
}

/// One stroke's measures, by mesher then method, or why it could not be measured.
type StrokeResult = anyhow::Result<Vec<Vec<StrokeMeasure>>>;

/// Every row of table 8 for `curves`. The strokes of all curves are meshed by `jobs` threads at
/// once (each stroke by every method and mesher on one thread, so that only two of its meshes
/// are held at a time); the rows are the same whatever `jobs` is, but for the times.
pub(super) fn mesh_rows(
    curves: &[DataSet],
    algos: &[Algo],
    bound: f64,
    poisson: &PoissonOptions,
    jobs: usize,
    progress: &ProgressBar,
    phases: &PhaseTimes,
) -> anyhow::Result<Vec<MeshEvalRow>> {
    // For each curve, each method's retained samples of each stroke ("original" first: the
    // reference of the Hausdorff columns).
    let mut kept_by_curve: Vec<Vec<(String, Vec<Vec<usize>>)>> = Vec::with_capacity(curves.len());
    let mut units: Vec<(usize, usize)> = Vec::new();
    for (c, curve) in curves.iter().enumerate() {
        let strokes: Vec<&[Sample]> = curve.strokes().collect();
        let mut kept_by_algo: Vec<(String, Vec<Vec<usize>>)> =
            vec![("original".into(), strokes.iter().map(|s| (0..s.len()).collect()).collect())];
        for algo in algos {
            kept_by_algo
                .push((algo.name.clone(), strokes.iter().map(|s| algo.run(s, bound)).collect()));
        }
        kept_by_curve.push(kept_by_algo);
        units.extend((0..strokes.len()).map(|s| (c, s)));
    }
    let strokes: Vec<Vec<&[Sample]>> = curves.iter().map(|c| c.strokes().collect()).collect();
    // The longest strokes first (the most work, as a rule), so that the last ones to finish
    // are short and no thread is left alone with a long stroke at the end.
    let mut order: Vec<usize> = (0..units.len()).collect();
    order.sort_by_key(|&unit| std::cmp::Reverse(strokes[units[unit].0][units[unit].1].len()));

    let next = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let measured: Mutex<Vec<Option<StrokeResult>>> =
        Mutex::new(units.iter().map(|_| None).collect());
    std::thread::scope(|scope| {
        for _ in 0..jobs.max(1) {
            scope.spawn(|| {
                while let Some(&unit) = order.get(next.fetch_add(1, Ordering::Relaxed)) {
                    if failed.load(Ordering::Relaxed) {
                        break;
                    }
                    let (c, s) = units[unit];
                    progress.set_message(curves[c].name.clone());
                    let kept = kept_by_curve[c].iter().map(|(_, kept)| kept[s].as_slice());
                    let result =
                        measure_stroke(strokes[c][s], kept, bound, poisson, progress, phases);
                    failed.fetch_or(result.is_err(), Ordering::Relaxed);
                    measured.lock().unwrap_or_else(PoisonError::into_inner)[unit] = Some(result);
                }
            });
        }
    });
    let mut measured = measured.into_inner().unwrap_or_else(PoisonError::into_inner).into_iter();

    let mut rows = Vec::new();
    for (curve, kept_by_algo) in curves.iter().zip(&kept_by_curve) {
        let first_row = rows.len();
        for mesher in MESHERS {
            for (algo, kept) in kept_by_algo {
                rows.push(MeshEvalRow {
                    curve: curve.name.clone(),
                    algo: algo.clone(),
                    mesher,
                    samples: kept.iter().map(Vec::len).sum(),
                    vertices: 0,
                    faces: 0,
                    bytes: 0,
                    plain_bytes: 0,
                    seconds: 0.0,
                    eta_vertices: None,
                    eta_faces: None,
                    eta_bytes: None,
                    eta_seconds: None,
                    hausdorff: Some(Hausdorff { to_reference: 0.0, from_reference: 0.0 }),
                });
            }
        }
        for _ in 0..curve.n_strokes() {
            // A unit that never ran was stopped by another's error, which is returned.
            let stroke = match measured.next().flatten() {
                Some(result) => result?,
                None => continue,
            };
            for (row, m) in rows[first_row..].iter_mut().zip(stroke.iter().flatten()) {
                row.vertices += m.vertices;
                row.faces += m.faces;
                row.bytes += m.bytes;
                row.plain_bytes += m.plain_bytes;
                row.seconds += m.seconds;
                row.hausdorff = row.hausdorff.zip(m.hausdorff).map(|(a, b)| Hausdorff {
                    to_reference: a.to_reference.max(b.to_reference),
                    from_reference: a.from_reference.max(b.from_reference),
                });
            }
        }
        let curve_rows = &mut rows[first_row..];
        let reference = curve_rows
            .iter()
            .find(|r| r.algo == ETA_ALGO && r.mesher == ETA_MESHER)
            .map(|r| (r.vertices as f64, r.faces as f64, r.bytes as f64, r.seconds));
        if let Some((vertices, faces, bytes, seconds)) = reference {
            let eta = |x: f64, of: f64| (of > 0.0).then(|| (1.0 - x / of) * 100.0);
            for r in curve_rows {
                r.eta_vertices = eta(r.vertices as f64, vertices);
                r.eta_faces = eta(r.faces as f64, faces);
                r.eta_bytes = eta(r.bytes as f64, bytes);
                r.eta_seconds = eta(r.seconds, seconds);
            }
        }
    }
    if let Some(Some(Err(error))) = measured.find(|m| matches!(m, Some(Err(_)))) {
        return Err(error);
    }
    Ok(rows)
}

/// The Hausdorff columns' sampling step for `mesher`'s meshes, px.
fn hausdorff_step(mesher: Mesher) -> f64 {
    match mesher {
        Mesher::Poisson => POISSON_HAUSDORFF_STEP,
        Mesher::Direct => SAMPLE_STEP,
    }
}

/// What the run spends its time on, summed over its threads: the phases of each mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Phase {
    /// The checked smooth outline from the retained samples (both meshers).
    Outline,
    /// The layered cloud and PoissonRecon.
    Poisson,
    /// The direct solid.
    Direct,
    /// The GLB in the default encoding (quantised, meshopt-compressed).
    Glb,
    /// The plain-float GLB, for its bytes.
    GlbPlain,
    /// The Hausdorff columns: each mesh's tree and surface samples.
    HausdorffSamples,
    /// The Hausdorff columns: the two largest distances.
    HausdorffDistances,
}

impl Phase {
    const ALL: [Phase; 7] = [
        Phase::Outline,
        Phase::Poisson,
        Phase::Direct,
        Phase::Glb,
        Phase::GlbPlain,
        Phase::HausdorffSamples,
        Phase::HausdorffDistances,
    ];

    fn name(self) -> &'static str {
        match self {
            Phase::Outline => "outline",
            Phase::Poisson => "Poisson (cloud + PoissonRecon)",
            Phase::Direct => "direct solid",
            Phase::Glb => "GLB, compressed",
            Phase::GlbPlain => "GLB, plain floats",
            Phase::HausdorffSamples => "Hausdorff: trees and samples",
            Phase::HausdorffDistances => "Hausdorff: distances",
        }
    }
}

/// CPU time by [`Phase`] over a run (each thread's own, so other processes on a busy machine
/// do not count), and the meshes built and reused.
#[derive(Debug, Default)]
pub(super) struct PhaseTimes {
    nanos: [AtomicU64; 7],
    /// Meshes built, and meshes whose retained samples were another method's of the same
    /// stroke (so the same mesh: its measures reused, not built again).
    built: AtomicUsize,
    reused: AtomicUsize,
}

impl PhaseTimes {
    /// Runs `f`, adding the thread's CPU time in it to `phase`'s; also returns its wall time,
    /// s (the table's T).
    fn time<T>(&self, phase: Phase, f: impl FnOnce() -> T) -> (T, f64) {
        let (started, cpu) = (Instant::now(), cpu_time::ThreadTime::try_now().ok());
        let value = f();
        let elapsed = started.elapsed();
        let cpu = cpu.and_then(|cpu| cpu.try_elapsed().ok()).unwrap_or(elapsed);
        let index = Phase::ALL.iter().position(|&p| p == phase).unwrap_or_default();
        let nanos = u64::try_from(cpu.as_nanos()).unwrap_or(u64::MAX);
        self.nanos[index].fetch_add(nanos, Ordering::Relaxed);
        (value, elapsed.as_secs_f64())
    }

    /// Seconds by phase, in [`Phase::ALL`]'s order.
    pub(super) fn seconds(&self) -> Vec<(Phase, f64)> {
        Phase::ALL
            .iter()
            .zip(&self.nanos)
            .map(|(&phase, nanos)| (phase, nanos.load(Ordering::Relaxed) as f64 / 1e9))
            .collect()
    }

    /// Where the run's thread time went, as Markdown.
    pub(super) fn markdown(&self) -> String {
        let seconds = self.seconds();
        let total: f64 = seconds.iter().map(|(_, s)| s).sum();
        let mut md = String::new();
        let _ = writeln!(
            md,
            "Where the time went (CPU seconds of the threads, summed; {} meshes built, {} the same \
             retained samples as another method's of the stroke, so not built again):\n",
            self.built.load(Ordering::Relaxed),
            self.reused.load(Ordering::Relaxed)
        );
        let mut table = Table::new(&["phase", "s", "%"], 1);
        for (phase, s) in seconds {
            table.row(vec![
                phase.name().into(),
                fixed(s, 1),
                fixed(s / total.max(1e-9) * 100.0, 1),
            ]);
        }
        table.row(vec!["all phases".into(), fixed(total, 1), "100.0".into()]);
        table.write(&mut md);
        md
    }
}

/// One stroke by each mesher ([`MESHERS`]) and each method's retained samples (`kept`, the
/// unsimplified stroke first): one measure per mesher and method, in that order. Each method's
/// outline is made once for both meshers; retained samples equal to an earlier method's give
/// the same mesh, so its measures (its time too) are reused; the reference's tree and samples
/// are made once.
fn measure_stroke<'a>(
    samples: &[Sample],
    kept: impl Iterator<Item = &'a [usize]>,
    bound: f64,
    poisson: &PoissonOptions,
    progress: &ProgressBar,
    phases: &PhaseTimes,
) -> anyhow::Result<Vec<Vec<StrokeMeasure>>> {
    let kept: Vec<&[usize]> = kept.collect();
    let outlines = kept
        .iter()
        .map(|kept| {
            let (outline, seconds) =
                phases.time(Phase::Outline, || stroke_outline(samples, kept, bound));
            Ok((outline?, seconds))
        })
        .collect::<anyhow::Result<Vec<(Outline, f64)>>>()?;
    let mut by_mesher = Vec::with_capacity(MESHERS.len());
    for mesher in MESHERS {
        let step = hausdorff_step(mesher);
        let mut reference: Option<SampledMesh> = None;
        let mut measures: Vec<StrokeMeasure> = Vec::with_capacity(outlines.len());
        for (i, (outline, outline_s)) in outlines.iter().enumerate() {
            if let Some(same) = kept[..i].iter().position(|earlier| *earlier == kept[i]) {
                measures.push(measures[same]);
                phases.reused.fetch_add(1, Ordering::Relaxed);
                progress.inc(1);
                continue;
            }
            let (mesh, bytes, seconds) = stroke_mesh(outline, mesher, poisson, phases)?;
            let (sampled, _) =
                phases.time(Phase::HausdorffSamples, || SampledMesh::new(&mesh, step));
            let hausdorff = if i == 0 {
                reference = sampled;
                reference.as_ref().map(|_| Hausdorff { to_reference: 0.0, from_reference: 0.0 })
            } else {
                let distances = || sampled.zip(reference.as_ref()).map(|(m, r)| m.hausdorff_to(r));
                phases.time(Phase::HausdorffDistances, distances).0
            };
            let (plain_bytes, _) = phases.time(Phase::GlbPlain, || plain_glb_bytes(&mesh));
            measures.push(StrokeMeasure {
                vertices: mesh.stats().vertices,
                faces: mesh.stats().triangles,
                bytes,
                plain_bytes,
                seconds: outline_s + seconds,
                hausdorff,
            });
            phases.built.fetch_add(1, Ordering::Relaxed);
            progress.inc(1);
        }
        by_mesher.push(measures);
    }
    Ok(by_mesher)
}

/// The checked smooth outline of a stroke's retained samples, the one both meshers build on.
fn stroke_outline(samples: &[Sample], kept: &[usize], bound: f64) -> anyhow::Result<Outline> {
    let smooth = penmesh::Centreline::Smooth(penmesh::SmoothOptions::default().bound(bound));
    let options = OutlineOptions::default().centreline(smooth);
    Ok(penmesh::fitted_outline(samples, kept, &Brush::default(), &options)?)
}

/// One stroke's mesh from its outline by `mesher`: the mesh, its GLB's bytes and the seconds
/// from the outline to the GLB.
fn stroke_mesh(
    outline: &Outline,
    mesher: Mesher,
    poisson: &PoissonOptions,
    phases: &PhaseTimes,
) -> anyhow::Result<(StrokeMesh, usize, f64)> {
    let meta =
        GlbMeta { stroke: uuid::Uuid::nil(), author: "eval".into(), brush: Brush::default() };
    let mesher_phase = match mesher {
        Mesher::Poisson => Phase::Poisson,
        Mesher::Direct => Phase::Direct,
    };
    let (mesh, mesh_s) = phases.time(mesher_phase, || build_mesh(mesher, outline, poisson));
    let mesh = mesh?;
    let (glb, glb_s) =
        phases.time(Phase::Glb, || penmesh::stroke_glb(&mesh, &meta, &GlbOptions::default()));
    Ok((mesh, glb.len(), mesh_s + glb_s))
}

/// The bytes of `mesh`'s GLB written as plain floats (not timed: the table's time is the
/// default encoding's).
fn plain_glb_bytes(mesh: &StrokeMesh) -> usize {
    let meta =
        GlbMeta { stroke: uuid::Uuid::nil(), author: "eval".into(), brush: Brush::default() };
    let options = GlbOptions::default().encoding(penmesh::GlbEncoding::Plain);
    penmesh::stroke_glb(mesh, &meta, &options).len()
}

/// Table 8 as Markdown: one table per curve, as the paper's, both meshers; then how much larger
/// and slower the Poisson mesh is than the direct solid of the same samples.
pub(super) fn mesh_markdown(rows: &[MeshEvalRow], poisson: &PoissonOptions) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "Meshes (table 8): Poisson = screened Poisson (PoissonRecon) of the dense layered point \
         cloud ({:?}, depth {}), direct = the LRPDP solid; same outline for both; eta against the BQS \
         Poisson mesh of the curve; Hausdorff against the same mesher's mesh of the \
         unsimplified strokes (sampled every {} px on the Poisson meshes, {} px on the direct \
         solids: each value is at most that much below the true one).\n",
        poisson.cloud, poisson.depth, POISSON_HAUSDORFF_STEP, SAMPLE_STEP
    );
    let percent = |x: Option<f64>| x.map_or("-".to_string(), |x| format!("{x:.1}"));
    let mut curves: Vec<&str> = Vec::new();
    for r in rows {
        if !curves.contains(&r.curve.as_str()) {
            curves.push(&r.curve);
        }
    }
    for curve in &curves {
        let _ = writeln!(md, "#### {curve}\n");
        let mut table = Table::new(
            &[
                "method",
                "mesher",
                "C",
                "N'",
                "eta N' %",
                "F",
                "eta F %",
                "S MB",
                "eta S %",
                "T s",
                "eta T %",
                "H mesh→ref px",
                "H ref→mesh px",
                "S plain MB",
            ],
            2,
        );
        for r in rows.iter().filter(|r| r.curve == *curve) {
            let (to, from) = r.hausdorff.map_or(("-".into(), "-".into()), |h| {
                (fixed(h.to_reference, 3), fixed(h.from_reference, 3))
            });
            table.row(vec![
                r.algo.clone(),
                r.mesher.name().to_string(),
                r.samples.to_string(),
                r.vertices.to_string(),
                percent(r.eta_vertices),
                r.faces.to_string(),
                percent(r.eta_faces),
                fixed(r.bytes as f64 / 1e6, 3),
                percent(r.eta_bytes),
                fixed(r.seconds, 4),
                percent(r.eta_seconds),
                to,
                from,
                fixed(r.plain_bytes as f64 / 1e6, 3),
            ]);
        }
        table.write(&mut md);
        md.push('\n');
    }
    let _ = writeln!(
        md,
        "Poisson against the direct solid of the same samples (smallest ratio over the methods of \
         each curve, the unsimplified strokes included):\n"
    );
    let mut table = Table::new(&["curve", "vertices ×", "bytes ×", "time ×", "plain bytes ×"], 1);
    for curve in &curves {
        let mut ratios = [f64::INFINITY; 4];
        for direct in rows.iter().filter(|r| r.curve == *curve && r.mesher == Mesher::Direct) {
            let Some(poisson) = rows.iter().find(|r| {
                r.curve == *curve && r.algo == direct.algo && r.mesher == Mesher::Poisson
            }) else {
                continue;
            };
            let pairs = [
                (poisson.vertices as f64, direct.vertices as f64),
                (poisson.bytes as f64, direct.bytes as f64),
                (poisson.seconds, direct.seconds),
                (poisson.plain_bytes as f64, direct.plain_bytes as f64),
            ];
            for (ratio, (p, d)) in ratios.iter_mut().zip(pairs) {
                *ratio = ratio.min(p / d);
            }
        }
        table.row(std::iter::once(curve.to_string()).chain(ratios.map(|r| fixed(r, 0))).collect());
    }
    table.write(&mut md);
    md
}

#[cfg(all(test, feature = "poisson"))]
mod tests {
    use super::*;

    /// A one-stroke curve small enough for a shallow octree to mesh quickly: a 30-px leaf.
    fn small_leaf() -> DataSet {
        let params = penmesh::GeneratorParams {
            shape: penmesh::Shape::Leaf,
            size: 30.0,
            ..penmesh::GeneratorParams::default()
        };
        let stroke = penmesh::generate_stroke(&params).unwrap().into_samples();
        DataSet {
            name: "leaf".into(),
            files: vec![DataFile { name: "leaf".into(), strokes: vec![stroke] }],
        }
    }

    #[test]
    fn rows_have_the_fields_and_bqs_poisson_is_the_eta_reference() {
        // One small generated stroke (a shallow octree keeps Poisson quick): one row per method
        // (and "original") and mesher, with every field of the JSON, and eta 0 for BQS's
        // Poisson mesh, the reference of every eta.
        let curve = small_leaf();
        let algos = algos(&["bqs".into(), "acuts".into()], (0.0, AcutsParams::default())).unwrap();
        let poisson = PoissonOptions { depth: 6, ..PoissonOptions::default() };
        let rows = mesh_rows(
            &[curve],
            &algos,
            1.74,
            &poisson,
            2,
            &ProgressBar::hidden(),
            &PhaseTimes::default(),
        )
        .unwrap();
        let json = serde_json::to_value(&rows).unwrap();
        let rows = json.as_array().unwrap();
        assert_eq!(rows.len(), 3 * 2);
        let fields = [
            "curve",
            "algo",
            "mesher",
            "vertices",
            "faces",
            "bytes",
            "seconds",
            "eta_vertices",
            "eta_faces",
            "eta_bytes",
            "eta_seconds",
            "hausdorff",
        ];
        for row in rows {
            for field in fields {
                assert!(row.get(field).is_some(), "{field} missing from {row}");
            }
            assert!(row["vertices"].as_u64().unwrap() > 0 && row["bytes"].as_u64().unwrap() > 0);
            assert!(row["hausdorff"]["to_reference"].as_f64().unwrap() >= 0.0, "{row}");
        }
        let bqs = rows.iter().find(|r| r["algo"] == "bqs" && r["mesher"] == "poisson").unwrap();
        for eta in ["eta_vertices", "eta_faces", "eta_bytes", "eta_seconds"] {
            assert_eq!(bqs[eta].as_f64(), Some(0.0), "{bqs}");
        }
        let direct = rows.iter().find(|r| r["algo"] == "bqs" && r["mesher"] == "direct").unwrap();
        assert!(direct["eta_bytes"].as_f64().unwrap() > 0.0, "{direct}");
    }

    #[test]
    fn rows_are_the_same_on_one_thread_and_on_three() {
        // Three small strokes (two curves) meshed on one thread and on three at once: the same
        // rows but for the times, so PoissonRecon's calls from several threads do not disturb
        // one another and every stroke lands in its own curve's rows.
        let stroke = |shape, size| {
            let params = penmesh::GeneratorParams { shape, size, ..Default::default() };
            penmesh::generate_stroke(&params).unwrap().into_samples()
        };
        let curves = vec![
            DataSet {
                name: "two".into(),
                files: vec![DataFile {
                    name: "two".into(),
                    strokes: vec![
                        stroke(penmesh::Shape::Leaf, 30.0),
                        stroke(penmesh::Shape::Figure8, 40.0),
                    ],
                }],
            },
            DataSet {
                name: "one".into(),
                files: vec![DataFile {
                    name: "one".into(),
                    strokes: vec![stroke(penmesh::Shape::Semicircles, 30.0)],
                }],
            },
        ];
        let algos = algos(&["dp".into()], (0.0, AcutsParams::default())).unwrap();
        let poisson = PoissonOptions { depth: 6, ..PoissonOptions::default() };
        let run = |jobs| {
            let phases = PhaseTimes::default();
            let rows =
                mesh_rows(&curves, &algos, 1.74, &poisson, jobs, &ProgressBar::hidden(), &phases);
            let mut json = serde_json::to_value(rows.unwrap()).unwrap();
            for row in json.as_array_mut().unwrap() {
                for key in ["seconds", "eta_seconds"] {
                    row.as_object_mut().unwrap().remove(key);
                }
            }
            json
        };
        let (serial, parallel) = (run(1), run(3));
        assert_eq!(serial, parallel);
        assert_eq!(serial.as_array().unwrap().len(), 2 * 2 * 2);
        assert!(serial.as_array().unwrap().iter().all(|r| r["vertices"].as_u64().unwrap() > 0));
    }

    #[test]
    fn the_same_retained_samples_are_meshed_once_and_measured_alike() {
        // `window-d` and `bqs` are the same greedy window, so they keep the same samples: their
        // meshes are built once a mesher (the reuse is counted), and their rows are the same
        // but for the name; every phase took some CPU time.
        let curve = small_leaf();
        let names = ["bqs".to_string(), "window-d".to_string()];
        let algos = algos(&names, (0.0, AcutsParams::default())).unwrap();
        let poisson = PoissonOptions { depth: 5, ..PoissonOptions::default() };
        let phases = PhaseTimes::default();
        let rows = mesh_rows(&[curve], &algos, 1.74, &poisson, 1, &ProgressBar::hidden(), &phases)
            .unwrap();
        assert_eq!(phases.reused.load(Ordering::Relaxed), 2);
        assert_eq!(phases.built.load(Ordering::Relaxed), 4);
        for mesher in MESHERS {
            let row = |algo: &str| {
                let r = rows.iter().find(|r| r.algo == algo && r.mesher == mesher).unwrap();
                let mut json = serde_json::to_value(r).unwrap();
                json.as_object_mut().unwrap().remove("algo");
                json
            };
            assert_eq!(row("bqs"), row("window-d"), "{mesher:?}");
        }
        let seconds = phases.seconds();
        let poisson_s = seconds.iter().find(|(p, _)| *p == Phase::Poisson).unwrap().1;
        assert!(poisson_s > 0.0, "{seconds:?}");
        assert!(phases.markdown().contains("4 meshes built, 2 the same"));
    }
}
