//! `plant_sim reference`: the scenario's desired trajectory sampled at its control period —
//! `reference.csv` (`t`, `qd_ij`, `vd_i`, `vd_dot_i`, `tau_d_i`) and a figure — so that a
//! manoeuvre is checked before it is flown.

use eqtrack_controller::group::{BuiltinGroup, OnGroup};
use eqtrack_controller::{GroupKind, Source, Trajectory};
use nalgebra::{SMatrix, SVector};
use plant::SimError;
use plant::output::{ensure_dir, num, write_json};
use plant::plot::{Line, Panel, render};
use plant::trajectory::input;
use plotters::style::RGBColor;
use scenario::{PathKind, Scenario};
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
    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
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

/// Writes `reference.csv`, `reference.{png,svg}` and the feasibility report
/// `reference.json` into `out`; returns the CSV's path and the report.
pub fn write_reference(s: &Scenario, out: &Path) -> Result<(PathBuf, Feasibility), SimError> {
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
    let report = write_feasibility(s, &rows, out)?;
    Ok((path, report))
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
    let angle = |r: &ReferenceRow| rotation_angle(&r.q, n);
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

/// A peak of a sampled quantity and the time it occurs.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Peak {
    /// The largest value.
    pub value: f64,
    /// The first sample time at which it occurs (s).
    pub t: f64,
}

impl Peak {
    fn none() -> Peak {
        Peak { value: 0.0, t: 0.0 }
    }

    fn offer(&mut self, value: f64, t: f64) {
        if value > self.value {
            *self = Peak { value, t };
        }
    }
}

/// An axis whose feedforward alone exceeds the torque limit.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LimitWarning {
    /// The axis (0-based index of `τ_d`).
    pub axis: usize,
    /// Its name (`τ_x` …, SE(3) forces `f_x` …).
    pub name: String,
    /// The limit on the axis.
    pub limit: f64,
    /// The largest `|τ_d|` on the axis and when.
    pub peak: Peak,
    /// The first and the last sample time at which `|τ_d| > limit`.
    pub from: f64,
    /// See `from`.
    pub to: f64,
}

impl std::fmt::Display for LimitWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "warning: axis {} ({}): the feedforward alone needs |{}| = {:.4} at t = {:.4} s, above the torque limit {} (exceeded from t = {:.4} s to {:.4} s): the actuators cannot fly this reference as given",
            self.axis,
            self.name,
            self.name,
            self.peak.value,
            self.peak.t,
            self.limit,
            self.from,
            self.to
        )
    }
}

/// What `plant_sim reference` reports before flight: peaks of the desired motion and of the
/// feedforward per axis, on the control-period grid, against the torque limit
/// (docs/paths.md, "Reading the feasibility report").
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Feasibility {
    /// The scenario.
    pub scenario: String,
    /// `so3` or `se3`.
    pub group: String,
    /// The control period: the grid the peaks are taken on (s).
    pub control_period: f64,
    /// Peak `|ω_d|` (rad/s).
    pub angular_speed: Peak,
    /// Peak `|α_d| = |ω̇_d|` (rad/s²; the world-frame angular acceleration has the same norm).
    pub angular_acceleration: Peak,
    /// SE(3): peak speed `|v_d| = |ṗ_d|` (m/s).
    pub speed: Option<Peak>,
    /// SE(3): peak acceleration `|p̈_d| = |v̇_d + ω_d × v_d|` (m/s²).
    pub acceleration: Option<Peak>,
    /// Peak `|τ_d|` per axis.
    pub torque: Vec<Peak>,
    /// The scenario's per-axis torque limit, if any.
    pub torque_limit: Option<Vec<f64>>,
    /// Every axis whose feedforward alone exceeds the limit.
    pub warnings: Vec<LimitWarning>,
}

/// The axis names of `τ_d` on `group`.
fn axis_name(group: GroupKind, i: usize) -> String {
    let names: &[&str] = match group {
        GroupKind::So3 => &["τ_x", "τ_y", "τ_z"],
        GroupKind::Se3 => &["τ_x", "τ_y", "τ_z", "f_x", "f_y", "f_z"],
        GroupKind::Se2 => &["τ", "f_x", "f_y"],
    };
    names
        .get(i)
        .map_or_else(|| format!("τ_{i}"), |s| (*s).to_owned())
}

