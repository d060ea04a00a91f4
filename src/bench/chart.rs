//! The speed-accuracy chart of `wavrad bench sweep` (`bench.svg`), drawn with `plotters` (SVG
//! backend only): one row per scene, on the left the error (log) against the solve seconds (log),
//! one line per order and domain mode; on the right the convergence history (unshot ratio, log,
//! against seconds, log) of one tolerance in both modes, the paper's figure 10.
//!
//! Owns [`ScenePlot`], [`Curve`] and [`draw`]. Invariants: every panel has a caption naming its
//! scene (`tests/bench_sweep.rs` finds them in the SVG); points that a log axis cannot show (not
//! finite or not positive) are left out, never clamped; a scene with nothing to show still gets
//! its panels, captioned "(no data)".

use plotters::prelude::*;
use std::path::Path;

/// One line: its legend, its order (the colour) and mode (solid with dots for extended domains,
/// dashed with crosses for tessellated), and its points `(x, y)`.
#[derive(Debug, Clone)]
pub struct Curve {
    pub label: String,
    pub order: usize,
    pub extended: bool,
    pub points: Vec<(f64, f64)>,
}

/// One scene's two panels.
#[derive(Debug, Clone)]
pub struct ScenePlot {
    pub name: String,
    /// Error (%) against solve seconds.
    pub error: Vec<Curve>,
    /// Unshot ratio against seconds, and the tolerance it was solved at.
    pub convergence: Vec<Curve>,
    pub convergence_tolerance: f64,
}

const ORDER_COLOURS: [RGBColor; 3] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
];
const PANEL_WIDTH: u32 = 560;
const PANEL_HEIGHT: u32 = 340;

fn err(e: impl std::fmt::Display) -> String {
    format!("drawing the chart: {e}")
}

/// A log axis range holding every value of `values` with a margin; `None` when none is positive.
fn log_range(values: impl Iterator<Item = f64>) -> Option<std::ops::Range<f64>> {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    (hi > 0.0).then(|| {
        let (lo, hi) = if hi / lo < 1.5 {
            (lo / 1.25, hi * 1.25)
        } else {
            (lo, hi)
        };
        lo / 1.15..hi * 1.15
    })
}

fn visible(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    points
        .iter()
        .copied()
        .filter(|&(x, y)| x.is_finite() && y.is_finite() && x > 0.0 && y > 0.0)
        .collect()
}

/// An axis label: three significant decimals at most, trailing zeros dropped ("0.03", "2", "150").
fn short(v: f64) -> String {
    let decimals = (2.0 - v.abs().log10().floor()).clamp(0.0, 12.0) as usize;
    let text = format!("{v:.decimals$}");
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        text
    }
}

/// A panel's axes and lines; `markers` draws each point (one per solve) as well.
fn panel(
    area: &DrawingArea<SVGBackend, plotters::coord::Shift>,
    caption: &str,
    (x_desc, y_desc): (&str, &str),
    curves: &[Curve],
    markers: bool,
) -> Result<(), String> {
    let xs = log_range(curves.iter().flat_map(|c| visible(&c.points)).map(|p| p.0));
    let ys = log_range(curves.iter().flat_map(|c| visible(&c.points)).map(|p| p.1));
    let (Some(xs), Some(ys)) = (xs, ys) else {
        area.titled(&format!("{caption} (no data)"), ("sans-serif", 16))
            .map_err(err)?;
        return Ok(());
    };
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 16))
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(56)
        .build_cartesian_2d(xs.log_scale(), ys.log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .x_label_formatter(&|v| short(*v))
        .y_label_formatter(&|v| short(*v))
        .light_line_style(WHITE.mix(0.0))
        .draw()
        .map_err(err)?;
    for curve in curves {
        let points = visible(&curve.points);
        if points.is_empty() {
            continue;
        }
        let colour = ORDER_COLOURS[(curve.order.max(1) - 1) % ORDER_COLOURS.len()];
        let style = colour.stroke_width(if curve.extended { 2 } else { 1 });
        if curve.extended {
            chart
                .draw_series(
                    LineSeries::new(points.clone(), style).point_size(if markers { 3 } else { 0 }),
                )
                .map_err(err)?
                .label(&curve.label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], style));
        } else {
            chart
                .draw_series(DashedLineSeries::new(points.clone(), 6, 4, style))
                .map_err(err)?
                .label(&curve.label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 6, y)], style));
            if markers {
                chart
                    .draw_series(points.iter().map(|&p| Cross::new(p, 4, style)))
                    .map_err(err)?;
            }
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.4))
        .label_font(("sans-serif", 11))
        .position(SeriesLabelPosition::LowerLeft)
        .draw()
        .map_err(err)?;
    Ok(())
}

/// Draws `scenes` into the SVG file `path`.
pub fn draw(path: &Path, scenes: &[ScenePlot]) -> Result<(), String> {
    let rows = scenes.len().max(1);
    let root =
        SVGBackend::new(path, (2 * PANEL_WIDTH, PANEL_HEIGHT * rows as u32)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let areas = root.split_evenly((rows, 2));
    for (scene, pair) in scenes.iter().zip(areas.chunks(2)) {
        panel(
            &pair[0],
            &format!("{}: error against time", scene.name),
            ("solve seconds", "error (nrms, %)"),
            &scene.error,
            true,
        )?;
        panel(
            &pair[1],
            &format!(
                "{}: convergence at tolerance {:e}",
                scene.name, scene.convergence_tolerance
            ),
            ("seconds", "unshot ratio"),
            &scene.convergence,
            false,
        )?;
    }
    root.present().map_err(err)
}

#[cfg(test)]
mod tests {
    use super::short;

    #[test]
    fn axis_labels_are_short() {
        assert_eq!(short(0.03), "0.03");
        assert_eq!(short(2.0), "2");
        assert_eq!(short(150.0), "150");
        assert_eq!(short(0.001), "0.001");
        assert_eq!(short(1.25), "1.25");
    }
}
