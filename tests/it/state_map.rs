//! A state of one model in another model of the same robot (`StateMap`): the tool frame of the
//! planar mobile manipulator and of its floating-base variant coincide in the world (placement
//! and velocity) at mapped states, up to the floating base's own height; a coordinate the source
//! lacks is an error naming it.

use crate::common::repo_dir;
use constraint_dynamics::Scene;
use constraint_dynamics::algorithm::{Data, forward_kinematics, frame_placement, frame_velocity};
use constraint_dynamics::model::StateMap;

/// Rounding of two kinematic chains with different base joints: 1.1e-16 achieved.
const TOL: f64 = 1e-14;

#[test]
fn the_tool_frame_is_where_both_models_of_the_robot_put_it() {
    let planar = Scene::load(repo_dir().join("params/mobile_manipulator.yaml")).unwrap();
    let floating = Scene::load(repo_dir().join("params/mobile_manipulator_floating.yaml")).unwrap();
    let (src, dst) = (&*planar.model, &*floating.model);
    let map = StateMap::new(src, dst).unwrap();
    // A planar state away from every zero: pose, twist and every joint.
    let q: Vec<f64> = (0..src.nq)
        .map(|i| 0.3 + 0.17 * i as f64 * if i % 2 == 0 { 1.0 } else { -1.0 })
        .collect();
    let mut q = q;
    src.normalize(&mut q);
    let v: Vec<f64> = (0..src.nv).map(|i| 0.2 - 0.13 * i as f64).collect();
    let (mut qf, mut vf) = (floating.q0.clone(), vec![7.0; dst.nv]);
    let height = dst.base_pose(&floating.q0).position[2];
    map.apply((src, dst), (&q, &v), (&mut qf, &mut vf));

    let tool = |m: &constraint_dynamics::Model, q: &[f64], v: &[f64]| {
        let mut d = Data::new(m);
        forward_kinematics(m, &mut d, q, v, &vec![0.0; m.nv]);
        let f = m.frame_id("tool0").unwrap();
        let x = frame_placement(m, &d, f);
        // The frame's velocity in world axes: R (v_local).
        let w = frame_velocity(m, &d, f);
        (
            x.translation,
            x.rotation * w.lin,
            x.rotation * w.ang,
            x.rotation,
        )
    };
    let (p0, v0, w0, r0) = tool(src, &q, &v);
    let (p1, v1, w1, r1) = tool(dst, &qf, &vf);
    let dp = p1 - p0;
    assert!(
        v0.norm() > 0.1 && w0.norm() > 0.1,
        "a state that moves the tool"
    );
    // The floating base keeps its own height; the planar base sits at z = 0.
    assert!(
        (dp.x.abs()).max(dp.y.abs()) <= TOL,
        "tool position moved by {dp:?}"
    );
    assert!(
        (dp.z - height).abs() <= TOL,
        "height {} vs base height {height}",
        dp.z
    );
    assert!((r1 * r0.transpose() - nalgebra::Matrix3::identity()).amax() <= TOL);
    assert!((v1 - v0).amax() <= TOL, "tool velocity {v0:?} vs {v1:?}");
    assert!(
        (w1 - w0).amax() <= TOL,
        "tool angular velocity {w0:?} vs {w1:?}"
    );
}

#[test]
fn a_coordinate_the_source_lacks_is_named() {
    let cart = Scene::load(repo_dir().join("params/diff_drive.yaml")).unwrap();
    let arm = Scene::load(repo_dir().join("params/mobile_manipulator.yaml")).unwrap();
    let err = StateMap::new(&cart.model, &arm.model)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("arm_") || err.contains("coordinate '"),
        "{err}"
    );
    assert!(err.contains("position coordinate"), "{err}");
}