/// The feasibility report of sampled reference rows.
pub fn feasibility(s: &Scenario, rows: &[ReferenceRow]) -> Feasibility {
    let m = s.group.dims().1;
    let planar = s.group == GroupKind::Se2;
    let positions = m == 6 || planar;
    let norm3 = |x: &[f64]| (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
    let mut report = Feasibility {
        scenario: s.name.clone(),
        group: s.group.name().to_owned(),
        control_period: s.control_period,
        angular_speed: Peak::none(),
        angular_acceleration: Peak::none(),
        speed: positions.then(Peak::none),
        acceleration: positions.then(Peak::none),
        torque: vec![Peak::none(); m],
        torque_limit: s.torque_limit.clone(),
        warnings: Vec::new(),
    };
    let mut over: Vec<Option<(f64, f64)>> = vec![None; m];
    for r in rows {
        if planar {
            // (ω, v_x, v_y): the turn rate, the planar speed, and the acceleration of the
            // body's origin in body axes, v̇ + ω J v
            let (w, v, vd) = (r.v[0], [r.v[1], r.v[2]], [r.v_dot[1], r.v_dot[2]]);
            report.angular_speed.offer(w.abs(), r.t);
            report.angular_acceleration.offer(r.v_dot[0].abs(), r.t);
            let a = [vd[0] - w * v[1], vd[1] + w * v[0]];
            if let Some(p) = report.speed.as_mut() {
                p.offer(v[0].hypot(v[1]), r.t);
            }
            if let Some(p) = report.acceleration.as_mut() {
                p.offer(a[0].hypot(a[1]), r.t);
            }
        } else {
            report.angular_speed.offer(norm3(&r.v[..3]), r.t);
            report.angular_acceleration.offer(norm3(&r.v_dot[..3]), r.t);
        }
        if m == 6 {
            let (w, v, vd) = (&r.v[..3], &r.v[3..6], &r.v_dot[3..6]);
            let a = [
                vd[0] + w[1] * v[2] - w[2] * v[1],
                vd[1] + w[2] * v[0] - w[0] * v[2],
                vd[2] + w[0] * v[1] - w[1] * v[0],
            ];
            if let Some(p) = report.speed.as_mut() {
                p.offer(norm3(v), r.t);
            }
            if let Some(p) = report.acceleration.as_mut() {
                p.offer(norm3(&a), r.t);
            }
        }
        for i in 0..m {
            let x = r.tau[i].abs();
            report.torque[i].offer(x, r.t);
            if let Some(l) = &s.torque_limit
                && x > l[i]
            {
                let span = over[i].get_or_insert((r.t, r.t));
                span.1 = r.t;
            }
        }
    }
    for (i, span) in over.iter().enumerate() {
        if let (Some((from, to)), Some(l)) = (span, &s.torque_limit) {
            report.warnings.push(LimitWarning {
                axis: i,
                name: axis_name(s.group, i),
                limit: l[i],
                peak: report.torque[i],
                from: *from,
                to: *to,
            });
        }
    }
    report
}

/// The report as text, one line per figure (the warnings are [`LimitWarning`]'s `Display`).
pub fn feasibility_text(f: &Feasibility) -> String {
    let mut out = format!(
        "feasibility of `{}` ({}), sampled every {} s:\n",
        f.scenario, f.group, f.control_period
    );
    let mut line = |name: &str, p: &Peak, unit: &str, note: &str| {
        out.push_str(&format!(
            "  peak {name:<24} {:>12.6} {unit:<7} at t = {:.4} s{note}\n",
            p.value, p.t
        ));
    };
    line("|ω_d|", &f.angular_speed, "rad/s", "");
    line("|α_d|", &f.angular_acceleration, "rad/s²", "");
    if let Some(p) = &f.speed {
        line("speed |v_d|", p, "m/s", "");
    }
    if let Some(p) = &f.acceleration {
        line("acceleration |p̈_d|", p, "m/s²", "");
    }
    let group = GroupKind::from_name(&f.group).unwrap_or(GroupKind::So3);
    for (i, p) in f.torque.iter().enumerate() {
        let limit = f.torque_limit.as_ref().map_or_else(
            || " (no limit)".to_owned(),
            |l| format!(" (limit {})", l[i]),
        );
        line(
            &format!("|{}| (feedforward)", axis_name(group, i)),
            p,
            "",
            &limit,
        );
    }
    out.push_str(&match (&f.torque_limit, f.warnings.len()) {
        (None, _) => "  no torque limit in the scenario: nothing to compare with\n".to_owned(),
        (Some(_), 0) => "  the feedforward stays within the torque limit on every axis\n".to_owned(),
        (Some(_), n) => format!("  the feedforward alone exceeds the torque limit on {n} axis/axes (warnings on stderr)\n"),
    });
    out
}

/// Writes `reference.json` (the [`Feasibility`] report) into `out`; returns the report.
pub fn write_feasibility(
    s: &Scenario,
    rows: &[ReferenceRow],
    out: &Path,
) -> Result<Feasibility, SimError> {
    let report = feasibility(s, rows);
    write_json(&report, &out.join("reference.json"))?;
    Ok(report)
}

/// The scenario with its waypoints flown the other way: `kind` replaces the path kind (a
/// stop path drops the given velocities, which only a through-path honours).
pub fn with_path_kind(s: &Scenario, kind: PathKind) -> Result<Scenario, SimError> {
    let mut other = s.clone();
    let Some(p) = other.path.as_mut().filter(|p| p.times.len() > 1) else {
        return Err(SimError::Input(format!(
            "scenario `{}` has no `[reference] waypoints` to fly two ways",
            s.name
        )));
    };
    p.kind = kind;
    if kind == PathKind::Stop {
        p.velocities.iter_mut().for_each(|v| *v = None);
    }
    Ok(other)
}

/// What `--compare-paths` found: peaks of each way of flying the waypoints.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PathComparison {
    /// `stop` then `through`: the feasibility report of each.
    pub reports: Vec<(String, Feasibility)>,
    /// Largest closed-loop attitude error `‖I − R_dᵀR‖_F` from the second waypoint's time on
    /// (after the start's transient), per way.
    pub tracking: Vec<(String, f64)>,
}

