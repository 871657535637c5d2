//! `plant_sim montecarlo`: the Monte Carlo study, and with `--estimators` the estimator study.

use super::progress;
use clap::Args;
use eqtrack_controller::Law;
use link::StopFlag;
use plant::SimError;
use plant::output::{ensure_dir, write_json};
use scenario::Scenario;
use scenario::cli::law_parser;
use std::path::{Path, PathBuf};
use studies::montecarlo;

#[derive(Args)]
pub(crate) struct McArgs {
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
    #[arg(long, default_value = "eqt,gt,nog,asym", value_name = "LIST", value_delimiter = ',', value_parser = law_parser())]
    laws: Vec<Law>,
    /// Samples CSV (header rx,ry,rz,wx,wy,wz), one run per row.
    #[arg(long, value_name = "FILE")]
    samples: Option<PathBuf>,
    /// Worker threads (default: one per core). The numbers do not depend on it.
    #[arg(long, value_name = "N")]
    threads: Option<usize>,
    /// Output directory; default out/montecarlo.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Compare estimators instead of laws (the first of --laws flies every run): truth,
    /// complementary, eqf. Needs a scenario with [sensors] (and kind = "eqf" for eqf).
    #[arg(long, value_name = "LIST", value_delimiter = ',', value_parser = estimator_parser)]
    estimators: Vec<scenario::EstimatorKind>,
    /// With --estimators: start each filter this far (rad, about an axis drawn per run)
    /// from the true attitude instead of TRIAD, and time its convergence.
    #[arg(long, value_name = "RAD", requires = "estimators")]
    initial_error: Option<f64>,
    /// Fly only shard I of N: the runs whose index is I modulo N (a Slurm array task:
    /// `--shard $SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT`), written whole to
    /// OUT/shard.bin for --merge.
    #[arg(long, value_name = "I/N", value_parser = clap::value_parser!(studies::shard::Shard), conflicts_with_all = ["merge", "estimators"])]
    shard: Option<studies::shard::Shard>,
    /// Join the shards in these directories into the study's outputs (the same bytes as
    /// the unsharded run); give the same --scenario, --runs, --seed (or --samples) and
    /// --laws as the shards.
    #[arg(long, value_name = "DIR", num_args = 1.., conflicts_with = "estimators")]
    merge: Vec<PathBuf>,
}

pub(crate) fn estimator_parser(text: &str) -> Result<scenario::EstimatorKind, String> {
    use scenario::EstimatorKind::*;
    [Truth, Complementary, Eqf]
        .into_iter()
        .find(|k| k.name() == text)
        .ok_or_else(|| format!("`{text}`: expected truth, complementary or eqf"))
}

pub(crate) fn montecarlo_cmd(args: McArgs, stop: &StopFlag) -> Result<(), SimError> {
    let base = match &args.scenario {
        Some(p) => Scenario::from_file(p)?,
        None => Scenario::builtin("montecarlo")?,
    };
    let laws = args.laws.clone();
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
        .clone()
        .unwrap_or_else(|| Path::new("out").join("montecarlo"));
    ensure_dir(&out)?;
    if !args.estimators.is_empty() {
        let study = (args.estimators.as_slice(), args.initial_error, args.threads);
        return estimator_study(&base, &samples, study, laws[0], &out, stop);
    }
    let study = studies::shard::Study::new(base.fingerprint(), &samples, &laws);
    let results = study_results(&args, &base, &samples, &study, stop)?;
    montecarlo::write_runs_csv(&results, &out.join("runs.csv"))?;
    if let (Some(shard), None) = (args.shard, stop.requested()) {
        return finish_shard(&base, shard, &study, &results, &out);
    }
    if let Some(sig) = stop.requested() {
        eprintln!(
            "{sig}: stopped after {} of {} runs; wrote {}/runs.csv",
            results.len(),
            samples.len() * laws.len(),
            out.display()
        );
        return Err(SimError::Interrupted(sig));
    }
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

/// The study's results: the shards of `--merge` joined, or the runs of `--shard` (all runs
/// without one) flown.
fn study_results(
    args: &McArgs,
    base: &Scenario,
    samples: &[montecarlo::Sample],
    study: &studies::shard::Study,
    stop: &StopFlag,
) -> Result<Vec<montecarlo::RunResult>, SimError> {
    if !args.merge.is_empty() {
        let dirs: Vec<&Path> = args.merge.iter().map(PathBuf::as_path).collect();
        return studies::shard::merge(&dirs, study);
    }
    let (laws, threads) = (&study.laws, args.threads);
    let share = match args.shard {
        Some(shard) => shard.select(samples),
        None => samples.iter().copied().enumerate().collect(),
    };
    let bar = progress((share.len() * laws.len()) as u64, "montecarlo");
    let results = montecarlo::run_indexed(base, &share, laws, threads, &|| bar.inc(1), stop)?;
    bar.finish_and_clear();
    Ok(results)
}

/// A shard's end: its runs written whole to `shard.bin` beside `runs.csv`.
fn finish_shard(
    base: &Scenario,
    shard: studies::shard::Shard,
    study: &studies::shard::Study,
    results: &[montecarlo::RunResult],
    out: &Path,
) -> Result<(), SimError> {
    studies::shard::write_shard(out, shard, study, results)?;
    println!(
        "Monte Carlo on `{}`: shard {} of {}, {} of {} runs x {} laws; wrote {}/{{runs.csv, {}}} (join the shards with --merge)",
        base.name,
        shard.index,
        shard.count,
        results.len() / study.laws.len().max(1),
        study.runs,
        study.laws.len(),
        out.display(),
        studies::shard::SHARD_FILE
    );
    Ok(())
}

/// `montecarlo --estimators`: the filters on the same runs.
pub(crate) fn estimator_study(
    base: &Scenario,
    samples: &[montecarlo::Sample],
    (estimators, initial_error, threads): (&[scenario::EstimatorKind], Option<f64>, Option<usize>),
    law: Law,
    out: &Path,
    stop: &StopFlag,
) -> Result<(), SimError> {
    use studies::estimator_study as study;
    let bar = progress((samples.len() * estimators.len()) as u64, "estimators");
    let results = study::run_study(
        base,
        samples,
        estimators,
        law,
        initial_error,
        threads,
        &|| bar.inc(1),
        stop,
    )?;
    bar.finish_and_clear();
    if let Some(sig) = stop.requested() {
        eprintln!(
            "{sig}: stopped after {} of {} runs",
            results.len(),
            samples.len() * estimators.len()
        );
        return Err(SimError::Interrupted(sig));
    }
    let stats = study::stats(&results, estimators);
    write_json(&stats, &out.join("summary.json"))?;
    study::write(&results, &stats, estimators, base.control_period, out)?;
    println!(
        "Estimators on `{}` with {}: {} runs each, T = {} s{}",
        base.name,
        law.name(),
        samples.len(),
        base.duration,
        initial_error.map_or(String::new(), |e| format!(", filters started {e} rad off"))
    );
    print!("{}", study::table(&stats));
    println!(
        "wrote {}/{{estimators.csv, estimators.md, nees.csv, summary.json, estimators.png, estimators.svg}}",
        out.display()
    );
    Ok(())
}
