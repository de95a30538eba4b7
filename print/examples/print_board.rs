//! Times the print of a board of generated strokes (docs/performance.md, "The print"):
//! `cargo run --release -p penmesh-print --example print_board -- [STROKES] [OUT.stl|OUT.3mf]`.
//! Strokes of every generator shape, 120 px, on a grid 100 px apart so neighbours overlap,
//! simplified by ACUTS (the indices the proxy keeps), on the identity placement.

use std::time::Instant;

use penmesh::{AcutsParams, Brush, DEFAULT_RESAMPLE_DISTANCE, GeneratorParams, Shape};
use penmesh_print::{IDENTITY, PrintOptions, PrintStroke, print_mesh, write_3mf, write_stl};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().map_or(Ok(1000), |a| a.parse())?;
    let out = args.next();
    let columns = (n as f64).sqrt().ceil() as usize;
    let strokes: Vec<PrintStroke> = (0..n)
        .map(|i| {
            let params = GeneratorParams {
                shape: Shape::ALL[i % Shape::ALL.len()],
                size: 120.0,
                seed: i as u64,
                ..GeneratorParams::default()
            };
            let stroke = penmesh::generate_stroke(&params)?;
            let (dx, dy) = ((i % columns) as f64 * 100.0, (i / columns) as f64 * 100.0);
            let raw: Vec<_> = stroke
                .samples()
                .iter()
                .map(|s| penmesh::Sample::new(s.x + dx, s.y + dy, s.t, s.p))
                .collect();
            let kept =
                penmesh::acuts(&raw, DEFAULT_RESAMPLE_DISTANCE, &AcutsParams::default()).kept;
            Ok(PrintStroke {
                raw,
                kept,
                brush: Brush::default(),
                placement: IDENTITY,
                solid: penmesh::Solid::ROD,
            })
        })
        .collect::<Result<_, penmesh::ParamError>>()?;
    let start = Instant::now();
    // When the last stroke's solid was made: the union's steps follow.
    let mut solids_s = 0.0;
    let mesh = print_mesh(&strokes, &PrintOptions::default(), &mut |done, _| {
        if done == n {
            solids_s = start.elapsed().as_secs_f64();
        }
    })?;
    let print_s = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let stl = write_stl(&mesh);
    let stl_s = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let threemf = write_3mf(&mesh)?;
    let threemf_s = start.elapsed().as_secs_f64();
    println!(
        "{n} strokes: print (solids and union) {print_s:.2} s (solids {solids_s:.2} s), STL {stl_s:.3} s ({} bytes), 3MF {threemf_s:.3} s ({} bytes), {} triangles, {:.0} mm³",
        stl.len(),
        threemf.len(),
        mesh.indices.len() / 3,
        mesh.volume()
    );
    println!(
        "open edges once welded by position (as an STL reader sees it): {}",
        mesh.open_edges()
    );
    if let Some(out) = out {
        std::fs::write(&out, if out.ends_with(".3mf") { threemf } else { stl })?;
    }
    Ok(())
}
