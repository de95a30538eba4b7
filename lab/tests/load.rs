//! Tests of `penmesh-lab load`: its argument checks, and short real runs against a spawned proxy and
//! the ceiling server (each a process of its own, as in a measurement).

use std::path::Path;
use std::process::{Command, Output};

fn penmesh(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_penmesh-lab")).args(args).output().expect("penmesh runs")
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

fn read_summary(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).expect("the summary was written"))
        .expect("the summary is JSON")
}

/// Refuses a target on another machine, naming what is allowed, before connecting anywhere.
#[test]
fn a_target_on_another_machine_is_refused() {
    for url in ["http://10.1.2.3:8080", "http://example.com", "ws://[2001:db8::1]:80"] {
        let output = penmesh(&["load", "--url", url, "--clients", "1", "--duration", "1"]);
        assert_eq!(output.status.code(), Some(1), "{url}");
        let err = stderr(&output);
        assert!(err.contains("only targets this machine"), "{url}: {err}");
        assert_eq!(err.lines().count(), 1, "{url}: {err}");
    }
}

/// Refuses zero pens, a ramp as long as the run, more sessions than pens, and settings for a
/// server the run does not start.
#[test]
fn settings_that_make_no_run_are_refused() {
    let base = ["load", "--url", "http://127.0.0.1:9", "--duration", "2"];
    let cases: [(&[&str], &str); 5] = [
        (&["--clients", "0"], "--clients 0"),
        (&["--clients", "2", "--ramp", "2"], "--ramp 2"),
        (&["--clients", "2", "--sessions", "3"], "--sessions 3"),
        (&["--clients", "1", "--proxy-arg=--commit-interval-ms=5"], "add --spawn-proxy"),
        (&["--clients", "1", "--ceiling-arg=--answer-task"], "add --spawn-ceiling"),
    ];
    for (extra, needle) in cases {
        let args: Vec<&str> = base.iter().chain(extra).copied().collect();
        let output = penmesh(&args);
        assert_eq!(output.status.code(), Some(1), "{args:?}");
        assert!(stderr(&output).contains(needle), "{args:?}: {}", stderr(&output));
    }
}

/// Five pens for two seconds against a spawned proxy: every sent sample is stored.
#[test]
fn a_short_run_against_a_spawned_proxy_loses_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("run.json");
    let output = penmesh(&[
        "load",
        "--spawn-proxy",
        "--clients",
        "5",
        "--sessions",
        "2",
        "--duration",
        "2",
        "--ramp",
        "0.5",
        "--pause-ms",
        "50",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let summary = read_summary(&json);
    assert_eq!(summary["target"], "proxy");
    assert_eq!(summary["connections"]["made"], 5);
    assert_eq!(summary["connections"]["failed"], 0);
    let sent = summary["samples"]["sent"].as_u64().unwrap();
    assert!(sent > 5 * 200, "2 s at 200 Hz per pen sends more than {sent}");
    assert_eq!(summary["samples"]["stored"].as_u64(), Some(sent));
    assert_eq!(summary["samples"]["acknowledged"].as_u64(), Some(sent));
    assert_eq!(summary["samples"]["lost"], 0);
    let strokes = &summary["strokes"];
    assert!(strokes["done"].as_u64().unwrap() >= 5, "{strokes}");
    assert_eq!(strokes["done"], strokes["begun"]);
    assert_eq!(strokes["stored_done"], strokes["done"]);
    assert!(summary["latency_ms"]["sample_to_ack"]["count"].as_u64() == Some(sent));
    // Every finished stroke's latency is counted once: ended by its pen, or by the run's end.
    let done_count = |key: &str| summary["latency_ms"][key]["count"].as_u64().unwrap();
    assert_eq!(
        done_count("pen_up_to_stroke_done") + done_count("run_end_to_stroke_done"),
        strokes["done"].as_u64().unwrap()
    );
    assert!(summary["server"]["peak_rss_kb"].as_u64().unwrap() > 0);
}

/// The ceiling answers the same protocol, in both of its ways of writing answers (at once, and
/// through a queue and a task of its own as the proxy does); there is nothing stored to count back.
#[test]
fn a_short_run_against_the_ceiling_is_acknowledged() {
    for extra in [None, Some("--ceiling-arg=--answer-task")] {
        let dir = tempfile::tempdir().unwrap();
        let json = dir.path().join("ceiling.json");
        let mut args =
            vec!["load", "--spawn-ceiling", "--clients", "3", "--duration", "1", "--json"];
        args.push(json.to_str().unwrap());
        args.extend(extra);
        let output = penmesh(&args);
        assert!(output.status.success(), "{extra:?}: {}", stderr(&output));
        let summary = read_summary(&json);
        assert_eq!(summary["target"], "ceiling");
        let sent = summary["samples"]["sent"].as_u64().unwrap();
        assert!(sent > 0, "{extra:?}");
        assert_eq!(summary["samples"]["acknowledged"].as_u64(), Some(sent), "{extra:?}");
        assert!(summary["samples"]["stored"].is_null());
    }
}
