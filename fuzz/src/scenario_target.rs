//! The scenario target: TOML text through [`Scenario::from_toml`], and every accepted scenario
//! through what the processes do with it (fingerprint, step count, law overrides, the
//! controller, the reference generator and the plant body of its group, a few closed-loop
//! cycles).

use crate::Outcome;
use crate::mutate::{ByteOp, MAX_INPUT, byte_op};
use crate::rng::Gen;
use controller::group::OnGroup;
use controller::{Law, MatrixLieGroup, Quantity};
use scenario::{BUILTINS, Scenario, ScenarioError};

/// Closed-loop cycles run on an accepted scenario, at most.
const CYCLES: usize = 3;
/// RKMK4 substeps one accepted case may spend per integrator (plant, reference): a scenario
/// asking for more substeps per period runs fewer cycles (down to one law evaluation and no
/// step), so a case stays cheap whatever `plant_substeps` says.
const SUBSTEP_BUDGET: usize = 2_000;

/// Hand-written valid scenarios that reach the optional keys the built-ins leave out.
const EXTRA_SEEDS: [&str; 9] = [
    // the disturbance-rejection terms and the world and step disturbances
    include_str!("../../scenarios/reject_so3.toml"),
    include_str!("../../scenarios/reject_se3.toml"),
    // `[sensors]` and `[estimator]` on both groups, with either filter
    include_str!("../../scenarios/sensors_so3.toml"),
    include_str!("../../scenarios/sensors_se3.toml"),
    include_str!("../../scenarios/eqf_so3.toml"),
    include_str!("../../scenarios/eqf_se3.toml"),
    r#"name = "so3_everything"
group = "so3"
law = "gt"
duration = 1.0
control_period = 0.001
plant_substeps = 4
reference_substeps = 2

[plant]
inertia = [[2.0, 0.1, 0.0], [0.1, 1.5, 0.0], [0.0, 0.0, 1.0]]
torque_limit = [1.0, 2.0, 3.0]
disturbance = [0.01, -0.02, 0.0]

[controller]
inertia = [[2.1, 0.0, 0.0], [0.0, 1.4, 0.0], [0.0, 0.0, 1.1]]
kp = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]
kd = [[0.5, 0.1, 0.0], [0.1, 0.5, 0.0], [0.0, 0.0, 0.5]]

[initial]
rotation = [0.1, -0.2, 0.3]
velocity = [0.0, 1.0, -1.0]

[reference]
rotation = [0.0, 0.5, 0.0]
velocity = [0.1, 0.0, 0.0]
torque = [
  { offset = 0.1, terms = [ { amplitude = 1.0, frequency = 1.0 }, { amplitude = 0.5, frequency = 3.0, phase = 1.0 } ] },
  { terms = [] },
  { offset = -0.2 },
]
"#,
    r#"group = "se3"
law = "eqt"
duration = 0.5
control_period = 0.05

[plant]
inertia = [
  [1, 0, 0, 0, 0, 0],
  [0, 1, 0, 0, 0, 0],
  [0, 0, 1, 0, 0, 0],
  [0, 0, 0, 3, 0, 0],
  [0, 0, 0, 0, 3, 0],
  [0, 0, 0, 0, 0, 3],
]
torque_limit = 10.0
disturbance = [0.0, 0.0, 0.0, 0.1, 0.0, -9.81]

[controller]
kp = 2.0
kd = [
  [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
  [0.0, 1.0, 0.0, 0.0, 0.0, 0.0],
  [0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
  [0.0, 0.0, 0.0, 2.0, 0.0, 0.0],
  [0.0, 0.0, 0.0, 0.0, 2.0, 0.0],
  [0.0, 0.0, 0.0, 0.0, 0.0, 2.0],
]

[initial]
rotation = [0.0, 0.0, 0.0]
position = [1.0, 2.0, 3.0]
velocity = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]

[reference]
rotation = [0.1, 0.2, 0.3]
velocity = [0.0, 0.0, 0.1, 1.0, 0.0, 0.0]
"#,
    r#"group = "so3"
law = "asym"
duration = 0.1
control_period = 0.01
[plant]
inertia = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
[controller]
kp = 1
kd = 1
[initial]
rotation = [0.0, 0.0, 3.0]
velocity = [0.0, 0.0, 0.0]
[reference]
rotation = [0.0, 0.0, 0.0]
velocity = [0.0, 0.0, 0.0]
"#,
];

