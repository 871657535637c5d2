//! The wire target: bytes through [`StateMsg::from_bytes`] / [`CommandMsg::from_bytes`], then
//! the receiver's checks, the identity helpers, and what each side does with an accepted
//! message (the controller evaluates its law on a state, the plant integrates a command).

use crate::mutate::{ByteOp, MAX_INPUT, byte_op};
use crate::rng::Gen;
use crate::scenario_target::controller_error_kind;
use crate::{MsgKind, Outcome, Receiver, WireCase};
use controller::group::OnGroup;
use controller::{GroupKind, MatrixLieGroup};
use ipc_types::{
    COMMAND_BYTES, CommandMsg, DecodeError, Identity, PROTOCOL_VERSION, STATE_BYTES, StateMsg,
    check_command, check_state, flags, mismatch, name_bytes, name_str,
};
use link::wire::{group_code, group_kind, wire_group};
use scenario::Scenario;
use std::hint::black_box;
use std::sync::OnceLock;

/// The type of a field of an encoded message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Ty {
    U32,
    U64,
    F64,
    /// The NUL-padded name.
    Name,
}

/// `(name, byte offset, type, count)` of the fields of an encoded [`StateMsg`].
const STATE_FIELDS: [(&str, usize, Ty, usize); 13] = [
    ("version", 0, Ty::U32, 1),
    ("group", 4, Ty::U32, 1),
    ("seq", 8, Ty::U64, 1),
    ("t", 16, Ty::F64, 1),
    ("control_period", 24, Ty::F64, 1),
    ("stamp_ns", 32, Ty::U64, 1),
    ("q", 40, Ty::F64, 16),
    ("v", 168, Ty::F64, 6),
    ("applied", 216, Ty::F64, 6),
    ("flags", 264, Ty::U32, 1),
    ("plant_pid", 268, Ty::U32, 1),
    ("fingerprint", 272, Ty::U64, 1),
    ("scenario", 280, Ty::Name, 1),
];

/// The fields of an encoded [`CommandMsg`].
const COMMAND_FIELDS: [(&str, usize, Ty, usize); 24] = [
    ("version", 0, Ty::U32, 1),
    ("group", 4, Ty::U32, 1),
    ("seq", 8, Ty::U64, 1),
    ("state_received_ns", 16, Ty::U64, 1),
    ("stamp_ns", 24, Ty::U64, 1),
    ("compute_ns", 32, Ty::U64, 1),
    ("tau", 40, Ty::F64, 6),
    ("lyapunov", 88, Ty::F64, 1),
    ("observer", 96, Ty::F64, 6),
    ("integral", 144, Ty::F64, 6),
    ("previous_seq", 192, Ty::U64, 1),
    ("estimate_before", 200, Ty::F64, 6),
    ("z_before", 248, Ty::F64, 6),
    ("heap_allocations", 296, Ty::U64, 1),
    ("flags", 304, Ty::U32, 1),
    ("mismatch", 308, Ty::U32, 1),
    ("fingerprint", 312, Ty::U64, 1),
    ("expected_period", 320, Ty::F64, 1),
    ("scenario", 328, Ty::Name, 1),
    ("law", 360, Ty::U32, 1),
    ("plans_received", 364, Ty::U32, 1),
    ("plan_seq", 368, Ty::U64, 1),
    ("plan_pid", 376, Ty::U32, 1),
    ("reserved", 380, Ty::U32, 1),
];

fn fields(kind: MsgKind) -> &'static [(&'static str, usize, Ty, usize)] {
    match kind {
        MsgKind::State => &STATE_FIELDS,
        MsgKind::Command => &COMMAND_FIELDS,
    }
}

