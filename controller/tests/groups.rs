//! The same property suite on every group and in both scalars (manif / Sophus style).

use controller::group::{MatrixLieGroup, Se3, So3};
use controller::{Real, real};
use nalgebra::{SMatrix, SVector};
use proptest::prelude::*;

fn vec_of<T: Real, const M: usize>(xs: &[f64]) -> SVector<T, M> {
    SVector::<T, M>::from_fn(|i, _| real(xs[i]))
}

fn err<T: Real, const R: usize, const C: usize>(a: &SMatrix<T, R, C>, b: &SMatrix<T, R, C>) -> f64 {
    nalgebra::try_convert::<T, f64>((a - b).amax()).unwrap()
}

/// `Σ_{k≤40} Xᵏ/k!`, the truncated series of the matrix exponential.
fn exp_series<T: Real, const N: usize>(x: &SMatrix<T, N, N>) -> SMatrix<T, N, N> {
    let mut sum = SMatrix::<T, N, N>::identity();
    let mut term = SMatrix::<T, N, N>::identity();
    for k in 1..=40 {
        term = term * x / real::<T>(k as f64);
        sum += term;
    }
    sum
}

/// Every axiom and identity of the suite for three algebra elements a, b, c.
fn suite<G, T, const N: usize, const M: usize>(a: &[f64], b: &[f64], c: &[f64], tol: f64)
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    let (va, vb, vc) = (vec_of::<T, M>(a), vec_of::<T, M>(b), vec_of::<T, M>(c));
    let (x, y, z) = (G::exp(&va), G::exp(&vb), G::exp(&vc));
    let id = G::identity::<T>();
    // identity, inverse, associativity
    assert!(err(&G::compose(&id, &x), &x) <= tol);
    assert!(err(&G::compose(&x, &id), &x) <= tol);
    assert!(err(&G::compose(&x, &G::inverse(&x)), &id) <= tol);
    assert!(err(&G::compose(&G::inverse(&x), &x), &id) <= tol);
    assert!(err(&G::inverse(&x), &x.try_inverse().unwrap()) <= tol);
    let l = G::compose(&G::compose(&x, &y), &z);
    let r = G::compose(&x, &G::compose(&y, &z));
    assert!(err(&l, &r) <= tol * 10.0);
    // Ad(a)Ad(b) = Ad(ab)
    let adab = G::adjoint(&x) * G::adjoint(&y);
    assert!(err(&adab, &G::adjoint(&G::compose(&x, &y))) <= tol * 10.0);
    // X hat(v) X⁻¹ = hat(Ad_X v)
    let lhs = x * G::hat(&vc) * G::inverse(&x);
    assert!(err(&lhs, &G::hat(&(G::adjoint(&x) * vc))) <= tol * 10.0);
    // ad against the matrix commutator
    let comm = G::hat(&va) * G::hat(&vb) - G::hat(&vb) * G::hat(&va);
    assert!(err(&(G::ad(&va) * vb), &G::vee(&comm)) <= tol);
    // hat/vee and the basis
    assert!(err(&G::vee(&G::hat(&va)), &va) <= tol);
    let mut sum = SMatrix::<T, N, N>::zeros();
    for i in 0..M {
        sum += G::basis::<T>(i) * va[i];
    }
    assert!(err(&sum, &G::hat(&va)) <= tol);
    // the closed-form Frobenius coordinates equal the definition through the basis
    let mm = x * z.transpose();
    let via_basis = SVector::<T, M>::from_fn(|i, _| mm.dot(&G::basis::<T>(i)));
    assert!(err(&G::frobenius_coordinates(&mm), &via_basis) <= tol);
    // exp against the truncated series
    assert!(err(&G::exp(&va), &exp_series(&G::hat(&va))) <= tol * 10.0);
}

/// `log(exp(v)) = v` for a rotation part of angle `angle` about the direction `axis`.
fn log_exp<G, T, const N: usize, const M: usize>(axis: &[f64], rest: &[f64], angle: f64, tol: f64)
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    let mut v = [0.0; 6];
    for i in 0..3 {
        v[i] = axis[i] / n * angle;
    }
    v[3..6].copy_from_slice(&rest[..3]);
    let v = vec_of::<T, M>(&v);
    let back = G::log(&G::exp(&v));
    let e = err(&back, &v);
    let scale = 1.0 + nalgebra::try_convert::<T, f64>(v.amax()).unwrap();
    assert!(
        e <= tol * scale,
        "log(exp(v)) − v = {e:e} at angle {angle:.17}"
    );
}