/// What replaces a number token.
pub(crate) const INTERESTING: [&str; 30] = [
    "nan",
    "inf",
    "-inf",
    "+inf",
    "0",
    "-0.0",
    "0.0",
    "1",
    "1e308",
    "1e309",
    "-1",
    "1e-320",
    "5e-324",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551616",
    "\"\"",
    "[]",
    "[[1]]",
    "true",
    "{}",
    "0x10",
    "1_000",
    "100000",
    "100001",
    "1e9",
    "1e-9",
    "3.141592653589793",
    "1.5",
    "07",
];

/// What replaces the text of a string token.
const STRINGS: [&str; 12] = [
    "so3",
    "se3",
    "eqt",
    "gt",
    "nog",
    "asym",
    "",
    "SO3",
    "x",
    "é",
    "\\u0000",
    "a name that is longer than thirty-two bytes",
];

/// Known keys and values for [`TomlOp::SetKey`].
const KEYS: [(&str, &[&str]); 22] = [
    ("path", &["\"stop\"", "\"through\"", "\"curvy\"", "3"]),
    (
        "disturbance_observer",
        &[
            "{ gain = 20.0 }",
            "{ gain = 0.0 }",
            "{ gain = 1e300, limit = 1e-300 }",
            "{ gain = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0], frame = \"world\" }",
            "{ gain = 5.0, frame = \"moon\" }",
            "{ gain = 1e-300, limit = [1.0, 1.0, 1.0] }",
        ],
    ),
    (
        "integral",
        &[
            "{ ki = 1.0, c = 5.0 }",
            "{ ki = 1e300, c = 1e300, limit = 1e-300 }",
            "{ ki = 1.0, c = 5.0, anti_windup = false }",
            "{ ki = -1.0, c = 5.0 }",
            "{ ki = [1.0, 1.0, 1.0, 1.0, 1.0, 1.0], c = 1.0, limit = 0.1 }",
        ],
    ),
    (
        "disturbance_world",
        &[
            "[0.0, 0.0, 0.0]",
            "[0.0, 0.0, 0.0, 0.5, 0.0, 0.0]",
            "[1e300, 0.0, 0.0]",
            "[nan, 0.0, 0.0]",
        ],
    ),
    (
        "disturbance_steps",
        &[
            "[{ t = 0.0, value = [0.1, 0.0, 0.0] }]",
            "[{ t = 0.5, value = [0.0, 0.0, 0.0, 0.0, 1.0, 0.0] }, { t = 0.6, value = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0] }]",
            "[{ t = 1.0, value = [1e308, 0.0, 0.0] }, { t = 0.5, value = [0.0, 0.0, 0.0] }]",
            "[{ t = -0.0, value = [] }]",
        ],
    ),
    ("group", &["\"se3\"", "\"so3\"", "\"SE3\"", "\"x\"", "3"]),
    (
        "law",
        &["\"gt\"", "\"nog\"", "\"asym\"", "\"eqt\"", "\"pd\""],
    ),
    (
        "plant_substeps",
        &["0", "1", "100000", "100001", "-1", "1.5", "3"],
    ),
    ("reference_substeps", &["0", "1", "100000", "-1", "2"]),
    (
        "duration",
        &["1e9", "20.0", "0.015", "1e-300", "0.3", "1e12"],
    ),
    ("control_period", &["0.01", "1e-12", "0.3", "0", "0.1"]),
    ("name", &["\"x\"", "\"\"", "\"é\"", "1"]),
    (
        "torque_limit",
        &[
            "5.0",
            "[1.0, 2.0, 3.0]",
            "[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]",
            "0",
            "-1.0",
            "[1.0, 0.0, 1.0]",
        ],
    ),
    (
        "disturbance",
        &[
            "[0.0, 0.0, 0.0]",
            "[0.1, 0.2, 0.3, 0.4, 0.5, 0.6]",
            "[]",
            "[1e300, 0.0, 0.0]",
        ],
    ),
    ("position", &["[1.0, 2.0, 3.0]", "[]", "[1e200, 0, 0]"]),
    (
        "inertia",
        &[
            "[[1.0]]",
            "[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]",
            "[[1, 0, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0], [0, 0, 1, 0, 0, 0], [0, 0, 0, 1, 0, 0], [0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 0, 1]]",
            "[[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]",
            "[[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]",
            "[[1e-300, 0.0, 0.0], [0.0, 1e-300, 0.0], [0.0, 0.0, 1e-300]]",
            "[[1e300, 0.0, 0.0], [0.0, 1e300, 0.0], [0.0, 0.0, 1e300]]",
        ],
    ),
    (
        "kp",
        &[
            "1.0",
            "0.0",
            "-1.0",
            "1e-300",
            "[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]",
            "[[1, 0, 0], [0, 1, 0], [0, 0, 1]]",
        ],
    ),
    (
        "kd",
        &[
            "1.0",
            "1e300",
            "[[1, 0, 0], [0, 1, 0], [0, 0, 1]]",
            "[[1, 0, 0], [0, 1, 0]]",
        ],
    ),
    (
        "rotation",
        &[
            "[0.0, 0.0, 0.0]",
            "[3.141592653589793, 0.0, 0.0]",
            "[1e10, 0.0, 0.0]",
            "[0.0, 0.0]",
        ],
    ),
    (
        "velocity",
        &[
            "[0.0, 0.0, 0.0]",
            "[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]",
            "[1e300, 0.0, 0.0]",
        ],
    ),
    (
        "torque",
        &[
            "[]",
            "[{ offset = 1.0 }, {}, {}]",
            "[{}, {}, {}, {}, {}, {}]",
            "[{ terms = [{ amplitude = 1, frequency = 1 }, { amplitude = 1, frequency = 1 }, { amplitude = 1, frequency = 1 }, { amplitude = 1, frequency = 1 }, { amplitude = 1, frequency = 1 }, { amplitude = 1, frequency = 1 }, { amplitude = 1, frequency = 1 }, { amplitude = 1, frequency = 1 }, { amplitude = 1, frequency = 1 }] }, {}, {}]",
            "[{ offset = 1e308, terms = [{ amplitude = 1e308, frequency = 1e308 }] }, {}, {}]",
        ],
    ),
    ("offset", &["0.0", "nan", "1e308"]),
];

