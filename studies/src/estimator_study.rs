//! `plant_sim montecarlo --estimators …`: the filters compared on the same seeded runs
//! (docs/maths.md, "Consistency" and "The two filters compared"). Each run of the Monte Carlo
//! study (its own initial condition, sensor seed and gyro bias) is flown once per estimator —
//! truth-fed, complementary filter, EqF — with the same law; per run the RMS attitude and
//! bias estimate errors, the tracking error of the true state and, for the EqF, its NEES; over
//! the runs the EqF's average NEES at each tick against its 95 % χ² band, and with
//! `--initial-error` the time each filter takes to converge from that attitude error.

use crate::montecarlo::{
    Sample, fly_against, in_pool, initial_state, reference_table, run_sensors,
};
use eqtrack_controller::Law;
use eqtrack_controller::group::so3::{exp_so3, log_so3};
use nalgebra::Vector3;
use plant::SimError;
use plant::output::num;
use plant::plot::{Line, Panel, law_color, render};
use plotters::style::RGBColor;
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use scenario::{EstimatorKind, EstimatorSpec, Scenario};
use serde::Serialize;
use std::path::Path;

/// An estimate has converged once its attitude error stays below this (rad).
pub const CONVERGED: f64 = 0.1;

/// The dimension of the EqF's error, `(R, b)`: the NEES of a consistent filter is χ²(6).
pub const NEES_DOF: f64 = 6.0;

/// One run flown with one estimator.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyRun {
    /// The run (its sample, sensor seed and bias).
    pub run: usize,
    /// The estimator.
    pub estimator: EstimatorKind,
    /// RMS over time of the attitude estimate error (rad; 0 truth-fed).
    pub rms_estimate_error: f64,
    /// RMS over time of `|b̂ − b|` (rad/s; 0 truth-fed).
    pub rms_bias_error: f64,
    /// RMS over time of the tracking error `‖I − R_dᵀR‖_F` of the true state.
    pub rms_attitude_error: f64,
    /// `‖I − R_dᵀR‖_F` at t = T.
    pub final_attitude_error: f64,
    /// EqF: the NEES averaged over the run's ticks.
    pub mean_nees: Option<f64>,
    /// The time after which the attitude estimate error stays below [`CONVERGED`] (`None`:
    /// it does not by the end; 0 truth-fed).
    pub convergence_time: Option<f64>,
    /// Per tick: attitude estimate error, bias error, NEES (NaN where there is none).
    pub series: Vec<[f64; 3]>,
}

/// The scenario of one variant: `base` with the run's sensors and the estimator of `kind`
/// (the base's own gains and noise model), started `initial_error` rad away from the true
/// attitude about an axis drawn for the run when given.
fn variant(
    base: &Scenario,
    run: usize,
    sample: Sample,
    kind: EstimatorKind,
    initial_error: Option<f64>,
) -> Result<Scenario, SimError> {
    let mut s = base.clone();
    run_sensors(&mut s, run);
    if kind == EstimatorKind::Truth {
        s.estimator = EstimatorSpec::default();
        return Ok(s);
    }
    if kind == EstimatorKind::Eqf && s.estimator.eqf.is_none() {
        return Err(SimError::Input(format!(
            "scenario `{}`: the eqf variant takes its noise model from the scenario's \
             [estimator] kind = \"eqf\"",
            base.name
        )));
    }
    s.estimator.kind = kind;
    if let Some(e) = initial_error {
        let mut rng = ChaCha8Rng::seed_from_u64(0x5eed ^ run as u64);
        let axis: [f64; 3] = std::array::from_fn(|_| StandardNormal.sample(&mut rng));
        let axis = Vector3::from(axis).normalize();
        let (r0, _) = initial_state(&s, sample);
        let start = log_so3(&(r0 * exp_so3(&(axis * e))));
        s.estimator.initial_attitude = Some([start[0], start[1], start[2]]);
        if let Some(q) = s.estimator.eqf.as_mut() {
            q.initial_attitude_std = e;
        }
    }
    Ok(s)
}

fn rms(xs: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = xs.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    (sum / n.max(1) as f64).sqrt()
}

