//! Shared helpers for the integration tests: the independent reference cases in
//! `../shared/reference/` (Pinocchio 4.1.0 numbers; never regenerated with this project's code).
#![allow(dead_code)]

use constraint_dynamics::forces::{ForcesSpec, JointSpringSpec};
use constraint_dynamics::{BaseType, Error, Model, ModelOptions, Scene, System};
use nalgebra::{DMatrix, DVector, UnitQuaternion};
use serde_json::Value;
use std::path::PathBuf;
use std::process::Command;

/// Workspaces of the system's model and constraints, for the tests that call the algorithms
/// themselves (the system's own are written only by its evaluations).
pub fn workspaces(
    sys: &System,
) -> (
    constraint_dynamics::algorithm::Data,
    constraint_dynamics::constraints::ConstraintData,
    constraint_dynamics::dynamics::KktWorkspace,
) {
    (
        constraint_dynamics::algorithm::Data::new(sys.model()),
        constraint_dynamics::constraints::ConstraintData::new(sys.model(), sys.constraints()),
        constraint_dynamics::dynamics::KktWorkspace::new(sys.model(), sys.constraints()),
    )
}

pub fn reference_dir() -> PathBuf {
    repo_dir().join("../shared/reference")
}

/// The repository root (the workspace's, whichever of its crates runs the test).
pub fn repo_dir() -> PathBuf {
    let here = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    here.ancestors()
        .find(|d| d.join("Cargo.lock").exists())
        .unwrap_or(&here)
        .to_path_buf()
}

pub fn load_case(name: &str) -> Value {
    let p = reference_dir().join("cases").join(format!("{name}.json"));
    let text = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    serde_json::from_str(&text).unwrap()
}

/// The case's model: its URDF with a free-flyer base when `floating_base` is set.
pub fn case_model(case: &Value) -> Model {
    let m = &case["model"];
    let urdf = reference_dir()
        .join("urdf")
        .join(m["urdf"].as_str().unwrap());
    let floating = !matches!(m["floating_base"], Value::Bool(false));
    let opts = ModelOptions {
        base: if floating {
            BaseType::Floating
        } else {
            BaseType::Fixed
        },
        ..Default::default()
    };
    let model = Model::from_urdf_file(urdf, &opts).unwrap();
    let names: Vec<String> = m["v_names"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_str().unwrap().to_string())
        .collect();
    assert_eq!(
        model.v_names, names,
        "coordinate order differs from the reference"
    );
    model
}

pub fn vecf(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap_or(f64::NAN))
        .collect()
}

pub fn dvec(v: &Value) -> DVector<f64> {
    DVector::from_vec(vecf(v))
}

pub fn dmat(v: &Value) -> DMatrix<f64> {
    let rows: Vec<Vec<f64>> = v.as_array().unwrap().iter().map(vecf).collect();
    let (r, c) = (rows.len(), rows.first().map_or(0, |x| x.len()));
    DMatrix::from_fn(r, c, |i, j| rows[i][j])
}

/// max |a − b| / max(1, max |b|): relative to the reference's scale.
pub fn rel_err(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len(), "length mismatch");
    let scale = b.iter().fold(1.0f64, |m, x| m.max(x.abs()));
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
        / scale
}

/// Asserts `rel_err(a, b) <= tol` and prints the achieved figure (`--nocapture` shows it), so
/// every tolerance can be checked against what the code reaches (docs/testing.md).
pub fn assert_close(what: &str, a: &[f64], b: &[f64], tol: f64) {
    let e = rel_err(a, b);
    eprintln!("achieved {what}: {e:.2e} (tol {tol:.0e})");
    assert!(
        e <= tol,
        "{what}: relative error {e:.3e} > {tol:.1e}\n ours: {a:?}\n  ref: {b:?}"
    );
}

/// The reference case's constraints as scene declarations (point feet/end effector, rolling disk).
pub fn specs_for(
    case: &Value,
    st: &Value,
) -> Vec<constraint_dynamics::constraints::ConstraintSpec> {
    let cons = st.get("constraints").unwrap_or(&case["constraints"]);
    cons.as_array()
        .unwrap()
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let link = c["link"].as_str().unwrap().to_string();
            match c["type"].as_str().unwrap() {
                "point_fixed_in_world" => {
                    let a = vecf(&c["world_anchor"]);
                    let rows = c["rows"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|r| match r.as_str() {
                            Some("x") => constraint_dynamics::constraints::Row::X,
                            Some("y") => constraint_dynamics::constraints::Row::Y,
                            Some("z") => constraint_dynamics::constraints::Row::Z,
                            // A row the reference names but this helper does not map would
                            // silently become another row: refuse it.
                            other => {
                                panic!("constraint {k}: unknown reference row {other:?} in {r}")
                            }
                        })
                        .collect();
                    constraint_dynamics::constraints::ConstraintSpec::Point {
                        name: format!("c{k}"),
                        frame_a: link,
                        point_a: [0.0; 3],
                        frame_b: "world".into(),
                        point_b: [a[0], a[1], a[2]],
                        rows,
                        unilateral: false,
                        friction: None,
                    }
                }
                "rolling_disk_on_plane_z0" => {
                    let ax = vecf(&c["disk_axis_in_body"]);
                    constraint_dynamics::constraints::ConstraintSpec::Rolling {
                        name: format!("c{k}"),
                        wheel: link,
                        axis: [ax[0], ax[1], ax[2]],
                        radius: c["radius"].as_f64().unwrap(),
                        axle_offset: 0.0,
                        axle_offset_turn_gain: 0.0,
                        lateral: Default::default(),
                        plane_normal: [0.0, 0.0, 1.0],
                        plane_height: 0.0,
                        friction: None,
                    }
                }
                t => panic!("unknown reference constraint type {t}"),
            }
        })
        .collect()
}

