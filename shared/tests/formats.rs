//! Stroke file readers and writers: the recorded data sets of `shared/data`, and each parser's
//! error cases.

use penmesh::data_sets::{DataSet, SIGCOMP2011_DUTCH, SVC2004};
use penmesh::{
    FormatError, Sample, Stroke, StrokeFormat, read_csv, read_hwr, read_json, read_strokes,
    read_svc2004, write_csv, write_json,
};

/// Every recording of a data set, read in place (`penmesh::data_sets`): (file name, raw text,
/// strokes), sorted.
fn read_set(set: DataSet) -> Vec<(String, String, Vec<Stroke>)> {
    set.read()
        .unwrap_or_else(|err| panic!("{err}"))
        .into_iter()
        .map(|recording| (recording.name(), recording.text, recording.strokes))
        .collect()
}

fn n_samples(strokes: &[Stroke]) -> usize {
    strokes.iter().map(Stroke::len).sum()
}

fn s(x: f64, y: f64, t: f64, p: f64) -> Sample {
    Sample::new(x, y, t, p)
}

/// Asserts that reading fails with a syntax error at `line`, `column` whose message has `text`.
fn check_syntax(result: Result<Vec<Stroke>, FormatError>, line: usize, column: usize, text: &str) {
    match result {
        Err(FormatError::Syntax { line: l, column: c, message }) => {
            assert_eq!((l, c), (line, column), "{message}");
            assert!(message.contains(text), "{message:?} should contain {text:?}");
        }
        other => panic!("expected a syntax error at {line}:{column}, got {other:?}"),
    }
}

/// Asserts that reading fails on a bad sample of `stroke`, at `index`, on `line`.
fn check_bad_sample(
    result: Result<Vec<Stroke>, FormatError>,
    stroke: usize,
    index: usize,
    line: Option<usize>,
    text: &str,
) {
    match result {
        Err(err @ FormatError::BadSample { .. }) => {
            let FormatError::BadSample { stroke: st, line: l, ref source } = err else {
                unreachable!()
            };
            assert_eq!((st, source.index(), l), (stroke, index, line), "{err}");
            assert!(err.to_string().contains(text), "{err} should contain {text:?}");
        }
        other => panic!("expected a bad sample, got {other:?}"),
    }
}

#[test]
// The 40 SVC2004 files hold 7,117 points in all, split into a plausible number of strokes.
fn svc2004_files_read_with_all_their_points() {
    let files = read_set(SVC2004);
    assert_eq!(files.len(), 40);
    let mut n_strokes = 0;
    for (name, text, strokes) in &files {
        let declared: usize = text.lines().next().unwrap().trim().parse().unwrap();
        assert_eq!(n_samples(strokes), declared, "{name}");
        assert!((1..=40).contains(&strokes.len()), "{name}: {} strokes", strokes.len());
        for stroke in strokes {
            let first = stroke.samples()[0];
            assert_eq!(first.t, 0.0, "{name}");
            assert!(stroke.samples().iter().all(|s| s.p > 0.0 && s.p <= 1.0), "{name}");
            // No gap above 20 ms stays inside a stroke.
            assert!(stroke.samples().windows(2).all(|w| w[1].t - w[0].t <= 20.0), "{name}");
        }
        n_strokes += strokes.len();
    }
    let total: usize = files.iter().map(|(_, _, strokes)| n_samples(strokes)).sum();
    assert_eq!(total, 7_117);
    println!("svc2004: 40 files, {total} samples, {n_strokes} strokes");
    assert!((80..=600).contains(&n_strokes), "{n_strokes} strokes");
}

#[test]
// The 15 Dutch files hold 18,843 samples, 6,077 of them hover samples that are dropped.
fn dutch_files_read_without_their_hover_samples() {
    let files = read_set(SIGCOMP2011_DUTCH);
    assert_eq!(files.len(), 15);
    let lines: usize = files.iter().map(|(_, text, _)| text.lines().count()).sum();
    assert_eq!(lines, 18_843);
    let total: usize = files.iter().map(|(_, _, strokes)| n_samples(strokes)).sum();
    assert_eq!(total, 18_843 - 6_077);
    let n_strokes: usize = files.iter().map(|(_, _, strokes)| strokes.len()).sum();
    for (name, _, strokes) in &files {
        assert!((1..=60).contains(&strokes.len()), "{name}: {} strokes", strokes.len());
        for stroke in strokes {
            assert!(stroke.samples().iter().all(|s| s.p > 0.0 && s.p <= 1.0), "{name}");
            let times: Vec<f64> = stroke.samples().iter().map(|s| s.t).collect();
            assert!(times.iter().enumerate().all(|(i, &t)| t == 5.0 * i as f64), "{name}");
        }
    }
    println!("sigcomp2011_dutch: 15 files, {total} pen-down samples, {n_strokes} strokes");
    assert!((15..=600).contains(&n_strokes), "{n_strokes} strokes");
}

