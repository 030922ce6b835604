//! `envelope`: the base's acceleration limits at one state (forward acceleration and
//! deceleration, yaw acceleration left and right) and what binds each, as JSON.

use constraint_dynamics::applied::applied_generalized_force;
use constraint_dynamics::envelope::{
    EnvelopeData, EnvelopeModel, EnvelopeReport, acceleration_envelope,
};
use constraint_dynamics::forces::ForceElements;
use constraint_dynamics::{Error, Result, System};
use serde_json::Value;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct EnvelopeArgs {
    /// Scene file (YAML).
    #[arg(long)]
    scene: PathBuf,
    /// State file (JSON with q and v, as for `eval`; its tau is ignored: the envelope asks what
    /// torques within the efforts can do); default: the scene's initial state.
    #[arg(long)]
    state: Option<PathBuf>,
}

pub fn run(a: EnvelopeArgs) -> Result<Value> {
    // Instantaneous answers: a sideways tyre's creep is no velocity to command.
    let scene = super::state::load_scene(&a.scene)?.rigid_sideways();
    let mut sys = System::from_scene(&scene)?;
    let (q, v, _tau) = super::state::load(&scene, a.state.as_deref())?;
    let em = EnvelopeModel::from_scene(&scene, &sys)?;
    let mut ed = EnvelopeData::new(&em);
    // The scene's force elements (springs, dampers, URDF damping) at (q, v) act as well.
    let mut elements = ForceElements::new(sys.model(), &scene.file.forces)?;
    let zero = vec![0.0; sys.model().nv];
    let mut applied = vec![0.0; sys.model().nv];
    applied_generalized_force(
        &mut sys,
        &mut elements,
        (0.0, q.as_slice(), v.as_slice()),
        &zero,
        &mut applied,
    );
    acceleration_envelope(&mut sys, &em, &mut ed, &q, &v, &applied)?;
    let report = EnvelopeReport::new(sys.model(), &em, &ed.envelope);
    let mut out = serde_json::to_value(report).map_err(|e| Error::Invalid(e.to_string()))?;
    out["scene"] = Value::from(a.scene.display().to_string());
    Ok(out)
}
