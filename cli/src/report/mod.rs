//! `report`: every integrator over a sweep of steps (or tolerances) on the benchmark scenes, against
//! closed forms where they exist and a tighter solution by another method otherwise. Writes one
//! CSV per scene, log-log work-precision PNGs (error, constraint drift and energy error against CPU
//! time, one line per method and drift control) and a generated README.md with the summary.

mod closed_forms;
mod measure;
mod output;
mod peers;
pub(crate) mod plot;
mod scenes;
mod tables;

use constraint_dynamics::predict::{
    DriftControl, Method, PredictionRequest, Predictor, Trajectory,
};
use constraint_dynamics::{Error, Result, Scene};
use indicatif::{ProgressBar, ProgressStyle};
use measure::{Refs, distance, final_distance, measure, predict, process_cpu_s};
use output::{plots, write_csv};
use peers::{peer_note, run_peer};
use scenes::Reference;
use serde_json::{Value, json};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;
use tables::{digits_view, fastest};

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
    /// Jacobian evaluations, apart from `evaluations`: the peers' and radau5's (the project's other
    /// methods: none).
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
                let (dopri, rk4) = reference_pair(&scene, 1e-13, *rk4_dt, b.horizon, &pb)?;
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
                let (dopri, rk4) = reference_pair(&scene, *rtol, *rk4_dt, b.horizon, &pb)?;
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
        let mut p = Predictor::from_scene(&a01)?.with_settings(|s| {
            s.method = Method::Dopri5;
            (s.rtol, s.atol, s.sample_period) = (1e-11, 1e-11, 1.0);
        })?;
        let c0 = process_cpu_s();
        let mut t = p.predict(&PredictionRequest::new(&a01.q0, &a01.v0).horizon(2000.0))?;
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
         `dopri5`, `dop853` — Dormand–Prince 8(5,3) —, `sdirk2`, and `radau5` — Radau IIA order 5, implicit, adaptive) runs over a \
         sweep of steps (dopri5, dop853 and radau5: tolerances rtol = atol) on each benchmark scene, \
         with projection onto the constraints and, where it matters, also without drift \
         control (`none`) and with Baumgarte terms (time constant 10 steps). The \
         error is measured against a closed form where one exists, otherwise against a tighter \
         solution by another method (named per scene). CPU time is the process CPU time of one \
         single-threaded prediction without the error estimate's companion run; our runs and the \
         peers' calls are timed by one rule: a run under 0.25 s is a warm-up, then the least of \
         5 runs (the peers: a warm-up call, then the least of 5 calls, also process CPU time); the \
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

/// The two independent reference runs of a scene: DOPRI5 at `rtol` and RK4 at `rk4_dt` [s],
/// both with projection, over `horizon` [s].
fn reference_pair(
    scene: &Scene,
    rtol: f64,
    rk4_dt: f64,
    horizon: f64,
    pb: &ProgressBar,
) -> Result<(Trajectory, Trajectory)> {
    let (dopri, _) = predict(
        scene,
        Method::Dopri5,
        DriftControl::Projection,
        true,
        rtol,
        horizon,
    )?;
    pb.inc(1);
    let (rk4, _) = predict(
        scene,
        Method::Rk4,
        DriftControl::Projection,
        false,
        rk4_dt,
        horizon,
    )?;
    pb.inc(1);
    Ok((dopri, rk4))
}
