//! A filter from a scenario's numbers, on either group, and one step of it as the law's
//! `(Q̂, V̂)`. The plant side builds it in `f64`; the processor-in-the-loop firmware in `f32`
//! from the same numbers cast once, so both run the same construction and the same step.

use crate::health::{Gate, Health, Verdicts};
use crate::{
    AttitudeConfig, AttitudeFilter, ComplementaryConfig, ComplementaryFilter, EqfConfig,
    EquivariantFilter, EstimatorError, Faults, MAX_DIRECTIONS, PoseConfig, PoseFilter,
};
use eqtrack_controller::Real;
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// The filter's kind and its own numbers (docs/maths.md, "Estimators").
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FilterKind<T: Real> {
    /// The complementary filter: `k_P`, `k_I`, and the weights (one per direction, and on
    /// SE(3) one more, last, for the accelerometer; the first `count` used).
    Complementary {
        /// `k_P` (1/s).
        kp: T,
        /// `k_I` (1/s²).
        ki: T,
        /// The weights.
        weights: [T; MAX_DIRECTIONS + 1],
        /// How many weights.
        count: usize,
    },
    /// The equivariant filter's noise model and start.
    Eqf {
        /// `σ_ω` (rad/s/√Hz).
        gyro_noise: T,
        /// `σ_b` (rad/s²/√Hz).
        bias_walk: T,
        /// Each direction's noise (and on SE(3) the accelerometer's, last).
        direction_noise: [T; MAX_DIRECTIONS + 1],
        /// How many noises.
        count: usize,
        /// The attitude's standard deviation at the start (rad).
        initial_attitude_std: T,
        /// The bias's standard deviation at the start (rad/s).
        initial_bias_std: T,
    },
}

/// Everything a filter is built from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings<T: Real> {
    /// The kind and its numbers.
    pub kind: FilterKind<T>,
    /// The direction sensors' world directions (the first `directions` used).
    pub world: [Vector3<T>; MAX_DIRECTIONS],
    /// How many direction sensors.
    pub directions: usize,
    /// The attitude to start from (`None`: TRIAD).
    pub initial_attitude: Option<Matrix3<T>>,
    /// Clamp of each bias component (rad/s).
    pub bias_limit: Option<T>,
    /// SE(3): the accelerometer's gate (m/s²).
    pub accel_gate: Option<T>,
    /// SE(3): the accelerometer's noise (m/s² per sample; 0: none).
    pub accel_noise: T,
    /// SE(3): the position fixes' noise (m; 0: none).
    pub position_noise: T,
}

/// A filter of either kind on either group.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Filter<T: Real> {
    /// The complementary filter on SO(3).
    Complementary(ComplementaryFilter<T>),
    /// The equivariant filter on SO(3).
    Eqf(EquivariantFilter<T>),
    /// SE(3): the complementary filter and the Kalman filter.
    Pose(PoseFilter<T>),
    /// SE(3): the equivariant filter and the Kalman filter.
    PoseEqf(PoseFilter<T, EqfConfig<T>>),
}

/// One step's estimate as the law's state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step<T: Real, const N: usize, const M: usize> {
    /// `Q̂`.
    pub q: SMatrix<T, N, N>,
    /// `V̂`.
    pub v: SVector<T, M>,
    /// `b̂`.
    pub bias: Vector3<T>,
}

