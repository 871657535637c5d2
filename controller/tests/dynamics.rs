//! The semidirect group, the actions, equivariance and the error-dynamics theorem, checked
//! numerically on SO(3) and SE(3).

use eqtrack_controller::group::{MatrixLieGroup, Se3, So3};
use eqtrack_controller::integrator::rkmk4_step;
use eqtrack_controller::semidirect::{
    Input, Phase, input_action, state_action, state_action_differential, vector_field,
};
use eqtrack_controller::tracking::{
    error_inertia, error_inertia_inverse, error_inertia_inverse_rate, error_input,
    torque_from_error_torque, tracking_error,
};
use nalgebra::{SMatrix, SVector};
use proptest::prelude::*;

fn v<const M: usize>(xs: &[f64]) -> SVector<f64, M> {
    SVector::<f64, M>::from_fn(|i, _| xs[i])
}

fn phase<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(xs: &[f64]) -> Phase<f64, N, M> {
    Phase {
        q: G::exp(&v::<M>(&xs[0..6])),
        p: v::<M>(&xs[6..12]),
    }
}

fn input<const M: usize>(xs: &[f64]) -> Input<f64, M> {
    Input {
        v: v::<M>(&xs[12..18]),
        tau: v::<M>(&xs[18..24]),
    }
}

fn d<const R: usize, const C: usize>(a: &SMatrix<f64, R, C>, b: &SMatrix<f64, R, C>) -> f64 {
    (a - b).amax()
}

fn semidirect_axioms<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
    a: &[f64],
    b: &[f64],
    c: &[f64],
) {
    let (x, y, z) = (
        phase::<G, N, M>(a),
        phase::<G, N, M>(b),
        phase::<G, N, M>(c),
    );
    let id = Phase::<f64, N, M>::identity();
    let close =
        |l: &Phase<f64, N, M>, r: &Phase<f64, N, M>| d(&l.q, &r.q) < 1e-12 && d(&l.p, &r.p) < 1e-11;
    assert!(close(&id.compose::<G>(&x), &x));
    assert!(close(&x.compose::<G>(&id), &x));
    assert!(close(&x.compose::<G>(&x.inverse::<G>()), &id));
    assert!(close(&x.inverse::<G>().compose::<G>(&x), &id));
    let l = x.compose::<G>(&y).compose::<G>(&z);
    let r = x.compose::<G>(&y.compose::<G>(&z));
    assert!(close(&l, &r));
    // φ is a right action: φ(X, φ(Y, ξ)) = φ(Y·X, ξ), φ(id, ξ) = ξ.
    let lhs = state_action::<G, f64, N, M>(&x, &state_action::<G, f64, N, M>(&y, &z));
    let rhs = state_action::<G, f64, N, M>(&y.compose::<G>(&x), &z);
    assert!(close(&lhs, &rhs));
    assert!(close(&state_action::<G, f64, N, M>(&id, &z), &z));
}

/// `Dφ_X f(ξ,u) = f(φ_X ξ, ψ_X u)`: the left side by central differences of φ_X along a
/// curve through ξ with velocity f(ξ,u).
fn equivariance<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(a: &[f64], b: &[f64]) {
    let x = phase::<G, N, M>(a);
    let xi = phase::<G, N, M>(b);
    let u = input::<M>(b);
    let f = vector_field::<G, f64, N, M>(&xi, &u);
    let curve = |e: f64| Phase {
        q: xi.q * G::exp(&(u.v * e)),
        p: xi.p + f.p_dot * e,
    };
    let h = 1e-5;
    let (plus, minus) = (
        state_action::<G, f64, N, M>(&x, &curve(h)),
        state_action::<G, f64, N, M>(&x, &curve(-h)),
    );
    let fd_q = (plus.q - minus.q) / (2.0 * h);
    let fd_p = (plus.p - minus.p) / (2.0 * h);
    let rhs = vector_field::<G, f64, N, M>(
        &state_action::<G, f64, N, M>(&x, &xi),
        &input_action::<G, f64, N, M>(&x, &u),
    );
    let scale = 1.0 + rhs.q_dot.amax() + rhs.p_dot.amax();
    assert!(
        d(&fd_q, &rhs.q_dot) < 1e-7 * scale,
        "Q part {}",
        d(&fd_q, &rhs.q_dot)
    );
    assert!(
        d(&fd_p, &rhs.p_dot) < 1e-7 * scale,
        "p part {}",
        d(&fd_p, &rhs.p_dot)
    );
    // the analytic differential agrees too
    let an = state_action_differential::<G, f64, N, M>(&x, &f);
    assert!(d(&an.q_dot, &rhs.q_dot) < 1e-10 * scale);
    assert!(d(&an.p_dot, &rhs.p_dot) < 1e-10 * scale);
}

