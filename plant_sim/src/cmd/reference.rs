//! `plant_sim reference`: a waypoint scenario's reference and feasibility report.

use clap::Args;
use plant::SimError;
use scenario::cli::ScenarioSource;
use std::path::{Path, PathBuf};

#[derive(Args)]
pub(crate) struct ReferenceArgs {
    #[command(flatten)]
    source: ScenarioSource,
    /// Output directory (created if needed); default out/<scenario name>.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Exit 1 when the feedforward alone exceeds the torque limit on an axis (default: a
    /// warning, exit 0).
    #[arg(long)]
    strict: bool,
    /// Also fly the waypoints both ways (`path = "stop"` and `"through"`): paths.{png,svg}
    /// and paths.json.
    #[arg(long)]
    compare_paths: bool,
}

pub(crate) fn reference_cmd(args: ReferenceArgs) -> Result<(), SimError> {
    let s = args.source.load("seed")?;
    let out = args.out.unwrap_or_else(|| Path::new("out").join(&s.name));
    let (csv, report) = studies::reference::write_reference(&s, &out)?;
    println!(
        "reference of `{}` ({}, {}{}): {} samples at {} s; wrote {}, {}/reference.{{png,svg}} and {}/reference.json",
        s.name,
        s.group.name(),
        s.path
            .as_ref()
            .map_or("feedforward series", |p| p.file.as_str()),
        s.path
            .as_ref()
            .filter(|p| p.times.len() > 1)
            .map_or(String::new(), |p| format!(", path = \"{}\"", p.kind.name())),
        s.steps() + 1,
        s.control_period,
        csv.display(),
        out.display(),
        out.display()
    );
    print!("{}", studies::reference::feasibility_text(&report));
    for w in &report.warnings {
        eprintln!("{w}");
    }
    if args.compare_paths {
        let c = studies::reference::compare_paths(&s, &out)?;
        for ((way, f), (_, flown)) in c.reports.iter().zip(&c.tracking) {
            let tau = f.torque.iter().map(|p| p.value).fold(0.0f64, f64::max);
            println!(
                "  {way:<8} peak |ω_d| {:.4} rad/s at t = {:.2} s, peak |τ_d| on an axis {tau:.4}, flown: largest attitude error from the second waypoint on {flown:.3e}",
                f.angular_speed.value, f.angular_speed.t
            );
        }
        println!(
            "wrote {0}/paths.{{png,svg}} and {0}/paths.json",
            out.display()
        );
    }
    if args.strict && !report.warnings.is_empty() {
        return Err(SimError::Run(format!(
            "--strict: the feedforward alone exceeds the torque limit on {} axis/axes (see the warnings above)",
            report.warnings.len()
        )));
    }
    Ok(())
}
