//! The equivariant filter (EqF) for attitude and gyro bias (docs/maths.md, "The equivariant filter for attitude and gyro bias"),
//! after van Goor, Hamel and Mahony, "Equivariant Filter
//! (EqF)", IEEE TAC 2023 (arXiv 2010.14666), with the symmetry of Fornasier, Ng, Mahony and
//! Weiss for a biased gyro (ICRA 2022, RA-L 2022).
//!
//! The state is `ξ = (R, b)`: the attitude and the gyro's bias. The symmetry group is
//! `G = SO(3) ⋉ ℝ³`, `(A₁, a₁)(A₂, a₂) = (A₁A₂, a₁ + A₁a₂)`, which as a group is SE(3): an
//! element is stored as the 4×4 matrix `[[A, a], [0, 1]]` and the crate's SE(3) exponential,
//! logarithm and adjoints serve. The functions of this module are the filter's maths, public
//! so that tests and readers can check each equation on its own.

use crate::complementary::{
    Directions, SLOTS, checked_bias, checked_count, checked_directions, checked_limit,
    checked_rotation, filter_accessors, first_attitude, orthonormalise, start_builders, usable,
};
use crate::{AttitudeEstimate, EstimatorError, Faults, MAX_DIRECTIONS, all_finite};
use eqtrack_controller::group::se3::{from_parts, rotation, translation};
use eqtrack_controller::group::so3::{exp_so3, left_jacobian_so3, skew};
use eqtrack_controller::group::{MatrixLieGroup, Se3};
use eqtrack_controller::{Real, real};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// A 6×6 matrix: the covariance of the error coordinates `ε = (ε_Ω, ε_α)`.
pub type Matrix6<T> = SMatrix<T, 6, 6>;
/// A 6-vector: error coordinates, or an element `(Ω, α)` of the symmetry's algebra.
pub type Vector6<T> = SVector<T, 6>;
/// An element `X = (A, a)` of the symmetry group `SO(3) ⋉ ℝ³`, as `[[A, a], [0, 1]]`.
pub type Symmetry<T> = SMatrix<T, 4, 4>;

/// Whether the symmetric `m` (its lower triangle read) is positive definite: each pivot of
/// Gaussian elimination on it, in order and without exchanges, positive (docs/maths.md,
/// "The square root on a microcontroller", no square root where none is needed). Those
/// pivots are the squares of the Cholesky factor's diagonal, so this is the Cholesky test
/// without its square roots. A NaN pivot is not positive.
pub fn positive_definite<T: Real, const N: usize>(m: &SMatrix<T, N, N>) -> bool {
    let mut a = *m;
    for j in 0..N {
        let d = a[(j, j)];
        if d.partial_cmp(&T::zero()) != Some(core::cmp::Ordering::Greater) {
            return false;
        }
        for i in j + 1..N {
            let f = a[(i, j)] / d;
            for k in j + 1..=i {
                let x = f * a[(k, j)];
                a[(i, k)] -= x;
            }
        }
    }
    true
}

/// The group element `(A, a)`.
pub fn symmetry<T: Real>(a: &Matrix3<T>, t: &Vector3<T>) -> Symmetry<T> {
    from_parts(a, t)
}

/// The action on the state, `φ(X, ξ) = (R A, Aᵀ(b − a))` for `X = (A, a)`, `ξ = (R, b)`: a
/// right action, `φ(Y, φ(X, ξ)) = φ(XY, ξ)` (docs/maths.md, "The equivariant filter for attitude and gyro bias").
pub fn act<T: Real>(x: &Symmetry<T>, r: &Matrix3<T>, b: &Vector3<T>) -> (Matrix3<T>, Vector3<T>) {
    let a = rotation(x);
    (r * a, a.tr_mul(&(b - translation(x))))
}

/// The action on the input `u = (ω, τ)` (the gyro sample and the bias's rate),
/// `ψ(X, u) = (Aᵀ(ω − a), Aᵀτ)`: the system is equivariant,
/// `dφ_X f_u(ξ) = f_{ψ(X, u)}(φ(X, ξ))` (docs/maths.md, "The equivariant filter for attitude and gyro bias").
pub fn act_input<T: Real>(
    x: &Symmetry<T>,
    omega: &Vector3<T>,
    tau: &Vector3<T>,
) -> (Vector3<T>, Vector3<T>) {
    let a = rotation(x);
    (a.tr_mul(&(omega - translation(x))), a.tr_mul(tau))
}

