//! Tracking error, error inputs, error inertia and the Lyapunov function
//! (docs/maths.md, "Tracking error and its dynamics" and "The EqT law").
//!
//! Throughout, `A = Ad_{Q_d}` and `A⁻¹ = Ad_{Q_d⁻¹}` (no matrix is inverted numerically).

use crate::Real;
use crate::group::MatrixLieGroup;
use crate::semidirect::{Input, Phase};
use nalgebra::{SMatrix, SVector};

/// The tracking error `(Q_E, p_E) = (Q Q_d⁻¹, A⁻ᵀ(p − p_d))`, which is the state action
/// `φ((Q_d, p_d)⁻¹, (Q, p))`.
pub fn tracking_error<G, T, const N: usize, const M: usize>(
    state: &Phase<T, N, M>,
    desired: &Phase<T, N, M>,
) -> Phase<T, N, M>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    let qd_inv = G::inverse(&desired.q);
    error_from::<G, T, N, M>(
        &state.q,
        &state.p,
        &qd_inv,
        &G::adjoint(&qd_inv),
        &desired.p,
    )
}

/// [`tracking_error`] of `(q, p)` from `Q_d⁻¹` and `A⁻ = Ad_{Q_d⁻¹}` already formed (the EqT
/// law needs them too, and forms them once): `(Q Q_d⁻¹, A⁻ᵀ(p − p_d))`.
pub(crate) fn error_from<G, T, const N: usize, const M: usize>(
    q: &SMatrix<T, N, N>,
    p: &SVector<T, M>,
    qd_inv: &SMatrix<T, N, N>,
    a_inv: &SMatrix<T, M, M>,
    p_d: &SVector<T, M>,
) -> Phase<T, N, M>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    Phase {
        q: G::compose(q, qd_inv),
        p: a_inv.tr_mul(&(p - p_d)),
    }
}

/// The error inputs `V_E = A(V − V_d)`, `τ_E = A⁻ᵀ(τ − τ_d) + ad_{V_E}ᵀ A⁻ᵀ p_d`
/// (docs/maths.md, "Tracking error and its dynamics"; equal to `ψ((Q_d,p_d)⁻¹, (V − V_d, τ − τ_d))`).
pub fn error_input<G, T, const N: usize, const M: usize>(
    desired: &Phase<T, N, M>,
    input: &Input<T, M>,
    desired_input: &Input<T, M>,
) -> Input<T, M>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    let a = G::adjoint(&desired.q);
    let a_inv = G::adjoint(&G::inverse(&desired.q));
    let v_e = a * (input.v - desired_input.v);
    Input {
        v: v_e,
        tau: a_inv.tr_mul(&(input.tau - desired_input.tau))
            + G::ad(&v_e).tr_mul(&a_inv.tr_mul(&desired.p)),
    }
}

/// The physical torque that realises a chosen error torque:
/// `τ = τ_d + Aᵀ(τ_E − ad_{V_E}ᵀ A⁻ᵀ p_d)` (the inverse of [`error_input`]'s torque map).
pub fn torque_from_error_torque<G, T, const N: usize, const M: usize>(
    desired: &Phase<T, N, M>,
    tau_d: &SVector<T, M>,
    v_e: &SVector<T, M>,
    tau_e: &SVector<T, M>,
) -> SVector<T, M>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    let a = G::adjoint(&desired.q);
    let a_inv = G::adjoint(&G::inverse(&desired.q));
    tau_d + a.tr_mul(&(tau_e - G::ad(v_e).tr_mul(&a_inv.tr_mul(&desired.p))))
}

/// The error inertia `Ī = A⁻ᵀ I A⁻¹`, so that `p_E = Ī V_E`.
pub fn error_inertia<G, T, const N: usize, const M: usize>(
    q_d: &SMatrix<T, N, N>,
    inertia: &SMatrix<T, M, M>,
) -> SMatrix<T, M, M>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    let a_inv = G::adjoint(&G::inverse(q_d));
    a_inv.tr_mul(inertia) * a_inv
}

/// The inverse error inertia `Ī⁻¹ = A I⁻¹ Aᵀ`.
pub fn error_inertia_inverse<G, T, const N: usize, const M: usize>(
    q_d: &SMatrix<T, N, N>,
    inertia_inv: &SMatrix<T, M, M>,
) -> SMatrix<T, M, M>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    let a = G::adjoint(q_d);
    a * inertia_inv * a.transpose()
}

