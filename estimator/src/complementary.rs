//! The explicit complementary filter on SO(3) with gyro bias, after Mahony, Hamel and
//! Pflimlin, "Nonlinear complementary filters on the special orthogonal group", IEEE TAC
//! 53(5), 2008 (docs/maths.md, "The complementary filter on SO(3)").

use crate::{EstimatorError, Faults, MAX_DIRECTIONS, StateEstimate, all_finite, direction, triad};
use eqtrack_controller::group::so3::exp_so3;
use eqtrack_controller::{Real, real};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// The builders both attitude filters' configurations share: `bias_limit`,
/// `initial_attitude`, `initial_bias`, each checking its value.
macro_rules! start_builders {
    () => {
        /// Clamps each bias component to `±limit` (rad/s).
        pub fn bias_limit(mut self, limit: T) -> Result<Self, EstimatorError> {
            self.bias_limit = Some(checked_limit(limit)?);
            Ok(self)
        }

        /// Starts from this attitude (a rotation) instead of TRIAD.
        pub fn initial_attitude(mut self, r: Matrix3<T>) -> Result<Self, EstimatorError> {
            self.initial_attitude = Some(checked_rotation(r)?);
            Ok(self)
        }

        /// Starts from this bias estimate.
        pub fn initial_bias(mut self, b: Vector3<T>) -> Result<Self, EstimatorError> {
            self.initial_bias = checked_bias(b)?;
            Ok(self)
        }
    };
}
pub(crate) use start_builders;

/// The accessors both attitude filters share (fields `cfg`, `faults`, `estimate`):
/// `try_new`, `config`, `faults`, `faults_mut`, `estimate`.
macro_rules! filter_accessors {
    ($config:ident) => {
        /// A filter on a configuration checked again first (`check` of its configuration).
        pub fn try_new(cfg: $config<T>) -> Result<Self, EstimatorError> {
            Ok(Self::new(cfg.check()?))
        }

        /// The configuration.
        pub fn config(&self) -> &$config<T> {
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
    };
}
pub(crate) use filter_accessors;

/// Direction slots: the sensors' directions and, on SE(3), the accelerometer.
pub(crate) const SLOTS: usize = MAX_DIRECTIONS + 1;

/// Gains, directions and guards of a [`ComplementaryFilter`].
///
/// Build it with [`ComplementaryConfig::new`] and the builder methods, which check every
/// value. The fields are public to be read; a configuration whose fields were written
/// directly is checked again by [`ComplementaryConfig::check`] (and
/// [`ComplementaryFilter::try_new`]).
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
    ///
    /// Errors: [`EstimatorError::BadGain`] (`"kp"`, `"ki"`: negative or not finite),
    /// [`EstimatorError::DirectionCount`], [`EstimatorError::WeightCount`] (one weight per
    /// direction), [`EstimatorError::BadDirection`] (shorter than
    /// [`MIN_DIRECTION_NORM`](crate::MIN_DIRECTION_NORM), or not finite),
    /// [`EstimatorError::BadWeight`] (not finite and positive).
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
        if world.len() < 2 || world.len() > max {
            return Err(EstimatorError::DirectionCount {
                given: world.len(),
                min: 2,
                max,
            });
        }
        if weights.len() != world.len() {
            return Err(EstimatorError::WeightCount {
                expected: world.len(),
                given: weights.len(),
            });
        }
        let count = world.len();
        let (world, weights) = checked_directions(world, weights, EstimatorError::BadWeight)?;
        Ok(ComplementaryConfig {
            kp,
            ki,
            world,
            weights,
            count,
            bias_limit: None,
            initial_attitude: None,
            initial_bias: Vector3::zeros(),
        })
    }

    start_builders!();

    /// Checks again a configuration whose public fields may have been written directly, and
    /// normalises its world directions: the same checks as [`ComplementaryConfig::new`] and
    /// the builder methods, with up to `MAX_DIRECTIONS + 1` directions (the SE(3) filter's
    /// accelerometer takes the last slot).
    pub fn check(self) -> Result<Self, EstimatorError> {
        let n = checked_count(self.count)?;
        let mut c = Self::with_slots(
            self.kp,
            self.ki,
            &self.world[..n],
            &self.weights[..n],
            SLOTS,
        )?;
        if let Some(l) = self.bias_limit {
            c = c.bias_limit(l)?;
        }
        if let Some(r) = self.initial_attitude {
            c = c.initial_attitude(r)?;
        }
        c.initial_bias(self.initial_bias)
    }
}

/// What the filter publishes at a tick: `Q̂ = R̂`, `V̂ = ω − b̂` ([`StateEstimate`] on
/// SO(3)).
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

