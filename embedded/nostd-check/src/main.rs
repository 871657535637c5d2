//! Calls the controller for SO(3) and SE(3) in f32 and f64, runs short closed loops (one with
//! the disturbance-rejection terms), builds a through-waypoint path, steps the estimators
//! (`eqtrack-estimator`), allocates a wrench to a hexarotor's rotors (`eqtrack-allocation`) and uses the
//! `ipc_types` wire contract, the serial link's frames (`eqtrack-serial-wire`) and the firmware's
//! cycle (`firmware_cycle`), in a binary with no std, no alloc and no global allocator.
//! Exits 0 when every check holds.
#![no_std]
#![no_main]

mod rt;

use eqtrack_controller::closed_loop::ClosedLoop;
use eqtrack_controller::group::{MatrixLieGroup, Se3, So3};
use eqtrack_controller::integrator::RigidBody;
use eqtrack_controller::law::Desired;
use eqtrack_controller::{Controller, ControllerConfig, Law, Real, Reference, real, so3_seed_feedforward};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

fn so3_check<T: Real>(law: Law) -> bool {
    let inertia = Matrix3::new(0.824, 0.0, 0.12, 0.0, 1.135, 0.0, 0.12, 0.0, 1.759).map(real::<T>);
    let c = match Controller::<T, So3, 3, 3>::new(ControllerConfig {
        law,
        error_frame: eqtrack_controller::ErrorFrame::World,
        inertia,
        k: Matrix3::identity(),
        kd: Matrix3::identity() * real::<T>(0.5),
        torque_limit: Some(Vector3::repeat(real(5.0))),
    }) {
        Ok(c) => c,
        Err(_) => return false,
    };
    let d = Desired {
        q: Matrix3::identity(),
        p: Vector3::zeros(),
        v: Vector3::zeros(),
        tau: Vector3::zeros(),
    };
    // at the goal with zero velocity the torque is zero; away from it, finite and non-zero
    let at_goal = match c.compute(&Matrix3::identity(), &Vector3::zeros(), &d) {
        Ok(o) => o.torque.norm() == T::zero(),
        Err(_) => false,
    };
    let r = So3::exp(&Vector3::new(real(0.3), real(-0.2), real(1.0)));
    let away = match c.compute(&r, &Vector3::new(real(1.0), real(0.0), real(0.5)), &d) {
        Ok(o) => o.torque.iter().all(|t| t.is_finite()) && o.torque.norm() > T::zero(),
        Err(_) => false,
    };
    at_goal && away
}

fn se3_check<T: Real>() -> bool {
    let c = match Controller::<T, Se3, 4, 6>::new(ControllerConfig {
        law: Law::Eqt,
        error_frame: eqtrack_controller::ErrorFrame::World,
        inertia: SMatrix::<T, 6, 6>::identity(),
        k: SMatrix::<T, 4, 4>::identity(),
        kd: SMatrix::<T, 6, 6>::identity(),
        torque_limit: None,
    }) {
        Ok(c) => c,
        Err(_) => return false,
    };
    let d = Desired {
        q: SMatrix::identity(),
        p: SVector::zeros(),
        v: SVector::zeros(),
        tau: SVector::zeros(),
    };
    let q = Se3::exp(&SVector::<T, 6>::from_fn(|i, _| {
        real(0.1 * (i as f64 + 1.0))
    }));
    match c.compute(&q, &SVector::zeros(), &d) {
        Ok(o) => o.torque.iter().all(|t| t.is_finite()) && o.torque.norm() > T::zero(),
        Err(_) => false,
    }
}

