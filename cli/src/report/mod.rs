//! `report`: every integrator over a sweep of steps (or tolerances) on the benchmark scenes, against
//! closed forms where they exist and a tighter solution by another method otherwise. Writes one
//! CSV per scene, log-log work-precision PNGs (error, constraint drift and energy error against CPU
//! time, one line per method and drift control) and a generated README.md with the summary.

mod closed_forms;
mod plot;
mod scenes;

use constraint_dynamics::predict::{DriftControl, Method, Predictor, Trajectory};
use constraint_dynamics::{Error, Result, Scene};
use indicatif::{ProgressBar, ProgressStyle};
use scenes::{Bench, DriftMeasure, Line, Peer, Reference, name};
use serde_json::{Value, json};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

#[derive(clap::Args)]
pub struct ReportArgs {
    /// Output folder (CSV, PNG, README.md).
    #[arg(long, default_value = "docs/report")]
    out: PathBuf,
    /// Short horizons and 3 points per line, for CI smoke runs (< 60 s). External peers
    /// (CasADi) are not run: they need PyPI on their first run.
    #[arg(long)]
    quick: bool,
    /// Only these scenes (repeatable; keys: a01_pendulum, double_fourbar, rod_body,
    /// vertical_disk, rolling_disk, diff_drive, spring_chain_stiff, andrews). Default: all.
    #[arg(long = "scene", value_name = "KEY")]
    scenes: Vec<String>,
}

/// One run of one line at one step or tolerance (the project's, or an external peer's).
struct Row {
    line: String,
    /// The method's scene-file name, or the peer's "peer/solver".
    method: String,
    drift: String,
    /// dt [s] or rtol.
    x: f64,
    /// `x` is a tolerance (rtol = atol), not a step.
    tolerance: bool,
    /// A run of an external peer.
    peer: bool,
    steps: usize,
    evaluations: usize,
    /// Peers: Jacobian evaluations, apart from `evaluations` (the project's methods: none).
    jacobian_evaluations: Option<usize>,
    cpu: f64,
    error: f64,
    phi: f64,
    jv: f64,
    energy: f64,
    least_squares: usize,
    status: String,
}

impl Row {
    fn ok(&self) -> bool {
        self.status == "ok"
    }
}

/// The repository root (the CLI crate is `cli/` in it): bundled scenes and `docs/report/`.
fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn io_err(path: &Path, e: std::io::Error) -> Error {
    Error::Io {
        path: path.display().to_string(),
        source: e,
    }
}

/// The CPU time of this process [s] (CLOCK_PROCESS_CPUTIME_ID: all its threads, ns resolution):
/// unlike wall-clock time, it does not count the time other processes hold the core, and it is
/// what the peers measure (Python's `time.process_time`).
fn process_cpu_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec through a valid pointer to a local.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    if rc != 0 {
        return f64::NAN;
    }
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// Runs shorter than this are repeated (up to 3 times) and the least time kept.
const REPEAT_BELOW_S: f64 = 0.25;

/// Predict with the given method, drift control and step/tolerance; the CPU time is the smallest
/// of up to 3 runs when a run takes less than `REPEAT_BELOW_S`.
fn predict(
    scene: &Scene,
    method: Method,
    drift: DriftControl,
    tolerance: bool,
    x: f64,
    horizon: f64,
) -> Result<(Trajectory, f64)> {
    let mut p = Predictor::from_scene(scene)?;
    p.settings.method = method;
    p.settings.drift = drift;
    p.settings.sample_period = horizon / 100.0;
    // The sweeps reach coarse steps on purpose and measure the true error themselves; the time
    // is the integrator's alone, without the error estimate's companion run.
    p.settings.max_error = f64::INFINITY;
    p.settings.error_estimate = false;
    p.settings.adapt = false;
    if tolerance {
        p.settings.rtol = x;
        p.settings.atol = x;
        p.settings.dt = horizon / 1e4;
    } else {
        p.settings.dt = x;
    }
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..3 {
        let c0 = process_cpu_s();
        let t = p.predict(&scene.q0, &scene.v0, &[], horizon)?;
        let cpu = process_cpu_s() - c0;
        best = best.min(cpu);
        let fast = cpu < REPEAT_BELOW_S;
        last = Some(t);
        if !fast {
            break;
        }
    }
    Ok((last.expect("one run"), best))
}

