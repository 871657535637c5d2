//! `plant_sim bench-loop`: the loop benchmark against its floors.

use alloc_counter::thread_allocations;
use clap::Args;
use link::StopFlag;
use plant::SimError;
use scenario::cli::{ScenarioSource, positive_seconds};
use std::path::{Path, PathBuf};
use std::time::Duration;

#[derive(Args)]
pub(crate) struct BenchLoopArgs {
    #[command(flatten)]
    source: ScenarioSource,
    /// Loop rates to measure, comma-separated (Hz).
    #[arg(
        long,
        value_name = "LIST",
        default_value = "1000,10000",
        value_delimiter = ','
    )]
    rates: Vec<f64>,
    /// Seconds per case and rate.
    #[arg(long, value_name = "S", default_value = "5", value_parser = positive_seconds)]
    duration: Duration,
    /// Output directory; default out/bench-loop.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// The cyclictest program for the operating-system floor (Debian's rt-tests;
    /// `scripts/rt-tests.sh` fetches it and prints its path).
    #[arg(long, value_name = "PATH", default_value = "cyclictest")]
    cyclictest: PathBuf,
}

pub(crate) fn bench_loop_cmd(args: BenchLoopArgs, stop: &StopFlag) -> Result<(), SimError> {
    let rates = args.rates;
    if let Some(r) = rates
        .iter()
        .find(|x| !(x.is_finite() && **x > 0.0 && **x <= 100_000.0))
    {
        return Err(SimError::Input(format!(
            "--rates: `{r}` is not a rate in (0, 100000] Hz"
        )));
    }
    let out = args
        .out
        .unwrap_or_else(|| Path::new("out").join("bench-loop"));
    let result = floors::bench_loop::bench_loop(
        &args.source,
        &rates,
        args.duration.as_secs_f64(),
        &args.cyclictest,
        &out,
        Some(thread_allocations),
        stop,
    )?;
    println!(
        "round trip of the controller loop (state published -> command received), scenario {}:",
        result.scenario
    );
    print!("{}", floors::bench_loop::table(&result.cases));
    println!("\nthe floors, measured in the same run at the same rates and durations:");
    print!("{}", floors::bench_loop::floors_table(&result));
    println!(
        "wrote {}/{{summary.json, table.md}} and one run directory per case",
        out.display()
    );
    Ok(())
}
