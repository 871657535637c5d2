//! Matrix Lie groups: one uniform set of operations on every group (docs/maths.md, "Conventions").
//!
//! A group element is its n×n matrix `Q`; an algebra element is its coordinate vector
//! `v ∈ ℝᵐ` in the basis `E_1..E_m` (`hat(v) = Σ vᵢ Eᵢ`). Momenta are coordinate vectors dual
//! to that basis, so `Ad*_X ≅ Ad_Xᵀ` and `ad*_v ≅ ad_vᵀ`.

pub mod se2;
pub mod se3;
pub mod so3;

pub use se2::Se2;
pub use se3::Se3;
pub use so3::So3;

use crate::Real;
use nalgebra::{SMatrix, SVector};

/// Which group a type implements (for messages, configuration and dispatch).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum GroupKind {
    /// The rotation group SO(3): n = m = 3.
    So3,
    /// The rigid-body group SE(3): n = 4, m = 6, twists ordered (ω, v).
    Se3,
    /// The planar rigid-body group SE(2): n = m = 3, twists ordered (ω, v_x, v_y).
    Se2,
}

impl GroupKind {
    /// Every supported group.
    pub const ALL: [GroupKind; 3] = [GroupKind::So3, GroupKind::Se3, GroupKind::Se2];

    /// The lower-case name used in files and messages (`"so3"`, `"se3"`, `"se2"`).
    pub fn name(self) -> &'static str {
        match self {
            GroupKind::So3 => "so3",
            GroupKind::Se3 => "se3",
            GroupKind::Se2 => "se2",
        }
    }

    /// Parses a lower-case name (`"so3"`, `"se3"`, `"se2"`).
    pub fn from_name(name: &str) -> Option<GroupKind> {
        GroupKind::ALL.iter().copied().find(|g| g.name() == name)
    }

    /// `(n, m)`: the matrix size and the algebra dimension.
    pub fn dims(self) -> (usize, usize) {
        match self {
            GroupKind::So3 => (3, 3),
            GroupKind::Se3 => (4, 6),
            GroupKind::Se2 => (3, 3),
        }
    }

    /// Runs `f` with the group's type and dimensions: the one place where a run-time
    /// [`GroupKind`] becomes a compile-time [`MatrixLieGroup`].
    pub fn dispatch<F: OnGroup>(self, f: F) -> F::Output {
        match self {
            GroupKind::So3 => f.run::<So3, 3, 3>(),
            GroupKind::Se3 => f.run::<Se3, 4, 6>(),
            GroupKind::Se2 => f.run::<Se2, 3, 3>(),
        }
    }
}

/// Code that is generic over the group, run through [`GroupKind::dispatch`].
pub trait OnGroup {
    /// What the code returns.
    type Output;
    /// Runs with the group `G` of n×n matrices and an m-dimensional algebra.
    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output;
}

/// A group eqtrack ships: what messages, configuration and vehicles need beyond the
/// mathematics ([`MatrixLieGroup`]).
///
/// The processes, the wire and the scenario files name a group by its [`GroupKind`] and fly
/// vehicles whose actuators are fixed in a rotating body; both need this trait. The law, the
/// phase-space group, the tracking error, the integrator, the references and the closed loop
/// need only [`MatrixLieGroup`], so a group defined outside this crate runs them
/// (docs/groups.md, "Add your own group").
pub trait BuiltinGroup<const N: usize, const M: usize>: MatrixLieGroup<N, M> {
    /// Which group this is (the wire's and the scenario's code for it).
    const KIND: GroupKind;

    /// The attitude part `R` of `Q` (SO(3): `Q` itself; SE(3): its rotation block), the
    /// rotation from body to world axes.
    fn rotation<T: Real>(q: &SMatrix<T, N, N>) -> nalgebra::Matrix3<T>;
}

