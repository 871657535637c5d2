//! SO(3): n = m = 3, `hat(v)` the cross-product matrix, `Ad_R = R`, `ad_v = v×`.

use super::{BuiltinGroup, GroupKind, MatrixLieGroup};
use crate::{Real, real};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// The rotation group SO(3).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct So3;

/// The cross-product matrix `v×` (docs/maths.md: `hat(v) = [[0,-v3,v2],[v3,0,-v1],[-v2,v1,0]]`;
/// the seed paper's displayed map has a typo, `v_2` where `v_3` belongs).
#[inline]
pub fn skew<T: Real>(v: &Vector3<T>) -> Matrix3<T> {
    let z = T::zero();
    Matrix3::new(z, -v[2], v[1], v[2], z, -v[0], -v[1], v[0], z)
}

/// `(X)^∨` of a (not necessarily skew) 3×3 matrix: the vector of its skew part's entries,
/// `((X₃₂ − X₂₃)/2, (X₁₃ − X₃₁)/2, (X₂₁ − X₁₂)/2)`.
#[inline]
pub fn vee_skew<T: Real>(x: &Matrix3<T>) -> Vector3<T> {
    let h: T = real(0.5);
    Vector3::new(
        (x[(2, 1)] - x[(1, 2)]) * h,
        (x[(0, 2)] - x[(2, 0)]) * h,
        (x[(1, 0)] - x[(0, 1)]) * h,
    )
}

/// Rodrigues' formula `exp(hat(w)) = I + A·W + B·W²`, `A = sinθ/θ`, `B = (1 − cosθ)/θ²`,
/// with series near θ = 0 and the half-angle form of B (no cancellation).
pub fn exp_so3<T: Real>(w: &Vector3<T>) -> Matrix3<T> {
    let theta2 = w.norm_squared();
    let wx = skew(w);
    let (a, b) = if theta2 < real(1e-4) {
        (
            T::one() - theta2 / real(6.0) + theta2 * theta2 / real(120.0),
            real::<T>(0.5) - theta2 / real(24.0) + theta2 * theta2 / real(720.0),
        )
    } else {
        let theta = eqtrack_hw_sqrt::sqrt(theta2);
        let half = theta * real(0.5);
        let s = crate::trig::sin(half) / half;
        (crate::trig::sin(theta) / theta, s * s * real(0.5))
    };
    Matrix3::identity() + wx * a + wx * wx * b
}

/// The left Jacobian of SO(3), `J(ω) = ∫₀¹ exp(s ω×) ds = I + B ω× + C ω×²` with
/// `B = (1 − cosθ)/θ²`, `C = (θ − sinθ)/θ³` (series near θ = 0): the translation part of
/// SE(3)'s exponential, and `exp(ω + δ) ≈ exp(J(ω)δ) exp(ω)` to first order in `δ`.
pub fn left_jacobian_so3<T: Real>(w: &Vector3<T>) -> Matrix3<T> {
    let theta2 = w.norm_squared();
    let wx = skew(w);
    let (b, c) = if theta2 < real(1e-2) {
        (
            real::<T>(0.5) - theta2 / real(24.0) + theta2 * theta2 / real(720.0)
                - theta2 * theta2 * theta2 / real(40320.0),
            real::<T>(1.0 / 6.0) - theta2 / real(120.0) + theta2 * theta2 / real(5040.0)
                - theta2 * theta2 * theta2 / real(362880.0),
        )
    } else {
        let theta = eqtrack_hw_sqrt::sqrt(theta2);
        let half = theta * real(0.5);
        let s = crate::trig::sin(half) / half;
        (
            s * s * real(0.5),
            (theta - crate::trig::sin(theta)) / (theta2 * theta),
        )
    };
    Matrix3::identity() + wx * b + wx * wx * c
}

