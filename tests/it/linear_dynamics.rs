//! The linear-time forward dynamics of a tree without constraint rows (`dynamics::tree`: ABA,
//! no n × n matrix) against the dense path (CRBA, bias forces, the LTL factor of M: the
//! multiplier form with no rows), and against a closed form.
//!
//! - Both paths agree on q̈ at random states of the bundled and reference robots (fixed and
//!   floating bases, multi-DOF joints) and of a 200-link chain, where `System` itself takes the
//!   linear path. Achieved, relative to max(1, max |q̈|): ≤ 1.3e-12 on the robots (the floating
//!   mobile manipulator; the fixed-base arms ≤ 8e-16), on the chain 3.9e-12 at its coiled start
//!   and ≤ 5.7e-11 at random states, where M's conditioning sets both paths' rounding
//!   (tolerance 1e-10).
//! - A double pendulum of point masses (Lagrange's equations in the absolute angles, written
//!   here) gives q̈ to 1.2e-15 (tolerance 1e-13).
//! - Where M is singular (a massless leaf) or singular to working precision (a leaf of 1e-20
//!   kg, whose ABA q̈ is finite), the linear path declines and `System` reports what the dense
//!   path reports.

use crate::chain;
use crate::common::*;
use constraint_dynamics::algorithm::{Data, aba};
use constraint_dynamics::constraints::{ConstraintData, ConstraintSet};
use constraint_dynamics::dynamics::{
    Baumgarte, Formulation, KktWorkspace, TreeWorkspace, constrained_forward_dynamics,
    takes_linear_path, tree_forward_dynamics,
};
use constraint_dynamics::system::DynamicsOptions;
use constraint_dynamics::{BaseType, Model, ModelOptions, System};
use std::f64::consts::PI;

/// A reproducible uniform draw in [−1, 1) (xorshift64*).
struct Draw(u64);

impl Draw {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let x = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11;
        2.0 * (x as f64 / (1u64 << 53) as f64) - 1.0
    }

    /// A random state: q = neutral ⊕ δ (δ within ±π per coordinate), v and τ in ±1 (±`scale`
    /// for τ).
    fn state(&mut self, m: &Model, tau_scale: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let delta: Vec<f64> = (0..m.nv).map(|_| PI * self.next()).collect();
        let mut q = vec![0.0; m.nq];
        m.integrate(&m.neutral(), &delta, 1.0, &mut q);
        let v = (0..m.nv).map(|_| self.next()).collect();
        let tau = (0..m.nv).map(|_| tau_scale * self.next()).collect();
        (q, v, tau)
    }
}

/// q̈ of the dense path: the multiplier form without rows.
fn dense_qdd(m: &Model, q: &[f64], v: &[f64], tau: &[f64]) -> Vec<f64> {
    let set = ConstraintSet::default();
    let mut data = Data::new(m);
    let mut cd = ConstraintData::new(m, &set);
    let mut ws = KktWorkspace::new(m, &set);
    constrained_forward_dynamics(
        m,
        &mut data,
        &set,
        &mut cd,
        &mut ws,
        q,
        v,
        tau,
        Baumgarte::default(),
    )
    .unwrap();
    ws.qdd.as_slice().to_vec()
}

/// q̈ of the linear path (asserting it accepts the state).
fn linear_qdd(m: &Model, q: &[f64], v: &[f64], tau: &[f64]) -> Vec<f64> {
    let mut data = Data::new(m);
    let mut ws = TreeWorkspace::new(m);
    assert!(
        tree_forward_dynamics(m, &mut data, &mut ws, q, v, tau),
        "the linear path declined a regular state"
    );
    data.qdd.as_slice().to_vec()
}

fn fixed(urdf: &str, name: &str) -> Model {
    let opts = ModelOptions {
        base: BaseType::Fixed,
        ..Default::default()
    };
    Model::from_urdf_str(urdf, name, &opts).unwrap()
}

