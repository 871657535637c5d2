//! The `param` service's requests: a [`ParamRequest`] as the plant's parameter thread reads
//! it, checked against the run's scenario. Seeds: for each run, a `get` of every tunable key
//! (full and short), and a `set` of every key the run has to its value in force and to a
//! scaled value of the right shape. Mutations: the key set to another (tunable, another
//! scenario key, odd text, invalid UTF-8, no NUL), the value set to a number, a special
//! value, an array or matrix of the right or a wrong shape, odd TOML or garbage, a number
//! in it replaced; the version and the operation; bytes of the encoding.

use super::board::Retuned;
use super::{Run, Seed, gains, runs};
use crate::mutate::{ByteOp, byte_op, u32_value};
use crate::rng::Gen;
use crate::scenario_target::{INTERESTING, number_spans, parse_class, random_number};
use crate::{Outcome, ParamsCase, ParamsKind, ParamsReceiver};
use eqtrack_controller::group::OnGroup;
use eqtrack_controller::{BuiltinGroup, GroupKind};
use ipc_types::params::{PARAM_KEY_BYTES, PARAM_TEXT_BYTES, PARAM_VALUE_BYTES};
use ipc_types::{PROTOCOL_VERSION, ParamRequest, padded_bytes, padded_str, param_op};
use link::params::{Answer, read_request, response};
use scenario::Scenario;
use scenario::tuning::{Acts, Change, TUNABLE, numbers, resolve};
use std::hint::black_box;

/// Bytes of an encoded [`ParamRequest`]: version, operation, key, value.
pub(super) const REQUEST_BYTES: usize = 8 + PARAM_KEY_BYTES + PARAM_VALUE_BYTES;

/// A request's bytes: its fields in order, little-endian.
pub(super) fn encode(r: &ParamRequest) -> Vec<u8> {
    let mut out = Vec::with_capacity(REQUEST_BYTES);
    out.extend_from_slice(&r.version.to_le_bytes());
    out.extend_from_slice(&r.op.to_le_bytes());
    out.extend_from_slice(&r.key);
    out.extend_from_slice(&r.value);
    out
}

/// The request of `bytes` (`None`: not [`REQUEST_BYTES`] long).
pub(super) fn decode(bytes: &[u8]) -> Option<ParamRequest> {
    if bytes.len() != REQUEST_BYTES {
        return None;
    }
    let u32_at = |i: usize| u32::from_le_bytes(bytes[i..i + 4].try_into().expect("4 bytes"));
    Some(ParamRequest {
        version: u32_at(0),
        op: u32_at(4),
        key: bytes[8..8 + PARAM_KEY_BYTES].try_into().expect("the key"),
        value: bytes[8 + PARAM_KEY_BYTES..].try_into().expect("the value"),
    })
}

/// A request of `op` on `key` with `value`.
fn request(op: u32, key: &str, value: &str) -> ParamRequest {
    ParamRequest {
        op,
        key: padded_bytes(key),
        value: padded_bytes(value),
        ..ParamRequest::default()
    }
}

/// Numbers as TOML text: a matrix of `rows` rows, or a list (one row), or one number.
fn toml_text(xs: &[f64], rows: usize) -> String {
    let list = |xs: &[f64]| {
        let items: Vec<String> = xs.iter().map(|x| format!("{x:?}")).collect();
        format!("[{}]", items.join(", "))
    };
    match (xs.len(), rows) {
        (1, _) => format!("{:?}", xs[0]),
        (_, 0 | 1) => list(xs),
        (n, r) => {
            let rows: Vec<String> = xs.chunks(n.div_ceil(r)).map(list).collect();
            format!("[{}]", rows.join(", "))
        }
    }
}

/// The rows of the matrix a tunable key holds (1: a list or a number).
fn rows_of(key: &str, n: usize) -> usize {
    if key == "controller.kp" || key == "controller.kd" {
        (n as f64).sqrt().round() as usize
    } else {
        1
    }
}

/// The seed requests.
pub(super) struct Seeds {
    items: Vec<Seed<ParamRequest>>,
}

