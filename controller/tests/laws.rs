//! The laws against each other, and the controller's validation and safety.

mod common;

use eqtrack_controller::group::{BuiltinGroup, MatrixLieGroup, Se3, So3};
use eqtrack_controller::law::so3::{self, So3LawInput};
use eqtrack_controller::law::{Desired, eqt};
use eqtrack_controller::validate::gain_from_slice;
use eqtrack_controller::{Controller, ControllerConfig, Error, GroupKind, Law, Quantity};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use proptest::prelude::*;

fn spd3(xs: &[f64]) -> Matrix3<f64> {
    let a = Matrix3::from_fn(|i, j| xs[i * 3 + j]);
    a.transpose() * a + Matrix3::identity() * 0.3
}

fn so3_input(xs: &[f64]) -> So3LawInput<f64> {
    let v3 = |o: usize| Vector3::new(xs[o], xs[o + 1], xs[o + 2]);
    So3LawInput {
        r: So3::exp(&(v3(0) * 1.7)),
        omega: v3(3) * 3.0,
        r_d: So3::exp(&(v3(6) * 1.7)),
        omega_d: v3(9) * 2.0,
        tau_d: v3(12),
        inertia: spd3(&xs[15..24]),
        k: spd3(&xs[24..33]),
        kd: spd3(&xs[33..42]),
    }
}

fn generic_eqt(x: &So3LawInput<f64>) -> Vector3<f64> {
    let desired = Desired {
        q: x.r_d,
        p: x.inertia * x.omega_d,
        v: x.omega_d,
        tau: x.tau_d,
    };
    eqt::<So3, f64, 3, 3>(
        &x.r,
        &x.omega,
        &(x.inertia * x.omega),
        &desired,
        &x.k,
        &x.kd,
    )
    .0
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn generic_eqt_equals_closed_form_with_matrix_gains(xs in prop::collection::vec(-1.0..1.0f64, 42)) {
        let x = so3_input(&xs);
        // non-diagonal gains (with probability one)
        prop_assert!(x.k[(0, 1)].abs() > 0.0 && x.kd[(1, 2)].abs() > 0.0);
        let g = generic_eqt(&x);
        let c = so3::eqt(&x);
        prop_assert!((g - c).amax() <= 1e-12 * (1.0 + c.amax()), "generic {g:?} closed {c:?}");
    }

    #[test]
    fn generic_eqt_equals_the_seed_formula_with_scalar_gains(
        xs in prop::collection::vec(-1.0..1.0f64, 42), kp in 0.1..3.0f64, kv in 0.1..3.0f64,
    ) {
        let mut x = so3_input(&xs);
        // The seed's (k_p, k_v) are K = (k_p/2)·1₃, K_d = k_v·1₃ (docs/maths.md, "Typos in the seed paper").
        x.k = Matrix3::identity() * (kp / 2.0);
        x.kd = Matrix3::identity() * kv;
        let g = generic_eqt(&x);
        let s = so3::seed(&x, kp, kv);
        prop_assert!((g - s).amax() <= 1e-12 * (1.0 + s.amax()));
    }

    #[test]
    fn comparison_laws_differ_from_eqt_only_in_their_terms(xs in prop::collection::vec(-1.0..1.0f64, 42)) {
        let x = so3_input(&xs);
        let we = x.omega - x.omega_d;
        let iwd = x.inertia * x.omega_d;
        // nog drops ω̃×Iω_d from EqT; asym halves ω_d×Iω̃ and adds ½I(ω×ω_d).
        let nog_gap = so3::eqt(&x) - so3::nog(&x) - we.cross(&iwd);
        prop_assert!(nog_gap.amax() < 1e-12 * (1.0 + so3::eqt(&x).amax()));
        let asym_gap = so3::eqt(&x) - so3::asym(&x)
            - x.omega_d.cross(&(x.inertia * we)) * 0.5
            + x.inertia * x.omega.cross(&x.omega_d) * 0.5;
        prop_assert!(asym_gap.amax() < 1e-12 * (1.0 + so3::eqt(&x).amax()));
        // on a set-point (ω_d = 0) with R_d = I all four laws coincide
        let mut sp = x;
        sp.omega_d = Vector3::zeros();
        sp.r_d = Matrix3::identity();
        for law in [so3::gt(&sp), so3::nog(&sp), so3::asym(&sp)] {
            prop_assert!((law - so3::eqt(&sp)).amax() < 1e-12 * (1.0 + law.amax()));
        }
    }
}

