//! The extended paper's Monte Carlo study (its Figure 3; docs/maths.md, "The simulations").
//!
//! Each run starts at `R(0) = R_d(0)·exp(hat(r))`, `ω(0) = ω_d(0) + w`. Drawn samples take
//! `R = Rz(θ)Ry(φ)Rx(ψ)` with the Euler angles uniform on [−π, π] and `r = log(R)`, and
//! `w ~ N(0, 1)` per axis, all from one ChaCha8 stream seeded with `--seed` in run order, so
//! the numbers do not depend on the thread count.

use eqtrack_controller::group::So3;
use eqtrack_controller::group::so3::{exp_so3, log_so3};
use eqtrack_controller::integrator::RigidBody;
use eqtrack_controller::law::Desired;
use eqtrack_controller::reference::Tabulated;
use eqtrack_controller::{GroupKind, Law};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use plant::SimError;
use plant::output::num;
use plant::plot::{Line, Panel, law_color, render};
use plant::trajectory::{effort, settling_time, simulate_against};
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal, Uniform};
use rayon::prelude::*;
use scenario::Scenario;
use serde::Serialize;
use std::path::Path;

/// One initial condition: rotation offset `r` and velocity offset `w`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// `R(0) = R_d(0)·exp(hat(r))`.
    pub r: [f64; 3],
    /// `ω(0) = ω_d(0) + w`.
    pub w: [f64; 3],
}

/// `Rz(θ) Ry(φ) Rx(ψ)`.
pub fn euler_zyx(theta: f64, phi: f64, psi: f64) -> Matrix3<f64> {
    exp_so3(&Vector3::new(0.0, 0.0, theta))
        * exp_so3(&Vector3::new(0.0, phi, 0.0))
        * exp_so3(&Vector3::new(psi, 0.0, 0.0))
}

/// Draws `runs` samples from the stream seeded with `seed`.
pub fn draw_samples(runs: usize, seed: u64) -> Vec<Sample> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // [−π, π) is a valid, non-empty range: `new` cannot fail here.
    let angle = Uniform::new(-std::f64::consts::PI, std::f64::consts::PI).expect("valid range");
    (0..runs)
        .map(|_| {
            let (t, f, p) = (
                angle.sample(&mut rng),
                angle.sample(&mut rng),
                angle.sample(&mut rng),
            );
            let r = log_so3(&euler_zyx(t, f, p));
            let w: [f64; 3] = std::array::from_fn(|_| StandardNormal.sample(&mut rng));
            Sample {
                r: [r[0], r[1], r[2]],
                w,
            }
        })
        .collect()
}

/// Reads samples from a CSV file with header `rx,ry,rz,wx,wy,wz`.
pub fn read_samples(path: &Path) -> Result<Vec<Sample>, SimError> {
    let where_ = path.display().to_string();
    let bad = |m: String| SimError::Input(format!("samples file {where_}: {m}"));
    let mut rd = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_path(path)
        .map_err(|e| bad(e.to_string()))?;
    let header: Vec<String> = rd
        .headers()
        .map_err(|e| bad(e.to_string()))?
        .iter()
        .map(str::to_owned)
        .collect();
    if header != ["rx", "ry", "rz", "wx", "wy", "wz"] {
        return Err(bad(format!(
            "header must be rx,ry,rz,wx,wy,wz, got {}",
            header.join(",")
        )));
    }
    let mut out = Vec::new();
    for (i, rec) in rd.records().enumerate() {
        let line = i + 2;
        let rec = rec.map_err(|e| bad(format!("line {line}: {e}")))?;
        let mut v = [0.0; 6];
        for (j, cell) in rec.iter().enumerate() {
            let x: f64 = cell.parse().map_err(|_| {
                bad(format!(
                    "line {line}, column {}: `{cell}` is not a number",
                    header[j]
                ))
            })?;
            if !x.is_finite() {
                return Err(bad(format!(
                    "line {line}, column {}: not a finite number",
                    header[j]
                )));
            }
            v[j] = x;
        }
        out.push(Sample {
            r: [v[0], v[1], v[2]],
            w: [v[3], v[4], v[5]],
        });
    }
    if out.is_empty() {
        return Err(bad("no samples".to_owned()));
    }
    Ok(out)
}

