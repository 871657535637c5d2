//! Mutations shared by the targets: byte-level ones, and the special values a number field
//! is set to.

use crate::rng::Gen;
use eqtrack_controller::GroupKind;
use ipc_types::PROTOCOL_VERSION;
use link::wire::group_code;

/// Inputs are cut to this many bytes after mutation (chunk duplication can grow them).
pub(crate) const MAX_INPUT: usize = 16 * 1024;

/// The byte-level mutations.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ByteOp {
    /// Flip one bit.
    BitFlip,
    /// Overwrite one byte with a random or boundary value.
    Overwrite,
    /// Insert 1–4 random bytes.
    Insert,
    /// Delete 1–16 bytes.
    Delete,
    /// Cut the input at a random point.
    Truncate,
    /// Copy a chunk of the input to another place in it.
    DuplicateChunk,
    /// Prefix of this input, suffix of another corpus item.
    Splice,
}

impl ByteOp {
    /// Every byte-level mutation.
    pub(crate) const ALL: [ByteOp; 7] = [
        ByteOp::BitFlip,
        ByteOp::Overwrite,
        ByteOp::Insert,
        ByteOp::Delete,
        ByteOp::Truncate,
        ByteOp::DuplicateChunk,
        ByteOp::Splice,
    ];
}

/// Applies one byte-level mutation; `other` is the splice partner.
pub(crate) fn byte_op(g: &mut Gen, op: ByteOp, data: &mut Vec<u8>, other: &[u8]) {
    if data.is_empty() && !matches!(op, ByteOp::Insert | ByteOp::Splice) {
        data.push(g.u32() as u8);
        return;
    }
    match op {
        ByteOp::BitFlip => {
            let i = g.below(data.len());
            data[i] ^= 1 << g.below(8);
        }
        ByteOp::Overwrite => {
            let i = g.below(data.len());
            data[i] = if g.chance(1, 2) {
                g.u32() as u8
            } else {
                *g.pick(&[0x00, 0x01, 0x7f, 0x80, 0xff, b'\n', b'"', b'[', b'=', b'0'])
            };
        }
        ByteOp::Insert => {
            let i = g.below(data.len() + 1);
            let n = g.range(1, 4);
            let bytes = g.bytes(n);
            data.splice(i..i, bytes);
        }
        ByteOp::Delete => {
            let i = g.below(data.len());
            let n = g.range(1, 16).min(data.len() - i);
            data.drain(i..i + n);
        }
        ByteOp::Truncate => {
            let n = g.below(data.len());
            data.truncate(n);
        }
        ByteOp::DuplicateChunk => {
            let a = g.below(data.len());
            let n = g.range(1, 256).min(data.len() - a);
            let chunk = data[a..a + n].to_vec();
            let at = g.below(data.len() + 1);
            data.splice(at..at, chunk);
        }
        ByteOp::Splice => {
            let i = g.below(data.len() + 1);
            let j = g.below(other.len() + 1);
            data.truncate(i);
            data.extend_from_slice(&other[j..]);
        }
    }
    data.truncate(MAX_INPUT);
}

/// Special f64 values: NaNs (quiet, negative, signalling payload), infinities, zeros,
/// subnormals, extremes, and ordinary magnitudes.
pub(crate) const F64S: [f64; 22] = [
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

/// A special f64 value ([`F64S`]) or, one time in five, random bits.
pub(crate) fn f64_value(g: &mut Gen) -> f64 {
    if g.chance(1, 5) {
        f64::from_bits(g.u64())
    } else {
        *g.pick(&F64S)
    }
}

/// A u32 near a boundary (0, small, the protocol version ±1, the top bit, a group code), a
/// change of the `old` value, or random.
pub(crate) fn u32_value(g: &mut Gen, old: u32) -> u32 {
    match g.below(10) {
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
    }
}

/// A u64 near a boundary (0, the top bit, `i64::MAX`), a change of the `old` value, or random.
pub(crate) fn u64_value(g: &mut Gen, old: u64) -> u64 {
    match g.below(10) {
        0 => 0,
        1 => old.wrapping_add(1),
        2 => old.wrapping_sub(1),
        3 => u64::MAX,
        4 => 1 << 63,
        5 => old ^ (1 << g.below(64)),
        6 => i64::MAX as u64,
        7 => old.wrapping_add(g.below(1000) as u64),
        _ => g.u64(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Streams;

    #[test]
    fn byte_ops_handle_empty_and_tiny_inputs() {
        let s = Streams::new(1);
        for case in 0..2000 {
            let mut g = s.case(case);
            let n = g.below(3);
            let mut data = g.bytes(n);
            let op = *g.pick(&ByteOp::ALL);
            byte_op(&mut g, op, &mut data, b"xy");
            assert!(data.len() <= MAX_INPUT);
        }
    }
}
