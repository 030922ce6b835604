//! Tests of the command line and parameter files against rcl's rules.

use super::*;

fn args(s: &str) -> Vec<String> {
    s.split_whitespace().map(str::to_string).collect()
}

#[test]
fn parses_every_flag_and_keeps_user_args() {
    let a = RosArgs::parse(args(
        "model.urdf --ros-args --params-file a.yaml -p rate:=50.0 -p name:=wheelie \
         -r odom:=/robot/odom -r __node:=cd -r __ns:=robot --log-level debug -e /enc -- --verbose",
    ))
    .unwrap();
    assert_eq!(a.user_args, vec!["model.urdf", "--verbose"]);
    assert_eq!(a.params_files, vec![PathBuf::from("a.yaml")]);
    assert_eq!(a.params[0].value, ParameterValue::Double(50.0));
    assert_eq!(a.params[1].value, ParameterValue::String("wheelie".into()));
    assert_eq!(
        a.remaps,
        vec![RemapRule {
            node: None,
            from: "odom".into(),
            to: "/robot/odom".into()
        }]
    );
    assert_eq!(a.node_name.as_deref(), Some("cd"));
    assert_eq!(a.namespace.as_deref(), Some("/robot"));
    assert_eq!(a.log_levels, vec!["debug"]);
    assert_eq!(a.ignored, vec!["-e /enc"]);
}

#[test]
fn several_ros_args_sections_and_long_forms() {
    let a = RosArgs::parse(args(
        "--ros-args --param a:=1 -- x --ros-args --remap __name:=n2",
    ))
    .unwrap();
    assert_eq!(a.user_args, vec!["x"]);
    assert_eq!(a.params[0].value, ParameterValue::Integer(1));
    assert_eq!(a.node_name.as_deref(), Some("n2"));
}

#[test]
fn param_values_are_typed_like_yaml() {
    let a = RosArgs::parse(args(
        "--ros-args -p b:=true -p i:=-3 -p d:=1e-3 -p s:='x' -p da:=[1.0,2] -p ia:=[1,2] -p sa:=[a,b] -p ba:=[true,false]",
    ))
    .unwrap();
    let v: Vec<_> = a.params.iter().map(|p| p.value.clone()).collect();
    assert_eq!(
        v,
        vec![
            ParameterValue::Boolean(true),
            ParameterValue::Integer(-3),
            ParameterValue::Double(1e-3),
            ParameterValue::String("x".into()),
            ParameterValue::DoubleArray(vec![1.0, 2.0]),
            ParameterValue::IntegerArray(vec![1, 2]),
            ParameterValue::StringArray(vec!["a".into(), "b".into()]),
            ParameterValue::BooleanArray(vec![true, false]),
        ]
    );
}

#[test]
fn errors_are_reported() {
    assert!(matches!(
        RosArgs::parse(args("--ros-args -p")),
        Err(RosArgsError::MissingValue(_))
    ));
    assert!(matches!(
        RosArgs::parse(args("--ros-args --bogus")),
        Err(RosArgsError::UnknownArgument(_))
    ));
    assert!(matches!(
        RosArgs::parse(args("--ros-args -p novalue")),
        Err(RosArgsError::MalformedRule(_))
    ));
    assert!(matches!(
        RosArgs::parse(args("--ros-args -r __node:=9x")),
        Err(RosArgsError::InvalidName { .. })
    ));
    assert!(matches!(
        RosArgs::parse(args("--ros-args -r __ns:=/a/")),
        Err(RosArgsError::InvalidName { .. })
    ));
    assert!(matches!(
        RosArgs::parse(args("--ros-args -p m:=[1,a]")),
        Err(RosArgsError::BadValue { .. })
    ));
    // Without --ros-args nothing is a ROS argument.
    assert_eq!(
        RosArgs::parse(args("-p x")).unwrap().user_args,
        vec!["-p", "x"]
    );
}

