//! `penmesh mesh`: simplify with ACUTS, build the LRPDP solid, write binary glTF.

use std::time::Instant;

use penmesh::{
    Brush, CloudOptions, GlbMeta, GlbOptions, GlbStroke, OutlineOptions, SolidOptions, StrokeMesh,
};

use crate::cli::MeshArgs;
use crate::io;

pub fn run(args: &MeshArgs) -> anyhow::Result<()> {
    let params = args.acuts.params()?;
    let brush = Brush {
        size: args.brush_size,
        pressure_response: args.pressure_response,
        ..Brush::default()
    };
    brush.validate().map_err(|e| anyhow::anyhow!("bad brush: {e}"))?;
    let strokes = io::read_strokes(&args.input)?;

    let started = Instant::now();
    let simplified: Vec<Vec<penmesh::Sample>> = strokes
        .iter()
        .map(|stroke| {
            let kept = penmesh::acuts(stroke.samples(), args.acuts.resample, &params).kept;
            kept.iter().map(|&i| stroke.samples()[i]).collect()
        })
        .collect();
    let simplify_time = started.elapsed();

    let started = Instant::now();
    let outlines: Vec<_> = simplified
        .iter()
        .map(|samples| penmesh::outline(samples, &brush, &OutlineOptions::default()))
        .collect();
    let meshes: Vec<StrokeMesh> =
        outlines.iter().map(|o| penmesh::solid_mesh(o, &SolidOptions::default())).collect();
    let metas: Vec<GlbMeta> = (0..meshes.len())
        .map(|_| GlbMeta { stroke: uuid::Uuid::new_v4(), author: "penmesh mesh".into(), brush })
        .collect();
    let glb_strokes: Vec<GlbStroke<'_>> =
        meshes.iter().zip(&metas).map(|(mesh, meta)| GlbStroke { mesh, meta }).collect();
    let glb = penmesh::strokes_glb(&glb_strokes, &GlbOptions::default().quantize(args.quantize));
    let build_time = started.elapsed();

    io::write_file(&args.out, &glb)?;
    if let Some(path) = &args.ply {
        let mut cloud = penmesh::PointCloud::default();
        for outline in &outlines {
            let part = penmesh::point_cloud(outline, &CloudOptions::default());
            cloud.points.extend(part.points);
            cloud.normals.extend(part.normals);
        }
        io::write_file(path, penmesh::point_cloud_ply(&cloud))?;
    }

    let vertices: usize = meshes.iter().map(|m| m.stats().vertices).sum();
    let triangles: usize = meshes.iter().map(|m| m.stats().triangles).sum();
    let n_input: usize = strokes.iter().map(|s| s.len()).sum();
    let n_kept: usize = simplified.iter().map(|s| s.len()).sum();
    println!(
        "{}: {} strokes, {n_input} samples -> {n_kept} kept; {vertices} vertices, {triangles} triangles, {} bytes{}",
        args.out.display(),
        strokes.len(),
        glb.len(),
        if args.quantize { " (quantised)" } else { "" },
    );
    println!(
        "simplify {:.3} ms, outline + mesh + GLB {:.3} ms",
        simplify_time.as_secs_f64() * 1e3,
        build_time.as_secs_f64() * 1e3
    );
    Ok(())
}
