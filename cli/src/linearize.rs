//! `linearize`: A = ∂x⁺/∂x and B = ∂x⁺/∂τ of one integrator step at a state (x = (q, v) in the
//! tangent space, δq a right perturbation q ⊕ δq; τ the generalized force held over the step).

use crate::json::matrix_rows;
use constraint_dynamics::predict::{Linearization, Method, linearize_step};
use constraint_dynamics::{Error, Result, Scene, System};
use serde_json::{Value, json};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct LinearizeArgs {
    /// Scene file (YAML).
    #[arg(long)]
    scene: PathBuf,
    /// State file (JSON with q, v, tau); default: the scene's initial state, τ = 0.
    #[arg(long)]
    state: Option<PathBuf>,
    /// Step [s] (default: the scene's integration dt).
    #[arg(long)]
    dt: Option<f64>,
    #[arg(long, help = method_help())]
    method: Option<String>,
}

/// `--method`'s help: the methods whose step is linearized.
fn method_help() -> String {
    let names = Method::names(Method::linearizable(), " | ");
    format!("{names} (default: the scene's method).")
}

pub fn run(a: LinearizeArgs) -> Result<Value> {
    let scene = Scene::load(&a.scene)?;
    let mut sys = System::from_scene(&scene)?;
    let (q, v, tau) = super::state::load(&scene, a.state.as_deref())?;
    let method = match a.method.as_deref() {
        None => scene.file.integration.method,
        Some(m) => serde_json::from_value::<Method>(json!(m)).map_err(|_| {
            let expected = Method::names(Method::linearizable(), ", ");
            Error::Invalid(format!("--method '{m}': expected one of {expected}"))
        })?,
    };
    let dt = a.dt.unwrap_or(scene.file.integration.dt);
    let mut lin = Linearization::new(&sys);
    linearize_step(&mut sys, &mut lin, method, 0.0, &q, &v, &tau, dt)?;
    let m = sys.model();
    Ok(json!({
        "scene": a.scene.display().to_string(),
        "method": method,
        "dt": dt,
        "x_order": "[dq (tangent, v order); dv]",
        "v_names": m.v_names,
        "q_next": lin.q_next,
        "v_next": lin.v_next,
        "A": matrix_rows(&lin.a),
        "B": matrix_rows(&lin.b),
    }))
}
