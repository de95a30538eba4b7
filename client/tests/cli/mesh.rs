//! `penmesh mesh`: the GLB, and the layered point cloud as PLY in either cloud.

use crate::helpers::{penmesh, run};

/// The points and normals of a binary PLY as `penmesh mesh --ply` writes it.
fn read_ply(bytes: &[u8]) -> Vec<[f32; 6]> {
    let end = b"end_header\n";
    let at = bytes.windows(end.len()).position(|w| w == end).expect("a PLY header") + end.len();
    let header = std::str::from_utf8(&bytes[..at]).unwrap();
    let count: usize = header
        .lines()
        .find_map(|l| l.strip_prefix("element vertex "))
        .expect("a vertex count")
        .parse()
        .unwrap();
    let body = &bytes[at..];
    assert_eq!(body.len(), count * 24, "six floats a point");
    body.chunks_exact(24)
        .map(|p| {
            std::array::from_fn(|i| f32::from_le_bytes(p[i * 4..i * 4 + 4].try_into().unwrap()))
        })
        .collect()
}

#[test]
fn the_ply_is_the_cloud_that_poisson_cloud_names() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("figure8.csv");
    let synth = run(penmesh().args(["synth", "figure8", "--out"]).arg(&csv));
    assert!(synth.status.success(), "{}", String::from_utf8_lossy(&synth.stderr));
    let mut clouds = Vec::new();
    for cloud in ["paper", "closed"] {
        let (glb, ply) =
            (dir.path().join(format!("{cloud}.glb")), dir.path().join(format!("{cloud}.ply")));
        let out = run(penmesh()
            .arg("mesh")
            .arg(&csv)
            .arg("--out")
            .arg(&glb)
            .arg("--ply")
            .arg(&ply)
            .args(["--poisson-cloud", cloud]));
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        assert!(std::fs::metadata(&glb).unwrap().len() > 0);
        clouds.push(read_ply(&std::fs::read(&ply).unwrap()));
    }
    let facing_up = |cloud: &[[f32; 6]]| cloud.iter().filter(|p| p[5] > 0.99).count();
    let (paper, closed) = (&clouds[0], &clouds[1]);
    // The paper's cloud is the sides only: no normal points up. The closed one adds the flat
    // top and bottom, on top of the same sides.
    assert_eq!(facing_up(paper), 0);
    assert!(facing_up(closed) > 0, "the closed cloud has a top");
    assert!(closed.len() > paper.len() + facing_up(closed));
    let top = closed.iter().filter(|p| p[5] > 0.99).map(|p| p[2]).fold(f32::MIN, f32::max);
    let side = paper.iter().map(|p| p[2]).fold(f32::MIN, f32::max);
    assert!((top - side).abs() < 1e-3, "the top lies on the side layers' highest: {top} {side}");
}