impl<T: Real> Settings<T> {
    /// The filter of these settings on SO(3) (`se3 = false`) or SE(3), checked by the
    /// builders of [`ComplementaryConfig`], [`EqfConfig`] and [`PoseConfig`].
    pub fn build(&self, se3: bool) -> Result<Filter<T>, EstimatorError> {
        let world = &self.world[..self.directions.min(MAX_DIRECTIONS)];
        Ok(match (self.kind, se3) {
            (
                FilterKind::Complementary {
                    kp,
                    ki,
                    weights,
                    count,
                },
                false,
            ) => {
                let cfg = ComplementaryConfig::new(kp, ki, world, &weights[..count.min(5)])?;
                Filter::Complementary(ComplementaryFilter::new(self.attitude_start(cfg)?))
            }
            (
                FilterKind::Complementary {
                    kp,
                    ki,
                    weights,
                    count,
                },
                true,
            ) => {
                let mut cfg = PoseConfig::new(
                    kp,
                    ki,
                    world,
                    &weights[..count.min(5)],
                    self.accel_noise,
                    self.position_noise,
                )?;
                if let Some(g) = self.accel_gate {
                    cfg = cfg.accel_gate(g)?;
                }
                cfg.attitude = self.attitude_start(cfg.attitude)?;
                Filter::Pose(PoseFilter::new(cfg))
            }
            (FilterKind::Eqf { .. }, false) => {
                let (gyro, walk, noise) = self.eqf_noise();
                let cfg = EqfConfig::new(gyro, walk, world, noise)?;
                Filter::Eqf(EquivariantFilter::new(self.eqf_start(cfg)?))
            }
            (FilterKind::Eqf { .. }, true) => {
                let (gyro, walk, noise) = self.eqf_noise();
                let mut cfg = PoseConfig::eqf(
                    gyro,
                    walk,
                    world,
                    noise,
                    self.accel_noise,
                    self.position_noise,
                )?;
                cfg.attitude = self.eqf_start(cfg.attitude)?;
                if let Some(g) = self.accel_gate {
                    cfg = cfg.accel_gate(g)?;
                }
                Filter::PoseEqf(PoseFilter::new(cfg))
            }
        })
    }

    /// The complementary filter's clamp and start.
    fn attitude_start(
        &self,
        mut cfg: ComplementaryConfig<T>,
    ) -> Result<ComplementaryConfig<T>, EstimatorError> {
        if let Some(l) = self.bias_limit {
            cfg = cfg.bias_limit(l)?;
        }
        if let Some(r) = self.initial_attitude {
            cfg = cfg.initial_attitude(r)?;
        }
        Ok(cfg)
    }

    fn eqf_noise(&self) -> (T, T, &[T]) {
        match &self.kind {
            FilterKind::Eqf {
                gyro_noise,
                bias_walk,
                direction_noise,
                count,
                ..
            } => (
                *gyro_noise,
                *bias_walk,
                &direction_noise[..(*count).min(MAX_DIRECTIONS + 1)],
            ),
            FilterKind::Complementary { .. } => (T::zero(), T::zero(), &[]),
        }
    }

    /// The EqF's start standard deviations, clamp and start attitude.
    fn eqf_start(&self, cfg: EqfConfig<T>) -> Result<EqfConfig<T>, EstimatorError> {
        let (a, b) = match self.kind {
            FilterKind::Eqf {
                initial_attitude_std,
                initial_bias_std,
                ..
            } => (initial_attitude_std, initial_bias_std),
            FilterKind::Complementary { .. } => return Ok(cfg),
        };
        let mut cfg = cfg.initial_std(a, b)?;
        if let Some(l) = self.bias_limit {
            cfg = cfg.bias_limit(l)?;
        }
        if let Some(r) = self.initial_attitude {
            cfg = cfg.initial_attitude(r)?;
        }
        Ok(cfg)
    }
}

impl<T: Real> Filter<T> {
    /// One tick on the samples (SO(3) filters ignore `accel` and `position`), as the law's
    /// `(Q̂, V̂)` on a group of `N × N` matrices and `M` velocities: `(R̂, ω − b̂)` on SO(3),
    /// `([R̂ x̂; 0 1], (ω − b̂, R̂ᵀ v̂))` on SE(3).
    pub fn step<const N: usize, const M: usize>(
        &mut self,
        h: T,
        gyro: &Vector3<T>,
        directions: &[Vector3<T>],
        accel: &Vector3<T>,
        position: Option<&Vector3<T>>,
    ) -> Step<T, N, M> {
        match self {
            Filter::Complementary(f) => attitude_step(f.step(h, gyro, directions)),
            Filter::Eqf(f) => attitude_step(f.step(h, gyro, directions)),
            Filter::Pose(f) => pose_step(f.step(h, gyro, directions, accel, position)),
            Filter::PoseEqf(f) => pose_step(f.step(h, gyro, directions, accel, position)),
        }
    }

