//! The plant side's estimator: the sensors ([`crate::sensors`]) sampled from the true body at
//! each tick, the `estimator` crate's filter stepped on them, and the estimate the law is
//! handed (docs/architecture.md, "Sensors and the estimator"). The same code runs in
//! `plant_sim sim` and in the plant of the pair, so lockstep equals the simulation bit for
//! bit.

use crate::SimError;
use crate::sensors::{SampleFault, Sensors};
use crate::trajectory::{EstimateRow, Row};
use controller::group::MatrixLieGroup;
use controller::group::so3::{exp_so3, log_so3};
use controller::integrator::RigidBody;
use estimator::{
    ComplementaryConfig, ComplementaryFilter, EqfConfig, EquivariantFilter, PoseConfig, PoseFilter,
};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use scenario::{EqfSpec, EstimatorKind, EstimatorSpec, Scenario, SensorsSpec};
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
    pub faults: estimator::Faults,
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
}

enum Filter {
    Truth,
    Attitude(Box<ComplementaryFilter<f64>>),
    Pose(Box<PoseFilter<f64>>),
    Eqf(Box<EquivariantFilter<f64>>),
    PoseEqf(Box<PoseFilter<f64, EqfConfig<f64>>>),
}

/// The sensors and the filter of one run.
pub struct Estimation {
    kind: EstimatorKind,
    seed: u64,
    sensors: Sensors,
    filter: Filter,
    period: f64,
    faults: Vec<(u64, SampleFault)>,
    planted: u64,
}

fn bad(e: estimator::EstimatorError) -> SimError {
    SimError::Input(format!("[estimator]: {e}"))
}

/// What a filter is built from: the scenario's `[estimator]` table and its sensors.
struct FilterInputs<'a> {
    e: &'a EstimatorSpec,
    /// The direction sensors' world directions.
    world: Vec<Vector3<f64>>,
    /// The filter's start attitude, if the scenario gives one (else TRIAD).
    initial: Option<Matrix3<f64>>,
    /// The accelerometer's noise (0: none).
    accel: f64,
    /// The position sensor's noise (0: none).
    position: f64,
}

impl<'a> FilterInputs<'a> {
    fn of(s: &'a Scenario, spec: &SensorsSpec) -> Self {
        FilterInputs {
            e: &s.estimator,
            world: spec
                .directions
                .iter()
                .map(|d| Vector3::from(d.world))
                .collect(),
            initial: s
                .estimator
                .initial_attitude
                .map(|r| exp_so3(&Vector3::from(r))),
            accel: spec.accelerometer.unwrap_or(0.0),
            position: spec.position.map_or(0.0, |p| p.noise),
        }
    }

    /// The filter of the scenario's kind on `group`.
    fn build(&self, group: controller::GroupKind) -> Result<Filter, SimError> {
        use controller::GroupKind::{Se3, So3};
        Ok(match (self.e.kind, group) {
            (EstimatorKind::Truth, _) => Filter::Truth,
            (EstimatorKind::Complementary, So3) => self.complementary()?,
            (EstimatorKind::Complementary, Se3) => self.pose()?,
            (EstimatorKind::Eqf, So3) => self.eqf()?,
            (EstimatorKind::Eqf, Se3) => self.pose_eqf()?,
        })
    }

    /// The complementary filter on SO(3).
    fn complementary(&self) -> Result<Filter, SimError> {
        let e = self.e;
        let mut cfg = ComplementaryConfig::new(e.kp, e.ki, &self.world, &e.weights).map_err(bad)?;
        if let Some(l) = e.bias_limit {
            cfg = cfg.bias_limit(l).map_err(bad)?;
        }
        if let Some(r) = self.initial {
            cfg = cfg.initial_attitude(r).map_err(bad)?;
        }
        Ok(Filter::Attitude(Box::new(ComplementaryFilter::new(cfg))))
    }

    /// The pose filter on SE(3): the complementary filter's attitude and a Kalman filter.
    fn pose(&self) -> Result<Filter, SimError> {
        let e = self.e;
        let mut cfg = PoseConfig::new(
            e.kp,
            e.ki,
            &self.world,
            &e.weights,
            self.accel,
            self.position,
        )
        .map_err(bad)?;
        if let Some(g) = e.accel_gate {
            cfg = cfg.accel_gate(g).map_err(bad)?;
        }
        if let Some(l) = e.bias_limit {
            cfg.attitude = cfg.attitude.bias_limit(l).map_err(bad)?;
        }
        if let Some(r) = self.initial {
            cfg.attitude = cfg.attitude.initial_attitude(r).map_err(bad)?;
        }
        Ok(Filter::Pose(Box::new(PoseFilter::new(cfg))))
    }

