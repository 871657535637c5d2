//! SE(2): n = m = 3, twists ordered **(ω, v_x, v_y)** (angular first), wrenches
//! `(τ, f_x, f_y)`; `hat(ω, v) = [[0, −ω, v_x], [ω, 0, v_y], [0, 0, 0]]`,
//! `Ad_(R,x) = [[1, 0], [−J x, R]]`, `ad_(ω,v) = [[0, 0], [−J v, ω J]]` with
//! `J = [[0, −1], [1, 0]]` (docs/maths.md, "Conventions").

use super::{BuiltinGroup, GroupKind, MatrixLieGroup};
use crate::{Real, real};
use nalgebra::{Matrix2, Matrix3, SMatrix, SVector, Vector2, Vector3};

/// The planar rigid-body group SE(2).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Se2;

/// The rotation block `R` (2 × 2) of an SE(2) matrix.
#[inline]
pub fn rotation2<T: Real>(q: &SMatrix<T, 3, 3>) -> Matrix2<T> {
    q.fixed_view::<2, 2>(0, 0).into_owned()
}

/// The translation `x` of an SE(2) matrix.
#[inline]
pub fn translation2<T: Real>(q: &SMatrix<T, 3, 3>) -> Vector2<T> {
    q.fixed_view::<2, 1>(0, 2).into_owned()
}

/// Builds `[[R, x], [0, 1]]`.
#[inline]
pub fn from_parts2<T: Real>(r: &Matrix2<T>, x: &Vector2<T>) -> SMatrix<T, 3, 3> {
    let mut q = SMatrix::<T, 3, 3>::identity();
    q.fixed_view_mut::<2, 2>(0, 0).copy_from(r);
    q.fixed_view_mut::<2, 1>(0, 2).copy_from(x);
    q
}

/// The pose at heading `theta` and position `x`.
pub fn pose<T: Real>(theta: T, x: &Vector2<T>) -> SMatrix<T, 3, 3> {
    let (s, c) = (crate::trig::sin(theta), crate::trig::cos(theta));
    from_parts2(&Matrix2::new(c, -s, s, c), x)
}

/// The heading `θ = atan2(R₂₁, R₁₁)` of an SE(2) matrix, in [−π, π] (±π only at a half
/// turn, where both name the same rotation).
pub fn heading<T: Real>(q: &SMatrix<T, 3, 3>) -> T {
    q[(1, 0)].atan2(q[(0, 0)])
}

/// `J v`, the rotation of a planar vector by a quarter turn (`J = [[0, −1], [1, 0]]`).
#[inline]
fn quarter<T: Real>(v: &Vector2<T>) -> Vector2<T> {
    Vector2::new(-v[1], v[0])
}

/// `(sinθ/θ, (1 − cosθ)/θ)`: the entries of `V(θ) = [[A, −B], [B, A]]`, the translation part
/// of the exponential, with series near θ = 0 and the half-angle form of `B`.
fn left_jacobian_entries<T: Real>(theta: T) -> (T, T) {
    let t2 = theta * theta;
    if t2 < real(1e-4) {
        (
            T::one() - t2 / real(6.0) + t2 * t2 / real(120.0),
            theta * (real::<T>(0.5) - t2 / real(24.0) + t2 * t2 / real(720.0)),
        )
    } else {
        let half = theta * real(0.5);
        let s = crate::trig::sin(half) / half;
        (crate::trig::sin(theta) / theta, half * s * s)
    }
}

/// `α = (θ/2) cot(θ/2)`: `V(θ)⁻¹ = [[α, θ/2], [−θ/2, α]]`, with its series near θ = 0
/// (at θ = ±π, α = 0).
fn inverse_jacobian_alpha<T: Real>(theta: T) -> T {
    let t2 = theta * theta;
    if t2 < real(1e-2) {
        T::one() - t2 / real(12.0) - t2 * t2 / real(720.0) - t2 * t2 * t2 / real(30240.0)
    } else {
        let half = theta * real(0.5);
        half * crate::trig::cos(half) / crate::trig::sin(half)
    }
}

/// The planar rotation of an SE(2) matrix as a rotation about the world's z axis.
pub fn rotation<T: Real>(q: &SMatrix<T, 3, 3>) -> Matrix3<T> {
    let z = T::zero();
    Matrix3::new(
        q[(0, 0)],
        q[(0, 1)],
        z,
        q[(1, 0)],
        q[(1, 1)],
        z,
        z,
        z,
        T::one(),
    )
}

