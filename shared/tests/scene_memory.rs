//! What reading a scene back holds (issue 49, item 9): its samples, and one stroke's JSON tree
//! at a time, never a tree of the whole document (about seven times its text). Its own test
//! binary, one test: it reads the process's peak resident memory (Linux), reset first.

use penmesh::{
    Author, Brush, IDENTITY_MATRIX, SCENE_FORMAT_VERSION, Sample, SceneInput, SceneStroke,
    StrokeExtras, read_scene, scene_glb,
};
use uuid::Uuid;

/// `VmHWM` or `VmRSS` of this process, in bytes.
fn status_bytes(field: &str) -> usize {
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    let line = status.lines().find(|l| l.starts_with(field)).unwrap();
    let kb: usize = line.split_whitespace().nth(1).unwrap().parse().unwrap();
    kb * 1024
}

#[test]
fn reading_a_scene_holds_its_samples_not_a_tree_of_its_json() {
    let n = 100_000;
    let samples: Vec<Sample> = (0..n)
        .map(|i| {
            let f = i as f64;
            Sample::new(f * 0.0625, 100.0 + (f / 50.0).sin() * 40.0, f * 8.0, 0.5)
        })
        .collect();
    let extras = StrokeExtras {
        format: SCENE_FORMAT_VERSION,
        stroke: Uuid::new_v4(),
        author: Author { participant: Uuid::new_v4(), name: "Ada".into() },
        drawn_at: 1_800_000_000_000,
        brush: Brush::default(),
        samples,
        duplicate_of: None,
        imported_from: None,
        solid: penmesh::Solid::ROD,
    };
    // Ten strokes of 100,000 samples: 1M samples, about 40 MB of JSON.
    let strokes =
        (0..10).map(|_| SceneStroke { extras: &extras, placement: IDENTITY_MATRIX, mesh: None });
    let input = SceneInput { meshes: Vec::new(), strokes: strokes.collect(), size_mm: 100.0 };
    let glb = scene_glb(&input).unwrap();
    // The peak from here on (writing 5 to clear_refs resets VmHWM to the current RSS).
    std::fs::write("/proc/self/clear_refs", "5").unwrap();
    let before = status_bytes("VmRSS:");
    let read = read_scene(&glb).unwrap();
    let grew = status_bytes("VmHWM:").saturating_sub(before);
    assert_eq!(read.len(), 10);
    assert_eq!(read[9].extras, extras);
    let samples = 10 * n * std::mem::size_of::<Sample>();
    eprintln!("reading {} MB of scene grew the peak by {} MB", glb.len() >> 20, grew >> 20);
    assert!(
        grew < 3 * samples,
        "reading {} MB of scene grew the peak by {} MB (its samples: {} MB)",
        glb.len() >> 20,
        grew >> 20,
        samples >> 20
    );
}
