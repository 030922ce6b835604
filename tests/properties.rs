//! Property tests (proptest): random robots and states drawn from the bundled URDFs and scenes
//! (`urdf/`, `params/`) and the reference URDFs (`../shared/reference/urdf/`), checked against
//! identities that hold for every input, not against numbers of this code:
//!
//! - inverse dynamics inverts forward dynamics: RNEA(q, v, ABA(q, v, τ)) = τ;
//! - the joint-space inertia M(q) is symmetric positive definite, and each column is the
//!   inverse dynamics of a unit acceleration without velocity and gravity (CRBA = RNEA);
//! - the embedded (Voronets) and multiplier forms give the same q̈ on the bundled scenes with
//!   rolling and no-side-slip constraints, at random admissible states and torques;
//! - the velocity projection satisfies its optimality (KKT) conditions: stationarity, J v = 0,
//!   bounds, signs of the bound multipliers and complementarity;
//! - the Lie-group `integrate` and `difference` are inverse to each other;
//! - the energy of random passive scenes is conserved at the method's order (RK4: halving dt
//!   divides the energy error by 2⁴);
//! - Baumgarte gains from a time constant are the critically damped closed form;
//! - a material point's acceleration is J_p q̈ + its bias (the constraints' γ);
//! - gravity's potential energy is −m g·c (centre of mass c), and the A01 pendulum's centre of
//!   mass is its point mass;
//! - the analytic derivatives of forward dynamics (∂q̈/∂q, ∂q̈/∂v, M⁻¹) equal central finite
//!   differences of ABA (the constrained ones are checked on every bundled scene by
//!   `derivatives_fd.rs`, and against Pinocchio's by `derivatives.rs`).
//!
//! Bounded: 64 cases per property (`PROPTEST_CASES` overrides), a fixed seed so that CI runs
//! the same cases (`PROPTEST_RNG_SEED` overrides), no persistence file. Tolerances are set from
//! the worst case over the cases, which each property prints (`-- --nocapture`), with the margin
//! stated next to it.

mod common;
use common::*;

use constraint_dynamics::algorithm::{
    Data, aba, center_of_mass, crba, forward_kinematics, forward_kinematics_pos,
    point_classical_acceleration, point_jacobian, potential_energy, rnea,
};
use constraint_dynamics::constraints::ConstraintSet;
use constraint_dynamics::dynamics::{Baumgarte, Formulation};
use constraint_dynamics::model::JointKind;
use constraint_dynamics::predict::{DriftControl, Method, Predictor};
use constraint_dynamics::projection::{ProjectionProblem, Side, Status, VelocityProjector};
use constraint_dynamics::{BaseType, Model, ModelOptions, Scene, System};
use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};
use std::path::PathBuf;
use std::sync::{Mutex, OnceLock};

/// 64 cases and a fixed seed unless the environment says otherwise.
fn config() -> Config {
    let mut c = Config::default();
    if std::env::var_os("PROPTEST_CASES").is_none() {
        c.cases = 64;
    }
    if std::env::var_os("PROPTEST_RNG_SEED").is_none() {
        c.rng_seed = RngSeed::Fixed(0x00c0_ffee);
    }
    c.failure_persistence = None;
    c
}

