//! The plant side's estimator: the sensors ([`crate::sensors`]) sampled from the true body at
//! each tick, the `eqtrack-estimator` crate's filter stepped on them, and the estimate the law is
//! handed (docs/architecture.md, "Sensors and the estimator"). The same code runs in
//! `plant_sim sim` and in the plant of the pair, so lockstep equals the simulation bit for
//! bit.

use crate::SimError;
use crate::sensors::{SampleFault, Sensors};
use crate::trajectory::{EstimateRow, Row};
use eqtrack_controller::group::BuiltinGroup;
use eqtrack_controller::group::so3::log_so3;
use eqtrack_controller::integrator::RigidBody;
use eqtrack_estimator::Filter;
use eqtrack_estimator::health::{Gate, Health};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use scenario::{EstimatorKind, Scenario};
use serde::Serialize;

/// `summary.json` → `estimator`: the sensors, the filter, its faults and its error.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct EstimatorReport {
    /// `truth` or `complementary`.
    pub kind: String,
    /// The sensors' seed.
    pub seed: u64,
    /// Direction sensors.
    pub directions: usize,
    /// What the filter skipped, held and clamped.
    pub faults: eqtrack_estimator::Faults,
    /// Test builds: faults planted in the samples (`--fault-sample`).
    pub planted_faults: u64,
    /// The attitude angle of `R̂ᵀR` at the end (rad).
    pub final_estimate_error: f64,
    /// Its root mean square over the rows (rad).
    pub rms_estimate_error: f64,
    /// Its largest value (rad).
    pub max_estimate_error: f64,
    /// EqF: the normalised estimation error squared of `(R, b)` averaged over the rows
    /// (docs/maths.md, "Consistency"); absent for the other kinds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mean_nees: Option<f64>,
    /// `[estimator] gate = true`: the gate's thresholds, its rejections and the health's
    /// changes; absent without the gate.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gate: Option<GateReport>,
}

/// `summary.json` → `estimator.gate` (docs/estimators.md, "The innovation gate and health").
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct GateReport {
    /// The χ²₂ threshold of a direction sample's NIS.
    pub direction_threshold: f64,
    /// The χ²₃ threshold of a position fix's NIS.
    pub position_threshold: f64,
    /// The health window (ticks).
    pub window: u32,
    /// Rejections within a window that degrade a sensor.
    pub rejections_to_degrade: u32,
    /// Rejections over the run, per sensor (`direction0` …, `accelerometer`, `position`).
    pub rejected: std::collections::BTreeMap<String, u64>,
    /// The χ² band on each direction's summed NIS: `[samples per block, upper bound]`.
    pub direction_band: [f64; 2],
    /// The χ² band on the fixes' summed NIS (SE(3)): `[samples per block, upper bound]`.
    pub position_band: [f64; 2],
    /// Blocks above the band over the run, per sensor.
    pub inconsistent_blocks: std::collections::BTreeMap<String, u64>,
    /// The mean NIS of the samples that passed, after the first window, per sensor: 2 for a
    /// consistent direction, 3 for a fix (absent: none passed).
    pub mean_nis: std::collections::BTreeMap<String, f64>,
    /// Each change of health, in time order.
    pub health: Vec<HealthChange>,
}

/// One change of the estimator's health.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct HealthChange {
    /// When (s).
    pub t: f64,
    /// `healthy`, `degraded` or `lost`.
    pub health: &'static str,
    /// What is wrong (empty when healthy), e.g. `rejected direction0`, `missing position`.
    pub reason: String,
}

/// A source's name in the scenario's spelling (`direction0`, `accelerometer`, `gyro`,
/// `position`, and `attitude` for two usable directions).
pub fn source_name(s: eqtrack_estimator::health::Source) -> String {
    use eqtrack_estimator::health::Source;
    match s {
        Source::Direction(i) => format!("direction{i}"),
        Source::Accelerometer => "accelerometer".to_owned(),
        Source::Gyro => "gyro".to_owned(),
        Source::Position => "position".to_owned(),
        Source::Attitude => "attitude".to_owned(),
    }
}

/// The health's name and its reason in words (`rejected direction0`, `missing gyro`).
pub fn describe(h: &Health) -> (&'static str, String) {
    use eqtrack_estimator::health::Reason;
    let name = match h {
        Health::Healthy => "healthy",
        Health::Degraded(_) => "degraded",
        Health::Lost(_) => "lost",
    };
    let reason = match h.reason() {
        None => String::new(),
        Some(Reason::Rejected(s)) => format!("rejected {}", source_name(s)),
        Some(Reason::Missing(s)) => format!("missing {}", source_name(s)),
        Some(Reason::Reset(s)) => format!("reset {}", source_name(s)),
        Some(Reason::Inconsistent(s)) => format!("inconsistent {}", source_name(s)),
    };
    (name, reason)
}

