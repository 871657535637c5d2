//! The firmware's cycle on the host: the configuration's bytes, the handshake, the answer to
//! a state (equal to the controller crate's own f32 law), and states it must drop; random
//! frames never panic it.

use eqtrack_controller::group::{MatrixLieGroup, So3};
use eqtrack_controller::{Controller, ControllerConfig, Law};
use eqtrack_serial_wire::{Frame, Hello, Samples, StateFrame};
use firmware_cycle::{
    Axis, Config, ConfigError, Cycle, Dropped, Estimator, Failure, MAX_CONFIG, Series, Term,
    Thruster, Vehicle,
};
use heapless::Vec;
use nalgebra::{Matrix3, Vector3};
use proptest::prelude::*;

fn v<const C: usize>(xs: &[f32]) -> Vec<f32, C> {
    Vec::from_slice(xs).unwrap()
}

const INERTIA: [f32; 9] = [0.824, 0.0, 0.12, 0.0, 1.135, 0.0, 0.12, 0.0, 1.759];

fn seed_like() -> Config {
    let axis = |a: f32, w: f32, p: f32| Axis {
        offset: 0.0,
        terms: Vec::from_slice(&[Term {
            amplitude: a,
            frequency: w,
            phase: p,
        }])
        .unwrap(),
    };
    Config {
        identity: Hello {
            group: 1,
            period: 0.01,
            fingerprint: 0xfeed,
            scenario: heapless::String::try_from("seed").unwrap(),
        },
        law: 0,
        error_frame: 1,
        origin: [0.0; 3],
        inertia: v(&INERTIA),
        k: v(&[0.5, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.5]),
        kd: v(&[0.5, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.5]),
        torque_limit: None,
        reference: Series {
            q0: v(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]),
            v0: v(&[0.0, 0.0, 0.0]),
            axes: Vec::from_slice(&[
                axis(1.0, 1.0, 0.0),
                axis(1.0, 1.0, -1.5707964),
                axis(0.5, 2.0, -1.5707964),
            ])
            .unwrap(),
            substeps: 10,
        },
        observer: None,
        integral: None,
        estimator: None,
        vehicle: None,
        detector: None,
        failsafe: None,
    }
}

fn state(seq: u64) -> StateFrame {
    let r = So3::exp(&Vector3::new(0.3f32, -0.2, 1.0));
    StateFrame {
        seq,
        t: seq as f64 * 0.01,
        q: (0..9).map(|i| r[(i / 3, i % 3)]).collect(),
        v: v(&[0.4, -0.1, 0.2]),
        applied: v(&[0.0; 3]),
        samples: None,
        wheel_speeds: Default::default(),
    }
}

fn greeted() -> Cycle {
    let config = seed_like();
    let mut c = Cycle::new(&config).unwrap();
    assert_eq!(
        c.on_frame(&Frame::Hello(config.identity.clone())),
        Some(Frame::Hello(config.identity))
    );
    c
}

#[test]
fn the_configuration_round_trips_and_bad_bytes_are_refused() {
    let config = seed_like();
    let mut buf = [0u8; MAX_CONFIG];
    let n = config.to_bytes(&mut buf).unwrap();
    assert_eq!(Config::from_bytes(&buf[..n]).unwrap(), config);
    assert!(Cycle::from_bytes(&buf[..n]).is_ok());
    assert_eq!(
        Config::from_bytes(&buf[..n - 1]).unwrap_err(),
        ConfigError::Bytes
    );
    let mut longer = buf[..n].to_vec();
    longer.push(0);
    assert_eq!(Config::from_bytes(&longer).unwrap_err(), ConfigError::Bytes);
    let mut bad = config.clone();
    bad.k = v(&[0.5; 4]);
    assert!(matches!(Cycle::new(&bad), Err(ConfigError::Shape("k", 4))));
    let mut bad = config.clone();
    bad.identity.group = 9;
    assert!(matches!(Cycle::new(&bad), Err(ConfigError::Group(9))));
    let mut bad = config.clone();
    bad.law = 4;
    assert!(matches!(Cycle::new(&bad), Err(ConfigError::Law(4))));
    let mut bad = config.clone();
    bad.error_frame = 3;
    assert!(matches!(Cycle::new(&bad), Err(ConfigError::ErrorFrame(3))));
    assert_eq!(
        ConfigError::ErrorFrame(3).to_string(),
        "error-frame index 3 (expected 0 to 2)"
    );
    for origin in [
        [f64::NAN, 0.0, 0.0],
        [0.0, f64::INFINITY, 0.0],
        [1.0, 0.0, 0.0],
    ] {
        // not finite; and the seed is on SO(3), which has no positions to shift
        let mut bad = config.clone();
        bad.origin = origin;
        assert!(
            matches!(Cycle::new(&bad), Err(ConfigError::Origin)),
            "{origin:?}"
        );
    }
    assert!(ConfigError::Origin.to_string().contains("zero on so3"));
    // the failsafe manager's settings: a good one makes a cycle and round-trips; an action
    // code that is none, a limit that is not a positive finite number, a rate that is not
    // finite, an actuator time constant that is not a finite number ≥ 0 are refused
    let good = firmware_cycle::Failsafe {
        actions: [2, 0, 0, 6],
        clear_ticks: 100,
        descend_rate: 0.5,
        ascend_rate: 0.3,
        limit_attitude: Some(1.0),
        limit_position: None,
        lag: 0.02,
        actuators_residual: Some(0.05),
    };
    let mut with = config.clone();
    with.failsafe = Some(good);
    let n = with.to_bytes(&mut buf).unwrap();
    assert_eq!(Config::from_bytes(&buf[..n]).unwrap(), with);
    assert!(Cycle::new(&with).is_ok());
    for bad in [
        firmware_cycle::Failsafe {
            actions: [7, 0, 0, 0],
            ..good
        },
        firmware_cycle::Failsafe {
            limit_attitude: Some(f32::NAN),
            ..good
        },
        firmware_cycle::Failsafe {
            limit_position: Some(-1.0),
            ..good
        },
        firmware_cycle::Failsafe {
            descend_rate: f32::INFINITY,
            ..good
        },
        firmware_cycle::Failsafe { lag: -0.01, ..good },
        firmware_cycle::Failsafe {
            actuators_residual: Some(0.0),
            ..good
        },
        firmware_cycle::Failsafe {
            actuators_residual: Some(f32::NAN),
            ..good
        },
        firmware_cycle::Failsafe {
            lag: f32::NAN,
            ..good
        },
    ] {
        let mut with = config.clone();
        with.failsafe = Some(bad);
        assert!(
            matches!(Cycle::new(&with), Err(ConfigError::Failsafe)),
            "{bad:?}"
        );
    }
    assert!(ConfigError::Failsafe.to_string().starts_with("failsafe: "));
    let mut bad = config;
    bad.kd = v(&[-1.0, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.5]);
    assert!(
        matches!(Cycle::new(&bad), Err(ConfigError::Controller(_))),
        "K_d not positive definite"
    );
}

