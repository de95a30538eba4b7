//! `penmesh-lab demo --fast`: everything it reports is in the database, with the counts it
//! printed.

use std::collections::HashMap;
use std::process::{Command, Output};

#[allow(dead_code)]
#[path = "../../client/tests/support/stored.rs"]
mod stored;
use stored::{assert_stored_complete, stored_strokes};

fn penmesh() -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_penmesh-lab"));
    cmd.env_remove("RUST_LOG");
    cmd
}

/// Runs to the end (the demo paces nothing with `--fast`; the test harness's own timeout
/// bounds it).
fn run(cmd: &mut Command) -> Output {
    cmd.output().expect("penmesh-lab runs")
}

/// The one JSON object a `--json` run prints, failing with its stderr otherwise.
fn json_of(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "penmesh-lab failed ({}): {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!("stdout is not one JSON object ({e}): {}", String::from_utf8_lossy(&out.stdout))
    })
}

#[tokio::test]
async fn demo_stores_every_stroke_and_mesh_it_reports() {
    // Arrange
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("demo.db");
    let out_dir = dir.path().join("glb");

    // Act
    let out = run(penmesh()
        .args(["demo", "--fast", "--json", "--people", "3", "--db"])
        .arg(&db)
        .arg("--out")
        .arg(&out_dir));

    // Assert
    let summary = json_of(&out);
    // The page of the session is printed first (on stderr with --json), its token in the fragment.
    let page = format!(
        "watch and draw: {}/s/{}#token=",
        summary["proxy"].as_str().unwrap(),
        summary["session"].as_str().unwrap()
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains(&page), "no `{page}` in stderr: {stderr}");
    assert!(summary.get("page").is_none(), "the page (with its token) only with --keep-serving");
    let reported = summary["strokes"].as_array().unwrap();
    assert_eq!(reported.len(), 3 * penmesh::Shape::ALL.len());
    assert_eq!(summary["totals"]["strokes"], reported.len());
    let stored: HashMap<String, _> =
        stored_strokes(&db).await.into_iter().map(|s| (s.id.clone(), s)).collect();
    assert_eq!(stored.len(), reported.len(), "the database holds other strokes than reported");
    for r in reported {
        let id = r["stroke"].as_str().unwrap();
        let s = &stored[id];
        assert_stored_complete(s);
        assert_eq!(s.session, summary["session"].as_str().unwrap());
        assert_eq!(s.n_points, r["n_resampled"].as_u64().unwrap(), "stroke {id}");
        assert_eq!(s.n_retained, r["n_retained"].as_u64().unwrap(), "stroke {id}");
        let (bytes, vertices, triangles) = s.mesh.unwrap();
        assert_eq!(bytes, r["glb_bytes"].as_u64().unwrap());
        assert_eq!(vertices, r["vertices"].as_u64().unwrap());
        assert_eq!(triangles, r["triangles"].as_u64().unwrap());
        assert!(r["exact"].as_bool().unwrap(), "stroke {id}: simplified differs from drawn");
        assert!(r["n_drawn"].as_u64().unwrap() >= s.n_points);
        let file = std::fs::read(r["glb_path"].as_str().unwrap()).unwrap();
        assert_eq!(
            Some(&file),
            s.glb.as_ref(),
            "stroke {id}: the GLB file differs from the stored one"
        );
    }
}
