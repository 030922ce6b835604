//! `calibrate`: fits what a team does not know of its robot to recorded drives (docs/logs.md),
//! prints the fitted values with their standard errors and each drive's errors before and after
//! (`evaluate`'s figures), and writes the calibrated scene.

use super::evaluate::ReplayArgs;
use constraint_dynamics::calibrate::{
    CalibrationSettings, FitParameter, SceneParameters, SceneSource, calibrate,
};
use constraint_dynamics::replay::{EvaluationSettings, Recording, evaluate};
use constraint_dynamics::{Error, Result};
use serde_json::{Value, json};
use std::path::{Component, Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args)]
pub struct CalibrateArgs {
    /// Scene file (YAML) to calibrate.
    #[arg(long)]
    scene: PathBuf,
    /// A recorded drive (rosbag2 `.mcap` file or bag directory); repeat for several.
    #[arg(long, required = true)]
    bag: Vec<PathBuf>,
    /// What to fit, comma-separated: rolling_radius, track_offset, track_turn_gain, base_mass,
    /// turning_friction, traction_torque, traction_load_transfer, command_lag, tyre_slip_speed,
    /// lateral_creep (default: every one the scene can take, which `default` names beside
    /// others). command_lag on a scene that declares none declares one, from the lag the
    /// drive's response shows: `--fit default,command_lag`.
    #[arg(long, value_delimiter = ',')]
    fit: Vec<String>,
    /// Do not fit the process noise (the scene's `uncertainty:` stays as it is).
    #[arg(long)]
    no_process_noise: bool,
    /// The horizons the fit weighs [s], comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0.5,1,2")]
    horizons: Vec<f64>,
    /// The horizons of the before/after figures [s], comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0.25,0.5,1,2")]
    report_horizons: Vec<f64>,
    #[command(flatten)]
    replay: ReplayArgs,
    /// Where to write the calibrated scene (its `urdf:` rewritten to resolve from there).
    #[arg(long)]
    out: PathBuf,
}

/// `to` relative to the directory `from` (both absolute).
fn relative(to: &Path, from: &Path) -> PathBuf {
    let a: Vec<Component> = to.components().collect();
    let b: Vec<Component> = from.components().collect();
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut out = PathBuf::new();
    for _ in common..b.len() {
        out.push("..");
    }
    for c in &a[common..] {
        out.push(c.as_os_str());
    }
    out
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> Error + '_ {
    move |source| Error::Io {
        path: path.display().to_string(),
        source,
    }
}

/// Each drive's figures (evaluate's `horizons`) with `scene`.
fn figures(
    scene: &constraint_dynamics::Scene,
    recordings: &[Recording],
    settings: &EvaluationSettings,
) -> Result<Vec<Value>> {
    recordings
        .iter()
        .map(|r| {
            let ev = evaluate(scene, r, settings).map_err(|e| Error::Invalid(e.to_string()))?;
            serde_json::to_value(&ev.horizons).map_err(|e| Error::Invalid(e.to_string()))
        })
        .collect()
}

