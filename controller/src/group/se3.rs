//! SE(3): n = 4, m = 6, twists ordered **(ω, v)** (angular first), wrenches (torque, force).
//! `Ad_(R,x) = [[R, 0], [x×R, R]]`, `ad_(ω,v) = [[ω×, 0], [v×, ω×]]` (docs/maths.md, "Conventions").

use super::so3::{exp_so3, left_jacobian_so3, log_so3, skew};
use super::{BuiltinGroup, GroupKind, MatrixLieGroup};
use crate::{Real, real};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// The rigid-body group SE(3).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Se3;

/// The rotation block `R` of an SE(3) matrix.
#[inline]
pub fn rotation<T: Real>(q: &SMatrix<T, 4, 4>) -> Matrix3<T> {
    q.fixed_view::<3, 3>(0, 0).into_owned()
}

/// The translation `x` of an SE(3) matrix.
#[inline]
pub fn translation<T: Real>(q: &SMatrix<T, 4, 4>) -> Vector3<T> {
    q.fixed_view::<3, 1>(0, 3).into_owned()
}

/// Builds `[[R, x], [0, 1]]`.
#[inline]
pub fn from_parts<T: Real>(r: &Matrix3<T>, x: &Vector3<T>) -> SMatrix<T, 4, 4> {
    let mut q = SMatrix::<T, 4, 4>::identity();
    q.fixed_view_mut::<3, 3>(0, 0).copy_from(r);
    q.fixed_view_mut::<3, 1>(0, 3).copy_from(x);
    q
}

fn split<T: Real>(v: &SVector<T, 6>) -> (Vector3<T>, Vector3<T>) {
    (
        Vector3::new(v[0], v[1], v[2]),
        Vector3::new(v[3], v[4], v[5]),
    )
}

fn join<T: Real>(w: &Vector3<T>, v: &Vector3<T>) -> SVector<T, 6> {
    SVector::<T, 6>::new(w[0], w[1], w[2], v[0], v[1], v[2])
}

fn blocks<T: Real>(a: &Matrix3<T>, b: &Matrix3<T>, c: &Matrix3<T>) -> SMatrix<T, 6, 6> {
    // [[a, 0], [b, c]]
    let mut m = SMatrix::<T, 6, 6>::zeros();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(a);
    m.fixed_view_mut::<3, 3>(3, 0).copy_from(b);
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(c);
    m
}

impl BuiltinGroup<4, 6> for Se3 {
    const KIND: GroupKind = GroupKind::Se3;

    fn rotation<T: Real>(q: &SMatrix<T, 4, 4>) -> Matrix3<T> {
        rotation(q)
    }
}

impl MatrixLieGroup<4, 6> for Se3 {
    const NAME: &'static str = "se3";

    fn hat<T: Real>(v: &SVector<T, 6>) -> SMatrix<T, 4, 4> {
        let (w, u) = split(v);
        let mut x = SMatrix::<T, 4, 4>::zeros();
        x.fixed_view_mut::<3, 3>(0, 0).copy_from(&skew(&w));
        x.fixed_view_mut::<3, 1>(0, 3).copy_from(&u);
        x
    }

    fn vee<T: Real>(x: &SMatrix<T, 4, 4>) -> SVector<T, 6> {
        SVector::<T, 6>::new(
            x[(2, 1)],
            x[(0, 2)],
            x[(1, 0)],
            x[(0, 3)],
            x[(1, 3)],
            x[(2, 3)],
        )
    }

    /// `exp(ω, v) = (exp(ω×), J(ω)v)` with `J` the left Jacobian of SO(3)
    /// ([`left_jacobian_so3`]).
    fn exp<T: Real>(v: &SVector<T, 6>) -> SMatrix<T, 4, 4> {
        let (w, u) = split(v);
        let j = left_jacobian_so3(&w);
        from_parts(&exp_so3(&w), &(j * u))
    }

    /// `log(R, x) = (ω, J(ω)⁻¹x)` with `J⁻¹ = I − ½ω× + D ω×²`,
    /// `D = (1 − (θ/2)cot(θ/2))/θ²` (series near θ = 0).
    fn log<T: Real>(q: &SMatrix<T, 4, 4>) -> SVector<T, 6> {
        let w = log_so3(&rotation(q));
        let x = translation(q);
        let theta2 = w.norm_squared();
        let wx = skew(&w);
        let d = if theta2 < real(1e-2) {
            real::<T>(1.0 / 12.0)
                + theta2 / real(720.0)
                + theta2 * theta2 / real(30240.0)
                + theta2 * theta2 * theta2 / real(1209600.0)
        } else {
            let theta = eqtrack_hw_sqrt::sqrt(theta2);
            let half = theta * real(0.5);
            (T::one() - half * crate::trig::cos(half) / crate::trig::sin(half)) / theta2
        };
        let j_inv = Matrix3::<T>::identity() - wx * real::<T>(0.5) + wx * wx * d;
        join(&w, &(j_inv * x))
    }

    fn inverse<T: Real>(q: &SMatrix<T, 4, 4>) -> SMatrix<T, 4, 4> {
        let rt = rotation(q).transpose();
        from_parts(&rt, &(-(rt * translation(q))))
    }

    fn attitude<T: Real>(q: &SMatrix<T, 4, 4>) -> Option<Matrix3<T>> {
        Some(rotation(q))
    }

    /// `(R_aᵀ R_b, R_aᵀ (x_b − x_a))`: the difference of the positions first.
    fn between<T: Real>(a: &SMatrix<T, 4, 4>, b: &SMatrix<T, 4, 4>) -> SMatrix<T, 4, 4> {
        let rt = rotation(a).transpose();
        from_parts(
            &(rt * rotation(b)),
            &(rt * (translation(b) - translation(a))),
        )
    }

    fn adjoint<T: Real>(q: &SMatrix<T, 4, 4>) -> SMatrix<T, 6, 6> {
        let r = rotation(q);
        blocks(&r, &(skew(&translation(q)) * r), &r)
    }

    fn ad<T: Real>(v: &SVector<T, 6>) -> SMatrix<T, 6, 6> {
        let (w, u) = split(v);
        let wx = skew(&w);
        blocks(&wx, &skew(&u), &wx)
    }

    /// With `V = (ω, v)`, `μ = (μ_ω, μ_v)`: `ad_Vᵀ μ = (μ_ω × ω + μ_v × v, μ_v × ω)`.
    fn ad_transpose_mul<T: Real>(v: &SVector<T, 6>, mu: &SVector<T, 6>) -> SVector<T, 6> {
        let (w, u) = split(v);
        let (mw, mv) = split(mu);
        join(&(mw.cross(&w) + mv.cross(&u)), &mv.cross(&w))
    }

    fn frobenius_coordinates<T: Real>(x: &SMatrix<T, 4, 4>) -> SVector<T, 6> {
        SVector::<T, 6>::new(
            x[(2, 1)] - x[(1, 2)],
            x[(0, 2)] - x[(2, 0)],
            x[(1, 0)] - x[(0, 1)],
            x[(0, 3)],
            x[(1, 3)],
            x[(2, 3)],
        )
    }
}