/// The worst figure a property reached over its cases, printed when the test ends.
struct Worst(Mutex<f64>, &'static str);
impl Worst {
    const fn new(what: &'static str) -> Self {
        Worst(Mutex::new(0.0), what)
    }
    fn note(&self, x: f64) {
        let mut w = self.0.lock().unwrap();
        *w = w.max(x);
    }
    fn report(&self) {
        eprintln!(
            "achieved {}: {:.2e} (worst case)",
            self.1,
            *self.0.lock().unwrap()
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Robots.

/// Every URDF with each base it is meant for or that makes sense, as (label, model). rod_body is
/// left out: its rod is massless (M is singular by design, seed 000), so M > 0 does not hold.
fn robots() -> &'static Vec<(String, Model)> {
    static R: OnceLock<Vec<(String, Model)>> = OnceLock::new();
    R.get_or_init(|| {
        let bundled = repo_dir().join("urdf");
        let reference = reference_dir().join("urdf");
        let list: [(PathBuf, BaseType); 16] = [
            (bundled.join("diff_drive.urdf"), BaseType::Planar),
            (bundled.join("double_fourbar.urdf"), BaseType::Fixed),
            (bundled.join("fourbar.urdf"), BaseType::Fixed),
            (bundled.join("mobile_manipulator.urdf"), BaseType::Planar),
            (bundled.join("mobile_manipulator.urdf"), BaseType::Floating),
            (bundled.join("pendulum_a01.urdf"), BaseType::Fixed),
            (bundled.join("rolling_disk.urdf"), BaseType::Floating),
            (bundled.join("slider_crank.urdf"), BaseType::Fixed),
            (bundled.join("spring_chain.urdf"), BaseType::Fixed),
            (bundled.join("vertical_disk.urdf"), BaseType::Planar),
            (reference.join("disk.urdf"), BaseType::Floating),
            (reference.join("disk.urdf"), BaseType::Planar),
            (reference.join("fourbar.urdf"), BaseType::Fixed),
            (reference.join("solo12.urdf"), BaseType::Floating),
            (reference.join("ur5_robot.urdf"), BaseType::Fixed),
            (reference.join("ur5_robot.urdf"), BaseType::Floating),
        ];
        list.into_iter()
            .map(|(path, base)| {
                let opts = ModelOptions {
                    base,
                    ..Default::default()
                };
                let model = Model::from_urdf_file(&path, &opts)
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                let name = path.file_name().unwrap().to_string_lossy();
                (format!("{name} ({base:?})"), model)
            })
            .collect()
    })
}

/// A configuration from uniform numbers in [−1, 1): revolute angles in [−π, π), prismatic
/// positions in [−0.5, 0.5) m, free-flyer positions in [−1, 1) m with a unit quaternion, planar
/// (x, y) in [−1, 1) m and yaw in [−π, π).
fn config_from(model: &Model, u: &[f64]) -> Vec<f64> {
    let pi = std::f64::consts::PI;
    let mut q = vec![0.0; model.nq];
    let mut k = 0;
    let mut next = || {
        let x = u[k % u.len()];
        k += 1;
        x
    };
    for b in model.bodies.iter().skip(1) {
        let j = &b.joint;
        let q = &mut q[j.idx_q..j.idx_q + j.kind.nq()];
        match j.kind {
            JointKind::Revolute { .. } => q[0] = pi * next(),
            JointKind::Prismatic { .. } => q[0] = 0.5 * next(),
            JointKind::FreeFlyer => {
                for x in q.iter_mut().take(3) {
                    *x = next();
                }
                // Four numbers kept away from the zero quaternion, then normalised.
                let raw = [next(), next(), next(), 1.5 + next()];
                let n = raw.iter().map(|x| x * x).sum::<f64>().sqrt();
                for i in 0..4 {
                    q[3 + i] = raw[i] / n;
                }
            }
            JointKind::Planar => {
                q[0] = next();
                q[1] = next();
                q[2] = pi * next();
            }
        }
    }
    q
}

fn scaled(u: &[f64], n: usize, scale: f64) -> Vec<f64> {
    (0..n).map(|i| scale * u[i % u.len()]).collect()
}

/// Random inputs: a robot index and three blocks of uniform numbers (q, v, τ).
fn robot_inputs() -> impl Strategy<Value = (usize, Vec<f64>, Vec<f64>, Vec<f64>)> {
    let n = robots().len();
    let block = || prop::collection::vec(-1.0f64..1.0, 32);
    (0..n, block(), block(), block())
}

// ---------------------------------------------------------------------------------------------
// RNEA ∘ ABA = id, M symmetric positive definite, CRBA = RNEA columns.

static RNEA_ABA: Worst = Worst::new("|RNEA(q, v, ABA(q, v, τ)) − τ| / max(1, |τ|)");
static M_COLS: Worst = Worst::new("|M e_i − (RNEA(q, 0, e_i) − RNEA(q, 0, 0))| / max(1, |M|)");
static M_COND: Worst = Worst::new("condition number of M (largest over the cases, informative)");

proptest! {
    #![proptest_config(config())]

    /// τ is drawn in [−10, 10) per coordinate, v in [−3, 3).
    #[test]
    fn rnea_inverts_aba((r, uq, uv, ut) in robot_inputs()) {
        let (name, model) = &robots()[r];
        let mut data = Data::new(model);
        let q = config_from(model, &uq);
        let v = scaled(&uv, model.nv, 3.0);
        let tau = scaled(&ut, model.nv, 10.0);
        let qdd = aba(model, &mut data, &q, &v, &tau).clone();
        let back = rnea(model, &mut data, &q, &v, qdd.as_slice()).clone();
        let e = rel_err(back.as_slice(), &tau);
        RNEA_ABA.note(e);
        // Worst case over the 64 cases: 2.8e-14; tol 1e-12.
        prop_assert!(e <= 1e-12, "{name}: RNEA(ABA(τ)) − τ: {e:e}");
    }

    #[test]
    fn mass_matrix_is_symmetric_positive_definite_and_equals_rnea_columns(
        (r, uq, _uv, _ut) in robot_inputs()
    ) {
        let (name, model) = &robots()[r];
        let mut data = Data::new(model);
        let q = config_from(model, &uq);
        let m = crba(model, &mut data, &q).clone();
        // Each entry is written to both triangles: exactly symmetric.
        prop_assert_eq!((&m - m.transpose()).amax(), 0.0, "{}: M not symmetric", name);
        let eig = m.clone().symmetric_eigen().eigenvalues;
        let (lo, hi) = (eig.min(), eig.max());
        prop_assert!(lo > 0.0, "{}: M not positive definite, eigenvalues {:?}", name, eig);
        M_COND.note(hi / lo);
        // Columns from inverse dynamics at v = 0 without gravity: M e_i = RNEA(q, 0, e_i) − RNEA(q, 0, 0).
        let mut no_g = model.clone();
        no_g.gravity = nalgebra::Vector3::zeros();
        let zero = vec![0.0; model.nv];
        let h0 = rnea(&no_g, &mut data, &q, &zero, &zero).clone();
        let mut worst: f64 = 0.0;
        for i in 0..model.nv {
            let mut e_i = zero.clone();
            e_i[i] = 1.0;
            let col = rnea(&no_g, &mut data, &q, &zero, &e_i).clone() - &h0;
            worst = worst.max((col - m.column(i)).amax());
        }
        let e = worst / m.amax().max(1.0);
        M_COLS.note(e);
        // Worst case: 8.9e-16; tol 5e-14.
        prop_assert!(e <= 5e-14, "{}: CRBA vs RNEA columns {:e}", name, e);
    }
}

static POINT_ACC: Worst =
    Worst::new("|a_p(q, v, q̈) − a_p(q, v, 0) − J_p q̈| / max(1, |J_p q̈|) (point acceleration)");

proptest! {
    #![proptest_config(config())]

    /// The classical acceleration of a material point is affine in q̈ with the point Jacobian as
    /// slope: a_p(q, v, q̈) = J_p(q) q̈ + a_p(q, v, 0) (the second term is the constraints' γ).
    /// Random robot, frame, point in [−0.5, 0.5)³ m, v ∈ [−3, 3), q̈ ∈ [−10, 10).
    #[test]
    fn point_acceleration_is_jacobian_times_qdd_plus_bias(
        (r, uq, uv, ua) in robot_inputs(),
        f in 0usize..1000,
        p in prop::array::uniform3(-0.5f64..0.5),
    ) {
        let (name, model) = &robots()[r];
        let mut data = Data::new(model);
        let q = config_from(model, &uq);
        let v = scaled(&uv, model.nv, 3.0);
        let a = scaled(&ua, model.nv, 10.0);
        let frame = f % model.frames.len();
        let p = nalgebra::Vector3::from(p);
        forward_kinematics(model, &mut data, &q, &v, &a);
        let with_a = point_classical_acceleration(model, &data, frame, &p);
        forward_kinematics(model, &mut data, &q, &v, &vec![0.0; model.nv]);
        let bias = point_classical_acceleration(model, &data, frame, &p);
        let mut j = DMatrix::zeros(3, model.nv);
        point_jacobian(model, &data, frame, &p, &mut j, 0);
        let ja = &j * DVector::from_vec(a);
        let e = rel_err((with_a - bias).as_slice(), ja.as_slice());
        POINT_ACC.note(e);
        // Worst case: 9.1e-16; tol 5e-14.
        prop_assert!(e <= 5e-14, "{}, frame {}: {:e}", name, model.frames[frame].name, e);
    }
}

static PEND_COM: Worst = Worst::new("A01 centre of mass vs (cos q, 0, −sin q)");
static COM_PE: Worst =
    Worst::new("|PE + m g·c| / max(1, |PE|) (centre of mass vs potential energy)");

proptest! {
    #![proptest_config(config())]

    /// Gravity's potential energy is −m g·c with c the centre of mass: `potential_energy` sums
    /// −m_i g·c_i body by body, `center_of_mass` averages the c_i, so each checks the other.
    #[test]
    fn potential_energy_is_minus_m_g_dot_centre_of_mass((r, uq, _uv, _ut) in robot_inputs()) {
        let (name, model) = &robots()[r];
        let mut data = Data::new(model);
        let q = config_from(model, &uq);
        forward_kinematics_pos(model, &mut data, &q);
        let pe = potential_energy(model, &data);
        let c = center_of_mass(model, &data);
        let e = (pe + model.total_mass() * model.gravity.dot(&c)).abs() / pe.abs().max(1.0);
        COM_PE.note(e);
        // Worst case: 4.2e-16; tol 2e-14.
        prop_assert!(e <= 2e-14, "{}: PE {} vs −m g·c {:e}", name, pe, e);
    }

    /// IFToMM A01: the point mass (1 kg, 1 m from the hinge, the link massless) is the centre
    /// of mass: c = (cos q, 0, −sin q) for the angle q from the horizontal.
    #[test]
    fn pendulum_centre_of_mass_is_the_point_mass(q in -10.0f64..10.0) {
        let scene = Scene::load(repo_dir().join("params/pendulum_a01.yaml")).unwrap();
        let mut data = Data::new(&scene.model);
        forward_kinematics_pos(&scene.model, &mut data, &[q]);
        let c = center_of_mass(&scene.model, &data);
        let e = rel_err(c.as_slice(), &[q.cos(), 0.0, -q.sin()]);
        PEND_COM.note(e);
        // Achieved 0 (cos, sin of the same angle); floor 1e-15.
        prop_assert!(e <= 1e-15, "q = {}: c = {:?}", q, c);
    }
}

/// A robot without mass has its centre of mass at the origin (not NaN).
#[test]
fn massless_robot_has_its_centre_of_mass_at_the_origin() {
    let urdf = r#"<robot name="ghost"><link name="base"/><link name="arm"/>
      <joint name="j" type="revolute"><parent link="base"/><child link="arm"/>
        <origin xyz="0.3 0 0"/><axis xyz="0 0 1"/><limit lower="-1" upper="1"/></joint></robot>"#;
    let model = Model::from_urdf_str(urdf, "ghost.urdf", &ModelOptions::default()).unwrap();
    let mut data = Data::new(&model);
    forward_kinematics_pos(&model, &mut data, &[0.4]);
    let c = center_of_mass(&model, &data);
    assert_eq!([c.x, c.y, c.z], [0.0; 3]);
}

// ---------------------------------------------------------------------------------------------
// Embedded and multiplier forms on the bundled scenes with rolling / no-side-slip constraints.

/// Scenes whose constraints include rolling or no-side-slip rows.
fn rolling_scenes() -> &'static Vec<Scene> {
    static S: OnceLock<Vec<Scene>> = OnceLock::new();
    S.get_or_init(|| {
        let mut found = vec![];
        for dir in [repo_dir().join("params"), repo_dir().join("params/report")] {
            let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
                .unwrap()
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == "yaml"))
                .collect();
            paths.sort();
            for p in paths {
                let text = std::fs::read_to_string(&p).unwrap();
                if text.contains("ros__parameters") || !text.contains("urdf:") {
                    continue;
                }
                if !(text.contains("kind: rolling") || text.contains("kind: no_side_slip")) {
                    continue;
                }
                found.push(Scene::load(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display())));
            }
        }
        assert!(found.len() >= 5, "rolling scenes: {}", found.len());
        found
    })
}

