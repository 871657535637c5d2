//! The case generator of the wire target: a seed message with 1–8 mutations (byte-level, or
//! aware of the encoding's fields) for a receiver that mostly expects it, or random bytes.

use super::layout::{Ty, fields, read_u32, read_u64, width, write_at};
use super::{Corpus, Item};
use crate::mutate::{ByteOp, F64S, MAX_INPUT, byte_op, f64_value, u32_value, u64_value};
use crate::rng::Gen;
use crate::{MsgKind, Receiver, WireCase};
use eqtrack_controller::GroupKind;
use ipc_types::{COMMAND_BYTES, STATE_BYTES};

/// The mutations of an encoded message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum WireOp {
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

/// The mutations and their weights.
pub(super) const WIRE_OPS: [(WireOp, u32); 13] = [
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
                actuators: *g.pick(&[0, 6, 8]),
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
        for _ in 0..g.mutation_count() {
            let op = g.pick_weighted(&WIRE_OPS);
            self.wire_op(g, op, &mut case);
        }
        case
    }

    /// A receiver expecting `base`, mostly: its group, the previous sequence number, its
    /// period or none; now and then one that expects something else.
    pub(super) fn receiver_for(&self, g: &mut Gen, base: &Item) -> Receiver {
        let other = |k: GroupKind| match k {
            GroupKind::So3 => GroupKind::Se3,
            GroupKind::Se3 => GroupKind::Se2,
            GroupKind::Se2 => GroupKind::So3,
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
            actuators: if g.chance(9, 10) {
                base.actuators
            } else {
                *g.pick(&[0, 6, 8, 12, 13])
            },
        }
    }

    /// Applies one mutation to `case`; a field is drawn first, for the ops that set one.
    pub(super) fn wire_op(&self, g: &mut Gen, op: WireOp, case: &mut WireCase) {
        let fs = fields(case.kind);
        let (_, offset, ty, count) = *g.pick(fs);
        let data = &mut case.bytes;
        match op {
            WireOp::Byte(ByteOp::Splice) => self.splice_aligned(g, data),
            WireOp::Byte(b) => {
                let other = &g.pick(&self.items).bytes;
                byte_op(g, b, data, other);
            }
            WireOp::F64Field | WireOp::IntField => {
                set_number_field(g, op, fs, (offset, ty, count), data);
            }
            WireOp::NameField => set_name_field(g, fs, data),
            WireOp::CrossField => self.copy_field(g, case.kind, (offset, ty, count), data),
            WireOp::Length => change_length(g, data),
            WireOp::KindSwap => {
                case.kind = match case.kind {
                    MsgKind::State => MsgKind::Command,
                    MsgKind::Command => MsgKind::State,
                }
            }
        }
    }

    /// The byte-level splice, aligned: another corpus item's bytes from the cut on.
    fn splice_aligned(&self, g: &mut Gen, data: &mut Vec<u8>) {
        // aligned: this message up to a point, another from the same point on (the
        // length is kept when the other is of the same type)
        let other = &g.pick(&self.items).bytes;
        let i = g.below(data.len().min(other.len()) + 1);
        data.truncate(i);
        data.extend_from_slice(&other[i..]);
    }

    /// One entry of the drawn field `(offset, type, count)` copied from another corpus item of
    /// kind `kind`.
    fn copy_field(
        &self,
        g: &mut Gen,
        kind: MsgKind,
        (offset, ty, count): (usize, Ty, usize),
        data: &mut [u8],
    ) {
        let donors: Vec<&Item> = self.items.iter().filter(|i| i.kind == kind).collect();
        let donor = g.pick(&donors);
        let at = offset + g.below(count) * width(ty);
        let end = (at + width(ty)).min(donor.bytes.len());
        if at < end {
            write_at(data, at, &donor.bytes[at..end]);
        }
    }
}

/// Sets one entry of a number field to a special or random value of its type: the drawn field
/// `(offset, type, count)` if its type fits `op`, else a random field of `fs` that does.
fn set_number_field(
    g: &mut Gen,
    op: WireOp,
    fs: &[(&str, usize, Ty, usize)],
    (offset, ty, count): (usize, Ty, usize),
    data: &mut [u8],
) {
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
        Ty::F64 => f64_value(g).to_le_bytes().to_vec(),
        Ty::U32 => {
            let old = read_u32(data, at).unwrap_or(0);
            u32_value(g, old).to_le_bytes().to_vec()
        }
        _ => {
            let old = read_u64(data, at).unwrap_or(0);
            u64_value(g, old).to_le_bytes().to_vec()
        }
    };
    write_at(data, at, &value);
}

/// The name field set to odd bytes: no NUL, invalid UTF-8, a cut character, a hidden tail.
fn set_name_field(g: &mut Gen, fs: &[(&str, usize, Ty, usize)], data: &mut [u8]) {
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

/// The message's length changed: a byte more or less, none, or far beyond `MAX_INPUT`.
fn change_length(g: &mut Gen, data: &mut Vec<u8>) {
    match g.below(20) {
        0..=8 => data.push(g.u32() as u8),
        9..=17 => {
            data.pop();
        }
        18 => data.clear(),
        _ => {
            let n = g.range(MAX_INPUT, 1 << 20);
            data.resize(n, 0xa5);
        }
    }
}
