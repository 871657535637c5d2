//! `trajectory.csv` and `summary.json`.

use crate::SimError;
use crate::trajectory::{SimulatedTrajectory, effort, settling_time};
use serde::Serialize;
use std::path::Path;

/// Formats a number with the shortest representation that reads back to the same f64.
pub fn num(x: f64) -> String {
    format!("{x:?}")
}

/// The column names of `trajectory.csv` for the group's (n, m).
pub fn trajectory_header(n: usize, m: usize) -> Vec<String> {
    let mut h: Vec<String> = [
        "t",
        "lyapunov",
        "config_error",
        "momentum_error",
        "attitude_error",
        "velocity_error",
        "torque_norm",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    h.extend((0..m).map(|i| format!("tau_{i}")));
    for i in 0..n {
        for j in 0..n {
            h.push(format!("q_{i}{j}"));
        }
    }
    h.extend((0..m).map(|i| format!("v_{i}")));
    h
}

/// The sensor and estimate columns of `trajectory.csv` (after `v_i`): `gyro_i`, `dir{j}_i`
/// for each direction, on SE(3) `acc_i` and `pos_i`, then `qhat_ij`, `bias_hat_i`, on SE(3)
/// `xhat_i` and `vhat_i` (world frame), and `estimate_error`; for the EqF (`covariance`)
/// then `cov_i` (the diagonal of its covariance: attitude rad², bias (rad/s)²) and `nees`.
pub fn estimate_header(n: usize, directions: usize, se3: bool, covariance: bool) -> Vec<String> {
    let three = |name: &str| -> Vec<String> { (0..3).map(|i| format!("{name}_{i}")).collect() };
    let mut h: Vec<String> = three("gyro");
    for j in 0..directions {
        h.extend(three(&format!("dir{j}")));
    }
    if se3 {
        h.extend(three("acc"));
        h.extend(three("pos"));
    }
    for i in 0..n {
        for j in 0..n {
            h.push(format!("qhat_{i}{j}"));
        }
    }
    h.extend(three("bias_hat"));
    if se3 {
        h.extend(three("xhat"));
        h.extend(three("vhat"));
    }
    h.push("estimate_error".to_owned());
    if covariance {
        h.extend((0..6).map(|i| format!("cov_{i}")));
        h.push("nees".to_owned());
    }
    h
}

/// The values of [`estimate_header`]'s columns for one row (empty `pos_i` on ticks without
/// a fix).
fn estimate_fields(
    e: &crate::trajectory::EstimateRow,
    n: usize,
    covariance: bool,
    rec: &mut Vec<Cell>,
) {
    let se3 = n == 4;
    let s = &e.samples;
    let nums = |xs: &[f64]| xs.iter().map(|x| Cell::Num(*x)).collect::<Vec<_>>();
    rec.extend(nums(s.gyro.as_slice()));
    for d in &s.directions[..s.count] {
        rec.extend(nums(d.as_slice()));
    }
    if se3 {
        for v in [s.accel, s.position] {
            match v {
                Some(a) => rec.extend(nums(a.as_slice())),
                None => rec.extend([Cell::Empty; 3]),
            }
        }
    }
    rec.extend(nums(&e.q_hat[..n * n]));
    rec.extend(nums(&e.bias_hat));
    if se3 {
        rec.extend((0..3).map(|i| Cell::Num(e.q_hat[i * 4 + 3])));
        // world velocity R̂ v̂ from the body twist's linear part
        rec.extend((0..3).map(|i| {
            Cell::Num(
                (0..3)
                    .map(|j| e.q_hat[i * 4 + j] * e.v_hat[3 + j])
                    .sum::<f64>(),
            )
        }));
    }
    rec.push(Cell::Num(e.estimate_error));
    // the columns are the scenario's (an EqF has them), whatever this tick's values are
    if covariance {
        match e.covariance {
            Some(c) => rec.extend(nums(&c)),
            None => rec.extend([Cell::Empty; 6]),
        }
        rec.push(e.nees.map_or(Cell::Empty, Cell::Num));
    }
}

/// The vehicle columns of `trajectory.csv` (docs/maths.md, "Control allocation"), for `n`
/// wrench components and `m` actuators: `demand_i`, `u_cmd_j`, `u_j`, `achieved_i`,
/// `alloc_status`.
pub fn vehicle_header(n: usize, m: usize) -> Vec<String> {
    let mut h: Vec<String> = (0..n).map(|i| format!("demand_{i}")).collect();
    h.extend((0..m).map(|j| format!("u_cmd_{j}")));
    h.extend((0..m).map(|j| format!("u_{j}")));
    h.extend((0..n).map(|i| format!("achieved_{i}")));
    h.push("alloc_status".to_owned());
    h
}

/// The values of [`vehicle_header`]'s columns for one row.
fn vehicle_fields(v: &crate::trajectory::VehicleRow, n: usize, m: usize, rec: &mut Vec<Cell>) {
    for xs in [&v.demand[..n], &v.u_cmd[..m], &v.u[..m], &v.achieved[..n]] {
        rec.extend(xs.iter().map(|x| Cell::Num(*x)));
    }
    rec.push(Cell::Int(u64::from(v.status)));
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> SimError + '_ {
    move |e| SimError::Run(format!("cannot write {}: {e}", path.display()))
}

fn csv_err(path: &Path) -> impl Fn(csv::Error) -> SimError + '_ {
    move |e| SimError::Run(format!("cannot write {}: {e}", path.display()))
}