/// An orthonormal basis (columns) of the null space of `j`.
fn null_space(j: &DMatrix<f64>) -> DMatrix<f64> {
    let nv = j.ncols();
    if j.nrows() == 0 {
        return DMatrix::identity(nv, nv);
    }
    // Pad to a square matrix so that the SVD returns all nv right singular vectors.
    let mut a = DMatrix::zeros(nv.max(j.nrows()), nv);
    a.view_mut((0, 0), (j.nrows(), nv)).copy_from(j);
    let svd = a.svd(false, true);
    let vt = svd.v_t.unwrap();
    let smax = svd.singular_values.max();
    let cols: Vec<_> = (0..nv)
        .filter(|&k| svd.singular_values[k] <= 1e-10 * smax.max(1.0))
        .map(|k| vt.row(k).transpose())
        .collect();
    DMatrix::from_columns(&cols)
}

/// A configuration near the scene's q0 that keeps every rolling contact on its plane: the base
/// moved in x, y and turned about the world z axis, joints (wheels, arm) at random angles.
fn perturbed_config(scene: &Scene, u: &[f64]) -> Vec<f64> {
    let model = &scene.model;
    let mut q = scene.q0.clone();
    let pi = std::f64::consts::PI;
    for (k, b) in model.bodies.iter().skip(1).enumerate() {
        let j = &b.joint;
        let q = &mut q[j.idx_q..j.idx_q + j.kind.nq()];
        let x = |i: usize| u[(3 * k + i) % u.len()];
        match j.kind {
            JointKind::Revolute { .. } => q[0] += pi * x(0),
            JointKind::Prismatic { .. } => {}
            JointKind::Planar => {
                q[0] += x(0);
                q[1] += x(1);
                q[2] += pi * x(2);
            }
            JointKind::FreeFlyer => {
                q[0] += x(0);
                q[1] += x(1);
                let yaw = nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, pi * x(2));
                let q0 = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                    q[6], q[3], q[4], q[5],
                ));
                let r = yaw * q0;
                q[3..7].copy_from_slice(&[r.i, r.j, r.k, r.w]);
            }
        }
    }
    q
}

