//! Disturbance rejection (docs/maths.md, "Disturbance rejection"): the momentum observer and
//! the geometric integral against constant disturbances, windup under saturation, a world
//! force on SE(3), and the observer's error rate.

use eqtrack_controller::closed_loop::ClosedLoop;
use eqtrack_controller::group::{MatrixLieGroup, Se3, So3};
use eqtrack_controller::integrator::RigidBody;
use eqtrack_controller::path::{Path, PathReference};
use eqtrack_controller::reference::Feedforward;
use eqtrack_controller::{
    Controller, ControllerConfig, Frame, IntegralConfig, Law, ObserverConfig, Reference,
    RejectionConfig,
};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

mod common;

const H: f64 = 0.002;

fn body() -> Matrix3<f64> {
    Matrix3::from_diagonal(&Vector3::new(0.02, 0.02, 0.04))
}

fn d() -> Vector3<f64> {
    Vector3::new(0.1, -0.05, 0.08)
}

fn observer(gain: f64, frame: Frame) -> Option<ObserverConfig<f64, 3>> {
    Some(ObserverConfig {
        gain: Vector3::repeat(gain),
        limit: None,
        frame,
    })
}

fn integral(ki: f64, c: f64, anti_windup: bool) -> Option<IntegralConfig<f64, 3>> {
    Some(IntegralConfig {
        ki: Vector3::repeat(ki),
        c: Vector3::repeat(c),
        limit: None,
        anti_windup,
    })
}

/// The set-point: J = diag(0.02, 0.02, 0.04), K = 1, K_d = 0.28, h = 2 ms, the body
/// disturbance `d`, from the identity at rest to `target`.
fn setpoint(
    target: Matrix3<f64>,
    limit: Option<f64>,
    rejection: RejectionConfig<f64, 3>,
) -> ClosedLoop<f64, So3, 3, 3, PathReference<f64, So3, 3, 3>> {
    let controller = Controller::new(ControllerConfig {
        law: Law::Eqt,
        error_frame: eqtrack_controller::ErrorFrame::World,
        inertia: body(),
        k: Matrix3::identity(),
        kd: Matrix3::identity() * 0.28,
        torque_limit: limit.map(Vector3::repeat),
    })
    .unwrap();
    let reference = PathReference::new(Path::hold(target).unwrap(), body(), H).unwrap();
    let plant = RigidBody::new(body(), Matrix3::identity(), Vector3::zeros()).unwrap();
    ClosedLoop::new(controller, reference, plant, 10)
        .unwrap()
        .with_disturbance(d())
        .unwrap()
        .with_rejection(rejection)
        .unwrap()
}

fn target() -> Matrix3<f64> {
    So3::exp(&Vector3::new(0.3, -0.2, 0.5))
}

/// The attitude error angle `|log(R R_dᵀ)|`.
fn angle(q: &Matrix3<f64>, q_d: &Matrix3<f64>) -> f64 {
    So3::log(&(q * q_d.transpose())).norm()
}

#[test]
fn t1_pd_leaves_the_predicted_offset_and_both_terms_remove_it() {
    let cases = [
        ("PD", RejectionConfig::default()),
        (
            "observer L = 20",
            RejectionConfig {
                observer: observer(20.0, Frame::Body),
                integral: None,
            },
        ),
        (
            "integral K_I = 1, c = 5",
            RejectionConfig {
                observer: None,
                integral: integral(1.0, 5.0, true),
            },
        ),
    ];
    for (name, config) in cases {
        let mut sim = setpoint(target(), None, config);
        let steps = (10.0 / H).round() as usize;
        let mut last = None;
        for _ in 0..=steps {
            last = Some(sim.step().unwrap());
        }
        let s = last.unwrap();
        assert!((s.t - 10.0).abs() < 1e-9);
        let err = angle(&s.q, &s.desired.q);
        // the estimate of d in the body frame: d̂, or the integral's torque −K_I z
        let estimate = s.output.observer - s.output.integral;
        println!(
            "T1 {name}: attitude error at 10 s {err:.3e} rad, estimate ({:.6}, {:.6}, {:.6})",
            estimate[0], estimate[1], estimate[2]
        );
        if name == "PD" {
            // asin(|d| / 2k) with k = 1: the potential's stiffness against d
            let predicted = (d().norm() / 2.0).asin();
            assert!((err - 0.0688).abs() < 1e-4, "{err}");
            assert!((err - predicted).abs() < 1e-4, "{err} vs {predicted}");
            assert_eq!(estimate, Vector3::zeros());
            // and it stays there: 40 s
            for _ in 0..(30.0 / H) as usize {
                sim.step().unwrap();
            }
            let late = angle(sim.plant.configuration(), &s.desired.q);
            assert!((late - err).abs() < 1e-6, "{late} vs {err}");
        } else {
            assert!(err < 1e-4, "{name}: {err}");
            assert!((estimate - d()).amax() < 1e-3, "{name}: {estimate}");
        }
    }
}