fn closed_loop_check<T: Real>() -> bool {
    let inertia = Matrix3::new(0.824, 0.0, 0.12, 0.0, 1.135, 0.0, 0.12, 0.0, 1.759).map(real::<T>);
    let build = || -> Result<ClosedLoop<T, So3, 3, 3>, eqtrack_controller::Error> {
        let c = Controller::new(ControllerConfig {
            law: Law::Eqt,
            error_frame: eqtrack_controller::ErrorFrame::World,
            inertia,
            k: Matrix3::identity() * real::<T>(0.5),
            kd: Matrix3::identity() * real::<T>(0.5),
            torque_limit: None,
        })?;
        let r = Reference::new(
            Matrix3::identity(),
            Vector3::zeros(),
            inertia,
            so3_seed_feedforward(),
            real(0.01),
            10,
        )?;
        let axis = Vector3::new(0.8, 0.6, 0.0) * (core::f64::consts::PI - 0.1);
        let p = RigidBody::new(
            inertia,
            So3::exp(&axis.map(real::<T>)),
            Vector3::new(real(4.0), real(-3.0), real(2.0)),
        )?;
        ClosedLoop::new(c, r, p, 10)
    };
    let Ok(mut sim) = build() else { return false };
    let Ok(first) = sim.step() else { return false };
    let mut last = first;
    for _ in 0..500 {
        match sim.step() {
            Ok(s) => last = s,
            Err(_) => return false,
        }
    }
    last.output.lyapunov.total < first.output.lyapunov.total
}

/// The wire contract without std: build, validate and reject messages.
fn ipc_check() -> bool {
    use ipc_types::WireGroup::{Se3, So3};
    use ipc_types::{CommandMsg, Invalid, StateMsg, check_command, check_state, service_names};
    let mut s = StateMsg::new(So3);
    s.seq = 3;
    s.control_period = 0.001;
    let ok = check_state(&s, So3, Some(2), None) == Ok(());
    s.v[1] = f64::NAN;
    let nan = check_state(&s, So3, Some(2), None) == Err(Invalid::NonFinite);
    let mut c = CommandMsg::new(Se3);
    c.seq = 3;
    let cmd = check_command(&c, Se3, 3, 0) == Ok(())
        && check_command(&c, So3, 3, 0) == Err(Invalid::Group)
        && check_command(&c, Se3, 3, 8) == Err(Invalid::Actuators);
    let round_trip = StateMsg::from_bytes(&s.to_bytes()).is_ok_and(|d| d.seq == 3);
    let names = service_names("board1").is_some_and(|n| n.state.as_str() == "eqtrack/board1/state");
    ok && nan && cmd && names && round_trip
}

/// The estimators without std: the complementary filter and the pose filter converge on
/// exact samples of a body at rest from a TRIAD start, and skip a NaN sample.
fn estimator_check<T: Real>() -> bool {
    use eqtrack_estimator::{ComplementaryConfig, ComplementaryFilter, PoseConfig, PoseFilter};
    let w = [Vector3::z(), Vector3::new(real(1.0), real(0.0), real(0.2))];
    let r = So3::exp(&Vector3::new(real::<T>(0.3), real(-0.4), real(0.2)));
    let y = [r.tr_mul(&w[0]), r.tr_mul(&w[1].normalize())];
    let b = Vector3::new(real::<T>(0.02), real(-0.01), real(0.03));
    let Ok(cfg) = ComplementaryConfig::new(real(2.0), real(1.0), &w, &[T::one(), T::one()]) else {
        return false;
    };
    let mut f = ComplementaryFilter::new(cfg);
    let mut e = f.step(real(0.01), &b, &y);
    for _ in 0..3000 {
        e = f.step(real(0.01), &b, &y);
    }
    let nan = Vector3::new(real::<T>(f64::NAN), T::zero(), T::zero());
    let held = f.step(real(0.01), &nan, &y) == e && f.faults().gyro == 1;
    let attitude = (e.r - r).norm() < real(1e-3) && (e.bias - b).norm() < real(1e-3);
    let Ok(pc) = PoseConfig::new(
        real(2.0),
        real(1.0),
        &w[1..],
        &[T::one(), T::one()],
        real(0.05),
        real(0.01),
    ) else {
        return false;
    };
    let mut p = PoseFilter::new(pc);
    let f_up = r.tr_mul(&Vector3::new(T::zero(), T::zero(), real(9.81)));
    let x = Vector3::new(real::<T>(1.0), real(2.0), real(3.0));
    let mut pe = p.step(real(0.01), &b, &y[1..], &f_up, Some(&x));
    for _ in 0..3000 {
        pe = p.step(real(0.01), &b, &y[1..], &f_up, Some(&x));
    }
    let pose = (pe.x - x).norm() < real(1e-3) && (pe.r - r).norm() < real(1e-3);
    held && attitude && pose && eqf_check(&w, &r, &y, &b)
}