/// Special f64 values: NaNs (quiet, negative, signalling payload), infinities, zeros,
/// subnormals, extremes, and ordinary magnitudes.
const F64S: [f64; 22] = [
    f64::NAN,
    -f64::NAN,
    f64::from_bits(0x7ff0_0000_0000_0001),
    f64::INFINITY,
    f64::NEG_INFINITY,
    0.0,
    -0.0,
    f64::MIN_POSITIVE,
    5e-324,
    -5e-324,
    1e-310,
    f64::MAX,
    f64::MIN,
    1e308,
    -1e308,
    1e300,
    1.0,
    -1.0,
    0.01,
    0.001,
    1e-9,
    1e9,
];

/// One seed message.
#[derive(Debug, Clone)]
struct Item {
    kind: MsgKind,
    group: GroupKind,
    seq: u64,
    period: f64,
    bytes: Vec<u8>,
}

/// Realistic messages of one scenario: a few cycles of the closed loop, a shutdown state and
/// a refusal.
struct Realistic<'a>(&'a Scenario);

impl OnGroup for Realistic<'_> {
    type Output = Vec<Item>;

    fn run<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(self) -> Vec<Item> {
        let s = self.0;
        // The built-in scenarios are valid: the unit tests check it.
        let c = s.controller::<G, N, M>().expect("built-in controller");
        let mut r = s
            .reference_generator::<G, N, M>()
            .expect("built-in reference");
        let mut body = s.plant_body::<G, N, M>().expect("built-in plant");
        let name = name_bytes(&s.name);
        let fp = s.fingerprint();
        let item = |kind, seq, bytes: &[u8]| Item {
            kind,
            group: G::KIND,
            seq,
            period: s.control_period,
            bytes: bytes.to_vec(),
        };
        let mut out = Vec::new();
        let mut last = StateMsg::new(link::wire::wire_group(G::KIND));
        // the realistic commands carry both disturbance-rejection terms
        let mut terms =
            controller::Rejection::new(rejection::<M>(), c.config().torque_limit.as_ref())
                .expect("valid terms");
        let mut applied = nalgebra::SVector::<f64, M>::zeros();
        for k in 0..4u64 {
            let mut st = StateMsg::new(link::wire::wire_group(G::KIND));
            st.seq = k;
            st.t = k as f64 * s.control_period;
            st.control_period = s.control_period;
            st.stamp_ns = 5_000_000_000 + k * 10_000_000;
            st.set_state(body.configuration(), &body.velocity());
            st.set_applied(&applied);
            st.flags = if k % 2 == 0 { flags::WAKE_EVENT } else { 0 };
            st.plant_pid = 4242;
            st.fingerprint = fp;
            st.scenario = name;
            let law = c
                .compute_rejecting(
                    &mut terms,
                    body.configuration(),
                    &body.velocity(),
                    &r.desired(),
                    &applied,
                    s.control_period,
                    true,
                )
                .expect("built-in law");
            applied = law.torque;
            let mut cmd = CommandMsg::new(link::wire::wire_group(G::KIND));
            cmd.seq = k;
            cmd.state_received_ns = st.stamp_ns + 20_000;
            cmd.stamp_ns = st.stamp_ns + 55_000;
            cmd.compute_ns = 35_000;
            cmd.set_torque(&law.torque);
            cmd.lyapunov = law.lyapunov.total;
            for i in 0..M {
                cmd.observer[i] = law.observer[i];
                cmd.integral[i] = law.integral[i];
            }
            cmd.previous_seq = k.checked_sub(1).unwrap_or(ipc_types::NO_PREVIOUS);
            cmd.heap_allocations = k.saturating_sub(1);
            cmd.fingerprint = fp;
            cmd.scenario = name;
            out.push(item(MsgKind::State, k, &st.to_bytes()));
            out.push(item(MsgKind::Command, k, &cmd.to_bytes()));
            body.advance(&law.torque, s.control_period, s.plant_substeps);
            r.advance();
            last = st;
        }
        last.seq += 1;
        last.flags = flags::SHUTDOWN;
        out.push(item(MsgKind::State, last.seq, &last.to_bytes()));
        let me = Identity::new(wire_group(G::KIND), 0.001, fp ^ 1, &s.name);
        let refusal = CommandMsg::refusal(&me, 0, mismatch::PERIOD | mismatch::SCENARIO);
        out.push(item(MsgKind::Command, 0, &refusal.to_bytes()));
        out
    }
}

