//! Every bundled scene: both formulations agree, static cases balance, locked joints reduce the
//! model, mimic joints become couplings, and the Lie-group operations are consistent.

use crate::common;
use common::*;
use constraint_dynamics::algorithm::Data;
use constraint_dynamics::constraints::ConstraintSet;
use constraint_dynamics::dynamics::*;
use constraint_dynamics::{BaseType, Model, ModelOptions, Scene, System};

// Tolerances from the achieved figures (printed by `assert_close`, `-- --nocapture`).
/// Floating mobile manipulator at rest: |q̈| 5.3e-14.
const TOL_MM_QDD: f64 = 2e-12;
/// Σ normal forces / m g − 1: 4.4e-16.
const TOL_MM_FZ: f64 = 2e-14;
/// Tangential contact force [N]: 2.8e-14.
const TOL_MM_TANGENTIAL: f64 = 2e-12;
/// Solo12 static equilibrium |q̈|: 2.1e-12 (Pinocchio: 8.9e-13).
const TOL_SOLO_QDD: f64 = 1e-10;
/// Σ f_z / m g − 1: 6.7e-16.
const TOL_SOLO_FZ: f64 = 5e-14;
/// Geared pair q̈ (closed form 1/(I_a + 4 I_b)): 1.6e-16.
const TOL_GEARS: f64 = 1e-14;
/// Geared pair φ: exactly 0; floor 1e-15.
const TOL_GEARS_PHI: f64 = 1e-15;
/// |quaternion| − 1 after integrate: exactly 0 (renormalised); floor 1e-15.
const TOL_UNIT: f64 = 1e-15;