/// The seed paper's appendix (Proposition "I_bar_dot"):
/// `d/dt Ī⁻¹ = ad_{A V_d} Ī⁻¹ + Ī⁻¹ ad_{A V_d}ᵀ`.
pub fn error_inertia_inverse_rate<G, T, const N: usize, const M: usize>(
    q_d: &SMatrix<T, N, N>,
    v_d: &SVector<T, M>,
    inertia_inv: &SMatrix<T, M, M>,
) -> SMatrix<T, M, M>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    let ii = error_inertia_inverse::<G, T, N, M>(q_d, inertia_inv);
    let ad = G::ad(&(G::adjoint(q_d) * v_d));
    ad * ii + ii * ad.transpose()
}

/// The potential `Υ(Q) = ½ tr((Q − I) K (Q − I)ᵀ)` (docs/maths.md, "The EqT law").
pub fn potential<T: Real, const N: usize>(q_e: &SMatrix<T, N, N>, k: &SMatrix<T, N, N>) -> T {
    let d = q_e - SMatrix::<T, N, N>::identity();
    (d * k).dot(&d) * crate::real(0.5)
}

/// The left-trivialised gradient of Υ, `grad_i = ⟨Q_Eᵀ(Q_E − I)K, E_i⟩_F`.
pub fn potential_gradient<G, T, const N: usize, const M: usize>(
    q_e: &SMatrix<T, N, N>,
    k: &SMatrix<T, N, N>,
) -> SVector<T, M>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    let d = q_e - SMatrix::<T, N, N>::identity();
    G::frobenius_coordinates(&(q_e.tr_mul(&d) * k))
}

/// The Lyapunov function and its parts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lyapunov<T> {
    /// Kinetic part `½ (V − V_d)ᵀ I (V − V_d)` (= `½ p_Eᵀ Ī⁻¹ p_E`).
    pub kinetic: T,
    /// Potential part `Υ(Q_E)`.
    pub potential: T,
    /// `L = kinetic + potential`.
    pub total: T,
}

/// The Lyapunov function `L = ½ (V − V_d)ᵀ I (V − V_d) + Υ(Q_E)` (docs/maths.md, "The EqT law"),
/// with `I` the controller's model inertia.
pub fn lyapunov<T: Real, const N: usize, const M: usize>(
    q_e: &SMatrix<T, N, N>,
    velocity_error: &SVector<T, M>,
    inertia: &SMatrix<T, M, M>,
    k: &SMatrix<T, N, N>,
) -> Lyapunov<T> {
    let kinetic = (inertia * velocity_error).dot(velocity_error) * crate::real(0.5);
    let potential = potential(q_e, k);
    Lyapunov {
        kinetic,
        potential,
        total: kinetic + potential,
    }
}

/// The error norms the simulations report.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorNorms<T> {
    /// `‖Q_E − I‖_F`.
    pub config_error: T,
    /// `‖p_E‖`.
    pub momentum_error: T,
    /// `‖I − R_dᵀR‖_F` (attitude part only); on a group without an
    /// [`attitude`](crate::MatrixLieGroup::attitude), `‖Q_E − I‖_F`.
    pub attitude_error: T,
    /// `‖V − V_d‖`.
    pub velocity_error: T,
}

/// Computes [`ErrorNorms`] from the state, the desired state and the tracking error.
pub fn error_norms<G, T, const N: usize, const M: usize>(
    q: &SMatrix<T, N, N>,
    q_d: &SMatrix<T, N, N>,
    error: &Phase<T, N, M>,
    velocity_error: &SVector<T, M>,
) -> ErrorNorms<T>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    let config_error = (error.q - SMatrix::<T, N, N>::identity()).norm();
    let attitude_error = match (G::attitude(q), G::attitude(q_d)) {
        (Some(r), Some(r_d)) => (nalgebra::Matrix3::identity() - r_d.tr_mul(&r)).norm(),
        _ => config_error,
    };
    ErrorNorms {
        config_error,
        momentum_error: error.p.norm(),
        attitude_error,
        velocity_error: velocity_error.norm(),
    }
}