/// The seed corpus and the mutator of the wire target.
pub(crate) struct Corpus {
    items: Vec<Item>,
}

/// The mutations of an encoded message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum WireOp {
    /// A byte-level mutation.
    Byte(ByteOp),
    /// An f64 field (or array entry) set to a special value or random bits.
    F64Field,
    /// A u32/u64 field (version, group, seq, flags, …) set to a boundary or random value.
    IntField,
    /// The name field set to odd bytes (no NUL, invalid UTF-8, a cut character).
    NameField,
    /// A field copied from another corpus item of the same kind.
    CrossField,
    /// The length changed: ±1, 0, or huge.
    Length,
    /// The bytes handed to the other message type's decoder.
    KindSwap,
}

const WIRE_OPS: [(WireOp, u32); 13] = [
    (WireOp::Byte(ByteOp::BitFlip), 8),
    (WireOp::Byte(ByteOp::Overwrite), 6),
    (WireOp::Byte(ByteOp::Insert), 1),
    (WireOp::Byte(ByteOp::Delete), 1),
    (WireOp::Byte(ByteOp::Truncate), 1),
    (WireOp::Byte(ByteOp::DuplicateChunk), 1),
    (WireOp::Byte(ByteOp::Splice), 1),
    (WireOp::F64Field, 28),
    (WireOp::IntField, 24),
    (WireOp::NameField, 6),
    (WireOp::CrossField, 8),
    (WireOp::Length, 3),
    (WireOp::KindSwap, 1),
];

impl Corpus {
    /// Realistic states and commands of the three built-in scenarios (both groups).
    pub(crate) fn new() -> Corpus {
        let items = scenario::BUILTINS
            .iter()
            .flat_map(|(name, _)| {
                let s = Scenario::builtin(name).expect("built-in scenario");
                s.group.dispatch(Realistic(&s))
            })
            .collect();
        Corpus { items }
    }

    /// One case: a corpus item with 1–8 mutations and a receiver in a state that fits the
    /// item, or (4 %) random bytes for a random receiver.
    pub(crate) fn generate(&self, g: &mut Gen) -> WireCase {
        if g.below(100) < 4 {
            let kind = *g.pick(&[MsgKind::State, MsgKind::Command]);
            let len = match (g.below(5), kind) {
                (0, _) => g.below(400),
                (_, MsgKind::State) => STATE_BYTES,
                (_, MsgKind::Command) => COMMAND_BYTES,
            };
            let receiver = Receiver {
                group: *g.pick(&GroupKind::ALL),
                last_seq: g.chance(1, 2).then(|| g.u64()),
                period: g.chance(1, 2).then(|| f64::from_bits(g.u64())),
                awaited: g.u64(),
            };
            return WireCase {
                kind,
                receiver,
                bytes: g.bytes(len),
            };
        }
        let base = g.pick(&self.items);
        let receiver = self.receiver_for(g, base);
        let mut case = WireCase {
            kind: base.kind,
            receiver,
            bytes: base.bytes.clone(),
        };
        let weights: Vec<u32> = WIRE_OPS.iter().map(|(_, w)| *w).collect();
        for _ in 0..g.mutation_count() {
            let op = WIRE_OPS[g.weighted(&weights)].0;
            self.wire_op(g, op, &mut case);
        }
        case
    }

