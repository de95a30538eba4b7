//! `penmesh-lab eval --glb-sizes`: the one-stroke GLB of every stroke as the pipeline builds it
//! (ACUTS with the given setting, the smooth centreline checked against the raw samples, the
//! default brush and solid), in each encoding: median, 90th percentile and largest size, and
//! bytes per raw sample. What `docs/performance.md` reports for issue 26.

use super::table::{Table, fixed};
use super::*;
use penmesh::GlbEncoding;

/// Scales every stroke about its first sample so that the larger side of its bounding box is
/// `size` px (a stroke that is one point stays as it is).
pub(super) fn scale_strokes_to(data_set: &mut DataSet, size: f64) {
    for stroke in data_set.files.iter_mut().flat_map(|f| f.strokes.iter_mut()) {
        let Some(first) = stroke.first().copied() else { continue };
        let (lo, hi) = stroke
            .iter()
            .fold((first.pos(), first.pos()), |(lo, hi), s| (lo.min(s.pos()), hi.max(s.pos())));
        let extent = (hi - lo).max_element();
        if extent > 0.0 {
            let scale = size / extent;
            for s in stroke.iter_mut() {
                s.x = first.x + (s.x - first.x) * scale;
                s.y = first.y + (s.y - first.y) * scale;
            }
        }
    }
}

/// One encoding's sizes over one data set (or all of them).
#[derive(Debug, Clone, Serialize)]
pub struct GlbSizeRow {
    pub data: String,
    pub encoding: String,
    pub strokes: usize,
    pub raw_samples: usize,
    pub median_bytes: usize,
    pub p90_bytes: usize,
    pub max_bytes: usize,
    /// The raw sample count of the stroke with the largest GLB.
    pub max_stroke_samples: usize,
    /// All GLB bytes over all raw samples.
    pub bytes_per_sample: f64,
    /// The median over strokes of a stroke's GLB bytes per raw sample.
    pub median_bytes_per_sample: f64,
    pub median_vertices: usize,
    pub max_vertices: usize,
}

/// What is measured, by name: each encoding of the default solid, and the default encoding of
/// the solid that keeps every centreline point (solid tolerance 0), to show what leaving out
/// the points no pixel shows saves. Only the first three are written by `--glb-out`.
fn encodings() -> Vec<(&'static str, GlbOptions, SolidOptions)> {
    let every_point = SolidOptions::default().tolerance(0.0);
    [
        ("plain", GlbEncoding::Plain, SolidOptions::default()),
        ("quantised", GlbEncoding::Quantized, SolidOptions::default()),
        ("meshopt", GlbEncoding::Meshopt, SolidOptions::default()),
        ("meshopt, every centreline point", GlbEncoding::Meshopt, every_point),
    ]
    .into_iter()
    .map(|(name, encoding, solid)| (name, GlbOptions::default().encoding(encoding), solid))
    .collect()
}

/// How many of [`encodings`] `--glb-out` writes.
const WRITTEN: usize = 3;