static FORMS: Worst = Worst::new("|q̈ embedded − q̈ multipliers| / max(1, |q̈|)");

proptest! {
    #![proptest_config(config())]

    /// Admissible v (J v = 0) of size up to ~5 per null-space direction, τ in [−5, 5).
    #[test]
    fn embedded_and_multiplier_forms_agree_on_rolling_scenes(
        s in 0..rolling_scenes().len(),
        uq in prop::collection::vec(-1.0f64..1.0, 32),
        uv in prop::collection::vec(-1.0f64..1.0, 32),
        ut in prop::collection::vec(-1.0f64..1.0, 32),
    ) {
        let scene = &rolling_scenes()[s];
        let mut sys = System::from_scene(scene).unwrap();
        let nv = sys.model.nv;
        let q = perturbed_config(scene, &uq);
        sys.formulation = Formulation::Multipliers;
        sys.forward_dynamics(&q, &vec![0.0; nv], &vec![0.0; nv], true).unwrap();
        let n = null_space(&sys.cdata.j);
        let v = &n * DVector::from_iterator(n.ncols(), (0..n.ncols()).map(|i| 5.0 * uv[i % 32]));
        let tau = scaled(&ut, nv, 5.0);
        let a = sys.forward_dynamics(&q, v.as_slice(), &tau, true).unwrap().clone();
        prop_assert!(sys.cdata.jv.amax() <= 1e-12 * (1.0 + v.amax()), "J v = {}", sys.cdata.jv);
        sys.formulation = Formulation::Embedded;
        let b = sys.forward_dynamics(&q, v.as_slice(), &tau, false).unwrap().clone();
        let e = rel_err(b.as_slice(), a.as_slice());
        FORMS.note(e);
        // Worst case: 1.9e-14; tol 1e-12.
        prop_assert!(e <= 1e-12, "{}: embedded vs multipliers {:e}", scene.path.display(), e);
    }
}