    /// The EqF's noise model (`kind = "eqf"` needs it).
    fn eqf_spec(&self) -> Result<&'a EqfSpec, SimError> {
        self.e.eqf.as_ref().ok_or_else(|| {
            SimError::Input("[estimator]: kind = \"eqf\" without its noise model".into())
        })
    }

    /// The start and the clamp, on either group's attitude filter.
    fn eqf_start(&self, cfg: EqfConfig<f64>) -> Result<EqfConfig<f64>, SimError> {
        let q = self.eqf_spec()?;
        let mut cfg = cfg
            .initial_std(q.initial_attitude_std, q.initial_bias_std)
            .map_err(bad)?;
        if let Some(l) = self.e.bias_limit {
            cfg = cfg.bias_limit(l).map_err(bad)?;
        }
        if let Some(r) = self.initial {
            cfg = cfg.initial_attitude(r).map_err(bad)?;
        }
        Ok(cfg)
    }

    /// The equivariant filter on SO(3).
    fn eqf(&self) -> Result<Filter, SimError> {
        let q = self.eqf_spec()?;
        let cfg = EqfConfig::new(q.gyro_noise, q.bias_walk, &self.world, &q.direction_noise)
            .map_err(bad)?;
        Ok(Filter::Eqf(Box::new(EquivariantFilter::new(
            self.eqf_start(cfg)?,
        ))))
    }

    /// The pose filter on SE(3) with the EqF for its attitude.
    fn pose_eqf(&self) -> Result<Filter, SimError> {
        let q = self.eqf_spec()?;
        let mut cfg = PoseConfig::eqf(
            q.gyro_noise,
            q.bias_walk,
            &self.world,
            &q.direction_noise,
            self.accel,
            self.position,
        )
        .map_err(bad)?;
        cfg.attitude = self.eqf_start(cfg.attitude)?;
        if let Some(g) = self.e.accel_gate {
            cfg = cfg.accel_gate(g).map_err(bad)?;
        }
        Ok(Filter::PoseEqf(Box::new(PoseFilter::new(cfg))))
    }
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
        let filter = FilterInputs::of(s, spec).build(s.group)?;
        Ok(Some(Estimation {
            kind: e.kind,
            seed: spec.seed,
            sensors: Sensors::new(spec, period),
            filter,
            period,
            faults: faults.to_vec(),
            planted: 0,
        }))
    }

    /// Tick k: samples the sensors from the true body (`held`: the torque held over the
    /// previous period, plus the disturbance), steps the filter, and returns the state the
    /// law is handed and the row's sensor and estimate columns.
    pub fn measure<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
        &mut self,
        k: u64,
        body: &RigidBody<f64, G, N, M>,
        held: &SVector<f64, M>,
    ) -> (SMatrix<f64, N, N>, SVector<f64, M>, EstimateRow) {
        let mut samples = self.sensors.sample(k, body, held);
        for (_, fault) in self.faults.iter().filter(|(fk, _)| *fk == k) {
            fault.apply(&mut samples);
            self.planted += 1;
        }
        self.estimate(samples, body.configuration(), &body.velocity())
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
        let pose = |e: estimator::PoseEstimate<f64>| {
            let lin = e.body_velocity();
            (
                SMatrix::from_fn(|i, j| match (i, j) {
                    (3, 3) => 1.0,
                    (3, _) => 0.0,
                    (_, 3) => e.x[i],
                    _ => e.r[(i, j)],
                }),
                SVector::from_fn(|i, _| if i < 3 { e.rate[i] } else { lin[i - 3] }),
                e.bias,
            )
        };
        let attitude = |e: estimator::AttitudeEstimate<f64>| {
            (
                SMatrix::from_fn(|i, j| e.r[(i, j)]),
                SVector::from_fn(|i, _| e.rate[i]),
                e.bias,
            )
        };
        let accel = samples.accel.unwrap_or_else(Vector3::zeros);
        let r_true = Matrix3::from_fn(|i, j| q[(i, j)]);
        let consistency = |f: &EquivariantFilter<f64>| {
            let s = f.covariance();
            (
                Some(std::array::from_fn(|i| s[(i, i)])),
                f.nees(&r_true, &samples.bias),
            )
        };
        let ((q_hat, v_hat, bias), (covariance, nees)) = match &mut self.filter {
            Filter::Truth => ((q, v, Vector3::zeros()), (None, None)),
            Filter::Attitude(f) => (attitude(f.step(h, &samples.gyro, dirs)), (None, None)),
            Filter::Pose(f) => {
                let e = f.step(h, &samples.gyro, dirs, &accel, samples.position.as_ref());
                (pose(e), (None, None))
            }
            Filter::Eqf(f) => {
                let e = f.step(h, &samples.gyro, dirs);
                (attitude(e), consistency(f))
            }
            Filter::PoseEqf(f) => {
                let e = f.step(h, &samples.gyro, dirs, &accel, samples.position.as_ref());
                (pose(e), consistency(f.attitude()))
            }
        };
        let rot = |m: &SMatrix<f64, N, N>| Matrix3::from_fn(|i, j| m[(i, j)]);
        let estimate_error = log_so3(&(rot(&q_hat).transpose() * rot(&q))).norm();
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
        let row = EstimateRow {
            samples,
            q_hat: qh,
            v_hat: vh,
            bias_hat: [bias[0], bias[1], bias[2]],
            estimate_error,
            covariance,
            nees,
        };
        (q_hat, v_hat, row)
    }

    /// The report for `summary.json`, with the estimate error over `rows`.
    pub fn report(&self, rows: &[Row]) -> EstimatorReport {
        let errors: Vec<f64> = rows
            .iter()
            .filter_map(|r| r.estimate.map(|e| e.estimate_error))
            .collect();
        let n = errors.len().max(1) as f64;
        let faults = match &self.filter {
            Filter::Truth => estimator::Faults::default(),
            Filter::Attitude(f) => *f.faults(),
            Filter::Pose(f) => *f.faults(),
            Filter::Eqf(f) => *f.faults(),
            Filter::PoseEqf(f) => *f.faults(),
        };
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
        }
    }
}
