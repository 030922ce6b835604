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
use scenes::{Bench, DriftMeasure, Line, Reference};
use serde_json::{Value, json};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args)]
pub struct ReportArgs {
    /// Output folder (CSV, PNG, README.md).
    #[arg(long, default_value = "docs/report")]
    out: PathBuf,
    /// Short horizons and 3 points per line, for CI smoke runs (< 60 s).
    #[arg(long)]
    quick: bool,
}

/// One run of one line at one step or tolerance.
struct Row {
    line: String,
    method: Method,
    drift: DriftControl,
    /// dt [s] or rtol.
    x: f64,
    steps: usize,
    evaluations: usize,
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

/// Predict with the given method, drift control and step/tolerance; the CPU time is the smallest
/// of up to 3 runs when a run takes less than 10 ms.
fn predict(
    scene: &Scene,
    method: Method,
    drift: DriftControl,
    x: f64,
    horizon: f64,
) -> Result<(Trajectory, f64)> {
    let mut p = Predictor::from_scene(scene)?;
    p.settings.method = method;
    p.settings.drift = drift;
    p.settings.sample_period = horizon / 100.0;
    // The sweeps reach coarse steps on purpose and measure the true error themselves.
    p.settings.max_error = f64::INFINITY;
    if method == Method::Dopri5 {
        p.settings.rtol = x;
        p.settings.atol = x;
        p.settings.dt = horizon / 1e4;
    } else {
        p.settings.dt = x;
    }
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..3 {
        let t = p.predict(&scene.q0, &scene.v0, &[], horizon)?;
        best = best.min(t.run_time_s);
        let fast = t.run_time_s < 0.01;
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

fn measure(
    scene: &Scene,
    b: &Bench,
    line: &Line,
    x: f64,
    refs: Option<&(Trajectory, Trajectory)>,
) -> Row {
    let mut row = Row {
        line: line.label(),
        method: line.method,
        drift: line.drift,
        x,
        steps: 0,
        evaluations: 0,
        cpu: f64::NAN,
        error: f64::NAN,
        phi: f64::NAN,
        jv: f64::NAN,
        energy: f64::NAN,
        least_squares: 0,
        status: "ok".into(),
    };
    let (t, cpu) = match predict(scene, line.method, line.drift, x, b.horizon) {
        Ok(r) => r,
        Err(e) => {
            row.status = e.to_string();
            return row;
        }
    };
    row.error = match (&b.reference, refs) {
        (Reference::ClosedForm(f), _) => t.samples.iter().map(f).fold(0.0, f64::max),
        (Reference::Numerical { .. }, Some((dopri, rk4))) => distance(
            scene,
            &t,
            if line.method == Method::Dopri5 {
                rk4
            } else {
                dopri
            },
        ),
        (Reference::Numerical { .. }, None) => f64::NAN,
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
         cpu_s: wall-clock time of the prediction on one core (least of up to 3 runs under 10 ms)"
    );
    s.push_str(
        "scene,line,method,drift,dt_s,rtol,steps,evaluations,cpu_s,error,max_position_residual,\
         max_velocity_residual,max_energy_error_J,least_squares_evaluations,status\n",
    );
    for r in rows {
        let (dt, rtol) = if r.method == Method::Dopri5 {
            (String::new(), format!("{:e}", r.x))
        } else {
            (format!("{:e}", r.x), String::new())
        };
        let _ = writeln!(
            s,
            "{},{},{},{},{dt},{rtol},{},{},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{},{}",
            b.key,
            r.line,
            serde_json::to_value(r.method)
                .unwrap_or_default()
                .as_str()
                .unwrap_or(""),
            serde_json::to_value(r.drift)
                .unwrap_or_default()
                .as_str()
                .unwrap_or(""),
            r.steps,
            r.evaluations,
            r.cpu,
            r.error,
            r.phi,
            r.jv,
            r.energy,
            r.least_squares,
            csv_field(&r.status)
        );
    }
    std::fs::write(path, s).map_err(|e| io_err(path, e))
}

fn plots(out: &Path, b: &Bench, rows: &[Row]) -> Result<Vec<String>> {
    let mut labels: Vec<String> = rows.iter().map(|r| r.line.clone()).collect();
    labels.dedup();
    let series = |f: &dyn Fn(&Row) -> f64| -> Vec<plot::Series> {
        labels
            .iter()
            .map(|l| {
                let mut points: Vec<(f64, f64)> = rows
                    .iter()
                    .filter(|r| &r.line == l && r.ok() && f(r).is_finite())
                    .map(|r| (r.cpu.max(1e-7), f(r)))
                    .collect();
                points.sort_by(|a, c| a.0.total_cmp(&c.0));
                plot::Series {
                    label: l.clone(),
                    points,
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

/// The fastest ok row with error ≤ target, as "line (dt or rtol): time".
fn fastest(rows: &[Row], target: f64) -> String {
    rows.iter()
        .filter(|r| r.ok() && r.error <= target)
        .min_by(|a, b| a.cpu.total_cmp(&b.cpu))
        .map(|r| {
            let x = if r.method == Method::Dopri5 {
                format!("rtol {:.0e}", r.x)
            } else {
                format!("dt {:.3e} s", r.x)
            };
            format!("{} ({x}): {:.3e} s", r.line, r.cpu)
        })
        .unwrap_or_else(|| "— (none)".into())
}

pub fn run(a: ReportArgs) -> Result<Value> {
    let start = Instant::now();
    let benches = scenes::benches(a.quick);
    std::fs::create_dir_all(&a.out).map_err(|e| io_err(&a.out, e))?;
    let total: usize = benches
        .iter()
        .map(|b| {
            b.lines.iter().map(|l| l.sweep.len()).sum::<usize>()
                + 2 * matches!(b.reference, Reference::Numerical { .. }) as usize
        })
        .sum::<usize>()
        + 1;
    let pb = ProgressBar::new(total as u64);
    pb.set_style(
        ProgressStyle::with_template("{bar:40.cyan/blue} {pos}/{len} [{elapsed_precise}] {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut md_scenes = String::new();
    let mut md_table = String::new();
    let mut written = vec![];
    for b in &benches {
        let scene = Scene::load(repo().join(b.scene))?;
        let mut note = String::new();
        let refs = if let Reference::Numerical { rk4_dt } = b.reference {
            pb.set_message(format!("{}: references", b.key));
            let (dopri, _) = predict(
                &scene,
                Method::Dopri5,
                DriftControl::Projection,
                1e-13,
                b.horizon,
            )?;
            pb.inc(1);
            let (rk4, _) = predict(
                &scene,
                Method::Rk4,
                DriftControl::Projection,
                rk4_dt,
                b.horizon,
            )?;
            pb.inc(1);
            let gap = distance(&scene, &rk4, &dopri);
            note = format!(" (RK4 dt = {rk4_dt:e} s; the two references agree to {gap:.1e})");
            Some((dopri, rk4))
        } else {
            None
        };
        let mut rows = vec![];
        for line in &b.lines {
            for &x in &line.sweep {
                pb.set_message(format!("{}: {} {x:e}", b.key, line.label()));
                rows.push(measure(&scene, b, line, x, refs.as_ref()));
                pb.inc(1);
            }
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
    pb.set_message("A01 high-precision bar");
    let a01 = Scene::load(repo().join("params/pendulum_a01.yaml"))?;
    let mut p = Predictor::from_scene(&a01)?;
    p.settings.method = Method::Dopri5;
    (p.settings.rtol, p.settings.atol, p.settings.sample_period) = (1e-11, 1e-11, 1.0);
    let t = p.predict(&a01.q0, &a01.v0, &[], 2000.0)?;
    let a01_err = t
        .samples
        .iter()
        .map(|s| {
            let (x, z) = closed_forms::a01_position(s.t);
            (s.q[0].cos() - x).hypot(-s.q[0].sin() - z)
        })
        .fold(0.0, f64::max);
    pb.inc(1);
    pb.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    let md = readme(&a, seconds, a01_err, &t, &md_table, &md_scenes);
    let readme_path = a.out.join("README.md");
    std::fs::write(&readme_path, md).map_err(|e| io_err(&readme_path, e))?;
    written.push("README.md".into());
    Ok(json!({
        "out": a.out.display().to_string(),
        "quick": a.quick,
        "seconds": seconds,
        "files": written,
        "a01": {"max_position_error_m": a01_err, "cpu_s": t.run_time_s, "steps": t.steps},
    }))
}

fn readme(
    a: &ReportArgs,
    seconds: f64,
    a01_err: f64,
    t: &Trajectory,
    table: &str,
    scenes: &str,
) -> String {
    let mode = if a.quick {
        "quick (short horizons, 3 points per line)"
    } else {
        "full"
    };
    format!(
        "# Work-precision report (generated)\n\n\
         Generated by `cargo run --release -- report{}` ({mode}) in {seconds:.0} s on one core; \
         do not edit, regenerate. Every integrator (semi-implicit Euler `sie`, `rk4`, `dopri5`, \
         `sdirk2`) runs over a sweep of steps (dopri5: tolerances rtol = atol) on each benchmark \
         scene, with projection onto the constraints and, where it matters, also without drift \
         control (`none`) and with Baumgarte terms (time constant 10 steps). The error is \
         measured against a closed form where one exists, otherwise against a tighter solution \
         by another method (named per scene). CPU time is the wall-clock time of one \
         single-threaded prediction (the least of 3 runs under 10 ms); the machine was shared, \
         so differences below ~30 % are noise. See [docs/propagation.md](../propagation.md) for the methods.\n\n\
         ## IFToMM A01 high-precision bar\n\n\
         dopri5 with rtol = atol = 1e-11 over 2000 s: largest mass position error {a01_err:.2e} m \
         against the elliptic closed form (bar: 1e-3 m), {} steps, {} evaluations, **{:.3} s** \
         CPU.\n\n\
         ## Fastest run to a given error\n\n\
         The cheapest run whose error (max over the samples, per scene as stated below) is at or \
         below the target; `—` when no run of the sweep reaches it.\n\n\
         | scene | ≤ 1e-3 | ≤ 1e-6 | ≤ 1e-9 |\n|---|---|---|---|\n{table}\n\
         ## Scenes\n{scenes}",
        if a.quick { " --quick" } else { "" },
        t.steps,
        t.evaluations,
        t.run_time_s
    )
}