/// The overshoot of a set-point step: how far past the set-point the attitude swings, along
/// the step's own axis, after the error first crosses zero.
/// Returns the overshoot (rad), the integral torque's peak (N·m) and the error at 30 s.
fn overshoot(rejection: RejectionConfig<f64, 3>) -> (f64, f64, f64) {
    let axis = Vector3::new(1.0, 2.0, 2.0) / 3.0;
    let target = So3::exp(&(axis * 170f64.to_radians()));
    let mut sim = setpoint(target, Some(0.3), rejection);
    let (mut worst, mut integral_peak) = (0.0f64, 0.0f64);
    let mut saturated = 0;
    for _ in 0..(30.0 / H) as usize {
        let s = sim.step().unwrap();
        // the error's component along the step axis: negative at the start
        let along = So3::log(&(s.q * target.transpose())).dot(&axis);
        worst = worst.max(along);
        integral_peak = integral_peak.max(s.output.integral.amax());
        saturated += usize::from(s.output.saturated);
    }
    assert!(
        saturated > 100,
        "the step saturates for a while: {saturated} ticks"
    );
    let end = angle(sim.plant.configuration(), &target);
    (worst, integral_peak, end)
}

#[test]
fn t2_anti_windup_and_the_observer_halve_the_overshoot_and_the_clamp_holds() {
    let (pd, _, pd_end) = overshoot(RejectionConfig::default());
    let (wound, _, wound_end) = overshoot(RejectionConfig {
        observer: None,
        integral: integral(1.0, 5.0, false),
    });
    let (anti, peak, anti_end) = overshoot(RejectionConfig {
        observer: None,
        integral: integral(1.0, 5.0, true),
    });
    let (obs, _, obs_end) = overshoot(RejectionConfig {
        observer: observer(20.0, Frame::Body),
        integral: None,
    });
    println!(
        "T2 overshoot of a 170° step (torque limit 0.3 N·m), and the error at 30 s: \
         PD {pd:.4} rad ({pd_end:.2e}), integral without anti-windup {wound:.4} rad \
         ({wound_end:.2e}), with anti-windup {anti:.4} rad ({anti_end:.2e}), observer {obs:.4} rad \
         ({obs_end:.2e}); the integral's torque peaks at {peak:.4} N·m"
    );
    assert!(anti_end < 1e-6 && obs_end < 1e-6, "{anti_end}, {obs_end}");
    assert!((pd_end - 0.0688).abs() < 1e-3, "{pd_end}");
    assert!(wound > 0.05, "{wound}");
    assert!(anti < 0.5 * wound, "{anti} vs {wound}");
    assert!(obs < 0.5 * wound, "{obs} vs {wound}");
    // the default clamp: half the torque limit
    assert!(peak <= 0.15 + 1e-12, "{peak}");
}

