//! External peers (CasADi on Andrews' squeezer): running one (its venv setup, then its script),
//! its runs as report rows, and the README paragraph on it.

use super::measure::final_distance;
use super::scenes::Peer;
use super::{Row, repo};
use constraint_dynamics::Scene;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// Run an external peer: its venv setup, then its script (JSON to a file). Its rows, with the
/// error against `reference` (q at the end of the horizon in the model's order), and what it
/// reported about itself. `Err` is why it did not run.
pub(super) fn run_peer(
    peer: &Peer,
    scene: &Scene,
    reference: &[f64],
) -> std::result::Result<(Vec<Row>, Value), String> {
    let root = repo();
    let venv = std::env::var_os(peer.venv_env)
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join(peer.venv));
    let setup = Command::new("bash")
        .arg(root.join(peer.setup))
        .arg(&venv)
        .current_dir(&root)
        .stdin(Stdio::null())
        .output()
        .map_err(|e| format!("{}: {e}", peer.setup))?;
    let tail = |b: &[u8]| {
        let text = String::from_utf8_lossy(b);
        let lines: Vec<&str> = text.lines().collect();
        lines[lines.len().saturating_sub(6)..].join(" / ")
    };
    if !setup.status.success() {
        return Err(format!(
            "{} failed ({}): {}",
            peer.setup,
            setup.status,
            tail(&setup.stderr)
        ));
    }
    let json_path = std::env::temp_dir().join(format!(
        "cd_report_peer_{}_{}.json",
        peer.name,
        std::process::id()
    ));
    let run = Command::new(venv.join("bin/python"))
        .arg(root.join(peer.script))
        .arg(&json_path)
        .current_dir(&root)
        .stdin(Stdio::null())
        .output()
        .map_err(|e| format!("{}/bin/python: {e}", venv.display()))?;
    if !run.status.success() {
        return Err(format!(
            "{} failed ({}): {}",
            peer.script,
            run.status,
            tail(&run.stderr)
        ));
    }
    let text =
        std::fs::read_to_string(&json_path).map_err(|e| format!("{}: {e}", json_path.display()))?;
    let _ = std::fs::remove_file(&json_path);
    let v: Value = serde_json::from_str(&text).map_err(|e| format!("{}: {e}", peer.script))?;
    // The peer's coordinate order → the model's.
    let names: Vec<String> = v["names"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|n| n.as_str().map(str::to_string))
                .collect()
        })
        .unwrap_or_default();
    let index: Vec<usize> = names
        .iter()
        .map(|n| {
            scene
                .model
                .q_names
                .iter()
                .position(|m| m == n)
                .ok_or_else(|| format!("{}: coordinate {n} not in the scene", peer.script))
        })
        .collect::<std::result::Result<_, _>>()?;
    if index.len() != scene.model.nq {
        return Err(format!(
            "{}: {} coordinates, the scene has {}",
            peer.script,
            index.len(),
            scene.model.nq
        ));
    }
    let mut rows = vec![];
    for r in v["runs"].as_array().into_iter().flatten() {
        let solver = r["solver"].as_str().unwrap_or("?");
        let status = r["status"].as_str().unwrap_or("no status").to_string();
        let count = |k: &str| r[k].as_u64().unwrap_or(0) as usize;
        let mut row = Row {
            line: format!("{}/{solver}", peer.name),
            method: format!("{}/{solver}", peer.name),
            drift: "none".into(),
            x: r["rtol"].as_f64().unwrap_or(f64::NAN),
            tolerance: true,
            peer: true,
            steps: count("nsteps"),
            evaluations: count("nfevals"),
            jacobian_evaluations: Some(count("njevals")),
            cpu: r["process_cpu_s"].as_f64().unwrap_or(f64::NAN),
            error: f64::NAN,
            phi: f64::NAN,
            jv: f64::NAN,
            energy: f64::NAN,
            least_squares: 0,
            status,
        };
        if row.ok() {
            let q: Vec<f64> = r["q"]
                .as_array()
                .map(|a| a.iter().map(|x| x.as_f64().unwrap_or(f64::NAN)).collect())
                .unwrap_or_default();
            if q.len() == index.len() {
                let mut qm = vec![0.0; scene.model.nq];
                for (k, &i) in index.iter().enumerate() {
                    qm[i] = q[k];
                }
                row.error = final_distance(scene, &qm, reference);
            } else {
                row.status = "no q in the peer's output".into();
            }
        }
        rows.push(row);
    }
    let mut about = v.clone();
    if let Some(o) = about.as_object_mut() {
        o.remove("runs");
    }
    Ok((rows, about))
}

/// The README paragraph on a peer's run: versions, build, model check, CPU measure.
pub(super) fn peer_note(peer: &Peer, about: &Value) -> String {
    let check = &about["model_check"];
    format!(
        "**Peer {}** — {}. This run: casadi {}, numpy {}, Python {}, {}; generated C compiled \
         {} (`{}`); model check at t = 0 against the test set: q̈(0) to {:.1e} and λ(0) to \
         {:.1e} relative. CPU: {}.\n\n",
        peer.name,
        peer.about,
        about["casadi"].as_str().unwrap_or("?"),
        about["numpy"].as_str().unwrap_or("?"),
        about["python"].as_str().unwrap_or("?"),
        about["compiler"].as_str().unwrap_or("?"),
        if about["compiled_now"].as_bool().unwrap_or(false) {
            format!(
                "in this run ({:.0} s, not in any CPU time)",
                about["compile_s"].as_f64().unwrap_or(0.0)
            )
        } else {
            "earlier (cached by the SHA-256 of the source)".into()
        },
        about["shared_library"]
            .as_str()
            .and_then(|p| Path::new(p).file_name())
            .map(|f| f.to_string_lossy().to_string())
            .unwrap_or_default(),
        check["qdd0_max_rel_error"].as_f64().unwrap_or(f64::NAN),
        check["lambda0_max_rel_error"].as_f64().unwrap_or(f64::NAN),
        about["cpu"].as_str().unwrap_or("?"),
    )
}
