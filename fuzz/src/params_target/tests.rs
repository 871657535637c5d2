use super::{Corpus, board, check, log, request, runs};
use crate::rng::Streams;
use crate::{Outcome, ParamsCase, ParamsKind, ParamsReceiver};
use ipc_types::{ParamMsg, ParamRequest, WireGroup, param_op};

fn receiver(scenario: &'static str, seq: u64, fingerprint: u64) -> ParamsReceiver {
    ParamsReceiver {
        scenario,
        seq,
        fingerprint,
    }
}

#[test]
fn encodings_have_the_structs_sizes_and_round_trip() {
    assert_eq!(board::BOARD_BYTES, core::mem::size_of::<ParamMsg>());
    assert_eq!(request::REQUEST_BYTES, core::mem::size_of::<ParamRequest>());
    let s = &runs()[1].scenario;
    let mut b = ParamMsg::new(WireGroup::Se3, 0x0102_0304, super::gains(s, 3));
    b.stamp_ns = 77;
    b.previous.c[5] = -2.5;
    let bytes = board::encode(&b);
    assert_eq!(bytes.len(), board::BOARD_BYTES);
    assert_eq!(board::decode(&bytes), Some(b));
    assert_eq!(&bytes[24..32], &0x0102_0304u64.to_le_bytes());
    // `current` at 32 and `previous` at 600, as docs/wire.md lays them out
    assert_eq!(&bytes[32..40], &3u64.to_le_bytes());
    assert_eq!(&bytes[600..608], &3u64.to_le_bytes());
    assert_eq!(board::decode(&bytes[1..]), None);
    let r = ParamRequest {
        op: param_op::SET,
        key: ipc_types::padded_bytes("kd"),
        value: ipc_types::padded_bytes("0.8"),
        ..ParamRequest::default()
    };
    let bytes = request::encode(&r);
    assert_eq!(request::decode(&bytes), Some(r));
    assert_eq!(&bytes[8..10], b"kd");
    assert_eq!(&bytes[72..75], b"0.8");
}

#[test]
fn the_header_is_the_recorders() {
    let text = String::from_utf8(
        Corpus::new()
            .logs_for_test()
            .first()
            .expect("a recorded seed")
            .clone(),
    )
    .unwrap();
    assert_eq!(text.lines().next(), Some(log::header().as_str()));
}

#[test]
fn the_seeds_are_accepted_by_their_receivers() {
    // boards: each seed board, for its run's controller, at a state of each set
    for run in runs().iter().take(super::BOARD_RUNS) {
        let s = &run.scenario;
        let first = ParamMsg::new(
            link::wire::wire_group(s.group),
            s.fingerprint(),
            super::gains(s, 0),
        );
        for seq in [0, 5, 150] {
            let case = ParamsCase {
                kind: ParamsKind::Board,
                receiver: receiver(run.name, seq, s.fingerprint()),
                bytes: board::encode(&first),
            };
            assert_eq!(check(&case), Outcome::Accepted, "{}", run.name);
        }
    }
    // every seed change of every run, recorded, reads back
    for run in runs() {
        let changes = log::seed_changes(run);
        assert_eq!(changes.len(), 2);
        let mut text = format!("{}\n", log::header());
        for c in &changes {
            text.push_str(&serde_json::to_string(c).unwrap());
            text.push('\n');
        }
        let case = ParamsCase {
            kind: ParamsKind::Log,
            receiver: receiver(run.name, 0, 0),
            bytes: text.into_bytes(),
        };
        assert_eq!(check(&case), Outcome::Accepted, "{}", run.name);
    }
    // requests: get and set of a gain the run has
    for (run, key, value) in [
        ("seed", "kd", "0.8"),
        ("se3_circle", "controller.kp", "2.0"),
        ("reject_so3", "controller.disturbance_observer.gain", "25.0"),
        (
            "reject_so3_integral",
            "controller.integral.c",
            "[4.0, 5.0, 6.0]",
        ),
        ("sensors_so3", "estimator.kp", "2.0"),
    ] {
        for op in [param_op::GET, param_op::SET] {
            let r = ParamRequest {
                op,
                key: ipc_types::padded_bytes(key),
                value: ipc_types::padded_bytes(value),
                ..ParamRequest::default()
            };
            let case = ParamsCase {
                kind: ParamsKind::Request,
                receiver: receiver(run, 0, 0),
                bytes: request::encode(&r),
            };
            assert_eq!(
                check(&case),
                Outcome::Accepted,
                "{run} {op} {key} = {value}"
            );
        }
    }
}

#[test]
fn a_refused_board_names_its_reason() {
    let run = &runs()[0];
    let s = &run.scenario;
    let mut b = ParamMsg::new(WireGroup::So3, s.fingerprint(), super::gains(s, 0));
    b.current.kd[4] = -1.0;
    let case = |b: &ParamMsg, fp: u64| ParamsCase {
        kind: ParamsKind::Board,
        receiver: receiver("seed", 3, fp),
        bytes: board::encode(b),
    };
    assert_eq!(
        check(&case(&b, s.fingerprint())),
        Outcome::Rejected(
            "Responder::retune: eqtrack_controller::Error::NotPositiveDefinite(DampingGain)"
                .to_owned()
        )
    );
    assert_eq!(
        check(&case(&b, 1)),
        Outcome::Rejected("ParamMsg::gains_for: ParamInvalid::Fingerprint".to_owned())
    );
}

#[test]
fn generated_cases_of_every_kind_are_checked() {
    let c = Corpus::new();
    let s = Streams::new(3);
    let mut kinds = [0usize; 3];
    for i in 0..600 {
        let case = c.generate(&mut s.case(i));
        kinds[case.kind as usize] += 1;
        let _ = check(&case);
    }
    assert!(kinds.iter().all(|n| *n > 100), "{kinds:?}");
}

impl Corpus {
    /// The recorded seed files' texts.
    fn logs_for_test(&self) -> Vec<Vec<u8>> {
        self.logs.texts()
    }
}