/// Whole lines for [`TomlOp::InsertLine`].
const LINES: [&str; 12] = [
    "[[x]]",
    "[plant]",
    "[controller]",
    "[initial]",
    "[reference]",
    "[x]",
    "[reference.torque]",
    "unknown = 1",
    "group = \"se3\"",
    "law = \"gt\"",
    "plant_substeps = 0",
    "# comment",
];

/// The mutations of TOML text.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TomlOp {
    /// A byte-level mutation.
    Byte(ByteOp),
    /// Replace a number token by an interesting value or a random number.
    ReplaceNumber,
    /// Replace the text of a string.
    ReplaceString,
    /// Delete a line.
    DeleteLine,
    /// Duplicate a line.
    DuplicateLine,
    /// Swap two lines.
    SwapLines,
    /// Set a known key: replace its line if there is one, else insert it.
    SetKey,
    /// Insert a known line (a section header, a key) anywhere.
    InsertLine,
    /// Change a list's length (drop, duplicate or append an element, empty it).
    ListLength,
    /// The first lines of this text, the last lines of another corpus item.
    LineSplice,
}

const TOML_OPS: [(TomlOp, u32); 16] = [
    (TomlOp::Byte(ByteOp::BitFlip), 4),
    (TomlOp::Byte(ByteOp::Overwrite), 4),
    (TomlOp::Byte(ByteOp::Insert), 3),
    (TomlOp::Byte(ByteOp::Delete), 4),
    (TomlOp::Byte(ByteOp::Truncate), 2),
    (TomlOp::Byte(ByteOp::DuplicateChunk), 3),
    (TomlOp::Byte(ByteOp::Splice), 2),
    (TomlOp::ReplaceNumber, 22),
    (TomlOp::ReplaceString, 6),
    (TomlOp::DeleteLine, 6),
    (TomlOp::DuplicateLine, 4),
    (TomlOp::SwapLines, 3),
    (TomlOp::SetKey, 14),
    (TomlOp::InsertLine, 4),
    (TomlOp::ListLength, 14),
    (TomlOp::LineSplice, 2),
];

/// The seed corpus and the mutator of the scenario target.
pub(crate) struct Corpus {
    items: Vec<Vec<u8>>,
}

impl Corpus {
    /// The built-in scenarios and the extra seeds.
    pub(crate) fn new() -> Corpus {
        let items = BUILTINS
            .iter()
            .map(|(_, text)| *text)
            .chain(EXTRA_SEEDS)
            .map(|t| t.as_bytes().to_vec())
            .collect();
        Corpus { items }
    }