    /// A receiver expecting `base`, mostly: its group, the previous sequence number, its
    /// period or none; now and then one that expects something else.
    fn receiver_for(&self, g: &mut Gen, base: &Item) -> Receiver {
        let other = |k: GroupKind| match k {
            GroupKind::So3 => GroupKind::Se3,
            GroupKind::Se3 => GroupKind::So3,
        };
        Receiver {
            group: if g.chance(9, 10) {
                base.group
            } else {
                other(base.group)
            },
            last_seq: match g.below(20) {
                0..=11 => base.seq.checked_sub(1),
                12..=16 => None,
                17..=18 => Some(base.seq),
                _ => Some(g.u64()),
            },
            period: match g.below(20) {
                0..=9 => Some(base.period),
                10..=17 => None,
                _ => Some(*g.pick(&F64S)),
            },
            awaited: match g.below(10) {
                0..=7 => base.seq,
                8 => base.seq + 1,
                _ => g.u64(),
            },
        }
    }

    fn wire_op(&self, g: &mut Gen, op: WireOp, case: &mut WireCase) {
        let fs = fields(case.kind);
        let (_, offset, ty, count) = *g.pick(fs);
        let data = &mut case.bytes;
        match op {
            WireOp::Byte(ByteOp::Splice) => {
                // aligned: this message up to a point, another from the same point on (the
                // length is kept when the other is of the same type)
                let other = &g.pick(&self.items).bytes;
                let i = g.below(data.len().min(other.len()) + 1);
                data.truncate(i);
                data.extend_from_slice(&other[i..]);
            }
            WireOp::Byte(b) => {
                let other = &g.pick(&self.items).bytes;
                byte_op(g, b, data, other);
            }
            WireOp::F64Field | WireOp::IntField => {
                // the drawn field if its type fits the op, else the first one that does
                let want = |t: Ty| match op {
                    WireOp::F64Field => t == Ty::F64,
                    _ => matches!(t, Ty::U32 | Ty::U64),
                };
                let (offset, ty, count) = if want(ty) {
                    (offset, ty, count)
                } else {
                    let candidates: Vec<_> = fs.iter().filter(|f| want(f.2)).collect();
                    let f = g.pick(&candidates);
                    (f.1, f.2, f.3)
                };
                let at = offset + g.below(count) * width(ty);
                let value: Vec<u8> = match ty {
                    Ty::F64 => {
                        let x = if g.chance(1, 5) {
                            f64::from_bits(g.u64())
                        } else {
                            *g.pick(&F64S)
                        };
                        x.to_le_bytes().to_vec()
                    }
                    Ty::U32 => {
                        let old = read_u32(data, at).unwrap_or(0);
                        let x = match g.below(10) {
                            0 => 0,
                            1 => *g.pick(&[1, 2, 3, 4]),
                            2 => PROTOCOL_VERSION
                                .wrapping_add(g.below(3) as u32)
                                .wrapping_sub(1),
                            3 => u32::MAX,
                            4 => 0x8000_0000,
                            5 => old ^ (1 << g.below(32)),
                            6 => group_code(*g.pick(&GroupKind::ALL)),
                            7 => old.wrapping_add(1),
                            _ => g.u32(),
                        };
                        x.to_le_bytes().to_vec()
                    }
                    _ => {
                        let old = read_u64(data, at).unwrap_or(0);
                        let x = match g.below(10) {
                            0 => 0,
                            1 => old.wrapping_add(1),
                            2 => old.wrapping_sub(1),
                            3 => u64::MAX,
                            4 => 1 << 63,
                            5 => old ^ (1 << g.below(64)),
                            6 => i64::MAX as u64,
                            7 => old.wrapping_add(g.below(1000) as u64),
                            _ => g.u64(),
                        };
                        x.to_le_bytes().to_vec()
                    }
                };
                write_at(data, at, &value);
            }
            WireOp::NameField => {
                let at = fs.iter().find(|f| f.2 == Ty::Name).map_or(0, |f| f.1);
                let name: Vec<u8> = match g.below(6) {
                    0 => vec![b'a'; 32],
                    1 => vec![0xff; 32],
                    2 => {
                        // a two-byte character cut at the end of the field
                        let mut v = vec![b'x'; 31];
                        v.push(0xc3);
                        v
                    }
                    3 => b"\0hidden after a NUL".to_vec(),
                    4 => "é".repeat(16).into_bytes(),
                    _ => g.bytes(32),
                };
                write_at(data, at, &name);
            }
            WireOp::CrossField => {
                let donors: Vec<&Item> =
                    self.items.iter().filter(|i| i.kind == case.kind).collect();
                let donor = g.pick(&donors);
                let at = offset + g.below(count) * width(ty);
                let end = (at + width(ty)).min(donor.bytes.len());
                if at < end {
                    write_at(data, at, &donor.bytes[at..end]);
                }
            }
            WireOp::Length => match g.below(20) {
                0..=8 => data.push(g.u32() as u8),
                9..=17 => {
                    data.pop();
                }
                18 => data.clear(),
                _ => {
                    let n = g.range(MAX_INPUT, 1 << 20);
                    data.resize(n, 0xa5);
                }
            },
            WireOp::KindSwap => {
                case.kind = match case.kind {
                    MsgKind::State => MsgKind::Command,
                    MsgKind::Command => MsgKind::State,
                }
            }
        }
    }
}

