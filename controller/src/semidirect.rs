//! The phase-space group `G ⋉ g*`, its actions and the extended Euler–Poincaré vector field
//! (docs/maths.md, "The objects").

use crate::Real;
use crate::group::MatrixLieGroup;
use nalgebra::{SMatrix, SVector};

/// A point `(Q, p)` of `G × g*`, and equally an element of the group `G ⋉ g*`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Phase<T: Real, const N: usize, const M: usize> {
    /// Configuration `Q ∈ G` (n×n).
    pub q: SMatrix<T, N, N>,
    /// Momentum coordinates `p ∈ g*` (dual to the basis `E_i`).
    pub p: SVector<T, M>,
}

/// An input `(V, τ)` of the extended system: a free velocity and a torque.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Input<T: Real, const M: usize> {
    /// Velocity `V ∈ g` (coordinates).
    pub v: SVector<T, M>,
    /// Torque `τ ∈ g*` (coordinates).
    pub tau: SVector<T, M>,
}

/// A tangent vector `(Q̇, ṗ)` at a point of `G × g*`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tangent<T: Real, const N: usize, const M: usize> {
    /// `Q̇` as an n×n matrix.
    pub q_dot: SMatrix<T, N, N>,
    /// `ṗ`.
    pub p_dot: SVector<T, M>,
}

impl<T: Real, const N: usize, const M: usize> Phase<T, N, M> {
    /// The identity `(I, 0)` of `G ⋉ g*`.
    pub fn identity() -> Self {
        Phase {
            q: SMatrix::identity(),
            p: SVector::zeros(),
        }
    }

    /// The semidirect product `(Q₁,p₁)(Q₂,p₂) = (Q₁Q₂, Ad_{Q₂}ᵀ p₁ + p₂)`.
    pub fn compose<G: MatrixLieGroup<N, M>>(&self, other: &Self) -> Self {
        Phase {
            q: G::compose(&self.q, &other.q),
            p: G::adjoint(&other.q).tr_mul(&self.p) + other.p,
        }
    }

    /// The inverse `(Q,p)⁻¹ = (Q⁻¹, −Ad_{Q⁻¹}ᵀ p)`.
    pub fn inverse<G: MatrixLieGroup<N, M>>(&self) -> Self {
        let qi = G::inverse(&self.q);
        Phase {
            q: qi,
            p: -G::adjoint(&qi).tr_mul(&self.p),
        }
    }
}

/// The state action `φ(X, ξ) = ξ·X` (right multiplication in `G ⋉ g*`).
pub fn state_action<G, T, const N: usize, const M: usize>(
    x: &Phase<T, N, M>,
    xi: &Phase<T, N, M>,
) -> Phase<T, N, M>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    xi.compose::<G>(x)
}

/// The input action `ψ((X,P),(V,τ)) = (Ad_{X⁻¹}V, Ad_Xᵀτ − ad_{Ad_{X⁻¹}V}ᵀ P)`.
pub fn input_action<G, T, const N: usize, const M: usize>(
    x: &Phase<T, N, M>,
    u: &Input<T, M>,
) -> Input<T, M>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    let v = G::adjoint(&G::inverse(&x.q)) * u.v;
    Input {
        v,
        tau: G::adjoint(&x.q).tr_mul(&u.tau) - G::ad(&v).tr_mul(&x.p),
    }
}

/// The extended Euler–Poincaré vector field `f((Q,p),(V,τ)) = (Q·hat(V), ad_Vᵀ p + τ)`.
pub fn vector_field<G, T, const N: usize, const M: usize>(
    xi: &Phase<T, N, M>,
    u: &Input<T, M>,
) -> Tangent<T, N, M>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    Tangent {
        q_dot: xi.q * G::hat(&u.v),
        p_dot: G::ad(&u.v).tr_mul(&xi.p) + u.tau,
    }
}

/// The differential of the state action, `Dφ_X(ξ)[(Q̇, ṗ)] = (Q̇·X_Q, Ad_{X_Q}ᵀ ṗ)`.
pub fn state_action_differential<G, T, const N: usize, const M: usize>(
    x: &Phase<T, N, M>,
    d: &Tangent<T, N, M>,
) -> Tangent<T, N, M>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    Tangent {
        q_dot: d.q_dot * x.q,
        p_dot: G::adjoint(&x.q).tr_mul(&d.p_dot),
    }
}
