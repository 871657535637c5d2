//! `plant_sim move`: a scenario moved with the world (docs/invariance.md), and with `--check`
//! flown beside the original and compared column by column.

use clap::Args;
use eqtrack_controller::group::{MatrixLieGroup, So3};
use link::StopFlag;
use nalgebra::Vector3;
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

pub(crate) fn move_cmd(args: MoveArgs, stop: &StopFlag) -> Result<(), SimError> {
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
    // a file name, whatever the scenario's `name` holds (no folder, never `..`)
    let stem = Path::new(&original.name)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .filter(|n| n != "..")
        .unwrap_or_else(|| "scenario".to_owned());
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| Path::new("out").join(format!("{stem}-moved")));
    ensure_dir(&out)?;
    let file = format!("{stem}.toml");
    let sources: Vec<PathBuf> = args
        .source
        .scenario
        .iter()
        .cloned()
        .chain(original.path.as_ref().map(|p| PathBuf::from(&p.file)))
        .collect();
    let targets: Vec<PathBuf> = std::iter::once(out.join(&file))
        .chain(moved.waypoints.iter().map(|(w, _)| out.join(w)))
        .collect();
    refuse_overwrite(&sources, &targets)?;
    let path = moved.write(&out, &file)?;
    // what was written loads, and its path is the original's moved
    let there = Scenario::from_file(&path)?;
    same_path_moved(&original, &there, &m)?;
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
    fly_both(&original, &there, &m, &out, &args, stop)
}

/// Refuses to write a moved file over the scenario or the waypoint file it was moved from.
fn refuse_overwrite(sources: &[PathBuf], targets: &[PathBuf]) -> Result<(), SimError> {
    let canonical = |p: &Path| std::fs::canonicalize(p).ok();
    for t in targets {
        let Some(t) = canonical(t) else { continue }; // not there yet: nothing to overwrite
        if sources.iter().any(|s| canonical(s).as_ref() == Some(&t)) {
            return Err(SimError::Input(format!(
                "--out: writing the moved scenario there would replace {} it was moved from; give another folder",
                t.display()
            )));
        }
    }
    Ok(())
}

/// The moved scenario's waypoints are the original's moved by `m` (within 1e-9): the file
/// written is read back as the loader reads it.
fn same_path_moved(a: &Scenario, b: &Scenario, m: &WorldMotion) -> Result<(), SimError> {
    let (Some(pa), Some(pb)) = (&a.path, &b.path) else {
        return Ok(());
    };
    let close = |x: [f64; 3], y: [f64; 3]| {
        x.iter()
            .zip(&y)
            .all(|(p, q)| (p - q).abs() <= 1e-9 * (1.0 + p.abs()))
    };
    let same = pa.poses.len() == pb.poses.len()
        && pa.poses.iter().zip(&pb.poses).all(|(x, y)| {
            close(m.place(x.position), y.position)
                && (m.rotation() * So3::exp(&Vector3::from(x.rotation))
                    - So3::exp(&Vector3::from(y.rotation)))
                .abs()
                .max()
                    <= 1e-9
        });
    if same {
        Ok(())
    } else {
        Err(SimError::Run(format!(
            "the moved waypoints read back are not the original's moved ({})",
            pb.file
        )))
    }
}

/// `--check`: flies the scenario and the moved scenario at `path` and compares them.
fn fly_both(
    original: &Scenario,
    there: &Scenario,
    m: &WorldMotion,
    out: &Path,
    #[allow(unused_variables)] args: &MoveArgs,
    stop: &StopFlag,
) -> Result<(), SimError> {
    #[cfg(feature = "fault-injection")]
    let planted = super::sample_faults(&args.fault_sample)?;
    #[cfg(not(feature = "fault-injection"))]
    let planted = Vec::new();
    let mut tables = Vec::new();
    for (s, dir) in [(original, "original"), (there, "moved")] {
        let traj = super::simulate_shown(s, &planted, &format!("{dir} {}", s.name), stop)?;
        let dir_path = out.join(dir);
        ensure_dir(&dir_path)?;
        write_trajectory_csv(&traj, &dir_path.join("trajectory.csv"))?;
        // two flights that both diverged are not "the same flight"
        if let Some(t) = plant::trajectory::first_non_finite(&traj) {
            return Err(SimError::Run(format!(
                "the {dir} flight diverged: its state is not finite from t = {t} s (its table is in {})",
                dir_path.display()
            )));
        }
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