#[test]
fn linear_and_dense_agree_on_the_robots() {
    let mut models: Vec<(String, Model)> = ["ur5_ee_point", "solo12_four_feet", "rolling_disk"]
        .iter()
        .map(|c| (c.to_string(), case_model(&load_case(c))))
        .collect();
    for s in [
        "params/mobile_manipulator.yaml",
        "params/mobile_manipulator_floating.yaml",
        "params/spring_chain.yaml",
        "params/andrews.yaml",
    ] {
        models.push((s.to_string(), (*scene(s).model).clone()));
    }
    let mut draw = Draw(0x9E37_79B9_7F4A_7C15);
    for (name, m) in &models {
        // Shallow trees: the dense path is the faster there, and `System` keeps it.
        assert!(!takes_linear_path(m), "{name}");
        for k in 0..5 {
            let (q, v, tau) = draw.state(m, 10.0);
            let dense = dense_qdd(m, &q, &v, &tau);
            let linear = linear_qdd(m, &q, &v, &tau);
            assert_close(&format!("{name} state {k}: q̈"), &linear, &dense, 1e-10);
        }
    }
}

#[test]
fn a_long_chain_takes_the_linear_path_and_agrees_with_the_dense_one() {
    let n = 200;
    // The chain's scene file, as the benchmark writes it, read back: its start state by name.
    let scene = chain::load_chain_scene(n, false);
    assert_eq!(scene.q0, chain::chain_q0(n));
    let m = (*scene.model).clone();
    assert_eq!(m.nv, n);
    assert!(takes_linear_path(&m));
    let mut sys = System::from_scene(&scene).unwrap();
    let mut draw = Draw(7);
    for k in 0..4 {
        // The scene's coiled start first, then random states.
        let (q, v, tau) = if k == 0 {
            (chain::chain_q0(n), vec![0.0; n], vec![0.0; n])
        } else {
            draw.state(&m, 1.0)
        };
        let dense = dense_qdd(&m, &q, &v, &tau);
        for formulation in [Formulation::Multipliers, Formulation::Embedded] {
            let opts = DynamicsOptions {
                formulation,
                ..Default::default()
            };
            let ours = sys.forward_dynamics_with(&q, &v, &tau, opts).unwrap();
            let ours = ours.as_slice().to_vec();
            assert_close(
                &format!("chain state {k} {formulation:?}"),
                &ours,
                &dense,
                1e-10,
            );
        }
        assert!(sys.lambda().is_empty());
    }
    // M and h on request, as the dense path forms them: M q̈ + h = τ.
    let (q, v, tau) = draw.state(&m, 1.0);
    let qdd = sys
        .forward_dynamics(&q, &v, &tau, false)
        .unwrap()
        .as_slice()
        .to_vec();
    let (mass, h) = sys.terms_at(&q, &v);
    let lhs: Vec<f64> = (0..n)
        .map(|i| (0..n).map(|c| mass[(i, c)] * qdd[c]).sum::<f64>() + h[i])
        .collect();
    assert_close("chain: M q̈ + h against τ", &lhs, &tau, 1e-10);
}

/// Two point masses m₁, m₂ on massless rods l₁, l₂ (joints about +y, each turning its link's
/// +x towards −z, as urdf/pendulum_a01.urdf), θ₁ = q₁ and θ₂ = q₁ + q₂ from the horizontal,
/// Δ = θ₁ − θ₂, joint torques τ₁, τ₂ (generalized forces Q₁ = τ₁ − τ₂ on θ₁, Q₂ = τ₂ on θ₂):
///   (m₁+m₂) l₁² θ̈₁ + m₂ l₁ l₂ cos Δ θ̈₂ = Q₁ − m₂ l₁ l₂ sin Δ θ̇₂² + (m₁+m₂) g l₁ cos θ₁
///   m₂ l₁ l₂ cos Δ θ̈₁ + m₂ l₂² θ̈₂ = Q₂ + m₂ l₁ l₂ sin Δ θ̇₁² + m₂ g l₂ cos θ₂
#[test]
fn double_pendulum_closed_form() {
    let (m1, m2, l1, l2, g) = (1.3, 0.7, 0.9, 0.6, 9.81);
    let urdf = format!(
        r#"<robot name="double_pendulum">
  <link name="base"/>
  <link name="upper"><inertial><origin xyz="{l1} 0 0"/><mass value="{m1}"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <link name="lower"><inertial><origin xyz="{l2} 0 0"/><mass value="{m2}"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <axis xyz="0 1 0"/><limit lower="-10" upper="10" effort="1" velocity="1"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="lower"/>
    <origin xyz="{l1} 0 0"/><axis xyz="0 1 0"/><limit lower="-10" upper="10" effort="1" velocity="1"/></joint>
</robot>"#
    );
    let m = fixed(&urdf, "double_pendulum.urdf");
    let mut draw = Draw(3);
    for k in 0..5 {
        let (q, v, tau) = draw.state(&m, 5.0);
        let (t1, t2) = (q[0], q[0] + q[1]);
        let (w1, w2) = (v[0], v[0] + v[1]);
        let d = t1 - t2;
        let a = [
            [(m1 + m2) * l1 * l1, m2 * l1 * l2 * d.cos()],
            [m2 * l1 * l2 * d.cos(), m2 * l2 * l2],
        ];
        let b = [
            tau[0] - tau[1] - m2 * l1 * l2 * d.sin() * w2 * w2 + (m1 + m2) * g * l1 * t1.cos(),
            tau[1] + m2 * l1 * l2 * d.sin() * w1 * w1 + m2 * g * l2 * t2.cos(),
        ];
        let det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
        let th1 = (b[0] * a[1][1] - a[0][1] * b[1]) / det;
        let th2 = (a[0][0] * b[1] - a[1][0] * b[0]) / det;
        let expected = [th1, th2 - th1];
        let linear = linear_qdd(&m, &q, &v, &tau);
        assert_close(
            &format!("double pendulum state {k}"),
            &linear,
            &expected,
            1e-13,
        );
    }
}

