//! The explicit complementary filter on SO(3) with gyro bias, after Mahony, Hamel and
//! Pflimlin, "Nonlinear complementary filters on the special orthogonal group", IEEE TAC
//! 53(5), 2008 (docs/maths.md, "The complementary filter on SO(3)").

use crate::{EstimatorError, Faults, MAX_DIRECTIONS, MIN_DIRECTION_NORM, all_finite, triad};
use controller::group::so3::exp_so3;
use controller::{Real, real};
use nalgebra::{Matrix3, Vector3};

/// Direction slots: the sensors' directions and, on SE(3), the accelerometer.
pub(crate) const SLOTS: usize = MAX_DIRECTIONS + 1;

/// Gains, directions and guards of a [`ComplementaryFilter`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComplementaryConfig<T: Real> {
    /// `k_P` (1/s): how hard the directions pull the attitude.
    pub kp: T,
    /// `k_I` (1/s²): how fast the bias estimate follows.
    pub ki: T,
    /// The unit world directions `d_i` (the first `count` used).
    pub world: [Vector3<T>; SLOTS],
    /// The weights `k_i` (the first `count` used).
    pub weights: [T; SLOTS],
    /// How many directions.
    pub count: usize,
    /// Clamp of each bias component (rad/s); `None`: no clamp.
    pub bias_limit: Option<T>,
    /// The attitude to start from; `None`: TRIAD from the first two usable directions.
    pub initial_attitude: Option<Matrix3<T>>,
    /// The bias estimate to start from.
    pub initial_bias: Vector3<T>,
}

impl<T: Real> ComplementaryConfig<T> {
    /// Gains `k_P`, `k_I`, world directions (normalised here) and their weights, at least two
    /// and at most [`MAX_DIRECTIONS`]; no bias limit, TRIAD start, zero initial bias.
    pub fn new(kp: T, ki: T, world: &[Vector3<T>], weights: &[T]) -> Result<Self, EstimatorError> {
        Self::with_slots(kp, ki, world, weights, MAX_DIRECTIONS)
    }

    pub(crate) fn with_slots(
        kp: T,
        ki: T,
        world: &[Vector3<T>],
        weights: &[T],
        max: usize,
    ) -> Result<Self, EstimatorError> {
        if !kp.is_finite() || kp < T::zero() {
            return Err(EstimatorError::BadGain("kp"));
        }
        if !ki.is_finite() || ki < T::zero() {
            return Err(EstimatorError::BadGain("ki"));
        }
        if world.len() < 2 || world.len() > max || weights.len() != world.len() {
            return Err(EstimatorError::DirectionCount {
                given: world.len().max(weights.len()),
                min: 2,
                max,
            });
        }
        let mut cfg = ComplementaryConfig {
            kp,
            ki,
            world: [Vector3::zeros(); SLOTS],
            weights: [T::zero(); SLOTS],
            count: world.len(),
            bias_limit: None,
            initial_attitude: None,
            initial_bias: Vector3::zeros(),
        };
        for (i, (d, w)) in world.iter().zip(weights).enumerate() {
            let n = d.norm();
            if !all_finite(d) || n < real(MIN_DIRECTION_NORM) {
                return Err(EstimatorError::BadDirection(i));
            }
            if !w.is_finite() || *w <= T::zero() {
                return Err(EstimatorError::BadWeight(i));
            }
            cfg.world[i] = d / n;
            cfg.weights[i] = *w;
        }
        Ok(cfg)
    }

    /// Clamps each bias component to `±limit` (rad/s).
    pub fn bias_limit(mut self, limit: T) -> Result<Self, EstimatorError> {
        if !limit.is_finite() || limit <= T::zero() {
            return Err(EstimatorError::BadGain("bias_limit"));
        }
        self.bias_limit = Some(limit);
        Ok(self)
    }

    /// Starts from this attitude (a rotation) instead of TRIAD.
    pub fn initial_attitude(mut self, r: Matrix3<T>) -> Result<Self, EstimatorError> {
        let err = (r.transpose() * r - Matrix3::identity()).norm();
        if !r.iter().all(|x| x.is_finite()) || err > real(1e-3) || r.determinant() < T::zero() {
            return Err(EstimatorError::BadInitialState);
        }
        self.initial_attitude = Some(r);
        Ok(self)
    }

    /// Starts from this bias estimate.
    pub fn initial_bias(mut self, b: Vector3<T>) -> Result<Self, EstimatorError> {
        if !all_finite(&b) {
            return Err(EstimatorError::BadInitialState);
        }
        self.initial_bias = b;
        Ok(self)
    }
}

/// What the filter publishes at a tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttitudeEstimate<T: Real> {
    /// `R̂_k` (identity until the filter has started).
    pub r: Matrix3<T>,
    /// `V̂_k = ω_k − b̂_k`: the body rate the law is handed.
    pub rate: Vector3<T>,
    /// `b̂_k`.
    pub bias: Vector3<T>,
    /// False until the filter has an attitude (TRIAD needs two usable, non-parallel
    /// directions).
    pub started: bool,
}

/// The filter's state: `R̂`, `b̂`, and what it has counted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComplementaryFilter<T: Real> {
    cfg: ComplementaryConfig<T>,
    estimate: AttitudeEstimate<T>,
    faults: Faults,
}

/// The usable, normalised samples of a tick (`None`: skipped).
pub(crate) type Directions<T> = [Option<Vector3<T>>; SLOTS];

