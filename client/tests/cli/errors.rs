//! Bad input and unreachable servers: one clear error line and a non-zero exit.

use std::process::Output;

use crate::helpers::{Proxy, penmesh, run};

const SESSION: &str = "00000000-0000-4000-8000-000000000001";

/// The run failed with exactly one line on stderr, containing every `needle`.
fn assert_one_error_line(out: &Output, needles: &[&str]) {
    assert!(!out.status.success(), "expected a failure");
    let stderr = String::from_utf8_lossy(&out.stderr);
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "expected one line, got: {stderr}");
    assert!(lines[0].starts_with("error: "), "{stderr}");
    for needle in needles {
        assert!(lines[0].contains(needle), "{needle:?} missing from: {stderr}");
    }
    assert!(out.stdout.is_empty(), "nothing on stdout: {}", String::from_utf8_lossy(&out.stdout));
}

fn draw_to(server: &str) -> std::process::Command {
    let mut cmd = penmesh();
    cmd.args(["draw", "--server", server, "--session", SESSION, "--token", "secret"]);
    cmd
}

#[test]
fn a_bad_input_file_names_the_file_and_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "x,y,t,p\n1,2,3,0.5\n4,5,oops,0.5\n").unwrap();

    let out = run(draw_to("http://127.0.0.1:9").arg("--input").arg(&bad));

    assert_one_error_line(&out, &["bad.csv", "line 3"]);
}

#[test]
fn a_missing_input_file_is_named() {
    let out = run(draw_to("http://127.0.0.1:9").args(["--input", "/nonexistent/strokes.csv"]));

    assert_one_error_line(&out, &["/nonexistent/strokes.csv"]);
}

#[test]
fn an_unreachable_server_is_named() {
    // Port 9 (discard) on the loopback: nothing listens there. The client keeps trying for
    // `--retry-for` seconds, as it does for a proxy that is starting or busy.
    let out = run(draw_to("http://127.0.0.1:9").args(["--synth", "leaf", "--retry-for", "1"]));

    assert_one_error_line(&out, &["could not reach the proxy within 1 s", "127.0.0.1:9"]);
}

#[test]
fn a_wrong_token_is_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let proxy = Proxy::start(&dir.path().join("p.db"), 0);

    let out = run(penmesh()
        .args(["draw", "--server", &proxy.url, "--session", &proxy.session])
        .args(["--token", "not-the-token", "--synth", "leaf"]));

    assert_one_error_line(&out, &["401", "token"]);
}

#[test]
fn a_server_url_without_scheme_is_refused() {
    let out = run(draw_to("127.0.0.1:9").args(["--synth", "leaf"]));

    assert_one_error_line(&out, &["http://"]);
}

#[test]
fn a_recorded_event_file_with_a_partial_record_or_no_ranges_fails_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("events.bin");
    std::fs::write(&file, [0u8; 30]).unwrap();

    let out = run(draw_to("http://127.0.0.1:9").arg("--device").arg(&file));

    assert_one_error_line(&out, &["events.bin", "--abs-x"]);
}
