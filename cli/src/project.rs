//! `project`: the constraint-respecting velocity closest to a desired one (kinetic-energy metric),
//! with bounds, as JSON: v*, its base-twist / joint split, the impulses per constraint, the active
//! bounds, or the named conflicting set when the request is infeasible. With `--period Δt` the
//! velocity is also reachable within Δt under the robot's efforts, friction cones and contacts
//! (the dynamic projection), and the answer names what binds it.

use constraint_dynamics::applied::applied_generalized_force;
use constraint_dynamics::envelope::EnvelopeModel;
use constraint_dynamics::forces::ForceElements;
use constraint_dynamics::projection::{DynamicProjector, ProjectionRequest};
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
    /// Control period Δt [s]: the answer is reachable within Δt from the state's velocity under
    /// the URDF efforts, the friction cones and the contacts (which push, never pull); 0 (the
    /// default) is the kinematic projection. Overrides the request's `period`.
    #[arg(long)]
    period: Option<f64>,
}

pub fn run(a: ProjectArgs) -> Result<Value> {
    // Instantaneous answers: a sideways tyre's creep is no velocity to command.
    let scene = super::state::load_scene(&a.scene)?.rigid_sideways();
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
    let mut request = ProjectionRequest::from_json(&text)?;
    if let Some(period) = a.period {
        request.period = period;
    }
    let mut projector = DynamicProjector::new(sys.model(), sys.constraints());
    let nv = sys.model().nv;
    let mut applied = vec![0.0; nv];
    let em = if request.period != 0.0 {
        // The scene's force elements (springs, dampers, URDF damping) at (q, v) act as well.
        let mut elements = ForceElements::new(sys.model(), &scene.file.forces)?;
        let zero = vec![0.0; nv];
        applied_generalized_force(
            &mut sys,
            &mut elements,
            (0.0, q.as_slice(), v.as_slice()),
            &zero,
            &mut applied,
        );
        Some(EnvelopeModel::from_scene(&scene, &sys)?)
    } else {
        None
    };
    let result = projector.project_request(&mut sys, em.as_ref(), &q, &v, &applied, &request)?;
    let mut out = serde_json::to_value(result).map_err(|e| Error::Invalid(e.to_string()))?;
    out["scene"] = Value::from(a.scene.display().to_string());
    Ok(out)
}
