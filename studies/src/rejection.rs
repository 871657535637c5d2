//! `plant_sim rejection`: what the disturbance-rejection terms buy
//! (docs/maths.md, "Disturbance rejection"). The scenario flown three ways — the plain law
//! (PD), the geometric integral, the momentum observer — side by side (`rejection.csv`, a
//! table and a figure); and with `--runs N`, a Monte Carlo over random constant body
//! disturbances (seeded), the final error's distribution per variant
//! (`rejection_montecarlo.csv`).

use eqtrack_controller::Frame;
use plant::SimError;
use plant::output::num;
use plant::plot::{Line, Panel, law_color, render};
use plant::trajectory::{Row, simulate};
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal, Uniform};
use rayon::prelude::*;
use scenario::{IntegralSpec, ObserverSpec, RejectionSpec, Scenario};
use std::path::Path;

/// The terms of the two non-trivial variants.
#[derive(Debug, Clone, PartialEq)]
pub struct Variants {
    /// The integral variant's term.
    pub integral: IntegralSpec,
    /// The observer variant's term.
    pub observer: ObserverSpec,
}

impl Variants {
    /// The scenario's own terms where it has them, else `K_I`, `c` and `L` (every axis).
    pub fn of(s: &Scenario, ki: f64, c: f64, gain: f64) -> Result<Variants, SimError> {
        for (flag, x) in [("--ki", ki), ("--c", c), ("--gain", gain)] {
            if !(x.is_finite() && x > 0.0) {
                return Err(SimError::Input(format!(
                    "{flag}: must be a finite number > 0, got {x}"
                )));
            }
        }
        let m = s.group.dims().1;
        Ok(Variants {
            integral: s.rejection.integral.clone().unwrap_or(IntegralSpec {
                ki: vec![ki; m],
                c: vec![c; m],
                limit: None,
                anti_windup: true,
            }),
            observer: s.rejection.observer.clone().unwrap_or(ObserverSpec {
                gain: vec![gain; m],
                limit: None,
                frame: Frame::Body,
            }),
        })
    }