/// The equivariant filter without std: from a TRIAD start on exact samples of a body at
/// rest it finds the attitude and the bias, keeps its covariance positive definite, and
/// counts a NaN gyro sample.
fn eqf_check<T: Real>(
    w: &[Vector3<T>; 2],
    r: &Matrix3<T>,
    y: &[Vector3<T>; 2],
    b: &Vector3<T>,
) -> bool {
    use eqtrack_estimator::{EqfConfig, EquivariantFilter};
    let Ok(cfg) = EqfConfig::new(real(0.01), real(0.01), w, &[real(0.01), real(0.01)]) else {
        return false;
    };
    let mut f = EquivariantFilter::new(cfg);
    let mut e = f.step(real(0.01), b, y);
    for _ in 0..3000 {
        e = f.step(real(0.01), b, y);
    }
    let nan = Vector3::new(real::<T>(f64::NAN), T::zero(), T::zero());
    f.step(real(0.01), &nan, y);
    let counted = f.faults().gyro == 1;
    let spd = f.covariance().cholesky().is_some();
    counted && spd && (e.r - r).norm() < real(1e-3) && (e.bias - b).norm() < real(1e-3)
}

/// Runs every check; 0 when all hold.
/// The disturbance-rejection terms without std: the seed loop under a constant body
/// disturbance with the observer and the integral; the observer's estimate converges to the
/// disturbance.
fn rejection_check<T: Real>() -> bool {
    let inertia = Matrix3::new(0.824, 0.0, 0.12, 0.0, 1.135, 0.0, 0.12, 0.0, 1.759).map(real::<T>);
    let d = Vector3::new(real::<T>(0.1), real(-0.05), real(0.08));
    let build = || -> Result<ClosedLoop<T, So3, 3, 3>, eqtrack_controller::Error> {
        let c = Controller::new(ControllerConfig {
            law: Law::Eqt,
            error_frame: eqtrack_controller::ErrorFrame::World,
            inertia,
            k: Matrix3::identity() * real::<T>(0.5),
            kd: Matrix3::identity() * real::<T>(0.5),
            torque_limit: Some(Vector3::repeat(real(5.0))),
        })?;
        let r = Reference::new(
            Matrix3::identity(),
            Vector3::zeros(),
            inertia,
            so3_seed_feedforward(),
            real(0.01),
            1,
        )?;
        let p = RigidBody::new(inertia, Matrix3::identity(), Vector3::zeros())?;
        ClosedLoop::new(c, r, p, 10)?
            .with_disturbance(d)?
            .with_rejection(eqtrack_controller::RejectionConfig {
                observer: Some(eqtrack_controller::ObserverConfig {
                    gain: Vector3::repeat(real(10.0)),
                    limit: None,
                    frame: eqtrack_controller::Frame::Body,
                }),
                integral: Some(eqtrack_controller::IntegralConfig {
                    ki: Vector3::repeat(real(0.1)),
                    c: Vector3::repeat(real(0.1)),
                    limit: None,
                    anti_windup: true,
                }),
            })
    };
    let Ok(mut sim) = build() else { return false };
    let mut last = None;
    for _ in 0..300 {
        match sim.step() {
            Ok(s) => last = Some(s),
            Err(_) => return false,
        }
    }
    // the observer's estimate converges to d (3 s at L = 10: e^-30)
    last.is_some_and(|s| (s.output.observer - d).amax() < real(1e-3))
}

/// A through-waypoint path on SE(3) (`Path::flying`, fixed capacity, no allocation): it
/// passes its waypoints and does not stop at the interior one.
fn through_path_check<T: Real>() -> bool {
    use eqtrack_controller::path::Path;
    let twist = |a: f64, b: f64, c: f64, x: f64| {
        SVector::<T, 6>::from_column_slice(&[
            real(a),
            real(b),
            real(c),
            real(x),
            real(0.5),
            real(0.0),
        ])
    };
    let times = [real::<T>(0.0), real(1.0), real(2.5)];
    let poses = [
        Se3::identity::<T>(),
        Se3::exp(&twist(0.3, -0.2, 1.5, 1.0)),
        Se3::exp(&twist(0.0, 1.0, 3.0, 2.0)),
    ];
    let given = [None, None, None];
    let Ok(path) = Path::<T, Se3, 4, 6>::flying(&times, &poses, &given) else {
        return false;
    };
    let tolerance = real::<T>(1e-4);
    let through = times
        .iter()
        .zip(&poses)
        .all(|(t, q)| (path.sample(*t).q - q).amax() < tolerance);
    let moving = path.sample(times[1]).v.amax() > real(0.1);
    through && moving && path.segments().count() == 2
}

