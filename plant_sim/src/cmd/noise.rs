//! `plant_sim noise`: the sensor-noise study.

use clap::Args;
use plant::SimError;
use plant::output::ensure_dir;
use scenario::Scenario;
use std::path::{Path, PathBuf};

#[derive(Args)]
pub(crate) struct NoiseArgs {
    /// Scenario with [sensors] and a complementary [estimator].
    #[arg(
        long,
        value_name = "FILE",
        default_value = "scenarios/sensors_so3.toml"
    )]
    scenario: PathBuf,
    /// Gyro noise densities to compare (rad/s/√Hz), comma-separated.
    #[arg(
        long,
        value_name = "LIST",
        default_value = "0.002,0.02,0.1",
        value_delimiter = ','
    )]
    gyro_noise: Vec<f64>,
    /// Seeded runs per configuration (sensor seeds 1..=N).
    #[arg(long, value_name = "N", default_value_t = 10)]
    runs: usize,
    /// Output directory; default out/noise.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

pub(crate) fn noise_cmd(args: NoiseArgs) -> Result<(), SimError> {
    let base = Scenario::from_file(&args.scenario)?;
    let out = args.out.unwrap_or_else(|| Path::new("out").join("noise"));
    ensure_dir(&out)?;
    let rows = studies::noise::study(&base, &args.gyro_noise, args.runs)?;
    studies::noise::write(&rows, &base.name, &out)?;
    print!("{}", studies::noise::table(&rows));
    println!(
        "wrote {}/{{noise.csv, table.md, noise.png, noise.svg}}",
        out.display()
    );
    Ok(())
}