/// The action on a direction measurement, `ρ(X, y) = Aᵀy`: `h_i(φ(X, ξ)) = ρ(X, h_i(ξ))` for
/// `h_i(R, b) = Rᵀd_i` (docs/maths.md, "The equivariant filter for attitude and gyro bias").
pub fn act_output<T: Real>(x: &Symmetry<T>, y: &Vector3<T>) -> Vector3<T> {
    rotation(x).tr_mul(y)
}

/// The lift `Λ(ξ, u) = (ω − b, b × ω − τ)`: `dφ_ξ(id)[Λ(ξ, u)] = f_u(ξ)`, the system's
/// vector field `Ṙ = R(ω − b)×`, `ḃ = τ` (it does not depend on `R`)
/// (docs/maths.md, "The equivariant filter for attitude and gyro bias").
pub fn lift<T: Real>(b: &Vector3<T>, omega: &Vector3<T>, tau: &Vector3<T>) -> Vector6<T> {
    let w = omega - b;
    let a = b.cross(omega) - tau;
    Vector6::new(w[0], w[1], w[2], a[0], a[1], a[2])
}

/// The state the group element `X` stands for, `ξ = φ(X, ξ°) = (A, −Aᵀa)` with the origin
/// `ξ° = (I, 0)`.
pub fn state_of<T: Real>(x: &Symmetry<T>) -> (Matrix3<T>, Vector3<T>) {
    act(x, &Matrix3::identity(), &Vector3::zeros())
}

/// The group element that stands for `ξ = (R, b)`, `X = (R, −R b)` (the action is free and
/// transitive: the only one with `φ(X, ξ°) = ξ`).
pub fn symmetry_of<T: Real>(r: &Matrix3<T>, b: &Vector3<T>) -> Symmetry<T> {
    from_parts(r, &(-(r * b)))
}

/// The error coordinates `ε = log(X X̂⁻¹)` (normal coordinates of the group at the identity)
/// of the true state `(R, b)` against the estimate `(R̂, b̂)` (docs/maths.md, "The equivariant filter for attitude and gyro bias").
pub fn error_coordinates<T: Real>(
    r: &Matrix3<T>,
    b: &Vector3<T>,
    r_hat: &Matrix3<T>,
    b_hat: &Vector3<T>,
) -> Vector6<T> {
    let x = symmetry_of(r, b);
    let x_hat = symmetry_of(r_hat, b_hat);
    Se3::log(&(x * Se3::inverse(&x_hat)))
}

fn blocks<T: Real>(a: &Matrix3<T>, b: &Matrix3<T>, c: &Matrix3<T>, d: &Matrix3<T>) -> Matrix6<T> {
    let mut m = Matrix6::zeros();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(a);
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(b);
    m.fixed_view_mut::<3, 3>(3, 0).copy_from(c);
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(d);
    m
}

/// The linearised error dynamics `ε̇ = A ε + B n`: `A = [[0, I], [0, ω̊×]]` with
/// `ω̊ = R̂(ω − b̂)` the estimated angular velocity in the world frame
/// (docs/maths.md, "The equivariant filter for attitude and gyro bias").
pub fn state_matrix<T: Real>(omega_world: &Vector3<T>) -> Matrix6<T> {
    let z = Matrix3::zeros();
    blocks(&z, &Matrix3::identity(), &z, &skew(omega_world))
}

/// `B = −diag(R̂, R̂)`: how the gyro's noise `n_ω` and the bias's walk `n_b`, `n = (n_ω, n_b)`,
/// enter the error dynamics (docs/maths.md, "The equivariant filter for attitude and gyro bias").
pub fn input_matrix<T: Real>(r_hat: &Matrix3<T>) -> Matrix6<T> {
    let z = Matrix3::zeros();
    blocks(&(-r_hat), &z, &z, &(-r_hat))
}