fn width(ty: Ty) -> usize {
    match ty {
        Ty::U32 => 4,
        Ty::U64 | Ty::F64 => 8,
        Ty::Name => ipc_types::NAME_BYTES,
    }
}

fn read_u32(data: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(data.get(at..at + 4)?.try_into().ok()?))
}

fn read_u64(data: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(data.get(at..at + 8)?.try_into().ok()?))
}

/// Writes `value` at `at`, as much of it as fits in `data` (an already shortened message
/// stays short).
fn write_at(data: &mut [u8], at: usize, value: &[u8]) {
    if at < data.len() {
        let end = (at + value.len()).min(data.len());
        data[at..end].copy_from_slice(&value[..end - at]);
    }
}

/// What the checks compare against: the two sides of a seed and an se3_circle run.
struct Context {
    so3: Scenario,
    se3: Scenario,
    identities: Vec<Identity>,
}

fn context() -> &'static Context {
    static CONTEXT: OnceLock<Context> = OnceLock::new();
    CONTEXT.get_or_init(|| {
        let so3 = Scenario::builtin("seed").expect("built-in scenario");
        let se3 = Scenario::builtin("se3_circle").expect("built-in scenario");
        let identities = vec![
            Identity::new(ipc_types::WireGroup::So3, 0.0, so3.fingerprint(), &so3.name),
            Identity::new(
                ipc_types::WireGroup::So3,
                0.01,
                so3.fingerprint(),
                &so3.name,
            ),
            Identity::new(ipc_types::WireGroup::Se3, 0.0, se3.fingerprint(), &se3.name),
            Identity::new(ipc_types::WireGroup::Se3, 0.01, 0, ""),
        ];
        Context {
            so3,
            se3,
            identities,
        }
    })
}

impl Context {
    fn scenario(&self, group: GroupKind) -> &Scenario {
        match group {
            GroupKind::So3 => &self.so3,
            GroupKind::Se3 => &self.se3,
        }
    }
}

/// The controller's side of an accepted state: its reference built with the state's period
/// (as `controller_node` does on the first state), stepped once, and the law evaluated at the
/// state's configuration and velocity.
struct LawOnState<'a> {
    scenario: &'a Scenario,
    msg: &'a StateMsg,
}

