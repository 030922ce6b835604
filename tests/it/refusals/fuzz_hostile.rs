//! Fuzzing the boundary: hostile URDF numbers and scene fields — NaN, ±∞, 1e308,
//! 1e-300, −0, words that are not numbers — through load, one evaluation of the constraint
//! forces and a short prediction. Property: no panic, and either a typed error or finite
//! outputs (q̈, λ, Jᵀλ, every sample's q, v, energies).
//!
//! 512 cases by default with a fixed seed (`PROPTEST_CASES`, `PROPTEST_RNG_SEED` override); the
//! longer run (tools/fuzz_long.sh) is described in docs/testing.md. Each case replaces 1–4 of the template's
//! numbers, so most cases reach the dynamics with one bad value rather than stopping at the
//! first check.

use constraint_dynamics::applied::constraint_forces_at;
use constraint_dynamics::forces::ForceElements;
use constraint_dynamics::predict::{PredictionRequest, Predictor};
use constraint_dynamics::scene::SceneFile;
use constraint_dynamics::{Scene, System};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};
use std::path::Path;
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

/// A two-joint arm with a mimic follower; `{N}` are the fuzzed numbers.
const URDF: &str = r#"<robot name="fuzz">
  <link name="base"/>
  <link name="upper"><inertial><origin xyz="{0} 0 0.2" rpy="0 {1} 0"/><mass value="{2}"/>
    <inertia ixx="{3}" iyy="0.02" izz="{4}" ixy="{5}" ixz="0" iyz="0"/></inertial></link>
  <link name="lower"><inertial><origin xyz="0 0 0.2"/><mass value="1"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="tip"><inertial><mass value="0.2"/>
    <inertia ixx="1e-3" iyy="1e-3" izz="1e-3" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <origin xyz="0 0 {6}" rpy="{7} 0 0"/><axis xyz="0 {8} 1"/>
    <limit lower="{9}" upper="2" effort="{10}" velocity="3"/><dynamics damping="{11}"/></joint>
  <joint name="elbow" type="continuous"><parent link="upper"/><child link="lower"/>
    <origin xyz="0 0 0.4"/><axis xyz="0 1 0"/></joint>
  <joint name="wrist" type="prismatic"><parent link="lower"/><child link="tip"/>
    <origin xyz="0 0 0.4"/><axis xyz="0 0 1"/><limit lower="-0.1" upper="0.1"/>
    <mimic joint="elbow" multiplier="{12}" offset="{13}"/></joint>
</robot>"#;

const URDF_DEFAULTS: [&str; 14] = [
    "0", "0", "2", "0.02", "0.02", "0", "0.1", "0", "0", "-2", "10", "0.1", "0.05", "0",
];

/// The scene: base, gravity, Baumgarte, a coupling a·q_s − 0.6·q_e + c = 0 (consistent at the
/// defaults), the initial state, the integration settings and a joint torque.
const SCENE: &str = "urdf: fuzz.urdf
base: {0}
gravity: [0, {1}, -9.81]
initial_state: {q: {shoulder: 0.3, elbow: {2}}, v: {shoulder: {3}, elbow: 0.3333333333333333}}
constraints:
  - {name: c, kind: coupling, joint_i: shoulder, joint_j: elbow, a: {5}, b: -0.6, c: {4}}
dynamics: {baumgarte_time_constant: {6}}
integration: {method: {7}, dt: {8}, horizon: 0.02, sample_period: {9}, drift: {10}}
forces: {joint_torques: [{joint: shoulder, value: {11}}]}
";

const SCENE_DEFAULTS: [&str; 12] = [
    "fixed",
    "0",
    "0.5",
    "0.2",
    "0",
    "1",
    "0.05",
    "rk4",
    "0.001",
    "0.005",
    "projection",
    "0.5",
];

fn hostile_number() -> impl Strategy<Value = String> {
    prop_oneof![
        3 => (-1e3f64..1e3).prop_map(|x| format!("{x}")),
        1 => Just("NaN".to_string()),
        1 => Just("inf".to_string()),
        1 => Just("-inf".to_string()),
        1 => Just("1e308".to_string()),
        1 => Just("-1e308".to_string()),
        1 => Just("1e-300".to_string()),
        1 => Just("-0.0".to_string()),
        1 => Just("0".to_string()),
        1 => Just("1e9".to_string()),
        1 => Just("1e10".to_string()),
        1 => Just("abc".to_string()),
        1 => Just(String::new()),
    ]
}

fn hostile_scene_value(slot: usize) -> BoxedStrategy<String> {
    match slot {
        0 => prop_oneof![
            Just("fixed"),
            Just("floating"),
            Just("planar"),
            Just("ball")
        ]
        .prop_map(str::to_string)
        .boxed(),
        7 => prop_oneof![
            Just("rk4"),
            Just("dopri5"),
            Just("sdirk2"),
            Just("semi_implicit_euler")
        ]
        .prop_map(str::to_string)
        .boxed(),
        10 => prop_oneof![Just("none"), Just("baumgarte"), Just("projection")]
            .prop_map(str::to_string)
            .boxed(),
        _ => hostile_number()
            .prop_map(|s| match s.as_str() {
                // YAML spells them .nan and .inf.
                "NaN" => ".nan".to_string(),
                "inf" => ".inf".to_string(),
                "-inf" => "-.inf".to_string(),
                "" => "''".to_string(),
                _ => s,
            })
            .boxed(),
    }
}