    /// One case: a corpus item with 1–8 mutations, or (5 %) a fully random input.
    pub(crate) fn generate(&self, g: &mut Gen) -> Vec<u8> {
        match g.below(100) {
            0..=1 => {
                let n = g.below(512);
                return g.bytes(n);
            }
            2..=4 => return token_soup(g),
            _ => {}
        }
        let mut data = g.pick(&self.items).clone();
        let weights: Vec<u32> = TOML_OPS.iter().map(|(_, w)| *w).collect();
        for _ in 0..g.mutation_count() {
            let op = TOML_OPS[g.weighted(&weights)].0;
            let other = g.pick(&self.items);
            toml_op(g, op, &mut data, other);
        }
        data.truncate(MAX_INPUT);
        data
    }
}

/// A random sequence of TOML-ish pieces.
fn token_soup(g: &mut Gen) -> Vec<u8> {
    const PIECES: [&str; 22] = [
        "group",
        "law",
        "inertia",
        "kp",
        "[plant]",
        "[controller]",
        "[initial]",
        "[reference]",
        " = ",
        "\n",
        "[",
        "]",
        ", ",
        "{",
        "}",
        "\"so3\"",
        "\"eqt\"",
        "1.0",
        "0",
        "nan",
        "[[",
        "torque",
    ];
    let mut out = Vec::new();
    for _ in 0..g.range(1, 80) {
        let piece = if g.chance(1, 4) {
            random_number(g)
        } else {
            (*g.pick(&PIECES)).to_owned()
        };
        out.extend_from_slice(piece.as_bytes());
    }
    out
}

/// A random numeric literal of varied magnitude and form.
pub(crate) fn random_number(g: &mut Gen) -> String {
    match g.below(6) {
        0 => format!("{}", g.below(15) as i64 - 2),
        1 => format!("{:.3}", (g.u64() % 20_000) as f64 / 1000.0 - 10.0),
        2 => format!("1e{}", g.below(661) as i64 - 330),
        3 => {
            let x = f64::from_bits(g.u64());
            if x.is_finite() {
                format!("{x:e}")
            } else {
                "0.5".to_owned()
            }
        }
        4 => format!("{}", g.u64() as i64),
        _ => format!("{}.{}", g.below(4), g.below(1000)),
    }
}

fn is_token_byte(b: u8) -> bool {
    b.is_ascii_alphanumeric() || matches!(b, b'_' | b'.' | b'+' | b'-')
}

/// The spans of number-like tokens (digits first, or a sign then a digit, `.`, `i` or `n`).
pub(crate) fn number_spans(data: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < data.len() {
        if !is_token_byte(data[i]) || (i > 0 && is_token_byte(data[i - 1])) {
            i += 1;
            continue;
        }
        let start = i;
        while i < data.len() && is_token_byte(data[i]) {
            i += 1;
        }
        let tok = &data[start..i];
        let numeric = tok[0].is_ascii_digit()
            || (matches!(tok[0], b'+' | b'-')
                && tok
                    .get(1)
                    .is_some_and(|b| b.is_ascii_digit() || matches!(b, b'.' | b'i' | b'n')))
            || tok == b"nan"
            || tok == b"inf";
        if numeric {
            spans.push((start, i));
        }
    }
    spans
}

/// The spans of the text of strings (between two quotes on one line).
fn string_spans(data: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut open = None;
    for (i, b) in data.iter().enumerate() {
        match (b, open) {
            (b'"', None) => open = Some(i + 1),
            (b'"', Some(s)) => {
                spans.push((s, i));
                open = None;
            }
            (b'\n', _) => open = None,
            _ => {}
        }
    }
    spans
}

pub(crate) fn split_lines(data: &[u8]) -> Vec<Vec<u8>> {
    data.split(|b| *b == b'\n').map(<[u8]>::to_vec).collect()
}

pub(crate) fn join_lines(lines: &[Vec<u8>]) -> Vec<u8> {
    lines.join(&b'\n')
}

/// The index of the bracket closing the list opened at `open`, brackets and braces nested.
fn matching_close(data: &[u8], open: usize) -> Option<usize> {
    let mut depth = 0usize;
    for (i, b) in data.iter().enumerate().skip(open) {
        match b {
            b'[' | b'{' => depth += 1,
            b']' | b'}' => {
                depth = depth.checked_sub(1)?;
                if depth == 0 {
                    return (*b == b']').then_some(i);
                }
            }
            _ => {}
        }
    }
    None
}