/// What one run of one law produced.
#[derive(Debug, Clone, PartialEq)]
pub struct RunResult {
    /// Sample index.
    pub run: usize,
    /// Law.
    pub law: Law,
    /// Initial condition.
    pub sample: Sample,
    /// `‖I − R_dᵀR‖_F` at t = T.
    pub final_attitude_error: f64,
    /// `Σ_{t_k < 5} ‖τ_k‖·h`.
    pub effort_0_5: f64,
    /// `Σ_{t_k < 20} ‖τ_k‖·h`.
    pub effort_0_20: f64,
    /// First time after which attitude_error stays below 0.1.
    pub settling_time: Option<f64>,
    /// Per step: attitude error, velocity error, torque norm, L.
    pub series: Vec<[f64; 4]>,
}

/// Runs every (sample, law) pair; results ordered by run, then by the order of `laws`. Once
/// `stop` is set, runs not yet started are skipped: the result holds the runs that finished
/// (check the flag afterwards).
pub fn run_all(
    base: &Scenario,
    samples: &[Sample],
    laws: &[Law],
    threads: Option<usize>,
    on_done: &(dyn Fn() + Sync),
    stop: &link::StopFlag,
) -> Result<Vec<RunResult>, SimError> {
    let indexed: Vec<(usize, Sample)> = samples.iter().copied().enumerate().collect();
    run_indexed(base, &indexed, laws, threads, on_done, stop)
}

/// [`run_all`] on the runs `(index, sample)` given (a shard of the study: each run keeps its
/// index, so its sensors and its place in the merged study are those of the whole study).
pub fn run_indexed(
    base: &Scenario,
    samples: &[(usize, Sample)],
    laws: &[Law],
    threads: Option<usize>,
    on_done: &(dyn Fn() + Sync),
    stop: &link::StopFlag,
) -> Result<Vec<RunResult>, SimError> {
    if base.group != GroupKind::So3 {
        return Err(SimError::Input(format!(
            "scenario `{}`: the Monte Carlo study is defined on so3, not {}",
            base.name,
            base.group.name()
        )));
    }
    for law in laws {
        base.clone().with_law(*law)?;
    }
    // The reference is the same for every run and law: integrated once, replayed by each.
    let table = reference_table(base)?;
    let jobs: Vec<(usize, Sample, Law)> = samples
        .iter()
        .flat_map(|(i, sample)| laws.iter().map(move |l| (*i, *sample, *l)))
        .collect();
    let work = || {
        jobs.par_iter()
            .map(|(i, sample, law)| {
                if stop.requested().is_some() {
                    return Ok(None);
                }
                let r = one_run(base, &table, *i, *sample, *law);
                on_done();
                r.map(Some)
            })
            .collect::<Result<Vec<_>, _>>()
            .map(|runs| runs.into_iter().flatten().collect())
    };
    in_pool(threads, work)
}

/// Runs `work` on `threads` worker threads (`None`: rayon's global pool, one per core).
pub fn in_pool<R: Send>(
    threads: Option<usize>,
    work: impl FnOnce() -> Result<R, SimError> + Send,
) -> Result<R, SimError> {
    match threads {
        None => work(),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map_err(|e| SimError::Run(format!("cannot start {n} threads: {e}")))?
            .install(work),
    }
}