/// Allocation without std: the hexarotor's hover wrench met exactly within the bounds, and a
/// demand past its reach keeps the torque (status 2, the force given up).
fn allocation_check<T: Real>() -> bool {
    use eqtrack_allocation::{Allocator, Geometry, Priority, Status, presets};
    let rotors = presets::hexarotor::<T>(real(0.25), real(0.5), real(0.016), real(8.0));
    let Ok(geometry) = Geometry::<T, 6>::new(&rotors) else {
        return false;
    };
    let Ok(alloc) = Allocator::new(geometry, &[], &[], Priority::Torque) else {
        return false;
    };
    let hover = nalgebra::SVector::<T, 6>::from([
        T::zero(),
        T::zero(),
        T::zero(),
        T::zero(),
        T::zero(),
        real(20.0),
    ]);
    let a = alloc.allocate(&hover);
    let met = a.status == Status::Met && (a.achieved - hover).amax() < real(1e-3);
    let within =
        a.u.iter()
            .take(6)
            .all(|x| *x >= -real::<T>(1e-6) && *x <= real(8.0 + 1e-6));
    let mut far = hover;
    far[2] = real(1.2);
    far[5] = real(45.0);
    let b = alloc.allocate(&far);
    let kept = b.status == Status::ForceGivenUp && (b.achieved[2] - real(1.2)).abs() < real(1e-3);
    met && within && kept
}

/// Failure detection without std: a hexarotor held at rest (its rotors' wrench balanced by a
/// steady push), rotor 2 dies at cycle 100; the detector names it, dead, within 30 cycles.
fn detection_check<T: Real>() -> bool {
    use eqtrack_allocation::{Allocator, Commands, Geometry, Priority, Restoring, VehicleControl, presets};
    use detection::{Config, Detector, Kind, threshold};
    let rotors = presets::hexarotor::<T>(real(0.25), real(0.5), real(0.016), real(8.0));
    let Ok(geometry) = Geometry::<T, 6>::new(&rotors) else {
        return false;
    };
    let Ok(alloc) = Allocator::new(geometry, &[], &[], Priority::Torque) else {
        return false;
    };
    let none = Restoring {
        weight: T::zero(),
        buoyancy: T::zero(),
        centre: nalgebra::Vector3::zeros(),
    };
    let h: T = real(0.01);
    let mut control = VehicleControl::new(alloc, none, T::zero(), h);
    let inertia = nalgebra::SMatrix::<T, 6, 6>::from_diagonal(&nalgebra::SVector::from([
        real(0.02),
        real(0.02),
        real(0.04),
        real(1.5),
        real(1.5),
        real(1.5),
    ]));
    let config = Config {
        decimation: 1,
        window: 10,
        threshold: real(threshold::chi2_upper(1, threshold::per_test(1e-3, 0.01, 6))),
        isolation: real(threshold::chi2_upper(5, 1e-6)),
        relative: real(0.01),
        margin: real(threshold::chi2_upper(1, 1e-3)),
        confirm: 5,
        warmup: 0,
        calibration: 20,
        memory: real(1e-3),
        floor: nalgebra::SVector::from_element(real(1e-3)),
        resolution: Commands::from_element(real(0.04)),
        inertia,
        damping_linear: nalgebra::SVector::zeros(),
        damping_quadratic: nalgebra::SVector::zeros(),
        period: h,
        time_constant: T::zero(),
    };
    let Ok(mut detector) = Detector::new(config) else {
        return false;
    };
    let u = Commands::<T>::from_fn(|j, _| if j < 6 { real(3.0) } else { T::zero() });
    let b = *control.allocator().geometry().effectiveness();
    let (mut mu, r) = (
        nalgebra::SVector::<T, 6>::zeros(),
        nalgebra::Matrix3::<T>::identity(),
    );
    let inverse = inertia
        .try_inverse()
        .unwrap_or_else(nalgebra::SMatrix::zeros);
    for k in 0..130 {
        let v = inverse * mu;
        if let Some(d) = detector.observe::<eqtrack_controller::group::Se3, 4>(&v, &r, &mut control) {
            return k > 100 && k <= 130 && d.actuator == 2 && d.kind == Kind::Dead;
        }
        detector.commanded(&u);
        let mut real_u = u;
        if k >= 100 {
            real_u[2] = T::zero();
        }
        mu += (b * real_u - b * u) * h;
    }
    false
}