fn fill(template: &str, values: &[String]) -> String {
    let mut s = template.to_string();
    for (i, v) in values.iter().enumerate() {
        s = s.replace(&format!("{{{i}}}"), v);
    }
    s
}

static CASES: AtomicUsize = AtomicUsize::new(0);
static REFUSED: AtomicUsize = AtomicUsize::new(0);

/// Load, evaluate and predict; Err is a typed refusal, Ok means every output was finite.
fn run(urdf: &str, scene: &str) -> Result<(), String> {
    let file: SceneFile = serde_yaml::from_str(scene).map_err(|e| e.to_string())?;
    let sc = Scene::from_parts(Path::new("fuzz.yaml"), file, urdf, "fuzz.urdf")
        .map_err(|e| e.to_string())?;
    let mut sys = System::from_scene(&sc).map_err(|e| e.to_string())?;
    let mut elements =
        ForceElements::new(sys.model(), &sc.file.forces).map_err(|e| e.to_string())?;
    let tau = vec![0.0; sys.model().nv];
    let at = constraint_forces_at(&mut sys, &mut elements, (0.0, &sc.q0, &sc.v0), &tau)
        .map_err(|e| e.to_string())?;
    for x in at.qdd.iter().chain(&at.lambda).chain(&at.generalized_force) {
        assert!(
            x.is_finite(),
            "a non-finite output left constraint_forces_at: {at:?}"
        );
    }
    let mut p = Predictor::from_scene(&sc).map_err(|e| e.to_string())?;
    let req = PredictionRequest::new(&sc.q0, &sc.v0)
        .horizon(0.02)
        .forces(true);
    let traj = p.predict(&req).map_err(|e| e.to_string())?;
    for s in &traj.samples {
        let energies = [s.kinetic_energy, s.potential_energy];
        for x in s.q.iter().chain(&s.v).chain(&energies) {
            assert!(
                x.is_finite(),
                "a non-finite sample left predict at t = {}",
                s.t
            );
        }
        for x in s.lambda.iter().flatten() {
            assert!(x.is_finite(), "a non-finite λ left predict at t = {}", s.t);
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn hostile_values_give_a_typed_error_or_finite_outputs(
        urdf_slots in proptest::collection::vec((0usize..14, hostile_number()), 0..3),
        scene_slots in proptest::collection::vec(0usize..12, 0..3)
            .prop_flat_map(|slots| {
                let values: Vec<BoxedStrategy<String>> =
                    slots.iter().map(|&s| hostile_scene_value(s)).collect();
                (Just(slots), values)
            }),
    ) {
        let mut u: Vec<String> = URDF_DEFAULTS.iter().map(|s| s.to_string()).collect();
        for (i, v) in urdf_slots {
            u[i] = v;
        }
        let mut sc: Vec<String> = SCENE_DEFAULTS.iter().map(|s| s.to_string()).collect();
        for (i, v) in scene_slots.0.iter().zip(scene_slots.1) {
            sc[*i] = v;
        }
        let result = run(&fill(URDF, &u), &fill(SCENE, &sc));
        let cases = CASES.fetch_add(1, Ordering::Relaxed) + 1;
        if result.is_err() {
            REFUSED.fetch_add(1, Ordering::Relaxed);
        }
        if cases == config().cases as usize {
            report_and_check(cases);
        }
    }
}

/// The defaults load and run: the fuzzing starts from a working scene, so a refusal is caused
/// by the value the case changed.
#[test]
fn the_fuzz_template_itself_runs() {
    let u: Vec<String> = URDF_DEFAULTS.iter().map(|s| s.to_string()).collect();
    let s: Vec<String> = SCENE_DEFAULTS.iter().map(|s| s.to_string()).collect();
    run(&fill(URDF, &u), &fill(SCENE, &s)).unwrap();
}

/// The least share of the cases that must run through, and be refused: a fuzz whose cases were
/// all refused would test no computation, one with none refused no check.
const MIN_SHARE: f64 = 0.05;

/// After the run's last case (shrinking after a failure counts more cases: no check then).
fn report_and_check(cases: usize) {
    let refused = REFUSED.load(Ordering::Relaxed);
    let ran = cases - refused;
    println!("fuzz: {ran} ran through, {refused} refused with a typed error, of {cases} cases");
    assert!(
        ran as f64 >= MIN_SHARE * cases as f64 && refused as f64 >= MIN_SHARE * cases as f64,
        "{ran} ran and {refused} refused of {cases}: the strategies no longer reach both outcomes"
    );
}