// ---------------------------------------------------------------------------------------------
// Velocity projection: KKT conditions.

/// The systems the projection is tried on: UR5 (end effector held) and Solo12 (four feet) from
/// the reference cases, the mobile manipulator and the differential drive from `params/`.
fn projection_systems() -> &'static Vec<(String, System)> {
    static S: OnceLock<Vec<(String, System)>> = OnceLock::new();
    S.get_or_init(|| {
        let mut out = vec![];
        for name in ["ur5_ee_point", "solo12_four_feet"] {
            let case = load_case(name);
            let model = case_model(&case);
            let st = &case["states"][0];
            let q = vecf(&st["q"]);
            let set = ConstraintSet::new(&model, &specs_for(&case, st), &q).unwrap();
            out.push((
                name.to_string(),
                System::new(model, set, Baumgarte::default(), Formulation::Multipliers),
            ));
        }
        for name in ["mobile_manipulator.yaml", "diff_drive.yaml"] {
            let scene = Scene::load(repo_dir().join("params").join(name)).unwrap();
            out.push((name.to_string(), System::from_scene(&scene).unwrap()));
        }
        out
    })
}

static KKT_STAT: Worst =
    Worst::new("projection stationarity |M(v − v_des) − Jᵀλ − ν| / max(1, |M v_des|)");
static KKT_JV: Worst = Worst::new("projection |J v|");
static KKT_BOUND: Worst =
    Worst::new("projection bound violation or gap on an active bound (relative)");
static KKT_SIGN: Worst = Worst::new("projection wrong-sign ν on an active bound");
static KKT_COMPL: Worst = Worst::new("projection |ν| on an inactive bound");