/// The transition over a period `h` with `ω̊` constant over it (it is: `R̂(t)(ω − b̂)` does not
/// change along the propagation), `Φ = exp(hA) = [[I, h J(hω̊)], [0, exp(hω̊×)]]` with `J`
/// the left Jacobian of SO(3) (docs/maths.md, "The equivariant filter for attitude and gyro bias").
pub fn transition<T: Real>(h: T, omega_world: &Vector3<T>) -> Matrix6<T> {
    let w = omega_world * h;
    blocks(
        &Matrix3::identity(),
        &(left_jacobian_so3(&w) * h),
        &Matrix3::zeros(),
        &exp_so3(&w),
    )
}

/// The process noise over a period `h`, `Q_d = ∫₀ʰ Φ(s) B Q Bᵀ Φ(s)ᵀ ds` with
/// `B Q Bᵀ = diag(σ_ω² I, σ_b² I)` (the rotations in `B` drop out) and `Φ(s)` taken as
/// `[[I, sI], [0, I]]` inside one period: `[[σ_ω²h + σ_b²h³/3, σ_b²h²/2], [σ_b²h²/2, σ_b²h]] ⊗ I₃`.
/// `σ_ω` is the gyro's rate noise density (rad/s/√Hz), `σ_b` its bias random walk
/// (rad/s²/√Hz) (docs/maths.md, "The equivariant filter for attitude and gyro bias").
pub fn process_noise<T: Real>(h: T, gyro_noise: T, bias_walk: T) -> Matrix6<T> {
    let (q11, q12, q22) = process_noise_entries(h, gyro_noise, bias_walk);
    let i = Matrix3::<T>::identity();
    blocks(&(i * q11), &(i * q12), &(i * q12), &(i * q22))
}

/// The three scalars of [`process_noise`]: `(σ_ω²h + σ_b²h³/3, σ_b²h²/2, σ_b²h)`.
fn process_noise_entries<T: Real>(h: T, gyro_noise: T, bias_walk: T) -> (T, T, T) {
    let (sw, sb) = (gyro_noise * gyro_noise, bias_walk * bias_walk);
    (
        sw * h + sb * h * h * h / real(3.0),
        sb * h * h * real(0.5),
        sb * h,
    )
}

/// The 3×3 blocks `(P, X, B)` of a symmetric `Σ = [[P, X], [Xᵀ, B]]`.
fn split<T: Real>(s: &Matrix6<T>) -> (Matrix3<T>, Matrix3<T>, Matrix3<T>) {
    (
        s.fixed_view::<3, 3>(0, 0).into_owned(),
        s.fixed_view::<3, 3>(0, 3).into_owned(),
        s.fixed_view::<3, 3>(3, 3).into_owned(),
    )
}

/// `Σ` from its blocks, the lower-left the transpose of the upper-right.
fn join<T: Real>(p: &Matrix3<T>, x: &Matrix3<T>, b: &Matrix3<T>) -> Matrix6<T> {
    blocks(p, x, &x.transpose(), b)
}

/// `Φ Σ Φᵀ + Q_d` with `Φ = [[I, F], [0, E]]` ([`transition`]) by blocks, `F = hJ(hω̊)`,
/// `E = exp(hω̊×)`: `[[P + FXᵀ + (X + FB)Fᵀ, (X + FB)Eᵀ], [·, EBEᵀ]] + Q_d`, a third of the
/// dense product's work (docs/maths.md, "The equivariant filter for attitude and gyro bias").
pub fn propagate_covariance<T: Real>(
    sigma: &Matrix6<T>,
    h: T,
    omega_world: &Vector3<T>,
    gyro_noise: T,
    bias_walk: T,
) -> Matrix6<T> {
    let w = omega_world * h;
    let (f, e) = (left_jacobian_so3(&w) * h, exp_so3(&w));
    let (p, x, b) = split(sigma);
    let xf = x + f * b;
    let (q11, q12, q22) = process_noise_entries(h, gyro_noise, bias_walk);
    let i = Matrix3::<T>::identity();
    join(
        &(p + f * x.transpose() + xf * f.transpose() + i * q11),
        &(xf * e.transpose() + i * q12),
        &(e * b * e.transpose() + i * q22),
    )
}

