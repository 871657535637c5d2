//! Conversions between the wire's codes (`ipc_types`, which knows no maths) and the maths
//! crate's types (`eqtrack-controller`): groups, laws and path segments. They live here, above both,
//! so that neither depends on the other.

use eqtrack_controller::path::{Segment, Shape};
use eqtrack_controller::{GroupKind, Law};
use ipc_types::plan::{SHAPE_REST, SHAPE_THROUGH};
use ipc_types::{MAX_M, MAX_N, WireGroup, WireLaw, WireSegment};
use nalgebra::{SMatrix, SVector};

/// The wire's name for a group.
pub fn wire_group(kind: GroupKind) -> WireGroup {
    match kind {
        GroupKind::So3 => WireGroup::So3,
        GroupKind::Se3 => WireGroup::Se3,
        GroupKind::Se2 => WireGroup::Se2,
    }
}

/// The maths crate's name for a wire group.
pub fn group_of(group: WireGroup) -> GroupKind {
    match group {
        WireGroup::So3 => GroupKind::So3,
        WireGroup::Se3 => GroupKind::Se3,
        WireGroup::Se2 => GroupKind::Se2,
    }
}

/// A group's code in a message's `group` field.
pub fn group_code(kind: GroupKind) -> u32 {
    wire_group(kind).code()
}

/// The group of a message's `group` code (`None`: unknown).
pub fn group_kind(code: u32) -> Option<GroupKind> {
    WireGroup::from_code(code).map(group_of)
}

/// A law's code in [`ipc_types::CommandMsg::law`]: 1 eqt, 2 gt, 3 nog, 4 asym.
pub fn law_code(law: Law) -> u32 {
    match law {
        Law::Eqt => WireLaw::Eqt,
        Law::Gt => WireLaw::Gt,
        Law::Nog => WireLaw::Nog,
        Law::Asym => WireLaw::Asym,
    }
    .code()
}

/// The law of a code (`None`: 0 or unknown).
pub fn law_from_code(code: u32) -> Option<Law> {
    WireLaw::from_code(code).map(|l| match l {
        WireLaw::Eqt => Law::Eqt,
        WireLaw::Gt => Law::Gt,
        WireLaw::Nog => Law::Nog,
        WireLaw::Asym => Law::Asym,
    })
}

/// The wire form of a path segment (docs/maths.md, "Streamed pieces").
pub fn wire_segment<const N: usize, const M: usize>(seg: &Segment<f64, N, M>) -> WireSegment {
    let mut w = WireSegment::EMPTY;
    w.t0 = seg.t0;
    w.t1 = seg.t1;
    for i in 0..N.min(MAX_N) {
        for j in 0..N.min(MAX_N) {
            w.start[i * N + j] = seg.start[(i, j)];
        }
    }
    let mut put = |k: usize, v: &SVector<f64, M>| {
        for i in 0..M.min(MAX_M) {
            w.twists[k * MAX_M + i] = v[i];
        }
    };
    w.shape = match &seg.shape {
        Shape::Rest { twist } => {
            put(0, twist);
            SHAPE_REST
        }
        Shape::Through { v } => {
            for (k, vk) in v.iter().enumerate() {
                put(k, vk);
            }
            SHAPE_THROUGH
        }
    };
    w
}

/// The segment a wire segment carries (entries beyond the wire's are NaN, and so is an
/// unknown shape, so neither ever passes `Segment::check`).
pub fn segment<const N: usize, const M: usize>(w: &WireSegment) -> Segment<f64, N, M> {
    let twist = |k: usize| -> SVector<f64, M> {
        SVector::from_fn(|i, _| {
            if i < MAX_M {
                w.twists[k * MAX_M + i]
            } else {
                f64::NAN
            }
        })
    };
    let shape = match w.shape {
        SHAPE_REST => Shape::Rest { twist: twist(0) },
        SHAPE_THROUGH => Shape::Through {
            v: [twist(0), twist(1), twist(2), twist(3), twist(4)],
        },
        _ => Shape::Rest {
            twist: SVector::from_element(f64::NAN),
        },
    };
    Segment {
        t0: w.t0,
        t1: w.t1,
        start: SMatrix::from_fn(|i, j| w.start.get(i * N + j).copied().unwrap_or(f64::NAN)),
        shape,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_and_laws_convert_both_ways_through_their_codes() {
        for g in GroupKind::ALL {
            assert_eq!(group_kind(group_code(g)), Some(g));
            assert_eq!(wire_group(g).dims(), g.dims());
            assert_eq!(group_of(wire_group(g)), g);
        }
        assert_eq!(group_kind(0), None);
        for law in Law::ALL {
            assert_eq!(law_from_code(law_code(law)), Some(law));
        }
        assert_eq!(law_from_code(0), None);
    }
}