/// T3's body: 1 kg, J = diag(0.02, 0.02, 0.04), tracking a reference that yaws at 1 rad/s at
/// the origin, with a world force of 0.5 N along x.
fn yawing(frame: Option<Frame>) -> f64 {
    let mut inertia = SMatrix::<f64, 6, 6>::identity();
    inertia
        .fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&Matrix3::from_diagonal(&Vector3::new(0.02, 0.02, 0.04)));
    let mut kd = SMatrix::<f64, 6, 6>::identity() * 2.0;
    kd.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(Matrix3::identity() * 0.28));
    let controller = Controller::<f64, Se3, 4, 6>::new(ControllerConfig {
        law: Law::Eqt,
        error_frame: eqtrack_controller::ErrorFrame::World,
        inertia,
        k: SMatrix::identity(),
        kd,
        torque_limit: None,
    })
    .unwrap();
    let v_d = SVector::<f64, 6>::from_row_slice(&[0.0, 0.0, 1.0, 0.0, 0.0, 0.0]);
    let reference = Reference::<f64, Se3, 4, 6>::new(
        SMatrix::identity(),
        v_d,
        inertia,
        Feedforward::zero(),
        H,
        1,
    )
    .unwrap();
    let plant = RigidBody::new(inertia, SMatrix::identity(), v_d).unwrap();
    let rejection = RejectionConfig {
        observer: frame.map(|f| ObserverConfig {
            gain: SVector::repeat(20.0),
            limit: None,
            frame: f,
        }),
        integral: None,
    };
    let force = SVector::<f64, 6>::from_row_slice(&[0.0, 0.0, 0.0, 0.5, 0.0, 0.0]);
    let mut sim = ClosedLoop::new(controller, reference, plant, 10)
        .unwrap()
        .with_world_disturbance(force)
        .unwrap()
        .with_rejection(rejection)
        .unwrap();
    let mut worst = 0.0f64;
    for k in 0..(20.0 / H) as usize {
        let s = sim.step().unwrap();
        if k as f64 * H >= 15.0 {
            let offset =
                eqtrack_controller::group::se3::translation(&(s.q * Se3::inverse(&s.desired.q)));
            worst = worst.max(offset.norm());
        }
    }
    worst
}

#[test]
fn t3_a_world_force_on_a_yawing_body_is_rejected_in_the_world_frame() {
    let pd = yawing(None);
    let body = yawing(Some(Frame::Body));
    let world = yawing(Some(Frame::World));
    println!(
        "T3 steady position offset under a 0.5 N world force, body yawing at 1 rad/s: \
         PD {pd:.4e} m, body-frame observer {body:.4e} m, world-frame observer {world:.4e} m"
    );
    assert!(pd > 0.05, "{pd}");
    assert!(body < pd, "{body} vs {pd}");
    assert!(world < 1e-3, "{world}");
    assert!(world < body, "{world} vs {body}");
}

#[test]
fn the_observer_error_decays_at_its_gain_whatever_the_law_does() {
    for law in [Law::Eqt, Law::Gt] {
        let gain = 20.0;
        let mut sim = common::seed_loop::<f64>(law, H, 10)
            .with_disturbance(d())
            .unwrap()
            .with_rejection(RejectionConfig {
                observer: observer(gain, Frame::Body),
                integral: None,
            })
            .unwrap();
        // least squares of ln|d̂ − d| against t over 0.3 s (the first tick only anchors)
        let (mut n, mut st, mut sy, mut stt, mut sty) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for _ in 0..(0.3 / H) as usize {
            let s = sim.step().unwrap();
            if s.t < H / 2.0 {
                assert_eq!(s.output.observer, Vector3::zeros());
                continue;
            }
            let y = (s.output.observer - d()).norm().ln();
            n += 1.0;
            st += s.t;
            sy += y;
            stt += s.t * s.t;
            sty += s.t * y;
        }
        let rate = -(n * sty - st * sy) / (n * stt - st * st);
        println!("observer error rate with {law:?}: {rate:.4} 1/s (gain {gain})");
        assert!((rate - gain).abs() < 0.01 * gain, "{rate}");
    }
}

proptest::proptest! {
    /// The closed forms of `ad_vᵀ μ` equal the matrix product (the observer's gyroscopic term).
    #[test]
    fn the_closed_forms_of_ad_transpose_equal_the_matrix_product(
        v in proptest::array::uniform6(-5.0f64..5.0),
        mu in proptest::array::uniform6(-5.0f64..5.0),
    ) {
        let (v6, mu6) = (SVector::<f64, 6>::from(v), SVector::<f64, 6>::from(mu));
        let d6 = Se3::ad_transpose_mul(&v6, &mu6) - Se3::ad(&v6).tr_mul(&mu6);
        proptest::prop_assert!(d6.amax() < 1e-12, "{}", d6);
        let (v3, mu3) = (v6.fixed_rows::<3>(0).into_owned(), mu6.fixed_rows::<3>(0).into_owned());
        let d3 = So3::ad_transpose_mul(&v3, &mu3) - So3::ad(&v3).tr_mul(&mu3);
        proptest::prop_assert!(d3.amax() < 1e-12, "{}", d3);
    }
}
