//! The binary on hostile input: absurd steps and horizons, an overflowing state, a
//! bad URDF number — each a one-line error on stderr and a failure exit, quickly, never a
//! `null` in the JSON or a run that does not end; a reader that closes the pipe early.

use crate::common;
use common::cli;
use std::time::Instant;

/// Runs the binary, expects a failure whose stderr has every `part`, in under 2 s.
fn refused(args: &[&str], parts: &[&str]) {
    let t = Instant::now();
    let out = cli().args(args).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    println!("{args:?}: {err}");
    assert!(!out.status.success(), "accepted: {args:?}");
    assert!(out.stdout.is_empty(), "printed JSON on failure");
    for p in parts {
        assert!(err.contains(p), "stderr {err:?} should mention {p:?}");
    }
    assert!(t.elapsed().as_secs_f64() < 2.0, "{:?}", t.elapsed());
}

#[test]
fn absurd_steps_and_horizons_are_refused_at_once() {
    let scene = ["predict", "--scene", "params/fourbar.yaml"];
    refused(
        &[&scene[..], &["--dt", "1e-300"]].concat(),
        &["integration steps", "max_steps"],
    );
    refused(
        &[&scene[..], &["--sample-period", "1e-300"]].concat(),
        &["output samples", "max_samples"],
    );
    refused(
        &[&scene[..], &["--horizon", "1e308"]].concat(),
        &["integration steps", "1e308"],
    );
}

#[test]
fn an_overflowing_state_is_refused_naming_the_file_and_entry() {
    let dir = std::env::temp_dir().join(format!("cd_hostile_cli_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let state = dir.join("state.json");
    std::fs::write(&state, r#"{"q": [0.5, 0, 0], "v": [1e308, 0, 0]}"#).unwrap();
    let s = state.display().to_string();
    refused(
        &["eval", "--scene", "params/fourbar.yaml", "--state", &s],
        &["state.json", "v: entry 0", "1e6"],
    );
}

/// A reader that stops early (`constraint_dynamics predict … | head`) ends the output: the tool
/// exits as it would have, without a panic on the closed pipe.
#[test]
fn a_reader_that_closes_the_pipe_ends_the_output_quietly() {
    use std::process::Stdio;
    // 1.4 MB of samples: more than a pipe holds, so the write meets the closed end whenever
    // the reader closes it.
    let args = [
        "predict",
        "--scene",
        "params/fourbar.yaml",
        "--horizon",
        "2",
        "--sample-period",
        "0.001",
    ];
    let mut child = (cli().args(args))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{:?}: {err}", out.status);
    assert!(!err.contains("panicked"), "{err}");
}
