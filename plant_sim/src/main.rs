//! `plant_sim`: the plant process and the simulation front end.
//!
//! ```text
//! plant_sim                                  # = plant_sim sim --builtin seed
//! plant_sim sim [--scenario FILE | --builtin NAME] [--law L] [--out DIR]
//! plant_sim montecarlo [--scenario FILE] [--runs N] [--seed S] [--laws eqt,gt,nog,asym]
//!                      [--samples FILE] [--threads N] [--out DIR]
//! ```
//! Exit codes: 0 done, 2 bad input (with a message naming the key and what is wrong),
//! 1 the run could not complete.

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use plant_sim::SimError;
use plant_sim::montecarlo;
use plant_sim::output::{Summary, ensure_dir, write_json, write_trajectory_csv};
use plant_sim::plot::trajectory_figure;
use plant_sim::trajectory::simulate;
use scenario::Scenario;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "plant_sim",
    version,
    about = "Equivariant tracking control: plant and simulator"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Run the closed loop in one process; write trajectory.csv, summary.json, figure.png/.svg.
    Sim(SimArgs),
    /// The extended paper's Monte Carlo study over the four laws.
    Montecarlo(McArgs),
}

#[derive(Args, Default)]
struct Source {
    /// Scenario file (TOML).
    #[arg(long, value_name = "FILE", conflicts_with = "builtin")]
    scenario: Option<PathBuf>,
    /// Built-in scenario: seed, montecarlo, se3_circle.
    #[arg(long, value_name = "NAME")]
    builtin: Option<String>,
}

impl Source {
    fn load(&self, default: &str) -> Result<Scenario, SimError> {
        Ok(match (&self.scenario, &self.builtin) {
            (Some(p), _) => Scenario::from_file(p)?,
            (None, Some(n)) => Scenario::builtin(n)?,
            (None, None) => Scenario::builtin(default)?,
        })
    }
}