/// Max over the samples of |q ⊖ q_ref|∞.
fn distance(scene: &Scene, t: &Trajectory, r: &Trajectory) -> f64 {
    let mut d = vec![0.0; scene.model.nv];
    let mut worst: f64 = 0.0;
    for (a, b) in t.samples.iter().zip(&r.samples) {
        scene.model.difference(&b.q, &a.q, &mut d);
        worst = d.iter().fold(worst, |m, x| m.max(x.abs()));
    }
    if t.samples.len() != r.samples.len() {
        return f64::NAN;
    }
    worst
}

/// |q ⊖ q_ref|∞ of two configurations.
fn final_distance(scene: &Scene, q: &[f64], q_ref: &[f64]) -> f64 {
    let mut d = vec![0.0; scene.model.nv];
    scene.model.difference(q_ref, q, &mut d);
    d.iter().fold(0.0, |m: f64, x| m.max(x.abs()))
}

/// The references of a scene, computed once.
enum Refs {
    None,
    /// Numerical: dopri5 (fixed-step rows) and RK4 (tolerance-driven rows) trajectories.
    Trajectories(Box<(Trajectory, Trajectory)>),
    /// Final: q at the end of the horizon, dopri5's and RK4's.
    Final {
        dopri: Vec<f64>,
        rk4: Vec<f64>,
    },
}

fn measure(scene: &Scene, b: &Bench, line: &Line, x: f64, refs: &Refs) -> Row {
    let mut row = Row {
        line: line.label(),
        method: name(line.method),
        drift: name(line.drift),
        x,
        tolerance: line.tolerances,
        peer: false,
        steps: 0,
        evaluations: 0,
        jacobian_evaluations: None,
        cpu: f64::NAN,
        error: f64::NAN,
        phi: f64::NAN,
        jv: f64::NAN,
        energy: f64::NAN,
        least_squares: 0,
        status: "ok".into(),
    };
    let (t, cpu) = match predict(
        scene,
        line.method,
        line.drift,
        line.tolerances,
        x,
        b.horizon,
    ) {
        Ok(r) => r,
        Err(e) => {
            row.status = e.to_string();
            return row;
        }
    };
    row.error = match (&b.reference, refs) {
        (Reference::ClosedForm(f), _) => t.samples.iter().map(f).fold(0.0, f64::max),
        (_, Refs::Trajectories(pair)) => {
            let (dopri, rk4) = &**pair;
            distance(scene, &t, if line.tolerances { rk4 } else { dopri })
        }
        (_, Refs::Final { dopri, rk4 }) => t.samples.last().map_or(f64::NAN, |s| {
            final_distance(scene, &s.q, if line.tolerances { rk4 } else { dopri })
        }),
        _ => f64::NAN,
    };
    let e0 = t.samples[0].kinetic_energy + t.samples[0].potential_energy;
    row.energy = 0.0;
    row.phi = 0.0;
    row.jv = 0.0;
    for s in &t.samples {
        row.energy = row
            .energy
            .max((s.kinetic_energy + s.potential_energy - e0).abs());
        row.phi = row.phi.max(s.position_residual);
        row.jv = row.jv.max(s.velocity_residual);
    }
    (row.steps, row.evaluations, row.cpu) = (t.steps, t.evaluations, cpu);
    row.least_squares = t.least_squares_evaluations;
    row
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\"").replace('\n', " "))
    } else {
        s.to_string()
    }
}

