//! `constraint_dynamics evaluate` from outside, on the recorded test logs (tests/data/logs/,
//! MuJoCo through tools/logs/make_logs.py), run from another directory: its figures agree with
//! a recomputation here from its own per-prediction records — the reference poses looked up
//! again in the bag by the mcap crate and CDR decoded into plain structs (not the tool's
//! reader), errors and NEES from the printed poses and covariances with a 3 × 3 inverse by
//! cofactors, the χ²(3) bounds from the closed-form CDF, percentiles by sorting — whatever the
//! threads it runs on, and bad input is a clear error, never a panic.

use crate::common::repo_dir;
use byteorder::LittleEndian;
use serde::Deserialize;
use serde_json::Value;

fn evaluate(args: &[&str]) -> (bool, Value, String) {
    let args: Vec<&str> = std::iter::once("evaluate")
        .chain(args.iter().copied())
        .collect();
    crate::run_cli(Some(&std::env::temp_dir()), &args)
}

#[derive(Deserialize)]
struct Stamp {
    sec: i32,
    nanosec: u32,
}
#[derive(Deserialize)]
struct Header {
    stamp: Stamp,
    _frame_id: String,
}
/// The head of a nav_msgs/Odometry in CDR: header, child frame, pose with covariance. The
/// 36 covariance entries are a fixed array: decoded as a tuple-like run of f64.
fn odometry(data: &[u8]) -> (i64, [f64; 3], [[f64; 3]; 3]) {
    #[derive(Deserialize)]
    struct Head {
        header: Header,
        _child: String,
        position: [f64; 3],
        orientation: [f64; 4],
        covariance: [[f64; 6]; 6],
    }
    let (h, _): (Head, usize) = cdr_encoding::from_bytes::<Head, LittleEndian>(&data[4..]).unwrap();
    let [x, y, z, w] = h.orientation;
    let yaw = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
    let idx = [0, 1, 5];
    let c = idx.map(|i| idx.map(|j| h.covariance[i][j]));
    let t = h.header.stamp.sec as i64 * 1_000_000_000 + h.header.stamp.nanosec as i64;
    (t, [h.position[0], h.position[1], yaw], c)
}

/// (stamp, (x, y, yaw), covariance) of every message of `topic` in the .mcap files under `bag`.
fn reference(bag: &std::path::Path, topic: &str) -> Vec<(i64, [f64; 3], [[f64; 3]; 3])> {
    let files: Vec<_> = match bag.is_dir() {
        true => std::fs::read_dir(bag)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
            .collect(),
        false => vec![bag.to_path_buf()],
    };
    let mut out = Vec::new();
    for f in files {
        let bytes = std::fs::read(f).unwrap();
        for m in mcap::MessageStream::new(&bytes).unwrap() {
            let m = m.unwrap();
            if m.channel.topic == topic {
                out.push(odometry(&m.data));
            }
        }
    }
    out
}

/// erf by its Maclaurin series (converges for all z used here, z ≤ 5).
fn erf(z: f64) -> f64 {
    let (mut term, mut sum, mut n) = (z, z, 0.0);
    while term.abs() > 1e-17 * sum.abs() {
        n += 1.0;
        term *= -z * z / n;
        sum += term / (2.0 * n + 1.0);
    }
    2.0 / std::f64::consts::PI.sqrt() * sum
}

/// P(χ²(3) ≤ x) = erf(√(x/2)) − √(2x/π) e^(−x/2).
fn chi2_3_cdf(x: f64) -> f64 {
    erf((x / 2.0).sqrt()) - (2.0 * x / std::f64::consts::PI).sqrt() * (-x / 2.0).exp()
}

/// The π at which the score test of a fraction p among m trials sits at its two-sided 5 %
/// bound: the roots of (1 + z²/m) π² − (2p + z²/m) π + p² = 0, z the normal 0.975 quantile
/// (erf by bisection).
fn score_interval(p: f64, m: f64) -> [f64; 2] {
    let (mut lo, mut hi) = (0.0, 5.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if 0.5 * (1.0 + erf(mid / 2f64.sqrt())) < 0.975 {
            lo = mid
        } else {
            hi = mid
        }
    }
    let z2 = (0.5 * (lo + hi)).powi(2);
    let (a, b, c) = (1.0 + z2 / m, -(2.0 * p + z2 / m), p * p);
    let d = (b * b - 4.0 * a * c).max(0.0).sqrt();
    [
        ((-b - d) / (2.0 * a)).max(0.0),
        ((-b + d) / (2.0 * a)).min(1.0),
    ]
}

fn chi2_3_quantile(p: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 50.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if chi2_3_cdf(mid) < p {
            lo = mid
        } else {
            hi = mid
        }
    }
    0.5 * (lo + hi)
}