#[test]
fn embedded_and_multiplier_forms_agree_on_every_bundled_scene() {
    let list = bundled_scenes();
    assert!(list.len() >= 6, "bundled scenes missing: {list:?}");
    for p in list {
        let scene = Scene::load(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        let mut sys = System::from_scene(&scene).unwrap();
        let nv = sys.model().nv;
        for k in 0..3 {
            // The scene state, then joint torques that excite every coordinate.
            let tau: Vec<f64> = (0..nv)
                .map(|i| k as f64 * ((i + 1) as f64 * 0.9).sin())
                .collect();
            let (q, v) = (scene.q0.clone(), scene.v0.clone());
            sys = sys.with_formulation(Formulation::Multipliers);
            let a = sys.forward_dynamics(&q, &v, &tau, true).unwrap().clone();
            sys = sys.with_formulation(Formulation::Embedded);
            let b = sys.forward_dynamics(&q, &v, &tau, false).unwrap().clone();
            // Achieved ≤ 4.8e-15 on the fixed and planar bases, 5.3e-14 on the floating
            // mobile manipulator (printed by assert_close).
            let tol = if sys.model().base == BaseType::Floating {
                5e-12
            } else {
                2e-13
            };
            assert_close(
                &format!("{} embedded vs multipliers", p.display()),
                b.as_slice(),
                a.as_slice(),
                tol,
            );
            assert!(a.iter().all(|x| x.is_finite()));
        }
        // Auto picks the embedded form when nobody asks for forces, multipliers when they do.
        sys = sys.with_formulation(Formulation::Auto);
        let (q, v) = (scene.q0.clone(), scene.v0.clone());
        sys.forward_dynamics(&q, &v, &vec![0.0; nv], false).unwrap();
        let expect = if sys.constraints().is_empty() {
            Formulation::Multipliers
        } else {
            Formulation::Embedded
        };
        assert_eq!(sys.last_formulation(), expect, "{}", p.display());
    }
}

#[test]
fn mobile_manipulator_standing_still_carries_its_weight_on_its_contacts() {
    let scene = Scene::load(repo_dir().join("params/mobile_manipulator_floating.yaml")).unwrap();
    let mut sys = System::from_scene(&scene).unwrap();
    let nv = sys.model().nv;
    let qdd = sys
        .forward_dynamics(&scene.q0, &vec![0.0; nv], &vec![0.0; nv], true)
        .unwrap()
        .clone();
    // Closed form: at rest on level ground nothing moves (q̈ = 0) and the contacts carry m g.
    assert_close(
        "standing still: q̈",
        qdd.as_slice(),
        &vec![0.0; nv],
        TOL_MM_QDD,
    );
    let mg = sys.model().total_mass() * 9.81;
    let forces = sys.constraint_forces();
    let fz: f64 = forces.iter().map(|f| f.force[2]).sum();
    assert_close(
        "standing still: Σ normal forces / m g",
        &[fz / mg],
        &[1.0],
        TOL_MM_FZ,
    );
    // The redundant lateral rows of the two wheels are reported, not hidden.
    assert_eq!(sys.multipliers().rank_deficiency, 1);
    for f in forces.iter().filter(|f| f.kind.name() == "rolling") {
        assert!(f.normal_force.unwrap() > 0.0);
        assert_close(
            &format!("{}: tangential force", f.name),
            &[f.tangential_force.unwrap()],
            &[0.0],
            TOL_MM_TANGENTIAL,
        );
    }
}

#[test]
fn solo12_static_equilibrium_carries_its_weight() {
    let case = load_case("solo12_four_feet");
    let model = case_model(&case);
    let st = case["states"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| {
            s["label"]
                .as_str()
                .unwrap()
                .to_lowercase()
                .contains("equilibrium")
        })
        .unwrap();
    let specs = (0..4)
        .map(|k| {
            let c = &st["constraints"][k];
            let a = vecf(&c["world_anchor"]);
            constraint_dynamics::constraints::ConstraintSpec::Point {
                name: format!("foot{k}"),
                frame_a: c["link"].as_str().unwrap().into(),
                point_a: [0.0; 3],
                frame_b: "world".into(),
                point_b: [a[0], a[1], a[2]],
                rows: vec![
                    constraint_dynamics::constraints::Row::X,
                    constraint_dynamics::constraints::Row::Y,
                    constraint_dynamics::constraints::Row::Z,
                ],
                unilateral: false,
                friction: None,
            }
        })
        .collect::<Vec<_>>();
    let q = vecf(&st["q"]);
    let set = ConstraintSet::new(&model, &specs, &q).unwrap();
    let mut sys = System::new(model, set, Baumgarte::default(), Formulation::Multipliers);
    let qdd = sys
        .forward_dynamics(&q, &vecf(&st["qd"]), &vecf(&st["tau"]), true)
        .unwrap()
        .clone();
    // The reference's static-equilibrium state: q̈ = 0 and Σ f_z = m g (Pinocchio itself reaches
    // |q̈| 8.9e-13 and |Σ λ_z − m g| 2.5e-14 N there, `crosschecks_maxabs`).
    assert_close("solo12 static: q̈", qdd.as_slice(), &[0.0; 18], TOL_SOLO_QDD);
    let mg = sys.model().total_mass() * 9.81;
    let fz: f64 = sys.constraint_forces().iter().map(|f| f.force[2]).sum();
    assert_close(
        "solo12 static: Σ f_z / m g",
        &[fz / mg],
        &[1.0],
        TOL_SOLO_FZ,
    );
}

#[test]
fn locked_joints_reduce_the_model_and_cost_nothing() {
    let urdf = reference_dir().join("urdf/ur5_robot.urdf");
    let full = Model::from_urdf_file(&urdf, &ModelOptions::default()).unwrap();
    let locked = vec![
        ("wrist_2_joint".to_string(), 0.4),
        ("wrist_3_joint".to_string(), -0.2),
    ];
    let red = Model::from_urdf_file(
        &urdf,
        &ModelOptions {
            locked_joints: locked,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!((red.nq, red.nv, red.nbodies()), (4, 4, full.nbodies() - 2));
    assert!(
        red.frame_id("tool0").is_ok(),
        "merged links stay named frames"
    );
    // The reduced M equals the full M's leading block with the locked joints at their values.
    let q_full = [0.1, -0.7, 1.1, 0.3, 0.4, -0.2];
    let (mut df, mut dr) = (Data::new(&full), Data::new(&red));
    let mf = constraint_dynamics::algorithm::crba_full(&full, &mut df, &q_full).clone();
    let mr = constraint_dynamics::algorithm::crba_full(&red, &mut dr, &q_full[..4]).clone();
    assert_close(
        "reduced M",
        mr.as_slice(),
        mf.view((0, 0), (4, 4)).clone_owned().as_slice(),
        1e-14, // achieved 2.1e-16
    );
}

#[test]
fn urdf_mimic_becomes_a_coupling_constraint() {
    let urdf = r#"<robot name="g">
      <link name="base"/>
      <link name="a"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
      <link name="b"><inertial><mass value="2"/><inertia ixx="0.02" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>
      <joint name="ja" type="continuous"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/></joint>
      <joint name="jb" type="continuous"><parent link="base"/><child link="b"/><axis xyz="0 0 1"/><mimic joint="ja" multiplier="-2" offset="0.1"/></joint>
    </robot>"#;
    let model = Model::from_urdf_str(urdf, "gear.urdf", &ModelOptions::default()).unwrap();
    let set = ConstraintSet::new(&model, &[], &[0.0, 0.1]).unwrap();
    assert_eq!(set.names, vec!["mimic:jb"]);
    // Two gears: q_b = −2 q_a + 0.1. A torque τ_a on gear a alone drives both:
    // (I_a + 4 I_b) q̈_a = τ_a (virtual work on the single DOF).
    let mut sys = System::new(model, set, Baumgarte::default(), Formulation::Multipliers);
    let qdd = sys
        .forward_dynamics(&[0.0, 0.1], &[0.0, 0.0], &[1.0, 0.0], true)
        .unwrap()
        .clone();
    let expect = 1.0 / (0.01 + 4.0 * 0.02);
    assert_close(
        "gears: q̈",
        qdd.as_slice(),
        &[expect, -2.0 * expect],
        TOL_GEARS,
    );
    let (mut data, mut cd, _) = workspaces(&sys);
    sys.constraints().evaluate(
        sys.model(),
        &mut data,
        &mut cd,
        0.0,
        &[0.3, -0.5],
        &[0.0, 0.0],
    );
    assert_close(
        "gears: φ",
        &[cd.phi[0]],
        &[-0.5 + 2.0 * 0.3 - 0.1],
        TOL_GEARS_PHI,
    );
}

#[test]
fn floating_and_planar_integration_are_consistent_on_the_group() {
    for base in [BaseType::Floating, BaseType::Planar] {
        let model = Model::from_urdf_file(
            reference_dir().join("urdf/disk.urdf"),
            &ModelOptions {
                base,
                ..Default::default()
            },
        )
        .unwrap();
        let mut q0 = model.neutral();
        q0[0] = 0.3;
        let v: Vec<f64> = (0..model.nv).map(|i| 0.5 + 0.3 * i as f64).collect();
        let mut q1 = vec![0.0; model.nq];
        model.integrate(&q0, &v, 0.7, &mut q1);
        let mut d = vec![0.0; model.nv];
        model.difference(&q0, &q1, &mut d);
        let back: Vec<f64> = d.iter().map(|x| x / 0.7).collect();
        // Achieved 6.7e-16 (floating), 1.0e-16 (planar).
        assert_close(&format!("{base:?} difference(integrate)"), &back, &v, 5e-14);
        if base == BaseType::Floating {
            let n: f64 = q1[3..7].iter().map(|x| x * x).sum::<f64>().sqrt();
            assert_close("quaternion stays unit", &[n], &[1.0], TOL_UNIT);
        }
        // q̇ = G(q) v agrees with the finite difference of integrate.
        let mut qd = vec![0.0; model.nq];
        model.qdot(&q0, &v, &mut qd);
        let h = 1e-7;
        model.integrate(&q0, &v, h, &mut q1);
        let fd: Vec<f64> = q1.iter().zip(&q0).map(|(a, b)| (a - b) / h).collect();
        // A one-sided difference with h = 1e-7: truncation O(h |q̈|) plus round-off
        // O(ε/h) ≈ 1e-9; achieved 1.0e-7 (floating), 4.0e-8 (planar).
        assert_close(&format!("{base:?} qdot"), &qd, &fd, 1e-6);
    }
}
