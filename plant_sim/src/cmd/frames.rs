//! `plant_sim frames`: the `error_frame` Monte Carlo on SE(3) (`studies::frames`).

use super::progress;
use clap::Args;
use clap::builder::{PossibleValuesParser, TypedValueParser};
use eqtrack_controller::ErrorFrame;
use link::StopFlag;
use plant::SimError;
use plant::output::ensure_dir;
use scenario::Scenario;
use scenario::cli::positive_seconds;
use std::path::{Path, PathBuf};
use std::time::Duration;
use studies::frames;

#[derive(Args)]
pub(crate) struct FramesArgs {
    /// Base SE(3) scenario (TOML); default the built-in se3_circle
    /// (scenarios/se3_circle.toml).
    #[arg(long, value_name = "FILE")]
    scenario: Option<PathBuf>,
    /// Number of drawn runs (each flown with every frame).
    #[arg(long, default_value_t = 200, value_name = "N")]
    runs: usize,
    /// Seed of the draws.
    #[arg(long, default_value_t = 1, value_name = "S")]
    seed: u64,
    /// Error frames to compare, comma-separated.
    #[arg(long, default_value = "reference,world,recentred", value_name = "LIST", value_delimiter = ',', value_parser = frame_parser())]
    frames: Vec<ErrorFrame>,
    /// Seconds per run (default: the scenario's duration).
    #[arg(long, value_name = "S", value_parser = positive_seconds)]
    duration: Option<Duration>,
    /// Worker threads (default: one per core). The numbers do not depend on it.
    #[arg(long, value_name = "N")]
    threads: Option<usize>,
    /// The radius (m) of the ball the world's translation is drawn from (0: no translation;
    /// the other draws stay the same).
    #[arg(
        long,
        value_name = "M",
        default_value_t = 1e4,
        allow_negative_numbers = true
    )]
    world_radius: f64,
    /// The world's turn about z is drawn uniform on [-RAD, RAD] (0: no turn).
    #[arg(long, value_name = "RAD", default_value_t = std::f64::consts::PI, allow_negative_numbers = true)]
    world_turn: f64,
    /// Output directory; default out/frames.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

/// clap's parser for an [`ErrorFrame`] (`reference`, `world`, `recentred`; listed in
/// `--help` and in the error for any other value).
fn frame_parser() -> impl TypedValueParser<Value = ErrorFrame> {
    PossibleValuesParser::new(ErrorFrame::ALL.map(ErrorFrame::name))
        .map(|name| ErrorFrame::from_name(&name).unwrap_or_default())
}

/// The base scenario (its duration overridden) and the world motions, checked.
fn checked(args: &FramesArgs) -> Result<(Scenario, frames::WorldMotion), SimError> {
    let mut base = match &args.scenario {
        Some(p) => Scenario::from_file(p)?,
        None => Scenario::builtin("se3_circle")?,
    };
    if let Some(d) = args.duration {
        base.duration = d.as_secs_f64();
        if base.steps() == 0 {
            return Err(SimError::Input(format!(
                "--duration: {} s is shorter than the control period ({} s)",
                base.duration, base.control_period
            )));
        }
    }
    frames::check_base(&base)?;
    if args.runs == 0 {
        return Err(SimError::Input("--runs: must be at least 1".to_owned()));
    }
    if args.threads == Some(0) {
        return Err(SimError::Input("--threads: must be at least 1".to_owned()));
    }
    for (i, f) in args.frames.iter().enumerate() {
        if args.frames[..i].contains(f) {
            return Err(SimError::Input(format!(
                "--frames: `{}` is given twice",
                f.name()
            )));
        }
    }
    let world = frames::WorldMotion {
        radius: args.world_radius,
        turn: args.world_turn,
    };
    world.check()?;
    Ok((base, world))
}

pub(crate) fn frames_cmd(args: FramesArgs, stop: &StopFlag) -> Result<(), SimError> {
    let (base, world) = checked(&args)?;
    let out = args.out.unwrap_or_else(|| Path::new("out").join("frames"));
    ensure_dir(&out)?;
    let draws = frames::draw(args.runs, args.seed, world);
    let bar = progress((draws.len() * args.frames.len()) as u64, "frames");
    let started = std::time::Instant::now();
    let results = frames::run_study(
        &base,
        &draws,
        &args.frames,
        args.threads,
        &|| bar.inc(1),
        stop,
    )?;
    bar.finish_and_clear();
    if let Some(sig) = stop.requested() {
        frames::write_csv(&results, &out.join("frames.csv"))?;
        eprintln!(
            "{sig}: stopped after {} of {} runs; wrote {}/frames.csv",
            results.len(),
            draws.len() * args.frames.len(),
            out.display()
        );
        return Err(SimError::Interrupted(sig));
    }
    let setup = frames::Setup {
        scenario: base.name.clone(),
        runs: draws.len(),
        seed: args.seed,
        duration: base.duration,
        world,
    };
    let stats = frames::write(&setup, &results, &args.frames, base.control_period, &out)?;
    println!(
        "error_frame on `{}`: {} runs x {} frames, T = {} s, world moved up to {} m and {} rad ({:.1} s)",
        base.name,
        draws.len(),
        args.frames.len(),
        base.duration,
        world.radius,
        world.turn,
        started.elapsed().as_secs_f64()
    );
    print!("{}", frames::summary_lines(&stats));
    println!(
        "wrote {}/{{frames.csv, table.md, frames.png, frames.svg}}",
        out.display()
    );
    Ok(())
}