/// Flies every (run, estimator) pair with `law`; results ordered by run, then by the order
/// of `estimators`. Once `stop` is set, runs not yet started are skipped.
#[allow(clippy::too_many_arguments)]
pub fn run_study(
    base: &Scenario,
    samples: &[Sample],
    estimators: &[EstimatorKind],
    law: Law,
    initial_error: Option<f64>,
    threads: Option<usize>,
    on_done: &(dyn Fn() + Sync),
    stop: &link::StopFlag,
) -> Result<Vec<StudyRun>, SimError> {
    if base.group != eqtrack_controller::GroupKind::So3 {
        return Err(SimError::Input(format!(
            "scenario `{}`: the Monte Carlo study is defined on so3, not {}",
            base.name,
            base.group.name()
        )));
    }
    if base.sensors.is_none() {
        return Err(SimError::Input(format!(
            "scenario `{}`: --estimators compares filters on the scenario's [sensors]; it has none",
            base.name
        )));
    }
    let Some(first) = samples.first() else {
        return Err(SimError::Input("no samples to fly".to_owned()));
    };
    if let Some(e) = initial_error
        && !(e.is_finite() && e > 0.0 && e < std::f64::consts::PI)
    {
        return Err(SimError::Input(format!(
            "--initial-error: `{e}` is not an angle in (0, π) rad"
        )));
    }
    let mut base = base.clone();
    base.law = law;
    // every variant is checked before any runs
    for kind in estimators {
        variant(&base, 0, *first, *kind, initial_error)?;
    }
    let jobs: Vec<(usize, EstimatorKind)> = (0..samples.len())
        .flat_map(|i| estimators.iter().map(move |k| (i, *k)))
        .collect();
    let table = reference_table(&base)?;
    let work = || {
        jobs.par_iter()
            .map(|&(run, kind)| {
                if stop.requested().is_some() {
                    return Ok(None);
                }
                let s = variant(&base, run, samples[run], kind, initial_error)?;
                let t = fly_against(&s, &table, run, samples[run])?;
                on_done();
                let series: Vec<[f64; 3]> = t
                    .rows
                    .iter()
                    .map(|r| match &r.estimate {
                        Some(e) if kind != EstimatorKind::Truth => {
                            let b = Vector3::from(e.bias_hat) - e.samples.bias;
                            [e.estimate_error, b.norm(), e.nees.unwrap_or(f64::NAN)]
                        }
                        _ => [0.0, 0.0, f64::NAN],
                    })
                    .collect();
                let h = t.control_period;
                // NaN counts as not converged
                let last_above = series
                    .iter()
                    .rposition(|x| x[0] >= CONVERGED || x[0].is_nan());
                let convergence_time = match last_above {
                    None => Some(0.0),
                    Some(k) if k + 1 < series.len() => Some((k + 1) as f64 * h),
                    Some(_) => None,
                };
                Ok(Some(StudyRun {
                    run,
                    estimator: kind,
                    rms_estimate_error: rms(series.iter().map(|x| x[0])),
                    rms_bias_error: rms(series.iter().map(|x| x[1])),
                    rms_attitude_error: rms(t.rows.iter().map(|r| r.attitude_error)),
                    final_attitude_error: t.rows.last().map_or(f64::NAN, |r| r.attitude_error),
                    mean_nees: t.estimator.as_ref().and_then(|e| e.mean_nees),
                    convergence_time,
                    series,
                }))
            })
            .collect::<Result<Vec<_>, SimError>>()
            .map(|runs| runs.into_iter().flatten().collect())
    };
    in_pool(threads, work)
}

/// The two-sided 95 % band of the mean of `runs` independent χ²(`dof`) variables, by the
/// Wilson–Hilferty approximation `χ²_p(k) ≈ k (1 − 2/(9k) + z_p √(2/(9k)))³`, `k = dof·runs`
/// (docs/maths.md, "Consistency").
pub fn chi2_band(dof: f64, runs: usize) -> (f64, f64) {
    let n = runs.max(1) as f64;
    let k = dof * n;
    let q = |z: f64| k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3) / n;
    (q(-1.959_963_984_540_054), q(1.959_963_984_540_054))
}

/// One estimator's figures over the runs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EstimatorStats {
    /// `truth`, `complementary` or `eqf`.
    pub estimator: String,
    /// Runs.
    pub runs: usize,
    /// Mean over runs of the RMS attitude estimate error (rad).
    pub rms_estimate_error: f64,
    /// Mean over runs of the RMS bias error (rad/s).
    pub rms_bias_error: f64,
    /// Mean over runs of the RMS tracking error `‖I − R_dᵀR‖_F`.
    pub rms_attitude_error: f64,
    /// Mean over runs of the final tracking error.
    pub final_attitude_error: f64,
    /// EqF: the NEES averaged over ticks and runs.
    pub mean_nees: Option<f64>,
    /// EqF: the 95 % band of the per-tick average NEES over the runs.
    pub nees_band: Option<(f64, f64)>,
    /// EqF: the fraction of ticks whose run-averaged NEES lies inside the band.
    pub nees_inside: Option<f64>,
    /// Runs whose estimate converged (error below [`CONVERGED`] to the end).
    pub converged: usize,
    /// Median convergence time of those (s).
    pub median_convergence_time: Option<f64>,
    /// Longest convergence time of those (s).
    pub max_convergence_time: Option<f64>,
}