/// A run's own sensors, when the scenario has `[sensors]`: the sensor seed and the gyro bias
/// are drawn from a ChaCha8 stream seeded with the scenario's sensor seed and the run index
/// (so they do not depend on the thread count): each bias component from `N(0, b_i²)`, `b_i`
/// the scenario's component, then the seed of the run's sensor stream.
pub fn run_sensors(s: &mut Scenario, run: usize) {
    if let Some(sp) = s.sensors.as_mut() {
        let mut rng = ChaCha8Rng::seed_from_u64(
            sp.seed ^ (run as u64 + 1).wrapping_mul(0x9e37_79b9_7f4a_7c15),
        );
        for b in sp.gyro.bias.iter_mut() {
            let n: f64 = StandardNormal.sample(&mut rng);
            *b *= n;
        }
        sp.seed = rand_chacha::rand_core::Rng::next_u64(&mut rng);
    }
}

/// The scenario's desired trajectory at `t_0 … t_N`, integrated once (what every run of a
/// study replays through [`Tabulated`]).
pub fn reference_table(s: &Scenario) -> Result<Vec<Desired<f64, 3, 3>>, SimError> {
    let mut source = s
        .reference_source::<So3, 3, 3>()
        .map_err(plant::trajectory::input(s))?;
    let mut table = Vec::with_capacity(s.steps() as usize + 1);
    Tabulated::record(&mut source, s.steps() as usize, &mut table);
    Ok(table)
}

/// Run `run` of the study on `s` (its sensors already the run's): the body starts at
/// `R(0) = R_d(0)·exp(hat(r))`, `ω(0) = ω_d(0) + w` and the closed loop is simulated.
pub fn fly(
    s: &Scenario,
    run: usize,
    sample: Sample,
) -> Result<plant::trajectory::SimulatedTrajectory, SimError> {
    fly_against(s, &reference_table(s)?, run, sample)
}

/// [`fly`] against the scenario's reference recorded once by [`reference_table`] (the same
/// numbers, without integrating the reference again).
pub fn fly_against(
    s: &Scenario,
    table: &[Desired<f64, 3, 3>],
    run: usize,
    sample: Sample,
) -> Result<plant::trajectory::SimulatedTrajectory, SimError> {
    let (r0, w0) = initial_state(s, sample);
    let plant = RigidBody::<f64, So3, 3, 3>::new(
        SMatrix::from_row_slice(&crate::study_inertia(s)),
        r0,
        SVector::from(w0),
    )
    .map_err(|e| SimError::Input(format!("run {run}: {e}")))?;
    let reference = Tabulated::new(table, s.control_period).map_err(plant::trajectory::input(s))?;
    simulate_against::<So3, 3, 3, _>(s, plant, reference, &[], &|_| Ok(()))
        .map_err(|e| SimError::Run(format!("run {run}, law {}: {e}", s.law.name())))
}

/// The initial attitude and rate of a sample: `R_d(0)·exp(hat(r))`, `ω_d(0) + w`.
pub fn initial_state(s: &Scenario, sample: Sample) -> (Matrix3<f64>, Vector3<f64>) {
    let r_d0: SMatrix<f64, 3, 3> = Scenario::configuration::<3>(&s.reference);
    let w_d0 = Vector3::from_row_slice(&s.reference.velocity);
    (
        r_d0 * exp_so3(&Vector3::from(sample.r)),
        w_d0 + Vector3::from(sample.w),
    )
}

fn one_run(
    base: &Scenario,
    table: &[Desired<f64, 3, 3>],
    run: usize,
    sample: Sample,
    law: Law,
) -> Result<RunResult, SimError> {
    let mut s = base.clone();
    s.law = law;
    run_sensors(&mut s, run);
    let traj = fly_against(&s, table, run, sample)?;
    let h = traj.control_period;
    Ok(RunResult {
        run,
        law,
        sample,
        final_attitude_error: traj
            .rows
            .last()
            .map(|r| r.attitude_error)
            .unwrap_or(f64::NAN),
        effort_0_5: effort(&traj.rows, h, 5.0),
        effort_0_20: effort(&traj.rows, h, 20.0),
        settling_time: settling_time(&traj.rows),
        series: traj
            .rows
            .iter()
            .map(|r| {
                [
                    r.attitude_error,
                    r.velocity_error,
                    r.torque_norm,
                    r.lyapunov,
                ]
            })
            .collect(),
    })
}