    /// [`Filter::step`] behind the innovation gate, and the gate's health monitor stepped
    /// (docs/estimators.md, "The innovation gate and health"): samples that fail the gate
    /// are skipped as unusable ones are. Returns the step and the health after it.
    pub fn step_gated<const N: usize, const M: usize>(
        &mut self,
        gate: &mut Gate<T>,
        h: T,
        gyro: &Vector3<T>,
        directions: &[Vector3<T>],
        accel: &Vector3<T>,
        position: Option<&Vector3<T>>,
    ) -> (Step<T, N, M>, Health) {
        fn attitude<T: Real, F: AttitudeFilter<T>>(
            f: &mut F,
            gate: &Gate<T>,
            h: T,
            gyro: &Vector3<T>,
            directions: &[Vector3<T>],
        ) -> (crate::AttitudeEstimate<T>, Verdicts<T>) {
            let n = f.config().count();
            let mut y = crate::complementary::usable(directions, n, f.faults_mut());
            let mut v = Verdicts::default();
            gate.directions(f, h, gyro, &mut y, &mut v);
            (f.step_usable(h, gyro, &y), v)
        }
        let (step, verdicts) = match self {
            Filter::Complementary(f) => {
                let (e, v) = attitude(f, gate, h, gyro, directions);
                (attitude_step(e), v)
            }
            Filter::Eqf(f) => {
                let (e, v) = attitude(f, gate, h, gyro, directions);
                (attitude_step(e), v)
            }
            Filter::Pose(f) => {
                let (e, v) = f.step_with(Some(gate), h, gyro, directions, accel, position);
                (pose_step(e), v)
            }
            Filter::PoseEqf(f) => {
                let (e, v) = f.step_with(Some(gate), h, gyro, directions, accel, position);
                (pose_step(e), v)
            }
        };
        let health = gate.observe(verdicts, gyro.iter().all(|x| x.is_finite()));
        (step, health)
    }

    /// Changes the complementary filter's `k_P` and `k_I` from the next step on (SO(3), or
    /// the attitude part of SE(3)); the estimate carries over. The EqF has no such gains:
    /// [`EstimatorError::BadGain`].
    pub fn retune(&mut self, kp: T, ki: T) -> Result<(), EstimatorError> {
        match self {
            Filter::Complementary(f) => f.set_gains(kp, ki),
            Filter::Pose(p) => p.attitude_mut().set_gains(kp, ki),
            Filter::Eqf(_) | Filter::PoseEqf(_) => Err(EstimatorError::BadGain("kp")),
        }
    }

    /// What it has skipped, held and clamped.
    pub fn faults(&self) -> &Faults {
        match self {
            Filter::Complementary(f) => f.faults(),
            Filter::Eqf(f) => f.faults(),
            Filter::Pose(f) => f.faults(),
            Filter::PoseEqf(f) => f.faults(),
        }
    }

    /// The equivariant filter, where it runs (its covariance and consistency).
    pub fn eqf(&self) -> Option<&EquivariantFilter<T>> {
        match self {
            Filter::Eqf(f) => Some(f),
            Filter::PoseEqf(f) => Some(f.attitude()),
            _ => None,
        }
    }
}

/// An attitude estimate as the law's `(Q̂, V̂) = (R̂, ω − b̂)` on SO(3).
fn attitude_step<T: Real, const N: usize, const M: usize>(
    e: crate::AttitudeEstimate<T>,
) -> Step<T, N, M> {
    Step {
        q: SMatrix::from_fn(|i, j| e.r[(i, j)]),
        v: SVector::from_fn(|i, _| e.rate[i]),
        bias: e.bias,
    }
}

/// A pose estimate as the law's `([R̂ x̂; 0 1], (ω − b̂, R̂ᵀ v̂))` on SE(3).
fn pose_step<T: Real, const N: usize, const M: usize>(e: crate::PoseEstimate<T>) -> Step<T, N, M> {
    let lin = e.body_velocity();
    Step {
        q: SMatrix::from_fn(|i, j| match (i, j) {
            (3, 3) => T::one(),
            (3, _) => T::zero(),
            (_, 3) => e.x[i],
            _ => e.r[(i, j)],
        }),
        v: SVector::from_fn(|i, _| if i < 3 { e.rate[i] } else { lin[i - 3] }),
        bias: e.bias,
    }
}