/// One cell of `trajectory.csv`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Cell {
    /// A number, written in full round-trip precision ([`num`]).
    Num(f64),
    /// A code or a count.
    Int(u64),
    /// Nothing at this tick (a position fix that did not arrive).
    Empty,
}

impl Cell {
    /// The cell as `trajectory.csv` writes it.
    pub fn text(&self) -> String {
        match self {
            Cell::Num(x) => num(*x),
            Cell::Int(i) => i.to_string(),
            Cell::Empty => String::new(),
        }
    }

    /// The number the CSV's text reads back as (`NaN` for an empty cell): the same bits as
    /// parsing [`Cell::text`].
    pub fn value(&self) -> f64 {
        match self {
            Cell::Num(x) => *x,
            Cell::Int(i) => *i as f64,
            Cell::Empty => f64::NAN,
        }
    }
}

/// The columns `trajectory.csv` has for `traj`, and which optional blocks they hold.
struct Layout {
    n: usize,
    m: usize,
    directions: Option<usize>,
    covariance: bool,
    /// `[estimator] gate = true`: the `health` column.
    health: bool,
    terms: bool,
    vehicle: Option<usize>,
    /// The reaction wheels: their `wheel_speed_i` and `wheel_cmd_i` columns.
    wheels: usize,
    status: bool,
    /// `[failsafe]`: the `failsafe` column.
    failsafe: bool,
    /// The number of columns: every row has exactly this many cells.
    width: usize,
}

impl Layout {
    fn of(traj: &SimulatedTrajectory) -> Layout {
        let (n, m) = traj.dims();
        let mut layout = Layout {
            n,
            m,
            directions: traj.estimator.as_ref().map(|e| e.directions),
            // from the filter's kind, never from its values: a run whose NEES was not finite
            // once had rows wider than its header
            covariance: traj
                .estimator
                .as_ref()
                .is_some_and(|e| e.kind == scenario::EstimatorKind::Eqf.name()),
            health: traj.estimator.as_ref().is_some_and(|e| e.gate.is_some()),
            terms: traj.rows.first().is_some_and(|r| r.terms.is_some()),
            vehicle: traj.rows.first().and_then(|r| r.vehicle).map(|v| v.count),
            wheels: traj
                .rows
                .first()
                .and_then(|r| r.vehicle)
                .map_or(0, |v| v.wheels),
            status: !traj.status.is_empty(),
            failsafe: traj.failsafe.is_some(),
            width: 0,
        };
        layout.width = layout.header().len();
        layout
    }

    fn header(&self) -> Vec<String> {
        let (n, m) = (self.n, self.m);
        let mut header = trajectory_header(n, m);
        if let Some(d) = self.directions {
            header.extend(estimate_header(n, d, n == 4, self.covariance));
        }
        if self.health {
            header.push("health".to_owned());
        }
        if self.terms {
            header.extend((0..m).map(|i| format!("dhat_{i}")));
            header.extend((0..m).map(|i| format!("integral_{i}")));
        }
        if let Some(count) = self.vehicle {
            header.extend(vehicle_header(m, count));
        }
        header.extend((0..self.wheels).map(|i| format!("wheel_speed_{i}")));
        header.extend((0..self.wheels).map(|i| format!("wheel_cmd_{i}")));
        if self.status {
            header.push("command_status".to_owned());
        }
        if self.failsafe {
            header.push("failsafe".to_owned());
        }
        header
    }