/// A matrix Lie group of n×n matrices with an m-dimensional algebra.
///
/// Implementations are zero-sized markers; every operation is an associated function generic
/// over the scalar. The defaults are the generic matrix definitions; groups override them with
/// closed forms where they exist.
///
/// This is all the law and its proof need: a group defined outside eqtrack implements the
/// seven required functions (and [`NAME`](Self::NAME)) and runs the law, the tracking error,
/// the integrator and the closed loop; the property kit (`eqtrack_controller::kit`, feature `kit`)
/// checks it. [`attitude`](Self::attitude) is optional, for the features that work in world
/// axes.
pub trait MatrixLieGroup<const N: usize, const M: usize>:
    Copy + Clone + core::fmt::Debug + Default + Send + Sync + 'static
{
    /// The group's name in messages (`"so3"`, `"se3"`, `"se2"` for eqtrack's own groups).
    const NAME: &'static str;

    /// `hat : ℝᵐ → g`, `hat(v) = Σ vᵢ Eᵢ`.
    fn hat<T: Real>(v: &SVector<T, M>) -> SMatrix<T, N, N>;

    /// `vee : g → ℝᵐ`, the inverse of [`hat`](Self::hat) on the algebra.
    fn vee<T: Real>(x: &SMatrix<T, N, N>) -> SVector<T, M>;

    /// The exponential map in closed form.
    fn exp<T: Real>(v: &SVector<T, M>) -> SMatrix<T, N, N>;

    /// The logarithm (principal branch), stable near the identity and near angle π.
    fn log<T: Real>(q: &SMatrix<T, N, N>) -> SVector<T, M>;

    /// The group inverse in closed form.
    fn inverse<T: Real>(q: &SMatrix<T, N, N>) -> SMatrix<T, N, N>;

    /// `Ad_Q` as the m×m matrix of `V ↦ Q V Q⁻¹`.
    fn adjoint<T: Real>(q: &SMatrix<T, N, N>) -> SMatrix<T, M, M>;

    /// `ad_v` as the m×m matrix of `W ↦ [hat(v), hat(W)]`.
    fn ad<T: Real>(v: &SVector<T, M>) -> SMatrix<T, M, M>;

    /// `ad_vᵀ μ` (the coadjoint action `ad*_v μ` in the dual coordinates), without forming
    /// the matrix. The default is `ad(v)ᵀ μ`; groups give closed forms.
    fn ad_transpose_mul<T: Real>(v: &SVector<T, M>, mu: &SVector<T, M>) -> SVector<T, M> {
        Self::ad(v).tr_mul(mu)
    }

    /// The rotation from body to world axes at `Q`, if the group has one; `None` (the
    /// default) when it has not.
    ///
    /// Two features work in world axes and need it: the disturbance observer with
    /// `frame = World` (refused, [`Error::NoAttitude`](crate::Error::NoAttitude), on a group
    /// without one) and the attitude part of [`error_norms`](crate::tracking::error_norms).
    fn attitude<T: Real>(q: &SMatrix<T, N, N>) -> Option<nalgebra::Matrix3<T>> {
        let _ = q;
        None
    }

    /// How the rotation `r` acts on algebra and dual coordinates: the rotated twist or wrench
    /// `w`, each linear and angular part turned by `r`, with no lever arm
    /// (docs/maths.md, "Disturbance rejection"). The default turns every block of three coordinates
    /// ([`rotate_blocks`](crate::disturbance::rotate_blocks)), which is SO(3)'s and SE(3)'s;
    /// a group whose coordinates are not blocks of three overrides it.
    fn rotate_coordinates<T: Real>(r: &nalgebra::Matrix3<T>, w: &SVector<T, M>) -> SVector<T, M> {
        crate::disturbance::rotate_blocks(r, w)
    }

    /// The basis element `E_i` (`i < m`; any other index gives the zero matrix).
    fn basis<T: Real>(i: usize) -> SMatrix<T, N, N> {
        let mut v = SVector::<T, M>::zeros();
        if i < M {
            v[i] = T::one();
        }
        Self::hat(&v)
    }

    /// The identity element.
    fn identity<T: Real>() -> SMatrix<T, N, N> {
        SMatrix::identity()
    }

    /// The group product `a·b`.
    fn compose<T: Real>(a: &SMatrix<T, N, N>, b: &SMatrix<T, N, N>) -> SMatrix<T, N, N> {
        a * b
    }

    /// `a⁻¹ b`: `b` seen from `a` (the law's error at the reference, `Q_d⁻¹ Q`). The default
    /// composes the inverse; a group with positions forms their difference before it rotates
    /// it, so that two nearby poses far from the origin keep their digits (docs/maths.md,
    /// "The law at the reference").
    fn between<T: Real>(a: &SMatrix<T, N, N>, b: &SMatrix<T, N, N>) -> SMatrix<T, N, N> {
        Self::compose(&Self::inverse(a), b)
    }

    /// The coordinates of the Frobenius pairing with the basis, `(⟨X, E_i⟩_F)_i`.
    ///
    /// This is how the left-trivialised gradient (docs/maths.md, "The EqT law":
    /// `grad_i = ⟨Q_Eᵀ(Q_E − I)K, E_i⟩_F`) is read off a matrix.
    fn frobenius_coordinates<T: Real>(x: &SMatrix<T, N, N>) -> SVector<T, M> {
        SVector::<T, M>::from_fn(|i, _| x.dot(&Self::basis::<T>(i)))
    }
}