/// The top-level elements of a list's inside, trimmed, empty ones dropped.
fn list_elements(inside: &[u8]) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    let mut depth = 0i32;
    let mut start = 0;
    for (i, b) in inside.iter().enumerate() {
        match b {
            b'[' | b'{' => depth += 1,
            b']' | b'}' => depth -= 1,
            b',' if depth == 0 => {
                out.push(inside[start..i].trim_ascii().to_vec());
                start = i + 1;
            }
            _ => {}
        }
    }
    out.push(inside[start..].trim_ascii().to_vec());
    out.retain(|e| !e.is_empty());
    out
}

fn toml_op(g: &mut Gen, op: TomlOp, data: &mut Vec<u8>, other: &[u8]) {
    match op {
        TomlOp::Byte(b) => byte_op(g, b, data, other),
        TomlOp::ReplaceNumber => {
            let spans = number_spans(data);
            if spans.is_empty() {
                return byte_op(g, ByteOp::Overwrite, data, other);
            }
            let (s, e) = *g.pick(&spans);
            let new = if g.chance(1, 2) {
                (*g.pick(&INTERESTING)).to_owned()
            } else {
                random_number(g)
            };
            data.splice(s..e, new.into_bytes());
        }
        TomlOp::ReplaceString => {
            let spans = string_spans(data);
            if spans.is_empty() {
                return byte_op(g, ByteOp::Overwrite, data, other);
            }
            let (s, e) = *g.pick(&spans);
            data.splice(s..e, g.pick(&STRINGS).bytes());
        }
        TomlOp::DeleteLine | TomlOp::DuplicateLine | TomlOp::SwapLines => {
            let mut lines = split_lines(data);
            let i = g.below(lines.len());
            match op {
                TomlOp::DeleteLine => {
                    lines.remove(i);
                }
                TomlOp::DuplicateLine => {
                    let copy = lines[i].clone();
                    let at = g.below(lines.len() + 1);
                    lines.insert(at, copy);
                }
                _ => {
                    let j = g.below(lines.len());
                    lines.swap(i, j);
                }
            }
            *data = join_lines(&lines);
        }
        TomlOp::SetKey => {
            let (key, values) = g.pick(&KEYS);
            let line = format!("{key} = {}", g.pick(values)).into_bytes();
            let mut lines = split_lines(data);
            let holders: Vec<usize> = lines
                .iter()
                .enumerate()
                .filter(|(_, l)| {
                    l.trim_ascii_start()
                        .strip_prefix(key.as_bytes())
                        .is_some_and(|rest| rest.trim_ascii_start().starts_with(b"="))
                })
                .map(|(i, _)| i)
                .collect();
            if holders.is_empty() || g.chance(1, 10) {
                let at = g.below(lines.len() + 1);
                lines.insert(at, line);
            } else {
                let i = *g.pick(&holders);
                lines[i] = line;
            }
            *data = join_lines(&lines);
        }
        TomlOp::InsertLine => {
            let mut lines = split_lines(data);
            let at = g.below(lines.len() + 1);
            lines.insert(at, g.pick(&LINES).as_bytes().to_vec());
            *data = join_lines(&lines);
        }
        TomlOp::ListLength => {
            let opens: Vec<usize> = data
                .iter()
                .enumerate()
                .filter(|(_, b)| **b == b'[')
                .map(|(i, _)| i)
                .collect();
            if opens.is_empty() {
                return byte_op(g, ByteOp::Insert, data, other);
            }
            let open = *g.pick(&opens);
            let Some(close) = matching_close(data, open) else {
                return byte_op(g, ByteOp::Delete, data, other);
            };
            let mut elems = list_elements(&data[open + 1..close]);
            match g.below(5) {
                0 if !elems.is_empty() => {
                    let i = g.below(elems.len());
                    elems.remove(i);
                }
                1 if !elems.is_empty() => {
                    let i = g.below(elems.len());
                    let copy = elems[i].clone();
                    elems.insert(i, copy);
                }
                2 => elems.clear(),
                3 if elems.len() > 1 => elems.truncate(1),
                _ => elems.push(random_number(g).into_bytes()),
            }
            let mut list = b"[".to_vec();
            list.extend(elems.join(&b", "[..]));
            list.push(b']');
            data.splice(open..=close, list);
        }
        TomlOp::LineSplice => {
            let mut lines = split_lines(data);
            let theirs = split_lines(other);
            lines.truncate(g.below(lines.len() + 1));
            let from = g.below(theirs.len() + 1);
            lines.extend_from_slice(&theirs[from..]);
            *data = join_lines(&lines);
        }
    }
}

