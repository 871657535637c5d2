//! Byte-level mutations shared by both targets.

use crate::rng::Gen;

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