    /// `(name, the scenario with that variant's terms)`: PD, integral, observer.
    pub fn scenarios(&self, s: &Scenario) -> [(&'static str, Scenario); 3] {
        let with = |rejection: RejectionSpec| {
            let mut v = s.clone();
            v.rejection = rejection;
            v
        };
        [
            ("pd", with(RejectionSpec::default())),
            (
                "integral",
                with(RejectionSpec {
                    observer: None,
                    integral: Some(self.integral.clone()),
                }),
            ),
            (
                "observer",
                with(RejectionSpec {
                    observer: Some(self.observer.clone()),
                    integral: None,
                }),
            ),
        ]
    }
}

/// The rotation angle (rad) of `R_dᵀR` from `‖I − R_dᵀR‖_F = 2√2 sin(θ/2)`.
pub fn angle(attitude_error: f64) -> f64 {
    2.0 * (attitude_error / (2.0 * std::f64::consts::SQRT_2))
        .clamp(0.0, 1.0)
        .asin()
}

/// The estimate of the body disturbance a row's terms hold: `d̂ − (−K_I z)`.
fn estimate(r: &Row, m: usize) -> Vec<f64> {
    match &r.terms {
        Some(t) => (0..m).map(|i| t.observer[i] - t.integral[i]).collect(),
        None => vec![0.0; m],
    }
}

/// One variant's run.
#[derive(Debug, Clone)]
pub struct Flown {
    /// `pd`, `integral` or `observer`.
    pub variant: &'static str,
    /// Its rows.
    pub rows: Vec<Row>,
}

/// Flies the three variants.
pub fn compare(s: &Scenario, v: &Variants) -> Result<Vec<Flown>, SimError> {
    v.scenarios(s)
        .into_par_iter()
        .map(|(variant, s)| {
            Ok(Flown {
                variant,
                rows: simulate(&s, &|_| Ok(()))?.rows,
            })
        })
        .collect()
}

/// The comparison as a Markdown table: the final attitude error and the estimate at T.
pub fn table(flown: &[Flown], m: usize) -> String {
    let mut t = String::from(
        "| variant | attitude error at T (rad) | estimate of d at T (body frame) |\n|---|---|---|\n",
    );
    for f in flown {
        let Some(last) = f.rows.last() else { continue };
        let e = estimate(last, m);
        t.push_str(&format!(
            "| {} | {:.3e} | ({}) |\n",
            f.variant,
            angle(last.attitude_error),
            e.iter()
                .map(|x| format!("{x:.4}"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    t
}

fn color(variant: &str) -> plotters::style::RGBColor {
    law_color(match variant {
        "pd" => "gt",
        "integral" => "nog",
        _ => "eqt",
    })
}

/// Writes `rejection.csv`, `table.md` and `rejection.png`/`.svg`.
pub fn write(flown: &[Flown], s: &Scenario, out: &Path) -> Result<(), SimError> {
    let m = s.group.dims().1;
    let fail = |e: std::io::Error| SimError::Run(format!("cannot write to {}: {e}", out.display()));
    let mut csv = String::from("t");
    for f in flown {
        csv.push_str(&format!(",{}_angle", f.variant));
        for i in 0..m {
            csv.push_str(&format!(",{}_estimate_{i}", f.variant));
        }
    }
    csv.push('\n');
    let n = flown.iter().map(|f| f.rows.len()).min().unwrap_or(0);
    for k in 0..n {
        csv.push_str(&num(flown[0].rows[k].t));
        for f in flown {
            let r = &f.rows[k];
            csv.push_str(&format!(",{}", num(angle(r.attitude_error))));
            for x in estimate(r, m) {
                csv.push_str(&format!(",{}", num(x)));
            }
        }
        csv.push('\n');
    }
    std::fs::write(out.join("rejection.csv"), csv).map_err(fail)?;
    std::fs::write(out.join("table.md"), table(flown, m)).map_err(fail)?;
    let lines = |pick: &dyn Fn(&Row) -> f64| -> Vec<Line> {
        flown
            .iter()
            .map(|f| Line {
                label: f.variant.to_owned(),
                color: color(f.variant),
                points: f.rows.iter().map(|r| (r.t, pick(r))).collect(),
            })
            .collect()
    };
    let mut panels = vec![
        Panel {
            title: "Attitude error angle of R_dᵀR".to_owned(),
            y_label: "rad".to_owned(),
            lines: lines(&|r| angle(r.attitude_error)),
        },
        Panel {
            title: "Attitude error angle, log10".to_owned(),
            y_label: "log10 rad".to_owned(),
            lines: lines(&|r| angle(r.attitude_error).max(1e-12).log10()),
        },
    ];
    for i in 0..m.min(3) {
        let d = s.disturbance.get(i).copied().unwrap_or(0.0);
        let mut l = lines(&|r| estimate(r, m)[i]);
        l.retain(|line| line.label != "pd");
        l.push(Line {
            label: format!("d_{i}"),
            color: plotters::style::RGBColor(120, 120, 120),
            points: vec![(0.0, d), (s.duration, d)],
        });
        panels.push(Panel {
            title: format!("Estimate of d_{i}: d̂ (observer), −K_I z (integral)"),
            y_label: "N·m".to_owned(),
            lines: l,
        });
    }
    render(
        &out.join("rejection"),
        &format!(
            "{}: a constant disturbance against PD, the integral, the observer",
            s.name
        ),
        &panels,
        1,
        (1000, 1500),
    )
}

/// One Monte Carlo run: the disturbance and each variant's final attitude angle.
#[derive(Debug, Clone, PartialEq)]
pub struct McRun {
    /// The run index.
    pub run: usize,
    /// The body disturbance drawn (m entries).
    pub disturbance: Vec<f64>,
    /// Final attitude angle (rad) per variant, in [`Variants::scenarios`] order.
    pub final_angle: [f64; 3],
}

/// `runs` seeded constant body disturbances (direction uniform on the sphere of the
/// torque axes, magnitude uniform in `[0, magnitude]`), each flown with the three variants.
pub fn montecarlo(
    s: &Scenario,
    v: &Variants,
    runs: usize,
    magnitude: f64,
    seed: u64,
) -> Result<Vec<McRun>, SimError> {
    if !(magnitude.is_finite() && magnitude >= 0.0) {
        return Err(SimError::Input(format!(
            "--magnitude: must be a finite number ≥ 0, got {magnitude}"
        )));
    }
    let m = s.group.dims().1;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let unit = Uniform::new(0.0, 1.0).map_err(|e| SimError::Input(e.to_string()))?;
    let draws: Vec<Vec<f64>> = (0..runs)
        .map(|_| {
            let dir: [f64; 3] = std::array::from_fn(|_| StandardNormal.sample(&mut rng));
            let norm = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
            let scale = magnitude * unit.sample(&mut rng) / norm.max(f64::MIN_POSITIVE);
            let mut d = vec![0.0; m];
            for i in 0..3 {
                d[i] = dir[i] * scale;
            }
            d
        })
        .collect();
    draws
        .into_par_iter()
        .enumerate()
        .map(|(run, d)| {
            let mut base = s.clone();
            base.disturbance = d.clone();
            let mut final_angle = [0.0; 3];
            for (i, (_, sv)) in v.scenarios(&base).into_iter().enumerate() {
                let t = simulate(&sv, &|_| Ok(()))?;
                final_angle[i] = t.rows.last().map_or(f64::NAN, |r| angle(r.attitude_error));
            }
            Ok(McRun {
                run,
                disturbance: d,
                final_angle,
            })
        })
        .collect()
}

/// The `q`-quantile (0..1) of `xs` (nearest rank).
fn quantile(xs: &mut [f64], q: f64) -> f64 {
    xs.sort_by(f64::total_cmp);
    let i = ((xs.len() as f64 * q).ceil() as usize).clamp(1, xs.len().max(1)) - 1;
    xs.get(i).copied().unwrap_or(f64::NAN)
}

/// The Monte Carlo's distribution as a Markdown table.
pub fn mc_table(runs: &[McRun]) -> String {
    let mut t = String::from(
        "| variant | median final error (rad) | 90th percentile | largest |\n|---|---|---|---|\n",
    );
    for (i, name) in ["pd", "integral", "observer"].iter().enumerate() {
        let mut xs: Vec<f64> = runs.iter().map(|r| r.final_angle[i]).collect();
        t.push_str(&format!(
            "| {name} | {:.3e} | {:.3e} | {:.3e} |\n",
            quantile(&mut xs, 0.5),
            quantile(&mut xs, 0.9),
            quantile(&mut xs, 1.0)
        ));
    }
    t
}

/// Writes `rejection_montecarlo.csv` and `montecarlo.md`.
pub fn write_mc(runs: &[McRun], out: &Path) -> Result<(), SimError> {
    let fail = |e: std::io::Error| SimError::Run(format!("cannot write to {}: {e}", out.display()));
    let m = runs.first().map_or(3, |r| r.disturbance.len());
    let mut csv = String::from("run");
    for i in 0..m {
        csv.push_str(&format!(",d_{i}"));
    }
    csv.push_str(",pd_final_angle,integral_final_angle,observer_final_angle\n");
    for r in runs {
        csv.push_str(&r.run.to_string());
        for x in r.disturbance.iter().chain(&r.final_angle) {
            csv.push_str(&format!(",{}", num(*x)));
        }
        csv.push('\n');
    }
    std::fs::write(out.join("rejection_montecarlo.csv"), csv).map_err(fail)?;
    std::fs::write(out.join("montecarlo.md"), mc_table(runs)).map_err(fail)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_angle_inverts_the_frobenius_error() {
        for theta in [0.0, 1e-6, 0.0688, 1.0, 3.0] {
            let f = 2.0 * std::f64::consts::SQRT_2 * (theta / 2.0f64).sin();
            assert!((angle(f) - theta).abs() < 1e-12, "{theta}");
        }
    }

    #[test]
    fn quantiles_are_nearest_rank() {
        let mut xs = vec![5.0, 1.0, 4.0, 2.0, 3.0];
        assert_eq!(quantile(&mut xs, 0.5), 3.0);
        assert_eq!(quantile(&mut xs, 1.0), 5.0);
        assert_eq!(quantile(&mut xs, 0.0), 1.0);
    }

    #[test]
    fn the_issue_set_point_pd_leaves_its_offset_and_both_terms_remove_it() {
        let file = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/reject_so3.toml");
        let s = Scenario::from_file(Path::new(file)).unwrap();
        let v = Variants::of(&s, 1.0, 5.0, 20.0).unwrap();
        let flown = compare(&s, &v).unwrap();
        let last = |i: usize| flown[i].rows.last().unwrap();
        assert!((angle(last(0).attitude_error) - 0.0688).abs() < 1e-4);
        for i in [1, 2] {
            assert!(angle(last(i).attitude_error) < 1e-4, "{}", flown[i].variant);
            let e = estimate(last(i), 3);
            for (a, b) in e.iter().zip([0.1, -0.05, 0.08]) {
                assert!((a - b).abs() < 1e-3, "{}: {e:?}", flown[i].variant);
            }
        }
        assert!(table(&flown, 3).contains("| pd | 6.879e-2 |"));
        // the Monte Carlo is seeded: the same seed, the same draws and results
        let a = montecarlo(&s, &v, 2, 0.2, 7).unwrap();
        assert_eq!(a, montecarlo(&s, &v, 2, 0.2, 7).unwrap());
        assert_ne!(
            a[0].disturbance,
            montecarlo(&s, &v, 2, 0.2, 8).unwrap()[0].disturbance
        );
        assert!(Variants::of(&s, 0.0, 5.0, 20.0).is_err());
        assert!(montecarlo(&s, &v, 1, f64::NAN, 7).is_err());
    }
}