impl Seeds {
    /// For each run: `get` of every tunable key and short name; `set` of each key it has to
    /// the value in force, to 1.5 times it (same shape) and, for the gains, to 2.5.
    pub(super) fn new() -> Seeds {
        let mut items = Vec::new();
        for (i, run) in runs().iter().enumerate() {
            let mut push = |op: u32, key: &str, value: &str| {
                items.push(Seed {
                    run: i,
                    input: request(op, key, value),
                });
            };
            for (key, short) in TUNABLE {
                push(param_op::GET, key, "");
                if let Some(short) = short {
                    push(param_op::GET, short, "");
                }
                let Ok((_, now)) = run.tuner.get(key) else {
                    continue;
                };
                let xs = numbers(&run.scenario, key);
                let scaled: Vec<f64> = xs.iter().map(|x| 1.5 * x).collect();
                push(param_op::SET, key, &now);
                push(
                    param_op::SET,
                    key,
                    &toml_text(&scaled, rows_of(key, xs.len())),
                );
                push(param_op::SET, short.unwrap_or(key), "2.5");
            }
        }
        Seeds { items }
    }

    /// One case: a seed request with 1–8 mutations, read by the plant of its run.
    pub(super) fn generate(&self, g: &mut Gen) -> ParamsCase {
        let seed = g.pick(&self.items);
        let mut r = seed.input;
        for _ in 0..g.mutation_count() {
            let op = g.pick_weighted(&REQUEST_OPS);
            self.request_op(g, op, &mut r, seed.run);
        }
        ParamsCase {
            kind: ParamsKind::Request,
            receiver: ParamsReceiver {
                scenario: runs()[seed.run].name,
                seq: 0,
                fingerprint: 0,
            },
            bytes: encode(&r),
        }
    }

    /// Applies one mutation to `r`, a request for run `run`.
    fn request_op(&self, g: &mut Gen, op: RequestOp, r: &mut ParamRequest, run: usize) {
        match op {
            RequestOp::Key => {
                let key: &&str = g.pick(&KEYS);
                r.key = padded_bytes(key);
            }
            RequestOp::KeyBytes => odd_bytes(g, &mut r.key),
            RequestOp::Value => r.value = padded_bytes(&value_text(g, &runs()[run])),
            RequestOp::ValueBytes => odd_bytes(g, &mut r.value),
            RequestOp::ValueNumber => {
                let text = padded_str(&r.value).to_owned();
                let spans = number_spans(text.as_bytes());
                if spans.is_empty() {
                    r.value = padded_bytes(&value_text(g, &runs()[run]));
                } else {
                    let (a, b) = *g.pick(&spans);
                    let new = if g.chance(1, 2) {
                        (*g.pick(&INTERESTING)).to_owned()
                    } else {
                        random_number(g)
                    };
                    r.value = padded_bytes(&format!("{}{new}{}", &text[..a], &text[b..]));
                }
            }
            RequestOp::Op => {
                r.op = match g.below(4) {
                    0 => param_op::GET,
                    1 => param_op::SET,
                    _ => u32_value(g, r.op),
                }
            }
            RequestOp::Version => r.version = u32_value(g, r.version),
            RequestOp::Byte(b) => {
                let mut bytes = encode(r);
                let other = encode(&g.pick(&self.items).input);
                byte_op(g, b, &mut bytes, &other);
                bytes.resize(REQUEST_BYTES, 0);
                *r = decode(&bytes).expect("resized to a whole request");
            }
        }
    }
}

/// The mutations of a request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RequestOp {
    /// The key set to one of [`KEYS`].
    Key,
    /// The key's bytes made odd (no NUL, invalid UTF-8, a cut character, a hidden tail).
    KeyBytes,
    /// The value set to a generated text ([`value_text`]).
    Value,
    /// The value's bytes made odd.
    ValueBytes,
    /// A number in the value replaced (by a special or a random one).
    ValueNumber,
    /// The operation: get, set, or a boundary or random value.
    Op,
    /// The version: a boundary or random value.
    Version,
    /// A byte-level mutation of the encoding (the length restored).
    Byte(ByteOp),
}

/// The mutations and their weights.
const REQUEST_OPS: [(RequestOp, u32); 14] = [
    (RequestOp::Key, 16),
    (RequestOp::KeyBytes, 3),
    (RequestOp::Value, 30),
    (RequestOp::ValueBytes, 3),
    (RequestOp::ValueNumber, 16),
    (RequestOp::Op, 5),
    (RequestOp::Version, 3),
    (RequestOp::Byte(ByteOp::BitFlip), 2),
    (RequestOp::Byte(ByteOp::Overwrite), 2),
    (RequestOp::Byte(ByteOp::Insert), 1),
    (RequestOp::Byte(ByteOp::Delete), 1),
    (RequestOp::Byte(ByteOp::Truncate), 1),
    (RequestOp::Byte(ByteOp::DuplicateChunk), 1),
    (RequestOp::Byte(ByteOp::Splice), 1),
];