    fn cells(
        &self,
        traj: &SimulatedTrajectory,
        k: usize,
        rec: &mut Vec<Cell>,
    ) -> Result<(), SimError> {
        let (n, m) = (self.n, self.m);
        let r = &traj.rows[k];
        rec.clear();
        rec.extend(
            [
                r.t,
                r.lyapunov,
                r.config_error,
                r.momentum_error,
                r.attitude_error,
                r.velocity_error,
                r.torque_norm,
            ]
            .map(Cell::Num),
        );
        for xs in [&r.tau[..m], &r.q[..n * n], &r.v[..m]] {
            rec.extend(xs.iter().map(|x| Cell::Num(*x)));
        }
        if self.directions.is_some() {
            let e = r.estimate.as_ref().ok_or_else(|| {
                SimError::Run(format!("row {k} of a run with sensors has no samples"))
            })?;
            estimate_fields(e, n, self.covariance, rec);
        }
        if self.health {
            // 0 healthy, 1 degraded, 2 lost (docs/estimators.md); empty on a tick without it
            let code = r.estimate.and_then(|e| e.health).map(|h| h.code());
            rec.push(code.map_or(Cell::Empty, |c| Cell::Int(u64::from(c))));
        }
        if self.terms {
            let t = r.terms.unwrap_or(crate::trajectory::Terms {
                observer: [f64::NAN; 6],
                integral: [f64::NAN; 6],
            });
            for xs in [&t.observer[..m], &t.integral[..m]] {
                rec.extend(xs.iter().map(|x| Cell::Num(*x)));
            }
        }
        if let Some(count) = self.vehicle {
            let v = r.vehicle.as_ref().ok_or_else(|| {
                SimError::Run(format!("row {k} of a run with a vehicle has no allocation"))
            })?;
            vehicle_fields(v, m, count, rec);
            for xs in [&v.wheel_speed[..self.wheels], &v.wheel_cmd[..self.wheels]] {
                rec.extend(xs.iter().map(|x| Cell::Num(*x)));
            }
        }
        if self.status {
            rec.push(Cell::Int(u64::from(
                traj.status.get(k).copied().unwrap_or(0),
            )));
        }
        if self.failsafe {
            // the action flown at this tick (docs/failsafe.md, "What a run reports")
            let code = traj.failsafe.as_ref().and_then(|f| f.code(k));
            rec.push(code.map_or(Cell::Empty, |c| Cell::Int(u64::from(c))));
        }
        if rec.len() != self.width {
            return Err(SimError::Run(format!(
                "row {k} has {} cells but the table has {} columns",
                rec.len(),
                self.width
            )));
        }
        Ok(())
    }
}

/// The table `trajectory.csv` holds: its header, then `row(cells)` for each control step in
/// order. The CSV and the Python package's columns are both made from it.
pub fn trajectory_table(
    traj: &SimulatedTrajectory,
    mut row: impl FnMut(&[Cell]) -> Result<(), SimError>,
) -> Result<Vec<String>, SimError> {
    let layout = Layout::of(traj);
    let mut rec = Vec::new();
    for k in 0..traj.rows.len() {
        layout.cells(traj, k, &mut rec)?;
        row(&rec)?;
    }
    Ok(layout.header())
}

/// Writes `trajectory.csv`, one row per control step, numbers in full round-trip precision.
/// A run that has flown never loses its rows to a writing error: when the table cannot be
/// written, the rows are written as they were formed to a rescue file beside it (else in the
/// system's temporary folder), and the error says where.
pub fn write_trajectory_csv(traj: &SimulatedTrajectory, path: &Path) -> Result<(), SimError> {
    write_table(traj, path).map_err(|e| SimError::Run(format!("{e}; {}", rescue(traj, path))))
}

fn write_table(traj: &SimulatedTrajectory, path: &Path) -> Result<(), SimError> {
    let mut w = csv::Writer::from_path(path).map_err(csv_err(path))?;
    let layout = Layout::of(traj);
    w.write_record(layout.header()).map_err(csv_err(path))?;
    let mut rec = Vec::new();
    let mut text: Vec<String> = Vec::new();
    for k in 0..traj.rows.len() {
        layout.cells(traj, k, &mut rec)?;
        text.clear();
        text.extend(rec.iter().map(Cell::text));
        w.write_record(&text).map_err(csv_err(path))?;
    }
    w.flush().map_err(io(path))
}