/// Smooth, arbitrary inputs for the extended system.
fn free_input<const M: usize>(t: f64, seed: &[f64], phase: f64) -> Input<f64, M> {
    Input {
        v: SVector::<f64, M>::from_fn(|i, _| seed[i] + 0.7 * (1.3 * t + i as f64 + phase).sin()),
        tau: SVector::<f64, M>::from_fn(|i, _| seed[6 + i] * (0.9 * t + 2.0 * i as f64).cos()),
    }
}

/// The error-dynamics theorem: along two trajectories of the extended system with arbitrary
/// inputs, d/dt (Q_E, p_E) = f(E, (V_E, τ_E)), by central differences.
fn error_dynamics<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(a: &[f64], b: &[f64]) {
    let h = 1e-3;
    let steps = 600;
    let mut x = phase::<G, N, M>(a);
    let mut xd = phase::<G, N, M>(b);
    let mut traj = Vec::with_capacity(steps + 1);
    for k in 0..=steps {
        let t = k as f64 * h;
        traj.push((t, x, xd));
        let (sa, sb) = (&a[12..], &b[12..]);
        let fa = |t: f64, _q: &SMatrix<f64, N, N>, p: &SVector<f64, M>| {
            let u = free_input::<M>(t, sa, 0.0);
            (u.v, G::ad(&u.v).tr_mul(p) + u.tau)
        };
        let fb = |t: f64, _q: &SMatrix<f64, N, N>, p: &SVector<f64, M>| {
            let u = free_input::<M>(t, sb, 1.0);
            (u.v, G::ad(&u.v).tr_mul(p) + u.tau)
        };
        x = rkmk4_step::<G, f64, _, N, M>(&x, t, h, fa);
        xd = rkmk4_step::<G, f64, _, N, M>(&xd, t, h, fb);
    }
    for k in (1..steps).step_by(97) {
        let (t, x, xd) = traj[k];
        let e_prev = tracking_error::<G, f64, N, M>(&traj[k - 1].1, &traj[k - 1].2);
        let e_next = tracking_error::<G, f64, N, M>(&traj[k + 1].1, &traj[k + 1].2);
        let e = tracking_error::<G, f64, N, M>(&x, &xd);
        let u = free_input::<M>(t, &a[12..], 0.0);
        let ud = free_input::<M>(t, &b[12..], 1.0);
        let ue = error_input::<G, f64, N, M>(&xd, &u, &ud);
        let rhs = vector_field::<G, f64, N, M>(&e, &ue);
        let fd_q = (e_next.q - e_prev.q) / (2.0 * h);
        let fd_p = (e_next.p - e_prev.p) / (2.0 * h);
        let scale = 1.0 + rhs.q_dot.amax() + rhs.p_dot.amax();
        assert!(
            d(&fd_q, &rhs.q_dot) < 1e-5 * scale,
            "Q_E: {}",
            d(&fd_q, &rhs.q_dot)
        );
        assert!(
            d(&fd_p, &rhs.p_dot) < 1e-5 * scale,
            "p_E: {}",
            d(&fd_p, &rhs.p_dot)
        );
        // (V_E, τ_E) is ψ((Q_d,p_d)⁻¹, (V − V_d, τ − τ_d)), and τ is recovered from τ_E.
        let diff = Input {
            v: u.v - ud.v,
            tau: u.tau - ud.tau,
        };
        let via_psi = input_action::<G, f64, N, M>(&xd.inverse::<G>(), &diff);
        assert!(d(&via_psi.v, &ue.v) < 1e-11 && d(&via_psi.tau, &ue.tau) < 1e-10);
        let tau = torque_from_error_torque::<G, f64, N, M>(&xd, &ud.tau, &ue.v, &ue.tau);
        assert!(d(&tau, &u.tau) < 1e-10);
    }
}