fn axis() -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(-1.0..1.0f64, 3).prop_filter("non-zero axis", |a| {
        a.iter().map(|x| x * x).sum::<f64>() > 1e-2
    })
}

fn algebra() -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(-1.8..1.8f64, 6)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn so3_suite_f64(a in algebra(), b in algebra(), c in algebra()) {
        suite::<So3, f64, 3, 3>(&a, &b, &c, 1e-12);
    }

    #[test]
    fn se3_suite_f64(a in algebra(), b in algebra(), c in algebra()) {
        suite::<Se3, f64, 4, 6>(&a, &b, &c, 1e-12);
    }

    #[test]
    fn so3_suite_f32(a in algebra(), b in algebra(), c in algebra()) {
        suite::<So3, f32, 3, 3>(&a, &b, &c, 5e-6);
    }

    #[test]
    fn se3_suite_f32(a in algebra(), b in algebra(), c in algebra()) {
        suite::<Se3, f32, 4, 6>(&a, &b, &c, 5e-6);
    }

    #[test]
    fn log_exp_generic_angles(ax in axis(), rest in algebra(), angle in 0.0..3.1f64) {
        log_exp::<So3, f64, 3, 3>(&ax, &rest, angle, 1e-12);
        log_exp::<Se3, f64, 4, 6>(&ax, &rest, angle, 1e-11);
        log_exp::<So3, f32, 3, 3>(&ax, &rest, angle, 2e-5);
        log_exp::<Se3, f32, 4, 6>(&ax, &rest, angle, 5e-5);
    }

    #[test]
    fn log_exp_within_1e_6_below_pi(ax in axis(), rest in algebra(), delta in 1e-12..1e-6f64) {
        let angle = core::f64::consts::PI - delta;
        log_exp::<So3, f64, 3, 3>(&ax, &rest, angle, 1e-9);
        log_exp::<Se3, f64, 4, 6>(&ax, &rest, angle, 1e-9);
    }

    #[test]
    fn log_exp_below_1e_9(ax in axis(), rest in algebra(), angle in 0.0..1e-9f64) {
        log_exp::<So3, f64, 3, 3>(&ax, &rest, angle, 1e-15);
        log_exp::<Se3, f64, 4, 6>(&ax, &rest, angle, 1e-15);
    }

    #[test]
    fn f32_log_near_pi_and_zero(ax in axis(), rest in algebra(), delta in 1e-6..1e-3f64, small in 0.0..1e-6f64) {
        log_exp::<So3, f32, 3, 3>(&ax, &rest, core::f64::consts::PI - delta, 1e-5);
        log_exp::<Se3, f32, 4, 6>(&ax, &rest, core::f64::consts::PI - delta, 1e-5);
        log_exp::<So3, f32, 3, 3>(&ax, &rest, small, 1e-7);
    }
}

#[test]
fn log_at_exactly_pi_returns_a_pi_rotation() {
    let v = SVector::<f64, 3>::new(0.0, core::f64::consts::PI, 0.0);
    let w = So3::log(&So3::exp(&v));
    assert!((w.norm() - core::f64::consts::PI).abs() < 1e-12);
    assert!(err(&So3::exp(&w), &So3::exp(&v)) < 1e-12);
}

#[test]
fn se3_adjoint_has_the_documented_blocks() {
    // Ad_(R,x) = [[R, 0], [x×R, R]] with twists ordered (ω, v).
    let q = Se3::exp(&SVector::<f64, 6>::new(0.3, -0.2, 0.5, 1.0, 2.0, -1.0));
    let ad = Se3::adjoint(&q);
    let r = q.fixed_view::<3, 3>(0, 0).into_owned();
    let x = q.fixed_view::<3, 1>(0, 3).into_owned();
    assert!(err(&ad.fixed_view::<3, 3>(0, 0).into_owned(), &r) < 1e-15);
    assert!(ad.fixed_view::<3, 3>(0, 3).amax() == 0.0);
    assert!(
        err(
            &ad.fixed_view::<3, 3>(3, 0).into_owned(),
            &(x.cross_matrix() * r)
        ) < 1e-15
    );
}