/// `J Σ Jᵀ` with the reset's `J = I + ½ ad_δ = [[A, 0], [C, A]]`, `A = I + ½Ω×`, `C = ½α×`
/// ([`reset_jacobian`]) by blocks: with `U = PCᵀ + XAᵀ`, `V = XᵀCᵀ + BAᵀ`,
/// `[[A P Aᵀ, A U], [·, C U + A V]]` (docs/maths.md, "The equivariant filter for attitude and gyro bias").
pub fn reset_covariance<T: Real>(sigma: &Matrix6<T>, delta: &Vector6<T>) -> Matrix6<T> {
    let half: T = real(0.5);
    let a = Matrix3::identity() + skew(&delta.fixed_rows::<3>(0).into_owned()) * half;
    let c = skew(&delta.fixed_rows::<3>(3).into_owned()) * half;
    let (p, x, b) = split(sigma);
    let (at, ct) = (a.transpose(), c.transpose());
    let u = p * ct + x * at;
    let v = x.transpose() * ct + b * at;
    join(&(a * p * at), &(a * u), &(c * u + a * v))
}

/// The output matrix of direction `d` measured as `y` (body frame), in the equivariant form
/// of the EqF paper: `C* = [½(d + R̂y)×, 0]` (3×6), so that the innovation `R̂y − d` is
/// `C* ε` to second order in `ε`. With `R̂y = d` (no error) it is the plain linearisation
/// `C = [d×, 0]` (docs/maths.md, "The equivariant filter for attitude and gyro bias").
pub fn output_matrix<T: Real>(d: &Vector3<T>, ry: &Vector3<T>) -> SMatrix<T, 3, 6> {
    let mut c = SMatrix::<T, 3, 6>::zeros();
    c.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&skew(&((d + ry) * real::<T>(0.5))));
    c
}

/// The first-order reset after a correction `Δ`, `J = I + ½ ad_Δ`: the covariance of the
/// error re-expressed about the corrected estimate is `J Σ Jᵀ` (docs/maths.md, "The equivariant filter for attitude and gyro bias").
pub fn reset_jacobian<T: Real>(delta: &Vector6<T>) -> Matrix6<T> {
    Matrix6::identity() + Se3::ad(delta) * real::<T>(0.5)
}

/// The noise model and start of an [`EquivariantFilter`], in physical units.
///
/// Build it with [`EqfConfig::new`] and the builder methods, which check every value. The
/// fields are public to be read; a configuration whose fields were written directly is
/// checked again by [`EqfConfig::check`] (and [`EquivariantFilter::try_new`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EqfConfig<T: Real> {
    /// `σ_ω`: the gyro's rate noise density (rad/s/√Hz).
    pub gyro_noise: T,
    /// `σ_b`: the gyro bias's random walk (rad/s²/√Hz).
    pub bias_walk: T,
    /// The unit world directions `d_i` (the first `count` used).
    pub world: [Vector3<T>; SLOTS],
    /// `σ_i`: each direction sample's noise, per axis (unitless, a unit vector's).
    pub direction_noise: [T; SLOTS],
    /// How many directions.
    pub count: usize,
    /// The attitude to start from; `None`: TRIAD from the first two usable directions.
    pub initial_attitude: Option<Matrix3<T>>,
    /// The bias estimate to start from.
    pub initial_bias: Vector3<T>,
    /// The attitude's standard deviation at the start (rad, per axis).
    pub initial_attitude_std: T,
    /// The bias's standard deviation at the start (rad/s, per axis).
    pub initial_bias_std: T,
    /// Clamp of each bias component (rad/s); `None`: no clamp.
    pub bias_limit: Option<T>,
}

impl<T: Real> EqfConfig<T> {
    /// The gyro's noise density `σ_ω` (rad/s/√Hz) and bias walk `σ_b` (rad/s²/√Hz), both
    /// finite and ≥ 0; the world directions (normalised here, at least two, at most
    /// [`MAX_DIRECTIONS`]) and each one's noise `σ_i` (finite and > 0). TRIAD start with an
    /// attitude standard deviation of 0.1 rad, zero initial bias with 0.05 rad/s, no bias
    /// limit.
    ///
    /// Errors: [`EstimatorError::BadGain`] (`"gyro_noise"`, `"bias_walk"`),
    /// [`EstimatorError::DirectionCount`], [`EstimatorError::WeightCount`] (one noise per
    /// direction), [`EstimatorError::BadDirection`], [`EstimatorError::BadNoise`].
    pub fn new(
        gyro_noise: T,
        bias_walk: T,
        world: &[Vector3<T>],
        direction_noise: &[T],
    ) -> Result<Self, EstimatorError> {
        Self::with_slots(
            gyro_noise,
            bias_walk,
            world,
            direction_noise,
            MAX_DIRECTIONS,
        )
    }

