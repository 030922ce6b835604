//! The dynamic projection (a control period Δt): from rest, a request far beyond reach gains
//! Δt times the envelope's limit — the closed forms of docs/projection.md ("The acceleration
//! envelope") on the cart with a tall mass, the envelope itself on the floating mobile
//! manipulator with its arm held; Δt = 0 is the kinematic projection bit for bit on every
//! reference case; every optimal answer carries a KKT and cone certificate; infeasible requests
//! name the limits that cannot hold together.
//!
//! Conventions: `M (v⁺ − v) = Δt (Q + Sᵀτ − h) + JᵀΛ`, Λ = impulse ON the robot over Δt.

mod common;
use common::*;
use constraint_dynamics::constraints::ConstraintSet;
use constraint_dynamics::envelope::{EnvelopeData, EnvelopeModel, acceleration_envelope};
use constraint_dynamics::projection::*;
use constraint_dynamics::scene::SceneFile;
use constraint_dynamics::{Scene, System};
use nalgebra::{DMatrix, DVector};
use serde_json::json;

const G: f64 = 9.81;

/// The cart's numbers (urdf/cart_tall_mass.urdf), as tests/envelope.rs writes them out.
mod cart {
    pub const R: f64 = 0.1;
    pub const I_W: f64 = 0.005;
    pub const TAU_MAX: f64 = 4.0;
    pub const L_C: f64 = 0.4;
    pub const M: f64 = 32.5;
    pub const M_X: f64 = -2.7;
    pub const M_Z: f64 = 13.225;
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// The cart's scene with the wheels' friction coefficient `mu`.
fn cart_scene(mu: f64) -> Scene {
    let path = repo_dir().join("tests/data/cart_tall_mass.yaml");
    let text = std::fs::read_to_string(&path).unwrap();
    let text = text.replace("friction: 0.8", &format!("friction: {mu}"));
    let file: SceneFile = serde_yaml::from_str(&text).unwrap();
    let urdf = repo_dir().join("urdf/cart_tall_mass.urdf");
    let urdf_text = std::fs::read_to_string(&urdf).unwrap();
    Scene::from_parts(&path, file, &urdf_text, &urdf.display().to_string()).unwrap()
}

struct Robot {
    scene: Scene,
    sys: System,
    em: EnvelopeModel,
    proj: DynamicProjector,
}

fn robot(scene: Scene) -> Robot {
    let sys = System::from_scene(&scene).unwrap();
    let em = EnvelopeModel::from_scene(&scene, &sys).unwrap();
    let proj = DynamicProjector::new(&sys.model, &sys.constraints);
    Robot {
        scene,
        sys,
        em,
        proj,
    }
}

impl Robot {
    fn named(&mut self, v: &[f64], request: serde_json::Value) -> Projection {
        let req = ProjectionRequest::from_json(&request.to_string()).unwrap();
        let q = self.scene.q0.clone();
        let zero = vec![0.0; self.sys.model.nv];
        self.proj
            .project_request(&mut self.sys, Some(&self.em), &q, v, &zero, &req)
            .unwrap()
    }
}

fn binding(p: &Projection) -> Vec<(String, String)> {
    let mut b: Vec<(String, String)> = p
        .dynamics
        .as_ref()
        .unwrap()
        .binding
        .iter()
        .map(|l| (l.kind.to_string(), l.name.clone()))
        .collect();
    b.sort();
    b.dedup();
    b
}

fn pair(kind: &str, a: &str, b: &str) -> Vec<(String, String)> {
    vec![(kind.into(), a.into()), (kind.into(), b.into())]
}

/// Relative agreement with Δt × the envelope's limit: the cone program is solved to 1e-10.
const TOL: f64 = 1e-6;

#[test]
fn infeasible_debug() {
    let mut r = robot(cart_scene(0.8));
    let v0 = r.scene.v0.clone();
    let p = r.named(
        &v0,
        json!({"base_twist": [1.0, 0, 0, 0, 0, 0], "upper": {"vx": -0.1}, "period": 0.01}),
    );
    eprintln!("{:?} {:?} {:?}", p.status, p.message, r.proj.tau);
}
