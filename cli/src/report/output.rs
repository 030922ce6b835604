//! The report's files per scene: the CSV of every row and the work-precision PNGs (drawn by
//! `plot`).

use super::scenes::{Bench, DriftMeasure};
use super::{Row, io_err, plot};
use constraint_dynamics::{Error, Result};
use std::fmt::Write as _;
use std::path::Path;

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\"").replace('\n', " "))
    } else {
        s.to_string()
    }
}

pub(super) fn write_csv(path: &Path, b: &Bench, reference_note: &str, rows: &[Row]) -> Result<()> {
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
         cpu_s: process CPU time of the prediction, one thread (a run under 0.25 s is a \
         warm-up, then the least of 5 runs; peers: a warm-up call, then the least of 5 calls); \
         jacobian_evaluations: radau5 and the peers"
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

pub(super) fn plots(out: &Path, b: &Bench, rows: &[Row]) -> Result<Vec<String>> {
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