    pub(crate) fn with_slots(
        gyro_noise: T,
        bias_walk: T,
        world: &[Vector3<T>],
        direction_noise: &[T],
        max: usize,
    ) -> Result<Self, EstimatorError> {
        for (name, x) in [("gyro_noise", gyro_noise), ("bias_walk", bias_walk)] {
            if !x.is_finite() || x < T::zero() {
                return Err(EstimatorError::BadGain(name));
            }
        }
        if world.len() < 2 || world.len() > max.min(SLOTS) {
            return Err(EstimatorError::DirectionCount {
                given: world.len(),
                min: 2,
                max,
            });
        }
        if direction_noise.len() != world.len() {
            return Err(EstimatorError::WeightCount {
                expected: world.len(),
                given: direction_noise.len(),
            });
        }
        let count = world.len();
        let (world, direction_noise) =
            checked_directions(world, direction_noise, EstimatorError::BadNoise)?;
        Ok(EqfConfig {
            gyro_noise,
            bias_walk,
            world,
            direction_noise,
            count,
            initial_attitude: None,
            initial_bias: Vector3::zeros(),
            initial_attitude_std: real(0.1),
            initial_bias_std: real(0.05),
            bias_limit: None,
        })
    }

    /// The standard deviations at the start: attitude (rad) and bias (rad/s), each finite
    /// and > 0.
    pub fn initial_std(mut self, attitude: T, bias: T) -> Result<Self, EstimatorError> {
        if !attitude.is_finite() || attitude <= T::zero() {
            return Err(EstimatorError::BadGain("initial_attitude_std"));
        }
        if !bias.is_finite() || bias <= T::zero() {
            return Err(EstimatorError::BadGain("initial_bias_std"));
        }
        self.initial_attitude_std = attitude;
        self.initial_bias_std = bias;
        Ok(self)
    }

    start_builders!();

    /// Checks again a configuration whose public fields may have been written directly, and
    /// normalises its world directions: the same checks as [`EqfConfig::new`] and the
    /// builders, with up to `MAX_DIRECTIONS + 1` directions.
    pub fn check(self) -> Result<Self, EstimatorError> {
        let n = checked_count(self.count)?;
        let mut c = Self::with_slots(
            self.gyro_noise,
            self.bias_walk,
            &self.world[..n],
            &self.direction_noise[..n],
            SLOTS,
        )?
        .initial_std(self.initial_attitude_std, self.initial_bias_std)?;
        if let Some(l) = self.bias_limit {
            c = c.bias_limit(l)?;
        }
        if let Some(r) = self.initial_attitude {
            c = c.initial_attitude(r)?;
        }
        c.initial_bias(self.initial_bias)
    }
}

/// The equivariant filter for attitude and gyro bias: the estimate `(R̂, b̂)` (the group
/// element `X̂ = (R̂, −R̂b̂)`), the covariance `Σ` of the error coordinates, and what it has
/// counted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EquivariantFilter<T: Real> {
    cfg: EqfConfig<T>,
    estimate: AttitudeEstimate<T>,
    sigma: Matrix6<T>,
    last_gyro: Option<Vector3<T>>,
    faults: Faults,
}

impl<T: Real> EquivariantFilter<T> {
    /// A filter that starts at its first step. `cfg` is used as it is (from the checked
    /// constructors it is valid; never a panic either way: a `count` beyond the capacity is
    /// cut to it). [`EquivariantFilter::try_new`] checks it first.
    pub fn new(mut cfg: EqfConfig<T>) -> Self {
        cfg.count = cfg.count.min(SLOTS);
        let (sr, sb) = (
            cfg.initial_attitude_std * cfg.initial_attitude_std,
            cfg.initial_bias_std * cfg.initial_bias_std,
        );
        let i = Matrix3::<T>::identity();
        EquivariantFilter {
            estimate: AttitudeEstimate {
                r: Matrix3::identity(),
                rate: Vector3::zeros(),
                bias: cfg.initial_bias,
                started: false,
            },
            sigma: blocks(&(i * sr), &Matrix3::zeros(), &Matrix3::zeros(), &(i * sb)),
            cfg,
            last_gyro: None,
            faults: Faults::default(),
        }
    }

