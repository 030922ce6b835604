//! Property tests (proptest): random robots and states drawn from the bundled URDFs and scenes
//! (`urdf/`, `params/`) and the reference URDFs (`../shared/reference/urdf/`), checked against
//! identities that hold for every input, not against numbers of this code:
//!
//! - inverse dynamics inverts forward dynamics: RNEA(q, v, ABA(q, v, τ)) = τ;
//! - the joint-space inertia M(q) is symmetric positive definite, and each column is the
//!   inverse dynamics of a unit acceleration without velocity and gravity (CRBA = RNEA);
//! - the Lie-group `integrate` and `difference` are inverse to each other;
//! - a material point's acceleration is J_p q̈ + its bias (the constraints' γ);
//! - gravity's potential energy is −m g·c (centre of mass c), and the A01 pendulum's centre of
//!   mass is its point mass;
//! - the analytic derivatives of forward dynamics (∂q̈/∂q, ∂q̈/∂v, M⁻¹) equal central finite
//!   differences of ABA (the constrained ones are checked on every bundled scene by
//!   `derivatives_fd.rs`, and against Pinocchio's by `derivatives.rs`).
//!
//! The properties of the bundled scenes (the two forms, the projection's KKT conditions, energy
//! at the method's order, Baumgarte gains) are in `properties_scenes.rs`.
//!
//! Bounded: 64 cases per property (`PROPTEST_CASES` overrides), a fixed seed so that CI runs
//! the same cases (`PROPTEST_RNG_SEED` overrides), no persistence file. Tolerances are set from
//! the worst case over the cases, which each property prints (`-- --nocapture`), with the margin
//! stated next to it.

use crate::common;
use common::*;

use constraint_dynamics::algorithm::{
    Data, aba, center_of_mass, crba, crba_full, forward_kinematics, forward_kinematics_pos,
    point_classical_acceleration, point_jacobian, potential_energy, rnea,
};
use constraint_dynamics::{BaseType, Model, ModelOptions, Scene};
use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use std::path::PathBuf;
use std::sync::OnceLock;

use crate::properties_support;
use properties_support::*;

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

/// Random inputs: a robot index and three blocks of uniform numbers (q, v, τ).
fn robot_inputs() -> impl Strategy<Value = (usize, Vec<f64>, Vec<f64>, Vec<f64>)> {
    let n = robots().len();
    let block = || prop::collection::vec(-1.0f64..1.0, 32);
    (0..n, block(), block(), block())
}

// ---------------------------------------------------------------------------------------------
// RNEA ∘ ABA = id, M symmetric positive definite, CRBA = RNEA columns.

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
        // Worst case over the 64 cases: 2.8e-14; tol 1e-12.
        prop_assert!(e <= 1e-12, "{name}: RNEA(ABA(τ)) − τ: {e:e}");
    }

    /// `crba` writes M's lower triangle and leaves the strict upper one as it was (NaN here);
    /// `crba_full` mirrors it. Both against M's columns from inverse dynamics.
    #[test]
    fn mass_matrix_is_symmetric_positive_definite_and_equals_rnea_columns(
        (r, uq, _uv, _ut) in robot_inputs()
    ) {
        let (name, model) = &robots()[r];
        let mut data = Data::new(model);
        let q = config_from(model, &uq);
        for c in 1..model.nv {
            for row in 0..c {
                data.mass_matrix[(row, c)] = f64::NAN;
            }
        }
        let lower = crba(model, &mut data, &q).clone();
        let upper_kept = (1..model.nv).all(|c| (0..c).all(|row| lower[(row, c)].is_nan()));
        prop_assert!(upper_kept, "{}: crba wrote above the diagonal", name);
        let m = crba_full(model, &mut data, &q).clone();
        // The upper triangle is the lower one mirrored: exactly symmetric.
        prop_assert_eq!((&m - m.transpose()).amax(), 0.0, "{}: M not symmetric", name);
        let eig = m.clone().symmetric_eigen().eigenvalues;
        let lo = eig.min();
        prop_assert!(lo > 0.0, "{}: M not positive definite, eigenvalues {:?}", name, eig);
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
            for row in i..model.nv {
                worst = worst.max((col[row] - lower[(row, i)]).abs());
            }
            worst = worst.max((col - m.column(i)).amax());
        }
        let e = worst / m.amax().max(1.0);
        // Worst case: 8.9e-16; tol 5e-14.
        prop_assert!(e <= 5e-14, "{}: CRBA vs RNEA columns {:e}", name, e);
    }
}

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
        // Worst case: 9.1e-16; tol 5e-14.
        prop_assert!(e <= 5e-14, "{}, frame {}: {:e}", name, model.frames[frame].name, e);
    }
}

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
// Lie groups.

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
        // Worst case: 1.2e-15 (the distance measured on the group, free of the quaternion's
        // sign); tol 5e-14.
        prop_assert!(e <= 5e-14, "{}: integrate(difference) {:e}", name, e);
    }
}

// ---------------------------------------------------------------------------------------------
// Analytic derivatives = finite differences.

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
            // Worst case over the 64 cases: 1.21e-9 (the differences' own O(h⁴) error on
            // q; v and τ reach rounding); tol 1e-7.
            prop_assert!(e <= 1e-7, "{}: {} differs from finite differences by {:e}", name, what, e);
        }
    }
}