/// The principal logarithm of a rotation, accurate near θ = 0 and near θ = π.
///
/// θ comes from `atan2(|sinθ·k|, cosθ)`; for θ < 2π/3 the axis comes from the skew part,
/// beyond it from the symmetric part `(R + Rᵀ)/2 − cosθ·I = (1 − cosθ) k kᵀ`, with the sign
/// fixed by the skew part.
pub fn log_so3<T: Real>(r: &Matrix3<T>) -> Vector3<T> {
    let c = (r.trace() - T::one()) * real(0.5);
    let c = c.clamp(-T::one(), T::one());
    let w = vee_skew(r); // sinθ·k
    let s = eqtrack_hw_sqrt::norm(&w);
    let theta = s.atan2(c);
    if c > real(-0.5) {
        let theta2 = theta * theta;
        let factor = if theta2 < real(1e-4) {
            T::one() + theta2 / real(6.0) + theta2 * theta2 * real(7.0 / 360.0)
        } else {
            theta / s
        };
        w * factor
    } else {
        let one_minus_c = T::one() - c;
        let b = (r + r.transpose()) * real::<T>(0.5) - Matrix3::<T>::identity() * c;
        let mut i = 0;
        for j in 1..3 {
            if b[(j, j)] > b[(i, i)] {
                i = j;
            }
        }
        let denom = eqtrack_hw_sqrt::sqrt(b[(i, i)] * one_minus_c);
        let mut k: Vector3<T> = b.column(i).into_owned() / denom;
        // Normalise away rounding, then fix the sign from sinθ·k (sinθ ≥ 0).
        let kn = eqtrack_hw_sqrt::norm(&k);
        if kn > T::zero() {
            k /= kn;
        }
        if k.dot(&w) < T::zero() {
            k = -k;
        }
        k * theta
    }
}

impl BuiltinGroup<3, 3> for So3 {
    const KIND: GroupKind = GroupKind::So3;

    fn rotation<T: Real>(q: &SMatrix<T, 3, 3>) -> Matrix3<T> {
        *q
    }
}

impl MatrixLieGroup<3, 3> for So3 {
    const NAME: &'static str = "so3";

    fn hat<T: Real>(v: &SVector<T, 3>) -> SMatrix<T, 3, 3> {
        skew(v)
    }

    fn vee<T: Real>(x: &SMatrix<T, 3, 3>) -> SVector<T, 3> {
        Vector3::new(x[(2, 1)], x[(0, 2)], x[(1, 0)])
    }

    fn exp<T: Real>(v: &SVector<T, 3>) -> SMatrix<T, 3, 3> {
        exp_so3(v)
    }

    fn log<T: Real>(q: &SMatrix<T, 3, 3>) -> SVector<T, 3> {
        log_so3(q)
    }

    fn inverse<T: Real>(q: &SMatrix<T, 3, 3>) -> SMatrix<T, 3, 3> {
        q.transpose()
    }

    fn attitude<T: Real>(q: &SMatrix<T, 3, 3>) -> Option<Matrix3<T>> {
        Some(<Self as BuiltinGroup<3, 3>>::rotation(q))
    }

    fn adjoint<T: Real>(q: &SMatrix<T, 3, 3>) -> SMatrix<T, 3, 3> {
        *q
    }

    fn ad<T: Real>(v: &SVector<T, 3>) -> SMatrix<T, 3, 3> {
        skew(v)
    }

    /// `ad_vᵀ μ = (v×)ᵀ μ = μ × v`.
    fn ad_transpose_mul<T: Real>(v: &SVector<T, 3>, mu: &SVector<T, 3>) -> SVector<T, 3> {
        mu.cross(v)
    }

    fn frobenius_coordinates<T: Real>(x: &SMatrix<T, 3, 3>) -> SVector<T, 3> {
        Vector3::new(
            x[(2, 1)] - x[(1, 2)],
            x[(0, 2)] - x[(2, 0)],
            x[(1, 0)] - x[(0, 1)],
        )
    }
}