#[test]
// The format is chosen by extension, case-insensitively, from a file name or a bare extension.
fn format_is_chosen_by_extension() {
    let cases = [
        ("a/b.csv", Some(StrokeFormat::Csv)),
        (".json", Some(StrokeFormat::Json)),
        ("U1S1.TXT", Some(StrokeFormat::Svc2004)),
        ("txt", Some(StrokeFormat::Svc2004)),
        ("001_01.hwr", Some(StrokeFormat::Hwr)),
        ("notes.md", None),
        ("", None),
    ];
    for (name, expected) in cases {
        assert_eq!(StrokeFormat::from_name(name), expected, "{name}");
    }
    let err = read_strokes("drawing.svg", "").unwrap_err();
    assert_eq!(err, FormatError::UnknownFormat { hint: "drawing.svg".into() });
    assert!(err.to_string().contains(".csv, .json"), "{err}");
}

#[test]
// A CSV with the plain header is one stroke; columns may come in any order; CRLF, quotes and
// blank lines are fine.
fn csv_reads_one_stroke() {
    let strokes = read_csv("x,y,t,p\r\n1,2,0,0.5\r\n3,4,6.5,1\r\n\r\n").unwrap();
    assert_eq!(strokes.len(), 1);
    assert_eq!(strokes[0].samples(), &[s(1.0, 2.0, 0.0, 0.5), s(3.0, 4.0, 6.5, 1.0)]);
    let strokes = read_csv("p, t, y, x\n0.5,0,2,1\n").unwrap();
    assert_eq!(strokes[0].samples(), &[s(1.0, 2.0, 0.0, 0.5)]);
    assert_eq!(read_csv("x,y,t,p\n").unwrap(), vec![]);
    // Quoted fields (as spreadsheets write them) and lines of blanks only.
    let strokes = read_csv("\"x\",\"y\",\"t\",\"p\"\n  \n\"1\",2,0,0.5\n").unwrap();
    assert_eq!(strokes[0].samples(), &[s(1.0, 2.0, 0.0, 0.5)]);
}

#[test]
// A `stroke` column splits the file wherever its value changes.
fn csv_stroke_column_splits_strokes() {
    let text = "stroke,x,y,t,p\na,0,0,0,0.5\na,1,0,5,0.5\nb,2,0,0,0.5\na,3,0,0,0.5\n";
    let strokes = read_csv(text).unwrap();
    let lens: Vec<usize> = strokes.iter().map(Stroke::len).collect();
    assert_eq!(lens, [2, 1, 1]);
}

#[test]
// CSV syntax errors name the line and the column.
fn csv_syntax_errors_name_line_and_column() {
    check_syntax(read_csv(""), 1, 1, "empty file");
    check_syntax(read_csv("x,y,t,q\n"), 1, 4, "unknown column \"q\"");
    check_syntax(read_csv("x,y,t,p,x\n"), 1, 5, "appears twice");
    check_syntax(read_csv("x,y,t\n"), 1, 1, "no \"p\" column");
    check_syntax(read_csv("x,y,t,p\n1,2,0,0.5\n1,2,zero,0.5\n"), 3, 3, "\"zero\" is not a number");
    check_syntax(read_csv("x,y,t,p\n1,2,0\n"), 2, 4, "expected 4 fields, found 3");
    check_syntax(read_csv("stroke,x,y,t,p\n,1,2,0,0.5\n"), 2, 1, "empty stroke label");
}