/// The run-averaged NEES at each tick (EqF runs only).
pub fn nees_series(results: &[StudyRun]) -> Vec<f64> {
    let runs: Vec<&StudyRun> = results
        .iter()
        .filter(|r| r.estimator == EstimatorKind::Eqf)
        .collect();
    let len = runs.iter().map(|r| r.series.len()).min().unwrap_or(0);
    (0..len)
        .map(|k| {
            let xs: Vec<f64> = runs
                .iter()
                .map(|r| r.series[k][2])
                .filter(|x| x.is_finite())
                .collect();
            xs.iter().sum::<f64>() / xs.len().max(1) as f64
        })
        .collect()
}

/// Per-estimator figures, in the order of `estimators`.
pub fn stats(results: &[StudyRun], estimators: &[EstimatorKind]) -> Vec<EstimatorStats> {
    let nees = nees_series(results);
    estimators
        .iter()
        .map(|kind| {
            let runs: Vec<&StudyRun> = results.iter().filter(|r| r.estimator == *kind).collect();
            let n = runs.len().max(1) as f64;
            let mean = |f: fn(&StudyRun) -> f64| runs.iter().map(|r| f(r)).sum::<f64>() / n;
            let mut times: Vec<f64> = runs.iter().filter_map(|r| r.convergence_time).collect();
            times.sort_by(f64::total_cmp);
            let eqf = *kind == EstimatorKind::Eqf;
            let band = eqf.then(|| chi2_band(NEES_DOF, runs.len()));
            EstimatorStats {
                estimator: kind.name().to_owned(),
                runs: runs.len(),
                rms_estimate_error: mean(|r| r.rms_estimate_error),
                rms_bias_error: mean(|r| r.rms_bias_error),
                rms_attitude_error: mean(|r| r.rms_attitude_error),
                final_attitude_error: mean(|r| r.final_attitude_error),
                mean_nees: eqf.then(|| nees.iter().sum::<f64>() / nees.len().max(1) as f64),
                nees_band: band,
                nees_inside: band.map(|(lo, hi)| {
                    nees.iter().filter(|x| lo <= **x && **x <= hi).count() as f64
                        / nees.len().max(1) as f64
                }),
                converged: times.len(),
                median_convergence_time: times.get(times.len() / 2).copied(),
                max_convergence_time: times.last().copied(),
            }
        })
        .collect()
}

/// The figures as a Markdown table.
pub fn table(stats: &[EstimatorStats]) -> String {
    let opt = |x: Option<f64>, p: usize| x.map_or("—".to_owned(), |x| format!("{x:.p$}"));
    let mut s = String::from(
        "| fed by | runs | RMS attitude estimate error (rad) | RMS bias error (rad/s) | RMS ‖I − R_dᵀR‖_F | final ‖I − R_dᵀR‖_F | mean NEES (95 % band) | converged | median / max convergence (s) |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for l in stats {
        let nees = match (l.mean_nees, l.nees_band) {
            (Some(m), Some((lo, hi))) => format!("{m:.2} ({lo:.2} – {hi:.2})"),
            _ => "—".to_owned(),
        };
        let filtered = |x: f64| {
            if l.estimator == "truth" {
                "—".to_owned()
            } else {
                format!("{x:.2e}")
            }
        };
        s += &format!(
            "| {} | {} | {} | {} | {:.4} | {:.2e} | {} | {}/{} | {} / {} |\n",
            l.estimator,
            l.runs,
            filtered(l.rms_estimate_error),
            filtered(l.rms_bias_error),
            l.rms_attitude_error,
            l.final_attitude_error,
            nees,
            l.converged,
            l.runs,
            opt(l.median_convergence_time, 2),
            opt(l.max_convergence_time, 2),
        );
    }
    s
}

