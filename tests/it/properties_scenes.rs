//! Property tests (proptest) on the bundled scenes (`params/`), checked against identities that
//! hold for every input, not against numbers of this code:
//!
//! - the embedded (Voronets) and multiplier forms give the same q̈ on the bundled scenes with
//!   rolling and no-side-slip constraints, at random admissible states and torques;
//! - the velocity projection satisfies its optimality (KKT) conditions: stationarity, J v = 0,
//!   bounds, signs of the bound multipliers and complementarity;
//! - the energy of random passive scenes is conserved at the method's order (RK4: halving dt
//!   divides the energy error by 2⁴);
//! - Baumgarte gains from a time constant are the critically damped closed form.
//!
//! Bounded as `properties.rs` (64 cases, a fixed seed; `PROPTEST_CASES`, `PROPTEST_RNG_SEED`).
//! Tolerances are set from the worst case over the cases, which each property prints
//! (`-- --nocapture`), with the margin stated next to it.

use crate::common;
use common::*;

use constraint_dynamics::actuators::Actuators;
use constraint_dynamics::constraints::ConstraintSet;
use constraint_dynamics::dynamics::{Baumgarte, Formulation};
use constraint_dynamics::forces::ForceElements;
use constraint_dynamics::model::JointKind;
use constraint_dynamics::predict::{DriftControl, Method, PredictionRequest, Predictor};
use constraint_dynamics::projection::{ProjectionProblem, Side, Status, VelocityProjector};
use constraint_dynamics::{Scene, System};
use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use std::path::PathBuf;
use std::sync::OnceLock;

use crate::properties_support;
use properties_support::*;

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
        let nv = sys.model().nv;
        let q = perturbed_config(scene, &uq);
        sys = sys.with_formulation(Formulation::Multipliers);
        sys.forward_dynamics(&q, &vec![0.0; nv], &vec![0.0; nv], true).unwrap();
        let n = null_space(&sys.rows().j);
        let v = &n * DVector::from_iterator(n.ncols(), (0..n.ncols()).map(|i| 5.0 * uv[i % 32]));
        let tau = scaled(&ut, nv, 5.0);
        let a = sys.forward_dynamics(&q, v.as_slice(), &tau, true).unwrap().clone();
        prop_assert!(sys.rows().jv.amax() <= 1e-12 * (1.0 + v.amax()), "J v = {}", sys.rows().jv);
        sys = sys.with_formulation(Formulation::Embedded);
        let b = sys.forward_dynamics(&q, v.as_slice(), &tau, false).unwrap().clone();
        let e = rel_err(b.as_slice(), a.as_slice());
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
        let (name, sys) = &projection_systems()[s];
        let (mut data, mut cd, _) = workspaces(sys);
        let model = sys.model().clone();
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
        let mut proj = VelocityProjector::new(&model, sys.constraints());
        let o = proj
            .project(&model, &mut data, sys.constraints(), &mut cd, &q, &p)
            .unwrap();
        prop_assert_eq!(o.status, Status::Optimal, "{}: {:?}", name, o);
        // The projection leaves M(q) and J(q) in the workspaces.
        let m = &data.mass_matrix;
        let j = &cd.j;
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
            Predictor::from_scene(sc).unwrap();
            let actuators = Actuators::new(&sc.model, &sc.file.actuators).unwrap();
            let forces = ForceElements::new(&sc.model, &sc.file.forces).unwrap();
            assert!(actuators.is_empty() && forces.is_conservative(), "{}", sc.path.display());
        }
        out
    })
}

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
        let nv = sys.model().nv;
        sys.forward_dynamics(&scene.q0, &vec![0.0; nv], &vec![0.0; nv], true).unwrap();
        let n = null_space(&sys.rows().j);
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
            let mut p = Predictor::from_scene(scene)
                .unwrap()
                .with_settings(|s| {
                    s.method = Method::Rk4;
                    s.dt = dt;
                    s.drift = DriftControl::None;
                    s.sample_period = 0.01;
                })
                .unwrap();
            let t = p.predict(&PredictionRequest::new(&scene.q0, v0.as_slice()).horizon(1.0)).unwrap();
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
