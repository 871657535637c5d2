//! SE(3): attitude by the complementary filter (the accelerometer one more direction, "up"),
//! position and velocity by a linear Kalman filter driven by the accelerometer and corrected
//! by position fixes (docs/maths.md, "Position and velocity on SE(3)").

use crate::complementary::{ComplementaryConfig, ComplementaryFilter, SLOTS};
use crate::{EstimatorError, Faults, GRAVITY, MAX_DIRECTIONS, MIN_DIRECTION_NORM, all_finite};
use controller::{Real, real};
use nalgebra::{Matrix2, Matrix3, Vector3};

/// Gains, noise and guards of a [`PoseFilter`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseConfig<T: Real> {
    /// The attitude filter's configuration; its last direction is the accelerometer's
    /// "up", `(0, 0, 1)`.
    pub attitude: ComplementaryConfig<T>,
    /// Skip the accelerometer as a direction when `| |f| − g |` exceeds this (m/s²).
    pub accel_gate: Option<T>,
    /// The accelerometer's noise, standard deviation per sample and axis (m/s²): the
    /// Kalman filter's process noise.
    pub accel_noise: T,
    /// A position fix's noise, standard deviation per axis (m).
    pub position_noise: T,
    /// The position's standard deviation before the first fix (m).
    pub initial_position_std: T,
    /// The velocity's standard deviation at the start (m/s).
    pub initial_velocity_std: T,
}

impl<T: Real> PoseConfig<T> {
    /// Gains `k_P`, `k_I`; the world directions of the direction sensors (at least one, at
    /// most [`MAX_DIRECTIONS`]) and their weights followed by the accelerometer's; the
    /// accelerometer's and the position fixes' noise. No gate, no bias limit, TRIAD start,
    /// initial standard deviations 1 m and 1 m/s.
    pub fn new(
        kp: T,
        ki: T,
        world: &[Vector3<T>],
        weights: &[T],
        accel_noise: T,
        position_noise: T,
    ) -> Result<Self, EstimatorError> {
        if world.is_empty() || world.len() > MAX_DIRECTIONS || weights.len() != world.len() + 1 {
            return Err(EstimatorError::DirectionCount {
                given: world.len(),
                min: 1,
                max: MAX_DIRECTIONS,
            });
        }
        let mut all = [Vector3::zeros(); SLOTS];
        all[..world.len()].copy_from_slice(world);
        all[world.len()] = Vector3::z();
        let attitude =
            ComplementaryConfig::with_slots(kp, ki, &all[..=world.len()], weights, SLOTS)?;
        for (name, x) in [
            ("accel_noise", accel_noise),
            ("position_noise", position_noise),
        ] {
            if !x.is_finite() || x < T::zero() {
                return Err(EstimatorError::BadGain(name));
            }
        }
        Ok(PoseConfig {
            attitude,
            accel_gate: None,
            accel_noise,
            position_noise,
            initial_position_std: T::one(),
            initial_velocity_std: T::one(),
        })
    }

    /// Skips the accelerometer as a direction when `| |f| − g |` exceeds `gate` (m/s²).
    pub fn accel_gate(mut self, gate: T) -> Result<Self, EstimatorError> {
        if !gate.is_finite() || gate <= T::zero() {
            return Err(EstimatorError::BadGain("accel_gate"));
        }
        self.accel_gate = Some(gate);
        Ok(self)
    }
}

/// The covariance of one axis' (position, velocity), shared by the three axes (their models
/// are the same).
pub type TranslationCovariance<T> = Matrix2<T>;

/// What the pose filter publishes at a tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseEstimate<T: Real> {
    /// `R̂`.
    pub r: Matrix3<T>,
    /// `x̂` (world, m).
    pub x: Vector3<T>,
    /// `v̂` (world, m/s).
    pub v: Vector3<T>,
    /// `ω_k − b̂_k` (body, rad/s).
    pub rate: Vector3<T>,
    /// `b̂_k`.
    pub bias: Vector3<T>,
    /// The covariance of each axis' (position, velocity).
    pub covariance: TranslationCovariance<T>,
    /// False until the attitude filter has started.
    pub started: bool,
}

impl<T: Real> PoseEstimate<T> {
    /// The body linear velocity `R̂ᵀ v̂`: with `rate` the twist `V̂ = (ω_k − b̂, R̂ᵀv̂)` the
    /// law is handed.
    pub fn body_velocity(&self) -> Vector3<T> {
        self.r.tr_mul(&self.v)
    }
}

/// Attitude, bias, position and velocity from a gyro, direction sensors, an accelerometer and
/// position fixes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseFilter<T: Real> {
    cfg: PoseConfig<T>,
    attitude: ComplementaryFilter<T>,
    estimate: PoseEstimate<T>,
    translation_started: bool,
}

