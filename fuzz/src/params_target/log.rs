//! `params.log`: a run's recorded changes as replay reads them back. Seeds: real files,
//! written with `recorder::create_params` and `append_param` from the runs' seed changes
//! (made with their tuners), and hand-written ones in the same format (empty, a header
//! alone, CRLF line ends, blank lines, numbers at the ends of the f64 range and with 17
//! digits, escaped strings). Mutations: the byte-level ones, lines deleted, duplicated,
//! swapped or taken from another file, a number or a string replaced, a change's fields
//! removed, added, duplicated or given another JSON type.

use super::{CHANGE_CYCLES, Run, Seed, changes, runs};
use crate::mutate::{ByteOp, MAX_INPUT, byte_op};
use crate::rng::Gen;
use crate::scenario_target::{join_lines, number_spans, random_number, split_lines, string_spans};
use crate::{Outcome, ParamsCase, ParamsKind, ParamsReceiver};
use recorder::ParamChange;
use recorder::params::{PARAMS_FILE, PARAMS_VERSION, parse_params};
use scenario::tuning::numbers;
use std::hint::black_box;
use std::sync::atomic::{AtomicU64, Ordering};

/// Changes of an accepted file that replay applies with the run's tuner, at most.
const REPLAYED: usize = 2;

/// The header line of a `params.log` (what `recorder::create_params` writes).
pub(super) fn header() -> String {
    format!("{{\"format\":\"eqtrack-params\",\"version\":{PARAMS_VERSION}}}")
}

/// The seed changes of `run`, as the plant records them: made with the run's tuner, each
/// with the cycle it took effect at, its time, and the numbers before and after.
pub(super) fn seed_changes(run: &Run) -> Vec<ParamChange> {
    let mut tuner = run.tuner.clone();
    changes(run.name)
        .iter()
        .zip(CHANGE_CYCLES)
        .map(|((key, value), cycle)| {
            let before = tuner.scenario().clone();
            let change = tuner.apply(key, value).expect("a seed change is accepted");
            ParamChange {
                cycle,
                t: cycle as f64 * before.control_period,
                key: change.key.to_owned(),
                value: change.value.clone(),
                previous: change.previous.clone(),
                numbers: numbers(&change.scenario, change.key),
                previous_numbers: numbers(&before, change.key),
            }
        })
        .collect()
}