#[test]
fn remapping_resolves_relative_private_and_node_scoped_rules() {
    let a = RosArgs::parse(args(
        "--ros-args -r cmd_vel:=/nav/cmd_vel -r other:~/x:=y -r /abs:=rel -r ~/priv:=/p",
    ))
    .unwrap();
    assert_eq!(a.resolve_topic("/robot", "cd", "cmd_vel"), "/nav/cmd_vel");
    assert_eq!(
        a.resolve_topic("/robot", "cd", "/robot/cmd_vel"),
        "/nav/cmd_vel"
    );
    assert_eq!(a.resolve_topic("/robot", "cd", "~/x"), "/robot/cd/x"); // rule is for node "other"
    assert_eq!(a.resolve_topic("/robot", "other", "~/x"), "/robot/y");
    assert_eq!(a.resolve_topic("/", "cd", "/abs"), "/rel");
    assert_eq!(a.resolve_topic("/", "cd", "~/priv"), "/p");
    assert_eq!(a.resolve_topic("/", "cd", "odom"), "/odom");
}

const FILE: &str = r#"
/**:
  ros__parameters:
    use_sim_time: false
    rate: 10.0
    solver: { tolerance: 1.0e-6 }
constraint_dynamics:
  ros__parameters:
    rate: 100.0
    frames: [odom, base_link]
    solver:
      tolerance: 1.0e-9
      max_iter: 50
/**/other:
  ros__parameters:
    rate: 1.0
robot:
  nested_node:
    ros__parameters:
      gains: [1, 2.5]
"#;

#[test]
fn params_file_node_specific_wins_over_wildcard() {
    let p = parse_params_yaml(FILE, "/constraint_dynamics").unwrap();
    assert_eq!(p.get("rate"), Some(&ParameterValue::Double(100.0)));
    assert_eq!(p.get("use_sim_time"), Some(&ParameterValue::Boolean(false)));
    assert_eq!(
        p.get("solver.tolerance"),
        Some(&ParameterValue::Double(1e-9))
    );
    assert_eq!(p.get("solver.max_iter"), Some(&ParameterValue::Integer(50)));
    assert_eq!(
        p.get("frames"),
        Some(&ParameterValue::StringArray(vec![
            "odom".into(),
            "base_link".into()
        ]))
    );
    // Specific-after-wildcard also when the wildcard comes later in the file.
    let reordered =
        "n:\n  ros__parameters:\n    a: 1\n/**:\n  ros__parameters:\n    a: 2\n    b: 3\n";
    let p = parse_params_yaml(reordered, "/n").unwrap();
    assert_eq!(p.get("a"), Some(&ParameterValue::Integer(1)));
    assert_eq!(p.get("b"), Some(&ParameterValue::Integer(3)));
}

#[test]
fn params_file_namespaces_and_wildcards() {
    // A key without leading slash is in the root namespace, as in rclcpp.
    let p = parse_params_yaml(FILE, "/robot/constraint_dynamics").unwrap();
    assert_eq!(p.get("rate"), Some(&ParameterValue::Double(10.0)));
    let p = parse_params_yaml(FILE, "/a/b/other").unwrap();
    assert_eq!(p.get("rate"), Some(&ParameterValue::Double(1.0)));
    let p = parse_params_yaml(FILE, "/robot/nested_node").unwrap();
    assert_eq!(
        p.get("gains"),
        Some(&ParameterValue::DoubleArray(vec![1.0, 2.5]))
    );
    assert!(node_key_matches("/ns/*", "/ns/n"));
    assert!(!node_key_matches("/ns/*", "/ns/a/n"));
    assert!(node_key_matches("/**", "/"));
    assert!(!node_key_matches("/x", "/y"));
}

#[test]
fn params_file_errors() {
    assert!(parse_params_yaml("ros__parameters: {a: 1}", "/n").is_err());
    assert!(parse_params_yaml("n: 3", "/n").is_err());
    assert!(parse_params_yaml("n:\n  ros__parameters:\n    a: ~\n", "/n").is_err());
    assert!(parse_params_yaml("", "/n").unwrap().values.is_empty());
}

