//! `plant_sim sim`: one scenario in process (the default command).

#[cfg(feature = "fault-injection")]
use super::sample_faults;
use super::simulate_shown;
use clap::Args;
use eqtrack_controller::Law;
use link::StopFlag;
use plant::SimError;
use plant::output::{Summary, ensure_dir, write_json, write_trajectory_csv};
use plant::plot::trajectory_figure;
use scenario::cli::{ScenarioSource, law_parser};
use std::path::{Path, PathBuf};

#[derive(Args, Default)]
pub(crate) struct SimArgs {
    #[command(flatten)]
    source: ScenarioSource,
    /// Override the scenario's law.
    #[arg(long, value_name = "L", value_parser = law_parser())]
    law: Option<Law>,
    /// Output directory (created if needed); default out/<scenario name>.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// The controller's scalar: f64 (the simulation), or f32: the processor-in-the-loop
    /// firmware's controller run in process, exactly as the firmware runs it (the plant of
    /// the pair in lockstep, the controller's frames through the serial protocol; the
    /// reference a processor-in-the-loop run must equal; docs/pil.md).
    #[arg(long, value_enum, value_name = "S", default_value_t = Scalar::F64)]
    controller_scalar: Scalar,
    /// Test builds only (feature `fault-injection`): K:KIND plants a bad sensor sample at
    /// tick K (gyro-nan, gyro-inf, gyro-spike, dir-nan, dir-inf, dir-zero, accel-far).
    #[cfg(feature = "fault-injection")]
    #[arg(long, value_name = "K:KIND", hide = true)]
    fault_sample: Vec<String>,
}

/// The controller's scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub(crate) enum Scalar {
    /// Double precision, in process.
    #[default]
    F64,
    /// Single precision, as the processor-in-the-loop firmware.
    F32,
}

pub(crate) fn sim(args: SimArgs, stop: &StopFlag) -> Result<(), SimError> {
    let mut s = args.source.load("seed")?;
    if let Some(l) = args.law {
        s = s.with_law(l)?;
    }
    if args.controller_scalar == Scalar::F32 {
        return super::pil::sim_f32(s, &args.source, args.out, stop);
    }
    let out = args.out.unwrap_or_else(|| Path::new("out").join(&s.name));
    ensure_dir(&out)?;
    // before the flight, so that a run the warning explains still shows it when it fails
    plant::trajectory::warn_world_frame(&s, s.steps());
    #[cfg(feature = "fault-injection")]
    let planted = sample_faults(&args.fault_sample)?;
    #[cfg(not(feature = "fault-injection"))]
    let planted = Vec::new();
    let traj = simulate_shown(&s, &planted, &format!("sim {}", s.name), stop)?;
    write_trajectory_csv(&traj, &out.join("trajectory.csv"))?;
    let summary = Summary::of(&traj, &s.name, s.law.name()).with_error_frame(&s);
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
        s.law_label(),
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
    for line in traj.vehicle.iter().flat_map(|v| v.detection_lines()) {
        println!("{line}");
    }
    for t in traj.failsafe.iter().flat_map(|f| f.transitions()) {
        println!("{}", t.line());
    }
    println!(
        "wrote {}/{{trajectory.csv, summary.json, figure.png, figure.svg}}",
        out.display()
    );
    diverged(&traj, &out)
}

/// Exit 1 for a run whose state, torque or Lyapunov value stopped being finite (its outputs
/// in `out` are written): a run that diverged never ends as if it had flown.
pub(crate) fn diverged(
    traj: &plant::trajectory::SimulatedTrajectory,
    out: &Path,
) -> Result<(), SimError> {
    if let Some(t) = plant::trajectory::first_non_finite(traj) {
        return Err(SimError::Run(format!(
            "the run diverged: its state is not finite from t = {t} s (its outputs are in {})",
            out.display()
        )));
    }
    // `[failsafe] tracking`: the error passed its limit, which latches
    match traj.failsafe.as_ref().and_then(|f| f.runaway()) {
        Some((t, errors)) => Err(SimError::Run(format!(
            "the tracking error passed its [failsafe] limit at t = {t} s{}: the run ran away (its outputs are in {})",
            errors
                .map(|(angle, distance)| format!(
                    " (attitude {angle:.4} rad, position {distance:.4} m)"
                ))
                .unwrap_or_default(),
            out.display()
        ))),
        None => Ok(()),
    }
}
