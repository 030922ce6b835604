//! Criterion benchmarks of the rigid-body and constrained algorithms on the reference robots
//! (UR5: 6 DOF, end-effector point held, 3 rows; Solo12 on a free-flyer: 18 DOF, 4 feet, 12 rows).
//! `tools/bench_vs_pinocchio.py` runs these beside Pinocchio and prints the ratios.

use constraint_dynamics::algorithm::*;
use constraint_dynamics::constraints::{ConstraintData, ConstraintSet, ConstraintSpec, Row};
use constraint_dynamics::dynamics::{Baumgarte, KktWorkspace, constrained_forward_dynamics};
use constraint_dynamics::{BaseType, Model, ModelOptions};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::PathBuf;

struct Case {
    name: &'static str,
    model: Model,
    q: Vec<f64>,
    v: Vec<f64>,
    tau: Vec<f64>,
    set: ConstraintSet,
}

fn reference() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/reference")
}

fn load(name: &'static str, urdf: &str, base: BaseType, case: &str) -> Case {
    let model = Model::from_urdf_file(
        reference().join("urdf").join(urdf),
        &ModelOptions {
            base,
            ..Default::default()
        },
    )
    .expect("model");
    let text = std::fs::read_to_string(reference().join("cases").join(case)).expect("case file");
    let json: serde_json::Value = serde_json::from_str(&text).expect("json");
    let st = &json["states"][2];
    let f = |v: &serde_json::Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let cons = st.get("constraints").unwrap_or(&json["constraints"]);
    let specs: Vec<ConstraintSpec> = cons
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let a = f(&c["world_anchor"]);
            ConstraintSpec::Point {
                name: format!("c{k}"),
                frame_a: c["link"].as_str().unwrap().into(),
                point_a: [0.0; 3],
                frame_b: "world".into(),
                point_b: [a[0], a[1], a[2]],
                rows: vec![Row::X, Row::Y, Row::Z],
            }
        })
        .collect();
    let q = f(&st["q"]);
    let set = ConstraintSet::new(&model, &specs, &q).expect("constraints");
    Case {
        name,
        q,
        v: f(&st["qd"]),
        tau: f(&st["tau"]),
        model,
        set,
    }
}

fn bench(c: &mut Criterion) {
    let cases = [
        load(
            "ur5",
            "ur5_robot.urdf",
            BaseType::Fixed,
            "ur5_ee_point.json",
        ),
        load(
            "solo12",
            "solo12.urdf",
            BaseType::Floating,
            "solo12_four_feet.json",
        ),
    ];
    for k in &cases {
        let (m, q, v, tau) = (&k.model, &k.q, &k.v, &k.tau);
        let mut d = Data::new(m);
        c.bench_function(&format!("{}/rnea", k.name), |b| {
            b.iter(|| {
                rnea(m, &mut d, black_box(q), black_box(v), black_box(tau));
            })
        });
        c.bench_function(&format!("{}/crba", k.name), |b| {
            b.iter(|| {
                crba(m, &mut d, black_box(q));
            })
        });
        c.bench_function(&format!("{}/aba", k.name), |b| {
            b.iter(|| {
                aba(m, &mut d, black_box(q), black_box(v), black_box(tau));
            })
        });
        let mut cd = ConstraintData::new(m, &k.set);
        let mut ws = KktWorkspace::new(m, &k.set);
        c.bench_function(&format!("{}/constraint_terms", k.name), |b| {
            b.iter(|| {
                k.set
                    .evaluate(m, &mut d, &mut cd, black_box(q), black_box(v))
            })
        });
        c.bench_function(&format!("{}/constrained_dynamics", k.name), |b| {
            b.iter(|| {
                constrained_forward_dynamics(
                    m,
                    &mut d,
                    &k.set,
                    &mut cd,
                    &mut ws,
                    black_box(q),
                    black_box(v),
                    black_box(tau),
                    Baumgarte::default(),
                )
                .unwrap();
            })
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().warm_up_time(std::time::Duration::from_millis(500)).measurement_time(std::time::Duration::from_secs(2));
    targets = bench
}
criterion_main!(benches);