#[test]
fn files_then_overrides_and_typed_struct() {
    let dir = std::env::temp_dir().join(format!("cd_ros_args_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let f1 = dir.join("a.yaml");
    let f2 = dir.join("b.yaml");
    std::fs::write(&f1, FILE).unwrap();
    std::fs::write(
        &f2,
        "constraint_dynamics:\n  ros__parameters:\n    rate: 200.0\n",
    )
    .unwrap();
    let a = RosArgs::parse(vec![
        "--ros-args".to_string(),
        "--params-file".into(),
        f1.display().to_string(),
        "--params-file".into(),
        f2.display().to_string(),
        "-p".into(),
        "solver.max_iter:=7".into(),
        "-p".into(),
        "someone_else:use_sim_time:=true".into(),
    ])
    .unwrap();
    let p = a.parameters("/constraint_dynamics").unwrap();
    assert_eq!(p.get("rate"), Some(&ParameterValue::Double(200.0)));
    assert_eq!(p.get("solver.max_iter"), Some(&ParameterValue::Integer(7)));
    assert_eq!(p.get("use_sim_time"), Some(&ParameterValue::Boolean(false)));

    #[derive(serde::Deserialize, Debug)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Solver {
        tolerance: f64,
        max_iter: u32,
    }
    #[derive(serde::Deserialize, Debug)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Params {
        rate: f64,
        use_sim_time: bool,
        frames: Vec<String>,
        solver: Solver,
    }
    let typed: Params = p.deserialize().unwrap();
    assert_eq!(typed.rate, 200.0);
    assert_eq!(typed.solver.max_iter, 7);
    assert_eq!(typed.solver.tolerance, 1e-9);

    #[derive(serde::Deserialize, Debug)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Narrow {
        rate: f64,
    }
    let err = p.deserialize::<Narrow>().unwrap_err().to_string();
    assert!(err.contains("unknown field"), "{err}");

    let missing = RosArgs::parse(args("--ros-args --params-file /nonexistent/x.yaml")).unwrap();
    assert!(matches!(
        missing.parameters("/n"),
        Err(RosArgsError::Io { .. })
    ));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn wildcard_sections_and_unqualified_overrides_are_shared() {
    let yaml = "
/**:
  ros__parameters:
    a: 1
    b: 1
/cd_x:
  ros__parameters:
    b: 2
    c: 2
";
    let p = parse_params_yaml(yaml, "/cd_x").unwrap();
    // `b` is set by the node's own section too, so it is the node's own.
    assert_eq!(p.shared.iter().collect::<Vec<_>>(), vec!["a"]);
    assert_eq!(p.get("b"), Some(&ParameterValue::Integer(2)));
    let a = RosArgs::parse(args(
        "--ros-args -p d:=1 -p cd_x:e:=1 -p /cd_x:f:=1 -p cd_y:g:=1",
    ))
    .unwrap();
    let mut q = a.parameters("/cd_x").unwrap();
    assert_eq!(q.shared.iter().collect::<Vec<_>>(), vec!["d"]);
    assert_eq!(q.get("g"), None);
    // A later shared value of an own name keeps it own; its value wins.
    q.merge(p);
    let mut over = Parameters::default();
    over.set("c".into(), ParameterValue::Integer(3), true);
    q.merge(over);
    assert_eq!(q.get("c"), Some(&ParameterValue::Integer(3)));
    assert_eq!(q.shared.iter().collect::<Vec<_>>(), vec!["a", "d"]);
    let dropped = q.drop_shared(|n| n == "a");
    assert_eq!(dropped, vec!["d"]);
    assert_eq!(q.get("d"), None);
    assert!(q.get("a").is_some() && q.get("e").is_some() && q.get("f").is_some());
}
