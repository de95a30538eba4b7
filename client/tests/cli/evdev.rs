//! A recorded tablet session (`tests/data/pen.evdev`: 64-bit `struct input_event` records of a
//! Wacom-like tablet with x in 0..21600, y in 0..13500, pressure in 0..2047) decodes into the
//! strokes that were drawn, and draws through the real path.

use penmesh::Sample;
use penmesh_client::input::{AxisRange, AxisRanges, EvdevDecoder, PenEvent, decode_events};

use crate::helpers::{
    Proxy, assert_stored_complete, expected_resampled, json_of, run, stored_strokes,
};

const RECORDING: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/pen.evdev");

fn ranges() -> AxisRanges {
    AxisRanges {
        x: AxisRange { min: 0, max: 21600 },
        y: AxisRange { min: 0, max: 13500 },
        pressure: Some(AxisRange { min: 0, max: 2047 }),
        canvas_width: 1920.0,
    }
}

/// The strokes of the recording, as the decoder sees them.
fn decoded_strokes() -> Vec<Vec<Sample>> {
    let events = decode_events(&std::fs::read(RECORDING).unwrap()).unwrap();
    let mut decoder = EvdevDecoder::new(ranges());
    let mut pen = Vec::new();
    for e in &events {
        decoder.push(e, &mut pen);
    }
    decoder.finish(&mut pen);
    let mut strokes: Vec<Vec<Sample>> = Vec::new();
    let mut down = false;
    for e in pen {
        match e {
            PenEvent::Down => {
                assert!(!down, "two downs in a row");
                down = true;
                strokes.push(Vec::new());
            }
            PenEvent::Sample(s) => {
                assert!(down, "a sample with the pen up");
                strokes.last_mut().unwrap().push(s);
            }
            PenEvent::Up => {
                assert!(down, "an up with the pen up");
                down = false;
            }
        }
    }
    assert!(!down);
    strokes
}

#[test]
fn recorded_events_decode_into_the_drawn_strokes() {
    let strokes = decoded_strokes();

    assert_eq!(strokes.iter().map(Vec::len).collect::<Vec<_>>(), vec![60, 40]);
    let scale = 1920.0 / 21600.0;
    // The line: from x = 2000 at 5 ms a report, pressure up and down again.
    let line = &strokes[0];
    assert_eq!(line[0], Sample::new(2000.0 * scale, 5000.0 * scale, 0.0, 300.0 / 2047.0));
    assert!((line[59].x - 7900.0 * scale).abs() < 1e-9);
    assert!((line[59].t - 295.0).abs() < 1e-9);
    assert!(line.iter().any(|s| s.p > 0.85));
    // The arc: radius 3000 units around (12000, 8000), constant pressure.
    let arc = &strokes[1];
    for s in arc {
        let r = ((s.x / scale - 12000.0).hypot(s.y / scale - 8000.0) - 3000.0).abs();
        assert!(r < 2.0, "{s:?} is off the arc by {r}");
        assert!((s.p - 1024.0 / 2047.0).abs() < 1e-12);
    }
    assert_eq!(arc[0].t, 0.0);
}

#[tokio::test]
async fn a_recorded_tablet_draws_through_the_proxy() {
    // Arrange
    let dir = tempfile::tempdir().unwrap();
    let proxy = Proxy::start(&dir.path().join("p.db"), 0);

    // Act
    let out = run(proxy
        .draw()
        .args(["--device", RECORDING, "--abs-x", "0:21600", "--abs-y", "0:13500"])
        .args(["--abs-pressure", "0:2047", "--name", "tablet"]));

    // Assert
    let summary = json_of(&out);
    let expected: Vec<Vec<Sample>> =
        decoded_strokes().iter().map(|s| expected_resampled(s)).collect();
    let stored = stored_strokes(&proxy.db).await;
    assert_eq!(stored.len(), 2);
    for (i, samples) in expected.iter().enumerate() {
        let id = summary["strokes"][i]["stroke"].as_str().unwrap();
        let s = stored.iter().find(|s| s.id == id).unwrap();
        assert_stored_complete(s);
        assert_eq!(&s.raw, samples);
        assert_eq!(
            summary["strokes"][i]["n_drawn"].as_u64().unwrap(),
            decoded_strokes()[i].len() as u64
        );
    }
}