pub fn run(a: CalibrateArgs) -> Result<Value> {
    let began = Instant::now();
    let mut fit = (a.fit.iter())
        .map(|n| n.trim())
        .filter(|n| *n != DEFAULT_SET)
        .map(|n| FitParameter::parse(n).map_err(|e| Error::Invalid(format!("--fit: {e}"))))
        .collect::<Result<Vec<_>>>()?;
    let text = std::fs::read_to_string(&a.scene).map_err(io(&a.scene))?;
    let mut yaml: serde_yaml::Value = serde_yaml::from_str(&text).map_err(|e| Error::Scene {
        file: a.scene.display().to_string(),
        message: e.to_string(),
    })?;
    // Loading it as every command does first: the scene's own errors, as they read there.
    let scene = super::state::load_scene(&a.scene)?;
    if a.fit.iter().any(|n| n.trim() == DEFAULT_SET) {
        let places = SceneParameters::new(&yaml, &scene.model)
            .map_err(|e| Error::Invalid(format!("{}: {e}", a.scene.display())))?;
        fit.extend(places.available());
    }
    let urdf_rel = yaml
        .get("urdf")
        .and_then(|u| u.as_str())
        .unwrap_or_default();
    let urdf_path = a.scene.parent().unwrap_or(Path::new(".")).join(urdf_rel);
    let urdf_text = std::fs::read_to_string(&urdf_path).map_err(io(&urdf_path))?;
    let urdf_name = urdf_path.display().to_string();
    let recordings = (a.bag.iter())
        .map(|b| a.replay.read(b))
        .collect::<Result<Vec<_>>>()?;
    let report = a.replay.settings(a.report_horizons.clone());
    // The figures of the scene as given: first where a lag's start is read from them.
    let mut before = None;
    let mut lag_start = None;
    if fit.contains(&FitParameter::CommandLag) {
        let b = figures(&scene, &recordings, &report)?;
        lag_start = declare_lag_to_fit(&mut yaml, &b);
        before = Some(b);
    }
    if let Some(start) = &lag_start {
        eprintln!("calibrate: {}", start["why"].as_str().unwrap_or_default());
    }
    let source = SceneSource {
        yaml: &yaml,
        path: &a.scene,
        urdf: (&urdf_text, &urdf_name),
    };
    let settings = CalibrationSettings {
        fit,
        replay: a.replay.settings(a.horizons.clone()),
        fit_process_noise: !a.no_process_noise,
        ..CalibrationSettings::default()
    };
    let cal = calibrate(&source, &recordings, &settings)
        .map_err(|e| Error::Invalid(format!("{}: {e}", a.scene.display())))?;

    // The calibrated scene, its URDF path resolving from where it is written.
    let mut out_yaml = cal.scene.clone();
    let out_dir = a.out.parent().filter(|p| !p.as_os_str().is_empty());
    let out_dir = std::fs::canonicalize(out_dir.unwrap_or(Path::new(".")))
        .map_err(io(out_dir.unwrap_or(Path::new("."))))?;
    let urdf_abs = std::fs::canonicalize(&urdf_path).map_err(io(&urdf_path))?;
    if let Some(m) = out_yaml.as_mapping_mut() {
        let rel = relative(&urdf_abs, &out_dir).display().to_string();
        m.insert("urdf".into(), rel.into());
    }
    let body = serde_yaml::to_string(&out_yaml).map_err(|e| Error::Invalid(e.to_string()))?;
    let bags: Vec<String> = a.bag.iter().map(|b| b.display().to_string()).collect();
    let header = format!(
        "# {} calibrated by `constraint_dynamics calibrate` on {} (docs/logs.md).\n",
        a.scene.display(),
        bags.join(", ")
    );
    std::fs::write(&a.out, header + &body).map_err(io(&a.out))?;

    // Before and after on every drive, read back as every other command reads a scene.
    let calibrated = super::state::load_scene(&a.out)?;
    let before = match before {
        Some(b) => b,
        None => figures(&scene, &recordings, &report)?,
    };
    let after = figures(&calibrated, &recordings, &report)?;
    let declares_lag =
        (calibrated.file.actuators.diff_drive.as_ref()).is_some_and(|d| d.command_lag.is_some());
    // Without a declared lag none of the fitted values can take one up, and the scene as
    // given shows it most clearly; with one, what the fit left of it.
    let advice: Vec<String> = (bags.iter().zip(before.iter().zip(&after)))
        .filter_map(|(bag, (before, after))| match declares_lag {
            false => lag_advice(bag, before, declares_lag),
            true => lag_advice(bag, after, declares_lag),
        })
        .collect();
    for a in &advice {
        eprintln!("calibrate: {a}");
    }
    let per_bag: Vec<Value> = (bags.iter().zip(before).zip(after))
        .map(|((bag, before), after)| json!({"bag": bag, "before": before, "after": after}))
        .collect();
    let mut out = serde_json::to_value(&cal).map_err(|e| Error::Invalid(e.to_string()))?;
    out["bags"] = Value::Array(per_bag);
    out["scene"] = json!(a.scene.display().to_string());
    out["out"] = json!(a.out.display().to_string());
    out["reference_topic"] = json!(recordings.first().map(|r| r.reference.name.clone()));
    out["run_time_s"] = json!(began.elapsed().as_secs_f64());
    out["advice"] = json!(advice);
    if let Some(start) = lag_start {
        out["command_lag_start"] = start;
    }
    Ok(out)
}