fn write_csv(path: &Path, b: &Bench, reference_note: &str, rows: &[Row]) -> Result<()> {
    let mut s = String::new();
    let _ = writeln!(s, "# {}", b.title);
    let _ = writeln!(
        s,
        "# scene: {}; horizon {} s; samples every {} s",
        b.scene,
        b.horizon,
        b.horizon / 100.0
    );
    let _ = writeln!(s, "# reference: {}{reference_note}", b.reference_text);
    let _ = writeln!(s, "# error: {}", b.error_metric);
    let _ = writeln!(
        s,
        "# drift: max over the samples of |φ| [m] and |J v| [m/s]; energy: max |E − E0| [J]; \
         cpu_s: process CPU time of the prediction, one thread (least of up to 3 runs under 0.25 \
         s; peers: least of 5 calls, see README.md); jacobian_evaluations: peers only"
    );
    s.push_str(
        "scene,line,method,drift,dt_s,rtol,steps,evaluations,cpu_s,error,max_position_residual,\
         max_velocity_residual,max_energy_error_J,least_squares_evaluations,\
         jacobian_evaluations,status\n",
    );
    let num = |x: f64| {
        if x.is_finite() {
            format!("{x:.6e}")
        } else {
            String::new()
        }
    };
    for r in rows {
        let (dt, rtol) = if r.tolerance {
            (String::new(), format!("{:e}", r.x))
        } else {
            (format!("{:e}", r.x), String::new())
        };
        let _ = writeln!(
            s,
            "{},{},{},{},{dt},{rtol},{},{},{},{},{},{},{},{},{},{}",
            b.key,
            r.line,
            r.method,
            r.drift,
            r.steps,
            r.evaluations,
            num(r.cpu),
            num(r.error),
            num(r.phi),
            num(r.jv),
            num(r.energy),
            r.least_squares,
            r.jacobian_evaluations
                .map(|n| n.to_string())
                .unwrap_or_default(),
            csv_field(&r.status)
        );
    }
    std::fs::write(path, s).map_err(|e| io_err(path, e))
}

fn plots(out: &Path, b: &Bench, rows: &[Row]) -> Result<Vec<String>> {
    let mut labels: Vec<(String, bool)> = rows.iter().map(|r| (r.line.clone(), r.peer)).collect();
    labels.dedup();
    let series = |f: &dyn Fn(&Row) -> f64| -> Vec<plot::Series> {
        labels
            .iter()
            .map(|(l, peer)| {
                let mut points: Vec<(f64, f64)> = rows
                    .iter()
                    .filter(|r| &r.line == l && r.ok() && f(r).is_finite())
                    .map(|r| (r.cpu.max(1e-7), f(r)))
                    .collect();
                points.sort_by(|a, c| a.0.total_cmp(&c.0));
                plot::Series {
                    label: if *peer {
                        format!("{l} (peer)")
                    } else {
                        l.clone()
                    },
                    points,
                    peer: *peer,
                }
            })
            .collect()
    };
    let mut files = vec![];
    let mut draw = |suffix: &str, what: &str, y: &str, f: &dyn Fn(&Row) -> f64| -> Result<()> {
        let name = format!("{}_{suffix}.png", b.key);
        let title = format!("{} — {what}", b.key);
        plot::work_precision(&out.join(&name), &title, y, &series(f)).map_err(Error::Invalid)?;
        files.push(name);
        Ok(())
    };
    draw("error", "error vs CPU time", "error", &|r| r.error)?;
    match b.drift {
        DriftMeasure::Position => draw(
            "drift",
            "constraint drift vs CPU time",
            "max |φ| [m]",
            &|r| r.phi,
        )?,
        DriftMeasure::Velocity => draw(
            "drift",
            "constraint drift vs CPU time",
            "max |J v| [m/s]",
            &|r| r.jv,
        )?,
        DriftMeasure::None => {}
    }
    draw(
        "energy",
        "energy error vs CPU time",
        "max |E − E0| [J]",
        &|r| r.energy,
    )?;
    Ok(files)
}