/// Sizes of every stroke's GLB, per data set and over all of them; each GLB is written into
/// `out` too, when given.
pub(super) fn glb_size_rows(
    data_sets: &[DataSet],
    resample: f64,
    params: &AcutsParams,
    out: Option<&Path>,
) -> anyhow::Result<Vec<GlbSizeRow>> {
    if let Some(dir) = out {
        fs_err::create_dir_all(dir)?;
    }
    let brush = Brush::default();
    let bound = params.tolerance + resample;
    let centreline = penmesh::Centreline::Smooth(penmesh::SmoothOptions::default().bound(bound));
    let outline_options = OutlineOptions::default().centreline(centreline);
    let meta = GlbMeta { stroke: uuid::Uuid::nil(), author: "eval".into(), brush };
    // Per encoding: (bytes, raw samples, vertices) of each stroke, per data set.
    let mut all: Vec<Vec<(usize, usize, usize)>> = vec![Vec::new(); encodings().len()];
    let mut rows = Vec::new();
    for data_set in data_sets {
        let mut per_encoding: Vec<Vec<(usize, usize, usize)>> = vec![Vec::new(); encodings().len()];
        for (stroke_idx, samples) in data_set.strokes().enumerate() {
            let kept = penmesh::acuts(samples, resample, params).kept;
            let outline = penmesh::fitted_outline(samples, &kept, &brush, &outline_options)
                .expect("ACUTS keeps increasing indices of the stroke");
            for (k, (sizes, (name, options, solid))) in
                per_encoding.iter_mut().zip(encodings()).enumerate()
            {
                let mesh = penmesh::solid_mesh(&outline, &solid);
                let glb = penmesh::stroke_glb(&mesh, &meta, &options);
                sizes.push((glb.len(), samples.len(), mesh.stats().vertices));
                if let Some(dir) = out.filter(|_| k < WRITTEN) {
                    let file = format!("{}-{stroke_idx:03}.{name}.glb", data_set.name);
                    io::write_file(&dir.join(file), &glb)?;
                }
            }
        }
        for (k, sizes) in per_encoding.into_iter().enumerate() {
            rows.push(size_row(&data_set.name, encodings()[k].0, &sizes));
            all[k].extend(sizes);
        }
    }
    if data_sets.len() > 1 {
        for (k, sizes) in all.iter().enumerate() {
            rows.push(size_row("all", encodings()[k].0, sizes));
        }
    }
    Ok(rows)
}

fn size_row(data: &str, encoding: &str, sizes: &[(usize, usize, usize)]) -> GlbSizeRow {
    let quantile = |mut values: Vec<usize>, q: f64| -> usize {
        values.sort_unstable();
        let at = ((values.len() as f64 - 1.0) * q).round() as usize;
        values.get(at).copied().unwrap_or(0)
    };
    let bytes: Vec<usize> = sizes.iter().map(|s| s.0).collect();
    let (max_bytes, max_stroke_samples) = sizes.iter().map(|s| (s.0, s.1)).max().unwrap_or((0, 0));
    let raw_samples: usize = sizes.iter().map(|s| s.1).sum();
    let mut per_sample: Vec<f64> = sizes.iter().map(|s| s.0 as f64 / s.1.max(1) as f64).collect();
    per_sample.sort_by(f64::total_cmp);
    let vertices: Vec<usize> = sizes.iter().map(|s| s.2).collect();
    GlbSizeRow {
        data: data.to_owned(),
        encoding: encoding.to_owned(),
        strokes: sizes.len(),
        raw_samples,
        median_bytes: quantile(bytes.clone(), 0.5),
        p90_bytes: quantile(bytes.clone(), 0.9),
        max_bytes,
        max_stroke_samples,
        bytes_per_sample: bytes.iter().sum::<usize>() as f64 / raw_samples.max(1) as f64,
        median_bytes_per_sample: per_sample
            .get(per_sample.len().saturating_sub(1) / 2)
            .copied()
            .unwrap_or(0.0),
        median_vertices: quantile(vertices.clone(), 0.5),
        max_vertices: vertices.iter().copied().max().unwrap_or(0),
    }
}

/// The rows as one Markdown table.
pub(super) fn glb_size_markdown(rows: &[GlbSizeRow]) -> String {
    let mut table = Table::new(
        &[
            "data",
            "encoding",
            "strokes",
            "raw samples",
            "median B",
            "p90 B",
            "max B (its raw samples)",
            "B per raw sample",
            "median B per raw sample",
            "median vertices",
            "max vertices",
        ],
        2,
    );
    for r in rows {
        table.row(vec![
            r.data.to_string(),
            r.encoding.to_string(),
            r.strokes.to_string(),
            r.raw_samples.to_string(),
            r.median_bytes.to_string(),
            r.p90_bytes.to_string(),
            format!("{} ({})", r.max_bytes, r.max_stroke_samples),
            fixed(r.bytes_per_sample, 1),
            fixed(r.median_bytes_per_sample, 1),
            r.median_vertices.to_string(),
            r.max_vertices.to_string(),
        ]);
    }
    let mut md = String::new();
    table.write(&mut md);
    md
}
