//! Figures as PNG and SVG (plotters, with the DejaVu Sans font embedded so that no system
//! font library is needed).

use crate::SimError;
use crate::trajectory::SimulatedTrajectory;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

/// One curve.
#[derive(Debug, Clone)]
pub struct Line {
    /// Legend label (empty: no legend entry).
    pub label: String,
    /// Colour.
    pub color: RGBColor,
    /// `(t, y)` points.
    pub points: Vec<(f64, f64)>,
}

/// One panel: a title, a y-axis label and its curves against time.
#[derive(Debug, Clone)]
pub struct Panel {
    /// Caption.
    pub title: String,
    /// Y-axis description.
    pub y_label: String,
    /// Curves.
    pub lines: Vec<Line>,
}

/// The colour of a law in every figure.
pub fn law_color(law: &str) -> RGBColor {
    match law {
        "eqt" => RGBColor(31, 119, 180),
        "gt" => RGBColor(214, 39, 40),
        "nog" => RGBColor(44, 160, 44),
        "asym" => RGBColor(255, 127, 14),
        _ => BLACK,
    }
}

static FONT: Once = Once::new();

fn register_font() {
    FONT.call_once(|| {
        // The embedded font is valid TrueType; a failure would only lose the labels.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    title: &str,
    panels: &[Panel],
    cols: usize,
    x_desc: &str,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let e = |x: DrawingAreaErrorKind<DB::ErrorType>| x.to_string();
    root.fill(&WHITE).map_err(e)?;
    let root = root.titled(title, ("sans-serif", 26)).map_err(e)?;
    let rows = panels.len().div_ceil(cols);
    let areas = root.split_evenly((rows, cols));
    for (area, panel) in areas.iter().zip(panels) {
        let pts = panel.lines.iter().flat_map(|l| l.points.iter());
        let (mut t1, mut y0, mut y1) = (0.0f64, 0.0f64, 0.0f64);
        for (t, y) in pts.filter(|(t, y)| t.is_finite() && y.is_finite()) {
            t1 = t1.max(*t);
            y0 = y0.min(*y);
            y1 = y1.max(*y);
        }
        if t1 <= 0.0 {
            t1 = 1.0;
        }
        if y1 <= y0 {
            y1 = y0 + 1.0;
        }
        let pad = 0.05 * (y1 - y0);
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..t1, (y0 - if y0 < 0.0 { pad } else { 0.0 })..(y1 + pad))
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(panel.y_label.as_str())
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 16))
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(e)?;
        let mut labelled = false;
        for line in &panel.lines {
            let color = line.color;
            let series = chart
                .draw_series(LineSeries::new(
                    line.points.iter().copied(),
                    color.stroke_width(2),
                ))
                .map_err(e)?;
            if !line.label.is_empty() {
                labelled = true;
                series.label(line.label.clone()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(3))
                });
            }
        }
        if labelled {
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperRight)
                .label_font(("sans-serif", 15))
                .border_style(BLACK)
                .background_style(WHITE.mix(0.85))
                .draw()
                .map_err(e)?;
        }
    }
    root.present().map_err(e)
}

/// Writes `stem.png` and `stem.svg` with `panels` laid out in `cols` columns, against time.
pub fn render(
    stem: &Path,
    title: &str,
    panels: &[Panel],
    cols: usize,
    size: (u32, u32),
) -> Result<(), SimError> {
    render_against(stem, title, panels, cols, size, "t [s]")
}

/// [`render`] with another quantity on the x axis (`x_desc` labels it).
pub fn render_against(
    stem: &Path,
    title: &str,
    panels: &[Panel],
    cols: usize,
    size: (u32, u32),
    x_desc: &str,
) -> Result<(), SimError> {
    register_font();
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    let fail = |p: &Path, e: String| SimError::Run(format!("cannot draw {}: {e}", p.display()));
    draw(
        BitMapBackend::new(&png, size).into_drawing_area(),
        title,
        panels,
        cols,
        x_desc,
    )
    .map_err(|e| fail(&png, e))?;
    draw(
        SVGBackend::new(&svg, size).into_drawing_area(),
        title,
        panels,
        cols,
        x_desc,
    )
    .map_err(|e| fail(&svg, e))?;
    Ok(())
}

/// The seed paper's figure: `L`, `‖Q_E − I‖_F` and `‖p_E‖` against time.
pub fn trajectory_figure(
    traj: &SimulatedTrajectory,
    title: &str,
    stem: &Path,
) -> Result<(), SimError> {
    let series =
        |f: fn(&crate::trajectory::Row) -> f64| traj.rows.iter().map(|r| (r.t, f(r))).collect();
    let blue = law_color("eqt");
    let panel = |title: &str, y: &str, points| Panel {
        title: title.to_owned(),
        y_label: y.to_owned(),
        lines: vec![Line {
            label: String::new(),
            color: blue,
            points,
        }],
    };
    let mut panels = vec![
        panel("Lyapunov function L", "L", series(|r| r.lyapunov)),
        panel(
            "Configuration error ‖Q_E − I‖_F",
            "‖Q_E − I‖_F",
            series(|r| r.config_error),
        ),
        panel(
            "Momentum error ‖p_E‖",
            "‖p_E‖",
            series(|r| r.momentum_error),
        ),
    ];
    if traj.estimator.is_some() {
        // the tracking error of the true state beside the estimate's own error
        panels.push(Panel {
            title: "Attitude: tracking error of the true state, and estimate error ∠(R̂ᵀR)"
                .to_owned(),
            y_label: "rad".to_owned(),
            lines: vec![
                Line {
                    label: "tracking ‖I − R_dᵀR‖_F (true state)".to_owned(),
                    color: blue,
                    points: series(|r| r.attitude_error),
                },
                Line {
                    label: "estimate error".to_owned(),
                    color: law_color("gt"),
                    points: series(|r| r.estimate.map_or(f64::NAN, |e| e.estimate_error)),
                },
            ],
        });
    }
    if let Some(count) = traj.rows.first().and_then(|r| r.vehicle).map(|v| v.count) {
        panels.push(actuator_panel(traj, count));
    }
    let height = 1100 * panels.len() as u32 / 3;
    render(stem, title, &panels, 1, (1000, height))
}

/// A vehicle's actuators: each one's output `u_j(t_k)` (after lag, limits and failures).
fn actuator_panel(traj: &SimulatedTrajectory, count: usize) -> Panel {
    const COLORS: [RGBColor; 4] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(148, 103, 189),
    ];
    Panel {
        title: "Actuator outputs u_j".to_owned(),
        y_label: "N".to_owned(),
        lines: (0..count)
            .map(|j| Line {
                label: format!("u_{j}"),
                color: COLORS[j % COLORS.len()],
                points: traj
                    .rows
                    .iter()
                    .map(|r| (r.t, r.vehicle.map_or(f64::NAN, |v| v.u[j])))
                    .collect(),
            })
            .collect(),
    }
}