/// The serial link's frames without std: a state frame encoded and decoded, a flipped bit
/// refused by the CRC, the deframer finding the frame in a stream.
fn serial_check() -> bool {
    use eqtrack_serial_wire::{Deframer, Frame, FrameError, MAX_ENCODED, StateFrame, decode, encode};
    let state = Frame::State(StateFrame {
        seq: 3,
        t: 0.03,
        q: heapless::Vec::from_slice(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0])
            .unwrap_or_default(),
        v: heapless::Vec::from_slice(&[0.5, -0.25, 0.125]).unwrap_or_default(),
        applied: heapless::Vec::new(),
        samples: None,
        wheel_speeds: Default::default(),
    });
    let mut out = [0u8; MAX_ENCODED];
    let Ok(n) = encode(&state, &mut out) else {
        return false;
    };
    let round_trip = decode(&out[..n - 1]).as_ref() == Ok(&state);
    let mut d = Deframer::new();
    let mut found = false;
    for b in &out[..n] {
        if let Some(r) = d.push(*b) {
            found = r.as_ref() == Ok(&state);
        }
    }
    out[3] ^= 0x10;
    let caught = matches!(
        decode(&out[..n - 1]),
        Err(FrameError::Crc | FrameError::Cobs)
    );
    round_trip && found && caught
}

/// The firmware's cycle without std: a configuration from its bytes, the handshake, and a
/// command for a state.
fn firmware_cycle_check() -> bool {
    use firmware_cycle::{Axis, Config, Cycle, MAX_CONFIG, Series};
    use heapless::Vec;
    use eqtrack_serial_wire::{Frame, Hello, StateFrame};
    let v = |xs: &[f32]| -> Vec<f32, 36> { Vec::from_slice(xs).unwrap_or_default() };
    let eye = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    let axis = || Axis {
        offset: 0.1,
        terms: Vec::new(),
    };
    let config = Config {
        identity: Hello {
            group: 1,
            period: 0.01,
            fingerprint: 7,
            scenario: heapless::String::new(),
        },
        law: 0,
        error_frame: 0,
        origin: [0.0; 3],
        inertia: v(&eye),
        k: Vec::from_slice(&eye).unwrap_or_default(),
        kd: v(&eye),
        torque_limit: None,
        reference: Series {
            q0: Vec::from_slice(&eye).unwrap_or_default(),
            v0: Vec::from_slice(&[0.0; 3]).unwrap_or_default(),
            axes: Vec::from_iter([axis(), axis(), axis()]),
            substeps: 2,
        },
        observer: None,
        integral: None,
        estimator: None,
        vehicle: None,
        detector: None,
        failsafe: None,
    };
    let mut bytes = [0u8; MAX_CONFIG];
    let Ok(n) = config.to_bytes(&mut bytes) else {
        return false;
    };
    let Ok(mut cycle) = Cycle::from_bytes(&bytes[..n]) else {
        return false;
    };
    let greeted = cycle.on_frame(&Frame::Hello(config.identity.clone()))
        == Some(Frame::Hello(config.identity));
    let state = Frame::State(StateFrame {
        seq: 1,
        t: 0.01,
        q: Vec::from_slice(&eye).unwrap_or_default(),
        v: Vec::from_slice(&[0.1, 0.0, 0.0]).unwrap_or_default(),
        applied: Vec::from_slice(&[0.0; 3]).unwrap_or_default(),
        samples: None,
        wheel_speeds: Default::default(),
    });
    let answered = matches!(cycle.on_frame(&state), Some(Frame::Command(c)) if c.seq == 1 && c.tau.iter().all(|x| x.is_finite()));
    greeted && answered && firmware_cycle_on_board_check()
}

