//! The mesh table (the paper's table 8) and the centreline table (straight against smooth).

use super::*;
use penmesh::GlbEncoding;

/// Table 8's row: the meshes of the simplified strokes against those of the originals.
#[derive(Debug, Clone, Serialize)]
pub struct MeshRow {
    pub algo: String,
    /// Samples the meshes are built from.
    pub samples: usize,
    pub vertices: usize,
    pub triangles: usize,
    /// GLB bytes (one file per signature).
    pub bytes: usize,
    pub time_ms: f64,
    /// Reductions against the unsimplified strokes' meshes, %.
    pub eta_vertices: f64,
    pub eta_triangles: f64,
    pub eta_bytes: f64,
    pub eta_time: f64,
}

/// Builds the LRPDP solid and one GLB per file from the original strokes and from each
/// algorithm's simplification.
pub(super) fn mesh_table(
    data_set: &DataSet,
    algos: &[Algo],
    kept_by_algo: &[Vec<Vec<usize>>],
    progress: &ProgressBar,
) -> Vec<MeshRow> {
    let brush = Brush::default();
    let build = |select: &dyn Fn(usize, &[Sample]) -> Vec<Sample>| {
        let (mut samples, mut vertices, mut triangles, mut bytes) = (0, 0, 0, 0);
        let mut seconds = 0.0;
        let mut stroke_idx = 0;
        for file in &data_set.files {
            let simplified: Vec<Vec<Sample>> = file
                .strokes
                .iter()
                .map(|s| {
                    stroke_idx += 1;
                    select(stroke_idx - 1, s)
                })
                .collect();
            let started = Instant::now();
            let meshes: Vec<penmesh::StrokeMesh> = simplified
                .iter()
                .map(|s| {
                    penmesh::stroke_mesh(
                        s,
                        &brush,
                        &OutlineOptions::default(),
                        &SolidOptions::default(),
                    )
                })
                .collect();
            let metas: Vec<GlbMeta> = meshes
                .iter()
                .map(|_| GlbMeta { stroke: uuid::Uuid::nil(), author: "eval".into(), brush })
                .collect();
            let strokes: Vec<GlbStroke<'_>> =
                meshes.iter().zip(&metas).map(|(mesh, meta)| GlbStroke { mesh, meta }).collect();
            // Plain, as docs/results.md reports them, whatever the default encoding.
            let glb =
                penmesh::strokes_glb(&strokes, &GlbOptions::default().encoding(GlbEncoding::Plain));
            seconds += started.elapsed().as_secs_f64();
            samples += simplified.iter().map(Vec::len).sum::<usize>();
            vertices += meshes.iter().map(|m| m.stats().vertices).sum::<usize>();
            triangles += meshes.iter().map(|m| m.stats().triangles).sum::<usize>();
            bytes += glb.len();
        }
        (samples, vertices, triangles, bytes, seconds * 1e3)
    };
    let reduction = |x: f64, reference: f64| {
        if reference > 0.0 { (1.0 - x / reference) * 100.0 } else { 0.0 }
    };
    let reference = build(&|_, s| s.to_vec());
    let row = |algo: &str, r: (usize, usize, usize, usize, f64)| MeshRow {
        algo: algo.to_string(),
        samples: r.0,
        vertices: r.1,
        triangles: r.2,
        bytes: r.3,
        time_ms: r.4,
        eta_vertices: reduction(r.1 as f64, reference.1 as f64),
        eta_triangles: reduction(r.2 as f64, reference.2 as f64),
        eta_bytes: reduction(r.3 as f64, reference.3 as f64),
        eta_time: reduction(r.4, reference.4),
    };
    let mut rows = vec![row("original", reference)];
    for (algo, kept) in algos.iter().zip(kept_by_algo) {
        rows.push(row(&algo.name, build(&|i, s| picked(s, &kept[i]))));
        progress.inc(data_set.n_strokes() as u64);
    }
    rows
}

/// Where the pen's path counts as smooth for the centreline table (the definition the fitted
/// centreline's corners follow): it turns by less than `SMOOTH_TURN_DEG` between the chords
/// `SMOOTH_REACH_PX` back and ahead along it.
pub(super) use penmesh::centreline::{
    SMOOTH_PATH_REACH as SMOOTH_REACH_PX, SMOOTH_PATH_TURN_DEG as SMOOTH_TURN_DEG,
};

/// How one centreline (straight or smooth) of ACUTS's simplification looks and how faithful it
/// is, over every stroke of a data set.
#[derive(Debug, Clone, Serialize)]
pub struct CentrelineRow {
    pub centreline: String,
    /// Tessellated centreline points (the retained samples, for the straight one).
    pub points: usize,
    /// Interior centreline points where the pen's path is smooth.
    pub smooth_points: usize,
    /// Of those, the share that turn by more than 10° and by more than 20°, %.
    pub over_10_deg: f64,
    pub over_20_deg: f64,
    /// Median and largest turn at those points, degrees.
    pub median_turn_deg: f64,
    pub max_turn_deg: f64,
    /// Largest distance of a raw sample to the centreline, px.
    pub raw_to_centreline: f64,
    /// Strokes with a raw sample further than the bound from the centreline.
    pub strokes_over_bound: usize,
    /// Largest distance of a point of the centreline to the raw path, px.
    pub centreline_to_raw: f64,
    pub vertices: usize,
    pub triangles: usize,
    /// Sum of the one-stroke GLB files, bytes.
    pub bytes: usize,
    /// The largest one-stroke GLB, bytes, and its raw sample count.
    pub max_stroke_bytes: usize,
    pub max_stroke_samples: usize,
    /// Outline + mesh + GLB, all strokes, ms.
    pub time_ms: f64,
}