/// Writes `estimators.csv` (per run), `nees.csv` (the EqF's run-averaged NEES per tick with
/// its band), `estimators.md` (the table) and the figure `estimators.{png,svg}`.
pub fn write(
    results: &[StudyRun],
    stats: &[EstimatorStats],
    estimators: &[EstimatorKind],
    control_period: f64,
    out: &Path,
) -> Result<(), SimError> {
    let fail = |e: std::io::Error| SimError::Run(format!("cannot write {}: {e}", out.display()));
    std::fs::write(out.join("estimators.csv"), runs_csv(results)).map_err(fail)?;
    std::fs::write(out.join("estimators.md"), table(stats)).map_err(fail)?;
    let nees = nees_series(results);
    let band = stats.iter().find_map(|s| s.nees_band);
    if let Some((lo, hi)) = band {
        let mut csv = String::from("t,mean_nees,band_low,band_high\n");
        for (k, x) in nees.iter().enumerate() {
            csv += &format!(
                "{},{},{},{}\n",
                num(k as f64 * control_period),
                num(*x),
                num(lo),
                num(hi)
            );
        }
        std::fs::write(out.join("nees.csv"), csv).map_err(fail)?;
    }
    let filters: Vec<EstimatorKind> = estimators
        .iter()
        .copied()
        .filter(|k| *k != EstimatorKind::Truth)
        .collect();
    let error_panel = |title: &str, y: &str, q: usize| Panel {
        title: title.to_owned(),
        y_label: y.to_owned(),
        lines: filters
            .iter()
            .map(|k| Line {
                label: k.name().to_owned(),
                color: estimator_color(*k),
                points: over_runs(results, *k, q, control_period),
            })
            .collect(),
    };
    let mut panels = vec![
        error_panel("Attitude estimate error, RMS over runs", "error [rad]", 0),
        error_panel("Gyro bias error |b̂ − b|, RMS over runs", "[rad/s]", 1),
    ];
    if let Some(band) = band {
        panels.push(nees_panel(&nees, band, control_period));
    }
    let runs = stats.first().map_or(0, |s| s.runs);
    render(
        &out.join("estimators"),
        &format!("The filters on the same {runs} seeded runs"),
        &panels,
        1,
        (1000, 350 * panels.len() as u32 + 50),
    )
}

/// `estimators.csv`: one line per run and estimator.
fn runs_csv(results: &[StudyRun]) -> String {
    let mut csv = String::from(
        "run,estimator,rms_estimate_error,rms_bias_error,rms_attitude_error,final_attitude_error,mean_nees,convergence_time\n",
    );
    let opt = |x: Option<f64>| x.map(num).unwrap_or_default();
    for r in results {
        csv += &format!(
            "{},{},{},{},{},{},{},{}\n",
            r.run,
            r.estimator.name(),
            num(r.rms_estimate_error),
            num(r.rms_bias_error),
            num(r.rms_attitude_error),
            num(r.final_attitude_error),
            opt(r.mean_nees),
            opt(r.convergence_time)
        );
    }
    csv
}

/// Each estimator's colour in the figure.
fn estimator_color(k: EstimatorKind) -> RGBColor {
    match k {
        EstimatorKind::Truth => law_color("eqt"),
        EstimatorKind::Complementary => law_color("gt"),
        EstimatorKind::Eqf => law_color("nog"),
    }
}

/// Per tick, the RMS over the runs of estimator `kind` of error `q` (0: attitude, 1: bias).
fn over_runs(
    results: &[StudyRun],
    kind: EstimatorKind,
    q: usize,
    control_period: f64,
) -> Vec<(f64, f64)> {
    let runs: Vec<&StudyRun> = results.iter().filter(|r| r.estimator == kind).collect();
    let len = runs.iter().map(|r| r.series.len()).min().unwrap_or(0);
    (0..len)
        .map(|k| {
            let ms =
                runs.iter().map(|r| r.series[k][q].powi(2)).sum::<f64>() / runs.len().max(1) as f64;
            (k as f64 * control_period, ms.sqrt())
        })
        .collect()
}

/// The EqF's run-averaged NEES per tick with its 95 % χ² band `(lo, hi)`.
fn nees_panel(nees: &[f64], (lo, hi): (f64, f64), control_period: f64) -> Panel {
    let t = |k: usize| k as f64 * control_period;
    let flat = |v: f64| vec![(0.0, v), (t(nees.len().saturating_sub(1)), v)];
    // a start far off makes the first ticks' NEES thousands: drawn clipped, so the band
    // stays readable
    let top = 3.0 * hi;
    let clipped = nees.iter().any(|x| *x > top);
    Panel {
        title: format!(
            "EqF: NEES averaged over the runs, with its 95 % χ² band{}",
            if clipped {
                format!(" (drawn clipped at {top:.0})")
            } else {
                String::new()
            }
        ),
        y_label: "NEES".to_owned(),
        lines: vec![
            Line {
                label: "mean NEES".to_owned(),
                color: estimator_color(EstimatorKind::Eqf),
                points: nees
                    .iter()
                    .enumerate()
                    .map(|(k, x)| (t(k), x.min(top)))
                    .collect(),
            },
            Line {
                label: format!("band {lo:.2} – {hi:.2}"),
                color: law_color("asym"),
                points: flat(lo),
            },
            Line {
                label: String::new(),
                color: law_color("asym"),
                points: flat(hi),
            },
        ],
    }
}