/// `pil_hexarotor`'s configuration (SE(3): the EqF, the observer, six rotors), as
/// `plant_sim pil-config` writes it (a workspace test keeps it so).
static HEXAROTOR: &[u8] = include_bytes!("../../firmware-cortex-m/pil_hexarotor.config");

/// The cycle with its estimator and allocation on board, without std: samples in, an
/// estimate and six rotor commands out.
fn firmware_cycle_on_board_check() -> bool {
    use firmware_cycle::Cycle;
    use heapless::Vec;
    use eqtrack_serial_wire::{Frame, Samples, StateFrame};
    let Ok(mut cycle) = Cycle::from_bytes(HEXAROTOR) else {
        return false;
    };
    let hello = cycle.hello();
    let greeted = cycle.on_frame(&hello) == Some(hello);
    let mut ok = greeted;
    for k in 0..5u64 {
        let state = Frame::State(StateFrame {
            seq: k,
            t: k as f64 * 0.002,
            q: Vec::new(),
            v: Vec::new(),
            applied: Vec::from_slice(&[0.0; 6]).unwrap_or_default(),
            samples: Some(Samples {
                gyro: [0.01, -0.02, 0.015],
                directions: Vec::from_slice(&[[1.0, 0.0, 0.0], [0.0, 0.6, 0.8]])
                    .unwrap_or_default(),
                accel: Some([0.0, 0.0, 9.81]),
                position: Some([0.0; 3]),
            }),
            wheel_speeds: Default::default(),
        });
        ok &= matches!(cycle.on_frame(&state), Some(Frame::Command(c))
            if c.seq == k
                && c.estimate.as_ref().is_some_and(|e| e.q.len() == 16 && e.q.iter().all(|x| x.is_finite()))
                && c.allocation.as_ref().is_some_and(|a| a.u_cmd.len() == 6 && a.u_cmd.iter().all(|x| x.is_finite())));
    }
    ok
}

/// The failsafe manager without std: a cause engages its action at once, a more severe one
/// takes over, and the milder one is back when it clears after the hysteresis.
fn failsafe_check() -> bool {
    use failsafe::{Action, Cause, Config, Inputs, Mode, State, step};
    let cfg = Config {
        actions: [None, Some(Action::Hold), Some(Action::Descend), None],
        clear_ticks: 2,
    };
    let est = Inputs {
        estimator: true,
        ..Inputs::default()
    };
    let both = Inputs {
        actuators: true,
        ..est
    };
    let mut s = State::default();
    let mut modes = [Mode::Nominal; 4];
    let mut thrust_axis = [false; 4];
    for ((m, i), f) in modes
        .iter_mut()
        .zip([est, both, est, est])
        .zip(thrust_axis.iter_mut())
    {
        let (next, _) = step(&cfg, &s, &i);
        s = next;
        *m = s.mode();
        *f = failsafe::thrust_axis::ThrustAxis::<f32>::flies(s.word());
    }
    // the thrust-axis law in f32: level at its set-point, the weight and no torque
    let Some(law) = failsafe::thrust_axis::ThrustAxis::<f32>::new(
        1.5,
        1.5 * 9.81,
        (0.02, 0.02, 0.04),
        (6.0, 4.0),
        0.02,
    ) else {
        return false;
    };
    let q = nalgebra::SMatrix::<f32, 4, 4>::identity();
    let v = nalgebra::SVector::<f32, 6>::zeros();
    let level = law
        .demand((&q, &v), (&q, &v))
        .is_some_and(|d| (d[5] - 1.5 * 9.81).abs() < 1e-4 && d[0] == 0.0 && d[1] == 0.0);
    let hold = Mode::Engaged {
        cause: Cause::Estimator,
        action: Action::Hold,
    };
    let descend = Mode::Engaged {
        cause: Cause::Actuators,
        action: Action::Descend,
    };
    modes == [hold, descend, descend, hold] && thrust_axis == [false, true, true, false] && level
}