#[test]
// Bad CSV samples come back as the model's error, naming stroke, sample index and line.
fn csv_bad_samples_are_refused() {
    let head = "stroke,x,y,t,p\n0,0,0,0,0.5\n1,0,0,0,0.5\n";
    check_bad_sample(
        read_csv(&format!("{head}1,NaN,0,1,0.5\n")),
        1,
        1,
        Some(4),
        "x is not a finite",
    );
    check_bad_sample(read_csv(&format!("{head}1,0,0,1,1.5\n")), 1, 1, Some(4), "pressure 1.5");
    check_bad_sample(read_csv(&format!("{head}1,0,0,-1,0.5\n")), 1, 1, Some(4), "backwards");
    let err = read_csv(&format!("{head}1,0,0,-1,0.5\n")).unwrap_err();
    assert!(err.to_string().starts_with("stroke 1, sample 1: time goes backwards"), "{err}");
    assert!(err.to_string().ends_with("(line 4)"), "{err}");
}

#[test]
// The CSV writer's output reads back as the same strokes, with and without a stroke column.
fn csv_round_trips() {
    let a = Stroke::new(vec![s(0.1, 2.0, 0.0, 0.3), s(1.0 / 3.0, -4.5, 6.666666666666667, 1.0)])
        .unwrap();
    let b = Stroke::new(vec![s(7.0, 8.0, 0.0, 0.0)]).unwrap();
    for strokes in [vec![a.clone()], vec![a, b], vec![]] {
        let text = write_csv(&strokes);
        assert_eq!(read_csv(&text).unwrap(), strokes, "{text}");
    }
}