impl OnGroup for LawOnState<'_> {
    type Output = Result<(), String>;

    fn run<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
        let stage = |name: &str, e: controller::Error| {
            format!("{name}: controller::Error::{}", controller_error_kind(&e))
        };
        let mut s = self.scenario.clone();
        s.control_period = self.msg.control_period;
        let c = s
            .controller::<G, N, M>()
            .map_err(|e| stage("controller()", e))?;
        let mut r = s
            .reference_generator::<G, N, M>()
            .map_err(|e| stage("reference_generator()", e))?;
        r.advance();
        let (q, v) = (self.msg.configuration::<N>(), self.msg.velocity::<M>());
        let out = c
            .compute(&q, &v, &r.desired())
            .map_err(|e| stage("compute()", e))?;
        assert!(
            out.torque.iter().all(|x| x.is_finite()),
            "Controller::compute returned a non-finite torque {:?}",
            out.torque.as_slice()
        );
        // with both disturbance-rejection terms: the state twice (anchor, then update) with
        // the torque it says was applied
        let mut terms =
            controller::Rejection::new(rejection::<M>(), c.config().torque_limit.as_ref())
                .map_err(|e| stage("Rejection::new()", e))?;
        let applied = self.msg.applied_torque::<M>();
        for _ in 0..2 {
            let out = c
                .compute_rejecting(
                    &mut terms,
                    &q,
                    &v,
                    &r.desired(),
                    &applied,
                    s.control_period,
                    true,
                )
                .map_err(|e| stage("compute_rejecting()", e))?;
            assert!(
                out.torque
                    .iter()
                    .chain(&out.observer)
                    .chain(&out.integral)
                    .all(|x| x.is_finite()),
                "Controller::compute_rejecting returned a non-finite number: {:?} {:?} {:?}",
                out.torque.as_slice(),
                out.observer.as_slice(),
                out.integral.as_slice()
            );
        }
        Ok(())
    }
}

/// Both disturbance-rejection terms, as a scenario would give them (observer in the world
/// frame, so the rotation enters; the integral clamped).
fn rejection<const M: usize>() -> controller::RejectionConfig<f64, M> {
    controller::RejectionConfig {
        observer: Some(controller::ObserverConfig {
            gain: nalgebra::SVector::repeat(20.0),
            limit: Some(nalgebra::SVector::repeat(5.0)),
            frame: controller::Frame::World,
        }),
        integral: Some(controller::IntegralConfig {
            ki: nalgebra::SVector::repeat(1.0),
            c: nalgebra::SVector::repeat(5.0),
            limit: Some(nalgebra::SVector::repeat(0.5)),
            anti_windup: true,
        }),
    }
}

/// The plant's side of an accepted command: the torque (plus the disturbance) applied for one
/// period, and the next state encoded.
struct PlantOnCommand<'a> {
    scenario: &'a Scenario,
    msg: &'a CommandMsg,
}

impl OnGroup for PlantOnCommand<'_> {
    type Output = ();

    fn run<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(self) {
        let s = self.scenario;
        let mut body = s.plant_body::<G, N, M>().expect("built-in plant");
        let applied = self.msg.torque::<M>() + s.disturbance_vector::<M>();
        body.advance(&applied, s.control_period, s.plant_substeps);
        let mut next = StateMsg::new(link::wire::wire_group(G::KIND));
        next.seq = self.msg.seq.wrapping_add(1);
        next.set_state(body.configuration(), &body.velocity());
        black_box(next.to_bytes());
    }
}

/// The identity helpers on one identity: `Display`, `mismatch` both ways, the name's round
/// trip through [`name_bytes`].
fn exercise_identity(id: &Identity) {
    black_box(id.to_string());
    for other in &context().identities {
        black_box(other.mismatch(id));
        black_box(id.mismatch(other));
    }
    black_box(id.mismatch(id));
    black_box(group_kind(id.group));
    let name = name_str(&id.scenario);
    assert_eq!(
        name_str(&name_bytes(name)),
        name,
        "name_str(name_bytes(name_str(x))) != name_str(x)"
    );
}

fn decode_kind(e: &DecodeError) -> &'static str {
    match e {
        DecodeError::Length { .. } => "DecodeError::Length",
    }
}