proptest! {
    #![proptest_config(config())]

    /// Random configuration, v_des in [−3, 3) and a random subset of bounds that always admits
    /// v = 0 (lo ≤ 0 ≤ hi, some lo = hi = 0), so every problem is feasible.
    #[test]
    fn projection_satisfies_its_kkt_conditions(
        s in 0..4usize,
        uq in prop::collection::vec(-1.0f64..1.0, 32),
        ud in prop::collection::vec(-1.0f64..1.0, 32),
        ub in prop::collection::vec(0.0f64..1.0, 64),
    ) {
        let (name, sys0) = &projection_systems()[s];
        let mut sys = sys0.clone();
        let model = sys.model.clone();
        let nv = model.nv;
        let q = config_from(&model, &uq);
        let mut p = ProjectionProblem::new(&model);
        p.v_des = scaled(&ud, nv, 3.0);
        for i in 0..nv {
            let (u, w) = (ub[2 * i], ub[2 * i + 1]);
            if u < 0.3 {
                p.upper[i] = 0.2 + 2.0 * w;
            } else if u < 0.6 {
                p.lower[i] = -0.2 - 2.0 * w;
            } else if u < 0.8 {
                p.upper[i] = 0.1 + w;
                p.lower[i] = -0.1 - w;
            } else if u < 0.85 {
                p.lower[i] = 0.0;
                p.upper[i] = 0.0;
            }
        }
        let mut proj = VelocityProjector::new(&model, &sys.constraints);
        let o = proj
            .project(&model, &mut sys.data, &sys.constraints, &mut sys.cdata, &q, &p)
            .unwrap();
        prop_assert_eq!(o.status, Status::Optimal, "{}: {:?}", name, o);
        // The projection leaves M(q) and J(q) in the workspaces.
        let m = &sys.data.mass_matrix;
        let j = &sys.cdata.j;
        let v = &proj.v;
        let dv = DVector::from_iterator(nv, (0..nv).map(|i| v[i] - p.v_des[i]));
        let stat = m * dv - j.transpose() * &proj.lambda - &proj.nu;
        let scale = (m * DVector::from_vec(p.v_des.clone())).amax().max(1.0);
        let (e_stat, e_jv) = (stat.amax() / scale, (j * v).amax());
        let mut active = vec![false; nv];
        let (mut e_bound, mut e_sign, mut e_compl): (f64, f64, f64) = (0.0, 0.0, 0.0);
        for (i, side) in proj.active_bounds() {
            active[i] = true;
            let (b, _) = proj.bound(i, side);
            e_bound = e_bound.max((v[i] - b).abs() / (1.0 + b.abs()));
            if proj.bound(i, Side::Lower).0 != proj.bound(i, Side::Upper).0 {
                let wrong = if side == Side::Lower { -proj.nu[i] } else { proj.nu[i] };
                e_sign = e_sign.max(wrong);
            }
        }
        for i in 0..nv {
            let (lo, _) = proj.bound(i, Side::Lower);
            let (hi, _) = proj.bound(i, Side::Upper);
            e_bound = e_bound.max((lo - v[i]) / (1.0 + lo.abs())).max((v[i] - hi) / (1.0 + hi.abs()));
            if !active[i] {
                e_compl = e_compl.max(proj.nu[i].abs());
            }
        }
        KKT_STAT.note(e_stat);
        KKT_JV.note(e_jv);
        KKT_BOUND.note(e_bound);
        KKT_SIGN.note(e_sign);
        KKT_COMPL.note(e_compl);
        // Worst cases: stationarity 7.1e-16 (tol 5e-14), |J v| 7.6e-14 (tol 5e-12), bounds
        // 7.8e-13 (tol 5e-11); wrong signs and complementarity exactly 0 (tol 0).
        prop_assert!(e_stat <= 5e-14, "{}: stationarity {:e}", name, e_stat);
        prop_assert!(e_jv <= 5e-12, "{}: J v {:e}", name, e_jv);
        prop_assert!(e_bound <= 5e-11, "{}: bounds {:e}", name, e_bound);
        prop_assert!(e_sign <= 0.0, "{}: wrong-sign multiplier {:e}", name, e_sign);
        prop_assert!(e_compl <= 0.0, "{}: complementarity {:e}", name, e_compl);
    }
}

// ---------------------------------------------------------------------------------------------
// Lie groups.

static LIE_DIFF: Worst = Worst::new("|difference(q, integrate(q, v, dt)) − v dt| / max(1, |v dt|)");
static LIE_INT: Worst = Worst::new("|integrate(q0, difference(q0, q1), 1) ⊖ q1|");

proptest! {
    #![proptest_config(config())]

    /// v dt with every rotation angle below π (dt ∈ [0.01, 1), |v| < 1.8 per coordinate, so
    /// |ω dt| < 1.8·√3 < π for a free-flyer; beyond π `difference` takes the shorter way round): `difference` recovers exactly the `integrate`d
    /// step, and `integrate` of a `difference` lands on the target.
    #[test]
    fn integrate_and_difference_are_inverse(
        (r, uq, uv, ut) in robot_inputs(),
        dt in 0.01f64..1.0,
    ) {
        let (name, model) = &robots()[r];
        let q0 = config_from(model, &uq);
        let v = scaled(&uv, model.nv, 1.8);
        let mut q1 = vec![0.0; model.nq];
        model.integrate(&q0, &v, dt, &mut q1);
        let mut d = vec![0.0; model.nv];
        model.difference(&q0, &q1, &mut d);
        let vdt: Vec<f64> = v.iter().map(|x| x * dt).collect();
        let e = rel_err(&d, &vdt);
        LIE_DIFF.note(e);
        // Worst case: 1.1e-15; tol 5e-14.
        prop_assert!(e <= 5e-14, "{}: difference(integrate) {:e}", name, e);

        // The other way: from q0 to an unrelated q2 (rotations below π apart are not needed:
        // `difference` takes the shortest path and `integrate` follows it).
        let q2 = config_from(model, &ut);
        model.difference(&q0, &q2, &mut d);
        let mut q3 = vec![0.0; model.nq];
        model.integrate(&q0, &d, 1.0, &mut q3);
        let mut back = vec![0.0; model.nv];
        model.difference(&q2, &q3, &mut back);
        let e = back.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        LIE_INT.note(e);
        // Worst case: 1.2e-15 (the distance measured on the group, free of the quaternion's
        // sign); tol 5e-14.
        prop_assert!(e <= 5e-14, "{}: integrate(difference) {:e}", name, e);
    }
}

// ---------------------------------------------------------------------------------------------
// Energy at the method's order.