/// The report's name of a scenario error: the variant, and for `Invalid` the key (indices
/// shown as `*`); for `Parse` a coarse class of the parser's message.
fn scenario_error_kind(e: &ScenarioError) -> String {
    match e {
        ScenarioError::Io { .. } => "ScenarioError::Io".to_owned(),
        ScenarioError::Parse { message, .. } => {
            let class = [
                ("unknown field", "unknown field"),
                ("missing field", "missing field"),
                ("invalid type", "invalid type"),
                ("duplicate key", "duplicate key"),
                ("did not match any variant", "untagged: no variant matched"),
                ("invalid length", "invalid length"),
                ("invalid value", "invalid value"),
            ]
            .iter()
            .find(|(needle, _)| message.contains(needle))
            .map_or("syntax or value", |(_, class)| class);
            format!("ScenarioError::Parse ({class})")
        }
        ScenarioError::Invalid { key, .. } => {
            let mut k = String::with_capacity(key.len());
            let mut in_index = false;
            for c in key.chars() {
                match c {
                    '[' => {
                        in_index = true;
                        k.push_str("[*");
                    }
                    ']' => {
                        in_index = false;
                        k.push(']');
                    }
                    _ if in_index => {}
                    _ => k.push(c),
                }
            }
            format!("ScenarioError::Invalid ({k})")
        }
        ScenarioError::UnknownBuiltin(_) => "ScenarioError::UnknownBuiltin".to_owned(),
        ScenarioError::Waypoints { .. } => "ScenarioError::Waypoints".to_owned(),
    }
}

/// The report's name of a controller error: variant and quantity (no sizes or indices).
pub(crate) fn controller_error_kind(e: &controller::Error) -> String {
    use controller::Error as E;
    let q = |q: &Quantity| format!("{q:?}");
    match e {
        E::NonFinite(x) => format!("NonFinite({})", q(x)),
        E::NotSymmetric(x) => format!("NotSymmetric({})", q(x)),
        E::NotPositiveDefinite(x) => format!("NotPositiveDefinite({})", q(x)),
        E::NotPositive(x) => format!("NotPositive({})", q(x)),
        E::WrongShape { quantity, .. } => format!("WrongShape({})", q(quantity)),
        E::LawNotDefined { law, group } => format!("LawNotDefined({law:?}, {group:?})"),
        E::TooManyTerms { .. } => "TooManyTerms".to_owned(),
        E::NotIncreasing { .. } => "NotIncreasing".to_owned(),
        E::TooManySegments { .. } => "TooManySegments".to_owned(),
        E::NotAtRest { .. } => "NotAtRest".to_owned(),
        E::MissesWaypoint { .. } => "MissesWaypoint".to_owned(),
    }
}

/// `controller::Error` of one stage, as a rejection name.
fn stage(name: &str, e: controller::Error) -> String {
    format!("{name}: controller::Error::{}", controller_error_kind(&e))
}

/// What the processes do with an accepted scenario, on its group.
struct Exercise<'a>(&'a Scenario);