fn config3(law: Law) -> ControllerConfig<f64, 3, 3> {
    ControllerConfig {
        law,
        error_frame: eqtrack_controller::ErrorFrame::World,
        inertia: common::fixed_wing(),
        k: Matrix3::identity(),
        kd: Matrix3::identity() * 0.5,
        torque_limit: None,
    }
}

fn config6(law: Law) -> ControllerConfig<f64, 4, 6> {
    ControllerConfig {
        law,
        error_frame: eqtrack_controller::ErrorFrame::World,
        inertia: SMatrix::<f64, 6, 6>::identity() * 2.0,
        k: SMatrix::<f64, 4, 4>::identity(),
        kd: SMatrix::<f64, 6, 6>::identity(),
        torque_limit: None,
    }
}

fn desired3() -> Desired<f64, 3, 3> {
    Desired {
        q: Matrix3::identity(),
        p: Vector3::zeros(),
        v: Vector3::zeros(),
        tau: Vector3::new(0.1, 0.2, 0.3),
    }
}

#[test]
fn comparison_laws_on_se3_are_a_typed_error() {
    for law in [Law::Gt, Law::Nog, Law::Asym] {
        let e = Controller::<f64, Se3, 4, 6>::new(config6(law)).unwrap_err();
        assert_eq!(e, Error::LawNotDefined { law, group: "se3" });
        assert!(e.to_string().contains("not defined for group se3"));
    }
    assert!(Controller::<f64, Se3, 4, 6>::new(config6(Law::Eqt)).is_ok());
    for law in Law::ALL {
        assert!(Controller::<f64, So3, 3, 3>::new(config3(law)).is_ok());
    }
}

#[test]
fn the_controller_dispatches_the_closed_forms_on_so3() {
    let r = So3::exp(&Vector3::new(0.4, -1.0, 2.0));
    let w = Vector3::new(0.3, -0.2, 0.9);
    let mut d = desired3();
    d.q = So3::exp(&Vector3::new(-0.3, 0.2, 0.1));
    d.v = Vector3::new(0.5, 0.1, -0.4);
    d.p = common::fixed_wing::<f64>() * d.v;
    let x = So3LawInput {
        r,
        omega: w,
        r_d: d.q,
        omega_d: d.v,
        tau_d: d.tau,
        inertia: common::fixed_wing(),
        k: Matrix3::identity(),
        kd: Matrix3::identity() * 0.5,
    };
    for (law, expect) in [
        (Law::Eqt, so3::eqt(&x)),
        (Law::Gt, so3::gt(&x)),
        (Law::Nog, so3::nog(&x)),
        (Law::Asym, so3::asym(&x)),
    ] {
        let c = Controller::<f64, So3, 3, 3>::new(config3(law)).unwrap();
        let out = c.compute(&r, &w, &d).unwrap();
        assert!((out.torque - expect).amax() < 1e-12, "{law:?}");
    }
}

#[test]
fn invalid_gains_and_inertia_are_typed_errors() {
    let mut c = config3(Law::Eqt);
    c.inertia[(0, 1)] = 0.5; // not symmetric
    assert_eq!(
        Controller::<f64, So3, 3, 3>::new(c).unwrap_err(),
        Error::NotSymmetric(Quantity::Inertia)
    );
    let mut c = config3(Law::Eqt);
    c.k = Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, 1.0));
    assert_eq!(
        Controller::<f64, So3, 3, 3>::new(c).unwrap_err(),
        Error::NotPositiveDefinite(Quantity::PotentialGain)
    );
    let mut c = config3(Law::Eqt);
    c.kd[(2, 2)] = f64::NAN;
    assert_eq!(
        Controller::<f64, So3, 3, 3>::new(c).unwrap_err(),
        Error::NonFinite(Quantity::DampingGain)
    );
    let mut c = config3(Law::Eqt);
    c.torque_limit = Some(Vector3::new(1.0, 0.0, 1.0));
    assert_eq!(
        Controller::<f64, So3, 3, 3>::new(c).unwrap_err(),
        Error::NotPositive(Quantity::TorqueLimit)
    );
    let mut c = config3(Law::Eqt);
    c.inertia = Matrix3::zeros();
    assert_eq!(
        Controller::<f64, So3, 3, 3>::new(c).unwrap_err(),
        Error::NotPositiveDefinite(Quantity::Inertia)
    );
}

