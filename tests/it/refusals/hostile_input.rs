//! Hostile numbers at the boundary: every one is a typed error naming the input, or
//! the results are finite — never NaN or ∞ out, never unbounded work.

use crate::common;
use common::assert_has;
use constraint_dynamics::predict::{IntegrationOverrides, Method, PredictionRequest, Predictor};
use constraint_dynamics::{Error, Scene, System};

fn scene_file(name: &str, body: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("cd_hostile_{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let p = d.join(name);
    std::fs::write(&p, body).unwrap();
    p
}

fn urdf(name: &str) -> String {
    common::repo_dir()
        .join("urdf")
        .join(name)
        .display()
        .to_string()
}

fn system_err(name: &str, body: &str) -> String {
    let p = scene_file(name, body);
    match Scene::load(&p) {
        Err(e) => e.to_string(),
        Ok(s) => System::from_scene(&s).unwrap_err().to_string(),
    }
}

#[test]
fn gravity_baumgarte_and_wheel_radius_are_bounded() {
    let dd = urdf("diff_drive.urdf");
    let e = system_err(
        "g.yaml",
        &format!("urdf: {dd}\nbase: planar\ngravity: [0, 0, .nan]\n"),
    );
    assert_has(&e, &["gravity", "m/s²"]);
    let e = system_err(
        "g2.yaml",
        &format!("urdf: {dd}\nbase: planar\ngravity: [0, 0, 1e300]\n"),
    );
    assert_has(&e, &["gravity", "at most 1e4"]);
    let e = system_err(
        "b.yaml",
        &format!("urdf: {dd}\nbase: planar\ndynamics: {{baumgarte_time_constant: 1e-300}}\n"),
    );
    assert_has(
        &e,
        &["dynamics.baumgarte_time_constant", "1e-300", "[1e-6, 1e6]"],
    );
    let e = system_err(
        "k.yaml",
        &format!("urdf: {dd}\nbase: planar\ndynamics: {{baumgarte: {{kp: 1e300, kd: 1}}}}\n"),
    );
    assert_has(&e, &["dynamics.baumgarte.kp"]);
    let e = system_err(
        "w.yaml",
        &format!(
            "urdf: {dd}\nbase: planar\nconstraints:\n  - {{name: w, kind: rolling, wheel: left_wheel, axis: [0,1,0], radius: 1e308}}\n"
        ),
    );
    assert_has(&e, &["constraint 'w'", "wheel radius 1e308", "at most"]);
    let e = system_err(
        "p.yaml",
        &format!(
            "urdf: {dd}\nbase: planar\nconstraints:\n  - {{name: h, kind: point, frame_a: base_link, point_a: [0, 0, 1e300]}}\n"
        ),
    );
    assert_has(&e, &["constraint 'h'", "point_a", "beyond"]);
}

fn fourbar() -> Predictor {
    let s = Scene::load(common::repo_dir().join("params/fourbar.yaml")).unwrap();
    Predictor::from_scene(&s).unwrap()
}

#[test]
fn absurd_steps_horizons_and_states_are_refused_before_running() {
    let mut p = fourbar();
    let s = Scene::load(common::repo_dir().join("params/fourbar.yaml")).unwrap();
    let (q, v) = (s.q0.clone(), s.v0.clone());
    let t = std::time::Instant::now();
    // Absurd steps and sample periods are this call's (a predictor is not configured with
    // them: `with_settings` refuses them for the scene's own horizon).
    let req = |horizon: f64, dt: f64, sample_period: Option<f64>| {
        let integration = IntegrationOverrides {
            dt: Some(dt),
            sample_period,
            ..Default::default()
        };
        PredictionRequest::new(&q, &v)
            .horizon(horizon)
            .integration(integration)
    };
    let e = p.predict(&req(1.0, 1e-300, None)).unwrap_err();
    assert!(matches!(e, Error::WorkLimit { .. }), "{e}");
    assert_has(
        &e.to_string(),
        &["integration steps", "integration.max_steps"],
    );
    let e = p
        .predict(&req(1.0, 1e-3, Some(1e-300)))
        .unwrap_err()
        .to_string();
    assert_has(&e, &["output samples", "max_samples"]);
    let e = p
        .predict(&req(1e308, 1e-3, Some(1e-2)))
        .unwrap_err()
        .to_string();
    assert_has(&e, &["integration steps", "1e308"]);
    // dopri5 adapts its step: bounded while running.
    let mut p = p
        .with_settings(|s| {
            s.dt = 1e-3;
            s.sample_period = 1e-2;
            s.method = Method::Dopri5;
            s.max_steps = 50.0;
        })
        .unwrap();
    let e = p
        .predict(&PredictionRequest::new(&q, &v).horizon(1e3))
        .unwrap_err()
        .to_string();
    assert_has(&e, &["steps (51)", "max_steps"]);
    let mut p = p
        .with_settings(|s| {
            s.method = Method::Rk4;
            s.max_steps = 1e6;
        })
        .unwrap();
    let mut big = v.clone();
    big[0] = 1e308;
    let e = p
        .predict(&PredictionRequest::new(&q, &big).horizon(0.1))
        .unwrap_err()
        .to_string();
    assert_has(&e, &["v: entry 0", "beyond the accepted magnitude 1e6"]);
    // All of the above refused without running: well under a second together.
    assert!(t.elapsed().as_secs_f64() < 1.0, "{:?}", t.elapsed());
}

/// A 1 000-link chain over 100 s (RK4, dt = 1 ms, the error estimate's companion: 1.2e6
/// evaluations by ABA, about 8 minutes) is refused up front with the estimate, naming the path
/// it counted.
#[test]
fn a_1000_link_chain_is_refused_by_the_work_budget() {
    let n = 1000;
    let mut s = String::from("<robot name=\"chain\"><link name=\"l0\"/>\n");
    for i in 1..=n {
        s.push_str(&format!(
            "<link name=\"l{i}\"><inertial><mass value=\"0.1\"/><inertia ixx=\"1e-3\" iyy=\"1e-3\" izz=\"1e-3\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>\n\
             <joint name=\"j{i}\" type=\"continuous\"><parent link=\"l{}\"/><child link=\"l{i}\"/><origin xyz=\"0 0 0.01\"/><axis xyz=\"1 0 0\"/></joint>\n",
            i - 1
        ));
    }
    s.push_str("</robot>");
    let u = scene_file("chain.urdf", &s);
    let p = scene_file("chain.yaml", &format!("urdf: {}\n", u.display()));
    let scene = Scene::load(&p).unwrap();
    let mut pred = Predictor::from_scene(&scene).unwrap();
    let t = std::time::Instant::now();
    let e = pred
        .predict(&PredictionRequest::new(&scene.q0, &scene.v0).horizon(100.0))
        .unwrap_err()
        .to_string();
    println!("1000-link chain, 100 s: {e} (in {:?})", t.elapsed());
    assert_has(
        &e,
        &[
            "work units",
            "1000-body",
            "linear-time path",
            "integration.max_work",
        ],
    );
    assert!(t.elapsed().as_secs_f64() < 0.5);
}

/// serde reads tagged constraint kinds through a buffer: its message pointed at the list's
/// first line with no index or field. Now: entry, name, field and line.
#[test]
fn constraint_errors_name_the_entry_field_and_line() {
    let dd = urdf("diff_drive.urdf");
    let head = format!(
        "urdf: {dd}\nbase: planar\nconstraints:\n  - {{name: a, kind: rolling, wheel: left_wheel, axis: [0,1,0], radius: 0.05}}\n  - name: w\n    kind: rolling\n    wheel: left_wheel\n    axis: [0, 1, 0]\n"
    );
    let e = system_err("c1.yaml", &format!("{head}    radius: abc\n"));
    assert_has(
        &e,
        &["constraints[1] 'w'", "field `radius`", "line 9", "\"abc\""],
    );
    let e = system_err(
        "c2.yaml",
        &format!("{head}    radius: 0.05\n    radus: 2\n"),
    );
    assert_has(
        &e,
        &[
            "constraints[1] 'w'",
            "field `radus`",
            "line 10",
            "unknown field",
        ],
    );
    let e = system_err(
        "c3.yaml",
        &format!(
            "{}    radius: 0.05\n",
            head.replace("radius: 0.05}", "radius: x}")
        ),
    );
    assert_has(&e, &["constraints[0] 'a'", "field `radius`", "line 4"]);
}
