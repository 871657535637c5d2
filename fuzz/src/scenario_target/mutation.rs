//! The case generator of the scenario target: a seed with 1–8 mutations (byte-level, or
//! aware of TOML's tokens, lines, keys and lists), or a fully random input.

use super::Corpus;
use super::tables::{INTERESTING, KEYS, LINES, STRINGS};
use super::text::{
    join_lines, list_elements, matching_close, number_spans, split_lines, string_spans,
};
use crate::mutate::{ByteOp, MAX_INPUT, byte_op};
use crate::rng::Gen;

/// The mutations of TOML text.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum TomlOp {
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

/// The mutations and their weights.
pub(super) const TOML_OPS: [(TomlOp, u32); 16] = [
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

impl Corpus {
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
        for _ in 0..g.mutation_count() {
            let op = g.pick_weighted(&TOML_OPS);
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

/// Applies one mutation to `data`; `other` is another corpus item, for the splices.
pub(super) fn toml_op(g: &mut Gen, op: TomlOp, data: &mut Vec<u8>, other: &[u8]) {
    match op {
        TomlOp::Byte(b) => byte_op(g, b, data, other),
        TomlOp::ReplaceNumber => replace_number(g, data, other),
        TomlOp::ReplaceString => replace_string(g, data, other),
        TomlOp::DeleteLine | TomlOp::DuplicateLine | TomlOp::SwapLines => edit_lines(g, op, data),
        TomlOp::SetKey => set_key(g, data),
        TomlOp::InsertLine => insert_line(g, data),
        TomlOp::ListLength => change_list_length(g, data, other),
        TomlOp::LineSplice => splice_lines(g, data, other),
    }
}

/// A number token replaced by an interesting value or a random number (no number: a byte
/// overwritten).
fn replace_number(g: &mut Gen, data: &mut Vec<u8>, other: &[u8]) {
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

/// The text of a string replaced by one of [`STRINGS`] (no string: a byte overwritten).
fn replace_string(g: &mut Gen, data: &mut Vec<u8>, other: &[u8]) {
    let spans = string_spans(data);
    if spans.is_empty() {
        return byte_op(g, ByteOp::Overwrite, data, other);
    }
    let (s, e) = *g.pick(&spans);
    data.splice(s..e, g.pick(&STRINGS).bytes());
}

/// A line deleted, duplicated (the copy inserted anywhere) or swapped with another, as `op`
/// says.
fn edit_lines(g: &mut Gen, op: TomlOp, data: &mut Vec<u8>) {
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

/// A known key set to one of its values: a line holding the key replaced, or (none, or one
/// time in ten) the line inserted anywhere.
fn set_key(g: &mut Gen, data: &mut Vec<u8>) {
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

/// One of [`LINES`] inserted anywhere.
fn insert_line(g: &mut Gen, data: &mut Vec<u8>) {
    let mut lines = split_lines(data);
    let at = g.below(lines.len() + 1);
    lines.insert(at, g.pick(&LINES).as_bytes().to_vec());
    *data = join_lines(&lines);
}

/// A list's elements changed (one dropped or duplicated, all or all but one dropped, a number
/// appended) and the list rewritten; no list: a byte inserted, an unclosed one: a byte deleted.
fn change_list_length(g: &mut Gen, data: &mut Vec<u8>, other: &[u8]) {
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

/// The first lines of `data` (a random number of them), then the last lines of `other`.
fn splice_lines(g: &mut Gen, data: &mut Vec<u8>, other: &[u8]) {
    let mut lines = split_lines(data);
    let theirs = split_lines(other);
    lines.truncate(g.below(lines.len() + 1));
    let from = g.below(theirs.len() + 1);
    lines.extend_from_slice(&theirs[from..]);
    *data = join_lines(&lines);
}