#[test]
fn wrongly_shaped_gains_are_typed_errors() {
    assert_eq!(
        gain_from_slice::<f64, 3>(Quantity::PotentialGain, &[1.0, 2.0]).unwrap_err(),
        Error::WrongShape {
            quantity: Quantity::PotentialGain,
            expected: 9,
            found: 2
        }
    );
    let k = gain_from_slice::<f64, 4>(Quantity::PotentialGain, &[2.0]).unwrap();
    assert_eq!(k, SMatrix::<f64, 4, 4>::identity() * 2.0);
    assert_eq!(
        gain_from_slice::<f64, 3>(Quantity::DampingGain, &[-1.0]).unwrap_err(),
        Error::NotPositiveDefinite(Quantity::DampingGain)
    );
}

#[test]
fn non_finite_state_gives_an_error_never_a_nan_torque() {
    let c = Controller::<f64, So3, 3, 3>::new(config3(Law::Eqt)).unwrap();
    let r = Matrix3::identity();
    let bad = Vector3::new(0.0, f64::NAN, 0.0);
    assert_eq!(
        c.compute(&r, &bad, &desired3()).unwrap_err(),
        Error::NonFinite(Quantity::State)
    );
    let mut rq = r;
    rq[(1, 1)] = f64::INFINITY;
    assert_eq!(
        c.compute(&rq, &Vector3::zeros(), &desired3()).unwrap_err(),
        Error::NonFinite(Quantity::State)
    );
    let mut d = desired3();
    d.tau[0] = f64::NAN;
    assert_eq!(
        c.compute(&r, &Vector3::zeros(), &d).unwrap_err(),
        Error::NonFinite(Quantity::Reference)
    );
    // finite but absurd inputs (not a rotation, entries 1e200): the potential's gradient
    // overflows, so the torque is refused rather than returned as inf or NaN
    let huge = Matrix3::new(1e200, -1e200, 3e200, 0.0, 1e200, 0.0, 2e200, 0.0, -1e200);
    assert_eq!(
        c.compute(&huge, &Vector3::zeros(), &desired3())
            .unwrap_err(),
        Error::NonFinite(Quantity::Torque)
    );
}

#[test]
fn saturation_clamps_each_axis() {
    let mut cfg = config3(Law::Eqt);
    cfg.torque_limit = Some(Vector3::new(0.5, 0.05, 10.0));
    let c = Controller::<f64, So3, 3, 3>::new(cfg).unwrap();
    let free = Controller::<f64, So3, 3, 3>::new(config3(Law::Eqt)).unwrap();
    let r = So3::exp(&Vector3::new(1.0, 2.0, -0.5));
    let w = Vector3::new(3.0, -2.0, 1.0);
    let raw = free.compute(&r, &w, &desired3()).unwrap().torque;
    let out = c.compute(&r, &w, &desired3()).unwrap();
    assert!(out.saturated);
    for i in 0..3 {
        let l = cfg.torque_limit.unwrap()[i];
        assert!(out.torque[i].abs() <= l);
        assert_eq!(out.torque[i], raw[i].clamp(-l, l));
    }
}