/// The bundled scene files (`params/*.yaml` with a robot, not ROS parameter files), sorted.
pub fn bundled_scenes() -> Vec<std::path::PathBuf> {
    let mut v: Vec<_> = std::fs::read_dir(repo_dir().join("params"))
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension().is_some_and(|x| x == "yaml")
                && std::fs::read_to_string(p)
                    .is_ok_and(|t| t.starts_with("#") || t.contains("urdf:"))
                && std::fs::read_to_string(p).is_ok_and(|t| !t.contains("ros__parameters"))
        })
        .collect();
    v.sort();
    v
}

/// A covariance row list (`Sample::covariance`) as a matrix.
pub fn rows_to_matrix(rows: &[Vec<f64>]) -> DMatrix<f64> {
    DMatrix::from_fn(rows.len(), rows.len(), |i, j| rows[i][j])
}

/// (δq, δv) of a state relative to a reference, in the tangent space (δq = q_ref⁻¹ q on the
/// group, the covariance's order).
pub fn tangent(model: &Model, q_ref: &[f64], v_ref: &[f64], q: &[f64], v: &[f64]) -> DVector<f64> {
    let nv = model.nv;
    let mut d = vec![0.0; nv];
    model.difference(q_ref, q, &mut d);
    let mut x = DVector::zeros(2 * nv);
    x.rows_mut(0, nv).copy_from_slice(&d);
    for i in 0..nv {
        x[nv + i] = v[i] - v_ref[i];
    }
    x
}

/// The suite's mobile manipulator (params/suite_mobile_manipulator.yaml) as its digital
/// controllers run: torques held over the 1 ms control period, stepped by RK4 at that period,
/// `max_error` at its default — the model the scene's live settings are measured against.
#[allow(dead_code)]
pub fn suite_held_scene() -> Scene {
    let mut scene = Scene::load(repo_dir().join("params/suite_mobile_manipulator.yaml")).unwrap();
    scene.file.actuators.hold = constraint_dynamics::actuators::Hold::ZeroOrder;
    scene.file.actuators.control_period = Some(1e-3);
    let s = &mut scene.file.integration;
    s.method = constraint_dynamics::predict::Method::Rk4;
    s.dt = 1e-3;
    s.set_max_error(constraint_dynamics::predict::IntegrationSettings::default().max_error);
    scene
}

/// The command of the tests under controllers: the suite's mobile manipulator
/// (params/suite_mobile_manipulator.yaml) turning at (0.2 m/s, 0.3 rad/s) with its arm held
/// where the scene starts it.
pub fn turning_with_arm_held() -> constraint_dynamics::actuators::Command {
    let mut cmd = constraint_dynamics::actuators::Command {
        base_twist: Some([0.2, 0.3]),
        ..Default::default()
    };
    for (joint, q) in [
        ("arm_shoulder_yaw", 0.0),
        ("arm_shoulder_pitch", 0.5),
        ("arm_elbow", 1.0),
        ("arm_wrist", 0.5),
    ] {
        cmd.joint_position.insert(joint.into(), q);
    }
    cmd
}

/// A bundled scene (`params/<name>`) and its system.
pub fn scene_system(name: &str) -> (constraint_dynamics::Scene, constraint_dynamics::System) {
    let scene = constraint_dynamics::Scene::load(repo_dir().join("params").join(name)).unwrap();
    let sys = constraint_dynamics::System::from_scene(&scene).unwrap();
    (scene, sys)
}

/// The reference thin disk (`../shared/reference/urdf/disk.urdf`: m = 1 kg, COM at the body
/// origin, I = diag(0.0025, 0.005, 0.0025) kg m², r = 0.1 m) on a `base` of that type.
pub fn reference_disk(base: BaseType) -> Model {
    Model::from_urdf_file(
        reference_dir().join("urdf/disk.urdf"),
        &ModelOptions {
            base,
            ..Default::default()
        },
    )
    .unwrap()
}

/// The multiplier form's system of `model` with the constraints `specs` (validated at q).
pub fn multiplier_system(
    model: Model,
    specs: &[constraint_dynamics::constraints::ConstraintSpec],
    q: &[f64],
) -> constraint_dynamics::System {
    use constraint_dynamics::dynamics::{Baumgarte, Formulation};
    let set = constraint_dynamics::constraints::ConstraintSet::new(&model, specs, q).unwrap();
    constraint_dynamics::System::new(model, set, Baumgarte::default(), Formulation::Multipliers)
}