/// The `--fit` name of every parameter the scene as given can take (the default set), to
/// name beside others.
const DEFAULT_SET: &str = "default";

/// Where a fit of `command_lag` starts on a scene with a diff drive that declares none, when
/// the drive's response (evaluate's, with the scene as given) shows no lag [s].
const LAG_START_S: f64 = 0.05;

/// Declares `actuators.diff_drive.command_lag` in `yaml` where `--fit command_lag` asks for one
/// the scene lacks: at the lag the drives' responses show with the scene as given (`before`:
/// evaluate's horizons per drive; the mean over the drives whose response at its longest
/// horizon is a lag above three standard errors), or at [`LAG_START_S`]. Returns the start
/// and why (the JSON's `command_lag_start`); None where the scene has no diff drive (the fit
/// then names what is missing) or declares a lag already.
fn declare_lag_to_fit(yaml: &mut serde_yaml::Value, before: &[Value]) -> Option<Value> {
    let drive = yaml.get_mut("actuators")?.get_mut("diff_drive")?;
    let drive = drive.as_mapping_mut()?;
    if drive.contains_key("command_lag") {
        return None;
    }
    let lags: Vec<f64> = (before.iter())
        .filter_map(response_lag)
        .filter(|(_, lag, se)| *lag > 0.0 && *lag > 3.0 * se)
        .map(|(_, lag, _)| lag)
        .collect();
    let (start, why) = match lags.is_empty() {
        true => (
            LAG_START_S,
            format!(
                "the scene declares no actuators.diff_drive.command_lag and the drive's \
                 response shows none: fitting one from {LAG_START_S} s"
            ),
        ),
        false => {
            let mean = lags.iter().sum::<f64>() / lags.len() as f64;
            (
                mean,
                format!(
                    "the scene declares no actuators.diff_drive.command_lag: fitting one from \
                     {mean:.3} s, the lag of the drive's response with the scene as given"
                ),
            )
        }
    };
    drive.insert("command_lag".into(), start.into());
    Some(json!({"value_s": start, "why": why}))
}

/// The response at the longest horizon that has one (evaluate's horizons): (horizon [s],
/// lag [s], its standard error [s]).
fn response_lag(figures: &Value) -> Option<(f64, f64, f64)> {
    (figures.as_array()?.iter().rev()).find_map(|h| {
        let r = &h["response"];
        Some((
            h["horizon_s"].as_f64()?,
            r["lag_s"].as_f64()?,
            r["lag_std_error_s"].as_f64()?,
        ))
    })
}

/// The lag [s] beyond which a drive is called late (the predictor's `monitor.lag_threshold`
/// default, docs/nodes.md).
const LAG_WORTH_S: f64 = 0.08;

/// Where a drive reaches its commands later than the scene predicts it (the response at the
/// longest horizon that has one, above [`LAG_WORTH_S`] and three standard errors,
/// docs/logs.md): what the scene should declare. `figures` is evaluate's horizons, of the
/// scene as given where it declares no lag and as calibrated where it does.
fn lag_advice(bag: &str, figures: &Value, declares_lag: bool) -> Option<String> {
    let (h, lag, se) = response_lag(figures)?;
    if !(lag > LAG_WORTH_S && lag > 3.0 * se) {
        return None;
    }
    let (which, what) = match declares_lag {
        false => (
            "as given",
            "declare actuators.diff_drive.command_lag (an estimate) and calibrate again, or \
             calibrate with --fit default,command_lag",
        ),
        true => (
            "as calibrated",
            "its declared command_lag falls short: start the fit from a longer one",
        ),
    };
    Some(format!(
        "{bag}: with the scene {which}, the drive reaches its commands {lag:.3} ± {se:.3} s \
         later than the model at {h} s: {what}"
    ))
}

#[cfg(test)]
mod tests {
    /// `--fit`'s help names every parameter the library can fit.
    #[test]
    fn the_fit_help_names_every_parameter() {
        use clap::CommandFactory;
        #[derive(clap::Parser)]
        struct Wrapper {
            #[command(flatten)]
            args: super::CalibrateArgs,
        }
        let help = Wrapper::command().render_long_help().to_string();
        for p in super::FitParameter::ALL {
            assert!(
                help.contains(p.name()),
                "{} missing from:\n{help}",
                p.name()
            );
        }
    }
}
