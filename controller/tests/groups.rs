//! The logarithm of every group near zero, at generic angles and near its cut locus, in both
//! scalars. The identities every group satisfies are the property kit's (`eqtrack_controller::kit`,
//! run by the crate's unit tests on SO(3), SE(3) and SE(2)).

use eqtrack_controller::group::{MatrixLieGroup, Se2, Se3, So3};
use eqtrack_controller::{Real, real};
use nalgebra::{SMatrix, SVector};
use proptest::prelude::*;

fn vec_of<T: Real, const M: usize>(xs: &[f64]) -> SVector<T, M> {
    SVector::<T, M>::from_fn(|i, _| real(xs[i]))
}

fn err<T: Real, const R: usize, const C: usize>(a: &SMatrix<T, R, C>, b: &SMatrix<T, R, C>) -> f64 {
    nalgebra::try_convert::<T, f64>((a - b).amax()).unwrap()
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

/// `log(exp(v)) = v` on SE(2) at heading `angle` (either sign) with translation `rest`.
fn log_exp_se2<T: Real>(rest: &[f64], angle: f64, tol: f64) {
    let v = vec_of::<T, 3>(&[angle, rest[0], rest[1]]);
    let back = Se2::log(&Se2::exp(&v));
    let e = err(&back, &v);
    let scale = 1.0 + nalgebra::try_convert::<T, f64>(v.amax()).unwrap();
    assert!(
        e <= tol * scale,
        "SE(2): log(exp(v)) − v = {e:e} at angle {angle:.17}"
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
    fn log_exp_generic_angles(ax in axis(), rest in algebra(), angle in 0.0..3.1f64) {
        log_exp::<So3, f64, 3, 3>(&ax, &rest, angle, 1e-12);
        log_exp::<Se3, f64, 4, 6>(&ax, &rest, angle, 1e-11);
        log_exp::<So3, f32, 3, 3>(&ax, &rest, angle, 2e-5);
        log_exp::<Se3, f32, 4, 6>(&ax, &rest, angle, 5e-5);
        let sign = ax[0].signum();
        log_exp_se2::<f64>(&rest, sign * angle, 1e-12);
        log_exp_se2::<f32>(&rest, sign * angle, 2e-5);
    }

    #[test]
    fn log_exp_within_1e_6_below_pi(ax in axis(), rest in algebra(), delta in 1e-12..1e-6f64) {
        let angle = core::f64::consts::PI - delta;
        log_exp::<So3, f64, 3, 3>(&ax, &rest, angle, 1e-9);
        log_exp::<Se3, f64, 4, 6>(&ax, &rest, angle, 1e-9);
        log_exp_se2::<f64>(&rest, ax[0].signum() * angle, 1e-9);
    }

    #[test]
    fn log_exp_below_1e_9(ax in axis(), rest in algebra(), angle in 0.0..1e-9f64) {
        log_exp::<So3, f64, 3, 3>(&ax, &rest, angle, 1e-15);
        log_exp::<Se3, f64, 4, 6>(&ax, &rest, angle, 1e-15);
        log_exp_se2::<f64>(&rest, ax[0].signum() * angle, 1e-15);
    }

    #[test]
    fn f32_log_near_pi_and_zero(ax in axis(), rest in algebra(), delta in 1e-6..1e-3f64, small in 0.0..1e-6f64) {
        log_exp::<So3, f32, 3, 3>(&ax, &rest, core::f64::consts::PI - delta, 1e-5);
        log_exp::<Se3, f32, 4, 6>(&ax, &rest, core::f64::consts::PI - delta, 1e-5);
        log_exp::<So3, f32, 3, 3>(&ax, &rest, small, 1e-7);
        log_exp_se2::<f32>(&rest, ax[0].signum() * (core::f64::consts::PI - delta), 1e-5);
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

#[test]
fn se2_has_the_documented_conventions() {
    // hat(ω, v) = [[0, −ω, v_x], [ω, 0, v_y], [0, 0, 0]], twists ordered (ω, v_x, v_y)
    let h = Se2::hat(&SVector::<f64, 3>::new(0.7, 2.0, -3.0));
    let expect = nalgebra::Matrix3::new(0.0, -0.7, 2.0, 0.7, 0.0, -3.0, 0.0, 0.0, 0.0);
    assert_eq!(h, expect);
    // a pure rotation by θ turns the plane; a pure twist (0, v) translates by v
    let q = Se2::exp(&SVector::<f64, 3>::new(
        core::f64::consts::FRAC_PI_2,
        0.0,
        0.0,
    ));
    assert!(
        err(
            &q,
            &nalgebra::Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0)
        ) < 1e-15
    );
    let q = Se2::exp(&SVector::<f64, 3>::new(0.0, 1.5, -2.5));
    assert_eq!((q[(0, 2)], q[(1, 2)]), (1.5, -2.5));
    // the log at exactly ±π returns a heading of magnitude π
    let w = Se2::log(&Se2::exp(&SVector::<f64, 3>::new(
        core::f64::consts::PI,
        1.0,
        0.5,
    )));
    assert!((w[0].abs() - core::f64::consts::PI).abs() < 1e-12, "{w}");
    assert!(
        err(
            &Se2::exp(&w),
            &Se2::exp(&SVector::<f64, 3>::new(core::f64::consts::PI, 1.0, 0.5))
        ) < 1e-12
    );
}
