//! What a what-if writes: `replay.csv` (recorded and replayed torques per cycle) and the
//! figure.

use super::ReplayOptions;
use ipc_types::{CommandMsg, MAX_M};
use link::Decision;
use plant::SimError;
use plant::plot::{Line, Panel, law_color, render};
use scenario::Scenario;
use std::path::Path;

/// One cycle of `replay.csv`.
pub(super) struct Row {
    pub(super) cycle: u64,
    pub(super) t: f64,
    pub(super) decision: Decision,
    pub(super) recorded: Option<CommandMsg>,
    pub(super) replayed: Option<CommandMsg>,
}

fn num(x: f64) -> String {
    if x.is_finite() {
        format!("{x:e}")
    } else {
        String::new()
    }
}

pub(super) fn write_csv<const M: usize>(rows: &[Row], path: &Path) -> Result<(), SimError> {
    let fail = |e: csv::Error| SimError::Run(format!("cannot write {}: {e}", path.display()));
    let mut w = csv::Writer::from_path(path).map_err(fail)?;
    let mut head = vec![
        "cycle".to_owned(),
        "t".to_owned(),
        "command_status".to_owned(),
    ];
    for side in ["recorded", "replayed"] {
        head.extend((0..M).map(|i| format!("{side}_tau_{i}")));
        head.push(format!("{side}_lyapunov"));
    }
    w.write_record(&head).map_err(fail)?;
    let side = |c: &Option<CommandMsg>| -> Vec<String> {
        let (tau, l) = match c {
            Some(c) => (c.tau, c.lyapunov),
            None => ([f64::NAN; MAX_M], f64::NAN),
        };
        tau[..M].iter().chain([&l]).map(|x| num(*x)).collect()
    };
    for r in rows {
        let mut rec = vec![
            r.cycle.to_string(),
            format!("{:e}", r.t),
            r.decision.code().to_string(),
        ];
        rec.extend(side(&r.recorded));
        rec.extend(side(&r.replayed));
        w.write_record(&rec).map_err(fail)?;
    }
    w.flush()
        .map_err(|e| SimError::Run(format!("cannot write {}: {e}", path.display())))
}

/// Recorded and replayed torque per axis and L, against time.
pub(super) fn figure<const M: usize>(
    rows: &[Row],
    opts: &ReplayOptions,
    s: &Scenario,
    recorded_law: &str,
    stem: &Path,
) -> Result<(), SimError> {
    let (rec_color, mut rep_color) = (law_color(recorded_law), law_color(s.law.name()));
    if rec_color == rep_color {
        rep_color = plotters::style::RGBColor(214, 39, 40);
    }
    let series = |pick: &dyn Fn(&CommandMsg) -> f64, which: fn(&Row) -> &Option<CommandMsg>| {
        rows.iter()
            .filter_map(|r| which(r).as_ref().map(|c| (r.t, pick(c))))
            .collect::<Vec<_>>()
    };
    let rec_label = format!("recorded ({})", recorded_law.to_uppercase());
    let rep_label = format!("replayed ({})", describe(opts, s));
    let panel = |title: String, y: &str, pick: &dyn Fn(&CommandMsg) -> f64| Panel {
        title,
        y_label: y.to_owned(),
        lines: vec![
            Line {
                label: rec_label.clone(),
                color: rec_color,
                points: series(pick, |r| &r.recorded),
            },
            Line {
                label: rep_label.clone(),
                color: rep_color,
                points: series(pick, |r| &r.replayed),
            },
        ],
    };
    let mut panels: Vec<Panel> = (0..M)
        .map(|i| panel(format!("Torque τ_{i}"), &format!("tau_{i}"), &|c| c.tau[i]))
        .collect();
    panels.push(panel("Lyapunov value L".to_owned(), "L", &|c| c.lyapunov));
    let cols = if panels.len() > 4 { 2 } else { 1 };
    let height = 300 * panels.len().div_ceil(cols) as u32 + 100;
    let title = format!(
        "replay of {}: recorded vs what-if, same states",
        opts.dir.display()
    );
    render(stem, &title, &panels, cols, (1200, height))
}

/// The what-if, in words.
fn describe(opts: &ReplayOptions, s: &Scenario) -> String {
    let mut parts = vec![s.law.name().to_uppercase()];
    if let Some(f) = s.error_frame_note() {
        parts.push(format!("error frame {f}"));
    }
    if let Some(p) = &opts.scenario {
        parts.push(format!("scenario {}", p.display()));
    }
    if opts.kp.is_some() {
        parts.push("K changed".to_owned());
    }
    if opts.kd.is_some() {
        parts.push("K_d changed".to_owned());
    }
    parts.join(", ")
}
