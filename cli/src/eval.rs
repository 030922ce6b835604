//! `eval`: q̈ (and with constraints λ and the forces) at one state.

use crate::json::matrix_rows;
use constraint_dynamics::applied::{applied_generalized_force, constraint_forces_at};
use constraint_dynamics::derivatives::DerivativeData;
use constraint_dynamics::dynamics::Formulation;
use constraint_dynamics::forces::ForceElements;
use constraint_dynamics::{Result, System};
use serde_json::{Value, json};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct EvalArgs {
    /// Scene file (YAML).
    #[arg(long)]
    scene: PathBuf,
    /// State file (JSON with q, v, tau); default: the scene's initial state, τ = 0.
    #[arg(long)]
    state: Option<PathBuf>,
    /// Also print M (nv × nv, row-major rows) and h = C v + g.
    #[arg(long)]
    terms: bool,
    /// Also print the analytic derivatives of q̈ and λ w.r.t. q (tangent space, q ⊕ δ), v and τ
    /// (`derivatives`; with --terms also RNEA's ∂τ/∂q, ∂τ/∂v at the state's q̈). τ is the total
    /// applied generalized force: the state's τ plus the scene's force elements at this state,
    /// whose own dependence on q and v is not differentiated.
    #[arg(long)]
    derivatives: bool,
    /// auto | multipliers | embedded (default: multipliers, so the forces are printed).
    #[arg(long, default_value = "multipliers")]
    formulation: String,
}

pub fn run(a: EvalArgs) -> Result<Value> {
    let scene = super::state::load_scene(&a.scene)?;
    let formulation = match a.formulation.as_str() {
        "auto" => Formulation::Auto,
        "multipliers" => Formulation::Multipliers,
        "embedded" => Formulation::Embedded,
        other => {
            return Err(constraint_dynamics::Error::Invalid(format!(
                "--formulation '{other}': expected auto, multipliers or embedded"
            )));
        }
    };
    let mut sys = System::from_scene(&scene)?.with_formulation(formulation);
    let (q, v, tau) = super::state::load(&scene, a.state.as_deref())?;
    // τ of the state file plus the scene's force elements (springs, dampers, scheduled torques).
    let mut elements = ForceElements::new(sys.model(), &scene.file.forces)?;
    let use_multipliers = sys.formulation() != Formulation::Embedded;
    let (qdd, at) = if use_multipliers {
        let at = constraint_forces_at(&mut sys, &mut elements, (0.0, &q, &v), &tau)?;
        (at.qdd.clone(), Some(at))
    } else {
        let nv = sys.model().nv;
        let mut applied = vec![0.0; nv];
        applied_generalized_force(&mut sys, &mut elements, (0.0, &q, &v), &tau, &mut applied);
        (
            sys.forward_dynamics(&q, &v, &applied, false)?
                .as_slice()
                .to_vec(),
            None,
        )
    };
    let m = sys.model();
    let mut out = json!({
        "scene": a.scene.display().to_string(),
        "q_names": m.q_names,
        "v_names": m.v_names,
        "formulation": sys.last_formulation(),
        "qdd": qdd,
    });
    if !sys.constraints().is_empty() {
        out["constraint_rows"] = json!(sys.constraints().row_names());
        out["phi"] = json!(sys.rows().phi.as_slice());
        out["velocity_residual"] = json!(sys.rows().jv.as_slice());
        if let Some(at) = &at {
            out["lambda"] = json!(at.lambda);
            out["generalized_constraint_force"] = json!(at.generalized_force);
            out["rank_deficiency"] = json!(at.rank_deficiency);
            out["constraints"] = serde_json::to_value(&at.forces).unwrap_or_default();
        } else {
            let p = &sys.embedded().partition;
            out["independent_velocities"] = json!(
                p.independent
                    .iter()
                    .map(|&i| m.v_names[i].clone())
                    .collect::<Vec<_>>()
            );
        }
    }
    if a.terms {
        // Formed here: a large tree's dynamics (O(n)) never forms M.
        let (mass, h) = sys.terms_at(&q, &v);
        out["M"] = matrix_rows(mass);
        out["h"] = json!(h.as_slice());
    }
    if a.derivatives {
        out["derivatives"] = derivatives(&mut sys, &mut elements, &q, &v, &tau, &qdd, a.terms)?;
    }
    let (ke, pe, com) = sys.energy(&q, &v);
    out["kinetic_energy"] = json!(ke);
    out["potential_energy"] = json!(pe);
    out["center_of_mass"] = json!(com);
    Ok(out)
}

/// The `derivatives` object of `eval --derivatives`.
fn derivatives(
    sys: &mut System,
    elements: &mut ForceElements,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    qdd: &[f64],
    terms: bool,
) -> Result<Value> {
    let nv = sys.model().nv;
    let mut applied = vec![0.0; nv];
    applied_generalized_force(sys, elements, (0.0, q, v), tau, &mut applied);
    let mut dd = DerivativeData::new(sys.model(), sys.constraints().nrows);
    let mut out = json!({
        "convention": "X[i][j] = d out_i / d in_j; d/dq along delta in q (+) delta (tangent, nv columns)",
    });
    sys.dynamics_derivatives(&mut dd, 0.0, q, v, &applied)?;
    if !sys.constraints().is_empty() {
        out["lambda_unique"] = json!(dd.lambda_unique);
        if dd.lambda_unique {
            out["dlambda_dq"] = matrix_rows(&dd.dlambda_dq);
            out["dlambda_dv"] = matrix_rows(&dd.dlambda_dv);
            out["dlambda_dtau"] = matrix_rows(&dd.dlambda_dtau);
        }
    }
    out["dqdd_dq"] = matrix_rows(&dd.dqdd_dq);
    out["dqdd_dv"] = matrix_rows(&dd.dqdd_dv);
    out["dqdd_dtau"] = matrix_rows(&dd.dqdd_dtau);
    if terms {
        sys.inverse_dynamics_derivatives(&mut dd, q, v, qdd);
        out["dtau_dq"] = matrix_rows(&dd.dtau_dq);
        out["dtau_dv"] = matrix_rows(&dd.dtau_dv);
    }
    Ok(out)
}