fn nees(e: [f64; 3], s: [[f64; 3]; 3]) -> f64 {
    let c = |i: usize, j: usize| {
        let rows: Vec<usize> = (0..3).filter(|&a| a != i).collect();
        let cols: Vec<usize> = (0..3).filter(|&b| b != j).collect();
        let m =
            s[rows[0]][cols[0]] * s[rows[1]][cols[1]] - s[rows[0]][cols[1]] * s[rows[1]][cols[0]];
        if (i + j).is_multiple_of(2) { m } else { -m }
    };
    let det: f64 = (0..3).map(|j| s[0][j] * c(0, j)).sum();
    // S⁻¹ = adj(S) / det, adj(S)[i][j] = cofactor(j, i).
    (0..3)
        .flat_map(|i| (0..3).map(move |j| (i, j)))
        .map(|(i, j)| e[i] * c(j, i) / det * e[j])
        .sum()
}

fn percentile(v: &[f64], p: f64) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let r = p / 100.0 * (s.len() - 1) as f64;
    let (i, f) = (r.floor() as usize, r.fract());
    if i + 1 < s.len() {
        s[i] * (1.0 - f) + s[i + 1] * f
    } else {
        s[i]
    }
}

fn close(what: &str, got: f64, want: f64, tol: f64) {
    assert!(
        (got - want).abs() <= tol * want.abs().max(1.0),
        "{what}: printed {got}, recomputed {want}"
    );
}