/// Checks one wire case.
pub(crate) fn check(case: &WireCase) -> Outcome {
    let r = &case.receiver;
    let ctx = context();
    match case.kind {
        MsgKind::State => {
            let msg = match StateMsg::from_bytes(&case.bytes) {
                Ok(m) => m,
                Err(e) => {
                    return Outcome::Rejected(format!("StateMsg::from_bytes: {}", decode_kind(&e)));
                }
            };
            assert_eq!(
                &msg.to_bytes()[..],
                &case.bytes[..],
                "StateMsg: decoding then encoding changed the bytes"
            );
            black_box(msg.configuration::<3>());
            black_box(msg.configuration::<4>());
            black_box(msg.velocity::<3>());
            black_box(msg.velocity::<6>());
            exercise_identity(&msg.identity());
            let seqs = [
                None,
                Some(0),
                Some(msg.seq.wrapping_sub(1)),
                Some(msg.seq),
                Some(u64::MAX),
            ];
            let periods = [None, Some(0.01), Some(msg.control_period), Some(f64::NAN)];
            for g in GroupKind::ALL {
                for last in seqs {
                    for p in periods {
                        let verdict = check_state(&msg, wire_group(g), last, p);
                        if verdict.is_ok() {
                            assert_eq!(msg.version, PROTOCOL_VERSION);
                            assert_eq!(group_kind(msg.group), Some(g));
                            assert!(last.is_none_or(|l| msg.seq > l));
                        }
                        let _ = black_box(verdict);
                    }
                }
            }
            match check_state(&msg, wire_group(r.group), r.last_seq, r.period) {
                Err(k) => Outcome::Rejected(format!("check_state: Invalid::{k:?}")),
                Ok(()) => {
                    let law = LawOnState {
                        scenario: ctx.scenario(r.group),
                        msg: &msg,
                    };
                    match r.group.dispatch(law) {
                        Ok(()) => Outcome::Accepted,
                        Err(kind) => Outcome::Rejected(kind),
                    }
                }
            }
        }
        MsgKind::Command => {
            let msg = match CommandMsg::from_bytes(&case.bytes) {
                Ok(m) => m,
                Err(e) => {
                    return Outcome::Rejected(format!(
                        "CommandMsg::from_bytes: {}",
                        decode_kind(&e)
                    ));
                }
            };
            assert_eq!(
                &msg.to_bytes()[..],
                &case.bytes[..],
                "CommandMsg: decoding then encoding changed the bytes"
            );
            black_box(msg.torque::<3>());
            black_box(msg.torque::<6>());
            let id = msg.identity();
            exercise_identity(&id);
            let refusal = CommandMsg::refusal(&id, msg.seq, msg.mismatch);
            assert_eq!(
                CommandMsg::from_bytes(&refusal.to_bytes()).map(|c| c.to_bytes()),
                Ok(refusal.to_bytes()),
                "refusal round trip"
            );
            for g in GroupKind::ALL {
                for awaited in [0, msg.seq, msg.seq.wrapping_add(1), u64::MAX] {
                    let verdict = check_command(&msg, wire_group(g), awaited);
                    if verdict.is_ok() {
                        assert_eq!(msg.seq, awaited);
                        assert_eq!(group_kind(msg.group), Some(g));
                    }
                    let _ = black_box(verdict);
                }
            }
            match check_command(&msg, wire_group(r.group), r.awaited) {
                Err(k) => Outcome::Rejected(format!("check_command: Invalid::{k:?}")),
                Ok(()) => {
                    r.group.dispatch(PlantOnCommand {
                        scenario: ctx.scenario(r.group),
                        msg: &msg,
                    });
                    Outcome::Accepted
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Streams;

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
        for item in &c.items {
            let case = WireCase {
                kind: item.kind,
                receiver: Receiver {
                    group: item.group,
                    last_seq: item.seq.checked_sub(1),
                    period: Some(item.period),
                    awaited: item.seq,
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
}