fn spd<const M: usize>(xs: &[f64]) -> SMatrix<f64, M, M> {
    let a = SMatrix::<f64, M, M>::from_fn(|i, j| xs[(i * M + j) % xs.len()] * 0.5);
    a.transpose() * a + SMatrix::identity() * 0.5
}

/// The seed's appendix: d/dt Ī⁻¹ = ad_{A V_d} Ī⁻¹ + Ī⁻¹ ad_{A V_d}ᵀ along a physical reference.
fn inertia_rate<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(a: &[f64]) {
    let inertia = spd::<M>(&a[0..24]);
    let inertia_inv = inertia.try_inverse().unwrap();
    let mut xd = phase::<G, N, M>(a);
    let h = 1e-4;
    let tau = v::<M>(&a[12..18]);
    let mut prev = xd;
    for k in 0..200 {
        let next = eqtrack_controller::integrator::physical_step::<G, f64, _, N, M>(
            &xd,
            k as f64 * h,
            h,
            &inertia_inv,
            |_| tau,
        );
        if k > 0 && k % 50 == 0 {
            let fd = (error_inertia_inverse::<G, f64, N, M>(&next.q, &inertia_inv)
                - error_inertia_inverse::<G, f64, N, M>(&prev.q, &inertia_inv))
                / (2.0 * h);
            let an = error_inertia_inverse_rate::<G, f64, N, M>(
                &xd.q,
                &(inertia_inv * xd.p),
                &inertia_inv,
            );
            assert!(d(&fd, &an) < 1e-6 * (1.0 + an.amax()), "{}", d(&fd, &an));
            // Ī Ī⁻¹ = 1 and p_E = Ī V_E
            let ib = error_inertia::<G, f64, N, M>(&xd.q, &inertia);
            let prod = ib * error_inertia_inverse::<G, f64, N, M>(&xd.q, &inertia_inv);
            assert!(d(&prod, &SMatrix::identity()) < 1e-10);
        }
        prev = xd;
        xd = next;
    }
}

fn state() -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(-1.5..1.5f64, 24)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn semidirect_group_axioms_and_right_action(a in state(), b in state(), c in state()) {
        semidirect_axioms::<So3, 3, 3>(&a, &b, &c);
        semidirect_axioms::<Se3, 4, 6>(&a, &b, &c);
    }

    #[test]
    fn equivariance_lemma_by_finite_differences(a in state(), b in state()) {
        equivariance::<So3, 3, 3>(&a, &b);
        equivariance::<Se3, 4, 6>(&a, &b);
    }

    #[test]
    fn error_inertia_inverse_rate_by_finite_differences(a in state()) {
        inertia_rate::<So3, 3, 3>(&a);
        inertia_rate::<Se3, 4, 6>(&a);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]

    #[test]
    fn error_dynamics_theorem_along_two_trajectories(a in state(), b in state()) {
        error_dynamics::<So3, 3, 3>(&a, &b);
        error_dynamics::<Se3, 4, 6>(&a, &b);
    }
}

fn free_step_is_the_full_step<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(a: &[f64]) {
    use eqtrack_controller::integrator::physical_step;
    let x = phase::<G, N, M>(a);
    let inertia = spd::<M>(&a[12..24]);
    let inv = inertia.try_inverse().unwrap();
    let torque = |s: f64| SVector::<f64, M>::from_fn(|i, _| a[i] * (1.0 + s).cos());
    // physical_step skips the stages' configurations its field never reads; rkmk4_step forms
    // them: the same step, bit for bit
    let lean = physical_step::<G, f64, _, N, M>(&x, 0.3, 0.01, &inv, torque);
    let full = rkmk4_step::<G, f64, _, N, M>(&x, 0.3, 0.01, |s, _q, p| {
        let v = inv * p;
        (v, G::ad(&v).tr_mul(p) + torque(s))
    });
    assert_eq!(lean, full);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn the_physical_step_without_stage_configurations_is_bit_exact(a in state()) {
        free_step_is_the_full_step::<So3, 3, 3>(&a);
        free_step_is_the_full_step::<Se3, 4, 6>(&a);
    }
}
