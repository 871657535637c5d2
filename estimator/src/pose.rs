//! SE(3): attitude by the complementary filter or the equivariant filter (the accelerometer
//! one more direction, "up"),
//! position and velocity by a linear Kalman filter driven by the accelerometer and corrected
//! by position fixes (docs/maths.md, "Position and velocity on SE(3)").

use crate::complementary::{ComplementaryConfig, SLOTS, usable};
use crate::eqf::EqfConfig;
use crate::{
    AttitudeConfig, AttitudeFilter, EstimatorError, Faults, GRAVITY, MAX_DIRECTIONS, StateEstimate,
    all_finite, direction,
};
use eqtrack_controller::group::se3::from_parts;
use eqtrack_controller::{Real, real};
use nalgebra::{Matrix2, Matrix3, SMatrix, SVector, Vector2, Vector3};

/// Gains, noise and guards of a [`PoseFilter`].
///
/// Build it with [`PoseConfig::new`] and the builder methods (the attitude part's builders,
/// e.g. `cfg.attitude = cfg.attitude.bias_limit(0.1)?`), which check every value; a
/// configuration whose fields were written directly is checked again by
/// [`PoseConfig::check`] (and [`PoseFilter::try_new`]).
///
/// `C` is the attitude filter's configuration: [`ComplementaryConfig`] (the default,
/// [`PoseConfig::new`]) or [`EqfConfig`] ([`PoseConfig::eqf`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseConfig<T: Real, C = ComplementaryConfig<T>> {
    /// The attitude filter's configuration; its last direction is the accelerometer's
    /// "up", `(0, 0, 1)`.
    pub attitude: C,
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
    ///
    /// Errors: those of [`ComplementaryConfig::new`] (a world direction's index is its
    /// place in `world`, the accelerometer's is `world.len()`), and
    /// [`EstimatorError::BadGain`] (`"accel_noise"`, `"position_noise"`: negative or not
    /// finite).
    pub fn new(
        kp: T,
        ki: T,
        world: &[Vector3<T>],
        weights: &[T],
        accel_noise: T,
        position_noise: T,
    ) -> Result<Self, EstimatorError> {
        counts(world.len(), weights.len())?;
        let all = with_up(world);
        let attitude =
            ComplementaryConfig::with_slots(kp, ki, &all[..=world.len()], weights, SLOTS)?;
        Self::around(attitude, accel_noise, position_noise)
    }
}

/// One to [`MAX_DIRECTIONS`] world directions, and one value (weight or noise) per direction
/// and one more, last, for the accelerometer.
fn counts(world: usize, values: usize) -> Result<(), EstimatorError> {
    if world == 0 || world > MAX_DIRECTIONS {
        return Err(EstimatorError::DirectionCount {
            given: world,
            min: 1,
            max: MAX_DIRECTIONS,
        });
    }
    if values != world + 1 {
        return Err(EstimatorError::WeightCount {
            expected: world + 1,
            given: values,
        });
    }
    Ok(())
}

/// The world directions followed by "up", `(0, 0, 1)`, the accelerometer's.
fn with_up<T: Real>(world: &[Vector3<T>]) -> [Vector3<T>; SLOTS] {
    let mut all = [Vector3::zeros(); SLOTS];
    let n = world.len().min(MAX_DIRECTIONS);
    all[..n].copy_from_slice(&world[..n]);
    all[n] = Vector3::z();
    all
}

impl<T: Real> PoseConfig<T, EqfConfig<T>> {
    /// The equivariant filter for the attitude: the gyro's noise density and bias walk; the
    /// world directions of the direction sensors (at least one, at most [`MAX_DIRECTIONS`])
    /// and their noises followed by the accelerometer's as a direction (unitless; its
    /// specific-force noise over `g` is the natural value); the accelerometer's and the
    /// position fixes' noise. Defaults as [`EqfConfig::new`] and [`PoseConfig::new`].
    ///
    /// Errors: those of [`EqfConfig::new`] (a world direction's index is its place in
    /// `world`, the accelerometer's is `world.len()`), and [`EstimatorError::BadGain`]
    /// (`"accel_noise"`, `"position_noise"`).
    pub fn eqf(
        gyro_noise: T,
        bias_walk: T,
        world: &[Vector3<T>],
        direction_noise: &[T],
        accel_noise: T,
        position_noise: T,
    ) -> Result<Self, EstimatorError> {
        counts(world.len(), direction_noise.len())?;
        let all = with_up(world);
        let attitude = EqfConfig::with_slots(
            gyro_noise,
            bias_walk,
            &all[..=world.len()],
            direction_noise,
            SLOTS,
        )?;
        Self::around(attitude, accel_noise, position_noise)
    }
}

