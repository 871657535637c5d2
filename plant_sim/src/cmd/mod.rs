//! The subcommands of `plant_sim`, one module each: its arguments and its handler.

use indicatif::{ProgressBar, ProgressStyle};
#[cfg(feature = "fault-injection")]
use plant::SimError;

pub(crate) mod bench_loop;
pub(crate) mod export;
pub(crate) mod frames;
pub(crate) mod live;
pub(crate) mod monitor;
pub(crate) mod montecarlo;
pub(crate) mod moved;
pub(crate) mod noise;
pub(crate) mod param;
pub(crate) mod pil;
pub(crate) mod reference;
pub(crate) mod rejection;
pub(crate) mod replay;
pub(crate) mod run;
pub(crate) mod sim;

pub(crate) fn progress(len: u64, what: &str) -> ProgressBar {
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

/// One in-process flight of `s` with the planted sample faults, its progress shown as `label`
/// and the stop flag checked every 256 steps (`sim`, and both flights of `move --check`).
pub(crate) fn simulate_shown(
    s: &scenario::Scenario,
    planted: &[(u64, plant::sensors::SampleFault)],
    label: &str,
    stop: &link::StopFlag,
) -> Result<plant::trajectory::SimulatedTrajectory, plant::SimError> {
    let bar = progress(s.steps() + 1, label);
    let traj = plant::trajectory::simulate_planted(s, planted, &|k| {
        if k % 256 == 0 {
            bar.set_position(k);
            plant::SimError::check(stop)?;
        }
        Ok(())
    })?;
    bar.finish_and_clear();
    Ok(traj)
}

/// The `--fault-sample K:KIND` injections (test builds only).
#[cfg(feature = "fault-injection")]
pub(crate) fn sample_faults(
    texts: &[String],
) -> Result<Vec<(u64, plant::sensors::SampleFault)>, SimError> {
    texts
        .iter()
        .map(|text| {
            let bad = || {
                SimError::Input(format!(
                    "--fault-sample: expected K:gyro-nan|gyro-inf|gyro-spike|dir-nan|dir-inf|dir-zero|accel-far|pos-scaled, got `{text}`"
                ))
            };
            let (k, kind) = text.split_once(':').ok_or_else(bad)?;
            let k: u64 = k.parse().map_err(|_| bad())?;
            let kind = plant::sensors::SampleFault::parse(kind).ok_or_else(bad)?;
            Ok((k, kind))
        })
        .collect()
}
