//! `plant_sim noise`: what sensor noise costs the loop (docs/maths.md, "What noise costs").
//! The scenario's sensors at several gyro noise densities, with its gyro bias and without,
//! flown truth-fed and complementary-filter-fed over seeded runs: the final and RMS tracking
//! error of the true state and the RMS estimate error, as a table, a CSV and a figure.

use plant::SimError;
use plant::output::num;
use plant::plot::{Line, Panel, law_color, render_against};
use plant::trajectory::simulate;
use rayon::prelude::*;
use scenario::{EstimatorKind, EstimatorSpec, Scenario};
use std::path::Path;

/// One configuration's figures, averaged over its runs.
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseRow {
    /// Gyro rate noise density (rad/s/√Hz).
    pub gyro_noise: f64,
    /// Whether the scenario's gyro bias was applied (else zero bias and no walk).
    pub bias: bool,
    /// `truth` or `complementary`.
    pub estimator: String,
    /// Runs averaged.
    pub runs: usize,
    /// Mean of `‖I − R_dᵀR‖_F` at t = T.
    pub final_attitude_error: f64,
    /// Mean over runs of the RMS over time of `‖I − R_dᵀR‖_F`.
    pub rms_attitude_error: f64,
    /// Mean over runs of the RMS estimate error (rad; 0 truth-fed).
    pub rms_estimate_error: f64,
}

/// Runs the study on `base` (which must have `[sensors]` and a filter in `[estimator]`,
/// complementary or EqF): for each gyro noise and bias on/off, `runs` sensor seeds
/// (1..=runs), truth-fed and filter-fed. The EqF's own gyro noise follows the study's, and
/// its bias walk is zero where the sensors' is (its noise model stays matched).
pub fn study(base: &Scenario, noises: &[f64], runs: usize) -> Result<Vec<NoiseRow>, SimError> {
    if base.sensors.is_none() || base.estimator.kind == EstimatorKind::Truth {
        return Err(SimError::Input(format!(
            "scenario `{}`: the noise study needs [sensors] and a filter in [estimator] \
             (kind = \"complementary\" or \"eqf\")",
            base.name
        )));
    }
    if runs == 0 || noises.is_empty() || noises.iter().any(|x| !x.is_finite() || *x < 0.0) {
        return Err(SimError::Input(
            "--runs must be at least 1 and --gyro-noise finite numbers ≥ 0".to_owned(),
        ));
    }
    let mut configs = Vec::new();
    for &noise in noises {
        for bias in [false, true] {
            for truth in [true, false] {
                configs.push((noise, bias, truth));
            }
        }
    }
    configs
        .par_iter()
        .map(|&(noise, bias, truth)| {
            let per_run: Vec<[f64; 3]> = (1..=runs as u64)
                .map(|seed| {
                    let mut s = base.clone();
                    if let Some(sp) = s.sensors.as_mut() {
                        sp.seed = seed;
                        sp.gyro.noise = noise;
                        if !bias {
                            sp.gyro.bias = [0.0; 3];
                            sp.gyro.bias_walk = 0.0;
                        }
                    }
                    if let Some(q) = s.estimator.eqf.as_mut() {
                        q.gyro_noise = noise;
                        if !bias {
                            q.bias_walk = 0.0;
                        }
                    }
                    if truth {
                        s.estimator = EstimatorSpec::default();
                    }
                    let t = simulate(&s, &|_| Ok(()))?;
                    let n = t.rows.len().max(1) as f64;
                    let rms =
                        (t.rows.iter().map(|r| r.attitude_error.powi(2)).sum::<f64>() / n).sqrt();
                    let est = t.estimator.as_ref().map_or(0.0, |e| e.rms_estimate_error);
                    let last = t.rows.last().map_or(f64::NAN, |r| r.attitude_error);
                    Ok([last, rms, est])
                })
                .collect::<Result<_, SimError>>()?;
            let mean = |i: usize| per_run.iter().map(|r| r[i]).sum::<f64>() / runs as f64;
            Ok(NoiseRow {
                gyro_noise: noise,
                bias,
                estimator: if truth {
                    EstimatorKind::Truth
                } else {
                    base.estimator.kind
                }
                .name()
                .to_owned(),
                runs,
                final_attitude_error: mean(0),
                rms_attitude_error: mean(1),
                rms_estimate_error: mean(2),
            })
        })
        .collect()
}

/// The rows as a Markdown table.
pub fn table(rows: &[NoiseRow]) -> String {
    let mut t = String::from(
        "| gyro noise (rad/s/√Hz) | gyro bias | fed | final ‖I − R_dᵀR‖_F | RMS ‖I − R_dᵀR‖_F | RMS estimate error (rad) |\n|---|---|---|---|---|---|\n",
    );
    for r in rows {
        t.push_str(&format!(
            "| {} | {} | {} | {:.4} | {:.4} | {:.4} |\n",
            r.gyro_noise,
            if r.bias { "yes" } else { "no" },
            r.estimator,
            r.final_attitude_error,
            r.rms_attitude_error,
            r.rms_estimate_error
        ));
    }
    t
}

/// Writes `noise.csv`, `table.md` and `noise.png`/`.svg` to `out`.
pub fn write(rows: &[NoiseRow], scenario: &str, out: &Path) -> Result<(), SimError> {
    let fail = |e: std::io::Error| SimError::Run(format!("cannot write to {}: {e}", out.display()));
    let mut csv = String::from(
        "gyro_noise,bias,estimator,runs,final_attitude_error,rms_attitude_error,rms_estimate_error\n",
    );
    for r in rows {
        csv.push_str(&format!(
            "{},{},{},{},{},{},{}\n",
            num(r.gyro_noise),
            r.bias,
            r.estimator,
            r.runs,
            num(r.final_attitude_error),
            num(r.rms_attitude_error),
            num(r.rms_estimate_error)
        ));
    }
    std::fs::write(out.join("noise.csv"), csv).map_err(fail)?;
    std::fs::write(out.join("table.md"), table(rows)).map_err(fail)?;
    let filter = rows
        .iter()
        .find(|r| r.estimator != "truth")
        .map_or("complementary", |r| r.estimator.as_str());
    let line = |estimator: &str, bias: bool, f: fn(&NoiseRow) -> f64, label: &str, color| Line {
        label: label.to_owned(),
        color,
        points: rows
            .iter()
            .filter(|r| r.estimator == estimator && r.bias == bias)
            .map(|r| (r.gyro_noise * 1e3, f(r)))
            .collect(),
    };
    let panel = |title: &str, f: fn(&NoiseRow) -> f64| Panel {
        title: title.to_owned(),
        y_label: "mean over runs".to_owned(),
        lines: vec![
            line("truth", true, f, "truth-fed", law_color("eqt")),
            line(filter, false, f, "filter-fed, no bias", law_color("nog")),
            line(filter, true, f, "filter-fed, with bias", law_color("gt")),
        ],
    };
    let panels = [
        panel(
            "RMS tracking error ‖I − R_dᵀR‖_F of the true state",
            |r| r.rms_attitude_error,
        ),
        panel("Final tracking error ‖I − R_dᵀR‖_F at t = T", |r| {
            r.final_attitude_error
        }),
        panel("RMS attitude estimate error (rad)", |r| {
            r.rms_estimate_error
        }),
    ];
    render_against(
        &out.join("noise"),
        &format!("{scenario}: what sensor noise costs"),
        &panels,
        1,
        (1000, 1100),
        "gyro noise density [mrad/s/√Hz]",
    )
}