impl<T: Real, C: AttitudeConfig<T>> PoseConfig<T, C> {
    /// The translation's defaults around an attitude configuration.
    fn around(attitude: C, accel_noise: T, position_noise: T) -> Result<Self, EstimatorError> {
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

    /// The standard deviations of position (m) and velocity (m/s) at the start (finite and
    /// positive; the position's is replaced by the fix's noise when the first call brings a
    /// fix).
    pub fn initial_std(mut self, position: T, velocity: T) -> Result<Self, EstimatorError> {
        if !position.is_finite() || position <= T::zero() {
            return Err(EstimatorError::BadGain("initial_position_std"));
        }
        if !velocity.is_finite() || velocity <= T::zero() {
            return Err(EstimatorError::BadGain("initial_velocity_std"));
        }
        self.initial_position_std = position;
        self.initial_velocity_std = velocity;
        Ok(self)
    }

    /// Checks again a configuration whose public fields may have been written directly:
    /// the same checks as [`PoseConfig::new`] and the builders, and the attitude part's last
    /// direction must be "up", `(0, 0, 1)`.
    pub fn check(self) -> Result<Self, EstimatorError> {
        let attitude = self.attitude.check()?;
        let up = attitude.count() - 1;
        if (attitude.world(up) - Vector3::z()).norm() > real(1e-12) {
            return Err(EstimatorError::BadDirection(up));
        }
        for (name, x) in [
            ("accel_noise", self.accel_noise),
            ("position_noise", self.position_noise),
        ] {
            if !x.is_finite() || x < T::zero() {
                return Err(EstimatorError::BadGain(name));
            }
        }
        let mut c = PoseConfig { attitude, ..self }
            .initial_std(self.initial_position_std, self.initial_velocity_std)?;
        if let Some(g) = self.accel_gate {
            c = c.accel_gate(g)?;
        }
        Ok(c)
    }
}

/// The floor of the position fix's variance and of the initial variances (m², m²/s²): keeps
/// the covariance positive definite when a noise is configured as zero.
pub const MIN_VARIANCE: f64 = 1e-12;

/// The covariance of one axis' (position, velocity), shared by the three axes (their models
/// are the same).
pub type TranslationCovariance<T> = Matrix2<T>;

/// What the pose filter publishes at a tick: `Q̂ = (R̂, x̂)`, `V̂ = (ω − b̂, R̂ᵀv̂)`
/// ([`StateEstimate`] on SE(3)).
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

    /// `Q̂ = [[R̂, x̂], [0, 1]]`.
    pub fn pose(&self) -> SMatrix<T, 4, 4> {
        from_parts(&self.r, &self.x)
    }

    /// `V̂ = (ω_k − b̂_k, R̂ᵀv̂)`, ordered (ω, v) as `eqtrack_controller::group::Se3`'s twists.
    pub fn twist(&self) -> SVector<T, 6> {
        let v = self.body_velocity();
        SVector::<T, 6>::new(self.rate[0], self.rate[1], self.rate[2], v[0], v[1], v[2])
    }
}

impl<T: Real> StateEstimate<T, 4, 6> for PoseEstimate<T> {
    fn q_hat(&self) -> SMatrix<T, 4, 4> {
        self.pose()
    }
    fn v_hat(&self) -> SVector<T, 6> {
        self.twist()
    }
}

/// Attitude, bias, position and velocity from a gyro, direction sensors, an accelerometer and
/// position fixes.
///
/// `C` is the attitude filter's configuration, which names the filter:
/// [`ComplementaryConfig`] (the default) for the [`ComplementaryFilter`](crate::ComplementaryFilter), [`EqfConfig`] for
/// the [`EquivariantFilter`](crate::EquivariantFilter).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseFilter<T: Real, C: AttitudeConfig<T> = ComplementaryConfig<T>> {
    cfg: PoseConfig<T, C>,
    attitude: C::Filter,
    estimate: PoseEstimate<T>,
    translation_started: bool,
}

impl<T: Real, C: AttitudeConfig<T>> PoseFilter<T, C> {
    /// A filter that starts at its first step. `cfg` is used as it is (see
    /// [`ComplementaryFilter::new`](crate::ComplementaryFilter::new)); [`PoseFilter::try_new`] checks it first.
    pub fn new(cfg: PoseConfig<T, C>) -> Self {
        let attitude = C::Filter::from_config(cfg.attitude);
        PoseFilter {
            estimate: PoseEstimate {
                r: Matrix3::identity(),
                x: Vector3::zeros(),
                v: Vector3::zeros(),
                rate: Vector3::zeros(),
                bias: cfg.attitude.initial_bias(),
                covariance: Matrix2::zeros(),
                started: false,
            },
            cfg,
            attitude,
            translation_started: false,
        }
    }