/// "rtol 1e-10" or "dt 1.000e-4 s".
fn setting(r: &Row) -> String {
    if r.tolerance {
        format!("rtol {:.0e}", r.x)
    } else {
        format!("dt {:.3e} s", r.x)
    }
}

/// The fastest ok row with error ≤ target.
fn fastest_row<'a>(rows: impl Iterator<Item = &'a Row>, target: f64) -> Option<&'a Row> {
    rows.filter(|r| r.ok() && r.error <= target)
        .min_by(|a, b| a.cpu.total_cmp(&b.cpu))
}

/// The fastest ok row with error ≤ target, as "line (dt or rtol): time".
fn fastest(rows: &[Row], target: f64) -> String {
    fastest_row(rows.iter(), target)
        .map(|r| format!("{} ({}): {:.3e} s", r.line, setting(r), r.cpu))
        .unwrap_or_else(|| "— (none)".into())
}

/// Significant digits of an error against the largest |q|: −log10(error / |q|max).
fn digits(error: f64, qmax: f64) -> f64 {
    -(error / qmax).log10()
}

/// The "digits" view: per line (the project's methods and each peer solver), the fastest run
/// to ≥ 10 and ≥ 12 significant digits in q; then every peer run.
fn digits_view(rows: &[Row], qmax: f64) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "**Digits.** The fastest run of each line to ≥ 10 and ≥ 12 significant digits in q \
         (error ≤ 1e-10·|q|max and ≤ 1e-12·|q|max, |q|max = {qmax:.4} rad; digits = \
         −log10(error / |q|max)); `—` when no run of the line gets there (its best in \
         brackets). Evaluations: right-hand sides (peers: + Jacobians).\n"
    );
    s.push_str("| line | ≥ 10 digits | ≥ 12 digits |\n|---|---|---|\n");
    let mut labels: Vec<&str> = rows.iter().map(|r| r.line.as_str()).collect();
    labels.dedup();
    let cell = |r: Option<&Row>, of: &[&Row]| match r {
        Some(r) => format!(
            "{}: **{:.2} ms**, {}{} evaluations, {:.1} digits",
            setting(r),
            r.cpu * 1e3,
            r.evaluations,
            r.jacobian_evaluations
                .map(|j| format!(" + {j}"))
                .unwrap_or_default(),
            digits(r.error, qmax)
        ),
        None => {
            let best = of
                .iter()
                .filter(|r| r.ok() && r.error.is_finite())
                .map(|r| digits(r.error, qmax))
                .fold(f64::NEG_INFINITY, f64::max);
            if best.is_finite() {
                format!("— (best {best:.1} digits)")
            } else {
                "— (no run)".into()
            }
        }
    };
    for l in labels {
        let of: Vec<&Row> = rows.iter().filter(|r| r.line == l).collect();
        let _ = writeln!(
            s,
            "| {l} | {} | {} |",
            cell(fastest_row(of.iter().copied(), 1e-10 * qmax), &of),
            cell(fastest_row(of.iter().copied(), 1e-12 * qmax), &of)
        );
    }
    let peers: Vec<&Row> = rows.iter().filter(|r| r.peer).collect();
    if !peers.is_empty() {
        s.push_str(
            "\nEvery peer run (error against the same reference as the fixed-step rows):\n\n\
             | peer/solver | rtol | CPU [ms] | RHS evaluations | Jacobian evaluations | steps | \
             error [rad] | digits | status |\n|---|---|---|---|---|---|---|---|---|\n",
        );
        for r in peers {
            let _ = writeln!(
                s,
                "| {} | {:.0e} | {:.3} | {} | {} | {} | {:.2e} | {:.1} | {} |",
                r.line,
                r.x,
                r.cpu * 1e3,
                r.evaluations,
                r.jacobian_evaluations
                    .map(|j| j.to_string())
                    .unwrap_or_default(),
                r.steps,
                r.error,
                digits(r.error, qmax),
                r.status.replace('|', "/")
            );
        }
    }
    s.push('\n');
    s
}