impl<T: Real> ComplementaryFilter<T> {
    /// A filter that starts at its first step.
    pub fn new(cfg: ComplementaryConfig<T>) -> Self {
        ComplementaryFilter {
            estimate: AttitudeEstimate {
                r: Matrix3::identity(),
                rate: Vector3::zeros(),
                bias: cfg.initial_bias,
                started: false,
            },
            cfg,
            faults: Faults::default(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &ComplementaryConfig<T> {
        &self.cfg
    }

    /// What it has skipped, held and clamped so far.
    pub fn faults(&self) -> &Faults {
        &self.faults
    }

    pub(crate) fn faults_mut(&mut self) -> &mut Faults {
        &mut self.faults
    }

    /// The estimate published last.
    pub fn estimate(&self) -> &AttitudeEstimate<T> {
        &self.estimate
    }

    /// Checks and normalises the first `n` direction samples (`directions[i]` for world
    /// direction `i`; missing ones count as skipped).
    pub(crate) fn usable(&mut self, directions: &[Vector3<T>], n: usize) -> Directions<T> {
        let mut out = [None; SLOTS];
        for (i, slot) in out.iter_mut().enumerate().take(n) {
            *slot = directions.get(i).and_then(|y| {
                let n = y.norm();
                (all_finite(y) && n >= real(MIN_DIRECTION_NORM)).then(|| y / n)
            });
            if slot.is_none() {
                self.faults.directions += 1;
            }
        }
        out
    }

    /// One tick with gyro sample `ω_k` and direction samples `y_{i,k}` (body frame, in the
    /// configuration's order), `h` the time since the last tick
    /// (docs/maths.md, "The complementary filter on SO(3)"):
    ///
    /// ```text
    /// ω_mes = Σ_i k_i ( ŷ_{i,k} × R̂_{k−1}ᵀ d_i )          ŷ = y/|y|
    /// R̂_k = R̂_{k−1} exp( h (ω_k − b̂_{k−1} + k_P ω_mes) )
    /// b̂_k = b̂_{k−1} − h k_I ω_mes
    /// ```
    ///
    /// publishing `R̂_k` and `ω_k − b̂_k`. The first step starts the filter instead (the given
    /// attitude, or TRIAD). A direction with a non-finite entry or of zero length is skipped;
    /// a non-finite gyro sample holds the previous estimate; both are counted. The estimate
    /// is never non-finite.
    pub fn step(
        &mut self,
        h: T,
        gyro: &Vector3<T>,
        directions: &[Vector3<T>],
    ) -> AttitudeEstimate<T> {
        let y = self.usable(directions, self.cfg.count);
        self.step_usable(h, gyro, &y)
    }

    /// [`ComplementaryFilter::step`] on checked, normalised samples.
    pub(crate) fn step_usable(
        &mut self,
        h: T,
        gyro: &Vector3<T>,
        y: &Directions<T>,
    ) -> AttitudeEstimate<T> {
        let gyro_ok = all_finite(gyro);
        if !gyro_ok {
            self.faults.gyro += 1;
        }
        if !self.estimate.started {
            self.start(y);
            if gyro_ok {
                self.estimate.rate = gyro - self.estimate.bias;
            }
            return self.estimate;
        }
        if !gyro_ok || !h.is_finite() || h <= T::zero() {
            return self.estimate;
        }
        let (r, b) = (self.estimate.r, self.estimate.bias);
        let mut w_mes = Vector3::zeros();
        let c = &self.cfg;
        for ((yi, d), k) in y.iter().zip(&c.world).zip(&c.weights).take(c.count) {
            if let Some(yi) = yi {
                w_mes += yi.cross(&r.tr_mul(d)) * *k;
            }
        }
        let step = (gyro - b + w_mes * self.cfg.kp) * h;
        let r_next = orthonormalise(&(r * exp_so3(&step)));
        let mut b_next = b - w_mes * (h * self.cfg.ki);
        if let Some(l) = self.cfg.bias_limit {
            for x in b_next.iter_mut() {
                if *x > l || *x < -l {
                    *x = x.clamp(-l, l);
                    self.faults.bias_clamped += 1;
                }
            }
        }
        // the samples were checked, so this holds unless they were huge; never publish less
        if r_next.iter().all(|x| x.is_finite()) && all_finite(&b_next) {
            self.estimate.r = r_next;
            self.estimate.bias = b_next;
            self.estimate.rate = gyro - b_next;
        }
        self.estimate
    }

    /// Starts from the configured attitude, or TRIAD from the first two usable,
    /// non-parallel directions (in order).
    fn start(&mut self, y: &Directions<T>) {
        if let Some(r) = self.cfg.initial_attitude {
            self.estimate.r = r;
            self.estimate.started = true;
            return;
        }
        let n = self.cfg.count;
        for i in 0..n {
            for j in i + 1..n {
                if let (Some(a), Some(b)) = (y[i], y[j])
                    && let Some(r) = triad(&a, &b, &self.cfg.world[i], &self.cfg.world[j])
                {
                    self.estimate.r = orthonormalise(&r);
                    self.estimate.started = true;
                    return;
                }
            }
        }
    }
}

/// The nearest-by-Gram–Schmidt rotation to `r` (columns 0 and 1 orthonormalised, the third
/// their cross product): keeps `R̂` a rotation in f32 over millions of steps.
pub(crate) fn orthonormalise<T: Real>(r: &Matrix3<T>) -> Matrix3<T> {
    let c0 = r.column(0).into_owned();
    let c0 = c0 / c0.norm();
    let c1 = r.column(1).into_owned();
    let c1 = c1 - c0 * c0.dot(&c1);
    let c1 = c1 / c1.norm();
    Matrix3::from_columns(&[c0, c1, c0.cross(&c1)])
}