/// What a request's key is set to: the tunable keys and short names (twice: they are the
/// interesting ones), other scenario keys and tables, and odd keys.
const KEYS: [&str; 50] = [
    "controller.kp",
    "controller.kd",
    "controller.disturbance_observer.gain",
    "controller.integral.ki",
    "controller.integral.c",
    "estimator.kp",
    "estimator.ki",
    "kp",
    "kd",
    "controller.kp",
    "controller.kd",
    "controller.disturbance_observer.gain",
    "controller.integral.ki",
    "controller.integral.c",
    "estimator.kp",
    "estimator.ki",
    "kp",
    "kd",
    "duration",
    "control_period",
    "name",
    "group",
    "law",
    "plant_substeps",
    "plant.inertia",
    "plant.disturbance",
    "initial.velocity",
    "reference.rotation",
    "controller.law",
    "controller.torque_limit",
    "controller.disturbance_observer",
    "controller.disturbance_observer.frame",
    "controller.integral",
    "controller.integral.limit",
    "estimator.kind",
    "sensors.seed",
    "controller",
    "plant",
    "",
    ".",
    "..",
    "kd.",
    ".kd",
    "controller..kd",
    "controller.kd.x",
    "controller.kp.kp",
    "KD",
    " kd",
    "controller.\"kd\"",
    "a.b.c.d.e.f.g.h.i.j.k.l.m.n.o.p.q.r.s.t.u.v.w.x.y.z.a.b.c.d.e",
];

/// Odd values: TOML that is not a number list, text around a number, garbage.
const ODD_VALUES: [&str; 30] = [
    "",
    " ",
    "[]",
    "[[]]",
    "[[1.0], [2.0, 3.0]]",
    "[[[1.0]]]",
    "[1.0, \"a\"]",
    "\"0.8\"",
    "'0.8'",
    "true",
    "{ gain = 1.0 }",
    "1979-05-27",
    "0.8 0.9",
    "1,2",
    "= 1",
    "[",
    "]",
    "0.8 # a comment",
    "0.8\nduration = 1.0",
    "[1.0,\n2.0,\n3.0]",
    "[1.0, 2.0, 3.0,]",
    "0x10",
    "0o7",
    "1_000",
    "+1.5",
    ".5",
    "5.",
    "infinity",
    "-nan",
    "[nan, inf, -inf]",
];

/// A value's text: a special number, a random one, a matrix or list of a random or the
/// run's shape, odd TOML, garbage, or the key's numbers in force scaled (right shape).
fn value_text(g: &mut Gen, run: &Run) -> String {
    let (n, m) = match run.scenario.group {
        GroupKind::So3 | GroupKind::Se2 => (3, 3),
        GroupKind::Se3 => (4, 6),
    };
    match g.below(10) {
        0 => (*g.pick(&INTERESTING)).to_owned(),
        1 => random_number(g),
        2 => (*g.pick(&ODD_VALUES)).to_owned(),
        3 | 4 => {
            let dim = if g.chance(3, 4) {
                *g.pick(&[n, m])
            } else {
                g.range(1, 7)
            };
            let cols = if g.chance(4, 5) { dim } else { g.range(1, 7) };
            let xs = entries(g, dim, cols);
            toml_text(&xs, dim)
        }
        5 => {
            let len = *g.pick(&[1, 2, 3, 4, 6, 7, m]);
            let xs: Vec<f64> = (0..len).map(|_| entry(g)).collect();
            toml_text(&xs, 1)
        }
        6 => {
            let len = g.below(40);
            String::from_utf8_lossy(&g.bytes(len)).into_owned()
        }
        _ => {
            let (key, _) = *g.pick(&TUNABLE);
            let xs = numbers(&run.scenario, key);
            let f = *g.pick(&[1.5, 0.5, 2.0, 10.0, 1e-3, -1.0, 0.0, 1e300, 1e-300]);
            let scaled: Vec<f64> = xs.iter().map(|x| f * x).collect();
            if scaled.is_empty() {
                format!("{f:?}")
            } else {
                toml_text(&scaled, rows_of(key, scaled.len()))
            }
        }
    }
}

/// One entry of a generated list: a plausible positive gain mostly, else anything.
fn entry(g: &mut Gen) -> f64 {
    match g.below(6) {
        0..=2 => 0.1 + (g.u64() % 5000) as f64 / 1000.0,
        3 => *g.pick(&[0.0, -1.0, 1e300, 1e-300, 5e-324, f64::NAN, f64::INFINITY]),
        _ => (g.u64() % 20_000) as f64 / 1000.0 - 10.0,
    }
}