#[test]
fn figures_agree_with_a_recomputation_from_the_bag() {
    let logs = repo_dir().join("tests/data/logs");
    let scene = repo_dir().join("params/suite_mobile_manipulator.yaml");
    let (b50, b95) = (chi2_3_quantile(0.5), chi2_3_quantile(0.95));
    for (bag, topic) in [
        ("validation_steps", "/ground_truth/odom"),
        ("validation_smooth.mcap", "/odom"),
    ] {
        let path = logs.join(bag);
        let mut args = vec![
            "--scene",
            scene.to_str().unwrap(),
            "--bag",
            path.to_str().unwrap(),
            "--records",
        ];
        if topic != "/odom" {
            args.extend(["--truth-topic", topic]);
        }
        let (ok, out, err) = evaluate(&args);
        assert!(ok, "{bag}: {err}");
        // The starts are replayed on every core; one thread or three give the same records.
        for threads in ["1", "3"] {
            let (ok, again, err) = evaluate(&[&args[..], &["--threads", threads]].concat());
            assert!(ok, "{bag}: {err}");
            assert_eq!(
                again["records"], out["records"],
                "{bag}: --threads {threads}"
            );
        }
        let refs = reference(&path, topic);
        let origin = refs.iter().map(|r| r.0).min().unwrap();
        let records = out["records"].as_array().unwrap();
        let f = |v: &Value| v.as_f64().unwrap();
        let mut by_h: std::collections::BTreeMap<String, Vec<[f64; 3]>> = Default::default();
        let mut t0s: Vec<f64> = Vec::new();
        for r in records {
            let (t0, h) = (f(&r["t0_s"]), f(&r["horizon_s"]));
            t0s.push(t0);
            let t_end = origin + ((t0 + h) * 1e9).round() as i64;
            let k = refs.iter().rposition(|x| x.0 <= t_end).unwrap();
            let (t_ref, pose, cov) = refs[k];
            close(
                "reference time",
                f(&r["reference_t_s"]),
                (t_ref - origin) as f64 * 1e-9,
                1e-9,
            );
            let pred: Vec<f64> = r["predicted"].as_array().unwrap().iter().map(f).collect();
            let pc: Vec<Vec<f64>> = (r["predicted_covariance"].as_array().unwrap().iter())
                .map(|row| row.as_array().unwrap().iter().map(f).collect())
                .collect();
            let mut e = [pose[0] - pred[0], pose[1] - pred[1], pose[2] - pred[2]];
            e[2] = (e[2] + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            let s = [0, 1, 2].map(|i| [0, 1, 2].map(|j| pc[i][j] + cov[i][j]));
            let n = nees(e, s);
            close(
                "position error",
                f(&r["position_error_m"]),
                e[0].hypot(e[1]),
                1e-9,
            );
            close("yaw error", f(&r["yaw_error_rad"]), e[2], 1e-9);
            close("nees", f(&r["nees"]), n, 1e-7);
            by_h.entry(format!("{h}"))
                .or_default()
                .push([e[0].hypot(e[1]), e[2].abs(), n]);
        }
        // Starts every 0.5 s.
        t0s.dedup();
        assert!(
            t0s.windows(2).all(|w| (w[1] - w[0] - 0.5).abs() < 1e-9),
            "{bag}: {t0s:?}"
        );
        assert_eq!(out["starts"].as_u64().unwrap() as usize, t0s.len());
        assert_eq!(out["predictions"].as_u64().unwrap() as usize, records.len());
        for h in out["horizons"].as_array().unwrap() {
            let rows = &by_h[&format!("{}", f(&h["horizon_s"]))];
            assert_eq!(h["predictions"].as_u64().unwrap() as usize, rows.len());
            for (col, key) in [(0, "position_error_m"), (1, "yaw_error_rad")] {
                let v: Vec<f64> = rows.iter().map(|r| r[col]).collect();
                close(key, f(&h[key]["median"]), percentile(&v, 50.0), 1e-9);
                close(key, f(&h[key]["p95"]), percentile(&v, 95.0), 1e-9);
                close(key, f(&h[key]["max"]), percentile(&v, 100.0), 1e-12);
            }
            let n = rows.len() as f64;
            let inside = |b: f64| rows.iter().filter(|r| r[2] <= b).count() as f64 / n;
            close("coverage p50", f(&h["coverage"]["p50"]), inside(b50), 1e-12);
            close("coverage p95", f(&h["coverage"]["p95"]), inside(b95), 1e-12);
            // The intervals on docs/logs.md's effective count: n / (1 + 2 Σ (1 − ℓ 0.5/h)²).
            let hs = f(&h["horizon_s"]);
            let lags = (1..)
                .map(|l| 1.0 - l as f64 * 0.5 / hs)
                .take_while(|r| *r > 0.0);
            let m = n / (1.0 + 2.0 * lags.map(|r| r * r).sum::<f64>());
            let cov = &h["coverage"];
            close("independent", f(&cov["independent_predictions"]), m, 1e-12);
            for (key, b) in [("p50_interval", b50), ("p95_interval", b95)] {
                let want = score_interval(inside(b), m);
                close(key, f(&cov[key][0]), want[0], 1e-9);
                close(key, f(&cov[key][1]), want[1], 1e-9);
            }
            close(
                "nees_mean",
                f(&h["nees_mean"]),
                rows.iter().map(|r| r[2]).sum::<f64>() / n,
                1e-7,
            );
        }
    }
}

#[test]
fn bad_input_is_a_clear_error() {
    let logs = repo_dir().join("tests/data/logs");
    let scene = repo_dir().join("params/suite_mobile_manipulator.yaml");
    let s = scene.to_str().unwrap();
    let bag = logs.join("calibration.mcap");
    let b = bag.to_str().unwrap();
    let truncated = std::env::temp_dir().join(format!("cd_eval_trunc_{}.mcap", std::process::id()));
    let bytes = std::fs::read(&bag).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    let t = truncated.to_str().unwrap();
    for (args, want) in [
        (
            vec!["--scene", s, "--bag", b, "--odom-topic", "/nope"],
            "no odometry topic '/nope'",
        ),
        (
            vec!["--scene", s, "--bag", b, "--cmd-vel-topic", "/odom"],
            "topic '/odom' is nav_msgs/msg/Odometry (cdr); expected geometry_msgs/msg/Twist",
        ),
        (vec!["--scene", s, "--bag", t], "truncated or corrupt after"),
        (
            vec!["--scene", s, "--bag", b, "--horizons", "0.25,-1"],
            "horizon [s] = -1",
        ),
        (
            vec!["--scene", s, "--bag", b, "--horizons", "75"],
            "horizon 75 s",
        ),
        (
            vec!["--scene", s, "--bag", "/nonexistent/bag.mcap"],
            "/nonexistent/bag.mcap",
        ),
        (
            vec!["--scene", s, "--bag", b, "--threads", "0"],
            "threads = 0: must be at least 1",
        ),
    ] {
        let (ok, _, err) = evaluate(&args);
        assert!(
            !ok && err.contains(want) && !err.contains("panicked"),
            "{args:?}: {err}"
        );
    }
    std::fs::remove_file(&truncated).ok();
}

/// A scene whose error bound refuses every start: each is rerun without the bound and counted,
/// and its figures are those of the same scene with no bound at all.
#[test]
fn refused_starts_are_rerun_without_the_bound_and_counted() {
    let text =
        std::fs::read_to_string(repo_dir().join("params/suite_mobile_manipulator.yaml")).unwrap();
    let urdf = repo_dir().join("urdf/mobile_manipulator.urdf");
    let dir = std::env::temp_dir().join(format!("cd_eval_refused_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bag = repo_dir().join("tests/data/logs/validation_smooth.mcap");
    let mut figures = Vec::new();
    for (name, bound) in [("tight", "1.0e-9"), ("none", ".inf")] {
        let scene = dir.join(format!("{name}.yaml"));
        // The bound on every kind: `max_error` alone, the per-kind keys dropped.
        let yaml: String = text
            .replace(
                "urdf: ../urdf/mobile_manipulator.urdf",
                &format!("urdf: {}", urdf.display()),
            )
            .replace("max_error: 0.05", &format!("max_error: {bound}"))
            .lines()
            .filter(|l| !l.trim_start().starts_with("max_error_"))
            .map(|l| format!("{l}\n"))
            .collect();
        assert!(yaml.contains(&format!("max_error: {bound}")));
        std::fs::write(&scene, yaml).unwrap();
        let args = [
            "--scene",
            scene.to_str().unwrap(),
            "--bag",
            bag.to_str().unwrap(),
            "--horizons",
            "0.5",
            "--every",
            "2",
        ];
        let (ok, out, err) = evaluate(&args);
        assert!(ok, "{name}: {err}");
        figures.push(out);
    }
    let (tight, none) = (&figures[0], &figures[1]);
    assert!(tight["predictions"].as_u64().unwrap() >= 9);
    assert_eq!(tight["refused"], tight["predictions"]);
    assert_eq!(none["refused"], 0);
    assert_eq!(
        tight["horizons"][0]["position_error_m"],
        none["horizons"][0]["position_error_m"]
    );
    assert_eq!(
        tight["horizons"][0]["yaw_error_rad"],
        none["horizons"][0]["yaw_error_rad"]
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `--plot DIR` writes PNG files (errors against the horizon; the ellipses per horizon) and
/// lists them.
#[test]
fn plots_are_written_where_asked() {
    let dir = std::env::temp_dir().join(format!("cd_evaluate_plots_{}", std::process::id()));
    let root = repo_dir();
    let (ok, out, err) = evaluate(&[
        "--scene",
        &root
            .join("params/suite_mobile_manipulator.yaml")
            .display()
            .to_string(),
        "--bag",
        &root
            .join("tests/data/logs/validation_smooth.mcap")
            .display()
            .to_string(),
        "--horizons",
        "0.5,1",
        "--plot",
        &dir.display().to_string(),
    ]);
    assert!(ok, "{err}");
    let plots: Vec<String> = serde_json::from_value(out["plots"].clone()).unwrap();
    assert_eq!(plots.len(), 3, "{plots:?}");
    for p in &plots {
        let bytes = std::fs::read(p).unwrap();
        assert!(bytes.starts_with(b"\x89PNG") && bytes.len() > 10_000, "{p}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// The drive's response (the monitor's fit, over the predictions whose command held) against
/// what the simulator was built with: the lagging drive's wheel-speed targets follow its
/// commands through 0.15 s, of which the model's own wheel loops already take some; the
/// bundled drive has no lag, tyres worn 1.5 % that creep under load (an effective radius 1 to
/// 2.5 % short, calibrate_cli.rs) and scrub in turns (spins about 5.7 % slow, arcs 1.5 %).
#[test]
fn the_drive_s_response_names_a_lag_and_the_worn_tyres() {
    let logs = repo_dir().join("tests/data/logs");
    let scene = repo_dir().join("params/suite_mobile_manipulator.yaml");
    let response = |bag: &str| {
        let path = logs.join(bag);
        let args = [
            "--scene",
            scene.to_str().unwrap(),
            "--bag",
            path.to_str().unwrap(),
            "--horizons",
            "1",
            "--every",
            "0.1",
        ];
        let (ok, out, err) = evaluate(&args);
        assert!(ok, "{bag}: {err}");
        let r = out["horizons"][0]["response"].clone();
        println!("{bag}: achieved response at 1 s: {r}");
        let f = |k: &str| r[k].as_f64().unwrap_or_else(|| panic!("{bag}: {k}: {r}"));
        (
            f("lag_s"),
            f("lag_std_error_s"),
            f("travel_ratio"),
            f("turn_ratio"),
        )
    };
    // Measured 0.133 ± 0.001 s.
    let (lag, se, _, _) = response("command_lag.mcap");
    assert!(lag > 0.08 && lag <= 0.15 && lag > 3.0 * se, "{lag} ± {se}");
    // Measured 0.033 s (below the monitor's 0.08 s), −1.40 % and −2.16 %.
    let (lag, _, travel, turn) = response("calibration.mcap");
    assert!(lag < 0.05, "{lag}");
    assert!((-0.025..=-0.01).contains(&travel), "{travel}");
    assert!((-0.057..=-0.015).contains(&turn), "{turn}");
}