/// Passive scenes (no actuator, conservative forces) and a torque-free asymmetric rigid body.
fn passive_scenes() -> &'static Vec<Scene> {
    static S: OnceLock<Vec<Scene>> = OnceLock::new();
    S.get_or_init(|| {
        let mut out: Vec<Scene> = ["pendulum_a01.yaml", "fourbar.yaml", "double_fourbar.yaml", "slider_crank.yaml"]
            .iter()
            .map(|n| Scene::load(repo_dir().join("params").join(n)).unwrap())
            .collect();
        let urdf = r#"<robot name="free_body"><link name="body"><inertial>
          <origin xyz="0 0 0" rpy="0 0 0"/><mass value="2.0"/>
          <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.3"/></inertial></link></robot>"#;
        let file = serde_yaml::from_str("urdf: free_body.urdf\nbase: floating\ngravity: [0.0, 0.0, 0.0]\n").unwrap();
        out.push(Scene::from_parts(&PathBuf::from("free_body.yaml"), file, urdf, "free_body.urdf").unwrap());
        for sc in &out {
            let p = Predictor::from_scene(sc).unwrap();
            assert!(p.actuators.is_empty() && p.forces.is_conservative(), "{}", sc.path.display());
        }
        out
    })
}

static ORDER: Worst = Worst::new("|observed RK4 energy order − 4|");

proptest! {
    #![proptest_config(config())]

    /// From the scene's configuration with a random admissible velocity (each null-space
    /// direction of J scaled in [−2, 2) rad/s or m/s; the free body tumbles at up to 6 rad/s
    /// about each axis), RK4 over 1 s without drift control at dt = 5 ms and 2.5 ms: the
    /// mean energy error over the samples drops by 2⁴ (observed order log2(e(dt)/e(dt/2)) = 4).
    #[test]
    fn energy_error_of_passive_scenes_has_the_method_order(
        s in 0..5usize,
        uv in prop::collection::vec(-1.0f64..1.0, 8),
    ) {
        let scene = &passive_scenes()[s];
        let mut sys = System::from_scene(scene).unwrap();
        let nv = sys.model.nv;
        sys.forward_dynamics(&scene.q0, &vec![0.0; nv], &vec![0.0; nv], true).unwrap();
        let n = null_space(&sys.cdata.j);
        // Each null-space direction at a speed of magnitude in [s/2, s) (s = 2, or 6 rad/s for
        // the free body) so that the error is well above round-off; the step per scene keeps
        // it in RK4's asymptotic range.
        let (scale, dt0) = match scene.path.file_name().unwrap().to_str().unwrap() {
            "free_body.yaml" => (6.0, 2.5e-3),
            "pendulum_a01.yaml" => (2.0, 1e-2),
            _ => (2.0, 5e-3),
        };
        let speed = |u: f64| scale * u.signum() * (0.5 + 0.5 * u.abs());
        let v0 = &n * DVector::from_iterator(n.ncols(), (0..n.ncols()).map(|i| speed(uv[i % 8])));
        let mut errors = vec![];
        for dt in [dt0, dt0 / 2.0] {
            let mut p = Predictor::from_scene(scene).unwrap();
            p.settings.method = Method::Rk4;
            p.settings.dt = dt;
            p.settings.drift = DriftControl::None;
            p.settings.sample_period = 0.01;
            let t = p.predict(&scene.q0, v0.as_slice(), &[], 1.0).unwrap();
            let e0 = t.samples[0].kinetic_energy + t.samples[0].potential_energy;
            // ΔE_h(t) = h⁴ C(t) + O(h⁵) at every sample time: the sum of |ΔE| over the
            // samples (the same times for both steps) scales as h⁴ too, and unlike the
            // maximum it does not jump between the peaks of an oscillating error.
            errors.push(
                t.samples
                    .iter()
                    .map(|x| (x.kinetic_energy + x.potential_energy - e0).abs())
                    .sum::<f64>()
                    / t.samples.len() as f64,
            );
        }
        // A state whose energy error at dt/2 is within 100× of round-off (~1e-12 J over the
        // run) has no order to measure (e.g. a body turning about a principal axis, whose
        // motion RK4 follows almost exactly): such draws are rejected and replaced.
        prop_assume!(errors[1] > 1e-10);
        let order = (errors[0] / errors[1]).log2();
        ORDER.note((order - 4.0).abs());
        // Worst case over the cases: |order − 4| = 0.33 (the free body; 0.13 on the others);
        // tol 0.5.
        prop_assert!(
            (order - 4.0).abs() <= 0.5,
            "{}: errors {:?}, observed order {}",
            scene.path.display(),
            errors,
            order
        );
    }

    /// Baumgarte gains for a time constant T: K_d = 2/T, K_p = 1/T², critically damped
    /// (K_d² = 4 K_p, a double root −1/T of s² + K_d s + K_p).
    #[test]
    fn baumgarte_gains_are_critically_damped(t in 1e-3f64..10.0) {
        let b = Baumgarte::from_time_constant(t);
        prop_assert!((b.kd - 2.0 / t).abs() <= 1e-15 * b.kd, "K_d {} for T = {}", b.kd, t);
        prop_assert!((b.kp - 1.0 / (t * t)).abs() <= 1e-15 * b.kp, "K_p {} for T = {}", b.kp, t);
        prop_assert!((b.kd * b.kd - 4.0 * b.kp).abs() <= 1e-14 * b.kd * b.kd);
    }
}

