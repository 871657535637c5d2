//! The instruction-count mode (feature `icount`): each measured call runs once between two
//! calls of [`icount_mark`], and `scripts/cortex-m.sh` counts the instructions QEMU executes
//! between them in its log (`-d in_asm,exec,nochain`: each translation block's instructions
//! when QEMU translates it, and a line, with its function's symbol, per execution of a
//! block). The calls (BENCHMARKS.md,
//! section 6):
//!
//! | marks | what |
//! |---|---|
//! | 0 → 1 | nothing: the cost of returning from one mark and calling the next (subtracted) |
//! | 2 → 3 | `Controller::compute`, SO(3) EqT, the papers' law (`error_frame` world), f32 |
//! | 4 → 5 | `Controller::compute`, SE(3) EqT (the generic law), `error_frame` world, f32 |
//! | 6 → 7 | one controller cycle: reference `desired()`, `compute`, reference `advance()` with 1 RKMK4 substep |
//! | 8 → 9 | the same with the seed's 10 substeps |
//! | 10 → 11 | one complementary-filter step (`eqtrack-estimator`), two directions, f32 |
//! | 12 → 13 | one pose-filter step (SE(3): one direction, the accelerometer, a position fix), f32 |
//! | 14 → 15 | one equivariant-filter step (`eqtrack-estimator`, attitude and gyro bias), two directions, f32 |
//! | 16 → 17 | `Controller::compute_rejecting`, SO(3) EqT with the momentum observer (body frame), f32 |
//! | 18 → 19 | the same with the geometric integral (anti-windup, clamp) instead |
//! | 20 → 21 | the same with both terms |
//! | 22 → 23 | the observer alone again, with its optional clamp |
//! | 24 → 25 | one allocation (`eqtrack-allocation`), the tilted hexarotor (6 rotors), a demand within reach, f32 |
//! | 26 → 27 | one allocation, the eight-thruster ROV, a demand within reach, f32 |
//! | 28 → 29 | one allocation, the hexarotor, a demand past its reach (saturated), f32 |
//! | 30 → 31 | PIL framing in: a `pil_hexarotor` state frame with its samples (109 bytes on the line) through the `Deframer` (COBS, CRC, postcard), a byte at a time |
//! | 32 → 33 | PIL: `Cycle::on_frame` on it: the EqF pose filter, the reference's step, the SE(3) law with the observer, the allocation to six rotors |
//! | 34 → 35 | PIL framing out: the command frame encoded (postcard, CRC, COBS) |
//! | 36 → 37 | its estimator alone: the pose filter with the EqF (two directions, accelerometer, fix) |
//! | 38 → 39 | its law alone: SE(3) EqT (the configuration's, at the reference) with the world-frame observer, `compute_rejecting` |
//! | 40 → 41 | its allocation alone: `VehicleControl::actuate` (weight compensated, six rotors) |
//! | 42 → 43 | `Controller::compute`, SO(3) EqT at the reference (`error_frame` reference, the default), the state of 2 → 3 |
//! | 44 → 45 | `Controller::compute`, SE(3) EqT at the reference, the state of 4 → 5 |
//!
//! The cycles (6 → 9) and the SO(3) rejection terms (16 → 23) fly the seed scenario's law, the
//! papers' (world); the PIL cycle (30 → 41) flies `pil_hexarotor`'s, at the reference.
//!
//! Then the worst cases (docs/vehicles.md, "Bounded time"), each call between a pair of marks
//! 46 → 47, in the order the `WORST`, `WARM`, `SATURATED`, `DETECTOR`, `DETECTOR_WEAK`, `WEAKEN`
//! and `WHEELS` lines name them:
//!
//! * every demand of `firmware_cases::demands`, solved cold with the default budget: the
//!   hexarotor, the ROV, the spacecraft (`WORST <vehicle> <demands> <stopped> <most iterations>`);
//! * each vehicle's saturating trajectory, warm-started (`WARM <vehicle> <ticks> <iterations>`);
//! * `pil_hexarotor`'s whole cycle (`Cycle::on_frame`) on frames that saturate its rotors
//!   (`SATURATED <cycles> <saturated allocations>`);
//! * the failure detector's cycle on `pil_rov_detect`'s ROV, with its settings, over a
//!   synthetic flight through the warm-up, the calibration, the tests, a thruster that dies
//!   and its finding (`DETECTOR rov <cycles> <cycle found> <actuator> <kind code> <value>
//!   <first cycle that tested>`); then over a flight in which that thruster loses half its
//!   thrust and is named weak and refined, each told over the cycles after its finding
//!   (`DETECTOR_WEAK rov <cycles> <cycle of the first report> <actuator> <kind code> <value>
//!   <cycle of the last report> <actuator> <kind code> <value>`);
//! * the tell of a weak thruster at once on that ROV's healthy allocator (`Kind::tell` of a
//!   factor of one half, which reweights the allocator, the thruster's thrust its variable),
//!   as an announced failure or replay's record tells it; then its refinement, and another
//!   thruster told weak while it is (`WEAKEN rov 3`, the worst of the three counted);
//! * `wheels_slew`'s whole cycle on four reaction wheels, on the frames of a slew whose
//!   wheels sweep up to their top speed (`WHEELS <cycles> <saturated allocations> <frames with
//!   a closed bound>`).