/// Builds each stroke's outline from ACUTS's retained samples with the straight and the smooth
/// centreline, and measures them against the raw path.
pub(super) fn centreline_table(
    data_set: &DataSet,
    kept: &[Vec<usize>],
    bound: f64,
) -> Vec<CentrelineRow> {
    use penmesh::centreline::{directed_distance, polyline_distance, polyline_turns};
    let brush = Brush::default();
    let smooth = penmesh::Centreline::Smooth(penmesh::SmoothOptions::default().bound(bound));
    let kinds = [
        ("straight (paper)", penmesh::Centreline::Straight, false),
        ("smooth, retained samples only", smooth, false),
        ("smooth, checked against the raw samples", smooth, true),
    ];
    let raws: Vec<Vec<_>> =
        data_set.strokes().map(|s| s.iter().map(Sample::pos).collect()).collect();
    let smooth_flags: Vec<Vec<bool>> = raws
        .iter()
        .map(|raw| {
            penmesh::centreline::smooth_at_samples(
                raw,
                SMOOTH_REACH_PX,
                SMOOTH_TURN_DEG.to_radians(),
            )
        })
        .collect();
    let meta = GlbMeta { stroke: uuid::Uuid::nil(), author: "eval".into(), brush };
    kinds
        .into_iter()
        .map(|(name, kind, fitted)| {
            let options = OutlineOptions::default().centreline(kind);
            let mut row = CentrelineRow {
                centreline: name.to_owned(),
                points: 0,
                smooth_points: 0,
                over_10_deg: 0.0,
                over_20_deg: 0.0,
                median_turn_deg: 0.0,
                max_turn_deg: 0.0,
                raw_to_centreline: 0.0,
                strokes_over_bound: 0,
                centreline_to_raw: 0.0,
                vertices: 0,
                triangles: 0,
                bytes: 0,
                max_stroke_bytes: 0,
                max_stroke_samples: 0,
                time_ms: 0.0,
            };
            let mut turns_deg = Vec::new();
            for (((samples, kept), raw), smooth) in
                data_set.strokes().zip(kept).zip(&raws).zip(&smooth_flags)
            {
                let simplified = picked(samples, kept);
                let started = Instant::now();
                let plain = GlbOptions::default().encoding(GlbEncoding::Plain);
                let penmesh::MeshedStroke { outline, mesh, glb } = if fitted {
                    penmesh::mesh_drawn_stroke(samples, kept, &meta, &options, &plain)
                        .expect("the simplifiers keep increasing indices of the stroke")
                } else {
                    penmesh::mesh_retained_stroke(&simplified, &meta, &options, &plain)
                };
                row.time_ms += started.elapsed().as_secs_f64() * 1e3;
                let centres = &outline.centres;
                row.points += centres.len();
                row.vertices += mesh.stats().vertices;
                row.triangles += mesh.stats().triangles;
                row.bytes += glb.len();
                if glb.len() > row.max_stroke_bytes {
                    (row.max_stroke_bytes, row.max_stroke_samples) = (glb.len(), samples.len());
                }
                let to_centreline =
                    raw.iter().map(|q| polyline_distance(*q, centres)).fold(0.0, f64::max);
                row.raw_to_centreline = row.raw_to_centreline.max(to_centreline);
                row.strokes_over_bound += usize::from(to_centreline > bound + 1e-9);
                row.centreline_to_raw =
                    row.centreline_to_raw.max(directed_distance(centres, raw, 4));
                // The turn at each interior centreline point whose nearest raw sample is smooth.
                for (k, t) in polyline_turns(centres).into_iter().enumerate() {
                    let at = centres[k + 1];
                    let nearest = (0..raw.len()).min_by(|&a, &b| {
                        raw[a].distance_squared(at).total_cmp(&raw[b].distance_squared(at))
                    });
                    if nearest.is_some_and(|i| smooth[i]) {
                        turns_deg.push(t.to_degrees());
                    }
                }
            }
            turns_deg.sort_by(f64::total_cmp);
            let share = |limit: f64| {
                let over = turns_deg.iter().filter(|&&t| t > limit).count();
                over as f64 / turns_deg.len().max(1) as f64 * 100.0
            };
            row.smooth_points = turns_deg.len();
            row.over_10_deg = share(10.0);
            row.over_20_deg = share(20.0);
            row.median_turn_deg = turns_deg.get(turns_deg.len() / 2).copied().unwrap_or(0.0);
            row.max_turn_deg = turns_deg.last().copied().unwrap_or(0.0);
            row
        })
        .collect()
}