/// Flies the scenario's waypoints both ways (`path = "stop"` and `"through"`): the desired
/// attitude angle, `|ω_d|`, `|τ_d|` and the closed loop's attitude error of each, drawn in
/// `paths.{png,svg}` and summarised in `paths.json` in `out`.
pub fn compare_paths(s: &Scenario, out: &Path) -> Result<PathComparison, SimError> {
    const STOP: RGBColor = RGBColor(31, 119, 180);
    const THROUGH: RGBColor = RGBColor(214, 39, 40);
    ensure_dir(out)?;
    let ways = [
        ("stop", PathKind::Stop, STOP),
        ("through", PathKind::Through, THROUGH),
    ];
    // the flown error once the initial transient is over: from the second waypoint on
    let start = s
        .path
        .as_ref()
        .and_then(|p| p.times.get(1).copied())
        .unwrap_or(0.0);
    let mut panels: Vec<Panel> = [
        ("Desired attitude: rotation angle of R_d from the identity", "angle (rad)"),
        ("Desired angular speed |ω_d|", "|ω_d| (rad/s)"),
        ("Feedforward |τ_d| (torque part)", "|τ_d|"),
        (
            "Flown (the scenario's start): attitude error ‖I − R_dᵀR‖_F from the second waypoint on",
            "error",
        ),
    ]
    .iter()
    .map(|(title, y)| Panel {
        title: (*title).to_owned(),
        y_label: (*y).to_owned(),
        lines: Vec::new(),
    })
    .collect();
    let mut result = PathComparison {
        reports: Vec::new(),
        tracking: Vec::new(),
    };
    let n = s.group.dims().0;
    let norm3 = |x: &[f64]| (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
    for (name, kind, color) in ways {
        let way = with_path_kind(s, kind)?;
        let rows = sample_reference(&way)?;
        let flown = plant::trajectory::simulate(&way, &|_| Ok(()))?;
        let line = |f: &dyn Fn(&ReferenceRow) -> f64| Line {
            label: name.to_owned(),
            color,
            points: rows.iter().map(|r| (r.t, f(r))).collect(),
        };
        panels[0].lines.push(line(&|r| rotation_angle(&r.q, n)));
        panels[1].lines.push(line(&|r| norm3(&r.v)));
        panels[2].lines.push(line(&|r| norm3(&r.tau)));
        panels[3].lines.push(Line {
            label: name.to_owned(),
            color,
            points: flown
                .rows
                .iter()
                .filter(|r| r.t >= start)
                .map(|r| (r.t, r.attitude_error))
                .collect(),
        });
        let worst = flown
            .rows
            .iter()
            .filter(|r| r.t >= start)
            .map(|r| r.attitude_error)
            .fold(0.0f64, f64::max);
        result.tracking.push((name.to_owned(), worst));
        result
            .reports
            .push((name.to_owned(), feasibility(&way, &rows)));
    }
    let title = format!(
        "{} — the waypoints flown two ways: stop at each, or through them",
        s.name
    );
    render(&out.join("paths"), &title, &panels, 1, (1000, 1400))?;
    write_json(&result, &out.join("paths.json"))?;
    Ok(result)
}

/// The rotation angle of the rotation block of a row-major n×n pose.
fn rotation_angle(q: &[f64], n: usize) -> f64 {
    let trace = q[0] + q[n + 1] + q[2 * n + 2];
    ((trace - 1.0) / 2.0).clamp(-1.0, 1.0).acos()
}