/// Writes `runs.csv`.
pub fn write_runs_csv(results: &[RunResult], path: &Path) -> Result<(), SimError> {
    let fail = |e: csv::Error| SimError::Run(format!("cannot write {}: {e}", path.display()));
    let mut w = csv::Writer::from_path(path).map_err(fail)?;
    w.write_record([
        "run",
        "law",
        "rx",
        "ry",
        "rz",
        "wx",
        "wy",
        "wz",
        "final_attitude_error",
        "effort_0_5",
        "effort_0_20",
        "settling_time",
    ])
    .map_err(fail)?;
    for r in results {
        let mut rec = vec![r.run.to_string(), r.law.name().to_owned()];
        rec.extend(r.sample.r.iter().chain(r.sample.w.iter()).map(|x| num(*x)));
        rec.push(num(r.final_attitude_error));
        rec.push(num(r.effort_0_5));
        rec.push(num(r.effort_0_20));
        rec.push(r.settling_time.map(num).unwrap_or_default());
        w.write_record(&rec).map_err(fail)?;
    }
    w.flush()
        .map_err(|e| SimError::Run(format!("cannot write {}: {e}", path.display())))
}

/// Per-law means over runs, per step: attitude error, velocity error, torque norm, L.
pub fn means(results: &[RunResult], laws: &[Law]) -> Vec<Vec<[f64; 4]>> {
    laws.iter()
        .map(|law| {
            let runs: Vec<&RunResult> = results.iter().filter(|r| r.law == *law).collect();
            let len = runs.iter().map(|r| r.series.len()).min().unwrap_or(0);
            let n = runs.len().max(1) as f64;
            (0..len)
                .map(|k| {
                    let mut acc = [0.0; 4];
                    for r in &runs {
                        for (a, x) in acc.iter_mut().zip(r.series[k]) {
                            *a += x;
                        }
                    }
                    acc.map(|a| a / n)
                })
                .collect()
        })
        .collect()
}

/// Writes `mean.csv`: `t` and `<law>_attitude_error, <law>_velocity_error,
/// <law>_torque_norm, <law>_lyapunov` per law.
pub fn write_mean_csv(
    mean: &[Vec<[f64; 4]>],
    laws: &[Law],
    control_period: f64,
    path: &Path,
) -> Result<(), SimError> {
    let fail = |e: csv::Error| SimError::Run(format!("cannot write {}: {e}", path.display()));
    let mut w = csv::Writer::from_path(path).map_err(fail)?;
    let mut header = vec!["t".to_owned()];
    for l in laws {
        for q in [
            "attitude_error",
            "velocity_error",
            "torque_norm",
            "lyapunov",
        ] {
            header.push(format!("{}_{q}", l.name()));
        }
    }
    w.write_record(&header).map_err(fail)?;
    let len = mean.iter().map(Vec::len).min().unwrap_or(0);
    for k in 0..len {
        let mut rec = vec![num(k as f64 * control_period)];
        for m in mean {
            rec.extend(m[k].iter().map(|x| num(*x)));
        }
        w.write_record(&rec).map_err(fail)?;
    }
    w.flush()
        .map_err(|e| SimError::Run(format!("cannot write {}: {e}", path.display())))
}

/// The comparison of one law over all runs.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct LawStats {
    /// Law name.
    pub law: String,
    /// Number of runs.
    pub runs: usize,
    /// Mean final attitude error.
    pub mean_final_attitude_error: f64,
    /// Largest final attitude error.
    pub max_final_attitude_error: f64,
    /// Mean effort over [0, 5 s).
    pub mean_effort_0_5: f64,
    /// Mean effort over [0, 20 s).
    pub mean_effort_0_20: f64,
    /// Runs that settled (attitude error below 0.1 for good).
    pub settled: usize,
    /// Mean settling time over the settled runs.
    pub mean_settling_time: Option<f64>,
    /// Median settling time over the settled runs.
    pub median_settling_time: Option<f64>,
}