// ---------------------------------------------------------------------------------------------
// Analytic derivatives = finite differences.

static DERIV: Worst = Worst::new(
    "|∂q̈/∂(q, v, τ) − finite differences| / max(1, |finite differences|) (ABA derivatives)",
);

/// Central differences of ABA along each coordinate: q on the Lie group (q ⊕ h e_j), h and h/2
/// combined by Richardson extrapolation (error O(h⁴)); v and τ with h = 1, exact up to rounding
/// because q̈ is quadratic in v and linear in τ.
fn aba_differences(model: &Model, q: &[f64], v: &[f64], tau: &[f64]) -> [DMatrix<f64>; 3] {
    let nv = model.nv;
    let mut data = Data::new(model);
    let mut out = [
        DMatrix::zeros(nv, nv),
        DMatrix::zeros(nv, nv),
        DMatrix::zeros(nv, nv),
    ];
    let mut qp = vec![0.0; model.nq];
    for j in 0..nv {
        let mut e = vec![0.0; nv];
        e[j] = 1.0;
        let mut on_q = |t: f64| {
            model.integrate(q, &e, t, &mut qp);
            aba(model, &mut data, &qp, v, tau).clone()
        };
        let central = |f: &mut dyn FnMut(f64) -> DVector<f64>, h: f64| (f(h) - f(-h)) / (2.0 * h);
        let h = 5e-4;
        let (d1, d2) = (central(&mut on_q, h), central(&mut on_q, h / 2.0));
        out[0].set_column(j, &((d2 * 4.0 - d1) / 3.0));
        let mut vp = v.to_vec();
        let mut on_v = |t: f64| {
            vp[j] = v[j] + t;
            aba(model, &mut data, q, &vp, tau).clone()
        };
        out[1].set_column(j, &central(&mut on_v, 1.0));
        let mut tp = tau.to_vec();
        let mut on_tau = |t: f64| {
            tp[j] = tau[j] + t;
            aba(model, &mut data, q, v, &tp).clone()
        };
        out[2].set_column(j, &central(&mut on_tau, 1.0));
    }
    out
}

proptest! {
    #![proptest_config(config())]

    /// ∂q̈/∂q, ∂q̈/∂v and M⁻¹ of `aba_derivatives` at random robots and states (v in [−3, 3),
    /// τ in [−10, 10)) against central differences of ABA itself.
    #[test]
    fn aba_derivatives_equal_finite_differences((r, uq, uv, ut) in robot_inputs()) {
        use constraint_dynamics::derivatives::{DerivativeData, aba_derivatives};
        let (name, model) = &robots()[r];
        let q = config_from(model, &uq);
        let v = scaled(&uv, model.nv, 3.0);
        let tau = scaled(&ut, model.nv, 10.0);
        let mut data = Data::new(model);
        let mut dd = DerivativeData::new(model, 0);
        aba_derivatives(model, &mut data, &mut dd, &q, &v, &tau).unwrap();
        let fd = aba_differences(model, &q, &v, &tau);
        for (what, ours, fd) in [("dqdd_dq", &dd.dqdd_dq, &fd[0]), ("dqdd_dv", &dd.dqdd_dv, &fd[1]), ("Minv", &dd.minv, &fd[2])] {
            let e = (ours - fd).amax() / fd.amax().max(1.0);
            DERIV.note(e);
            // Worst case over the 64 cases: 1.21e-9 (the differences' own O(h⁴) error on
            // q; v and τ reach rounding); tol 1e-7.
            prop_assert!(e <= 1e-7, "{}: {} differs from finite differences by {:e}", name, what, e);
        }
    }
}

/// Prints the worst figures of every property (run with `-- --nocapture --test-threads=1` after
/// the others to read them; in a parallel run the figures of properties still running are 0).
#[test]
fn zz_report_worst_figures() {
    for w in [
        &RNEA_ABA, &M_COLS, &M_COND, &POINT_ACC, &COM_PE, &PEND_COM, &FORMS, &KKT_STAT, &KKT_JV,
        &KKT_BOUND, &KKT_SIGN, &KKT_COMPL, &LIE_DIFF, &LIE_INT, &ORDER, &DERIV,
    ] {
        w.report();
    }
}