#[derive(Args, Default)]
struct SimArgs {
    #[command(flatten)]
    source: Source,
    /// Override the scenario's law: eqt, gt, nog, asym.
    #[arg(long, value_name = "L")]
    law: Option<String>,
    /// Output directory (created if needed); default out/<scenario name>.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

#[derive(Args)]
struct McArgs {
    /// Base scenario (TOML); default the built-in `montecarlo`.
    #[arg(long, value_name = "FILE")]
    scenario: Option<PathBuf>,
    /// Number of drawn samples (ignored with --samples).
    #[arg(long, default_value_t = 200, value_name = "N")]
    runs: usize,
    /// Seed of the sample stream.
    #[arg(long, default_value_t = 1, value_name = "S")]
    seed: u64,
    /// Laws to compare, comma-separated.
    #[arg(long, default_value = "eqt,gt,nog,asym", value_name = "LIST")]
    laws: String,
    /// Samples CSV (header rx,ry,rz,wx,wy,wz), one run per row.
    #[arg(long, value_name = "FILE")]
    samples: Option<PathBuf>,
    /// Worker threads (default: one per core). The numbers do not depend on it.
    #[arg(long, value_name = "N")]
    threads: Option<usize>,
    /// Output directory; default out/montecarlo.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

fn progress(len: u64, what: &str) -> ProgressBar {
    // indicatif draws only when stderr is a terminal.
    let bar = ProgressBar::new(len);
    if let Ok(style) =
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} {elapsed_precise} eta {eta}")
    {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message(what.to_owned());
    bar
}

fn sim(args: SimArgs) -> Result<(), SimError> {
    let mut s = args.source.load("seed")?;
    if let Some(l) = &args.law {
        s = s.with_law(l)?;
    }
    let out = args.out.unwrap_or_else(|| Path::new("out").join(&s.name));
    ensure_dir(&out)?;
    let bar = progress(s.steps() + 1, &format!("sim {}", s.name));
    let traj = simulate(&s, &|k| {
        if k % 256 == 0 {
            bar.set_position(k);
        }
    })?;
    bar.finish_and_clear();
    write_trajectory_csv(&traj, &out.join("trajectory.csv"))?;
    let summary = Summary::of(&traj, &s.name, s.law.name());
    write_json(&summary, &out.join("summary.json"))?;
    let title = format!(
        "{} — {} on {}, T = {} s",
        s.name,
        s.law.name().to_uppercase(),
        s.group.name().to_uppercase(),
        s.duration
    );
    trajectory_figure(&traj, &title, &out.join("figure"))?;
    let f = &summary.final_errors;
    println!(
        "scenario {} ({}, law {}), {} steps of {} s",
        s.name,
        s.group.name(),
        s.law.name(),
        s.steps(),
        s.control_period
    );
    println!(
        "final: L = {:.4e}, |Q_E - I| = {:.4e}, |p_E| = {:.4e}, attitude error = {:.4e}, velocity error = {:.4e}",
        f.lyapunov, f.config_error, f.momentum_error, f.attitude_error, f.velocity_error
    );
    println!(
        "peak torque {:.4}, effort {:.4}, settling time {}",
        summary.peak_torque,
        summary.effort,
        summary
            .settling_time
            .map(|t| format!("{t:.2} s"))
            .unwrap_or_else(|| "not settled".to_owned())
    );
    println!(
        "wrote {}/{{trajectory.csv, summary.json, figure.png, figure.svg}}",
        out.display()
    );
    Ok(())
}

fn montecarlo_cmd(args: McArgs) -> Result<(), SimError> {
    let base = match &args.scenario {
        Some(p) => Scenario::from_file(p)?,
        None => Scenario::builtin("montecarlo")?,
    };
    let laws = args
        .laws
        .split(',')
        .map(|n| {
            controller::Law::from_name(n.trim()).ok_or_else(|| {
                SimError::Input(format!(
                    "--laws: unknown law `{}` (expected eqt, gt, nog, asym)",
                    n.trim()
                ))
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    if args.threads == Some(0) {
        return Err(SimError::Input("--threads: must be at least 1".to_owned()));
    }
    let samples = match &args.samples {
        Some(p) => montecarlo::read_samples(p)?,
        None => {
            if args.runs == 0 {
                return Err(SimError::Input("--runs: must be at least 1".to_owned()));
            }
            montecarlo::draw_samples(args.runs, args.seed)
        }
    };
    let out = args
        .out
        .unwrap_or_else(|| Path::new("out").join("montecarlo"));
    ensure_dir(&out)?;
    let bar = progress((samples.len() * laws.len()) as u64, "montecarlo");
    let results = montecarlo::run_all(&base, &samples, &laws, args.threads, &|| bar.inc(1))?;
    bar.finish_and_clear();
    montecarlo::write_runs_csv(&results, &out.join("runs.csv"))?;
    let mean = montecarlo::means(&results, &laws);
    montecarlo::write_mean_csv(&mean, &laws, base.control_period, &out.join("mean.csv"))?;
    let stats = montecarlo::stats(&results, &laws);
    write_json(&stats, &out.join("summary.json"))?;
    montecarlo::figure(
        &mean,
        &laws,
        base.control_period,
        samples.len(),
        &out.join("figure"),
    )?;
    println!(
        "Monte Carlo on `{}`: {} runs x {} laws, T = {} s",
        base.name,
        samples.len(),
        laws.len(),
        base.duration
    );
    print!("{}", montecarlo::table(&stats));
    println!(
        "wrote {}/{{runs.csv, mean.csv, summary.json, figure.png, figure.svg}}",
        out.display()
    );
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        None => sim(SimArgs::default()),
        Some(Command::Sim(a)) => sim(a),
        Some(Command::Montecarlo(a)) => montecarlo_cmd(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.exit_code() as u8)
        }
    }
}