    /// A filter on a configuration checked again first ([`PoseConfig::check`]).
    pub fn try_new(cfg: PoseConfig<T, C>) -> Result<Self, EstimatorError> {
        Ok(Self::new(cfg.check()?))
    }

    /// The configuration.
    pub fn config(&self) -> &PoseConfig<T, C> {
        &self.cfg
    }

    /// The estimate published last.
    pub fn estimate(&self) -> &PoseEstimate<T> {
        &self.estimate
    }

    /// What it has skipped, held and clamped so far.
    pub fn faults(&self) -> &Faults {
        self.attitude.faults()
    }

    /// The attitude filter it drives.
    pub fn attitude(&self) -> &C::Filter {
        &self.attitude
    }

    /// The attitude filter, to change its gains.
    pub fn attitude_mut(&mut self) -> &mut C::Filter {
        &mut self.attitude
    }

    /// One tick (docs/maths.md, "Position and velocity on SE(3)"): the attitude filter's
    /// step with the accelerometer as the direction "up" (unless gated or unusable), then
    /// the Kalman filter's prediction over `h` with `a_k = R̂(t_k) f_k + g` and, when a fix
    /// came, its update. `R̂(t_k)` is the attitude filter's estimate of `R(t_k)`: for the
    /// complementary filter `R̂_{k−1}`, the attitude it compares tick k's samples with
    /// (its `R̂_k` runs one tick ahead on a rotating body: docs/maths.md, "The complementary filter on SO(3)");
    /// for the equivariant filter its new `R̂_k`.
    ///
    /// The first call starts the translation (the position from the fix if one came, with
    /// the fix's noise, else zero with `initial_position_std`; zero velocity with
    /// `initial_velocity_std`) and the attitude (see the attitude filter's `step`). Until
    /// the attitude has started the prediction uses `a = 0`.
    ///
    /// Guards, each counted in [`Faults`]: an accelerometer sample with a non-finite entry
    /// (or whose length overflows) is not a direction and the prediction uses `a = 0`
    /// (`accel`); one shorter than [`MIN_DIRECTION_NORM`](crate::MIN_DIRECTION_NORM) (free
    /// fall) is not a direction (`directions`) but is used for the prediction; one with
    /// `| |f| − g | > accel_gate` is not a direction (`accel_gated`) but is used for the
    /// prediction; a fix with a non-finite entry is skipped (`position`); if the translation
    /// update came out non-finite it is not used (`held`). The estimate is never non-finite.
    pub fn step(
        &mut self,
        h: T,
        gyro: &Vector3<T>,
        directions: &[Vector3<T>],
        accel: &Vector3<T>,
        position: Option<&Vector3<T>>,
    ) -> PoseEstimate<T> {
        self.step_with(None, h, gyro, directions, accel, position).0
    }