/// `changes` written to a real `params.log` with the recorder (in a directory of its own
/// under the system's temporary directory, removed after), and read back as bytes.
fn recorded(changes: &[ParamChange]) -> Vec<u8> {
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let dir = std::env::temp_dir().join(format!(
        "eqtrack-fuzz-params-{}-{}",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&dir).expect("a temporary directory");
    recorder::create_params(&dir).expect("params.log starts");
    for c in changes {
        recorder::append_param(&dir, c).expect("a change is appended");
    }
    let bytes = std::fs::read(dir.join(PARAMS_FILE)).expect("params.log reads");
    let _ = std::fs::remove_dir_all(&dir);
    bytes
}

/// A hand-written change with odd but valid numbers and strings.
fn odd_change(cycle: u64, numbers: Vec<f64>) -> ParamChange {
    ParamChange {
        cycle,
        t: cycle as f64 * 0.01,
        key: "controller.kd".to_owned(),
        value: "[0.30000000000000004, 1e-300, 1.7976931348623157e308]".to_owned(),
        previous: "\"é\\n\\\"\"".to_owned(),
        numbers,
        previous_numbers: vec![0.5, -0.0],
    }
}

/// The seed files.
pub(super) struct Seeds {
    items: Vec<Seed<Vec<u8>>>,
}

impl Seeds {
    /// Each run's changes recorded (one and both), and hand-written files.
    pub(super) fn new() -> Seeds {
        let mut items = Vec::new();
        for (i, run) in runs().iter().enumerate() {
            let cs = seed_changes(run);
            items.push(Seed {
                run: i,
                input: recorded(&cs[..1]),
            });
            items.push(Seed {
                run: i,
                input: recorded(&cs),
            });
        }
        let line = |c: &ParamChange| serde_json::to_string(c).expect("a change serializes");
        let seed_changes = seed_changes(&runs()[0]);
        let odd = [
            odd_change(3, vec![0.1 + 0.2, 5e-324, f64::MAX, f64::MIN_POSITIVE]),
            odd_change(
                4,
                vec![1.234_567_890_123_456_7e-300, 9.999_999_999_999_999e307],
            ),
            odd_change(u64::MAX, vec![-1.0, 1e22, 1e23, 123_456_789.123_456_78]),
        ];
        let texts = [
            String::new(),
            format!("{}\n", header()),
            format!(
                "{}\r\n{}\r\n{}\r\n",
                header(),
                line(&seed_changes[0]),
                line(&seed_changes[1])
            ),
            format!(
                "\n{}\n\n  \n{}\n\n",
                header(),
                odd.iter().map(line).collect::<Vec<_>>().join("\n")
            ),
            format!("{} \n{}", header(), line(&odd[0])),
        ];
        items.extend(texts.into_iter().map(|t| Seed {
            run: 0,
            input: t.into_bytes(),
        }));
        Seeds { items }
    }

    /// The seed files' texts.
    #[cfg(test)]
    pub(super) fn texts(&self) -> Vec<Vec<u8>> {
        self.items.iter().map(|s| s.input.clone()).collect()
    }

    /// One case: a seed file with 1–8 mutations, read by replay of its run.
    pub(super) fn generate(&self, g: &mut Gen) -> ParamsCase {
        let seed = g.pick(&self.items);
        let mut text = seed.input.clone();
        for _ in 0..g.mutation_count() {
            let op = g.pick_weighted(&LOG_OPS);
            self.log_op(g, op, &mut text);
        }
        text.truncate(MAX_INPUT);
        ParamsCase {
            kind: ParamsKind::Log,
            receiver: ParamsReceiver {
                scenario: runs()[seed.run].name,
                seq: 0,
                fingerprint: 0,
            },
            bytes: text,
        }
    }

    /// Applies one mutation to a file's text.
    fn log_op(&self, g: &mut Gen, op: LogOp, text: &mut Vec<u8>) {
        match op {
            LogOp::Byte(b) => {
                let other = &g.pick(&self.items).input;
                byte_op(g, b, text, other);
            }
            LogOp::Line => {
                let mut lines = split_lines(text);
                let i = g.below(lines.len());
                match g.below(4) {
                    0 => {
                        lines.remove(i);
                    }
                    1 => {
                        let l = lines[i].clone();
                        lines.insert(i, l);
                    }
                    2 => {
                        let j = g.below(lines.len());
                        lines.swap(i, j);
                    }
                    _ => {
                        let other = split_lines(&g.pick(&self.items).input);
                        lines.insert(i, g.pick(&other).clone());
                    }
                }
                *text = join_lines(&lines);
            }
            LogOp::Number => {
                let spans = number_spans(text);
                if spans.is_empty() {
                    return;
                }
                let (a, b) = *g.pick(&spans);
                let new = match g.below(3) {
                    0 => (*g.pick(&JSON_NUMBERS)).to_owned(),
                    1 => random_number(g),
                    // 17 significant digits, anywhere in the range of f64
                    _ => format!(
                        "{}.{:016}e{}",
                        g.range(1, 9),
                        g.u64() % 10_000_000_000_000_000,
                        g.below(617) as i64 - 308
                    ),
                };
                text.splice(a..b, new.into_bytes());
            }
            LogOp::Str => {
                let spans = string_spans(text);
                if spans.is_empty() {
                    return;
                }
                let (a, b) = *g.pick(&spans);
                let new = *g.pick(&JSON_STRINGS);
                text.splice(a..b, new.bytes());
            }
            LogOp::Field => field_op(g, text),
        }
    }
}

/// The mutations of a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum LogOp {
    /// A byte-level mutation.
    Byte(ByteOp),
    /// A line deleted, duplicated, swapped with another, or taken from another file.
    Line,
    /// A number replaced: a JSON boundary, a special or random one, 17 digits.
    Number,
    /// The text of a string replaced.
    Str,
    /// A change's field removed, added, duplicated or given another JSON type.
    Field,
}