/// A `rows` × `cols` matrix row-major: the identity times a gain, a symmetric matrix, or
/// any entries.
fn entries(g: &mut Gen, rows: usize, cols: usize) -> Vec<f64> {
    let kind = g.below(3);
    let d = entry(g);
    let mut xs = vec![0.0; rows * cols];
    for i in 0..rows {
        for j in 0..cols {
            xs[i * cols + j] = match kind {
                0 if i == j => d,
                0 => 0.0,
                1 if j < i => xs[j * cols + i],
                _ => entry(g),
            };
        }
    }
    xs
}

/// Odd bytes at the front of a fixed field: no NUL at all, invalid UTF-8, a character cut
/// at the end of the field, a NUL hiding a tail, random bytes.
fn odd_bytes<const L: usize>(g: &mut Gen, field: &mut [u8; L]) {
    match g.below(5) {
        0 => field.fill(b'k'),
        1 => {
            let i = g.below(L);
            field[i] = *g.pick(&[0xff, 0xc3, 0x80, 0xed, 0xf4]);
        }
        2 => {
            // a two-byte character whose second byte falls off the field
            field.fill(b'1');
            field[L - 1] = 0xc3;
        }
        3 => {
            let tail = b"\0kp = 1.0";
            let at = g.below(L - tail.len());
            field[at..at + tail.len()].copy_from_slice(tail);
        }
        _ => {
            let n = g.range(1, L);
            field[..n].copy_from_slice(&g.bytes(n));
        }
    }
}

/// The report's name of a request `read_request` refuses.
fn read_kind(why: &str) -> &'static str {
    [
        ("request of protocol", "Version"),
        ("unknown operation", "Operation"),
        ("key is not UTF-8", "KeyNotUtf8"),
        ("value is not UTF-8", "ValueNotUtf8"),
    ]
    .iter()
    .find(|(needle, _)| why.contains(needle))
    .map_or("Other", |(_, k)| k)
}

/// The tuner's refusals with a message of their own.
const TUNER_REFUSALS: [(&str, &str); 6] = [
    ("neither a number nor a TOML value", "ValueUnreadable"),
    ("cannot change while the pair runs", "NotTunable"),
    (
        "a running pair can retune a term it started with",
        "TermAbsent",
    ),
    ("changes more than a gain", "MoreThanAGain"),
    ("is not a table", "NotATable"),
    ("an empty key", "EmptyKey"),
];

/// The report's name of a refusal of the tuner: its own refusals by name, the scenario's by
/// the tunable key it names (or "another key") and the reader's class (or `Invalid`).
pub(super) fn tuner_kind(why: &str) -> String {
    if let Some((_, k)) = TUNER_REFUSALS.iter().find(|(n, _)| why.contains(n)) {
        return (*k).to_owned();
    }
    let class = parse_class(why)
        .or_else(|| why.contains("TOML parse error").then_some("syntax"))
        .unwrap_or("Invalid");
    let key = why
        .strip_prefix("key `")
        .and_then(|rest| rest.split('`').next())
        .and_then(resolve)
        .unwrap_or("another key");
    format!("scenario ({key}): {class}")
}

/// The answer's wire form: its text cut at a character boundary, a prefix of the text.
fn check_answer(ok: bool, text: &str) {
    let wire = response(&Answer {
        ok,
        cycle: 7,
        text: text.to_owned(),
    });
    let back = padded_str(&wire.text);
    assert!(
        text.starts_with(back),
        "the answer's wire text is not a prefix of its text: {back:?} / {text:?}"
    );
    if text.len() <= PARAM_TEXT_BYTES && !text.contains('\0') {
        assert_eq!(back, text, "an answer that fits is cut");
    }
    assert_eq!(wire.ok, u32::from(ok));
}

