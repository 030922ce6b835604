//! Bad input gets an error that names the problem (file, element, key, frame, constraint).

use crate::common;
use common::assert_has;
use constraint_dynamics::constraints::{ConstraintSet, ConstraintSpec};
use constraint_dynamics::{Model, ModelOptions, Scene, System};

const GOOD: &str = r#"<robot name="r">
  <link name="base"/>
  <link name="arm"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1"/></joint>
</robot>"#;

fn err(urdf: &str) -> String {
    Model::from_urdf_str(urdf, "test.urdf", &ModelOptions::default())
        .unwrap_err()
        .to_string()
}

#[test]
fn missing_velocity_and_effort_limits_are_accepted_as_unbounded() {
    let m = Model::from_urdf_str(GOOD, "good.urdf", &ModelOptions::default()).unwrap();
    assert_eq!(m.limits.velocity, vec![f64::INFINITY]);
    assert_eq!(m.limits.effort, vec![f64::INFINITY]);
    assert_eq!((m.limits.q_lower[0], m.limits.q_upper[0]), (-1.0, 1.0));
}

#[test]
fn malformed_xml_names_file_and_line() {
    let e = err("<robot name=\"r\">\n<link name=\"a\">\n</robot>");
    assert_has(&e, &["test.urdf", "line", "malformed XML"]);
}

#[test]
fn unknown_joint_type_is_named() {
    let e = err(&GOOD.replace("type=\"revolute\"", "type=\"ball\""));
    assert_has(
        &e,
        &["test.urdf", "joint 'j1'", "unknown joint type 'ball'"],
    );
}

#[test]
fn negative_mass_is_named() {
    let e = err(&GOOD.replace("<mass value=\"1\"/>", "<mass value=\"-2\"/>"));
    assert_has(&e, &["link 'arm'", "mass -2"]);
}

#[test]
fn non_positive_definite_inertia_is_named() {
    let e = err(&GOOD.replace("izz=\"0.1\"", "izz=\"-0.3\""));
    assert_has(&e, &["link 'arm'", "not positive definite"]);
    let e = err(&GOOD.replace("izz=\"0.1\"", "izz=\"0.5\""));
    assert_has(&e, &["link 'arm'", "triangle inequality"]);
}

