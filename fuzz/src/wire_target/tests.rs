use super::layout::{COMMAND_FIELDS, STATE_FIELDS, read_u32, read_u64, width};
use super::mutation::WIRE_OPS;
use super::{Corpus, check};
use crate::rng::Streams;
use crate::{Outcome, Receiver, WireCase};
use eqtrack_controller::GroupKind;
use ipc_types::{COMMAND_BYTES, CommandMsg, STATE_BYTES, StateMsg, name_bytes};
use link::wire::group_code;

#[test]
fn field_tables_match_the_encoding() {
    let mut s = StateMsg::new(ipc_types::WireGroup::Se3);
    s.seq = 0x0102_0304_0506_0708;
    s.control_period = 0.25;
    s.v[5] = -7.5;
    s.plant_pid = 99;
    s.scenario = name_bytes("abc");
    let b = s.to_bytes();
    assert_eq!(b.len(), STATE_BYTES);
    assert_eq!(read_u32(&b, 4), Some(group_code(GroupKind::Se3)));
    assert_eq!(read_u64(&b, 8), Some(s.seq));
    assert_eq!(read_u64(&b, 24), Some(0.25f64.to_bits()));
    assert_eq!(read_u64(&b, 168 + 5 * 8), Some((-7.5f64).to_bits()));
    s.applied[2] = 1.25;
    let b2 = s.to_bytes();
    assert_eq!(read_u64(&b2, 216 + 2 * 8), Some(1.25f64.to_bits()));
    assert_eq!(read_u32(&b, 268), Some(99));
    assert_eq!(&b[280..283], b"abc");
    s.set_wheel_speeds(&[0.0, 0.0, -12.5]);
    let b3 = s.to_bytes();
    assert_eq!(read_u32(&b3, 312), Some(3));
    assert_eq!(read_u64(&b3, 320 + 2 * 8), Some((-12.5f64).to_bits()));
    let last = STATE_FIELDS[STATE_FIELDS.len() - 1];
    assert_eq!(last.1 + width(last.2) * last.3, STATE_BYTES);

    let mut c = CommandMsg::new(ipc_types::WireGroup::So3);
    c.tau[5] = 3.5;
    c.lyapunov = 2.0;
    c.mismatch = 6;
    c.expected_period = 0.125;
    c.observer[1] = -0.5;
    c.integral[4] = 0.75;
    c.previous_seq = 77;
    c.estimate_before[1] = 2.5;
    c.z_before[5] = -4.5;
    c.scenario = name_bytes("xyz");
    let b = c.to_bytes();
    assert_eq!(read_u64(&b, 40 + 5 * 8), Some(3.5f64.to_bits()));
    assert_eq!(read_u64(&b, 88), Some(2.0f64.to_bits()));
    assert_eq!(read_u64(&b, 96 + 8), Some((-0.5f64).to_bits()));
    assert_eq!(read_u64(&b, 144 + 4 * 8), Some(0.75f64.to_bits()));
    assert_eq!(read_u64(&b, 192), Some(77));
    assert_eq!(read_u64(&b, 200 + 8), Some(2.5f64.to_bits()));
    assert_eq!(read_u64(&b, 248 + 5 * 8), Some((-4.5f64).to_bits()));
    assert_eq!(read_u32(&b, 308), Some(6));
    assert_eq!(read_u64(&b, 320), Some(0.125f64.to_bits()));
    assert_eq!(&b[328..331], b"xyz");
    let last = COMMAND_FIELDS[COMMAND_FIELDS.len() - 1];
    assert_eq!(last.1 + width(last.2) * last.3, COMMAND_BYTES);
    for fs in [&STATE_FIELDS[..], &COMMAND_FIELDS[..]] {
        for w in fs.windows(2) {
            assert_eq!(w[0].1 + width(w[0].2) * w[0].3, w[1].1, "{}", w[1].0);
        }
    }
}

#[test]
fn the_seed_messages_are_accepted_by_their_receivers() {
    let c = Corpus::new();
    assert!(c.items.len() >= 20);
    // a vehicle's commands are among them
    assert!(c.items.iter().filter(|i| i.actuators == 8).count() >= 3);
    for item in &c.items {
        let case = WireCase {
            kind: item.kind,
            receiver: Receiver {
                group: item.group,
                last_seq: item.seq.checked_sub(1),
                period: Some(item.period),
                awaited: item.seq,
                actuators: item.actuators,
            },
            bytes: item.bytes.clone(),
        };
        assert_eq!(check(&case), Outcome::Accepted, "{case:?}");
    }
}

#[test]
fn every_op_runs() {
    let c = Corpus::new();
    let s = Streams::new(5);
    for (i, (op, _)) in WIRE_OPS.iter().cycle().take(3000).enumerate() {
        let mut g = s.case(i as u64);
        let base = g.pick(&c.items).clone();
        let mut case = WireCase {
            kind: base.kind,
            receiver: c.receiver_for(&mut g, &base),
            bytes: base.bytes.clone(),
        };
        c.wire_op(&mut g, *op, &mut case);
        let _ = check(&case);
    }
}
