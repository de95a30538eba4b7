//! `penmesh export` and `penmesh import` (issue 39): a session drawn with `penmesh draw`,
//! exported as GLB, imported into a new session and exported again gives the same pen data;
//! the print comes out as STL; a file that is no penmesh GLB is refused naming why.

use std::path::Path;

use penmesh::read_scene;
use serde_json::Value;

use crate::helpers::{Proxy, json_of, penmesh, run};

/// `penmesh export` of `session` into `out`, asserting success.
fn export(proxy: &Proxy, (session, token): (&str, &str), format: &str, out: &Path) {
    let result = run(penmesh()
        .args(["export", "--server", &proxy.url, "--session", session, "--token", token])
        .args(["--format", format, "--size-mm", "80", "--out"])
        .arg(out));
    assert!(result.status.success(), "{}", String::from_utf8_lossy(&result.stderr));
}

#[tokio::test]
async fn a_session_exported_imported_and_exported_again_keeps_its_pen_data() {
    let dir = tempfile::tempdir().unwrap();
    let proxy = Proxy::start(&dir.path().join("p.db"), 0);
    json_of(&run(proxy.draw().args(["--synth", "leaf", "--count", "2", "--name", "Ann"])));
    let first = (proxy.session.as_str(), proxy.token.as_str());
    let glb = dir.path().join("first.glb");
    export(&proxy, first, "glb", &glb);
    let exported = read_scene(&std::fs::read(&glb).unwrap()).unwrap();
    assert_eq!(exported.len(), 2);
    assert!(exported.iter().all(|s| s.extras.author.name == "Ann"));

    let created: Value = reqwest::Client::new()
        .post(format!("{}/v1/sessions", proxy.url))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let second = (created["session"].as_str().unwrap(), created["token"].as_str().unwrap());
    let imported = run(penmesh()
        .args(["import", "--server", &proxy.url, "--session", second.0, "--token", second.1])
        .args(["--name", "Imogen"])
        .arg(&glb));
    assert!(imported.status.success(), "{}", String::from_utf8_lossy(&imported.stderr));
    assert!(String::from_utf8_lossy(&imported.stdout).starts_with("imported 2 strokes"));
    let again_file = dir.path().join("again.glb");
    export(&proxy, second, "glb", &again_file);
    let again = read_scene(&std::fs::read(&again_file).unwrap()).unwrap();
    for original in &exported {
        let copy = again
            .iter()
            .find(|s| {
                s.extras.imported_from.as_ref().map(|f| f.stroke) == Some(original.extras.stroke)
            })
            .unwrap();
        assert_eq!(copy.extras.samples, original.extras.samples);
        assert_eq!(copy.extras.brush, original.extras.brush);
        assert_eq!(copy.placement, original.placement);
        assert_eq!(copy.extras.author.name, "Imogen");
    }

    // The print: a whole binary STL.
    let stl = dir.path().join("print.stl");
    export(&proxy, first, "stl", &stl);
    let bytes = std::fs::read(&stl).unwrap();
    let triangles = u32::from_le_bytes(bytes[80..84].try_into().unwrap()) as usize;
    assert!(triangles > 0);
    assert_eq!(bytes.len(), 84 + 50 * triangles);

    // Not a penmesh GLB: refused, naming why; nothing written for a refused export.
    let junk = dir.path().join("junk.glb");
    std::fs::write(&junk, b"solid nothing\nendsolid").unwrap();
    let refused = run(penmesh()
        .args(["import", "--server", &proxy.url, "--session", second.0, "--token", second.1])
        .arg(&junk));
    assert!(!refused.status.success());
    let why = String::from_utf8_lossy(&refused.stderr);
    assert!(why.contains("400") && why.contains("not a GLB"), "{why}");
    let missing = dir.path().join("none.obj");
    let refused = run(penmesh()
        .args(["export", "--server", &proxy.url, "--session", first.0, "--token", first.1])
        .args(["--format", "glb", "--size-mm=-3", "--out"])
        .arg(&missing));
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("size_mm"));
    assert!(!missing.exists());
}
