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

/// The lines of an export asked with its progress (`Accept: application/x-ndjson`); `query`
/// is the export's query string (`format=stl`, …).
async fn progress_lines(proxy: &Proxy, query: &str) -> Vec<Value> {
    let response = reqwest::Client::new()
        .get(format!("{}/v1/sessions/{}/export?{query}", proxy.url, proxy.session))
        .bearer_auth(&proxy.token)
        .header("accept", "application/x-ndjson")
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["content-type"], "application/x-ndjson");
    let text = response.text().await.unwrap();
    text.lines().map(|line| serde_json::from_str(line).unwrap()).collect()
}

#[tokio::test]
async fn a_long_export_tells_its_progress_and_a_failure_midway_writes_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let proxy = Proxy::start(&dir.path().join("p.db"), 0);
    json_of(&run(proxy.draw().args(["--synth", "scribble", "--count", "6"])));
    let session = (proxy.session.as_str(), proxy.token.as_str());

    // The progress lines: the stages in order, each step at or after the one before, the file
    // last; the file the same bytes as the plain GET's.
    let lines = progress_lines(&proxy, "format=stl").await;
    let (file, progress) = lines.split_last().unwrap();
    let stages = ["reading", "solids", "union"];
    let mut at = (0, 0);
    for line in progress {
        let step = &line["progress"];
        let stage = stages.iter().position(|s| *s == step["stage"]).unwrap_or_else(|| {
            panic!("a stage that is not one of {stages:?}: {line}");
        });
        let done = step["done"].as_u64().unwrap();
        assert!(done <= step["total"].as_u64().unwrap(), "{line}");
        assert!((stage, done) >= at, "{line} after {at:?}");
        at = (stage, done);
    }
    assert_eq!(at.0, 2, "the union was reported: {progress:?}");
    let file = &file["file"];
    assert_eq!(file["content_type"], "model/stl");
    assert_eq!(file["name"], format!("penmesh-{}.stl", proxy.session));
    use base64::Engine as _;
    let streamed =
        base64::engine::general_purpose::STANDARD.decode(file["base64"].as_str().unwrap()).unwrap();
    assert_eq!(file["bytes"], streamed.len());
    let plain = reqwest::Client::new()
        .get(format!("{}/v1/sessions/{}/export?format=stl", proxy.url, proxy.session))
        .bearer_auth(&proxy.token)
        .send()
        .await
        .unwrap();
    assert_eq!(plain.headers()["content-type"], "model/stl");
    assert_eq!(plain.bytes().await.unwrap().to_vec(), streamed, "the same print either way");
    // `penmesh export` reads the lines and writes that file.
    let out = dir.path().join("print.stl");
    let exported = run(penmesh()
        .args(["export", "--server", &proxy.url, "--session", session.0, "--token", session.1])
        .args(["--format", "stl", "--out"])
        .arg(&out));
    assert!(exported.status.success(), "{}", String::from_utf8_lossy(&exported.stderr));
    assert_eq!(std::fs::read(&out).unwrap(), streamed);

    // A stroke that loses its simplified samples fails the print once it has begun: an error
    // line, which `penmesh export` reports, writing nothing. Asked at other sizes: the print
    // at 100 mm is kept for its retry, keyed by the model as the API changes it (a finished
    // stroke's samples never change there; this damage is done in the database behind it).
    let url = format!("sqlite://{}", proxy.db.display());
    let pool = sqlx::SqlitePool::connect(&url).await.unwrap();
    sqlx::query("DELETE FROM simplified WHERE stroke_id = (SELECT MIN(stroke_id) FROM simplified)")
        .execute(&pool)
        .await
        .unwrap();
    let lines = progress_lines(&proxy, "format=stl&size_mm=90").await;
    let error = &lines.last().unwrap()["error"];
    assert_eq!(error["status"], 409, "{lines:?}");
    assert_eq!(error["code"], "conflict");
    assert!(error["message"].as_str().unwrap().contains("has no simplified samples"), "{error}");
    let failed_out = dir.path().join("failed.stl");
    let failed = run(penmesh()
        .args(["export", "--server", &proxy.url, "--session", session.0, "--token", session.1])
        .args(["--format", "stl", "--size-mm", "80", "--out"])
        .arg(&failed_out));
    assert!(!failed.status.success());
    let why = String::from_utf8_lossy(&failed.stderr);
    assert!(why.contains("409") && why.contains("has no simplified samples"), "{why}");
    assert!(!failed_out.exists(), "no file for a failed export");
}