    /// [`PoseFilter::step`] with the innovation gate when one is given (docs/estimators.md,
    /// "The innovation gate and health"): each usable direction, the accelerometer's "up"
    /// among them, and the fix are tested against the prior and skipped when they fail. An
    /// accelerometer sample the magnitude gate (`accel_gate`) keeps out is present but not a
    /// direction: the body is accelerating, the sensor is not faulty. Returns the tick's
    /// verdicts.
    pub(crate) fn step_with(
        &mut self,
        gate: Option<&crate::health::Gate<T>>,
        h: T,
        gyro: &Vector3<T>,
        directions: &[Vector3<T>],
        accel: &Vector3<T>,
        position: Option<&Vector3<T>>,
    ) -> (PoseEstimate<T>, crate::health::Verdicts<T>) {
        let mut verdicts = crate::health::Verdicts::default();
        let n = self.attitude.config().count().saturating_sub(1);
        let mut y = usable(directions, n, self.attitude.faults_mut());
        let g: T = real(GRAVITY);
        let accel_ok = self.up(accel, &mut y[n], &mut verdicts, n);
        if let Some(g) = gate {
            g.directions(&self.attitude, h, gyro, &mut y, &mut verdicts);
        }
        let prior = *self.attitude.estimate();
        let att = self.attitude.step_usable(h, gyro, &y);
        // the attitude at t_k: the prior for a filter that leads by a tick, else the new one
        let at_sample = if C::Filter::LEADS { prior } else { att };
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
            let sv = self.cfg.initial_velocity_std;
            let (vx, vv) = (
                (sx * sx).max(real(MIN_VARIANCE)),
                (sv * sv).max(real(MIN_VARIANCE)),
            );
            let p0 = Matrix2::new(vx, T::zero(), T::zero(), vv);
            if all_finite(&x0) && p0.iter().all(|x| x.is_finite()) {
                self.estimate.x = x0;
                self.estimate.v = Vector3::zeros();
                self.estimate.covariance = p0;
                self.translation_started = true;
            }
        } else {
            let before = (self.estimate.x, self.estimate.v, self.estimate.covariance);
            if h.is_finite() && h > T::zero() {
                let a = if accel_ok && at_sample.started {
                    at_sample.r * accel - Vector3::z() * g
                } else {
                    Vector3::zeros()
                };
                self.predict(h, &a);
            }
            if let Some(z) = fix {
                let pass = gate.is_none_or(|g| {
                    let s = self.estimate.covariance[(0, 0)] + self.fix_variance();
                    g.position(&(z - self.estimate.x), s, &mut verdicts)
                });
                if pass {
                    self.update(&z);
                }
            }
            let e = &self.estimate;
            if !(all_finite(&e.x) && all_finite(&e.v) && e.covariance.iter().all(|x| x.is_finite()))
            {
                (self.estimate.x, self.estimate.v, self.estimate.covariance) = before;
                self.attitude.faults_mut().held += 1;
            }
        }
        self.estimate.r = att.r;
        self.estimate.rate = att.rate;
        self.estimate.bias = att.bias;
        self.estimate.started = att.started;
        (self.estimate, verdicts)
    }

    /// The accelerometer's sample as the direction "up" in `slot` (slot `n`): not when it
    /// has a non-finite entry (`accel`; the return is then false, and the prediction uses
    /// `a = 0`), is too short (`directions`), or its magnitude is kept out by `accel_gate`
    /// (`accel_gated`; present for the health monitor, neither passed nor rejected).
    fn up(
        &mut self,
        accel: &Vector3<T>,
        slot: &mut Option<Vector3<T>>,
        verdicts: &mut crate::health::Verdicts<T>,
        n: usize,
    ) -> bool {
        let g: T = real(GRAVITY);
        let accel_ok = all_finite(accel) && eqtrack_controller::hw_sqrt::norm(accel).is_finite();
        if !accel_ok {
            self.attitude.faults_mut().accel += 1;
        } else if let Some((up, norm)) = direction(accel) {
            if self
                .cfg
                .accel_gate
                .is_some_and(|gate| (norm - g).abs() > gate)
            {
                self.attitude.faults_mut().accel_gated += 1;
                verdicts.present |= 1 << n;
                verdicts.unused |= 1 << n;
            } else {
                *slot = Some(up);
            }
        } else {
            self.attitude.faults_mut().directions += 1;
        }
        accel_ok
    }

    /// A fix's variance per axis, `σ_p²` floored at [`MIN_VARIANCE`].
    fn fix_variance(&self) -> T {
        (self.cfg.position_noise * self.cfg.position_noise).max(real(MIN_VARIANCE))
    }

    /// The prediction over `h` (docs/maths.md, "Position and velocity on SE(3)"):
    /// `x ← x + h v + h²/2 a`, `v ← v + h a`; `P ← F P Fᵀ + σ_a² G Gᵀ` with
    /// `F = [[1, h], [0, 1]]`, `G = (h²/2, h)`.
    fn predict(&mut self, h: T, a: &Vector3<T>) {
        let half: T = real(0.5);
        let e = &mut self.estimate;
        e.x += e.v * h + a * (half * h * h);
        e.v += a * h;
        let f = Matrix2::new(T::one(), h, T::zero(), T::one());
        let gq = Vector2::new(half * h * h, h);
        let sa2 = self.cfg.accel_noise * self.cfg.accel_noise;
        e.covariance = f * e.covariance * f.transpose() + gq * gq.transpose() * sa2;
    }

    /// The update with a fix `z` (docs/maths.md, "Position and velocity on SE(3)"):
    /// `H = [1, 0]`, noise `σ_p²` (floored at [`MIN_VARIANCE`]), in Joseph form and
    /// symmetrised so the covariance stays symmetric positive definite.
    fn update(&mut self, z: &Vector3<T>) {
        let rp = self.fix_variance();
        let e = &mut self.estimate;
        let p = e.covariance;
        let s = p[(0, 0)] + rp;
        if !s.is_finite() || s <= T::zero() {
            return;
        }
        let k = Vector2::new(p[(0, 0)] / s, p[(1, 0)] / s);
        let innovation = z - e.x;
        e.x += innovation * k[0];
        e.v += innovation * k[1];
        let ikh = Matrix2::new(T::one() - k[0], T::zero(), -k[1], T::one());
        let joseph = ikh * p * ikh.transpose() + k * k.transpose() * rp;
        e.covariance = (joseph + joseph.transpose()) * real::<T>(0.5);
    }
}