/// The mutations and their weights.
const LOG_OPS: [(LogOp, u32); 11] = [
    (LogOp::Byte(ByteOp::BitFlip), 4),
    (LogOp::Byte(ByteOp::Overwrite), 4),
    (LogOp::Byte(ByteOp::Insert), 2),
    (LogOp::Byte(ByteOp::Delete), 2),
    (LogOp::Byte(ByteOp::Truncate), 1),
    (LogOp::Byte(ByteOp::DuplicateChunk), 2),
    (LogOp::Byte(ByteOp::Splice), 2),
    (LogOp::Line, 8),
    (LogOp::Number, 16),
    (LogOp::Str, 6),
    (LogOp::Field, 10),
];

/// What replaces a number: JSON's boundaries and non-numbers, the ends of f64 and u64.
const JSON_NUMBERS: [&str; 26] = [
    "0",
    "-0",
    "-0.0",
    "1e400",
    "-1e400",
    "1e-400",
    "18446744073709551615",
    "18446744073709551616",
    "-1",
    "1.0",
    "1e2",
    "NaN",
    "Infinity",
    "null",
    "\"1\"",
    "[]",
    "01",
    "1.",
    ".5",
    "2.2250738585072011e-308",
    "4.9406564584124654e-324",
    "1.7976931348623157e308",
    "1.7976931348623159e308",
    "9007199254740993",
    "1.2345678901234567e-300",
    "0.1e1",
];

/// What replaces the text of a string: keys, values, escapes, odd characters.
const JSON_STRINGS: [&str; 14] = [
    "",
    "controller.kp",
    "kd",
    "duration",
    "0.8",
    "NaN",
    "[[1.0, 0.0], [0.0, 1.0]]",
    "\\ud800",
    "\\u0000",
    "\\x",
    "é",
    "\\\"",
    "cycle",
    "eqtrack-params",
];

/// A change's line as JSON, changed: a field removed, an unknown one added, one given
/// another JSON type or an array's length changed, or (as text) a field duplicated.
fn field_op(g: &mut Gen, text: &mut Vec<u8>) {
    let mut lines = split_lines(text);
    let candidates: Vec<usize> = (0..lines.len())
        .filter(|i| lines[*i].starts_with(b"{"))
        .collect();
    if candidates.is_empty() {
        return;
    }
    let i = *g.pick(&candidates);
    let Ok(serde_json::Value::Object(mut fields)) = serde_json::from_slice(&lines[i]) else {
        return;
    };
    let names: Vec<String> = fields.keys().cloned().collect();
    if names.is_empty() {
        return;
    }
    let name = g.pick(&names).clone();
    match g.below(5) {
        0 => {
            fields.remove(&name);
        }
        1 => {
            fields.insert("extra".to_owned(), serde_json::Value::from(1));
        }
        2 => {
            let value = match g.below(6) {
                0 => serde_json::Value::Null,
                1 => serde_json::Value::from("0.8"),
                2 => serde_json::Value::from(true),
                3 => serde_json::json!([1.0, [2.0]]),
                4 => serde_json::json!({ "cycle": 1 }),
                _ => serde_json::Value::from(-1),
            };
            fields.insert(name, value);
        }
        3 => {
            if let Some(serde_json::Value::Array(xs)) = fields.get_mut(&name) {
                if g.chance(1, 2) {
                    xs.pop();
                } else {
                    xs.push(serde_json::Value::from(g.below(10) as f64 / 4.0));
                }
            }
        }
        _ => {
            // as text: the field again before the closing brace
            let value = fields
                .get(&name)
                .map(ToString::to_string)
                .unwrap_or_default();
            let mut line = serde_json::Value::Object(fields).to_string();
            line.pop();
            line.push_str(&format!(",\"{name}\":{value}}}"));
            lines[i] = line.into_bytes();
            *text = join_lines(&lines);
            return;
        }
    }
    lines[i] = serde_json::Value::Object(fields).to_string().into_bytes();
    *text = join_lines(&lines);
}

