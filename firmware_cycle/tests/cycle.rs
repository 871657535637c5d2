//! The firmware's cycle on the host: the configuration's bytes, the handshake, the answer to
//! a state (equal to the controller crate's own f32 law), and states it must drop; random
//! frames never panic it.

use controller::group::{MatrixLieGroup, So3};
use controller::{Controller, ControllerConfig, Law};
use firmware_cycle::{Axis, Config, ConfigError, Cycle, Dropped, MAX_CONFIG, Series, Term};
use heapless::Vec;
use nalgebra::{Matrix3, Vector3};
use proptest::prelude::*;
use serial_wire::{Frame, Hello, StateFrame};

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
                serial_wire::mismatch::SCENARIO | serial_wire::mismatch::PERIOD
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
        let s = StateFrame { seq, t: 0.0, q: v(&q), v: v(&vel), applied: v(&applied), samples: None };
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