#[test]
fn the_handshake_refuses_a_mismatch_and_greets_a_match() {
    let config = seed_like();
    let mut c = Cycle::new(&config).unwrap();
    // a state before any Hello: it asks to be greeted, once (the next get nothing)
    assert_eq!(
        c.on_frame(&Frame::State(state(0))),
        Some(Frame::Hello(config.identity.clone()))
    );
    assert_eq!(c.on_frame(&Frame::State(state(1))), None);
    let mut other = config.identity.clone();
    other.fingerprint ^= 1;
    other.period = 0.02;
    match c.on_frame(&Frame::Hello(other)) {
        Some(Frame::Refused { mismatch, identity }) => {
            assert_eq!(
                mismatch,
                eqtrack_serial_wire::mismatch::SCENARIO | eqtrack_serial_wire::mismatch::PERIOD
            );
            assert_eq!(identity, config.identity);
        }
        f => panic!("expected a refusal, got {f:?}"),
    }
    assert!(!c.greeted());
    assert_eq!(c.counts().refused, 1);
    assert_eq!(
        c.on_frame(&Frame::Hello(config.identity.clone())),
        Some(Frame::Hello(config.identity))
    );
    assert!(c.greeted());
    assert_eq!(c.on_frame(&Frame::Bye), None);
    assert!(!c.greeted());
}