/// The sensors and the filter of one run.
pub struct Estimation {
    kind: EstimatorKind,
    seed: u64,
    sensors: Sensors,
    /// `None`: the law sees the truth, or (processor in the loop) the controller filters.
    filter: Option<Filter<f64>>,
    /// `[estimator] gate = true`: the innovation gate and health monitor.
    gate: Option<Gate<f64>>,
    period: f64,
    faults: Vec<(u64, SampleFault)>,
    planted: u64,
}

fn bad(e: eqtrack_estimator::EstimatorError) -> SimError {
    SimError::Input(format!("[estimator]: {e}"))
}

impl Estimation {
    /// The scenario's sensors and estimator at control period `period` (`None`: the
    /// scenario simulates no sensors, and the law sees the exact state as always).
    pub fn new(
        s: &Scenario,
        period: f64,
        faults: &[(u64, SampleFault)],
    ) -> Result<Option<Estimation>, SimError> {
        let Some(spec) = &s.sensors else {
            return Ok(None);
        };
        let e = &s.estimator;
        let filter = match s.filter_settings()? {
            None => None,
            Some(settings) => Some(
                settings
                    .build(s.group == eqtrack_controller::GroupKind::Se3)
                    .map_err(bad)?,
            ),
        };
        let gate = s.gate_config().map(|c| {
            Gate::new(
                c,
                spec.directions.len(),
                s.group == eqtrack_controller::GroupKind::Se3,
            )
        });
        Ok(Some(Estimation {
            kind: e.kind,
            seed: spec.seed,
            sensors: Sensors::new(spec, period),
            filter,
            gate,
            period,
            faults: faults.to_vec(),
            planted: 0,
        }))
    }

    /// Tick k: samples the sensors from the true body (`held`: the torque held over the
    /// previous period, plus the disturbance), steps the filter, and returns the state the
    /// law is handed and the row's sensor and estimate columns.
    pub fn measure<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
        &mut self,
        k: u64,
        body: &RigidBody<f64, G, N, M>,
        held: &SVector<f64, M>,
    ) -> (SMatrix<f64, N, N>, SVector<f64, M>, EstimateRow) {
        let samples = self.sample(k, body, held);
        self.estimate(samples, body.configuration(), &body.velocity())
    }

    /// Tick k's samples from the true body (with the test's planted faults), without
    /// stepping a filter: what a controller that estimates on board is sent.
    pub fn sample<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
        &mut self,
        k: u64,
        body: &RigidBody<f64, G, N, M>,
        held: &SVector<f64, M>,
    ) -> crate::sensors::Samples {
        let mut samples = self.sensors.sample(k, body, held);
        for (_, fault) in self.faults.iter().filter(|(fk, _)| *fk == k) {
            fault.apply(&mut samples);
            self.planted += 1;
        }
        samples
    }

    /// Changes the complementary filter's `k_P` and `k_I` from the next tick on (run-time
    /// parameters); nothing to change when the law sees the truth.
    pub fn retune(&mut self, kp: f64, ki: f64) -> Result<(), SimError> {
        match &mut self.filter {
            Some(f) => f.retune(kp, ki).map_err(bad),
            None => Ok(()),
        }
    }

    /// The filter runs on the controller (processor in the loop, docs/pil.md): this side
    /// only samples, and the rows take the estimate the commands come back with.
    pub fn on_board(mut self) -> Estimation {
        self.filter = None;
        self.gate = None;
        self
    }

    /// Whether the innovation gate runs (`[estimator] gate = true`).
    pub fn gated(&self) -> bool {
        self.gate.is_some()
    }

    /// Steps the filter on one tick's `samples` (drawn from the true state `(q, v)`) and
    /// returns the state the law is handed and the row's sensor and estimate columns.
    /// `plant_sim replay` steps the run's filter through it over the recorded samples.
    pub fn estimate<const N: usize, const M: usize>(
        &mut self,
        samples: crate::sensors::Samples,
        q: &SMatrix<f64, N, N>,
        v: &SVector<f64, M>,
    ) -> (SMatrix<f64, N, N>, SVector<f64, M>, EstimateRow) {
        let (q, v) = (*q, *v);
        let h = self.period;
        let dirs = &samples.directions[..samples.count];
        let accel = samples.accel.unwrap_or_else(Vector3::zeros);
        let mut health = None;
        let (q_hat, v_hat, bias, covariance, nees) = match &mut self.filter {
            None => (q, v, Vector3::zeros(), None, None),
            Some(f) => {
                let position = samples.position.as_ref();
                let e = match &mut self.gate {
                    None => f.step::<N, M>(h, &samples.gyro, dirs, &accel, position),
                    Some(g) => {
                        let (e, now) =
                            f.step_gated::<N, M>(g, h, &samples.gyro, dirs, &accel, position);
                        health = Some(now);
                        e
                    }
                };
                let (covariance, nees) = match f.eqf() {
                    Some(eqf) => {
                        let s = eqf.covariance();
                        let r_true = Matrix3::from_fn(|i, j| q[(i, j)]);
                        (
                            Some(std::array::from_fn(|i| s[(i, i)])),
                            eqf.nees(&r_true, &samples.bias),
                        )
                    }
                    None => (None, None),
                };
                (e.q, e.v, e.bias, covariance, nees)
            }
        };
        let mut row = row(samples, &q, &q_hat, &v_hat, &bias, covariance, nees);
        row.health = health;
        (q_hat, v_hat, row)
    }

    /// The report for `summary.json`, with the estimate error over `rows`.
    pub fn report(&self, rows: &[Row]) -> EstimatorReport {
        let errors: Vec<f64> = rows
            .iter()
            .filter_map(|r| r.estimate.map(|e| e.estimate_error))
            .collect();
        let n = errors.len().max(1) as f64;
        let faults = self
            .filter
            .as_ref()
            .map_or_else(eqtrack_estimator::Faults::default, |f| *f.faults());
        let nees: Vec<f64> = rows
            .iter()
            .filter_map(|r| r.estimate.and_then(|e| e.nees))
            .collect();
        let mean_nees = (self.kind == EstimatorKind::Eqf)
            .then(|| nees.iter().sum::<f64>() / nees.len() as f64)
            .filter(|x| x.is_finite());
        EstimatorReport {
            kind: self.kind.name().to_owned(),
            seed: self.seed,
            directions: self.sensors.directions(),
            faults,
            planted_faults: self.planted,
            final_estimate_error: errors.last().copied().unwrap_or(f64::NAN),
            rms_estimate_error: (errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt(),
            max_estimate_error: errors.iter().copied().fold(0.0, f64::max),
            mean_nees,
            gate: self.gate.as_ref().map(|g| gate_report(g, rows)),
        }
    }
}

