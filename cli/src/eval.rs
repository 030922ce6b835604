//! `eval`: q̈ (and with constraints λ and the forces) at one state.

use constraint_dynamics::applied::{applied_generalized_force, constraint_forces_at};
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
    /// auto | multipliers | embedded (default: multipliers, so the forces are printed).
    #[arg(long, default_value = "multipliers")]
    formulation: String,
}

pub fn run(a: EvalArgs) -> Result<Value> {
    let scene = super::state::load_scene(&a.scene)?;
    let mut sys = System::from_scene(&scene)?;
    sys.formulation = match a.formulation.as_str() {
        "auto" => Formulation::Auto,
        "multipliers" => Formulation::Multipliers,
        "embedded" => Formulation::Embedded,
        other => {
            return Err(constraint_dynamics::Error::Invalid(format!(
                "--formulation '{other}': expected auto, multipliers or embedded"
            )));
        }
    };
    let (q, v, tau) = super::state::load(&scene, a.state.as_deref())?;
    // τ of the state file plus the scene's force elements (springs, dampers, scheduled torques).
    let mut elements = ForceElements::new(&sys.model, &scene.file.forces)?;
    let use_multipliers = sys.formulation != Formulation::Embedded;
    let (qdd, at) = if use_multipliers {
        let at = constraint_forces_at(&mut sys, &mut elements, (0.0, &q, &v), &tau)?;
        (at.qdd.clone(), Some(at))
    } else {
        let nv = sys.model.nv;
        let mut applied = vec![0.0; nv];
        applied_generalized_force(
            &mut sys,
            &mut elements,
            (0.0, &q, &v),
            &tau,
            &vec![0.0; nv],
            &mut applied,
        );
        (
            sys.forward_dynamics(&q, &v, &applied, false)?
                .as_slice()
                .to_vec(),
            None,
        )
    };
    let m = &sys.model;
    let mut out = json!({
        "scene": a.scene.display().to_string(),
        "q_names": m.q_names,
        "v_names": m.v_names,
        "formulation": sys.last_formulation,
        "qdd": qdd,
    });
    if !sys.constraints.is_empty() {
        out["constraint_rows"] = json!(sys.constraints.row_names());
        out["phi"] = json!(sys.cdata.phi.as_slice());
        out["velocity_residual"] = json!(sys.cdata.jv.as_slice());
        if let Some(at) = &at {
            out["lambda"] = json!(at.lambda);
            out["generalized_constraint_force"] = json!(at.generalized_force);
            out["rank_deficiency"] = json!(at.rank_deficiency);
            out["constraints"] = serde_json::to_value(&at.forces).unwrap_or_default();
        } else {
            let p = &sys.embedded.partition;
            out["independent_velocities"] = json!(
                p.independent
                    .iter()
                    .map(|&i| m.v_names[i].clone())
                    .collect::<Vec<_>>()
            );
        }
    }
    if a.terms {
        let mm = &sys.data.mass_matrix;
        let rows: Vec<Vec<f64>> = (0..mm.nrows())
            .map(|i| mm.row(i).iter().copied().collect())
            .collect();
        // h = C v + g (data.tau holds the bias forces after the dynamics call)
        out["M"] = json!(rows);
        out["h"] = json!(sys.data.tau.as_slice());
    }
    let (ke, pe, com) = sys.energy(&q, &v);
    out["kinetic_energy"] = json!(ke);
    out["potential_energy"] = json!(pe);
    out["center_of_mass"] = json!(com);
    Ok(out)
}
