//! The instruction-count mode (feature `icount`): each measured call runs once between two
//! calls of [`icount_mark`], and `scripts/cortex-m.sh` counts the instructions QEMU executes
//! between them in its single-step execution log (`-singlestep -d exec,nochain`: one log
//! line per executed instruction, with its function's symbol). The calls (BENCHMARKS.md,
//! section 6):
//!
//! | marks | what |
//! |---|---|
//! | 0 → 1 | nothing: the cost of returning from one mark and calling the next (subtracted) |
//! | 2 → 3 | `Controller::compute`, SO(3) EqT, f32 |
//! | 4 → 5 | `Controller::compute`, SE(3) EqT (the generic law), f32 |
//! | 6 → 7 | one controller cycle: reference `desired()`, `compute`, reference `advance()` with 1 RKMK4 substep |
//! | 8 → 9 | the same with the seed's 10 substeps |
//! | 10 → 11 | one complementary-filter step (`estimator`), two directions, f32 |
//! | 12 → 13 | one pose-filter step (SE(3): one direction, the accelerometer, a position fix), f32 |
//! | 14 → 15 | one equivariant-filter step (`estimator`, attitude and gyro bias), two directions, f32 |
//! | 16 → 17 | `Controller::compute_rejecting`, SO(3) EqT with the momentum observer (body frame), f32 |
//! | 18 → 19 | the same with the geometric integral (anti-windup, clamp) instead |
//! | 20 → 21 | the same with both terms |
//! | 22 → 23 | the observer alone again, with its optional clamp |
//! | 24 → 25 | one allocation (`allocation`), the tilted hexarotor (6 rotors), a demand within reach, f32 |
//! | 26 → 27 | one allocation, the eight-thruster ROV, a demand within reach, f32 |
//! | 28 → 29 | one allocation, the hexarotor, a demand past its reach (saturated), f32 |

use controller::Trajectory;
use core::hint::black_box;
use cortex_m_semihosting::hprintln;
use firmware_cases::{se3_cases, se3_controller, seed_reference, so3_cases, so3_controller};

/// The marker the counting script looks for by name.
#[inline(never)]
fn icount_mark(id: u32) {
    black_box(id);
}