/// The rescue file of a table that could not be written: `path` with the extension
/// `rescued.csv`, else the same name in the system's temporary folder. Each line holds a row's
/// cells as far as they were formed (lines may differ in width); the first line is the header.
/// Returns what happened, for the error message.
fn rescue(traj: &SimulatedTrajectory, path: &Path) -> String {
    let name = path
        .file_stem()
        .map_or_else(|| "trajectory".into(), |s| s.to_string_lossy().into_owned());
    let file = format!("{name}.rescued.csv");
    let places = [
        path.with_file_name(&file),
        std::env::temp_dir().join(format!("eqtrack-{}-{file}", std::process::id())),
    ];
    for place in &places {
        if write_rescue(traj, place).is_ok() {
            return format!(
                "the run's {} rows were written as formed to {} (header first; a row's line may be shorter or longer than the header)",
                traj.rows.len(),
                place.display()
            );
        }
    }
    format!(
        "the rows could not be rescued either ({} and {} are not writable)",
        places[0].display(),
        places[1].display()
    )
}

fn write_rescue(traj: &SimulatedTrajectory, path: &Path) -> Result<(), SimError> {
    let mut w = csv::WriterBuilder::new()
        .flexible(true)
        .from_path(path)
        .map_err(csv_err(path))?;
    let layout = Layout::of(traj);
    w.write_record(layout.header()).map_err(csv_err(path))?;
    let mut rec = Vec::new();
    for k in 0..traj.rows.len() {
        // whatever the row's cells were when forming it stopped
        let _ = layout.cells(traj, k, &mut rec);
        w.write_record(rec.iter().map(Cell::text))
            .map_err(csv_err(path))?;
    }
    w.flush().map_err(io(path))
}

/// The final errors of a run.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct FinalErrors {
    /// L at t = T.
    pub lyapunov: f64,
    /// ‖Q_E − I‖_F at t = T.
    pub config_error: f64,
    /// ‖p_E‖ at t = T.
    pub momentum_error: f64,
    /// ‖I − R_dᵀR‖_F at t = T.
    pub attitude_error: f64,
    /// ‖V − V_d‖ at t = T.
    pub velocity_error: f64,
}

/// `summary.json` of a simulation.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Summary {
    /// Scenario name.
    pub scenario: String,
    /// Group name.
    pub group: String,
    /// Law name.
    pub law: String,
    /// Where EqT formed its error, when not the papers' world frame (`reference`,
    /// `recentred`; absent: the world frame, or a comparison law).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_frame: Option<String>,
    /// Duration T (s).
    pub duration: f64,
    /// Control period (s).
    pub control_period: f64,
    /// Rows written (N + 1).
    pub rows: usize,
    /// Errors at t = T.
    #[serde(rename = "final")]
    pub final_errors: FinalErrors,
    /// Largest `‖τ_k‖`.
    pub peak_torque: f64,
    /// Largest `|τ_k,i|` over steps and axes.
    pub peak_torque_axis: f64,
    /// `Σ_{t_k < T} ‖τ_k‖·control_period`.
    pub effort: f64,
    /// First time after which attitude_error stays below 0.1 (null: not settled by T).
    pub settling_time: Option<f64>,
    /// The sensors and the estimator (absent: none were simulated).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimator: Option<crate::estimation::EstimatorReport>,
    /// The vehicle: saturation, allocation residual, failures (absent: no `[vehicle]`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vehicle: Option<crate::vehicle::VehicleReport>,
    /// `[failsafe]`: every transition of the manager, in time order (absent: no `[failsafe]`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub failsafe: Option<Vec<crate::failsafe::TransitionReport>>,
}

