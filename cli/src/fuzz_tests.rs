//! Fuzzing the CLI's input files: the `--state` file (`eval`, `predict`), the
//! `--commands` file and the `--covariance` file of `predict`, as mutated valid JSON (wrong
//! types, numbers as strings, 1e308 and out-of-range numbers, null, missing and extra keys, deep
//! nesting, wrong and huge lengths) through the parsers the commands call. Property: no panic,
//! and a typed error naming the file or finite values of the right size. 512 cases per parser
//! by default, fixed seed (`PROPTEST_CASES`, `PROPTEST_RNG_SEED` override).

use crate::{covariance, predict, state};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

fn config() -> Config {
    let mut c = Config::default();
    if std::env::var_os("PROPTEST_CASES").is_none() {
        c.cases = 512;
    }
    if std::env::var_os("PROPTEST_RNG_SEED").is_none() {
        c.rng_seed = RngSeed::Fixed(0x15_15);
    }
    c.failure_persistence = None;
    c
}

fn scene() -> constraint_dynamics::Scene {
    let p = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../params/mobile_manipulator.yaml"
    );
    state::load_scene(std::path::Path::new(p)).unwrap()
}

/// A temporary file holding `text`.
fn file(text: &str) -> PathBuf {
    static N: AtomicUsize = AtomicUsize::new(0);
    let p = std::env::temp_dir().join(format!(
        "cd_fuzz_files_{}_{}.json",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::write(&p, text).unwrap();
    p
}

/// One JSON number, possibly hostile.
fn number() -> impl Strategy<Value = String> {
    prop_oneof![
        6 => (-3.0..3.0f64).prop_map(|x| format!("{x}")),
        1 => Just("1e308".to_string()),
        1 => Just("-1e308".to_string()),
        1 => Just("1e309".to_string()),
        1 => Just("1e-300".to_string()),
        1 => Just("-0".to_string()),
        1 => Just("\"NaN\"".to_string()),
        1 => Just("null".to_string()),
        1 => Just("true".to_string()),
        1 => Just("{}".to_string()),
        1 => Just("[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[1]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]".to_string()),
    ]
}

/// A JSON array of around n numbers (0, n−1, n, n+1, 10 000), or not an array at all.
fn array(n: usize) -> impl Strategy<Value = String> {
    prop_oneof![
        8 => prop_oneof![Just(0usize), Just(n - 1), Just(n), Just(n), Just(n), Just(n + 1), Just(10_000usize)]
            .prop_flat_map(|len| prop::collection::vec(number(), len))
            .prop_map(|v| format!("[{}]", v.join(","))),
        1 => number(),
        1 => Just("\"q\"".to_string()),
    ]
}

/// An object from (key, value) fields, some dropped, maybe an extra key, maybe cut short.
fn object(fields: Vec<(String, String)>, drop: u8, extra: bool, cut: Option<f64>) -> String {
    let mut parts: Vec<String> = fields
        .into_iter()
        .enumerate()
        .filter(|(i, _)| drop >> i & 1 == 0)
        .map(|(_, (k, v))| format!("\"{k}\": {v}"))
        .collect();
    if extra {
        parts.push("\"extra\": 1".into());
    }
    let s = format!("{{{}}}", parts.join(", "));
    match cut {
        Some(f) => s[..s.floor_char_boundary((f * s.len() as f64) as usize)].to_string(),
        None => s,
    }
}

fn cut() -> impl Strategy<Value = Option<f64>> {
    prop_oneof![8 => Just(None), 1 => (0.0..1.0f64).prop_map(Some)]
}

proptest! {
    #![proptest_config(config())]

    /// `--state FILE`: {"q", "v", "tau"}.
    #[test]
    fn state_file_hostile(q in array(9), v in array(9), tau in array(9),
                          drop in prop_oneof![4 => Just(0u8), 1 => 0..8u8], extra in prop::bool::weighted(0.1),
                          cut in cut()) {
        let sc = scene();
        let text = object(vec![("q".into(), q), ("v".into(), v), ("tau".into(), tau)], drop, extra, cut);
        let p = file(&text);
        let r = state::load(&sc, Some(&p));
        let _ = std::fs::remove_file(&p);
        match r {
            Err(e) => prop_assert!(e.to_string().contains(&p.display().to_string()), "{e}"),
            Ok((q, v, tau)) => {
                prop_assert_eq!((q.len(), v.len(), tau.len()), (sc.model.nq, sc.model.nv, sc.model.nv));
                prop_assert!(q.iter().chain(&v).chain(&tau).all(|x| x.is_finite()));
            }
        }
    }

    /// `predict --covariance FILE`: {"P": [[...]]} or {"sigma": {...}}.
    #[test]
    fn covariance_file_hostile(rows in prop_oneof![Just(0usize), Just(17usize), Just(18usize), Just(18usize), Just(19usize)],
                               row in array(18), sigma in prop::collection::vec((prop_oneof![
                                   Just("arm_elbow".to_string()), Just("arm_elbow:rate".to_string()),
                                   Just("".to_string()), any::<String>()], number()), 0..4),
                               which in 0..3u8, extra in prop::bool::weighted(0.1), cut in cut()) {
        let sc = scene();
        let p_text = format!("[{}]", vec![row; rows].join(","));
        let sigma_text = format!("{{{}}}", sigma.iter()
            .map(|(k, v)| format!("{}: {v}", serde_json::Value::String(k.clone()))).collect::<Vec<_>>().join(","));
        let text = object(vec![("P".into(), p_text), ("sigma".into(), sigma_text)], which, extra, cut);
        let path = file(&text);
        let r = covariance::load(&sc.model, &path);
        let _ = std::fs::remove_file(&path);
        match r {
            Err(e) => prop_assert!(!e.to_string().is_empty()),
            Ok(m) => {
                prop_assert_eq!(m.shape(), (2 * sc.model.nv, 2 * sc.model.nv));
                prop_assert!(m.iter().all(|x| x.is_finite()), "non-finite P from {text}");
            }
        }
    }

    /// `predict --commands FILE`: [{"t", "base_twist", "joint_velocity", "joint_position"}].
    #[test]
    fn commands_file_hostile(entries in prop::collection::vec((number(), array(2), number(), number(),
                                 prop_oneof![Just(0u8), 0..16u8], prop::bool::weighted(0.05)), 0..6),
                             big in prop::bool::weighted(0.02), cut in cut()) {
        let mut items: Vec<String> = entries.into_iter().map(|(t, bt, jv, jp, drop, extra)| object(vec![
            ("t".into(), t), ("base_twist".into(), bt),
            ("joint_velocity".into(), format!("{{\"arm_elbow\": {jv}}}")),
            ("joint_position".into(), format!("{{\"nope\": {jp}}}")),
        ], drop, extra, None)).collect();
        if big {
            items.extend((0..10_000).map(|i| format!("{{\"t\": {}}}", i as f64 * 0.01)));
        }
        let mut text = format!("[{}]", items.join(","));
        if let Some(f) = cut {
            text.truncate(text.floor_char_boundary((f * text.len() as f64) as usize));
        }
        let path = file(&text);
        let r = predict::fuzz_load_commands(&path);
        let _ = std::fs::remove_file(&path);
        match r {
            Err(e) => prop_assert!(e.to_string().contains(&path.display().to_string()), "{e}"),
            Ok(cmds) => prop_assert!(cmds.iter().all(|(t, c)| t.is_finite()
                && c.base_twist.iter().flatten().all(|x| x.is_finite())
                && c.joint_velocity.values().chain(c.joint_position.values()).all(|x| x.is_finite()))),
        }
    }
}

/// Found by tools/fuzz_long.sh (seed 503634): σ = 1e308 squared to +∞ in P.
#[test]
fn covariance_sigma_1e308_is_refused() {
    let sc = scene();
    let path = file(r#"{"sigma": {"arm_elbow": 1e308}}"#);
    let r = covariance::load(&sc.model, &path);
    let _ = std::fs::remove_file(&path);
    let e = r.expect_err("sigma 1e308 must be refused").to_string();
    assert!(e.contains("sigma.arm_elbow"), "{e}");
}
