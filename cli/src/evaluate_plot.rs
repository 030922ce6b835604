//! `evaluate --plot DIR`: the errors against the horizon, and the predicted 95 % position
//! ellipses over the reference path (plotters, bitmap backend, the report's embedded font).

use crate::report::plot::register;
use constraint_dynamics::replay::{Evaluation, Recording};
use plotters::prelude::*;
use std::path::Path;

/// χ²(2) quantile of 0.95: the position block's 95 % ellipse.
const CHI2_2_P95: f64 = 5.991_464_547_107_979;

type Fail = String;

fn fail<E: std::error::Error + Send + Sync>(
    path: &Path,
) -> impl Fn(DrawingAreaErrorKind<E>) -> Fail + '_ {
    move |e| format!("{}: {e}", path.display())
}

/// `errors_vs_horizon.png`: median, p95 and worst position [mm] and yaw [mrad] error per horizon.
fn errors(path: &Path, ev: &Evaluation) -> Result<(), Fail> {
    let root = BitMapBackend::new(path, (960, 720)).into_drawing_area();
    root.fill(&WHITE).map_err(fail(path))?;
    let panels = root.split_evenly((2, 1));
    let h_max = ev.horizons.iter().map(|h| h.horizon_s).fold(0.0, f64::max) * 1.05;
    type Pick = fn(&constraint_dynamics::replay::HorizonSummary) -> [f64; 3];
    let kinds: [(&str, Pick); 2] = [
        ("position error [mm]", |h| {
            let s = h.position_error_m;
            [s.median, s.p95, s.max].map(|x| 1e3 * x)
        }),
        ("|yaw error| [mrad]", |h| {
            let s = h.yaw_error_rad;
            [s.median, s.p95, s.max].map(|x| 1e3 * x)
        }),
    ];
    for (panel, (label, pick)) in panels.iter().zip(kinds) {
        let top = (ev.horizons.iter()).map(|h| pick(h)[2]).fold(0.0, f64::max) * 1.1;
        let mut chart = ChartBuilder::on(panel)
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(64)
            .build_cartesian_2d(0.0..h_max, 0.0..top.max(1e-6))
            .map_err(fail(path))?;
        chart
            .configure_mesh()
            .x_desc("horizon [s]")
            .y_desc(label)
            .label_style(("sans-serif", 15))
            .draw()
            .map_err(fail(path))?;
        for (i, name) in ["median", "p95", "worst"].into_iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let pts: Vec<(f64, f64)> = (ev.horizons.iter())
                .map(|h| (h.horizon_s, pick(h)[i]))
                .collect();
            chart
                .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
                .map_err(fail(path))?
                .label(name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
            chart
                .draw_series(pts.into_iter().map(|p| Circle::new(p, 4, color.filled())))
                .map_err(fail(path))?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .position(SeriesLabelPosition::UpperLeft)
            .draw()
            .map_err(fail(path))?;
    }
    root.present().map_err(fail(path))
}

/// The 95 % ellipse of a 2 × 2 covariance around `c`, as a closed polyline.
fn ellipse(c: [f64; 2], p: [[f64; 2]; 2]) -> Vec<(f64, f64)> {
    let (a, b, d) = (p[0][0], 0.5 * (p[0][1] + p[1][0]), p[1][1]);
    let mean = 0.5 * (a + d);
    let diff = (0.25 * (a - d) * (a - d) + b * b).sqrt();
    let (l1, l2) = ((mean + diff).max(0.0), (mean - diff).max(0.0));
    let angle = 0.5 * (2.0 * b).atan2(a - d);
    let (r1, r2) = ((CHI2_2_P95 * l1).sqrt(), (CHI2_2_P95 * l2).sqrt());
    (0..=48)
        .map(|k| {
            let t = std::f64::consts::TAU * k as f64 / 48.0;
            let (x, y) = (r1 * t.cos(), r2 * t.sin());
            (
                c[0] + x * angle.cos() - y * angle.sin(),
                c[1] + x * angle.sin() + y * angle.cos(),
            )
        })
        .collect()
}

/// `ellipses_<h>s.png`: the reference path, and for every prediction of horizon `h` its
/// predicted position with the 95 % ellipse and a line to where the reference was.
fn ellipses(path: &Path, ev: &Evaluation, recording: &Recording, h: f64) -> Result<(), Fail> {
    let track: Vec<(f64, f64)> = (recording.reference.samples.iter())
        .map(|(_, o)| (o.pose.position[0], o.pose.position[1]))
        .collect();
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in &track {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    if x0 > x1 {
        return Ok(());
    }
    // Equal scales on both axes, with a margin.
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let half = 0.55 * (x1 - x0).max(y1 - y0).max(0.1);
    let root = BitMapBackend::new(path, (900, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(fail(path))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("predictions over {h} s: 95 % position ellipses"),
            ("sans-serif", 20),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(64)
        .build_cartesian_2d(cx - half..cx + half, cy - half..cy + half)
        .map_err(fail(path))?;
    chart
        .configure_mesh()
        .x_desc("x [m] (odom)")
        .y_desc("y [m] (odom)")
        .label_style(("sans-serif", 15))
        .draw()
        .map_err(fail(path))?;
    chart
        .draw_series(LineSeries::new(track, BLACK.mix(0.5)))
        .map_err(fail(path))?
        .label(recording.reference.name.clone())
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.mix(0.5)));
    let blue = Palette99::pick(1).to_rgba();
    let red = Palette99::pick(0).to_rgba();
    for r in ev.records.iter().filter(|r| r.horizon_s == h) {
        let c = [r.predicted[0], r.predicted[1]];
        let p = r.predicted_covariance;
        let block = [[p[0][0], p[0][1]], [p[1][0], p[1][1]]];
        chart
            .draw_series(LineSeries::new(ellipse(c, block), blue.stroke_width(1)))
            .map_err(fail(path))?;
        chart
            .draw_series(LineSeries::new(
                vec![(c[0], c[1]), (r.reference[0], r.reference[1])],
                red.stroke_width(1),
            ))
            .map_err(fail(path))?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(fail(path))?;
    root.present().map_err(fail(path))
}

/// Writes the plots into `dir`; returns their paths.
pub fn write(dir: &Path, ev: &Evaluation, recording: &Recording) -> Result<Vec<String>, Fail> {
    register();
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut written = Vec::new();
    let path = dir.join("errors_vs_horizon.png");
    errors(&path, ev)?;
    written.push(path.display().to_string());
    for h in ev.horizons.iter().map(|h| h.horizon_s) {
        let path = dir.join(format!("ellipses_{h}s.png"));
        ellipses(&path, ev, recording, h)?;
        written.push(path.display().to_string());
    }
    Ok(written)
}
