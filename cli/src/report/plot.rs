//! Log-log work-precision diagrams (plotters, bitmap backend). Text is drawn with DejaVu Sans
//! embedded in the binary (the `dejavu` crate through plotters' ab_glyph backend), so no system
//! font is needed.

use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};
use std::path::Path;
use std::sync::Once;

static FONT: Once = Once::new();

pub(crate) fn register() {
    FONT.call_once(|| {
        // The family plotters asks for by default.
        let _ = register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular());
    });
}

/// One series: a label and (CPU time [s], value) points; an external peer's is drawn with
/// triangles and a thinner line.
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    pub peer: bool,
}

const FLOOR: f64 = 1e-17;

const PEER_COLORS: [RGBColor; 4] = [
    RGBColor(0, 0, 0),
    RGBColor(150, 75, 0),
    RGBColor(110, 110, 110),
    RGBColor(120, 0, 60),
];

/// Tick labels at mantissas 1, 2 and 5 only (log axes get a tick at every integer mantissa).
fn label(x: &f64) -> String {
    let s = format!("{x:.0e}");
    if s.starts_with(['1', '2', '5']) {
        s
    } else {
        String::new()
    }
}

/// Draw `series` on log-log axes into a PNG at `path`.
pub fn work_precision(
    path: &Path,
    title: &str,
    y_label: &str,
    series: &[Series],
) -> Result<(), String> {
    register();
    let pts = series.iter().flat_map(|s| s.points.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in pts {
        let y = y.max(FLOOR);
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    if x0 > x1 {
        return Ok(()); // nothing to draw
    }
    let (x0, x1) = (x0 / 1.5, x1 * 1.5);
    let (y0, y1) = (y0 / 5.0, y1 * 5.0);
    let root = BitMapBackend::new(path, (960, 640)).into_drawing_area();
    let e = |e: DrawingAreaErrorKind<_>| format!("{}: {e}", path.display());
    root.fill(&WHITE).map_err(e)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(80)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc("CPU time [s]")
        .y_desc(y_label)
        .x_label_formatter(&label)
        .y_label_formatter(&label)
        .label_style(("sans-serif", 15))
        .draw()
        .map_err(e)?;
    let mut peers = 0;
    for (i, s) in series.iter().enumerate() {
        if s.points.is_empty() {
            continue;
        }
        // Peers in dark colours of their own (and triangles), the project's from the palette.
        let color = if s.peer {
            PEER_COLORS[peers % PEER_COLORS.len()].to_rgba()
        } else {
            Palette99::pick(i - peers).to_rgba()
        };
        peers += s.peer as usize;
        let width = if s.peer { 1 } else { 2 };
        let pts: Vec<(f64, f64)> = s.points.iter().map(|&(x, y)| (x, y.max(FLOOR))).collect();
        let peer = s.peer;
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(width)))
            .map_err(e)?
            .label(s.label.clone())
            .legend(move |(x, y)| {
                let line = PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(width));
                let mark: DynElement<_, _> = if peer {
                    TriangleMarker::new((x + 10, y), 6, color.filled()).into_dyn()
                } else {
                    Circle::new((x + 10, y), 3, color.filled()).into_dyn()
                };
                EmptyElement::at((0, 0)) + line + mark
            });
        if s.peer {
            chart
                .draw_series(
                    pts.into_iter()
                        .map(|p| TriangleMarker::new(p, 7, color.filled())),
                )
                .map_err(e)?;
        } else {
            chart
                .draw_series(pts.into_iter().map(|p| Circle::new(p, 4, color.filled())))
                .map_err(e)?;
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(e)?;
    root.present().map_err(e)?;
    Ok(())
}