/// The oracle: the request read; a get answered and its value, set again, changes nothing;
/// a set checked, an accepted change verified ([`verify_change`]).
pub(super) fn check(run: &Run, bytes: &[u8]) -> Outcome {
    let Some(req) = decode(bytes) else {
        return Outcome::Rejected("ParamRequest: not a whole request".to_owned());
    };
    let asked = match read_request(&req) {
        Err(why) => {
            check_answer(false, &why);
            return Outcome::Rejected(format!("read_request: {}", read_kind(&why)));
        }
        Ok(a) => a,
    };
    assert_eq!(req.version, PROTOCOL_VERSION);
    assert!(asked.op == param_op::GET || asked.op == param_op::SET);
    assert!(asked.key.len() <= PARAM_KEY_BYTES && !asked.key.contains('\0'));
    assert!(asked.value.len() <= PARAM_VALUE_BYTES && !asked.value.contains('\0'));
    if asked.op == param_op::GET {
        return match run.tuner.get(&asked.key) {
            Err(why) => {
                check_answer(false, &why);
                Outcome::Rejected(format!("Tuner::get: {}", tuner_kind(&why)))
            }
            Ok((key, now)) => {
                check_answer(true, &now);
                assert_eq!(resolve(&asked.key), Some(key), "get answered another key");
                let same = run.tuner.check(key, &now).unwrap_or_else(|e| {
                    panic!("setting {key} to its value in force `{now}` is refused: {e}")
                });
                assert!(
                    &same.scenario == run.tuner.scenario(),
                    "setting {key} to its value in force `{now}` changes the scenario"
                );
                Outcome::Accepted
            }
        };
    }
    match run.tuner.check(&asked.key, &asked.value) {
        Err(why) => {
            check_answer(false, &why);
            Outcome::Rejected(format!("Tuner::check: {}", tuner_kind(&why)))
        }
        Ok(change) => {
            check_answer(true, &change.value);
            verify_change(run, &asked.key, &change)
        }
    }
}

/// An accepted change: its key is the one asked for; its scenario resolves the key to
/// non-empty finite numbers, has a fingerprint, builds its controller and terms; the running
/// pair takes it (the run's responder retunes to its gains and answers a state, or the
/// run's estimator takes its gains); committed, it is in force, and setting it again is
/// accepted and changes nothing.
fn verify_change(run: &Run, name: &str, change: &Change) -> Outcome {
    assert_eq!(resolve(name), Some(change.key), "a change of another key");
    let xs = numbers(&change.scenario, change.key);
    assert!(
        !xs.is_empty() && xs.iter().all(|x| x.is_finite()),
        "{} = {}: the numbers {xs:?}",
        change.key,
        change.value
    );
    assert_ne!(change.scenario.fingerprint(), 0, "a zero fingerprint");
    change.scenario.group.dispatch(Builds(&change.scenario));
    let taken = match change.acts() {
        Acts::Controller => {
            let g = gains(&change.scenario, 0);
            let outcome = run.scenario.group.dispatch(Retuned {
                s: &run.scenario,
                gains: &g,
                seq: 0,
            });
            if let Outcome::Rejected(k) = &outcome {
                assert!(
                    !k.starts_with("Responder::retune"),
                    "{} = {}: the tuner accepts gains the running controller refuses ({k})",
                    change.key,
                    change.value
                );
            }
            outcome
        }
        Acts::Estimator => {
            let s = &run.scenario;
            let e = plant::estimation::Estimation::new(s, s.control_period, &[])
                .expect("the run's estimator");
            if let Some(mut e) = e {
                let est = &change.scenario.estimator;
                if let Err(why) = e.retune(est.kp, est.ki) {
                    panic!(
                        "{} = {}: the tuner accepts gains the running estimator refuses ({why})",
                        change.key, change.value
                    );
                }
            }
            Outcome::Accepted
        }
    };
    let previous = run.tuner.get(change.key).expect("the key is in force").1;
    assert_eq!(change.previous, previous, "the change's previous value");
    let mut t = run.tuner.clone();
    t.commit(change).expect("a checked change commits");
    assert!(
        t.scenario() == &change.scenario,
        "committed, the change's scenario is not in force"
    );
    let in_force = t.get(change.key).expect("in force").1;
    let again = t
        .check(change.key, &change.value)
        .expect("a change in force, set again, is accepted");
    assert!(
        again.scenario == change.scenario,
        "a change in force, set again, changes the scenario"
    );
    black_box(&again);
    // the value in force reads as the change said (this target found `1_000` in force as
    // `1000.0` when commit read the text again)
    assert!(
        in_force == change.value,
        "committed, {} reads `{in_force}`, the change said `{}`",
        change.key,
        change.value
    );
    match taken {
        Outcome::Accepted => Outcome::Accepted,
        Outcome::Rejected(k) => Outcome::Rejected(format!("change: {k}")),
    }
}

/// An accepted change's scenario builds its controller and its responder.
struct Builds<'a>(&'a Scenario);

impl OnGroup for Builds<'_> {
    type Output = ();

    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) {
        let s = self.0;
        let c = s
            .controller::<G, N, M>()
            .expect("an accepted change's scenario builds its controller");
        control_cycle::Responder::new(c, s.rejection_config())
            .expect("an accepted change's scenario builds its terms");
    }
}