impl OnGroup for Exercise<'_> {
    type Output = Result<(), String>;

    fn run<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
        let s = self.0;
        let controller = s
            .controller::<G, N, M>()
            .map_err(|e| stage("controller()", e))?;
        let mut reference = s
            .reference_generator::<G, N, M>()
            .map_err(|e| stage("reference_generator()", e))?;
        let mut body = s
            .plant_body::<G, N, M>()
            .map_err(|e| stage("plant_body()", e))?;
        let _ = s
            .feedforward::<M>()
            .map_err(|e| stage("feedforward()", e))?;
        // the disturbance-rejection terms, fed with the torque applied, as the node runs them
        let mut terms = controller::Rejection::new(
            s.rejection_config::<M>(),
            controller.config().torque_limit.as_ref(),
        )
        .map_err(|e| stage("Rejection::new()", e))?;
        let mut applied = nalgebra::SVector::<f64, M>::zeros();
        let world = s.world_disturbance::<M>();
        let most = s.plant_substeps.max(s.reference_substeps).max(1);
        let cycles = (SUBSTEP_BUDGET / most).min(CYCLES);
        for k in 0..=cycles {
            let desired = reference.desired();
            let (q, v) = (*body.configuration(), body.velocity());
            let out = if s.rejection_config::<M>().any() {
                controller
                    .compute_rejecting(
                        &mut terms,
                        &q,
                        &v,
                        &desired,
                        &applied,
                        s.control_period,
                        true,
                    )
                    .map_err(|e| stage("compute_rejecting()", e))?
            } else {
                controller
                    .compute(&q, &v, &desired)
                    .map_err(|e| stage("compute()", e))?
            };
            assert!(
                out.torque
                    .iter()
                    .chain(&out.observer)
                    .chain(&out.integral)
                    .all(|x| x.is_finite()),
                "the controller returned a non-finite number: {:?} {:?} {:?}",
                out.torque.as_slice(),
                out.observer.as_slice(),
                out.integral.as_slice()
            );
            if k == cycles {
                break;
            }
            applied = out.torque;
            let total = out.torque + s.disturbance_at::<M>(k as u64);
            match &world {
                None => body.advance(&total, s.control_period, s.plant_substeps),
                Some(w) => body.advance_with_world(&total, w, s.control_period, s.plant_substeps),
            }
            reference.advance();
        }
        Ok(())
    }
}

/// Checks one scenario input (bytes: invalid UTF-8 is replaced, so the parser still runs).
pub(crate) fn check(input: &[u8]) -> Outcome {
    let text = String::from_utf8_lossy(input);
    let s = match Scenario::from_toml(&text, "fuzz input", "fuzz") {
        Ok(s) => s,
        Err(e) => return Outcome::Rejected(scenario_error_kind(&e)),
    };
    let fp = s.fingerprint();
    assert_ne!(fp, 0, "Scenario::fingerprint is documented never to be 0");
    assert_eq!(fp, s.clone().fingerprint(), "fingerprint not deterministic");
    std::hint::black_box(s.steps());
    for law in Law::ALL {
        let _ = std::hint::black_box(s.clone().with_law(law));
    }
    match s.group.dispatch(Exercise(&s)) {
        Ok(()) => Outcome::Accepted,
        Err(kind) => Outcome::Rejected(kind),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Streams;

    #[test]
    fn every_seed_is_accepted() {
        for item in &Corpus::new().items {
            assert_eq!(
                check(item),
                Outcome::Accepted,
                "{}",
                String::from_utf8_lossy(item)
            );
        }
    }

    #[test]
    fn number_tokens_are_found() {
        let spans = number_spans(b"a = [1.0, -2e-3, +inf, nan]\nse3 = x_1 # 7");
        let toks: Vec<&[u8]> = spans
            .iter()
            .map(|(s, e)| &b"a = [1.0, -2e-3, +inf, nan]\nse3 = x_1 # 7"[*s..*e])
            .collect();
        assert_eq!(
            toks,
            [&b"1.0"[..], b"-2e-3", b"+inf", b"nan", b"7"].to_vec()
        );
    }

    #[test]
    fn list_length_changes_keep_nested_lists_apart() {
        let data = b"x = [[1, 2], [3, 4]]";
        assert_eq!(matching_close(data, 4), Some(19));
        assert_eq!(
            list_elements(&data[5..19]),
            vec![b"[1, 2]".to_vec(), b"[3, 4]".to_vec()]
        );
        assert_eq!(matching_close(b"[1, {]", 0), None);
    }

    #[test]
    fn invalid_keys_are_named_without_indices() {
        let e = ScenarioError::Invalid {
            origin: String::new(),
            key: "reference.torque[2].terms[10]".to_owned(),
            message: String::new(),
        };
        assert_eq!(
            scenario_error_kind(&e),
            "ScenarioError::Invalid (reference.torque[*].terms[*])"
        );
    }

    #[test]
    fn every_op_runs_on_every_seed() {
        let c = Corpus::new();
        let s = Streams::new(3);
        for (case, (op, _)) in TOML_OPS.iter().cycle().take(2000).enumerate() {
            let mut g = s.case(case as u64);
            let mut data = g.pick(&c.items).clone();
            toml_op(&mut g, *op, &mut data, &c.items[0]);
            let _ = check(&data);
        }
    }
}
