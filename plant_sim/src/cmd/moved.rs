//! `plant_sim move`: a scenario moved with the world (docs/invariance.md), and with `--check`
//! flown beside the original and compared column by column.

use clap::Args;
use plant::SimError;
use plant::output::{ensure_dir, write_json, write_trajectory_csv};
use scenario::Scenario;
use scenario::cli::ScenarioSource;
use scenario::moving::{WorldMotion, move_scenario};
use std::path::{Path, PathBuf};
use studies::moved::{TOLERANCE, compare, summary_text, table};

#[derive(Args)]
pub(crate) struct MoveArgs {
    #[command(flatten)]
    source: ScenarioSource,
    /// The world's shift (m): the moved scenario's poses are `R_T x + offset`.
    #[arg(long, value_name = "X,Y,Z", value_parser = offset, default_value = "0,0,0", allow_hyphen_values = true)]
    offset: [f64; 3],
    /// The world's turn about the vertical z (rad), applied before the shift.
    #[arg(
        long,
        value_name = "RAD",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    heading: f64,
    /// Output directory (created if needed): the moved scenario and its waypoint file;
    /// default out/<scenario name>-moved.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Also fly the scenario and the moved scenario and compare their trajectory.csv column
    /// by column (DIR/original/, DIR/moved/, DIR/check.json): exit 1 when the moved flight
    /// is not the same flight within 1e-6 of (1 + |value|).
    #[arg(long)]
    check: bool,
    /// Test builds only (feature `fault-injection`): K:KIND plants a bad sensor sample at
    /// tick K in both flights.
    #[cfg(feature = "fault-injection")]
    #[arg(long, value_name = "K:KIND", hide = true)]
    fault_sample: Vec<String>,
}

/// `X,Y,Z`: three finite numbers.
fn offset(text: &str) -> Result<[f64; 3], String> {
    let xs: Vec<&str> = text.split(',').map(str::trim).collect();
    let [x, y, z] = xs.as_slice() else {
        return Err(format!("expected three numbers X,Y,Z, got `{text}`"));
    };
    let mut out = [0.0; 3];
    for (o, t) in out.iter_mut().zip([x, y, z]) {
        *o = t
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("`{t}` is not a finite number (in `{text}`)"))?;
    }
    Ok(out)
}

pub(crate) fn move_cmd(args: MoveArgs) -> Result<(), SimError> {
    if !args.heading.is_finite() {
        return Err(SimError::Input(format!(
            "--heading: must be a finite number of radians, got {}",
            args.heading
        )));
    }
    let m = WorldMotion {
        heading: args.heading,
        offset: args.offset,
    };
    let original = args.source.load("seed")?;
    let (table_in, origin, base) = args.source.table("seed")?;
    let text = toml::to_string(&table_in).map_err(|e| SimError::Run(e.to_string()))?;
    let moved = move_scenario(&text, &origin, base.as_deref(), &m)?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| Path::new("out").join(format!("{}-moved", original.name)));
    ensure_dir(&out)?;
    let file = format!("{}.toml", original.name);
    let path = moved.write(&out, &file)?;
    println!(
        "moved `{}` with the world: turned by {} rad about z, shifted by ({}, {}, {}) m; wrote {}{}",
        original.name,
        m.heading,
        m.offset[0],
        m.offset[1],
        m.offset[2],
        path.display(),
        moved
            .waypoints
            .as_ref()
            .map_or(String::new(), |(w, _)| format!(
                " and {}",
                out.join(w).display()
            ))
    );
    if original
        .sensors
        .as_ref()
        .is_some_and(|s| s.position.is_some())
        && m.heading != 0.0
    {
        eprintln!(
            "note: `{}` has position fixes, whose noise is drawn in world axes: turned, it draws different noise and flies a different flight (shift it only to compare)",
            original.name
        );
    }
    if !args.check {
        return Ok(());
    }
    fly_both(&original, &path, &m, &out, &args)
}

/// `--check`: flies the scenario and the moved scenario at `path` and compares them.
fn fly_both(
    original: &Scenario,
    path: &Path,
    m: &WorldMotion,
    out: &Path,
    #[allow(unused_variables)] args: &MoveArgs,
) -> Result<(), SimError> {
    let there = Scenario::from_file(path)?;
    #[cfg(feature = "fault-injection")]
    let planted = super::sample_faults(&args.fault_sample)?;
    #[cfg(not(feature = "fault-injection"))]
    let planted = Vec::new();
    let mut tables = Vec::new();
    for (s, dir) in [(original, "original"), (&there, "moved")] {
        let traj = plant::trajectory::simulate_planted(s, &planted, &|_| Ok(()))?;
        let dir = out.join(dir);
        ensure_dir(&dir)?;
        write_trajectory_csv(&traj, &dir.join("trajectory.csv"))?;
        tables.push(table(&traj)?);
    }
    let check = compare(original.group, m, &tables[0], &tables[1]).map_err(SimError::Run)?;
    write_json(&check, &out.join("check.json"))?;
    println!(
        "flew both ({} rows each): {1}/original/trajectory.csv, {1}/moved/trajectory.csv; the comparison in {1}/check.json",
        check.rows,
        out.display()
    );
    print!("{}", summary_text(&check));
    match check.worst() {
        Some(w) if !check.same_flight() => Err(SimError::Run(format!(
            "the moved flight differs: column `{}` by {:.3e} at t = {} s (more than {TOLERANCE:e} of 1 + |value|)",
            w.column, w.worst, w.t
        ))),
        _ => {
            println!("the same flight: every column within {TOLERANCE:e} of 1 + |value|");
            Ok(())
        }
    }
}
