//! `plant_sim reference`: the scenario's desired trajectory sampled at its control period —
//! `reference.csv` (`t`, `qd_ij`, `vd_i`, `vd_dot_i`, `tau_d_i`) and a figure — so that a
//! manoeuvre is checked before it is flown.

use crate::SimError;
use crate::output::{ensure_dir, num};
use crate::plot::{Line, Panel, render};
use crate::trajectory::input;
use controller::group::{MatrixLieGroup, OnGroup};
use controller::{Source, Trajectory};
use nalgebra::{SMatrix, SVector};
use plotters::style::RGBColor;
use scenario::Scenario;
use std::path::{Path, PathBuf};

/// One sample of the desired trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceRow {
    /// `t_k`.
    pub t: f64,
    /// `Q_d`, row-major.
    pub q: Vec<f64>,
    /// `V_d`.
    pub v: Vec<f64>,
    /// `V̇_d`.
    pub v_dot: Vec<f64>,
    /// `τ_d`.
    pub tau: Vec<f64>,
}

/// The reference at every control step from 0 to the duration. `V̇_d` is the path's own
/// (exact) acceleration for waypoints and set-points, and `I⁻¹(ad_{V_d}ᵀ p_d + τ_d)` (the
/// Euler–Poincaré equations) for the feedforward series.
pub fn sample_reference(s: &Scenario) -> Result<Vec<ReferenceRow>, SimError> {
    s.group.dispatch(Sampler(s))
}

struct Sampler<'a>(&'a Scenario);

impl OnGroup for Sampler<'_> {
    type Output = Result<Vec<ReferenceRow>, SimError>;
    fn run<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
        let s = self.0;
        let mut source = s.reference_source::<G, N, M>().map_err(input(s))?;
        let inertia = SMatrix::<f64, M, M>::from_row_slice(&s.model_inertia);
        let inv = inertia.try_inverse().unwrap_or_else(SMatrix::zeros);
        let flat = |m: &[f64]| m.to_vec();
        let mut rows = Vec::with_capacity(s.steps() as usize + 1);
        for _ in 0..=s.steps() {
            let d = source.desired();
            let v_dot: SVector<f64, M> = match &source {
                Source::Path(p) => p.sample().v_dot,
                Source::Series(_) => inv * (G::ad(&d.v).tr_mul(&d.p) + d.tau),
            };
            rows.push(ReferenceRow {
                t: source.time(),
                q: flat(d.q.transpose().as_slice()),
                v: flat(d.v.as_slice()),
                v_dot: flat(v_dot.as_slice()),
                tau: flat(d.tau.as_slice()),
            });
            source.advance();
        }
        Ok(rows)
    }
}

/// The header of `reference.csv` for the group's (n, m).
pub fn reference_header(n: usize, m: usize) -> Vec<String> {
    let mut h = vec!["t".to_owned()];
    h.extend((0..n * n).map(|i| format!("qd_{}{}", i / n, i % n)));
    for name in ["vd", "vd_dot", "tau_d"] {
        h.extend((0..m).map(|i| format!("{name}_{i}")));
    }
    h
}

/// Writes `reference.csv` and `reference.{png,svg}` into `out`; returns the CSV's path.
pub fn write_reference(s: &Scenario, out: &Path) -> Result<PathBuf, SimError> {
    let rows = sample_reference(s)?;
    ensure_dir(out)?;
    let path = out.join("reference.csv");
    let fail = |e: csv::Error| SimError::Run(format!("cannot write {}: {e}", path.display()));
    let (n, m) = s.group.dims();
    let mut w = csv::Writer::from_path(&path).map_err(fail)?;
    w.write_record(reference_header(n, m)).map_err(fail)?;
    for r in &rows {
        let fields = std::iter::once(r.t)
            .chain(r.q.iter().copied())
            .chain(r.v.iter().copied())
            .chain(r.v_dot.iter().copied())
            .chain(r.tau.iter().copied())
            .map(num);
        w.write_record(fields).map_err(fail)?;
    }
    w.flush()
        .map_err(|e| SimError::Run(format!("cannot write {}: {e}", path.display())))?;
    reference_figure(s, &rows, &out.join("reference"))?;
    Ok(path)
}

/// Rotation angle of `Q_d` from the identity, `V_d`, `V̇_d` and `τ_d` against time.
fn reference_figure(s: &Scenario, rows: &[ReferenceRow], stem: &Path) -> Result<(), SimError> {
    const COLORS: [RGBColor; 6] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(255, 127, 14),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
    ];
    let n = s.group.dims().0;
    let panel = |title: &str, y: &str, pick: &dyn Fn(&ReferenceRow) -> &[f64]| Panel {
        title: title.to_owned(),
        y_label: y.to_owned(),
        lines: (0..pick(&rows[0]).len())
            .map(|i| Line {
                label: format!("{y}_{i}"),
                color: COLORS[i % COLORS.len()],
                points: rows.iter().map(|r| (r.t, pick(r)[i])).collect(),
            })
            .collect(),
    };
    let angle = |r: &ReferenceRow| {
        let trace = r.q[0] + r.q[n + 1] + r.q[2 * n + 2];
        ((trace - 1.0) / 2.0).clamp(-1.0, 1.0).acos()
    };
    let panels = [
        Panel {
            title: "Attitude: rotation angle of R_d from the identity".to_owned(),
            y_label: "angle (rad)".to_owned(),
            lines: vec![Line {
                label: String::new(),
                color: COLORS[0],
                points: rows.iter().map(|r| (r.t, angle(r))).collect(),
            }],
        },
        panel("Body velocity V_d", "vd", &|r| &r.v),
        panel("Body acceleration dV_d/dt", "vd_dot", &|r| &r.v_dot),
        panel("Feedforward torque τ_d", "tau_d", &|r| &r.tau),
    ];
    let title = format!(
        "{} — reference on {}",
        s.name,
        s.group.name().to_uppercase()
    );
    render(stem, &title, &panels, 1, (1000, 1400))
}