#[test]
fn the_answer_is_the_f32_laws_and_bad_states_are_dropped() {
    let config = seed_like();
    let mut c = greeted();
    // the same law and reference built directly
    let law = Controller::<f32, So3, 3, 3>::new(ControllerConfig {
        law: Law::Eqt,
        error_frame: eqtrack_controller::ErrorFrame::World,
        inertia: Matrix3::from_row_slice(&INERTIA),
        k: Matrix3::identity() * 0.5,
        kd: Matrix3::identity() * 0.5,
        torque_limit: None,
    })
    .unwrap();
    let mut reference = config.reference::<So3, 3, 3>().unwrap();
    for _ in 0..5 {
        reference.advance();
    }
    let s = state(5);
    let expected = law
        .compute(
            &Matrix3::from_row_slice(&s.q),
            &Vector3::from_row_slice(&s.v),
            &reference.desired(),
        )
        .unwrap();
    match c.on_frame(&Frame::State(s)) {
        Some(Frame::Command(cmd)) => {
            assert_eq!(cmd.seq, 5);
            assert_eq!(cmd.law, 0);
            assert_eq!(cmd.tau.as_slice(), expected.torque.as_slice());
            assert_eq!(cmd.lyapunov, expected.lyapunov.total);
            assert!(cmd.observer.is_empty() && cmd.integral.is_empty());
        }
        f => panic!("expected a command, got {f:?}"),
    }
    // an old state, a wrong shape, a NaN, a jump too far: no command, each counted
    assert_eq!(c.on_frame(&Frame::State(state(4))), None);
    let mut s = state(6);
    s.v = v(&[0.0; 2]);
    assert_eq!(c.on_frame(&Frame::State(s)), None);
    let mut s = state(6);
    s.q[0] = f32::NAN;
    assert_eq!(c.on_frame(&Frame::State(s)), None);
    assert_eq!(c.on_frame(&Frame::State(state(2_000_000))), None);
    let d = c.counts().dropped;
    assert_eq!(d[Dropped::Backwards as usize], 1);
    assert_eq!(d[Dropped::Shape as usize], 1);
    assert_eq!(d[Dropped::Law as usize], 1);
    assert_eq!(d[Dropped::Jump as usize], 1);
    assert_eq!(c.counts().answered, 1);
    // a new handshake starts the run over: state 0 is answered again
    c.on_frame(&Frame::Hello(config.identity.clone()));
    assert!(matches!(
        c.on_frame(&Frame::State(state(0))),
        Some(Frame::Command(_))
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn random_states_never_panic_and_never_answer_a_nan(
        seq in 0u64..3000,
        q in prop::collection::vec(prop::num::f32::ANY, 0..=16),
        vel in prop::collection::vec(prop::num::f32::ANY, 0..=6),
        applied in prop::collection::vec(prop::num::f32::ANY, 0..=6),
    ) {
        let mut c = greeted();
        let s = StateFrame { seq, t: 0.0, q: v(&q), v: v(&vel), applied: v(&applied), samples: None, wheel_speeds: Default::default() };
        if let Some(Frame::Command(cmd)) = c.on_frame(&Frame::State(s)) {
            prop_assert!(cmd.tau.iter().all(|x| x.is_finite()));
            prop_assert!(cmd.lyapunov.is_finite());
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// A configuration file damaged anywhere, or random bytes, is refused or builds a cycle;
    /// never a panic.
    #[test]
    fn damaged_configurations_never_panic(flips in prop::collection::vec((0usize..400, any::<u8>()), 1..8), cut in 0usize..400, noise in prop::collection::vec(any::<u8>(), 0..300)) {
        let mut buf = [0u8; MAX_CONFIG];
        let n = seed_like().to_bytes(&mut buf).unwrap();
        let mut bytes = buf[..n].to_vec();
        for (i, x) in flips {
            let i = i % bytes.len();
            bytes[i] ^= x;
        }
        bytes.truncate(cut.max(1).min(bytes.len()));
        let _ = Cycle::from_bytes(&bytes);
        let _ = Cycle::from_bytes(&noise);
    }
}

/// The seed with the complementary filter on two directions and four reaction wheels (three
/// on the axes, one along (1, 1, 1); the second fails at t = 0.05 s, stuck at 0.01 N m).
fn on_board() -> Config {
    Config {
        estimator: Some(Estimator {
            eqf: false,
            gains: [2.0, 0.3],
            values: v(&[1.0, 1.0]),
            initial_std: [0.0; 2],
            world: Vec::from_slice(&[[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]).unwrap(),
            initial_attitude: None,
            bias_limit: Some(0.2),
            accel_gate: None,
            accel_noise: 0.0,
            position_noise: 0.0,
            gate: None,
        }),
        vehicle: Some(Vehicle {
            actuators: [
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
                [1.0, 1.0, 1.0],
            ]
            .iter()
            .map(|axis| Thruster {
                position: [0.0; 3],
                axis: *axis,
                torque_per_thrust: 1.0,
                min: -0.5,
                max: 0.5,
            })
            .collect(),
            weights: Vec::new(),
            preferred: Vec::new(),
            torque_first: true,
            weight: 0.0,
            buoyancy: 0.0,
            centre: [0.0; 3],
            rate_limit: 0.0,
            failures: Vec::from_slice(&[Failure {
                actuator: 1,
                t: 0.05,
                value: 0.01,
            }])
            .unwrap(),
            budget: eqtrack_allocation::DEFAULT_BUDGET,
            wheels: Vec::new(),
            momentum: None,
        }),
        ..seed_like()
    }
}

fn samples(r: &Matrix3<f32>, gyro: [f32; 3]) -> Samples {
    let body = |d: Vector3<f32>| {
        let b = r.transpose() * d;
        [b[0], b[1], b[2]]
    };
    Samples {
        gyro,
        directions: Vec::from_slice(&[body(Vector3::x()), body(Vector3::z())]).unwrap(),
        accel: None,
        position: None,
    }
}

fn sampled(seq: u64, samples: Samples) -> StateFrame {
    StateFrame {
        seq,
        t: seq as f64 * 0.01,
        q: Vec::new(),
        v: Vec::new(),
        applied: v(&[0.0; 3]),
        samples: Some(samples),
        wheel_speeds: Default::default(),
    }
}

#[test]
fn on_board_the_estimator_feeds_the_law_and_the_allocator_splits_its_torque() {
    let config = on_board();
    let mut c = Cycle::new(&config).unwrap();
    c.on_frame(&Frame::Hello(config.identity.clone()));
    // the estimator crate's filter, built from the same settings, beside it
    let mut filter = config
        .estimator
        .as_ref()
        .unwrap()
        .settings()
        .build(false)
        .unwrap();
    let r = So3::exp(&Vector3::new(0.3f32, -0.2, 1.0));
    for k in 0..10u64 {
        let smp = samples(&r, [0.01, -0.02, 0.03]);
        let dirs = [
            Vector3::from(smp.directions[0]),
            Vector3::from(smp.directions[1]),
        ];
        let expected = filter.step::<3, 3>(
            0.01,
            &Vector3::from(smp.gyro),
            &dirs,
            &Vector3::zeros(),
            None,
        );
        let Some(Frame::Command(cmd)) = c.on_frame(&Frame::State(sampled(k, smp))) else {
            panic!("state {k}: no command");
        };
        let e = cmd.estimate.expect("the estimate");
        let rows: std::vec::Vec<f32> = (0..9).map(|i| expected.q[(i / 3, i % 3)]).collect();
        assert_eq!(e.q.as_slice(), rows.as_slice(), "state {k}");
        assert_eq!(e.v.as_slice(), expected.v.as_slice(), "state {k}");
        // TRIAD from two exact directions, then a biased gyro on a still body: the estimate
        // stays near the attitude (the bias is 0.037 rad/s; 0.1 s of it is 4 mrad)
        assert!(
            (Matrix3::from_row_slice(&e.q) - r).norm() < 0.02,
            "{:?}",
            e.q
        );
        let a = cmd.allocation.expect("the allocation");
        assert_eq!(a.u_cmd.len(), 4);
        assert!(
            a.u_cmd.iter().all(|u| u.abs() <= 0.5 + 1e-6),
            "{:?}",
            a.u_cmd
        );
        // the torque the commands achieve: B u with B the four unit axes
        let skew = a.u_cmd[3] / 3f32.sqrt();
        let achieved = Vector3::new(a.u_cmd[0] + skew, a.u_cmd[1] + skew, a.u_cmd[2] + skew);
        assert!(
            (achieved - Vector3::from_row_slice(&a.achieved)).norm() < 1e-5,
            "{achieved:?} vs {:?}",
            a.achieved
        );
        if a.status == 0 {
            assert!(
                (achieved - Vector3::from_row_slice(&cmd.tau)).norm() < 1e-4,
                "state {k}: met, yet {achieved:?} vs {:?}",
                cmd.tau
            );
        }
        // from t = 0.05 s (k ≥ 5) the failed wheel is held at its stuck value
        if k >= 5 {
            assert_eq!(a.u_cmd[1], 0.01, "state {k}");
        }
    }
}

#[test]
fn on_board_bad_samples_never_give_a_nan_and_missing_ones_are_dropped() {
    let config = on_board();
    let mut c = Cycle::new(&config).unwrap();
    c.on_frame(&Frame::Hello(config.identity.clone()));
    let r = So3::exp(&Vector3::new(0.1f32, 0.2, -0.3));
    // a state without samples, for a controller that estimates: dropped as the wrong shape
    assert_eq!(c.on_frame(&Frame::State(state(0))), None);
    assert_eq!(c.counts().dropped[Dropped::Shape as usize], 1);
    for (k, bad) in [f32::NAN, f32::INFINITY, -f32::INFINITY, 1e30, 0.0]
        .into_iter()
        .enumerate()
    {
        let mut smp = samples(&r, [bad, 0.0, 0.0]);
        smp.directions[0] = [bad, bad, 0.0];
        if k == 4 {
            smp.directions.clear();
        }
        match c.on_frame(&Frame::State(sampled(k as u64, smp))) {
            Some(Frame::Command(cmd)) => {
                assert!(
                    cmd.tau.iter().all(|x| x.is_finite()),
                    "{bad}: {:?}",
                    cmd.tau
                );
                let e = cmd.estimate.unwrap();
                assert!(e.q.iter().chain(&e.v).all(|x| x.is_finite()), "{bad}");
                assert!(cmd.allocation.unwrap().u_cmd.iter().all(|x| x.is_finite()));
            }
            // the filter skips or holds: the law still answers
            f => panic!("{bad}: expected a command, got {f:?}"),
        }
    }
    // and a controller without an estimator drops a state that brings samples
    let mut plain = greeted();
    assert_eq!(
        plain.on_frame(&Frame::State(sampled(0, samples(&r, [0.0; 3])))),
        None
    );
    assert_eq!(plain.counts().dropped[Dropped::Shape as usize], 1);
}

#[test]
fn an_estimator_or_a_vehicle_the_crates_refuse_is_a_configuration_error() {
    let mut config = on_board();
    config.estimator.as_mut().unwrap().world.clear();
    assert!(matches!(
        Cycle::new(&config).err(),
        Some(ConfigError::Estimator(_))
    ));
    let mut config = on_board();
    config.estimator.as_mut().unwrap().values[0] = -1.0;
    assert!(matches!(
        Cycle::new(&config).err(),
        Some(ConfigError::Estimator(_))
    ));
    // the innovation gate: a good one makes a cycle and round-trips; a threshold or band
    // bound that is not a finite number > 0, a noise that is negative or not finite, a window
    // of 0, a rejection count outside 1 to 8, refused
    let good = firmware_cycle::Gate {
        direction: 38.0,
        position: 36.6,
        noise: v(&[0.01, 0.01]),
        window: 50,
        rejections: 1,
        direction_band: (50, 183.0),
        position_band: (0, 0.0),
    };
    let mut config = on_board();
    config.estimator.as_mut().unwrap().gate = Some(good.clone());
    let mut buf = [0u8; 4096];
    let n = config.to_bytes(&mut buf).unwrap();
    assert_eq!(Config::from_bytes(&buf[..n]).unwrap(), config);
    assert!(Cycle::new(&config).is_ok());
    let bad: [fn(&mut firmware_cycle::Gate); 10] = [
        |g| g.direction = f32::NAN,
        |g| g.position = -1.0,
        |g| g.noise[1] = -0.01,
        |g| g.noise[0] = f32::NAN,
        |g| g.noise[0] = f32::INFINITY,
        |g| g.window = 0,
        |g| g.rejections = 0,
        |g| g.rejections = 9,
        |g| g.direction_band.1 = f32::INFINITY,
        |g| g.position_band = (5, 0.0),
    ];
    for (i, spoil) in bad.iter().enumerate() {
        let mut gate = good.clone();
        spoil(&mut gate);
        let mut config = on_board();
        config.estimator.as_mut().unwrap().gate = Some(gate);
        let e = Cycle::new(&config).err();
        assert!(matches!(e, Some(ConfigError::Gate)), "{i}: {e:?}");
    }
    assert!(
        ConfigError::Gate
            .to_string()
            .starts_with("estimator gate: ")
    );
    let mut config = on_board();
    config.vehicle.as_mut().unwrap().actuators[0].axis = [0.0; 3];
    let e = Cycle::new(&config).err();
    assert!(matches!(e, Some(ConfigError::Vehicle(_))), "{e:?}");
    assert!(e.unwrap().to_string().starts_with("vehicle:"));
    let mut config = on_board();
    config.vehicle.as_mut().unwrap().actuators[2].min = 1.0;
    assert!(matches!(
        Cycle::new(&config).err(),
        Some(ConfigError::Vehicle(_))
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Random samples (any f32, any count of directions, fixes or not) never panic the
    /// estimator on board and never answer a non-finite torque, estimate or command.
    #[test]
    fn random_samples_never_panic_and_never_answer_a_nan(
        ticks in prop::collection::vec((
            prop::array::uniform3(prop::num::f32::ANY),
            prop::collection::vec(prop::array::uniform3(prop::num::f32::ANY), 0..=4),
            prop::option::of(prop::array::uniform3(prop::num::f32::ANY)),
        ), 1..20),
    ) {
        let config = on_board();
        let mut c = Cycle::new(&config).unwrap();
        c.on_frame(&Frame::Hello(config.identity.clone()));
        for (k, (gyro, dirs, accel)) in ticks.into_iter().enumerate() {
            let smp = Samples {
                gyro,
                directions: Vec::from_slice(&dirs).unwrap(),
                accel,
                position: None,
            };
            if let Some(Frame::Command(cmd)) = c.on_frame(&Frame::State(sampled(k as u64, smp))) {
                prop_assert!(cmd.tau.iter().all(|x| x.is_finite()));
                let e = cmd.estimate.unwrap();
                prop_assert!(e.q.iter().chain(&e.v).all(|x| x.is_finite()));
                prop_assert!(cmd.allocation.unwrap().u_cmd.iter().all(|x| x.is_finite()));
            }
        }
    }
}

/// `pil_hexarotor`'s configuration (SE(3): the EqF with the pose filter, the world-frame
/// observer, six rotors), as `plant_sim pil-config` writes it (a workspace test keeps it so).
const HEXAROTOR: &[u8] = include_bytes!("../../embedded/firmware-cortex-m/pil_hexarotor.config");

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// The same on SE(3): random samples, fixes and applied wrenches never panic the EqF,
    /// the law or the allocation on board, and never answer a non-finite number.
    #[test]
    fn random_se3_samples_never_panic_and_never_answer_a_nan(
        ticks in prop::collection::vec((
            prop::array::uniform3(prop::num::f32::ANY),
            prop::collection::vec(prop::array::uniform3(prop::num::f32::ANY), 0..=4),
            prop::option::of(prop::array::uniform3(prop::num::f32::ANY)),
            prop::option::of(prop::array::uniform3(prop::num::f32::ANY)),
            prop::array::uniform6(prop::num::f32::ANY),
        ), 1..12),
    ) {
        let mut c = Cycle::from_bytes(HEXAROTOR).unwrap();
        let hello = c.hello();
        c.on_frame(&hello);
        for (k, (gyro, dirs, accel, position, applied)) in ticks.into_iter().enumerate() {
            let s = StateFrame {
                seq: k as u64,
                t: k as f64 * 0.002,
                q: Vec::new(),
                v: Vec::new(),
                applied: Vec::from_slice(&applied).unwrap(),
                samples: Some(Samples {
                    gyro,
                    directions: Vec::from_slice(&dirs).unwrap(),
                    accel,
                    position,
                }),
                wheel_speeds: Default::default(),
            };
            if let Some(Frame::Command(cmd)) = c.on_frame(&Frame::State(s)) {
                prop_assert!(cmd.tau.iter().chain(&cmd.observer).all(|x| x.is_finite()));
                let e = cmd.estimate.unwrap();
                prop_assert!(e.q.iter().chain(&e.v).all(|x| x.is_finite()));
                let a = cmd.allocation.unwrap();
                prop_assert_eq!(a.u_cmd.len(), 6);
                prop_assert!(a.u_cmd.iter().chain(&a.accounted).all(|x| x.is_finite()));
            }
        }
    }
}

proptest! {
    /// Any local origin in an SE(3) configuration: a finite one builds the cycle and it
    /// answers with finite numbers; any other is refused as the origin, never a panic.
    #[test]
    fn any_local_origin_is_taken_or_refused_by_name(
        origin in prop::array::uniform3(prop::num::f64::ANY),
    ) {
        let mut config = firmware_cycle::Config::from_bytes(HEXAROTOR).unwrap();
        config.origin = origin;
        match Cycle::new(&config) {
            Ok(_) => prop_assert!(origin.iter().all(|x| x.is_finite())),
            Err(e) => {
                prop_assert!(matches!(e, ConfigError::Origin), "{e}");
                prop_assert!(!origin.iter().all(|x| x.is_finite()));
            }
        }
    }
}

/// A detector's settings for `on_board`'s four thrusters on SO(3).
fn detector() -> firmware_cycle::Detector {
    firmware_cycle::Detector {
        decimation: 1,
        window: 10,
        threshold: 40.0,
        isolation: 30.0,
        relative: 0.01,
        margin: 10.8,
        confirm: 5,
        warmup: 20,
        calibration: 80,
        memory: 0.001,
        floor: v(&[0.01; 3]),
        resolution: v(&[0.005; 4]),
        damping_linear: v(&[0.0; 3]),
        damping_quadratic: v(&[0.0; 3]),
        time_constant: 0.0,
    }
}

/// The failure detector is the crate's feature `detector`: built with it (as the workspace
/// builds it), a configuration with a detector makes a cycle whose commands carry the
/// detector's cycle; built without it (`cargo test -p firmware_cycle`, as a firmware for a
/// scenario without `[fault_detection]` is built), that configuration is refused, naming the
/// feature, and one without a detector still makes its cycle.
#[test]
fn a_detector_is_the_features() {
    let mut with = on_board();
    with.detector = Some(detector());
    let made = Cycle::new(&with);
    if cfg!(feature = "detector") {
        let mut cycle = made.unwrap();
        let hello = cycle.hello();
        cycle.on_frame(&hello);
        let r = Matrix3::identity();
        let state = Frame::State(sampled(0, samples(&r, [0.0; 3])));
        let Some(Frame::Command(c)) = cycle.on_frame(&state) else {
            panic!("no command");
        };
        let d = c.detection.unwrap();
        assert_eq!((d.alarms, d.suspect, d.detected), (0, 0, 0));
    } else {
        let e = made.err().unwrap();
        assert_eq!(e, ConfigError::DetectorNotBuilt);
        assert!(e.to_string().contains("feature `detector`"), "{e}");
    }
    assert!(Cycle::new(&on_board()).is_ok());
    // settings the detector refuses, and a detector without a vehicle (either build)
    let mut lonely = with.clone();
    lonely.vehicle = None;
    let e = Cycle::new(&lonely).err().unwrap();
    assert!(
        matches!(
            e,
            ConfigError::DetectorWithoutVehicle | ConfigError::DetectorNotBuilt
        ),
        "{e}"
    );
}

/// The failsafe's `link` cause on the firmware, as in the pair's controller
/// (docs/failsafe.md, "Causes"): a command the host did not apply (the state after it reports
/// the wrench of the one before) raises `link` on a state that follows the last one answered,
/// and the hold is left after `clear_ticks` ticks with every command applied.
#[test]
fn a_command_the_host_did_not_apply_raises_link() {
    let mut config = seed_like();
    config.failsafe = Some(firmware_cycle::Failsafe {
        actions: [2, 0, 0, 0],
        clear_ticks: 5,
        descend_rate: 0.5,
        ascend_rate: 0.3,
        limit_attitude: None,
        limit_position: None,
        lag: 0.0,
        actuators_residual: None,
    });
    // the manager's words of a run in which the host applied every command but `late`
    let words = |late: Option<u64>| -> std::vec::Vec<u32> {
        let mut c = Cycle::new(&config).unwrap();
        c.on_frame(&Frame::Hello(config.identity.clone()));
        let mut applied: Vec<f32, 6> = v(&[0.0; 3]);
        (0..30)
            .map(|k| {
                let mut s = state(k);
                s.applied = applied.clone();
                let Some(Frame::Command(cmd)) = c.on_frame(&Frame::State(s)) else {
                    panic!("state {k} not answered");
                };
                if late != Some(k) {
                    applied = cmd.tau.clone();
                }
                cmd.failsafe.unwrap()
            })
            .collect()
    };
    // action `hold` (code 2) for cause `link` (code 1), with `link` raised (bit 8)
    let hold = 2 | 1 << 4 | 1 << 8;
    assert!(words(None).iter().all(|w| *w == 0), "{:?}", words(None));
    let late = words(Some(10));
    assert!(late[..11].iter().all(|w| *w == 0), "{late:?}");
    assert_eq!(late[11], hold, "{late:?}");
    assert_eq!(late.iter().filter(|w| **w == hold).count(), 5, "{late:?}");
    assert_eq!(late[29], 0);
}

/// The seed with four reaction wheels in a pyramid (each axis 30° off the x-y plane) and no
/// thrusters, as `wheels_slew` flies them, with momentum management when `managed`.
fn wheeled(managed: bool) -> Config {
    let (c, s) = (0.866_025_4f32, 0.5f32);
    let wheels = [[c, 0.0, s], [0.0, c, s], [-c, 0.0, s], [0.0, -c, s]]
        .iter()
        .map(|axis| firmware_cycle::Wheel {
            axis: *axis,
            inertia: 0.01,
            max_torque: 0.5,
            max_speed: 100.0,
        })
        .collect();
    Config {
        vehicle: Some(Vehicle {
            actuators: Vec::new(),
            weights: Vec::new(),
            preferred: Vec::new(),
            torque_first: false,
            weight: 0.0,
            buoyancy: 0.0,
            centre: [0.0; 3],
            rate_limit: 0.0,
            failures: Vec::new(),
            budget: eqtrack_allocation::DEFAULT_BUDGET,
            wheels,
            momentum: managed.then(|| firmware_cycle::Momentum {
                null_gain: 0.5,
                bias: v(&[20.0, -20.0, 20.0, -20.0]),
                dump_threshold: 0.0,
                dump_gain: 0.0,
            }),
        }),
        ..seed_like()
    }
}

/// `state(seq)` with the wheels turning at `speeds`.
fn spinning(seq: u64, speeds: &[f32]) -> StateFrame {
    StateFrame {
        wheel_speeds: v(speeds),
        ..state(seq)
    }
}

/// On board, a wheeled vehicle's command is the allocation crate's `actuate_wheeled` of the
/// law's torque, bit for bit (with and without momentum management): the demand is the law's
/// torque plus the gyroscopic torque of the wheels' absolute momentum
/// `h_i = J_s (g_iᵀω + Ω_i)` (docs/maths.md, "Reaction wheels"; worked out here
/// independently, in f64), and the wrench accounted for leaves that torque out.
#[test]
fn on_board_the_wheels_allocation_is_the_allocation_crates() {
    for managed in [false, true] {
        let config = wheeled(managed);
        let mut c = Cycle::new(&config).unwrap();
        c.on_frame(&Frame::Hello(config.identity.clone()));
        let vehicle = config.vehicle.as_ref().unwrap();
        let mut control = vehicle.control::<3>(0.01).unwrap();
        let r = So3::exp(&Vector3::new(0.3f32, -0.2, 1.0));
        let omega = Vector3::new(0.4f32, -0.1, 0.2);
        for k in 0..20u64 {
            let speeds = [
                30.0 + k as f32,
                -45.0,
                80.0 - 2.0 * k as f32,
                k as f32 * 0.5,
            ];
            let Some(Frame::Command(cmd)) = c.on_frame(&Frame::State(spinning(k, &speeds))) else {
                panic!("state {k}: no command");
            };
            let a = cmd.allocation.expect("the allocation");
            let tau = Vector3::from_row_slice(&cmd.tau);
            let expected = control.actuate_wheeled(&tau, &r, &omega, &speeds);
            assert_eq!(
                a.u_cmd.as_slice(),
                &expected.allocation.u.as_slice()[..4],
                "{k}"
            );
            assert_eq!(a.demand.as_slice(), expected.demand.as_slice(), "{k}");
            // the gyroscopic torque, in f64 from the frame's numbers
            let w = omega.cast::<f64>();
            let mut h = nalgebra::Vector3::<f64>::zeros();
            for (wheel, s) in vehicle.wheels.iter().zip(speeds) {
                let g = nalgebra::Vector3::from(wheel.axis)
                    .cast::<f64>()
                    .normalize();
                h += g * (f64::from(wheel.inertia) * (g.dot(&w) + f64::from(s)));
            }
            let gyro = w.cross(&h);
            let demand = Vector3::from_row_slice(&a.demand).cast::<f64>();
            assert!(
                (demand - tau.cast::<f64>() - gyro).norm() < 1e-5 * (1.0 + gyro.norm()),
                "{k}: the demand {demand:?}, the law's {tau:?}, the gyroscopic {gyro:?}"
            );
            // the relative momentum J_s Ω alone would be another torque
            let relative: nalgebra::Vector3<f64> = vehicle
                .wheels
                .iter()
                .zip(speeds)
                .map(|(wheel, s)| {
                    let g = nalgebra::Vector3::from(wheel.axis)
                        .cast::<f64>()
                        .normalize();
                    w.cross(&(g * f64::from(wheel.inertia * s)))
                })
                .sum();
            assert!((relative - gyro).norm() > 1e-4, "{k}");
            let accounted = Vector3::from_row_slice(&a.accounted).cast::<f64>();
            let achieved = Vector3::from_row_slice(&a.achieved).cast::<f64>();
            assert!((accounted - (achieved - gyro)).norm() < 1e-5, "{k}");
        }
    }
}

/// A wheel at its top speed gets no command that speeds it up: the command that would (at
/// rest) is replaced by one that does not, the others take over; and within a period no
/// command ever takes a wheel past its top speed, at random speeds within the limits.
#[test]
fn on_board_a_wheel_at_its_top_speed_is_not_sped_up() {
    let config = wheeled(false);
    let fresh = || {
        let mut c = Cycle::new(&config).unwrap();
        c.on_frame(&Frame::Hello(config.identity.clone()));
        c
    };
    let u = |c: &mut Cycle, speeds: &[f32]| match c.on_frame(&Frame::State(spinning(0, speeds))) {
        Some(Frame::Command(cmd)) => cmd.allocation.unwrap().u_cmd,
        other => panic!("{other:?}"),
    };
    let at_rest = u(&mut fresh(), &[0.0; 4]);
    let (j, most) =
        at_rest.iter().enumerate().fold(
            (0, f32::MIN),
            |b, (j, x)| if *x > b.1 { (j, *x) } else { b },
        );
    assert!(most > 0.0, "{at_rest:?}");
    let mut speeds = [0.0f32; 4];
    speeds[j] = 100.0;
    let fast = u(&mut fresh(), &speeds);
    assert!(fast[j] <= 0.0, "wheel {j}: {fast:?} (at rest {at_rest:?})");
    let mut rng = 0x2545_f491_4f6c_dd1du64;
    for _ in 0..200 {
        let mut speeds = [0.0f32; 4];
        for s in &mut speeds {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            *s = ((rng >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0) * 100.0;
        }
        let cmd = u(&mut fresh(), &speeds);
        for (x, s) in cmd.iter().zip(speeds) {
            // the speed a period later, J_s dΩ/dt = u (the body's part aside)
            let next = s + x * 0.01 / 0.01;
            assert!(
                next.abs() <= 100.0 + 1e-3 || next.abs() <= s.abs(),
                "{speeds:?} {cmd:?}"
            );
            assert!(x.abs() <= 0.5, "{cmd:?}");
        }
    }
}

/// A state whose wheel speeds are not one per wheel is dropped as the wrong shape, one with a
/// speed that is not a number as a non-finite state; random speeds never panic the cycle nor
/// answer a NaN.
#[test]
fn on_board_bad_wheel_speeds_are_dropped() {
    let config = wheeled(false);
    let mut c = Cycle::new(&config).unwrap();
    c.on_frame(&Frame::Hello(config.identity.clone()));
    assert_eq!(c.on_frame(&Frame::State(spinning(0, &[1.0; 3]))), None);
    assert_eq!(c.on_frame(&Frame::State(state(0))), None);
    assert_eq!(c.on_frame(&Frame::State(spinning(0, &[1.0; 5]))), None);
    assert_eq!(c.counts().dropped[Dropped::Shape as usize], 3);
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        assert_eq!(
            c.on_frame(&Frame::State(spinning(0, &[1.0, bad, 0.0, 0.0]))),
            None
        );
    }
    assert_eq!(c.counts().dropped[Dropped::Law as usize], 3);
    assert!(matches!(
        c.on_frame(&Frame::State(spinning(0, &[1.0; 4]))),
        Some(Frame::Command(_))
    ));
    // a vehicle without wheels drops a state that carries speeds
    let mut plain = greeted();
    assert_eq!(plain.on_frame(&Frame::State(spinning(0, &[1.0]))), None);
    assert_eq!(plain.counts().dropped[Dropped::Shape as usize], 1);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn random_wheel_speeds_never_panic_and_never_answer_a_nan(
        seq in 0u64..50,
        speeds in prop::collection::vec(prop::num::f32::ANY, 0..=6),
        managed in any::<bool>(),
    ) {
        let config = wheeled(managed);
        let mut c = Cycle::new(&config).unwrap();
        c.on_frame(&Frame::Hello(config.identity.clone()));
        if let Some(Frame::Command(cmd)) = c.on_frame(&Frame::State(spinning(seq, &speeds))) {
            prop_assert_eq!(speeds.len(), 4);
            let a = cmd.allocation.unwrap();
            prop_assert!(cmd.tau.iter().chain(&a.u_cmd).chain(&a.accounted).all(|x| x.is_finite()));
            prop_assert!(a.u_cmd.iter().all(|x| x.abs() <= 0.5));
        }
    }
}

/// Wheels and momentum management round-trip through the configuration's bytes; a bad
/// wheel or momentum setting, or more actuators than the allocator holds, is refused naming
/// its key.
#[test]
fn bad_wheels_are_refused_naming_the_key() {
    let config = wheeled(true);
    let mut buf = [0u8; MAX_CONFIG];
    let n = config.to_bytes(&mut buf).unwrap();
    assert_eq!(Config::from_bytes(&buf[..n]).unwrap(), config);
    assert!(Cycle::new(&config).is_ok());
    type Spoil = fn(&mut Vehicle);
    let bad: [(Spoil, &str); 14] = [
        (|v| v.wheels[0].axis = [0.0; 3], "wheel.axis"),
        (|v| v.wheels[1].axis[2] = f32::NAN, "wheel.axis"),
        (|v| v.wheels[2].inertia = 0.0, "wheel.inertia"),
        (|v| v.wheels[2].inertia = -0.01, "wheel.inertia"),
        (|v| v.wheels[3].inertia = f32::INFINITY, "wheel.inertia"),
        (|v| v.wheels[0].max_torque = -0.5, "wheel.max_torque"),
        (|v| v.wheels[0].max_torque = f32::NAN, "wheel.max_torque"),
        (|v| v.wheels[1].max_speed = -1.0, "wheel.max_speed"),
        (|v| v.wheels[1].max_speed = 0.0, "wheel.max_speed"),
        (
            |v| v.momentum.as_mut().unwrap().null_gain = -1.0,
            "momentum.null_gain",
        ),
        (
            |v| v.momentum.as_mut().unwrap().dump_threshold = f32::NAN,
            "momentum.dump_threshold",
        ),
        (
            |v| v.momentum.as_mut().unwrap().dump_gain = -0.1,
            "momentum.dump_gain",
        ),
        (
            |v| {
                v.momentum.as_mut().unwrap().bias.pop();
            },
            "momentum.bias",
        ),
        (
            |v| {
                // twelve thrusters and four wheels: more than the allocator's 12 columns
                let t = Thruster {
                    position: [0.0; 3],
                    axis: [1.0, 0.0, 0.0],
                    torque_per_thrust: 1.0,
                    min: -1.0,
                    max: 1.0,
                };
                v.actuators = core::iter::repeat_n(t, 12).collect();
            },
            "actuators",
        ),
    ];
    for (i, (spoil, key)) in bad.iter().enumerate() {
        let mut config = wheeled(true);
        spoil(config.vehicle.as_mut().unwrap());
        let e = Cycle::new(&config).err();
        assert_eq!(e, Some(ConfigError::Vehicle(key)), "{i}");
        assert!(e.unwrap().to_string().contains(&format!("`{key}`")), "{i}");
    }
}

/// The failure detector on board sees the wheels (docs/maths.md, "Failure detection" and
/// "Reaction wheels"): over 150 states of a wheeled vehicle, each command's detector cycle is
/// the `detection` crate's `observe_wheeled` of the frame's speeds, bit for bit (the
/// allocation's commands told to it, as the cycle tells them), and not what a detector
/// blind to the speeds computes.
#[cfg(feature = "detector")]
#[test]
fn on_board_the_detector_takes_the_wheel_speeds() {
    let mut config = wheeled(false);
    config.detector = Some(detector());
    let mut c = Cycle::new(&config).unwrap();
    c.on_frame(&Frame::Hello(config.identity.clone()));
    let vehicle = config.vehicle.as_ref().unwrap();
    let inertia = nalgebra::Matrix3::from_row_slice(&INERTIA);
    let settings = config
        .detector
        .as_ref()
        .unwrap()
        .config::<3>(inertia, 0.01)
        .unwrap();
    let replica = || {
        let mut d = detection::Detector::<f32, 3>::new(settings).unwrap();
        d.gap();
        (d, vehicle.control::<3>(0.01).unwrap())
    };
    let ((mut seeing, mut control), (mut blind, mut blind_control)) = (replica(), replica());
    let r = So3::exp(&Vector3::new(0.3f32, -0.2, 1.0));
    let omega = Vector3::new(0.4f32, -0.1, 0.2);
    let (mut applied, mut differs, mut tested) = ([0.0f32; 3], false, 0);
    for k in 0..150u64 {
        let t = k as f32 * 0.01;
        let speeds = [40.0 * t, -30.0 + 10.0 * t, 25.0, 60.0 - 40.0 * t];
        let frame = StateFrame {
            applied: v(&applied),
            ..spinning(k, &speeds)
        };
        let Some(Frame::Command(cmd)) = c.on_frame(&Frame::State(frame)) else {
            panic!("state {k}: no command");
        };
        let tau = Vector3::from_row_slice(&cmd.tau);
        seeing.observe_wheeled::<So3, 3>(&omega, &r, &speeds, &mut control);
        blind.observe_wheeled::<So3, 3>(&omega, &r, &[], &mut blind_control);
        let a = control.actuate_wheeled(&tau, &r, &omega, &speeds);
        seeing.commanded(&a.allocation.u);
        let b = blind_control.actuate_wheeled(&tau, &r, &omega, &speeds);
        blind.commanded(&b.allocation.u);
        let d = cmd.detection.unwrap();
        let last = seeing.statistic();
        if last.testing {
            tested += 1;
            assert_eq!(d.statistic.to_bits(), last.best.to_bits(), "state {k}");
            differs |= blind.statistic().best.to_bits() != last.best.to_bits();
        } else {
            assert_eq!(d.statistic, 0.0, "state {k}");
        }
        applied.copy_from_slice(&cmd.allocation.unwrap().accounted);
    }
    assert!(tested > 20, "{tested} states tested");
    assert!(differs, "a detector without the speeds computes the same");
}

/// A wheel's axis is made unit on the board: axes three times as long fly the same commands
/// (to f32's rounding of the division), where the gyroscopic torque taken from raw axes would
/// be nine times as large.
#[test]
fn on_board_wheel_axes_are_made_unit() {
    let answer = |config: &Config| {
        let mut c = Cycle::new(config).unwrap();
        c.on_frame(&Frame::Hello(config.identity.clone()));
        match c.on_frame(&Frame::State(spinning(0, &[300.0, -200.0, 100.0, 50.0]))) {
            Some(Frame::Command(cmd)) => cmd.allocation.unwrap(),
            other => panic!("{other:?}"),
        }
    };
    let unit = answer(&wheeled(false));
    let mut long = wheeled(false);
    for w in &mut long.vehicle.as_mut().unwrap().wheels {
        w.axis = w.axis.map(|x| 3.0 * x);
    }
    let long = answer(&long);
    for (a, b) in unit.demand.iter().zip(&long.demand) {
        assert!(
            (a - b).abs() <= 1e-6 * (1.0 + a.abs()),
            "{:?} vs {:?}",
            unit.demand,
            long.demand
        );
    }
    for (a, b) in unit.u_cmd.iter().zip(&long.u_cmd) {
        assert!(
            (a - b).abs() <= 1e-6,
            "{:?} vs {:?}",
            unit.u_cmd,
            long.u_cmd
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// A wheeled configuration damaged anywhere (its wheels and momentum management among
    /// the bytes) is refused or builds a cycle whose answer to a spinning state is finite;
    /// never a panic.
    #[test]
    fn damaged_wheel_configurations_never_panic(flips in prop::collection::vec((0usize..600, any::<u8>()), 1..8)) {
        let mut buf = [0u8; MAX_CONFIG];
        let n = wheeled(true).to_bytes(&mut buf).unwrap();
        let mut bytes = buf[..n].to_vec();
        for (i, x) in flips {
            let i = i % bytes.len();
            bytes[i] ^= x;
        }
        if let Ok(mut c) = Cycle::from_bytes(&bytes) {
            let hello = c.hello();
            c.on_frame(&hello);
            if let Some(Frame::Command(cmd)) = c.on_frame(&Frame::State(spinning(0, &[100.0, -50.0, 10.0, 0.0]))) {
                let u = cmd.allocation.iter().flat_map(|a| a.u_cmd.iter());
                prop_assert!(cmd.tau.iter().chain(u).all(|x| x.is_finite()));
            }
        }
    }
}