impl BuiltinGroup<3, 3> for Se2 {
    const KIND: GroupKind = GroupKind::Se2;

    fn rotation<T: Real>(q: &SMatrix<T, 3, 3>) -> Matrix3<T> {
        rotation(q)
    }
}

impl MatrixLieGroup<3, 3> for Se2 {
    const NAME: &'static str = "se2";

    fn hat<T: Real>(v: &SVector<T, 3>) -> SMatrix<T, 3, 3> {
        let z = T::zero();
        Matrix3::new(z, -v[0], v[1], v[0], z, v[2], z, z, z)
    }

    fn vee<T: Real>(x: &SMatrix<T, 3, 3>) -> SVector<T, 3> {
        Vector3::new(x[(1, 0)], x[(0, 2)], x[(1, 2)])
    }

    /// `exp(ω, v) = (R(ω), V(ω) v)`.
    fn exp<T: Real>(v: &SVector<T, 3>) -> SMatrix<T, 3, 3> {
        let (a, b) = left_jacobian_entries(v[0]);
        let u = Vector2::new(v[1], v[2]);
        let x = u * a + quarter(&u) * b;
        pose(v[0], &x)
    }

    /// `log(R, x) = (θ, V(θ)⁻¹ x)`, `θ = atan2(R₂₁, R₁₁)`.
    fn log<T: Real>(q: &SMatrix<T, 3, 3>) -> SVector<T, 3> {
        let theta = heading(q);
        let alpha = inverse_jacobian_alpha(theta);
        let x = translation2(q);
        let u = x * alpha - quarter(&x) * (theta * real(0.5));
        Vector3::new(theta, u[0], u[1])
    }

    fn inverse<T: Real>(q: &SMatrix<T, 3, 3>) -> SMatrix<T, 3, 3> {
        let rt = rotation2(q).transpose();
        from_parts2(&rt, &(-(rt * translation2(q))))
    }

    /// `(R_aᵀ R_b, R_aᵀ (x_b − x_a))`: the difference of the positions first.
    fn between<T: Real>(a: &SMatrix<T, 3, 3>, b: &SMatrix<T, 3, 3>) -> SMatrix<T, 3, 3> {
        let rt = rotation2(a).transpose();
        from_parts2(
            &(rt * rotation2(b)),
            &(rt * (translation2(b) - translation2(a))),
        )
    }

    /// `[[1, 0], [−J x, R]]`.
    fn adjoint<T: Real>(q: &SMatrix<T, 3, 3>) -> SMatrix<T, 3, 3> {
        let r = rotation2(q);
        let jx = quarter(&translation2(q));
        let z = T::zero();
        Matrix3::new(
            T::one(),
            z,
            z,
            -jx[0],
            r[(0, 0)],
            r[(0, 1)],
            -jx[1],
            r[(1, 0)],
            r[(1, 1)],
        )
    }

    /// `[[0, 0], [−J v, ω J]]`.
    fn ad<T: Real>(v: &SVector<T, 3>) -> SMatrix<T, 3, 3> {
        let z = T::zero();
        Matrix3::new(z, z, z, v[2], z, -v[0], -v[1], v[0], z)
    }

    /// `ad_vᵀ μ = (v_y μ_x − v_x μ_y, ω μ_y, −ω μ_x)` for `μ = (μ_θ, μ_x, μ_y)`.
    fn ad_transpose_mul<T: Real>(v: &SVector<T, 3>, mu: &SVector<T, 3>) -> SVector<T, 3> {
        Vector3::new(v[2] * mu[1] - v[1] * mu[2], v[0] * mu[2], -v[0] * mu[1])
    }

    fn frobenius_coordinates<T: Real>(x: &SMatrix<T, 3, 3>) -> SVector<T, 3> {
        Vector3::new(x[(1, 0)] - x[(0, 1)], x[(0, 2)], x[(1, 2)])
    }

    fn attitude<T: Real>(q: &SMatrix<T, 3, 3>) -> Option<Matrix3<T>> {
        Some(rotation(q))
    }

    /// The torque about z is unchanged; the force turns with the top-left 2 × 2 block of `r`.
    fn rotate_coordinates<T: Real>(r: &Matrix3<T>, w: &SVector<T, 3>) -> SVector<T, 3> {
        Vector3::new(
            w[0],
            r[(0, 0)] * w[1] + r[(0, 1)] * w[2],
            r[(1, 0)] * w[1] + r[(1, 1)] * w[2],
        )
    }
}