impl Summary {
    /// Computes the summary of a trajectory.
    pub fn of(traj: &SimulatedTrajectory, scenario: &str, law: &str) -> Summary {
        let (_, m) = traj.dims();
        let last = traj.rows.last().copied();
        let f = |g: fn(&crate::trajectory::Row) -> f64| last.as_ref().map(g).unwrap_or(f64::NAN);
        Summary {
            scenario: scenario.to_owned(),
            group: traj.group.name().to_owned(),
            law: law.to_owned(),
            error_frame: None,
            duration: traj.duration,
            control_period: traj.control_period,
            rows: traj.rows.len(),
            final_errors: FinalErrors {
                lyapunov: f(|r| r.lyapunov),
                config_error: f(|r| r.config_error),
                momentum_error: f(|r| r.momentum_error),
                attitude_error: f(|r| r.attitude_error),
                velocity_error: f(|r| r.velocity_error),
            },
            peak_torque: traj.rows.iter().map(|r| r.torque_norm).fold(0.0, f64::max),
            peak_torque_axis: traj
                .rows
                .iter()
                .flat_map(|r| r.tau[..m].iter().map(|x| x.abs()))
                .fold(0.0, f64::max),
            effort: effort(&traj.rows, traj.control_period, traj.duration),
            settling_time: settling_time(&traj.rows),
            estimator: traj.estimator.clone(),
            vehicle: traj.vehicle.clone(),
            failsafe: traj.failsafe.as_ref().map(|f| f.transitions().to_vec()),
        }
    }

    /// The summary with the scenario's error frame noted (see [`Summary::error_frame`]).
    pub fn with_error_frame(mut self, s: &scenario::Scenario) -> Summary {
        self.error_frame = s.error_frame_note().map(str::to_owned);
        self
    }
}

/// Writes any serialisable summary as pretty JSON.
pub fn write_json<S: Serialize>(value: &S, path: &Path) -> Result<(), SimError> {
    let text = serde_json::to_string_pretty(value)
        .map_err(|e| SimError::Run(format!("cannot encode {}: {e}", path.display())))?;
    std::fs::write(path, text + "\n").map_err(io(path))
}

/// Creates the output directory if needed.
pub fn ensure_dir(dir: &Path) -> Result<(), SimError> {
    std::fs::create_dir_all(dir).map_err(|e| {
        SimError::Run(format!(
            "cannot create output directory {}: {e}",
            dir.display()
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use scenario::Scenario;

    /// A short EqF flight with position fixes (its table has every estimate column).
    fn eqf_flight() -> SimulatedTrajectory {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios");
        let text = std::fs::read_to_string(format!("{dir}/eqf_se3.toml"))
            .unwrap()
            .replace("duration = 60.0", "duration = 0.5");
        let s = Scenario::from_toml(&text, "eqf", "eqf").unwrap();
        crate::trajectory::simulate(&s, &|_| Ok(())).unwrap()
    }

    fn widths(traj: &SimulatedTrajectory) -> (usize, Vec<usize>) {
        let mut rows = Vec::new();
        let header = trajectory_table(traj, |r| {
            rows.push(r.len());
            Ok(())
        })
        .unwrap();
        (header.len(), rows)
    }

    #[test]
    fn a_tables_header_and_rows_agree_whatever_the_filters_values() {
        let mut traj = eqf_flight();
        let (h, rows) = widths(&traj);
        assert!(rows.iter().all(|w| *w == h), "{h} vs {rows:?}");
        // the values that once changed the header: no finite NEES at all (the mean is then
        // not finite and is not reported), and ticks without a covariance
        for (k, r) in traj.rows.iter_mut().enumerate() {
            let e = r.estimate.as_mut().unwrap();
            e.nees = None;
            if k % 3 == 0 {
                e.covariance = None;
            }
        }
        traj.estimator.as_mut().unwrap().mean_nees = None;
        let (h2, rows) = widths(&traj);
        assert_eq!(h2, h, "the header changed with the filter's values");
        assert!(rows.iter().all(|w| *w == h), "{h} vs {rows:?}");
    }

    #[test]
    fn a_table_that_cannot_be_written_leaves_its_rows_in_a_rescue_file_and_says_so() {
        let mut traj = eqf_flight();
        let k = traj.rows.len() / 2;
        traj.rows[k].estimate = None; // a row that cannot be formed
        let dir = std::env::temp_dir().join(format!("eqtrack-rescue-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("trajectory.csv");
        let e = write_trajectory_csv(&traj, &path).unwrap_err().to_string();
        let rescued = dir.join("trajectory.rescued.csv");
        assert!(
            e.contains(&format!("row {k} of a run with sensors has no samples")),
            "{e}"
        );
        assert!(e.contains(&rescued.display().to_string()), "{e}");
        let text = std::fs::read_to_string(&rescued).unwrap();
        assert_eq!(text.lines().count(), traj.rows.len() + 1);
        // the row that failed keeps its time and state
        let line = text.lines().nth(k + 1).unwrap();
        assert!(line.starts_with(&num(traj.rows[k].t)), "{line}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