    filter_accessors!(EqfConfig);

    /// `Σ`: the covariance of the error coordinates `ε = log(X X̂⁻¹)`, ordered
    /// (attitude, bias) as [`error_coordinates`].
    pub fn covariance(&self) -> &Matrix6<T> {
        &self.sigma
    }

    /// The normalised estimation error squared `εᵀ Σ⁻¹ ε` of the true state `(R, b)`
    /// against the estimate; `None` before the start or when `Σ` has no Cholesky factor
    /// (docs/maths.md, "Consistency").
    pub fn nees(&self, r: &Matrix3<T>, b: &Vector3<T>) -> Option<T> {
        if !self.estimate.started {
            return None;
        }
        let e = error_coordinates(r, b, &self.estimate.r, &self.estimate.bias);
        let chol = self.sigma.cholesky()?;
        Some(e.dot(&chol.solve(&e)))
    }

    /// One tick with gyro sample `ω_k` and direction samples `y_{i,k}` (body frame, in the
    /// configuration's order), `h` the time since the last tick (docs/maths.md, "The equivariant filter for attitude and gyro bias"):
    ///
    /// ```text
    /// ω̄ = (ω_{k−1} + ω_k)/2                         the gyro over the period
    /// R̂ ← R̂ exp(h(ω̄ − b̂))    Σ ← Φ Σ Φᵀ + Q_d      Φ, Q_d at ω̊ = R̂(ω̄ − b̂)
    /// for each direction: r_i = R̂ y_i − d_i,  C_i = C*(d_i, R̂ y_i)
    ///   S = C_i Σ C_iᵀ + σ_i² I,  K = Σ C_iᵀ S⁻¹,  δ ← δ + K(r_i − C_i δ),  Σ ← Σ − K C_i Σ
    /// X̂ ← exp(δ) X̂,   Σ ← J Σ Jᵀ  (J = I + ½ ad_δ),  Σ ← (Σ + Σᵀ)/2
    /// ```
    ///
    /// publishing `R̂_k` and `ω_k − b̂_k`, after re-orthonormalising `R̂_k`.
    ///
    /// The first step starts the filter instead and publishes without propagating or
    /// updating: `R̂_0` is the configured attitude, or TRIAD from the first two usable,
    /// non-parallel directions (in list order), `b̂_0` the configured initial bias, and
    /// `Σ_0 = diag(σ_R² I, σ_b² I)` from the initial standard deviations. If TRIAD has no
    /// such pair the filter has not started: it publishes the identity with
    /// `started == false` and tries again at the next call.
    ///
    /// Guards, each counted in [`Faults`]: a direction with a non-finite entry, a length that
    /// overflows or shorter than [`MIN_DIRECTION_NORM`](crate::MIN_DIRECTION_NORM) (or
    /// missing from `directions`) is skipped for this tick (`directions`); a gyro sample with a
    /// non-finite entry is not used (`gyro`): the period is propagated with the last good one
    /// and the published rate is held; a period `h` that is not finite and positive, or a
    /// step that comes out non-finite or with a covariance that has no Cholesky factor (not
    /// positive definite), holds the previous estimate and covariance (`held`); with a bias limit each
    /// bias component is clamped to it (`bias_clamped`). The estimate is never non-finite
    /// and the call never panics.
    pub fn step(
        &mut self,
        h: T,
        gyro: &Vector3<T>,
        directions: &[Vector3<T>],
    ) -> AttitudeEstimate<T> {
        let y = usable(directions, self.cfg.count, &mut self.faults);
        self.step_usable(h, gyro, &y)
    }