/// Runs the measured calls between marks; true when every result was finite.
pub fn run() -> bool {
    let (Ok(so3), Ok(se3), Ok(mut ref1), Ok(mut ref10)) =
        (so3_controller(), se3_controller(), seed_reference(1), seed_reference(10))
    else {
        hprintln!("ERR icount - construction failed");
        return false;
    };
    let c = so3_cases()[5];
    let d = se3_cases(&se3.config().inertia)[2];
    // one step in first, so no call is the very first (state as in a running loop)
    ref1.advance();
    ref10.advance();
    // Opaque from here on: the inputs are constants, and the compiler would otherwise
    // evaluate the calls at compile time or move them out from between the marks.
    let (so3, se3, c, d) = (black_box(so3), black_box(se3), black_box(c), black_box(d));
    let (mut ref1, mut ref10) = (black_box(ref1), black_box(ref10));
    let mut ok = true;
    let mut finite = |x: f32| ok &= x.is_finite();

    icount_mark(0);
    icount_mark(1);

    icount_mark(2);
    let r = black_box(so3.compute(black_box(&c.q), black_box(&c.v), black_box(&c.desired)));
    icount_mark(3);
    finite(r.map_or(f32::NAN, |o| o.torque.norm()));

    icount_mark(4);
    let r = black_box(se3.compute(black_box(&d.q), black_box(&d.v), black_box(&d.desired)));
    icount_mark(5);
    finite(r.map_or(f32::NAN, |o| o.torque.norm()));

    for (first, reference) in [(6, &mut ref1), (8, &mut ref10)] {
        icount_mark(first);
        let desired = reference.desired();
        let r = black_box(so3.compute(black_box(&c.q), black_box(&c.v), &desired));
        reference.advance();
        icount_mark(first + 1);
        finite(r.map_or(f32::NAN, |o| o.torque.norm()));
    }
    // the estimators, started and converged on a body at rest before the measured step
    let w = [
        nalgebra::Vector3::z(),
        nalgebra::Vector3::new(1.0f32, 0.0, 0.2),
    ];
    let r = c.q;
    let y = [r.tr_mul(&w[0]), r.tr_mul(&w[1].normalize())];
    let gyro = nalgebra::Vector3::new(0.02f32, -0.01, 0.03);
    let f_up = r.tr_mul(&nalgebra::Vector3::new(0.0, 0.0, 9.81f32));
    let x = nalgebra::Vector3::new(1.0f32, 2.0, 3.0);
    let (Ok(cc), Ok(pc)) = (
        estimator::ComplementaryConfig::new(2.0f32, 1.0, &w, &[1.0, 1.0]),
        estimator::PoseConfig::new(2.0f32, 1.0, &w[1..], &[1.0, 1.0], 0.05, 0.01),
    ) else {
        hprintln!("ERR icount - estimator construction failed");
        return false;
    };
    let Ok(ec) = estimator::EqfConfig::new(0.002f32, 1e-5, &w, &[0.01, 0.01]) else {
        hprintln!("ERR icount - EqF construction failed");
        return false;
    };
    let mut cf = estimator::ComplementaryFilter::new(cc);
    let mut pf = estimator::PoseFilter::new(pc);
    let mut eqf = estimator::EquivariantFilter::new(ec);
    for _ in 0..10 {
        cf.step(0.01, &gyro, &y);
        pf.step(0.01, &gyro, &y[1..], &f_up, Some(&x));
        eqf.step(0.01, &gyro, &y);
    }
    let (mut cf, mut pf, mut eqf, y) = (black_box(cf), black_box(pf), black_box(eqf), black_box(y));

    icount_mark(10);
    let e = black_box(cf.step(black_box(0.01), black_box(&gyro), black_box(&y)));
    icount_mark(11);
    finite(e.r.norm() + e.rate.norm());

    icount_mark(12);
    let e = black_box(pf.step(
        black_box(0.01),
        black_box(&gyro),
        black_box(&y[1..]),
        black_box(&f_up),
        black_box(Some(&x)),
    ));
    icount_mark(13);
    finite(e.r.norm() + e.x.norm());

    icount_mark(14);
    let e = black_box(eqf.step(black_box(0.01), black_box(&gyro), black_box(&y)));
    icount_mark(15);
    finite(e.r.norm() + e.rate.norm() + eqf.covariance().norm());

    // the disturbance-rejection terms: each run on two states first, so the measured call is
    // a running cycle's update
    let observer = controller::ObserverConfig {
        gain: nalgebra::Vector3::repeat(20.0f32),
        limit: None,
        frame: controller::Frame::Body,
    };
    let integral = controller::IntegralConfig {
        ki: nalgebra::Vector3::repeat(1.0f32),
        c: nalgebra::Vector3::repeat(5.0),
        limit: Some(nalgebra::Vector3::repeat(0.15)),
        anti_windup: true,
    };
    let variants = [
        (16, Some(observer), None),
        (18, None, Some(integral)),
        (20, Some(observer), Some(integral)),
        (
            22,
            Some(controller::ObserverConfig {
                limit: Some(nalgebra::Vector3::repeat(1.0)),
                ..observer
            }),
            None,
        ),
    ];
    let applied = nalgebra::Vector3::new(0.1f32, -0.2, 0.05);
    for (first, observer, integral) in variants {
        let config = controller::RejectionConfig { observer, integral };
        let Ok(mut terms) = controller::Rejection::new(config, None) else {
            hprintln!("ERR icount - rejection construction failed");
            return false;
        };
        // twice: the first call anchors, the second computes (and caches) the gain
        for _ in 0..2 {
            let _ = so3.compute_rejecting(&mut terms, &c.q, &c.v, &c.desired, &applied, 0.002, true);
        }
        let mut terms = black_box(terms);
        icount_mark(first);
        let r = black_box(so3.compute_rejecting(
            &mut terms,
            black_box(&c.q),
            black_box(&c.v),
            black_box(&c.desired),
            black_box(&applied),
            black_box(0.002),
            true,
        ));
        icount_mark(first + 1);
        finite(r.map_or(f32::NAN, |o| o.torque.norm()));
    }

    ok &= allocations();
    hprintln!("ICOUNT done {}", ok);
    ok
}

/// One allocation each (docs/maths.md, "Control allocation"): the two presets within reach,
/// and the hexarotor saturated; true when every answer was finite.
fn allocations() -> bool {
    use allocation::{Allocator, Geometry, Priority, presets};
    use nalgebra::SVector;
    let hexarotor = presets::hexarotor(0.25f32, 0.5, 0.016, 8.0);
    let rov = presets::rov_heavy(0.4f32, 0.3, 0.12, 0.22, 40.0);
    let (Ok(gh), Ok(gr)) = (Geometry::<f32, 6>::new(&hexarotor), Geometry::<f32, 6>::new(&rov)) else {
        hprintln!("ERR icount - geometry construction failed");
        return false;
    };
    let (Ok(ah), Ok(ar)) = (
        Allocator::new(gh, &[], &[], Priority::Torque),
        Allocator::new(gr, &[], &[], Priority::Torque),
    ) else {
        hprintln!("ERR icount - allocator construction failed");
        return false;
    };
    let cases = [
        (24, ah, SVector::<f32, 6>::from([0.1, -0.05, 0.02, 0.5, -0.3, 20.0])),
        (26, ar, SVector::<f32, 6>::from([1.0, -2.0, 3.0, 20.0, -10.0, 5.0])),
        (28, ah, SVector::<f32, 6>::from([0.5, -0.3, 1.2, 2.0, -1.0, 45.0])),
    ];
    let mut ok = true;
    for (first, alloc, demand) in cases {
        let (alloc, demand) = (black_box(alloc), black_box(demand));
        icount_mark(first);
        let a = black_box(alloc.allocate(black_box(&demand)));
        icount_mark(first + 1);
        ok &= a.u.iter().all(|x| x.is_finite());
    }
    ok
}
