//! The state file: `{"q": [...], "v": [...], "tau": [...]}` in the printed coordinate order
//! (v and tau optional, zero by default). Without a file, the scene's initial state and τ = 0.

use constraint_dynamics::{Error, Result, Scene};
use serde::Deserialize;
use std::path::Path;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StateFile {
    pub q: Vec<f64>,
    #[serde(default)]
    pub v: Option<Vec<f64>>,
    #[serde(default)]
    pub tau: Option<Vec<f64>>,
}

/// Load a scene, printing what the loader accepted but a user should know (a non-physical
/// inertia on a welded link, a repaired body) to stderr, one `warning:` line each.
pub fn load_scene(path: &Path) -> Result<Scene> {
    let scene = Scene::load(path)?;
    for w in &scene.model.warnings {
        eprintln!("warning: {w}");
    }
    Ok(scene)
}

/// (q, v, τ) from `path`, or the scene's initial state.
pub fn load(scene: &Scene, path: Option<&Path>) -> Result<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    let nv = scene.model.nv;
    let Some(path) = path else {
        return Ok((scene.q0.clone(), scene.v0.clone(), vec![0.0; nv]));
    };
    let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
        path: path.display().to_string(),
        source: e,
    })?;
    let s: StateFile = serde_json::from_str(&text).map_err(|e| Error::Scene {
        file: path.display().to_string(),
        message: e.to_string(),
    })?;
    let (q, v, tau) = (
        s.q,
        s.v.unwrap_or_else(|| vec![0.0; nv]),
        s.tau.unwrap_or_else(|| vec![0.0; nv]),
    );
    // Sizes, finiteness and the documented magnitudes (limits::MAX_STATE), naming the file.
    constraint_dynamics::limits::check_input_state(&scene.model, &q, &v, &tau).map_err(|e| {
        Error::Scene {
            file: path.display().to_string(),
            message: e.to_string(),
        }
    })?;
    Ok((q, v, tau))
}