    /// The gate's prior (docs/estimators.md, "The innovation gate and health"): `R̂` and the
    /// attitude block of `Σ` propagated over `h` with the gyro as [`EquivariantFilter::step`]
    /// will propagate them (unpropagated when it cannot be), before the update.
    pub(crate) fn prior(
        &self,
        h: T,
        gyro: &Vector3<T>,
    ) -> Option<(Matrix3<T>, Option<Matrix3<T>>)> {
        let e = &self.estimate;
        if !e.started {
            return None;
        }
        let mean = match (self.last_gyro, all_finite(gyro)) {
            (Some(p), true) => Some((p + gyro) * real::<T>(0.5)),
            (Some(p), false) => Some(p),
            (None, true) => Some(*gyro),
            (None, false) => None,
        };
        let attitude = |s: &Matrix6<T>| s.fixed_view::<3, 3>(0, 0).into_owned();
        match mean {
            Some(m) if h.is_finite() && h > T::zero() => {
                let w = m - e.bias;
                let (sw, sb) = (self.cfg.gyro_noise, self.cfg.bias_walk);
                let sigma = propagate_covariance(&self.sigma, h, &(e.r * w), sw, sb);
                Some((e.r * exp_so3(&(w * h)), Some(attitude(&sigma))))
            }
            _ => Some((e.r, Some(attitude(&self.sigma)))),
        }
    }

    /// Direction slot `slot`'s noise `σ_i`.
    pub(crate) fn noise(&self, slot: usize) -> T {
        self.cfg
            .direction_noise
            .get(slot)
            .copied()
            .unwrap_or_else(T::zero)
    }

    /// [`EquivariantFilter::step`] on checked, normalised samples.
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
            let c = &self.cfg;
            if let Some(r) = first_attitude(c.initial_attitude, &c.world, c.count, y) {
                self.estimate.r = r;
                self.estimate.started = true;
            }
            self.publish_rate(gyro, gyro_ok);
            return self.estimate;
        }
        let mean = match (self.last_gyro, gyro_ok) {
            (Some(p), true) => (p + gyro) * real::<T>(0.5),
            (Some(p), false) => p,
            (None, true) => *gyro,
            (None, false) => {
                self.faults.held += 1;
                return self.estimate;
            }
        };
        if !h.is_finite() || h <= T::zero() {
            self.faults.held += 1;
            self.publish_rate(gyro, gyro_ok);
            return self.estimate;
        }
        let before = (self.estimate, self.sigma);
        self.propagate(h, &mean);
        self.update(y);
        let mut clamped = 0;
        if let Some(l) = self.cfg.bias_limit {
            for x in self.estimate.bias.iter_mut() {
                if *x > l || *x < -l {
                    *x = x.clamp(-l, l);
                    clamped += 1;
                }
            }
        }
        self.estimate.r = orthonormalise(&self.estimate.r);
        let e = &self.estimate;
        let rate = if gyro_ok { gyro - e.bias } else { e.rate };
        // Σ − KCΣ is positive definite in exact arithmetic only: a Cholesky factor proves it
        if e.r.iter().all(|x| x.is_finite())
            && all_finite(&e.bias)
            && all_finite(&rate)
            && self.sigma.iter().all(|x| x.is_finite())
            && positive_definite(&self.sigma)
        {
            self.estimate.rate = rate;
            self.faults.bias_clamped += clamped;
        } else {
            (self.estimate, self.sigma) = before;
            self.faults.held += 1;
        }
        self.publish_rate(gyro, gyro_ok);
        self.estimate
    }

    /// The published rate `ω_k − b̂_k` (held when the sample is bad), and the sample kept
    /// for the next period.
    fn publish_rate(&mut self, gyro: &Vector3<T>, gyro_ok: bool) {
        if !gyro_ok {
            return;
        }
        let rate = gyro - self.estimate.bias;
        if all_finite(&rate) {
            self.estimate.rate = rate;
            self.last_gyro = Some(*gyro);
        }
    }

    /// The propagation over `h` with the gyro `ω̄`: `X̂ ← X̂ exp(h Λ(ξ̂, ω̄))`, which leaves
    /// `b̂` and turns `R̂` by `exp(h(ω̄ − b̂))`; `Σ ← Φ Σ Φᵀ + Q_d` ([`propagate_covariance`]).
    fn propagate(&mut self, h: T, mean: &Vector3<T>) {
        let e = &mut self.estimate;
        let w = mean - e.bias;
        let (sw, sb) = (self.cfg.gyro_noise, self.cfg.bias_walk);
        self.sigma = propagate_covariance(&self.sigma, h, &(e.r * w), sw, sb);
        e.r *= exp_so3(&(w * h));
    }

    /// The update with each usable direction, then the correction `X̂ ← exp(δ) X̂` and the
    /// reset of `Σ`.
    fn update(&mut self, y: &Directions<T>) {
        let r_hat = self.estimate.r;
        let mut delta = Vector6::<T>::zeros();
        let mut sigma = self.sigma;
        let c = &self.cfg;
        for ((yi, d), s) in y.iter().zip(&c.world).zip(&c.direction_noise).take(c.count) {
            let Some(yi) = yi else { continue };
            let ry = r_hat * yi;
            let m = output_matrix(d, &ry).fixed_view::<3, 3>(0, 0).into_owned();
            // C Σ with C = [M, 0]: only Σ's attitude rows count
            let cs: SMatrix<T, 3, 6> = m * sigma.fixed_rows::<3>(0);
            let innovation = ry - d - m * delta.fixed_rows::<3>(0);
            let s = cs.fixed_columns::<3>(0) * m.transpose() + Matrix3::identity() * (*s * *s);
            let Some(s_inv) = s.try_inverse() else {
                continue;
            };
            let k: SMatrix<T, 6, 3> = cs.transpose() * s_inv;
            delta += k * innovation;
            sigma -= k * cs;
        }
        if delta == Vector6::zeros() {
            self.sigma = symmetric(&sigma);
            return;
        }
        let correction = Se3::exp(&delta);
        let a = rotation(&correction);
        let e = &mut self.estimate;
        e.r = a * r_hat;
        e.bias -= e.r.tr_mul(&translation(&correction));
        self.sigma = symmetric(&reset_covariance(&sigma, &delta));
    }
}