/// The row's sensor and estimate columns: the samples, the estimate `(Q̂, V̂, b̂)`, its
/// attitude error against the true `q`, and the EqF's covariance and consistency.
pub fn row<const N: usize, const M: usize>(
    samples: crate::sensors::Samples,
    q: &SMatrix<f64, N, N>,
    q_hat: &SMatrix<f64, N, N>,
    v_hat: &SVector<f64, M>,
    bias: &Vector3<f64>,
    covariance: Option<[f64; 6]>,
    nees: Option<f64>,
) -> EstimateRow {
    let rot = |m: &SMatrix<f64, N, N>| Matrix3::from_fn(|i, j| m[(i, j)]);
    let estimate_error = log_so3(&(rot(q_hat).transpose() * rot(q))).norm();
    let mut qh = [0.0; 16];
    let mut vh = [0.0; 6];
    for i in 0..N {
        for j in 0..N {
            qh[i * N + j] = q_hat[(i, j)];
        }
    }
    for i in 0..M {
        vh[i] = v_hat[i];
    }
    EstimateRow {
        samples,
        q_hat: qh,
        v_hat: vh,
        bias_hat: [bias[0], bias[1], bias[2]],
        estimate_error,
        covariance,
        nees,
        health: None,
    }
}

/// The gate's part of the summary: its thresholds, its rejections per sensor, and each
/// change of health over `rows` (from healthy at the start).
fn gate_report(g: &Gate<f64>, rows: &[Row]) -> GateReport {
    let c = g.config();
    let mut health = Vec::new();
    let mut last = Health::Healthy;
    for r in rows {
        if let Some(h) = r.estimate.and_then(|e| e.health)
            && h != last
        {
            let (name, reason) = describe(&h);
            health.push(HealthChange {
                t: r.t,
                health: name,
                reason,
            });
            last = h;
        }
    }
    GateReport {
        direction_threshold: c.direction,
        position_threshold: c.position,
        window: c.window,
        rejections_to_degrade: c.rejections,
        rejected: g.rejections().map(|(s, n)| (source_name(s), n)).collect(),
        direction_band: [f64::from(c.direction_band.samples), c.direction_band.upper],
        position_band: [f64::from(c.position_band.samples), c.position_band.upper],
        inconsistent_blocks: g
            .consistency()
            .map(|(s, n, _)| (source_name(s), n))
            .collect(),
        mean_nis: g
            .consistency()
            .filter_map(|(s, _, m)| Some((source_name(s), m?)))
            .collect(),
        health,
    }
}
