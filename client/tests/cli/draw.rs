//! Two `penmesh draw` processes in one session: everything each drew is stored once.

use std::process::Stdio;

use penmesh::Shape;

use crate::helpers::{
    Proxy, assert_stored_complete, expected_resampled, json_of, stored_strokes, synth, wait,
};

#[tokio::test]
async fn two_drawers_in_one_session_store_everything_once() {
    // Arrange
    let dir = tempfile::tempdir().unwrap();
    let proxy = Proxy::start(&dir.path().join("p.db"), 0);
    let csv = dir.path().join("leaf.csv");
    let leaf = synth(Shape::Leaf, 350.0, 250.0, 7);
    std::fs::write(&csv, penmesh::write_csv(std::slice::from_ref(&leaf))).unwrap();

    // Act: both at once, one from the generator, one from a file.
    let first = proxy
        .draw()
        .args(["--synth", "figure8", "--count", "3", "--seed", "10", "--name", "one"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let second = proxy
        .draw()
        .arg("--input")
        .arg(&csv)
        .args(["--name", "two", "--batch-size", "5"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let first = json_of(&wait(first));
    let second = json_of(&wait(second));

    // Assert
    let mut expected = Vec::new();
    for (seed, r) in (10..).zip(first["strokes"].as_array().unwrap()) {
        let drawn = synth(
            Shape::Figure8,
            penmesh::DEFAULT_SPEED_PX_PER_S,
            penmesh::DEFAULT_SHAPE_SIZE_PX,
            seed,
        );
        expected
            .push((r["stroke"].as_str().unwrap().to_string(), expected_resampled(drawn.samples())));
    }
    let r = &second["strokes"][0];
    expected.push((r["stroke"].as_str().unwrap().to_string(), expected_resampled(leaf.samples())));
    assert_eq!(expected.len(), 4);

    let stored = stored_strokes(&proxy.db).await;
    assert_eq!(stored.len(), expected.len(), "every stroke stored exactly once");
    for (id, samples) in expected {
        let s =
            stored.iter().find(|s| s.id == id).unwrap_or_else(|| panic!("stroke {id} not stored"));
        assert_stored_complete(s);
        assert_eq!(s.session, proxy.session);
        assert_eq!(s.raw, samples, "stroke {id}: stored samples differ from the drawn ones");
    }
}