/// Computes the comparison table.
pub fn stats(results: &[RunResult], laws: &[Law]) -> Vec<LawStats> {
    laws.iter()
        .map(|law| {
            let rs: Vec<&RunResult> = results.iter().filter(|r| r.law == *law).collect();
            let n = rs.len().max(1) as f64;
            let mean = |f: fn(&RunResult) -> f64| rs.iter().map(|r| f(r)).sum::<f64>() / n;
            let mut settle: Vec<f64> = rs.iter().filter_map(|r| r.settling_time).collect();
            settle.sort_by(f64::total_cmp);
            LawStats {
                law: law.name().to_owned(),
                runs: rs.len(),
                mean_final_attitude_error: mean(|r| r.final_attitude_error),
                max_final_attitude_error: rs
                    .iter()
                    .map(|r| r.final_attitude_error)
                    .fold(0.0, f64::max),
                mean_effort_0_5: mean(|r| r.effort_0_5),
                mean_effort_0_20: mean(|r| r.effort_0_20),
                settled: settle.len(),
                mean_settling_time: (!settle.is_empty())
                    .then(|| settle.iter().sum::<f64>() / settle.len() as f64),
                median_settling_time: (!settle.is_empty()).then(|| settle[settle.len() / 2]),
            }
        })
        .collect()
}

/// The comparison table as text.
pub fn table(stats: &[LawStats]) -> String {
    let opt = |x: Option<f64>| {
        x.map(|v| format!("{v:.2}"))
            .unwrap_or_else(|| "-".to_owned())
    };
    let mut s = format!(
        "{:<6} {:>5} {:>12} {:>12} {:>12} {:>12} {:>9} {:>11} {:>11}\n",
        "law",
        "runs",
        "final att.",
        "max final",
        "effort 0-5",
        "effort 0-20",
        "settled",
        "mean settle",
        "med. settle"
    );
    for l in stats {
        s += &format!(
            "{:<6} {:>5} {:>12.3e} {:>12.3e} {:>12.3} {:>12.3} {:>9} {:>11} {:>11}\n",
            l.law,
            l.runs,
            l.mean_final_attitude_error,
            l.max_final_attitude_error,
            l.mean_effort_0_5,
            l.mean_effort_0_20,
            format!("{}/{}", l.settled, l.runs),
            opt(l.mean_settling_time),
            opt(l.median_settling_time),
        );
    }
    s
}

/// The four panels of the extended paper's Figure 3 from the per-law means.
pub fn figure(
    mean: &[Vec<[f64; 4]>],
    laws: &[Law],
    control_period: f64,
    runs: usize,
    stem: &Path,
) -> Result<(), SimError> {
    let titles = [
        ("Mean attitude error ‖I − R_dᵀR‖_F", "attitude error"),
        ("Mean angular velocity error ‖ω − ω_d‖", "‖ω − ω_d‖ [rad/s]"),
        ("Mean torque ‖τ‖", "‖τ‖ [N m]"),
        ("Mean Lyapunov function L", "L"),
    ];
    let panels: Vec<Panel> = titles
        .iter()
        .enumerate()
        .map(|(q, (title, y))| Panel {
            title: title.to_string(),
            y_label: y.to_string(),
            lines: laws
                .iter()
                .zip(mean)
                .map(|(l, m)| Line {
                    label: l.name().to_uppercase(),
                    color: law_color(l.name()),
                    points: m
                        .iter()
                        .enumerate()
                        .map(|(k, v)| (k as f64 * control_period, v[q]))
                        .collect(),
                })
                .collect(),
        })
        .collect();
    render(
        stem,
        &format!("Monte Carlo, {runs} runs per law"),
        &panels,
        2,
        (1500, 1050),
    )
}