/// The serde message classes of a refused line.
const JSON_CLASSES: [&str; 14] = [
    "missing field",
    "unknown field",
    "invalid type",
    "duplicate field",
    "EOF while parsing",
    "trailing characters",
    "number out of range",
    "control character",
    "invalid escape",
    "invalid unicode",
    "lone leading surrogate",
    "expected value",
    "key must be a string",
    "invalid value",
];

/// The report's name of a refused file: the header, its format, a change line (with the
/// JSON reader's class), or cycles that do not increase.
fn log_kind(why: &str) -> String {
    let class = JSON_CLASSES
        .iter()
        .find(|c| why.contains(*c))
        .copied()
        .unwrap_or("syntax");
    if why.starts_with("line 1: not a params.log header") {
        format!("header ({class})")
    } else if why.starts_with("line 1: format") {
        "format or version".to_owned()
    } else if why.contains("changes take effect at increasing cycles") {
        "cycles".to_owned()
    } else {
        format!("change line ({class})")
    }
}

/// Whether two lists of changes are the same, their numbers at most `ulps` apart (0: bit
/// for bit).
fn same_within(a: &[ParamChange], b: &[ParamChange], ulps: u64) -> bool {
    let near = |x: f64, y: f64| (x.to_bits() as i64).abs_diff(y.to_bits() as i64) <= ulps;
    let all_near = |xs: &[f64], ys: &[f64]| {
        xs.len() == ys.len() && xs.iter().zip(ys).all(|(x, y)| near(*x, *y))
    };
    a.len() == b.len()
        && a.iter().zip(b).all(|(x, y)| {
            x.cycle == y.cycle
                && near(x.t, y.t)
                && x.key == y.key
                && x.value == y.value
                && x.previous == y.previous
                && all_near(&x.numbers, &y.numbers)
                && all_near(&x.previous_numbers, &y.previous_numbers)
        })
}

/// The oracle: the file parsed (invalid UTF-8 replaced, as a lossy reader would); an
/// accepted file's cycles increase, and its changes re-serialized (the header and one
/// `serde_json` line each) parse back bit for bit; replay applies the first ones with the
/// run's tuner (refusals are replay's typed errors).
pub(super) fn check(run: &Run, bytes: &[u8]) -> Outcome {
    let text = String::from_utf8_lossy(bytes);
    let changes = match parse_params(&text) {
        Err(why) => return Outcome::Rejected(format!("parse_params: {}", log_kind(&why))),
        Ok(c) => c,
    };
    assert!(
        changes.windows(2).all(|w| w[0].cycle < w[1].cycle),
        "parse_params accepted cycles that do not increase"
    );
    let mut again = format!("{}\n", header());
    for c in &changes {
        again.push_str(&serde_json::to_string(c).expect("a parsed change serializes"));
        again.push('\n');
    }
    let back = parse_params(&again)
        .unwrap_or_else(|e| panic!("re-serialized changes are refused: {e}\n{again}"));
    // bit for bit (serde_json's float_roundtrip: replay compares the numbers exactly; this
    // target found them 2 ulp off without it)
    assert!(
        same_within(&back, &changes, 0),
        "re-serialized changes parse back otherwise:\n{changes:?}\n{back:?}"
    );
    let mut tuner = run.tuner.clone();
    for c in changes.iter().take(REPLAYED) {
        match tuner.apply(&c.key, &c.value) {
            Ok(change) => {
                black_box(numbers(&change.scenario, change.key));
            }
            Err(_) => break,
        }
    }
    Outcome::Accepted
}