impl<T: Real> PoseFilter<T> {
    /// A filter that starts at its first step.
    pub fn new(cfg: PoseConfig<T>) -> Self {
        let attitude = ComplementaryFilter::new(cfg.attitude);
        PoseFilter {
            estimate: PoseEstimate {
                r: Matrix3::identity(),
                x: Vector3::zeros(),
                v: Vector3::zeros(),
                rate: Vector3::zeros(),
                bias: cfg.attitude.initial_bias,
                covariance: Matrix2::zeros(),
                started: false,
            },
            cfg,
            attitude,
            translation_started: false,
        }
    }

    /// What it has skipped, held and clamped so far.
    pub fn faults(&self) -> &Faults {
        self.attitude.faults()
    }

    /// One tick (docs/maths.md, "Position and velocity on SE(3)"): the attitude filter's
    /// step with the accelerometer as the direction "up" (unless gated or not finite), then
    /// the Kalman filter's prediction over `h` with `a = R̂_k f_k + g` and, when a fix came,
    /// its update. The first step starts both (the position from the fix, if one came).
    pub fn step(
        &mut self,
        h: T,
        gyro: &Vector3<T>,
        directions: &[Vector3<T>],
        accel: &Vector3<T>,
        position: Option<&Vector3<T>>,
    ) -> PoseEstimate<T> {
        let n = self.cfg.attitude.count - 1;
        let mut y = self.attitude.usable(directions, n);
        let accel_ok = all_finite(accel);
        let g: T = real(GRAVITY);
        let norm = accel.norm();
        if !accel_ok || norm < real(MIN_DIRECTION_NORM) {
            self.attitude.faults_mut().accel += 1;
        } else if self
            .cfg
            .accel_gate
            .is_some_and(|gate| (norm - g).abs() > gate)
        {
            self.attitude.faults_mut().accel_gated += 1;
        } else {
            y[n] = Some(accel / norm);
        }
        let att = self.attitude.step_usable(h, gyro, &y);
        let fix = match position {
            Some(p) if all_finite(p) => Some(*p),
            Some(_) => {
                self.attitude.faults_mut().position += 1;
                None
            }
            None => None,
        };
        if !self.translation_started {
            let (x0, sx) = match fix {
                Some(p) => (p, self.cfg.position_noise),
                None => (Vector3::zeros(), self.cfg.initial_position_std),
            };
            self.estimate.x = x0;
            self.estimate.v = Vector3::zeros();
            let sv = self.cfg.initial_velocity_std;
            self.estimate.covariance = Matrix2::new(sx * sx, T::zero(), T::zero(), sv * sv);
            self.translation_started = true;
        } else if h.is_finite() && h > T::zero() {
            let a = if accel_ok {
                att.r * accel - Vector3::z() * g
            } else {
                Vector3::zeros()
            };
            self.predict(h, &a);
            if let Some(z) = fix {
                self.update(&z);
            }
        }
        self.estimate.r = att.r;
        self.estimate.rate = att.rate;
        self.estimate.bias = att.bias;
        self.estimate.started = att.started;
        self.estimate
    }

    /// `x ← x + h v + h²/2 a`, `v ← v + h a`; `P ← F P Fᵀ + σ_a² G Gᵀ` with
    /// `F = [[1, h], [0, 1]]`, `G = (h²/2, h)`.
    fn predict(&mut self, h: T, a: &Vector3<T>) {
        let half: T = real(0.5);
        let e = &mut self.estimate;
        e.x += e.v * h + a * (half * h * h);
        e.v += a * h;
        let f = Matrix2::new(T::one(), h, T::zero(), T::one());
        let gq = nalgebra::Vector2::new(half * h * h, h);
        let sa2 = self.cfg.accel_noise * self.cfg.accel_noise;
        e.covariance = f * e.covariance * f.transpose() + gq * gq.transpose() * sa2;
    }

    /// The update with a fix `z` (`H = [1, 0]`, noise `σ_p²`, floored at 1e-12 m²), in
    /// Joseph form so the covariance stays symmetric positive definite.
    fn update(&mut self, z: &Vector3<T>) {
        let e = &mut self.estimate;
        let rp = (self.cfg.position_noise * self.cfg.position_noise).max(real(1e-12));
        let p = e.covariance;
        let s = p[(0, 0)] + rp;
        if !s.is_finite() || s <= T::zero() {
            return;
        }
        let k = nalgebra::Vector2::new(p[(0, 0)] / s, p[(1, 0)] / s);
        let innovation = z - e.x;
        e.x += innovation * k[0];
        e.v += innovation * k[1];
        let ikh = Matrix2::new(T::one() - k[0], T::zero(), -k[1], T::one());
        let joseph = ikh * p * ikh.transpose() + k * k.transpose() * rp;
        e.covariance = (joseph + joseph.transpose()) * real::<T>(0.5);
    }
}