/// Asserts that an error message mentions every one of `parts`.
pub fn assert_has(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "error {msg:?} should mention {p:?}");
    }
}

/// A scene file of the repository (`rel` from its root), loaded.
pub fn scene(rel: &str) -> Scene {
    Scene::load(repo_dir().join(rel)).unwrap()
}

/// A scene from YAML text (the URDF path made absolute), loaded through a temporary file.
pub fn scene_from(urdf: &str, base: &str, constraints: &str) -> Result<System, Error> {
    let urdf = repo_dir().join("urdf").join(urdf);
    let yaml = format!(
        "urdf: {:?}\nbase: {base}\nconstraints:\n{constraints}",
        urdf.display().to_string()
    );
    System::from_scene(&scene_from_yaml(&yaml)?)
}

/// A scene from its URDF and YAML text (`urdf: NAME.urdf`), both written to a directory of its
/// own under the system's temporary directory and read back as a scene file is, the directory
/// removed again.
pub fn scene_with_urdf(name: &str, urdf: &str, yaml: &str) -> Scene {
    // One directory per call: the tests run in parallel threads of one process.
    static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let k = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("cd_{name}_{}_{k}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary directory");
    std::fs::write(dir.join(format!("{name}.urdf")), urdf).expect("the URDF written");
    std::fs::write(dir.join(format!("{name}.yaml")), yaml).expect("the scene written");
    let scene = Scene::load(dir.join(format!("{name}.yaml")));
    let _ = std::fs::remove_dir_all(&dir);
    scene.unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// A scene from YAML text (its paths absolute), loaded through a temporary file of its own.
pub fn scene_from_yaml(yaml: &str) -> Result<Scene, Error> {
    // One file per call: the tests run in parallel threads of one process.
    static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let path = std::env::temp_dir().join(format!(
        "scene_from_{}_{}.yaml",
        std::process::id(),
        N.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    ));
    std::fs::write(&path, yaml).unwrap();
    let scene = Scene::load(&path);
    let _ = std::fs::remove_file(&path);
    scene
}

/// A free-flyer's configuration: position `p`, orientation `rot` (x, y, z, w).
pub fn q_at(p: [f64; 3], rot: &UnitQuaternion<f64>) -> Vec<f64> {
    vec![p[0], p[1], p[2], rot.i, rot.j, rot.k, rot.w]
}

/// q moved by `h` along the tangent direction `dir` (on the configuration's group).
pub fn perturbed(model: &Model, q: &[f64], dir: &[f64], h: f64) -> Vec<f64> {
    let mut out = vec![0.0; q.len()];
    model.integrate(q, dir, h, &mut out);
    out
}

/// The five-slider chain with springs 1e6, 1e7, 1e8, 1e7, 1e6 N/m on 0.1 kg masses.
pub fn very_stiff_chain() -> (Scene, ForcesSpec) {
    let sc = scene("params/report/spring_chain_stiff.yaml");
    let mut spec = ForcesSpec::default();
    for (i, k) in [1e6, 1e7, 1e8, 1e7, 1e6].into_iter().enumerate() {
        spec.joint_springs.push(JointSpringSpec {
            joint: format!("slider{}", i + 1),
            stiffness: k,
            damping: 0.0,
            rest: 0.0,
        });
    }
    (sc, spec)
}

/// The CLI (`constraint_dynamics`, built for cli/tests only) run from the repository root: the
/// tests' scene paths are relative to it.
pub fn cli() -> Command {
    let Some(exe) = option_env!("CARGO_BIN_EXE_constraint_dynamics") else {
        panic!("the CLI binary is built for the CLI's own tests (cli/tests) only");
    };
    let mut c = Command::new(exe);
    c.current_dir(repo_dir());
    c
}

/// The cart of tests/data/cart_tall_mass.yaml (urdf/cart_tall_mass.urdf), written out by hand for
/// the envelope's closed forms (docs/projection.md): wheel radius, wheel spin inertia, effort, caster
/// distance behind the axle, total mass, Σ m x and Σ m z over every body (wheels included).
pub mod cart {
    pub const R: f64 = 0.1;
    pub const I_W: f64 = 0.005;
    pub const TAU_MAX: f64 = 4.0;
    pub const L_C: f64 = 0.4;
    /// 20 (chassis) + 2 × 1 (wheels) + 0.5 (caster) + 10 (tall mass) [kg].
    pub const M: f64 = 32.5;
    /// 20 × (−0.1) + 0.5 × (−0.4) + 10 × (−0.05) [kg·m] (wheels at x = 0).
    pub const M_X: f64 = -2.7;
    /// Heights above the ground: 20 × 0.1 + 2 × 1 × 0.1 + 0.5 × 0.05 + 10 × 1.1 [kg·m].
    pub const M_Z: f64 = 13.225;
}

/// xorshift64*: a deterministic stream in [0, 1) (the randomised projection certificates).
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }
}