/// Run an external peer: its venv setup, then its script (JSON to a file). Its rows, with the
/// error against `reference` (q at the end of the horizon in the model's order), and what it
/// reported about itself. `Err` is why it did not run.
fn run_peer(
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
fn peer_note(peer: &Peer, about: &Value) -> String {
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

pub fn run(a: ReportArgs) -> Result<Value> {
    let start = Instant::now();
    let mut benches = scenes::benches(a.quick);
    if !a.scenes.is_empty() {
        for k in &a.scenes {
            if !benches.iter().any(|b| b.key == k) {
                return Err(Error::Invalid(format!("report: no scene {k}")));
            }
        }
        benches.retain(|b| a.scenes.iter().any(|k| k == b.key));
    }
    let with_a01 = benches.iter().any(|b| b.key == "a01_pendulum");
    std::fs::create_dir_all(&a.out).map_err(|e| io_err(&a.out, e))?;
    let total: usize = benches
        .iter()
        .map(|b| {
            b.lines.iter().map(|l| l.sweep.len()).sum::<usize>()
                + 2 * !matches!(b.reference, Reference::ClosedForm(_)) as usize
                + b.peers.len()
        })
        .sum::<usize>()
        + with_a01 as usize;
    let pb = ProgressBar::new(total as u64);
    pb.set_style(
        ProgressStyle::with_template("{bar:40.cyan/blue} {pos}/{len} [{elapsed_precise}] {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut md_scenes = String::new();
    let mut md_table = String::new();
    let mut written = vec![];
    let mut peers_json = serde_json::Map::new();
    for b in &benches {
        let scene = Scene::load(repo().join(b.scene))?;
        let mut note = String::new();
        // Final-state scenes: the largest |q| of the reference, for the digits view.
        let mut qmax = None;
        let refs = match &b.reference {
            Reference::ClosedForm(_) => Refs::None,
            Reference::Numerical { rk4_dt } => {
                pb.set_message(format!("{}: references", b.key));
                let (dopri, _) = predict(
                    &scene,
                    Method::Dopri5,
                    DriftControl::Projection,
                    true,
                    1e-13,
                    b.horizon,
                )?;
                pb.inc(1);
                let (rk4, _) = predict(
                    &scene,
                    Method::Rk4,
                    DriftControl::Projection,
                    false,
                    *rk4_dt,
                    b.horizon,
                )?;
                pb.inc(1);
                let gap = distance(&scene, &rk4, &dopri);
                note = format!(" (RK4 dt = {rk4_dt:e} s; the two references agree to {gap:.1e})");
                Refs::Trajectories(Box::new((dopri, rk4)))
            }
            Reference::Final {
                rtol,
                rk4_dt,
                published,
            } => {
                pb.set_message(format!("{}: references", b.key));
                let last = |t: Trajectory| t.samples.last().map(|s| s.q.clone());
                let (dopri, _) = predict(
                    &scene,
                    Method::Dopri5,
                    DriftControl::Projection,
                    true,
                    *rtol,
                    b.horizon,
                )?;
                pb.inc(1);
                let (rk4, _) = predict(
                    &scene,
                    Method::Rk4,
                    DriftControl::Projection,
                    false,
                    *rk4_dt,
                    b.horizon,
                )?;
                pb.inc(1);
                let (Some(dopri), Some(rk4)) = (last(dopri), last(rk4)) else {
                    return Err(Error::Invalid(format!("{}: empty reference run", b.key)));
                };
                let gap = final_distance(&scene, &rk4, &dopri);
                let mut published_q = vec![f64::NAN; scene.model.nq];
                for (n, x) in published.names.iter().zip(published.q) {
                    if let Some(i) = scene.model.q_names.iter().position(|m| m == n) {
                        published_q[i] = *x;
                    }
                }
                let to_published = final_distance(&scene, &dopri, &published_q);
                note = format!(
                    " (dopri5 rtol = atol = {rtol:e}, RK4 dt = {rk4_dt:e} s: the two agree to \
                     {gap:.1e} rad; both differ from {} by {to_published:.2e} rad)",
                    published.source
                );
                qmax = Some(dopri.iter().fold(0.0, |m: f64, x| m.max(x.abs())));
                Refs::Final { dopri, rk4 }
            }
        };
        let mut rows = vec![];
        for line in &b.lines {
            for &x in &line.sweep {
                pb.set_message(format!("{}: {} {x:e}", b.key, line.label()));
                rows.push(measure(&scene, b, line, x, &refs));
                pb.inc(1);
            }
        }
        let mut peer_md = String::new();
        if a.quick && b.key == "andrews" {
            peer_md.push_str(
                "**Peers not run** (`--quick`: the CasADi peer needs PyPI on its first run and \
                 takes ~1 min; the full report runs it).\n\n",
            );
        }
        for peer in &b.peers {
            pb.set_message(format!("{}: peer {}", b.key, peer.name));
            let reference = match &refs {
                Refs::Final { dopri, .. } => Some(dopri.as_slice()),
                _ => None,
            };
            let outcome = match reference {
                Some(r) => run_peer(peer, &scene, r),
                None => Err("peers need a final-state reference".into()),
            };
            match outcome {
                Ok((peer_rows, about)) => {
                    peer_md.push_str(&peer_note(peer, &about));
                    peers_json.insert(
                        peer.name.into(),
                        json!({"status": "ok", "runs": peer_rows.len(), "about": about}),
                    );
                    rows.extend(peer_rows);
                }
                Err(why) => {
                    pb.suspend(|| {
                        eprintln!(
                            "report: WARNING: the peer {} of {} did NOT run: {why}",
                            peer.name, b.key
                        )
                    });
                    let _ = writeln!(
                        peer_md,
                        "**⚠ The peer {} did NOT run, so it is missing from this scene's \
                         diagrams and CSV:** {}\n",
                        peer.name,
                        why.replace('\n', " ")
                    );
                    peers_json.insert(peer.name.into(), json!({"status": why}));
                }
            }
            pb.inc(1);
        }
        let csv = a.out.join(format!("{}.csv", b.key));
        write_csv(&csv, b, &note, &rows)?;
        written.push(format!("{}.csv", b.key));
        let pngs = plots(&a.out, b, &rows)?;
        let _ = writeln!(
            md_table,
            "| {} | {} | {} | {} |",
            b.key,
            fastest(&rows, 1e-3),
            fastest(&rows, 1e-6),
            fastest(&rows, 1e-9)
        );
        let _ = writeln!(md_scenes, "\n### {}: {}\n", b.key, b.title);
        let _ = writeln!(
            md_scenes,
            "Scene `{}`, horizon {} s. Error: {}. Reference: {}{note}. Data: [{}.csv]({}.csv).\n",
            b.scene, b.horizon, b.error_metric, b.reference_text, b.key, b.key
        );
        md_scenes.push_str(&peer_md);
        if let Some(qmax) = qmax {
            md_scenes.push_str(&digits_view(&rows, qmax));
        }
        let failed: Vec<&Row> = rows.iter().filter(|r| !r.ok()).collect();
        if !failed.is_empty() {
            md_scenes.push_str("Runs that stopped with a typed error (not plotted):\n\n");
            for r in failed {
                let _ = writeln!(md_scenes, "- {} at {:e}: {}", r.line, r.x, r.status);
            }
            md_scenes.push('\n');
        }
        for p in &pngs {
            let _ = writeln!(md_scenes, "![{p}]({p})");
        }
        written.extend(pngs);
    }
    // The IFToMM A01 high-precision bar: 2000 s, mass position within 1e-3 m at every second.
    let a01 = if with_a01 {
        pb.set_message("A01 high-precision bar");
        let a01 = Scene::load(repo().join("params/pendulum_a01.yaml"))?;
        let mut p = Predictor::from_scene(&a01)?;
        p.settings.method = Method::Dopri5;
        (p.settings.rtol, p.settings.atol, p.settings.sample_period) = (1e-11, 1e-11, 1.0);
        let c0 = process_cpu_s();
        let mut t = p.predict(&a01.q0, &a01.v0, &[], 2000.0)?;
        t.run_time_s = process_cpu_s() - c0;
        let a01_err = t
            .samples
            .iter()
            .map(|s| {
                let (x, z) = closed_forms::a01_position(s.t);
                (s.q[0].cos() - x).hypot(-s.q[0].sin() - z)
            })
            .fold(0.0, f64::max);
        pb.inc(1);
        Some((a01_err, t))
    } else {
        None
    };
    pb.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    let md = readme(&a, seconds, a01.as_ref(), &md_table, &md_scenes);
    let readme_path = a.out.join("README.md");
    std::fs::write(&readme_path, md).map_err(|e| io_err(&readme_path, e))?;
    written.push("README.md".into());
    let mut out = json!({
        "out": a.out.display().to_string(),
        "quick": a.quick,
        "seconds": seconds,
        "files": written,
        "peers": peers_json,
    });
    if let (Some((err, t)), Some(o)) = (a01, out.as_object_mut()) {
        o.insert(
            "a01".into(),
            json!({"max_position_error_m": err, "cpu_s": t.run_time_s, "steps": t.steps}),
        );
    }
    Ok(out)
}

fn readme(
    a: &ReportArgs,
    seconds: f64,
    a01: Option<&(f64, Trajectory)>,
    table: &str,
    scenes: &str,
) -> String {
    let mode = if a.quick {
        "quick (short horizons, 3 points per line)"
    } else {
        "full"
    };
    let mut args = String::new();
    if a.quick {
        args.push_str(" --quick");
    }
    for k in &a.scenes {
        let _ = write!(args, " --scene {k}");
    }
    let a01 = match a01 {
        Some((a01_err, t)) => format!(
            "## IFToMM A01 high-precision bar\n\n\
             dopri5 with rtol = atol = 1e-11 over 2000 s: largest mass position error \
             {a01_err:.2e} m against the elliptic closed form (bar: 1e-3 m), {} steps, {} \
             evaluations, **{:.3} s** CPU.\n\n",
            t.steps, t.evaluations, t.run_time_s
        ),
        None => String::new(),
    };
    format!(
        "# Work-precision report (generated)\n\n\
         Generated by `cargo run --release -- report{args}` ({mode}) in {seconds:.0} s on one \
         core; do not edit, regenerate. Every integrator (semi-implicit Euler `sie`, `rk4`, \
         `dopri5`, `sdirk2`) runs over a sweep of steps (dopri5: tolerances rtol = atol) on each \
         benchmark scene, with projection onto the constraints and, where it matters, also \
         without drift control (`none`) and with Baumgarte terms (time constant 10 steps). The \
         error is measured against a closed form where one exists, otherwise against a tighter \
         solution by another method (named per scene). CPU time is the process CPU time of one \
         single-threaded prediction without the error estimate's companion run (the least of 3 \
         runs under 0.25 s; the peers': the least of 5 calls, also process CPU time); the \
         machine was shared (CPU time does not count the time others hold the core, but caches \
         are shared), so differences below ~30 % are noise. \
         External peers (Andrews' squeezer: CasADi's CVODES and IDAS) are drawn with triangles \
         in the same diagrams and are rows of the same CSV. See \
         [docs/propagation.md](../propagation.md) for the methods and the peers.\n\n\
         {a01}\
         ## Fastest run to a given error\n\n\
         The cheapest run whose error (max over the samples, per scene as stated below) is at or \
         below the target; `—` when no run of the sweep reaches it.\n\n\
         | scene | ≤ 1e-3 | ≤ 1e-6 | ≤ 1e-9 |\n|---|---|---|---|\n{table}\n\
         ## Scenes\n{scenes}"
    )
}
