//! `plant_sim rejection`: the disturbance-rejection study.

use clap::Args;
use plant::SimError;
use plant::output::ensure_dir;
use scenario::Scenario;
use scenario::cli::ScenarioSource;
use std::path::{Path, PathBuf};

#[derive(Args)]
pub(crate) struct RejectionArgs {
    #[command(flatten)]
    source: ScenarioSource,
    /// The integral variant's K_I (every axis) when the scenario has no `integral`.
    #[arg(
        long,
        value_name = "X",
        default_value_t = 1.0,
        allow_negative_numbers = true
    )]
    ki: f64,
    /// The integral variant's c (every axis) when the scenario has no `integral`.
    #[arg(
        long,
        value_name = "X",
        default_value_t = 5.0,
        allow_negative_numbers = true
    )]
    c: f64,
    /// The observer variant's gain L (1/s, every axis) when the scenario has no
    /// `disturbance_observer`.
    #[arg(
        long,
        value_name = "X",
        default_value_t = 20.0,
        allow_negative_numbers = true
    )]
    gain: f64,
    /// Monte Carlo: this many random constant body disturbances (0: none).
    #[arg(long, value_name = "N", default_value_t = 0)]
    runs: usize,
    /// Monte Carlo: the largest disturbance magnitude (N·m); each is uniform in [0, X] in a
    /// uniformly random direction.
    #[arg(
        long,
        value_name = "X",
        default_value_t = 0.2,
        allow_negative_numbers = true
    )]
    magnitude: f64,
    /// Monte Carlo: the seed of the draws.
    #[arg(long, value_name = "S", default_value_t = 1)]
    seed: u64,
    /// Output directory; default out/rejection-<scenario name>.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

pub(crate) fn rejection_cmd(args: RejectionArgs) -> Result<(), SimError> {
    use studies::rejection;
    // default: the set-point, shipped as a scenario file
    let s = if args.source.scenario.is_none() && args.source.builtin.is_none() {
        Scenario::from_file(Path::new("scenarios/reject_so3.toml"))?
    } else {
        args.source.load("seed")?
    };
    let v = rejection::Variants::of(&s, args.ki, args.c, args.gain)?;
    let out = args
        .out
        .unwrap_or_else(|| Path::new("out").join(format!("rejection-{}", s.name)));
    ensure_dir(&out)?;
    let flown = rejection::compare(&s, &v)?;
    rejection::write(&flown, &s, &out)?;
    print!("{}", rejection::table(&flown, s.group.dims().1));
    println!(
        "wrote {}/{{rejection.csv, table.md, rejection.png, rejection.svg}}",
        out.display()
    );
    if args.runs > 0 {
        let runs = rejection::montecarlo(&s, &v, args.runs, args.magnitude, args.seed)?;
        rejection::write_mc(&runs, &out)?;
        let mut calm = s.clone();
        calm.disturbance = vec![0.0; s.group.dims().1];
        calm.rejection = Default::default();
        let undisturbed = plant::trajectory::simulate(&calm, &|_| Ok(()))?
            .rows
            .last()
            .map_or(f64::NAN, |r| rejection::angle(r.attitude_error));
        println!(
            "Monte Carlo: {} random constant disturbances up to {} N·m (seed {}); without a \
             disturbance the plain law ends {undisturbed:.3e} rad from the reference",
            args.runs, args.magnitude, args.seed
        );
        print!("{}", rejection::mc_table(&runs));
        println!(
            "wrote {}/{{rejection_montecarlo.csv, montecarlo.md}}",
            out.display()
        );
    }
    Ok(())
}
