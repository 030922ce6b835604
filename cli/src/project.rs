//! `project`: the constraint-respecting velocity closest to a desired one (kinetic-energy metric),
//! with bounds, as JSON: v*, its base-twist / joint split, the impulses per constraint, the active
//! bounds, or the named conflicting set when the request is infeasible.

use constraint_dynamics::projection::{ProjectionRequest, VelocityProjector, project_system};
use constraint_dynamics::{Error, Result, System};
use serde_json::Value;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct ProjectArgs {
    /// Scene file (YAML).
    #[arg(long)]
    scene: PathBuf,
    /// State file (JSON with q and v, as for `eval`); default: the scene's initial state. v is
    /// the current velocity of an `accel_limit`.
    #[arg(long)]
    state: Option<PathBuf>,
    /// The request: a JSON file, or inline JSON if it starts with '{'. `{"v_des": [...]}` or
    /// `{"base_twist": [...], "joints": {"name": value}}`, plus optional `lower`/`upper` (by
    /// coordinate name), `accel_limit` {dt, a_max}, `A`, `b`, `velocity_limits`, `fill`.
    #[arg(long = "v-des")]
    v_des: String,
}

pub fn run(a: ProjectArgs) -> Result<Value> {
    let scene = super::state::load_scene(&a.scene)?;
    let mut sys = System::from_scene(&scene)?;
    let (q, v, _tau) = super::state::load(&scene, a.state.as_deref())?;
    let text = if a.v_des.trim_start().starts_with('{') {
        a.v_des.clone()
    } else {
        std::fs::read_to_string(&a.v_des).map_err(|e| Error::Io {
            path: a.v_des.clone(),
            source: e,
        })?
    };
    let request = ProjectionRequest::from_json(&text)?;
    let mut projector = VelocityProjector::new(&sys.model, &sys.constraints);
    let result = project_system(&mut projector, &mut sys, &q, &v, &request)?;
    let mut out = serde_json::to_value(result).map_err(|e| Error::Invalid(e.to_string()))?;
    out["scene"] = Value::from(a.scene.display().to_string());
    Ok(out)
}