use eqtrack_controller::{ErrorFrame, Trajectory as _};
use core::hint::black_box;
use cortex_m_semihosting::hprintln;
use firmware_cases::{
    se3_cases, se3_controller, se3_controller_in, seed_reference, so3_cases, so3_controller,
    so3_controller_in,
};

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
    // the result stays where the call wrote it (black_box of a reference: no copy of the
    // 200-byte output is counted)
    let r = se3.compute(black_box(&d.q), black_box(&d.v), black_box(&d.desired));
    black_box(&r);
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
        eqtrack_estimator::ComplementaryConfig::new(2.0f32, 1.0, &w, &[1.0, 1.0]),
        eqtrack_estimator::PoseConfig::new(2.0f32, 1.0, &w[1..], &[1.0, 1.0], 0.05, 0.01),
    ) else {
        hprintln!("ERR icount - estimator construction failed");
        return false;
    };
    let Ok(ec) = eqtrack_estimator::EqfConfig::new(0.002f32, 1e-5, &w, &[0.01, 0.01]) else {
        hprintln!("ERR icount - EqF construction failed");
        return false;
    };
    let mut cf = eqtrack_estimator::ComplementaryFilter::new(cc);
    let mut pf = eqtrack_estimator::PoseFilter::new(pc);
    let mut eqf = eqtrack_estimator::EquivariantFilter::new(ec);
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
    let observer = eqtrack_controller::ObserverConfig {
        gain: nalgebra::Vector3::repeat(20.0f32),
        limit: None,
        frame: eqtrack_controller::Frame::Body,
    };
    let integral = eqtrack_controller::IntegralConfig {
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
            Some(eqtrack_controller::ObserverConfig {
                limit: Some(nalgebra::Vector3::repeat(1.0)),
                ..observer
            }),
            None,
        ),
    ];
    let applied = nalgebra::Vector3::new(0.1f32, -0.2, 0.05);
    for (first, observer, integral) in variants {
        let config = eqtrack_controller::RejectionConfig { observer, integral };
        let Ok(mut terms) = eqtrack_controller::Rejection::new(config, None) else {
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
    ok &= pil_cycle();
    ok &= at_the_reference();
    #[cfg(feature = "worst-cases")]
    {
        ok &= worst_cases();
        ok &= saturated_cycles();
        ok &= detector_cycles();
        ok &= wheel_cycles();
    }
    hprintln!("ICOUNT done {}", ok);
    ok
}

/// The law at the reference (`error_frame` reference, what every shipped scenario but the
/// seed's flies; marks 42 to 45): the same controllers and states as marks 2 to 5; true when
/// every torque was finite.
fn at_the_reference() -> bool {
    let (Ok(so3), Ok(se3)) = (
        so3_controller_in(ErrorFrame::Reference),
        se3_controller_in(ErrorFrame::Reference),
    ) else {
        hprintln!("ERR icount - construction at the reference failed");
        return false;
    };
    let c = so3_cases()[5];
    let d = se3_cases(&se3.config().inertia)[2];
    let (so3, se3, c, d) = (black_box(so3), black_box(se3), black_box(c), black_box(d));
    let mut ok = true;

    icount_mark(42);
    let r = black_box(so3.compute(black_box(&c.q), black_box(&c.v), black_box(&c.desired)));
    icount_mark(43);
    ok &= r.is_ok_and(|o| o.torque.norm().is_finite());

    icount_mark(44);
    let r = se3.compute(black_box(&d.q), black_box(&d.v), black_box(&d.desired));
    black_box(&r);
    icount_mark(45);
    ok &= r.is_ok_and(|o| o.torque.norm().is_finite());
    ok
}

/// One allocation each (docs/maths.md, "Control allocation"): the two presets within reach,
/// and the hexarotor saturated; true when every answer was finite.
fn allocations() -> bool {
    use eqtrack_allocation::{Allocator, Geometry, Priority, presets};
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

/// `pil_hexarotor`'s firmware configuration (`plant_sim pil-config`; a workspace test keeps
/// it equal to the scenario's).
static PIL_CONFIG: &[u8] = include_bytes!("../pil_hexarotor.config");

/// A hovering hexarotor's samples at tick k: level, at rest, the gyro's bias, the two
/// directions and gravity's specific force, a position fix every tenth tick.
fn hover(k: u64) -> eqtrack_serial_wire::StateFrame {
    let mut directions = heapless::Vec::new();
    let _ = directions.push([1.0f32, 0.0, 0.0]);
    let _ = directions.push([0.0f32, 0.6, 0.8]);
    eqtrack_serial_wire::StateFrame {
        seq: k,
        t: k as f64 * 0.002,
        q: heapless::Vec::new(),
        v: heapless::Vec::new(),
        applied: heapless::Vec::from_slice(&[0.0, 0.0, 0.0, 0.1, 0.0, 14.7]).unwrap_or_default(),
        samples: Some(eqtrack_serial_wire::Samples {
            gyro: [0.01, -0.02, 0.015],
            directions,
            accel: Some([0.0, 0.0, 9.81]),
            position: (k % 10 == 0).then_some([0.0, 0.0, 0.0]),
        }),
        wheel_speeds: Default::default(),
    }
}

/// `pil_hexarotor`'s cycle, running: greeted, then 20 hovering frames, so that the estimator
/// has started and the observer is anchored (`None`: the configuration does not build).
fn running_cycle() -> Option<firmware_cycle::Cycle> {
    let mut cycle = firmware_cycle::Cycle::from_bytes(PIL_CONFIG).ok()?;
    let hello = cycle.hello();
    cycle.on_frame(&hello);
    for k in 0..20 {
        cycle.on_frame(&eqtrack_serial_wire::Frame::State(hover(k)));
    }
    Some(cycle)
}

/// One processor-in-the-loop cycle of `pil_hexarotor` and its parts (marks 30 to 41); true
/// when every answer was finite.
fn pil_cycle() -> bool {
    use firmware_cycle::Config;
    use eqtrack_serial_wire::{Deframer, Frame, MAX_ENCODED, encode};
    let (Ok(config), Some(cycle)) = (Config::from_bytes(PIL_CONFIG), running_cycle()) else {
        hprintln!("ERR icount - the PIL configuration does not build");
        return false;
    };
    let mut bytes = [0u8; MAX_ENCODED];
    let Ok(n) = encode(&Frame::State(hover(20)), &mut bytes) else {
        hprintln!("ERR icount - the state frame does not encode");
        return false;
    };
    let (mut cycle, bytes) = (black_box(cycle), black_box(bytes));
    // held through a reference, as the PIL firmware holds its deframer (an RTIC resource): not
    // at an offset of this function's large frame, recomputed for every byte
    let mut deframer = Deframer::new();
    let deframer = black_box(&mut deframer);
    let mut ok = true;

    icount_mark(30);
    let mut frame = None;
    for b in &bytes[..n] {
        if let Some(f) = deframer.push(*b) {
            frame = Some(f);
        }
    }
    icount_mark(31);
    let Some(Ok(frame)) = black_box(frame) else {
        hprintln!("ERR icount - the state frame does not decode");
        return false;
    };

    icount_mark(32);
    let answer = black_box(cycle.on_frame(black_box(&frame)));
    icount_mark(33);
    let Some(answer) = answer else {
        hprintln!("ERR icount - no command");
        return false;
    };
    // the law's wrench of this cycle: the allocation alone is measured on it
    let mut wrench = nalgebra::SVector::<f32, 6>::repeat(f32::NAN);
    if let Frame::Command(c) = &answer {
        ok &= c.tau.iter().all(|x| x.is_finite());
        ok &= c.allocation.as_ref().is_some_and(|a| a.u_cmd.iter().all(|x| x.is_finite()));
        if c.tau.len() == 6 {
            wrench = nalgebra::SVector::from_row_slice(&c.tau);
        }
    } else {
        hprintln!("ERR icount - the PIL cycle did not answer with a command");
        return false;
    }

    let mut out = black_box([0u8; MAX_ENCODED]);
    icount_mark(34);
    let encoded = black_box(encode(black_box(&answer), &mut out));
    icount_mark(35);
    ok &= encoded.is_ok();

    // the parts alone, from the same configuration
    let (Some(e), Ok(se3), Ok(terms), Some(v)) = (
        config.estimator.as_ref(),
        config.controller::<eqtrack_controller::group::Se3, 4, 6>(),
        config.rejection::<6>(),
        config.vehicle.as_ref(),
    ) else {
        hprintln!("ERR icount - the PIL parts do not build");
        return false;
    };
    let (Ok(mut filter), Ok(Some(mut rejection)), Ok(mut control)) = (
        e.settings().build(true),
        eqtrack_controller::Rejection::of(terms, se3.config().torque_limit.as_ref()),
        v.control::<6>(0.002),
    ) else {
        hprintln!("ERR icount - the PIL parts do not build");
        return false;
    };
    let samples = hover(20).samples.unwrap_or_else(|| unreachable!());
    let dirs = [nalgebra::Vector3::new(1.0f32, 0.0, 0.0), nalgebra::Vector3::new(0.0, 0.6, 0.8)];
    let (gyro, accel) = (nalgebra::Vector3::from(samples.gyro), nalgebra::Vector3::new(0.0f32, 0.0, 9.81));
    for _ in 0..20 {
        filter.step::<4, 6>(0.002, &gyro, &dirs, &accel, None);
    }
    let d = se3_cases(&se3.config().inertia)[2];
    let applied = nalgebra::SVector::<f32, 6>::from([0.0, 0.0, 0.0, 0.1, 0.0, 14.7]);
    for _ in 0..2 {
        let _ = se3.compute_rejecting(&mut rejection, &d.q, &d.v, &d.desired, &applied, 0.002, true);
    }
    let (mut filter, mut rejection) = (black_box(filter), black_box(rejection));

    icount_mark(36);
    let fix = nalgebra::Vector3::<f32>::zeros();
    let est = black_box(filter.step::<4, 6>(
        black_box(0.002),
        black_box(&gyro),
        black_box(&dirs),
        black_box(&accel),
        Some(black_box(&fix)),
    ));
    icount_mark(37);
    ok &= est.q.iter().all(|x| x.is_finite());

    icount_mark(38);
    let r = black_box(se3.compute_rejecting(
        &mut rejection,
        black_box(&d.q),
        black_box(&d.v),
        black_box(&d.desired),
        black_box(&applied),
        black_box(0.002),
        true,
    ));
    icount_mark(39);
    ok &= r.is_ok_and(|o| o.torque.iter().all(|x| x.is_finite()));

    let r_hat = black_box(est.q.fixed_view::<3, 3>(0, 0).into_owned());
    icount_mark(40);
    let a = black_box(control.actuate(black_box(&wrench), &r_hat));
    icount_mark(41);
    ok &= a.allocation.u.iter().all(|x| x.is_finite());
    ok
}

/// Every seeded demand of each vehicle, cold, then its saturating trajectory, warm (marks
/// 46 → 47 around each allocation); true when every answer was finite.
#[cfg(feature = "worst-cases")]
fn worst_cases() -> bool {
    use firmware_cases::demands;
    let (Some(hex), Some(rov), Some(sc)) = (demands::hexarotor(), demands::rov(), demands::spacecraft()) else {
        hprintln!("ERR icount - the demand sets' allocators do not build");
        return false;
    };
    vehicle("hexarotor", &hex) & vehicle("rov", &rov) & vehicle("spacecraft", &sc)
}

#[cfg(feature = "worst-cases")]
fn vehicle<const K: usize>(name: &str, alloc: &eqtrack_allocation::Allocator<f32, K>) -> bool {
    use eqtrack_allocation::Status;
    use firmware_cases::demands::{self, PER_KIND, Seeded, TRAJECTORY};
    let mut rng = Seeded::new(demands::seed(name));
    let (mut ok, mut stopped, mut most) = (true, 0, 0);
    let n = demands::KINDS.len() * PER_KIND;
    for i in 0..n {
        let (d, bounds) = demands::demand(alloc, i, &mut rng);
        let (a, d, bounds) = (black_box(alloc), black_box(d), black_box(bounds));
        icount_mark(46);
        let r = black_box(a.allocate_within(&d, &bounds));
        icount_mark(47);
        ok &= r.u.iter().all(|x| x.is_finite());
        stopped += usize::from(r.status == Status::Stopped);
        most = most.max(r.iterations);
    }
    hprintln!("WORST {} {} {} {}", name, n, stopped, most);
    let bounds = alloc.bounds();
    let (mut previous, mut iterations) = (None, 0);
    for k in 0..TRAJECTORY {
        let d = black_box(demands::trajectory(alloc, k));
        let a = black_box(alloc);
        icount_mark(46);
        let r = black_box(a.allocate_from(&d, &bounds, previous.as_ref()));
        icount_mark(47);
        ok &= r.u.iter().all(|x| x.is_finite());
        iterations += r.iterations;
        previous = Some(r.u);
    }
    hprintln!("WARM {} {} {}", name, TRAJECTORY, iterations);
    ok
}

/// `pil_hexarotor`'s whole cycle on frames that saturate its rotors: after a hover, the body
/// is told it spins (the gyro) far from its position fix, so the law asks for more than the
/// rotors give (marks 46 → 47 around each `Cycle::on_frame`); true when every command was
/// finite and the allocations saturated.
#[cfg(feature = "worst-cases")]
fn saturated_cycles() -> bool {
    use eqtrack_serial_wire::Frame;
    const CYCLES: usize = 40;
    let Some(mut cycle) = running_cycle() else {
        hprintln!("ERR icount - the PIL configuration does not build");
        return false;
    };
    let (mut ok, mut saturated) = (true, 0);
    for k in 20..20 + CYCLES as u64 {
        let mut f = hover(k);
        if let Some(s) = f.samples.as_mut() {
            s.gyro = [3.0, -2.0, 4.0];
            s.position = Some([4.0, -3.0, 2.0]);
        }
        let frame = black_box(Frame::State(f));
        icount_mark(46);
        let answer = black_box(cycle.on_frame(black_box(&frame)));
        icount_mark(47);
        match answer {
            Some(Frame::Command(cmd)) => {
                ok &= cmd.tau.iter().all(|x| x.is_finite());
                let status = cmd.allocation.as_ref().map_or(0, |a| a.status);
                saturated += usize::from(status == 1 || status == 2);
                ok &= status != 3;
            }
            _ => ok = false,
        }
    }
    hprintln!("SATURATED {} {}", CYCLES, saturated);
    ok
}

/// `pil_rov_detect`'s configuration (`plant_sim pil-config --scenario
/// scenarios/pil_rov_detect.toml`): the ROV and its failure detector's settings.
#[cfg(feature = "worst-cases")]
static ROV_CONFIG: &[u8] = include_bytes!("../pil_rov_detect.config");

/// The cycles of each of the detector's flights.
#[cfg(feature = "worst-cases")]
const ROV_CYCLES: usize = 200;

/// What a flight of [`rov_flight`] found: its first and last reports (cycle, actuator, kind
/// code, value), and the first cycle that tested.
#[cfg(feature = "worst-cases")]
struct Flight {
    first: Option<(usize, usize, u32, f32)>,
    last: Option<(usize, usize, u32, f32)>,
    testing: Option<usize>,
}

/// `pil_rov_detect`'s vehicle and control period (`None`: it does not decode, printed).
#[cfg(feature = "worst-cases")]
fn rov_vehicle() -> Option<(firmware_cycle::Vehicle, f32)> {
    let Ok(config) = firmware_cycle::Config::from_bytes(ROV_CONFIG) else {
        hprintln!("ERR icount - the ROV's configuration does not decode");
        return None;
    };
    let h = config.identity.period as f32;
    config.vehicle.map(|v| (v, h))
}

/// One synthetic flight of `pil_rov_detect`'s ROV and its detector ([`detector_cycles`]):
/// thruster 1 gives `factor` of its thrust from cycle 140 (0: dead), the wrench asked swaying
/// `sway` times the first flight's. `None`: the configuration does not build, or the flight
/// diverged (printed).
#[cfg(feature = "worst-cases")]
fn rov_flight(factor: f32, sway: f32) -> Option<Flight> {
    use eqtrack_controller::group::{MatrixLieGroup, Se3};
    use firmware_cases::demands::Seeded;
    use nalgebra::{Matrix3, SMatrix, SVector};
    const FAILS: usize = 140;
    let Ok(config) = firmware_cycle::Config::from_bytes(ROV_CONFIG) else {
        hprintln!("ERR icount - the ROV's configuration does not decode");
        return None;
    };
    let h = config.identity.period as f32;
    let inertia = SMatrix::<f32, 6, 6>::from_row_slice(&config.inertia);
    let (Some(vehicle), Some(settings), Some(inverse)) =
        (config.vehicle.as_ref(), config.detector.as_ref(), inertia.try_inverse())
    else {
        hprintln!("ERR icount - the ROV's configuration has no vehicle or detector");
        return None;
    };
    let (Ok(mut control), Ok(d)) = (vehicle.control::<6>(h), settings.config::<6>(inertia, h)) else {
        hprintln!("ERR icount - the ROV's vehicle or detector does not build");
        return None;
    };
    let Ok(mut detector) = detection::Detector::new(d) else {
        hprintln!("ERR icount - the ROV's detector refuses its settings");
        return None;
    };
    let b = *control.allocator().geometry().effectiveness();
    let decay = libm::expf(-h / d.time_constant);
    let mean = d.time_constant / h * (1.0 - decay);
    let current = SVector::<f32, 6>::from_column_slice(&[0.0, 0.0, 0.0, 6.0, -4.0, 3.0]);
    let r = Matrix3::<f32>::identity();
    let mut rng = Seeded::new(0x0de7_ec70);
    let (mut v, mut output, mut command) = (SVector::<f32, 6>::zeros(), None, None);
    let mut flight = Flight {
        first: None,
        last: None,
        testing: None,
    };
    for k in 0..ROV_CYCLES {
        let (dd, rr, vv) = (black_box(&mut detector), black_box(&r), black_box(&v));
        icount_mark(46);
        if let Some(u) = &command {
            dd.commanded(u);
        }
        let finding = dd.observe::<Se3, 4>(vv, rr, &mut control);
        icount_mark(47);
        if let Some(f) = black_box(finding) {
            let seen = Some((k, f.actuator, f.kind.code(), f.kind.value()));
            flight.first = flight.first.or(seen);
            flight.last = seen;
        }
        if flight.testing.is_none() && detector.statistic().testing {
            flight.testing = Some(k);
        }
        // the wrench asked for: a swaying, yawing flight held near rest against the current
        let t = k as f32 * h;
        let ff = SVector::<f32, 6>::from_column_slice(&[
            0.0,
            0.0,
            0.3 * libm::cosf(2.0 * t),
            8.0 * sway * libm::cosf(3.0 * t),
            6.0 * sway * libm::cosf(2.5 * t + 1.0),
            0.0,
        ]);
        let u = control.actuate(&(ff - v * 20.0 - current), &r).allocation.u;
        // the plant over the period: the lagged thrust (the first command at once), thruster
        // 1 giving `factor` of its thrust from cycle FAILS, Euler on the momentum
        let start = output.unwrap_or(u);
        let mut thrust = u + (start - u) * mean;
        output = Some(u + (start - u) * decay);
        if k >= FAILS {
            thrust[1] *= factor;
        }
        let mu = inertia * v;
        let drag = -(d.damping_linear.component_mul(&v)
            + d.damping_quadratic.component_mul(&v.abs().component_mul(&v)));
        let noise = SVector::<f32, 6>::from_fn(|i, _| (rng.unit() - 0.5) * if i < 3 { 0.02 } else { 0.4 });
        let wrench = Se3::ad_transpose_mul(&v, &mu) + b * thrust + control.restoring(&r) + drag + current + noise;
        v = inverse * (mu + wrench * h);
        command = Some(u);
    }
    if !v.iter().all(|x| x.is_finite()) {
        hprintln!("ERR icount - the ROV's synthetic flight diverged");
        return None;
    }
    Some(flight)
}

/// The failure detector's cycle on `pil_rov_detect`'s ROV (marks 46 → 47 around each: the
/// command of the cycle before taken, `Detector::commanded`, and the period that ended
/// observed, `Detector::observe`, which tests and on a finding tells the allocator), over two
/// synthetic flights ([`rov_flight`]). In the first thruster 1 dies at cycle 140
/// (`DETECTOR rov …`); in the second, which sways three times as hard, it gives half its thrust
/// from cycle 140, is named weak and then refined, each told over the cycles after
/// (`DETECTOR_WEAK rov …`). True when the first finds thruster 1 (of its kind, the synthetic
/// flight's cruder model leaves the detector a bias: it is printed, not judged) and the
/// second reports thruster 1 weak, named and refined.
#[cfg(feature = "worst-cases")]
fn detector_cycles() -> bool {
    let Some(dead) = rov_flight(0.0, 1.0) else {
        return false;
    };
    let (k, actuator, kind, value) = dead.first.unwrap_or((0, usize::MAX, 0, 0.0));
    hprintln!(
        "DETECTOR rov {} {} {} {} {} {}",
        ROV_CYCLES,
        k,
        actuator,
        kind,
        value,
        dead.testing.unwrap_or(ROV_CYCLES)
    );
    let Some(weak) = rov_flight(0.5, 3.0) else {
        return false;
    };
    let (k, wa, wk, wv) = weak.first.unwrap_or((0, usize::MAX, 0, 0.0));
    let (r, ra, rk, rv) = weak.last.unwrap_or((0, usize::MAX, 0, 0.0));
    hprintln!(
        "DETECTOR_WEAK rov {} {} {} {} {} {} {} {} {}",
        ROV_CYCLES,
        k,
        wa,
        wk,
        wv,
        r,
        ra,
        rk,
        rv
    );
    let Some((vehicle, h)) = rov_vehicle() else {
        return false;
    };
    // a weak thruster told at once on a healthy allocator, as an announced failure, or replay
    // following a record, tells it: the allocator reweighted, the thruster's thrust its
    // variable (the detector tells it over the cycles after its finding, counted above)
    let Ok(mut healthy) = vehicle.control::<6>(h) else {
        return false;
    };
    // told from healthy; refined; and another told while that one is weak
    for (j, k) in [(3, 0.5f32), (3, 0.45), (5, 0.7)] {
        let cc = black_box(&mut healthy);
        icount_mark(46);
        detection::Kind::Weak(black_box(k)).tell(j, cc);
        icount_mark(47);
    }
    hprintln!("WEAKEN rov 3");
    let f = healthy.factors();
    actuator == 1 && (wa, wk, ra, rk) == (1, 3, 1, 3) && r > k && f[3] == 0.45 && f[5] == 0.7
}

/// `wheels_slew`'s configuration (`plant_sim pil-config --scenario scenarios/wheels_slew.toml`):
/// four reaction wheels in a pyramid, no thrusters.
#[cfg(feature = "worst-cases")]
static WHEELS_CONFIG: &[u8] = include_bytes!("../wheels_slew.config");

/// `wheels_slew`'s whole cycle (`Cycle::on_frame`: the SO(3) law, the wheels' gyroscopic
/// torque, their bounds narrowed near the top speed, the allocation to four wheel motors;
/// marks 46 → 47 around each) on the frames of a slew: the body 2 rad from the target and
/// turning, so that the law asks for more torque than the motors give, and wheels 0 and 3
/// sweeping up to their top speed by frame 30 and held there, so that from then on the bound
/// that would speed wheel 0 further is closed (`WHEELS <cycles> <saturated allocations>
/// <frames at the top speed whose wheel-0 command does not speed it up>`). True when every
/// command was finite, the allocations saturated and the bound closed.
#[cfg(feature = "worst-cases")]
fn wheel_cycles() -> bool {
    use eqtrack_controller::group::{MatrixLieGroup, So3};
    use eqtrack_serial_wire::{Frame, StateFrame};
    const CYCLES: usize = 40;
    let Ok(mut cycle) = firmware_cycle::Cycle::from_bytes(WHEELS_CONFIG) else {
        hprintln!("ERR icount - the wheels' configuration does not build");
        return false;
    };
    let hello = cycle.hello();
    cycle.on_frame(&hello);
    let (mut ok, mut saturated, mut closed) = (true, 0, 0);
    for k in 0..CYCLES as u64 {
        let s = k as f32 / CYCLES as f32;
        let reach = (k as f32 / 30.0).min(1.0);
        let r = So3::exp(&(nalgebra::Vector3::new(1.2f32, -1.0, 1.2) * (1.0 - 0.3 * s)));
        let frame = black_box(Frame::State(StateFrame {
            seq: k,
            t: k as f64 * 0.01,
            q: (0..9).map(|i| r[(i / 3, i % 3)]).collect(),
            v: heapless::Vec::from_slice(&[0.05 * s, -0.04 * s, 0.05 * s]).unwrap_or_default(),
            applied: heapless::Vec::from_slice(&[0.0; 3]).unwrap_or_default(),
            samples: None,
            wheel_speeds: heapless::Vec::from_slice(&[600.0 * reach, -300.0 * s, 100.0, -600.0 * reach])
                .unwrap_or_default(),
        }));
        icount_mark(46);
        let answer = black_box(cycle.on_frame(black_box(&frame)));
        icount_mark(47);
        match answer {
            Some(Frame::Command(cmd)) => {
                ok &= cmd.tau.iter().all(|x| x.is_finite());
                let a = cmd.allocation.as_ref();
                ok &= a.is_some_and(|a| a.u_cmd.len() == 4 && a.u_cmd.iter().all(|x| x.is_finite()));
                let status = a.map_or(0, |a| a.status);
                saturated += usize::from(status == 1 || status == 2);
                ok &= status != 3;
                closed += usize::from(reach == 1.0 && a.is_some_and(|a| a.u_cmd.first().is_some_and(|u| *u <= 0.0)));
            }
            _ => ok = false,
        }
    }
    hprintln!("WHEELS {} {} {}", CYCLES, saturated, closed);
    ok && saturated > 0 && closed > 0
}