/// The innovation gate without std: a direction turned by 30° is rejected while the other
/// passes, and the health says which.
fn gate_check<T: Real>() -> bool {
    use eqtrack_estimator::health::{GateConfig, Health, Reason, Source};
    use eqtrack_estimator::{FilterKind, Settings};
    let w = [Vector3::z(), Vector3::x()];
    let r = So3::exp(&Vector3::new(real::<T>(0.3), real(-0.4), real(0.2)));
    let settings = Settings {
        kind: FilterKind::Eqf {
            gyro_noise: real(0.002),
            bias_walk: real(1e-5),
            direction_noise: [real(0.01); 5],
            count: 2,
            initial_attitude_std: real(0.1),
            initial_bias_std: real(0.05),
        },
        world: [w[0], w[1], Vector3::zeros(), Vector3::zeros()],
        directions: 2,
        initial_attitude: None,
        bias_limit: None,
        accel_gate: None,
        accel_noise: T::zero(),
        position_noise: T::zero(),
    };
    let Ok(mut f) = settings.build(false) else {
        return false;
    };
    let cfg = GateConfig {
        direction: real(38.0),
        position: real(36.6),
        noise: [real(0.01); 5],
        window: 10,
        rejections: 1,
        direction_band: eqtrack_estimator::health::Band {
            samples: 5,
            upper: real(41.3),
        },
        position_band: eqtrack_estimator::health::Band::off(),
    };
    let mut gate = eqtrack_estimator::health::Gate::new(cfg, 2, false);
    let turned = So3::exp(&Vector3::new(T::zero(), T::zero(), real(0.5236)));
    let zero = Vector3::zeros();
    let mut health = Health::Healthy;
    for k in 0..40 {
        let y0 = r.tr_mul(&w[0]);
        let y1 = r.tr_mul(&w[1]);
        let y = if k < 20 { [y0, y1] } else { [y0, turned * y1] };
        let (_, h): (eqtrack_estimator::Step<T, 3, 3>, Health) =
            f.step_gated(&mut gate, real(0.01), &zero, &y, &zero, None);
        health = h;
    }
    let rejected: u64 = gate.rejections().map(|(_, n)| n).sum();
    health == Health::Lost(Reason::Missing(Source::Attitude)) && rejected == 20
}

fn run() -> i32 {
    let checks: [(&str, bool); 23] = [
        ("failsafe manager", failsafe_check()),
        ("innovation gate f32", gate_check::<f32>()),
        ("innovation gate f64", gate_check::<f64>()),
        ("detection f32", detection_check::<f32>()),
        ("detection f64", detection_check::<f64>()),
        ("firmware_cycle", firmware_cycle_check()),
        ("serial_wire frames", serial_check()),
        ("allocation f32", allocation_check::<f32>()),
        ("allocation f64", allocation_check::<f64>()),
        ("through-waypoint path f32", through_path_check::<f32>()),
        ("through-waypoint path f64", through_path_check::<f64>()),
        ("disturbance rejection f32", rejection_check::<f32>()),
        ("disturbance rejection f64", rejection_check::<f64>()),
        ("estimator f32", estimator_check::<f32>()),
        ("estimator f64", estimator_check::<f64>()),
        ("ipc_types messages", ipc_check()),
        ("so3 eqt f32", so3_check::<f32>(Law::Eqt)),
        ("so3 eqt f64", so3_check::<f64>(Law::Eqt)),
        ("so3 gt f64", so3_check::<f64>(Law::Gt)),
        ("se3 eqt f32", se3_check::<f32>()),
        ("se3 eqt f64", se3_check::<f64>()),
        ("so3 closed loop f32", closed_loop_check::<f32>()),
        ("so3 closed loop f64", closed_loop_check::<f64>()),
    ];
    let mut code = 0;
    for (name, ok) in checks {
        rt::write(if ok { b"ok    " } else { b"FAIL  " });
        rt::write(name.as_bytes());
        rt::write(b"\n");
        if !ok {
            code = 1;
        }
    }
    rt::write(if code == 0 {
        b"nostd-check: eqtrack-controller, eqtrack-estimator, eqtrack-allocation, detection, failsafe, ipc_types, eqtrack-serial-wire and firmware_cycle run with no std, no alloc, no allocator\n"
    } else {
        b"nostd-check: FAILED\n"
    });
    code
}