impl<T: Real> StateEstimate<T, 3, 3> for AttitudeEstimate<T> {
    fn q_hat(&self) -> SMatrix<T, 3, 3> {
        self.r
    }
    fn v_hat(&self) -> SVector<T, 3> {
        self.rate
    }
}

/// The filter's state: `R̂`, `b̂`, and what it has counted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComplementaryFilter<T: Real> {
    cfg: ComplementaryConfig<T>,
    estimate: AttitudeEstimate<T>,
    faults: Faults,
}

pub(crate) use crate::Directions;

impl<T: Real> ComplementaryFilter<T> {
    /// A filter that starts at its first step. `cfg` is used as it is (from the checked
    /// constructors it is valid; never a panic either way: a `count` beyond the capacity is
    /// cut to it). [`ComplementaryFilter::try_new`] checks it first.
    pub fn new(mut cfg: ComplementaryConfig<T>) -> Self {
        cfg.count = cfg.count.min(SLOTS);
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

    filter_accessors!(ComplementaryConfig);

    /// Changes `k_P` and `k_I` from the next step on, checked as
    /// [`ComplementaryConfig::new`] checks them (an error changes nothing); the estimate and
    /// the bias carry over (run-time parameters, docs/live.md, "Tuning a running pair").
    pub fn set_gains(&mut self, kp: T, ki: T) -> Result<(), EstimatorError> {
        if !kp.is_finite() || kp < T::zero() {
            return Err(EstimatorError::BadGain("kp"));
        }
        if !ki.is_finite() || ki < T::zero() {
            return Err(EstimatorError::BadGain("ki"));
        }
        self.cfg.kp = kp;
        self.cfg.ki = ki;
        Ok(())
    }

    /// Checks and normalises the first `n` direction samples (see [`usable`]).
    pub(crate) fn usable(&mut self, directions: &[Vector3<T>], n: usize) -> Directions<T> {
        usable(directions, n, &mut self.faults)
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
    /// publishing `R̂_k` and `ω_k − b̂_k`, then re-orthonormalising `R̂_k`
    /// (docs/maths.md, "The complementary filter on SO(3)").
    ///
    /// The first step starts the filter instead and publishes without propagating: `R̂_0` is
    /// the configured attitude, or TRIAD from the first two usable, non-parallel directions
    /// (in list order), and `b̂_0` the configured initial bias. If TRIAD has no such pair the
    /// filter has not started: it publishes the identity with `started == false` (and
    /// `ω_k − b̂_0`) and tries again at the next call.
    ///
    /// Guards, each counted in [`Faults`]: a direction with a non-finite entry, a length
    /// that overflows or shorter than [`MIN_DIRECTION_NORM`](crate::MIN_DIRECTION_NORM) (or
    /// missing from `directions`) is skipped for this tick; a gyro sample with a non-finite
    /// entry holds the previous estimate; so does a period `h` that is not finite and
    /// positive, or an update that comes out non-finite; with a bias limit each bias
    /// component is clamped to it. The estimate is never non-finite and the call never
    /// panics.
    ///
    /// A body at rest, seen by a gyro with a bias and two exact direction sensors: the first
    /// step starts the filter at the true attitude (TRIAD), and the bias is learnt (200 s).
    ///
    /// ```
    /// use eqtrack_controller::group::{MatrixLieGroup, So3};
    /// use eqtrack_estimator::{ComplementaryConfig, ComplementaryFilter};
    /// use nalgebra::Vector3;
    ///
    /// let world = [Vector3::z(), Vector3::new(0.5, 0.0, 0.866)];
    /// let r = So3::exp(&Vector3::new(0.3, -0.4, 0.2));
    /// let samples = [r.tr_mul(&world[0]), r.tr_mul(&world[1].normalize())];
    /// let bias = Vector3::new(0.02, -0.01, 0.03);
    /// let cfg = ComplementaryConfig::new(1.0, 0.3, &world, &[1.0, 1.0]).expect("valid gains");
    /// let mut filter = ComplementaryFilter::new(cfg);
    /// let first = filter.step(0.01, &bias, &samples);
    /// assert!(first.started && (first.r - r).norm() < 1e-9);
    /// let mut last = first;
    /// for _ in 0..20_000 {
    ///     last = filter.step(0.01, &bias, &samples); // the gyro reads only its bias
    /// }
    /// assert!((last.bias - bias).norm() < 1e-4 && last.rate.norm() < 1e-4);
    /// ```
    pub fn step(
        &mut self,
        h: T,
        gyro: &Vector3<T>,
        directions: &[Vector3<T>],
    ) -> AttitudeEstimate<T> {
        let y = self.usable(directions, self.cfg.count);
        self.step_usable(h, gyro, &y)
    }

    /// The gate's prior: `R̂_{k−1}`, the attitude tick k's samples are compared with; no
    /// covariance.
    pub(crate) fn prior(
        &self,
        _h: T,
        _gyro: &Vector3<T>,
    ) -> Option<(Matrix3<T>, Option<Matrix3<T>>)> {
        self.estimate.started.then_some((self.estimate.r, None))
    }

    /// No noise model: the gate tests against the sensors' ([`crate::health::GateConfig`]).
    pub(crate) fn noise(&self, _slot: usize) -> T {
        T::zero()
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
            let rate = gyro - self.estimate.bias;
            if all_finite(&rate) {
                self.estimate.rate = rate;
            }
            return self.estimate;
        }
        if !gyro_ok {
            return self.estimate;
        }
        if !h.is_finite() || h <= T::zero() {
            self.faults.held += 1;
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
        let mut clamped = 0;
        if let Some(l) = self.cfg.bias_limit {
            for x in b_next.iter_mut() {
                if *x > l || *x < -l {
                    *x = x.clamp(-l, l);
                    clamped += 1;
                }
            }
        }
        let rate = gyro - b_next;
        // the samples were checked, so this holds unless they were huge: never publish less
        if r_next.iter().all(|x| x.is_finite()) && all_finite(&b_next) && all_finite(&rate) {
            self.estimate.r = r_next;
            self.estimate.bias = b_next;
            self.estimate.rate = rate;
            self.faults.bias_clamped += clamped;
        } else {
            self.faults.held += 1;
        }
        self.estimate
    }

    /// Starts from the configured attitude, or TRIAD (see [`first_attitude`]).
    fn start(&mut self, y: &Directions<T>) {
        let c = &self.cfg;
        if let Some(r) = first_attitude(c.initial_attitude, &c.world, c.count, y) {
            self.estimate.r = r;
            self.estimate.started = true;
        }
    }
}

/// A bias limit: finite and > 0 (`BadGain("bias_limit")`).
pub(crate) fn checked_limit<T: Real>(limit: T) -> Result<T, EstimatorError> {
    if !limit.is_finite() || limit <= T::zero() {
        return Err(EstimatorError::BadGain("bias_limit"));
    }
    Ok(limit)
}

/// A starting attitude: finite, orthonormal within 1e-3 and proper (`BadInitialState`).
pub(crate) fn checked_rotation<T: Real>(r: Matrix3<T>) -> Result<Matrix3<T>, EstimatorError> {
    let err = (r.transpose() * r - Matrix3::identity()).norm();
    if !r.iter().all(|x| x.is_finite()) || err > real(1e-3) || r.determinant() < T::zero() {
        return Err(EstimatorError::BadInitialState);
    }
    Ok(r)
}

/// A starting bias: finite (`BadInitialState`).
pub(crate) fn checked_bias<T: Real>(b: Vector3<T>) -> Result<Vector3<T>, EstimatorError> {
    if !all_finite(&b) {
        return Err(EstimatorError::BadInitialState);
    }
    Ok(b)
}

/// The slot count of a configuration checked again: 2 to [`SLOTS`].
pub(crate) fn checked_count(n: usize) -> Result<usize, EstimatorError> {
    if !(2..=SLOTS).contains(&n) {
        return Err(EstimatorError::DirectionCount {
            given: n,
            min: 2,
            max: SLOTS,
        });
    }
    Ok(n)
}

/// The unit world directions and their positive values (a filter's weights or noises), in
/// slots: `BadDirection(i)` for a zero or non-finite direction, `bad_value(i)` for a value
/// that is not finite and positive. `world` and `values` have the same length, at most
/// [`SLOTS`] (the callers check both).
pub(crate) fn checked_directions<T: Real>(
    world: &[Vector3<T>],
    values: &[T],
    bad_value: fn(usize) -> EstimatorError,
) -> Result<([Vector3<T>; SLOTS], [T; SLOTS]), EstimatorError> {
    let mut units = [Vector3::zeros(); SLOTS];
    let mut out = [T::zero(); SLOTS];
    for (i, (d, w)) in world.iter().zip(values).enumerate().take(SLOTS) {
        let Some((unit, _)) = direction(d) else {
            return Err(EstimatorError::BadDirection(i));
        };
        if !w.is_finite() || *w <= T::zero() {
            return Err(bad_value(i));
        }
        units[i] = unit;
        out[i] = *w;
    }
    Ok((units, out))
}

/// Checks and normalises the first `n` direction samples (`directions[i]` for world
/// direction `i`; missing ones count as skipped in `faults.directions`, extra ones are
/// ignored).
pub(crate) fn usable<T: Real>(
    directions: &[Vector3<T>],
    n: usize,
    faults: &mut Faults,
) -> Directions<T> {
    let mut out = [None; SLOTS];
    for (i, slot) in out.iter_mut().enumerate().take(n) {
        *slot = directions.get(i).and_then(|y| direction(y).map(|(u, _)| u));
        if slot.is_none() {
            faults.directions += 1;
        }
    }
    out
}

/// A filter's first attitude: the configured one, or TRIAD from the first two usable,
/// non-parallel directions (in order; docs/maths.md, "TRIAD"), re-orthonormalised; `None`
/// when there is no such pair yet.
pub(crate) fn first_attitude<T: Real>(
    configured: Option<Matrix3<T>>,
    world: &[Vector3<T>; SLOTS],
    count: usize,
    y: &Directions<T>,
) -> Option<Matrix3<T>> {
    if configured.is_some() {
        return configured;
    }
    let n = count.min(SLOTS);
    for i in 0..n {
        for j in i + 1..n {
            if let (Some(a), Some(b)) = (y[i], y[j])
                && let Some(r) = triad(&a, &b, &world[i], &world[j])
            {
                return Some(orthonormalise(&r));
            }
        }
    }
    None
}

/// Gram–Schmidt on `r`'s first two columns, the third their cross product: a rotation within
/// rounding of `r` when `r` is within rounding of one. Keeps `R̂` a rotation over millions of
/// steps (docs/maths.md, "The complementary filter on SO(3)").
pub(crate) fn orthonormalise<T: Real>(r: &Matrix3<T>) -> Matrix3<T> {
    let c0 = r.column(0).into_owned();
    let c0 = c0 / eqtrack_controller::hw_sqrt::norm(&c0);
    let c1 = r.column(1).into_owned();
    let c1 = c1 - c0 * c0.dot(&c1);
    let c1 = c1 / eqtrack_controller::hw_sqrt::norm(&c1);
    Matrix3::from_columns(&[c0, c1, c0.cross(&c1)])
}

#[cfg(test)]
mod tests {

    #[test]
    fn set_gains_checks_and_keeps_the_estimate() {
        let world = [Vector3::new(0.0, 0.0, 1.0), Vector3::new(1.0, 0.0, 0.0)];
        let cfg = ComplementaryConfig::new(1.0, 0.3, &world, &[1.0, 1.0]).unwrap();
        let mut f = ComplementaryFilter::new(cfg);
        let before = *f.estimate();
        for (kp, ki) in [
            (f64::NAN, 0.3),
            (-1.0, 0.3),
            (1.0, f64::INFINITY),
            (1.0, -0.1),
        ] {
            assert!(f.set_gains(kp, ki).is_err());
            assert_eq!((f.config().kp, f.config().ki), (1.0, 0.3));
        }
        f.set_gains(2.0, 0.5).unwrap();
        assert_eq!((f.config().kp, f.config().ki), (2.0, 0.5));
        assert_eq!(*f.estimate(), before);
    }

    use super::*;
    use eqtrack_controller::group::so3::exp_so3;

    #[test]
    fn orthonormalise_keeps_a_rotation_and_repairs_a_perturbed_one() {
        let r = exp_so3(&Vector3::new(0.3, -1.2, 2.0));
        // a rotation comes back within rounding (measured 1.0e-15)
        let e = (orthonormalise(&r) - r).norm();
        assert!(e < 1e-14, "{e}");
        // a perturbed one comes back a rotation, within the perturbation
        let p = r + Matrix3::from_fn(|i, j| 1e-4 * ((i * 3 + j) as f64 - 4.0));
        let q = orthonormalise(&p);
        assert!((q.transpose() * q - Matrix3::identity()).norm() < 1e-15);
        assert!((q.determinant() - 1.0).abs() < 1e-15);
        assert!((q - r).norm() < 1e-3);
    }

    #[test]
    fn a_direction_is_unit_or_refused() {
        let (u, n) = crate::direction(&Vector3::new(3.0, 0.0, 4.0)).unwrap();
        assert_eq!((u, n), (Vector3::new(0.6, 0.0, 0.8), 5.0));
        for bad in [
            Vector3::zeros(),
            Vector3::new(0.0, 1e-7, 0.0),
            Vector3::new(f64::NAN, 1.0, 0.0),
            Vector3::new(0.0, f64::NEG_INFINITY, 0.0),
            Vector3::repeat(1e200),
        ] {
            assert!(crate::direction(&bad).is_none(), "{bad}");
        }
        assert!(
            crate::direction(&Vector3::repeat(1e20f32)).is_none(),
            "f32 overflow"
        );
    }
}