#[test]
fn cycle_and_two_roots_are_named() {
    let cyc = GOOD.replace(
        "</robot>",
        r#"<joint name="back" type="fixed"><parent link="arm"/><child link="base"/></joint></robot>"#,
    );
    assert_has(&err(&cyc), &["cycle"]);
    let two = GOOD.replace("</robot>", r#"<link name="stray"/></robot>"#);
    assert_has(&err(&two), &["2 root links", "stray"]);
    let twoparents = GOOD.replace(
        "</robot>",
        r#"<link name="c"/><joint name="ja" type="fixed"><parent link="base"/><child link="c"/></joint>
           <joint name="jb" type="fixed"><parent link="arm"/><child link="c"/></joint></robot>"#,
    );
    assert_has(
        &err(&twoparents),
        &["joint 'jb'", "already has parent joint 'ja'"],
    );
}

#[test]
fn locked_joint_that_does_not_exist_is_named() {
    let opts = ModelOptions {
        locked_joints: vec![("elbow".into(), 0.3)],
        ..Default::default()
    };
    let e = Model::from_urdf_str(GOOD, "t.urdf", &opts)
        .unwrap_err()
        .to_string();
    assert_has(&e, &["locked joint 'elbow'", "no joint of that name"]);
}

fn scene_dir() -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("cd_bad_input_{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write_scene(name: &str, body: &str) -> std::path::PathBuf {
    let urdf = common::repo_dir().join("urdf/diff_drive.urdf");
    let p = scene_dir().join(name);
    std::fs::write(
        &p,
        format!("urdf: {}\nbase: planar\n{body}", urdf.display()),
    )
    .unwrap();
    p
}

#[test]
fn unknown_scene_key_is_named() {
    let p = write_scene("typo.yaml", "gravty: [0, 0, -9.81]\n");
    let e = Scene::load(&p).unwrap_err().to_string();
    assert_has(&e, &["typo.yaml", "unknown field `gravty`"]);
    let p = write_scene(
        "typo2.yaml",
        "constraints:\n  - {name: c, kind: rolling, wheel: left_wheel, axis: [0,1,0], radius: 0.05, radus: 1}\n",
    );
    assert_has(&Scene::load(&p).unwrap_err().to_string(), &["radus"]);
}

#[test]
fn bad_rollout_settings_are_named() {
    let p = write_scene(
        "rollouts.yaml",
        "rollouts:\n  hold: continuous\n  integration: {method: ros2, jacobian_spans: 0}\n",
    );
    let e = Scene::load(&p).unwrap_err().to_string();
    assert_has(
        &e,
        &["rollouts.yaml", "rollouts: ", "integration.jacobian_spans"],
    );
    let p = write_scene("rollouts2.yaml", "rollouts:\n  hold: sampled\n");
    assert_has(
        &Scene::load(&p).unwrap_err().to_string(),
        &["hold", "sampled"],
    );
}

fn system_err(body: &str) -> String {
    let p = write_scene("c.yaml", body);
    let scene = Scene::load(&p).unwrap();
    System::from_scene(&scene).unwrap_err().to_string()
}

#[test]
fn constraint_errors_name_the_constraint_and_problem() {
    let e = system_err("constraints:\n  - {name: hold, kind: point, frame_a: nosuchlink}\n");
    assert_has(
        &e,
        &[
            "constraint 'hold'",
            "unknown frame 'nosuchlink'",
            "base_link",
        ],
    );
    let e = system_err(
        "constraints:\n  - {name: w, kind: rolling, wheel: left_wheel, axis: [0,1,0], radius: 0.0}\n",
    );
    assert_has(&e, &["constraint 'w'", "radius 0 m must be positive"]);
    // A distance of exactly 0 has no direction: refused like a negative one.
    let e = system_err(
        "constraints:\n  - {name: rod, kind: distance, frame_a: left_wheel, frame_b: world, distance: 0.0}\n",
    );
    assert_has(&e, &["constraint 'rod'", "distance 0 m must be positive"]);
    let e = system_err(
        "constraints:\n  - {name: w, kind: rolling, wheel: left_wheel, axis: [0,1,0], radius: 0.05, plane_normal: [0,1,0]}\n",
    );
    assert_has(&e, &["constraint 'w'", "parallel to the plane normal"]);
    let e = system_err(
        "constraints:\n  - {name: g, kind: coupling, joint_i: left_wheel_joint, joint_j: nope, a: 1, b: 1, c: 0}\n",
    );
    assert_has(&e, &["constraint 'g'", "unknown joint 'nope'"]);
    // 0·q_i + 0·q_j = c constrains nothing: refused; a single zero coefficient is a lock.
    let e = system_err(
        "constraints:\n  - {name: g, kind: coupling, joint_i: left_wheel_joint, joint_j: right_wheel_joint, a: 0, b: 0, c: 0}\n",
    );
    assert_has(&e, &["constraint 'g'", "a and b not both zero"]);
    let p = write_scene(
        "lock.yaml",
        "constraints:\n  - {name: g, kind: coupling, joint_i: left_wheel_joint, joint_j: right_wheel_joint, a: 0, b: 1, c: 0}\n",
    );
    System::from_scene(&Scene::load(&p).unwrap()).unwrap();
}

/// The ground plane's height is bounded like every length (`limits::MAX_LENGTH` = 1e6 m, "at
/// most": 1e6 itself is accepted) and must be finite.
#[test]
fn rolling_plane_height_is_finite_and_at_most_the_length_limit() {
    let rolling = |h: &str| {
        format!(
            "constraints:\n  - {{name: w, kind: rolling, wheel: left_wheel, axis: [0,1,0], radius: 0.05, plane_height: {h}}}\n"
        )
    };
    // Own file names: `system_err`'s c.yaml is shared with the other tests' threads.
    let load = |k: usize, h: &str| {
        let p = write_scene(&format!("height{k}.yaml"), &rolling(h));
        System::from_scene(&Scene::load(&p).unwrap())
    };
    for (k, h) in ["2e6", "-2e6", ".nan", ".inf"].into_iter().enumerate() {
        let e = load(k, h).unwrap_err().to_string();
        assert_has(&e, &["constraint 'w'", "plane_height", "at most 1e6 m"]);
    }
    for (k, h) in ["1e6", "-1e6"].into_iter().enumerate() {
        load(4 + k, h).unwrap();
    }
}

/// Axes and normals are directions: a zero or infinite vector has none and is refused by name
/// (the rolling wheel's axis and plane normal, the knife edge's axis).
#[test]
fn zero_and_infinite_axes_are_refused() {
    let cases = [
        (
            "{name: w, kind: rolling, wheel: left_wheel, axis: [0,0,0], radius: 0.05}",
            "wheel axis",
        ),
        (
            "{name: w, kind: rolling, wheel: left_wheel, axis: [.inf,0,0], radius: 0.05}",
            "wheel axis",
        ),
        (
            "{name: w, kind: rolling, wheel: left_wheel, axis: [0,1,0], radius: 0.05, plane_normal: [0,0,0]}",
            "plane normal",
        ),
        (
            "{name: w, kind: no_side_slip, frame: base_link, axis: [0,0,0]}",
            "axis",
        ),
        (
            "{name: w, kind: no_side_slip, frame: base_link, axis: [0,-.inf,0]}",
            "axis",
        ),
    ];
    for (k, (c, what)) in cases.into_iter().enumerate() {
        let p = write_scene(
            &format!("axis{k}.yaml"),
            &format!("constraints:\n  - {c}\n"),
        );
        let e = System::from_scene(&Scene::load(&p).unwrap())
            .unwrap_err()
            .to_string();
        assert_has(
            &e,
            &["constraint 'w'", &format!("{what} is zero or not finite")],
        );
    }
}

/// Points are lengths bounded by `limits::MAX_LENGTH` = 1e6 m ("at most": 1e6 is accepted) and
/// must be finite; a row that the kind does not have is named by its YAML spelling.
#[test]
fn points_beyond_the_length_limit_and_foreign_rows_are_named() {
    let point = |k: usize, p: &str, rows: &str| {
        let body = format!(
            "constraints:\n  - {{name: h, kind: point, frame_a: base_link, point_a: {p}, rows: {rows}}}\n"
        );
        let path = write_scene(&format!("point{k}.yaml"), &body);
        System::from_scene(&Scene::load(&path).unwrap())
    };
    for (k, p) in ["[0, 0, 2e6]", "[-2e6, 0, 0]", "[0, .nan, 0]"]
        .into_iter()
        .enumerate()
    {
        let e = point(k, p, "[x, y]").unwrap_err().to_string();
        assert_has(&e, &["constraint 'h'", "point_a", "beyond 1e6 m"]);
    }
    point(3, "[1e6, 0, -1e6]", "[x, y]").unwrap();
    let e = point(4, "[0, 0, 0]", "[x, rx]").unwrap_err().to_string();
    assert_has(
        &e,
        &["constraint 'h'", "row 'rx' is not valid for this kind"],
    );
}

#[test]
fn inconsistent_constraints_are_an_error_not_garbage() {
    // The same wheel joint coupled to two incompatible accelerations: q_l − q_r = 0 and
    // q_l − q_r = 1 at once, evaluated with a velocity-level Baumgarte pull that cannot be met.
    let p = write_scene(
        "inc.yaml",
        "constraints:\n  - {name: a, kind: coupling, joint_i: left_wheel_joint, joint_j: right_wheel_joint, a: 1, b: -1, c: 0}\n  - {name: b, kind: coupling, joint_i: left_wheel_joint, joint_j: right_wheel_joint, a: 1, b: -1, c: 1}\ndynamics: {baumgarte: {kp: 100, kd: 0}}\n",
    );
    let scene = Scene::load(&p).unwrap();
    let mut sys = System::from_scene(&scene).unwrap();
    let (q, v) = (scene.q0.clone(), scene.v0.clone());
    let e = sys
        .forward_dynamics(&q, &v, &vec![0.0; q.len()], true)
        .unwrap_err()
        .to_string();
    assert_has(&e, &["inconsistent constraints", "cannot all be met"]);
}

#[test]
fn nan_and_wrong_sizes_are_named() {
    let scene = Scene::load(common::repo_dir().join("params/fourbar.yaml")).unwrap();
    let mut sys = System::from_scene(&scene).unwrap();
    let (mut q, v) = (scene.q0.clone(), scene.v0.clone());
    let e = sys
        .forward_dynamics(&q, &v[..2], &[0.0; 3], true)
        .unwrap_err()
        .to_string();
    assert_has(&e, &["v: expected 3 values, got 2"]);
    q[1] = f64::NAN;
    let e = sys
        .forward_dynamics(&q, &v, &[0.0; 3], true)
        .unwrap_err()
        .to_string();
    assert_has(&e, &["q: entry 1 is not finite"]);
    let none = ConstraintSet::new(sys.model(), &[] as &[ConstraintSpec], &scene.q0).unwrap();
    assert!(none.is_empty() && none.nrows == 0);
}