/// `(Σ + Σᵀ)/2`: exactly symmetric (rounding leaves the products above a few ulps off).
fn symmetric<T: Real>(s: &Matrix6<T>) -> Matrix6<T> {
    (s + s.transpose()) * real::<T>(0.5)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_reset_is_the_left_jacobian_to_first_order() {
        // exp(δ + η) exp(−δ) ≈ exp(J η): J = I + ½ ad_δ + O(|δ|²)
        let delta = Vector6::new(1e-3, -2e-3, 5e-4, 3e-3, 1e-3, -2e-3);
        let eta = Vector6::new(1e-7, 2e-7, -1e-7, 0.0, 3e-7, 1e-7);
        let lhs = Se3::log(&(Se3::exp(&(delta + eta)) * Se3::exp(&(-delta))));
        let rhs = reset_jacobian(&delta) * eta;
        // the neglected term is O(|δ|²|η|) ~ 1e-12
        assert!((lhs - rhs).norm() < 5e-12, "{}", (lhs - rhs).norm());
        // and without the reset the difference is first order in δ
        assert!((lhs - eta).norm() > 1e-10);
    }

    proptest::proptest! {
        /// The pivots' test of positive definiteness answers as nalgebra's Cholesky
        /// factorisation does, in f64 and f32, on `A Aᵀ` shifted by `s I` (definite for
        /// `s > 0`, indefinite below the least eigenvalue), on 6 × 6 matrices as the filter's
        /// covariance is, and on a NaN.
        #[test]
        fn the_pivots_test_is_the_cholesky_test(
            entries in proptest::collection::vec(-2.0f64..2.0, 36),
            shift in -3.0f64..3.0,
        ) {
            let a = SMatrix::<f64, 6, 6>::from_column_slice(&entries);
            let m = a * a.transpose() + SMatrix::<f64, 6, 6>::identity() * shift;
            let least = m.symmetric_eigenvalues().min();
            // away from the edge, where rounding may decide either way
            proptest::prop_assume!(least.abs() > 1e-9);
            proptest::prop_assert_eq!(positive_definite(&m), m.cholesky().is_some());
            proptest::prop_assert_eq!(positive_definite(&m), least > 0.0);
            let m32 = m.map(|x| x as f32);
            if least.abs() > 1e-2 {
                proptest::prop_assert_eq!(positive_definite(&m32), m32.cholesky().is_some());
            }
            let mut nan = m;
            nan[(3, 3)] = f64::NAN;
            proptest::prop_assert!(!positive_definite(&nan));
        }
    }
}