#[test]
fn the_law_works_in_f32_on_both_groups() {
    let c = Controller::<f32, So3, 3, 3>::new(ControllerConfig {
        law: Law::Eqt,
        error_frame: eqtrack_controller::ErrorFrame::World,
        inertia: common::fixed_wing(),
        k: Matrix3::identity(),
        kd: Matrix3::identity(),
        torque_limit: None,
    })
    .unwrap();
    let d = Desired {
        q: Matrix3::identity(),
        p: Vector3::zeros(),
        v: Vector3::zeros(),
        tau: Vector3::zeros(),
    };
    let r = So3::exp(&Vector3::new(0.1f32, 0.2, 0.3));
    let t32 = c
        .compute(&r, &Vector3::new(0.5, 0.0, 0.0), &d)
        .unwrap()
        .torque;
    let c64 = Controller::<f64, So3, 3, 3>::new(config3(Law::Eqt)).unwrap();
    let mut d64 = desired3();
    d64.tau = Vector3::zeros();
    let mut cfg = config3(Law::Eqt);
    cfg.kd = Matrix3::identity();
    let c64b = Controller::<f64, So3, 3, 3>::new(cfg).unwrap();
    let _ = c64;
    let t64 = c64b
        .compute(
            &So3::exp(&Vector3::new(0.1, 0.2, 0.3)),
            &Vector3::new(0.5, 0.0, 0.0),
            &d64,
        )
        .unwrap()
        .torque;
    for i in 0..3 {
        assert!((t32[i] as f64 - t64[i]).abs() < 1e-6 * (1.0 + t64[i].abs()));
    }
    let c6 = Controller::<f32, Se3, 4, 6>::new(ControllerConfig {
        law: Law::Eqt,
        error_frame: eqtrack_controller::ErrorFrame::World,
        inertia: SMatrix::<f32, 6, 6>::identity(),
        k: SMatrix::<f32, 4, 4>::identity(),
        kd: SMatrix::<f32, 6, 6>::identity(),
        torque_limit: None,
    })
    .unwrap();
    let q = Se3::exp(&SVector::<f32, 6>::new(0.1, 0.2, 0.3, 1.0, -1.0, 0.5));
    let d6 = Desired {
        q: SMatrix::identity(),
        p: SVector::zeros(),
        v: SVector::zeros(),
        tau: SVector::zeros(),
    };
    let out = c6.compute(&q, &SVector::zeros(), &d6).unwrap();
    assert!(out.torque.iter().all(|t| t.is_finite()) && out.torque.norm() > 0.1);
}

proptest! {
    /// The safe-mode law dissipates: `Vᵀ sat(−K_d V) ≤ 0` for a diagonal `K_d` whatever the
    /// limits, `= −VᵀK_dV` without one; every axis stays within its limit.
    #[test]
    fn safe_mode_torque_damps_and_respects_the_limit(
        v in prop::collection::vec(-10.0..10.0f64, 6),
        d in prop::collection::vec(0.05..5.0f64, 6),
        l in prop::collection::vec(0.01..3.0f64, 6),
    ) {
        use eqtrack_controller::law::safe_mode_torque;
        let v = SVector::<f64, 6>::from_column_slice(&v);
        let kd = SMatrix::<f64, 6, 6>::from_diagonal(&SVector::from_column_slice(&d));
        let limit = SVector::<f64, 6>::from_column_slice(&l);
        let free = safe_mode_torque(&kd, &v, None);
        prop_assert!((v.dot(&free) + v.dot(&(kd * v))).abs() <= 1e-9 * (1.0 + v.norm_squared()));
        let tau = safe_mode_torque(&kd, &v, Some(&limit));
        prop_assert!(v.dot(&tau) <= 0.0);
        for i in 0..6 {
            prop_assert!(tau[i].abs() <= limit[i]);
            prop_assert!(tau[i] * free[i] >= 0.0, "clamping keeps each axis' sign");
        }
    }
}

#[test]
fn saturation_clamps_each_axis_and_says_so() {
    use eqtrack_controller::law::saturate;
    let limit = Vector3::new(1.0, 2.0, 3.0);
    let mut tau = Vector3::new(-5.0, 1.5, 3.5);
    assert!(saturate(&mut tau, Some(&limit)));
    assert_eq!(tau, Vector3::new(-1.0, 1.5, 3.0));
    let mut inside = Vector3::new(0.5, -2.0, 0.0);
    assert!(!saturate(&mut inside, Some(&limit)));
    assert_eq!(inside, Vector3::new(0.5, -2.0, 0.0));
    assert!(!saturate(&mut tau, None));
    // the controller's own safe-mode torque uses its K_d and limit
    let c = Controller::<f64, So3, 3, 3>::new(config3(Law::Eqt)).unwrap();
    let v = Vector3::new(100.0, -0.1, 0.0);
    let t = c.safe_mode_torque(&v);
    let kd = c.config().kd;
    let mut expect = -(kd * v);
    saturate(&mut expect, c.config().torque_limit.as_ref());
    assert_eq!(t, expect);
}

#[test]
fn group_dispatch_gives_each_kind_its_type() {
    use eqtrack_controller::group::OnGroup;
    struct Dims;
    impl OnGroup for Dims {
        type Output = (GroupKind, usize, usize);
        fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
            (G::KIND, N, M)
        }
    }
    for g in GroupKind::ALL {
        let (kind, n, m) = g.dispatch(Dims);
        assert_eq!(kind, g);
        assert_eq!((n, m), g.dims());
        assert_eq!(GroupKind::from_name(g.name()), Some(g));
    }
}