/// The 64-link chain with a leaf link `tip_inner` (the URDF text inside `<link name="tip">`)
/// on its own joint under link 1.
fn chain_with_tip(tip_inner: &str, file: &str) -> Model {
    let urdf = chain::chain_urdf(64).replace(
        "</robot>",
        &format!(
            r#"<link name="tip">{tip_inner}</link><joint name="tip_joint" type="revolute">
  <parent link="link1"/><child link="tip"/><axis xyz="0 0 1"/>
  <limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"#
        ),
    );
    fixed(&urdf, file)
}

/// At (q, v = 0, τ) the linear path declines and `System` errs as the dense path does,
/// naming the tip's joint.
fn assert_left_to_the_dense_path(m: &Model, q: &[f64], tau: &[f64]) {
    let zero = vec![0.0; m.nv];
    let mut data = Data::new(m);
    let mut ws = TreeWorkspace::new(m);
    assert!(!tree_forward_dynamics(m, &mut data, &mut ws, q, &zero, tau));
    let mut sys = System::new(
        m.clone(),
        ConstraintSet::default(),
        Baumgarte::default(),
        Formulation::Multipliers,
    );
    let err = sys.forward_dynamics(q, &zero, tau, false).unwrap_err();
    assert_has(&err.to_string(), &["tip_joint", "no inertia"]);
}

#[test]
fn a_singular_tree_is_left_to_the_dense_path() {
    // A massless leaf link on its own joint: M is singular, ABA's pivot there is 0. The model
    // alone loads (a scene refuses it unless constraints fix that joint); its dynamics err
    // through `System` as the dense path does.
    let m = chain_with_tip("", "chain_with_massless_tip.urdf");
    assert!(m.singular.is_some());
    assert_left_to_the_dense_path(&m, &m.neutral(), &vec![0.0; m.nv]);
}

#[test]
fn a_nearly_singular_tree_is_left_to_the_dense_path() {
    // A leaf link of 1e-20 kg on its own joint: ABA's pivot there is finite (its inertia,
    // 1e-22 kg·m²) but 1e-14 of M's largest entry is above it, so M is singular to working
    // precision: the linear path declines on the pivot check (q̈ itself comes out finite,
    // about 1e20 times the torque) and `System` reports what the dense path reports.
    let m = chain_with_tip(
        r#"<inertial><origin xyz="0 0 0"/><mass value="1e-20"/>
  <inertia ixx="1e-22" ixy="0" ixz="0" iyy="1e-22" iyz="0" izz="1e-22"/></inertial>"#,
        "chain_with_light_tip.urdf",
    );
    let q = m.neutral();
    let zero = vec![0.0; m.nv];
    let tau: Vec<f64> = (0..m.nv).map(|k| 0.1 * (k as f64).cos()).collect();
    let mut data = Data::new(&m);
    aba(&m, &mut data, &q, &zero, &tau);
    assert!(
        data.qdd.iter().all(|x| x.is_finite()),
        "ABA's q̈ is finite here"
    );
    assert_left_to_the_dense_path(&m, &q, &tau);
}