#[test]
// JSON accepts a stroke as a list or an object, a list of strokes, and {"strokes": [...]}.
fn json_reads_each_shape() {
    let one = vec![Stroke::new(vec![s(1.0, 2.0, 0.0, 0.5), s(3.0, 4.0, 5.0, 0.25)]).unwrap()];
    let cases = [
        ("[[1,2,0,0.5],[3,4,5,0.25]]", one.clone()),
        (r#"{"id": 7, "samples": [[1,2,0,0.5],[3,4,5,0.25]]}"#, one.clone()),
        ("[[[1,2,0,0.5],[3,4,5,0.25]]]", one.clone()),
        (r#"[{"samples": [[1,2,0,0.5],[3,4,5,0.25]]}]"#, one.clone()),
        (r#"{"strokes": [[[1,2,0,0.5],[3,4,5,0.25]]]}"#, one.clone()),
        ("[]", vec![]),
        ("[[], [[1,2,0,0.5],[3,4,5,0.25]]]", vec![Stroke::default(), one[0].clone()]),
    ];
    for (text, expected) in cases {
        assert_eq!(read_json(text).unwrap(), expected, "{text}");
    }
}

#[test]
// JSON errors name the line and column and what is wrong.
fn json_errors_name_line_and_column() {
    check_syntax(read_json("[[1,2,0,0.5],\n [3,4,5]]"), 2, 8, "expected 4 numbers, found 3");
    check_syntax(read_json("[[1,2,0,0.5],\n [3,4,5,\"a\"]]"), 2, 11, "invalid type: string");
    check_syntax(read_json("[[1,2,0,0.5], 3]"), 1, 16, "a list of samples holds a number");
    check_syntax(read_json("[[1,2,0,0.5]"), 1, 12, "EOF");
    check_syntax(read_json("[1,2,0,0.5]"), 1, 1, "single sample");
    check_syntax(read_json("{\"id\": 1}"), 1, 9, "needs a \"samples\" or a \"strokes\"");
    check_syntax(read_json("[[[[1,2,0,0.5]]]]"), 1, 17, "nested too deeply");
    check_syntax(read_json("{\"samples\": [[[1,2,0,0.5]]]}"), 1, 28, "found a list of strokes");
}

#[test]
// Bad JSON samples come back as the model's error with stroke and sample index.
fn json_bad_samples_are_refused() {
    let text = "[[[0,0,0,0.5]], [[0,0,0,0.5],[0,0,10,0.5],[0,0,5,0.5]]]";
    check_bad_sample(read_json(text), 1, 2, None, "stroke 1, sample 2: time goes backwards");
    check_bad_sample(read_json("[[0,0,0,-0.1]]"), 0, 0, None, "pressure -0.1 is outside");
}

#[test]
// The JSON writer's output reads back as the same strokes.
fn json_round_trips() {
    let a = Stroke::new(vec![s(0.1, 2.0, 0.0, 0.3), s(1.0 / 3.0, -4.5, 6.666666666666667, 1.0)])
        .unwrap();
    for strokes in [vec![a.clone()], vec![a.clone(), a], vec![]] {
        let text = write_json(&strokes);
        assert_eq!(read_json(&text).unwrap(), strokes, "{text}");
    }
}

#[test]
// SVC2004 splits at a gap over 20 ms and at button 0, and makes times relative per stroke.
fn svc2004_splits_strokes() {
    let text = "5\r\n\
        10 20 1000 0 0 0 1023\r\n\
        11 21 1010 1 0 0 512\r\n\
        12 22 1031 1 0 0 100\r\n\
        13 23 1040 0 0 0 100\r\n\
        14 24 1045 2 0 0 100\r\n";
    let strokes = read_svc2004(text).unwrap();
    let samples: Vec<&[Sample]> = strokes.iter().map(Stroke::samples).collect();
    assert_eq!(
        samples,
        [
            &[s(10.0, 20.0, 0.0, 1.0), s(11.0, 21.0, 10.0, 512.0 / 1023.0)][..],
            &[s(12.0, 22.0, 0.0, 100.0 / 1023.0)][..],
            &[s(13.0, 23.0, 0.0, 100.0 / 1023.0), s(14.0, 24.0, 5.0, 100.0 / 1023.0)][..],
        ]
    );
}

#[test]
// SVC2004 errors: count line, field count, numbers, count mismatch, bad samples with lines.
fn svc2004_errors() {
    check_syntax(read_svc2004(""), 1, 1, "empty file");
    check_syntax(read_svc2004("lots\n"), 1, 1, "expected the number of points");
    check_syntax(read_svc2004("1\n1 2 3 4 5 6\n"), 2, 7, "expected 7 numbers");
    check_syntax(read_svc2004("1\n1 2 3 4 5 6 7 8\n"), 2, 8, "found 8");
    check_syntax(read_svc2004("1\n1 2 3 x 5 6 7\n"), 2, 4, "\"x\" is not a number");
    check_syntax(read_svc2004("2\n1 2 3 1 5 6 7\n"), 2, 1, "declares 2 points but the file has 1");
    check_bad_sample(
        read_svc2004("2\n1 2 100 0 0 0 500\n1 2 100 1 0 0 1024\n"),
        0,
        1,
        Some(3),
        "pressure",
    );
    // A time that goes back is refused even when its button marks a new stroke.
    check_bad_sample(
        read_svc2004("2\n1 2 100 0 0 0 500\n1 2 90 0 0 0 500\n"),
        0,
        1,
        Some(3),
        "time goes backwards",
    );
}

#[test]
// .hwr drops zero-pressure hover samples, splits there, and times samples 5 ms apart.
fn hwr_splits_at_hover() {
    let text = "0 0 0\r\n1 1 100\r\n2 2 200\r\n3 3 0\r\n4 4 0\r\n5 5 1023\r\n6 6 0\r\n";
    let strokes = read_hwr(text).unwrap();
    let samples: Vec<&[Sample]> = strokes.iter().map(Stroke::samples).collect();
    assert_eq!(
        samples,
        [
            &[s(1.0, 1.0, 0.0, 100.0 / 1023.0), s(2.0, 2.0, 5.0, 200.0 / 1023.0)][..],
            &[s(5.0, 5.0, 0.0, 1.0)][..],
        ]
    );
    assert_eq!(read_hwr("").unwrap(), vec![]);
}

#[test]
// .hwr errors: field count and numbers by line and column; bad pressures as sample errors.
fn hwr_errors() {
    check_syntax(read_hwr("1 2 3\n1 2\n"), 2, 3, "expected 3 numbers (x y pressure), found 2");
    check_syntax(read_hwr("1 2 3\n1 2 3 4\n"), 2, 4, "found 4");
    check_syntax(read_hwr("1 2 p\n"), 1, 3, "\"p\" is not a number");
    check_bad_sample(read_hwr("1 2 0\n1 2 3\n1 2 2000\n"), 0, 1, Some(3), "pressure");
    check_bad_sample(read_hwr("1 2 0\n1 2 -5\n"), 0, 0, Some(2), "pressure");
    check_bad_sample(read_hwr("1 NaN 5\n"), 0, 0, Some(1), "y is not a finite");
}
