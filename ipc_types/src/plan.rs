//! The streamed reference: a planner process publishes the pieces of a path ahead of time,
//! [`PLAN_WINDOW`] segments per [`PlanMsg`], and the controller appends the ones it does not
//! have yet to its `controller::path::Path` (docs/maths.md, "Streamed pieces"). A segment is
//! exactly `controller::path::Segment`: start time, end time, start pose, its shape (a
//! rest-to-rest geodesic or a through-waypoint quintic Hermite piece) and the shape's
//! body-frame displacements — so the controller evaluates it at any `t_k` without allocating,
//! and a streamed path equals, bit for bit, the same path built from a file.

use crate::{DecodeError, Get, MAX_M, MAX_N, PROTOCOL_VERSION, Put, all_finite, length, own_dims};
use controller::GroupKind;
use controller::path::{Segment, Shape};
#[cfg(feature = "zero-copy")]
use iceoryx2_bb_derive_macros::ZeroCopySend;
#[cfg(feature = "zero-copy")]
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;
use nalgebra::{SMatrix, SVector};

/// Segments per plan message.
pub const PLAN_WINDOW: usize = 8;

/// How far a streamed start pose's rotation may be from orthonormal (max-entry norm of
/// `RᵀR − I`) and still be accepted: a pose written from a rotation matrix in f64 is within
/// a few ulps; anything off by more is not a pose.
pub const POSE_TOLERANCE: f64 = 1e-9;

/// Bytes of an encoded [`WireSegment`].
pub const SEGMENT_BYTES: usize = 8 + 8 + 4 + 4 + 8 * MAX_N * MAX_N + 8 * 5 * MAX_M;
/// Bytes of an encoded [`PlanMsg`] (little-endian, field by field, as the flight recorder
/// keeps it).
pub const PLAN_BYTES: usize = 4 + 4 + 8 + 8 + 4 + 4 + 4 + 4 + PLAN_WINDOW * SEGMENT_BYTES;

/// [`WireSegment::shape`] of a rest-to-rest geodesic piece (`path = "stop"`).
pub const SHAPE_REST: u32 = 0;
/// [`WireSegment::shape`] of a through-waypoint quintic Hermite piece (`path = "through"`).
pub const SHAPE_THROUGH: u32 = 1;

/// One piece of a path on the wire (`controller::path::Segment`, padded to the largest
/// group).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "zero-copy",
    derive(ZeroCopySend),
    type_name("eqtrack::WireSegment4")
)]
#[repr(C)]
pub struct WireSegment {
    /// Start time (s, on the plant's clock `t_k = k·period`).
    pub t0: f64,
    /// End time (s, `> t0`).
    pub t1: f64,
    /// [`SHAPE_REST`] or [`SHAPE_THROUGH`].
    pub shape: u32,
    /// Zero.
    pub reserved: u32,
    /// The pose at `t0`, row-major n×n in the first n² entries.
    pub start: [f64; MAX_N * MAX_N],
    /// [`SHAPE_REST`]: `ξ = log(Q_start⁻¹ Q_end)` in the first m entries, the rest zero.
    /// [`SHAPE_THROUGH`]: `v_1 … v_5`, m entries each, at offsets `0, MAX_M, …, 4·MAX_M`.
    pub twists: [f64; 5 * MAX_M],
}

/// A window of consecutive path segments from a planner.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "zero-copy",
    derive(ZeroCopySend),
    type_name("eqtrack::PlanMsg4")
)]
#[repr(C)]
pub struct PlanMsg {
    /// [`PROTOCOL_VERSION`] (0: nothing written yet).
    pub version: u32,
    /// [`crate::group_code`].
    pub group: u32,
    /// Increases with every publication of a planner.
    pub seq: u64,
    /// CLOCK_MONOTONIC at publication (ns).
    pub stamp_ns: u64,
    /// The index of `segments[0]` in the planner's path (diagnostic).
    pub first_index: u32,
    /// Segments used, `0..=PLAN_WINDOW`.
    pub count: u32,
    /// The planner's process id.
    pub planner_pid: u32,
    /// Zero.
    pub reserved: u32,
    /// The segments, in time order.
    pub segments: [WireSegment; PLAN_WINDOW],
}

/// Why a plan message was not used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PlanReject {
    /// The protocol version differs.
    Version,
    /// The group differs from the receiver's.
    Group,
    /// More segments than [`PLAN_WINDOW`].
    Count,
    /// A number is NaN or infinite.
    NonFinite,
    /// A segment ends before it starts, or starts before the previous one ends.
    Times,
    /// A start pose is not on the group (rotation not orthonormal within
    /// [`POSE_TOLERANCE`], or a reflection; SE(3): last row not `0 0 0 1`).
    NotOnGroup,
    /// A segment's shape code is neither [`SHAPE_REST`] nor [`SHAPE_THROUGH`].
    Shape,
    /// A segment lasts less than the receiver's control period (it would move between two
    /// ticks, so no tick sees its speed).
    ShortLeg,
}

impl PlanReject {
    /// How many kinds there are (for counters indexed by `kind as usize`).
    pub const KINDS: usize = 8;
}

impl core::fmt::Display for PlanReject {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            PlanReject::Version => "wrong protocol version",
            PlanReject::Group => "wrong group",
            PlanReject::Count => "more segments than a plan message holds",
            PlanReject::NonFinite => "non-finite number",
            PlanReject::Times => "segment times not increasing",
            PlanReject::NotOnGroup => "a start pose is not on the group",
            PlanReject::Shape => "unknown segment shape",
            PlanReject::ShortLeg => "a segment is shorter than the control period",
        })
    }
}

const EMPTY_SEGMENT: WireSegment = WireSegment {
    t0: 0.0,
    t1: 0.0,
    shape: SHAPE_REST,
    reserved: 0,
    start: [0.0; MAX_N * MAX_N],
    twists: [0.0; 5 * MAX_M],
};

impl WireSegment {
    /// The first `m` entries of twist `k` (`k < 5`, `m ≤ MAX_M`): `ξ` for `k = 0` of a
    /// [`SHAPE_REST`] piece, `v_{k+1}` of a [`SHAPE_THROUGH`] piece.
    pub fn twist(&self, k: usize, m: usize) -> &[f64] {
        &self.twists[k * MAX_M..k * MAX_M + m]
    }

    /// The wire form of `seg`.
    pub fn from_segment<const N: usize, const M: usize>(seg: &Segment<f64, N, M>) -> Self {
        let mut w = EMPTY_SEGMENT;
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
        let shape = match &seg.shape {
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
        w.shape = shape;
        w
    }

    /// The segment (entries beyond the wire's are NaN, and so is an unknown shape, so neither
    /// ever passes [`Segment::check`]).
    pub fn segment<const N: usize, const M: usize>(&self) -> Segment<f64, N, M> {
        let twist = |k: usize| -> SVector<f64, M> {
            SVector::from_fn(|i, _| {
                if i < MAX_M {
                    self.twists[k * MAX_M + i]
                } else {
                    f64::NAN
                }
            })
        };
        let shape = match self.shape {
            SHAPE_REST => Shape::Rest { twist: twist(0) },
            SHAPE_THROUGH => Shape::Through {
                v: [twist(0), twist(1), twist(2), twist(3), twist(4)],
            },
            _ => Shape::Rest {
                twist: SVector::from_element(f64::NAN),
            },
        };
        Segment {
            t0: self.t0,
            t1: self.t1,
            start: SMatrix::from_fn(|i, j| self.start.get(i * N + j).copied().unwrap_or(f64::NAN)),
            shape,
        }
    }
}

impl PlanMsg {
    /// An empty plan of `group` with the version filled in.
    pub fn new(group: GroupKind) -> Self {
        PlanMsg {
            version: PROTOCOL_VERSION,
            group: crate::group_code(group),
            seq: 0,
            stamp_ns: 0,
            first_index: 0,
            count: 0,
            planner_pid: 0,
            reserved: 0,
            segments: [EMPTY_SEGMENT; PLAN_WINDOW],
        }
    }

    /// The segments used.
    pub fn used(&self) -> &[WireSegment] {
        &self.segments[..(self.count as usize).min(PLAN_WINDOW)]
    }
}

impl PlanMsg {
    /// Little-endian encoding, field by field (the flight recorder keeps plan messages so).
    pub fn to_bytes(&self) -> [u8; PLAN_BYTES] {
        let mut buf = [0u8; PLAN_BYTES];
        let mut p = Put {
            buf: &mut buf,
            at: 0,
        };
        p.bytes(&self.version.to_le_bytes());
        p.bytes(&self.group.to_le_bytes());
        p.bytes(&self.seq.to_le_bytes());
        p.bytes(&self.stamp_ns.to_le_bytes());
        p.bytes(&self.first_index.to_le_bytes());
        p.bytes(&self.count.to_le_bytes());
        p.bytes(&self.planner_pid.to_le_bytes());
        p.bytes(&self.reserved.to_le_bytes());
        for w in &self.segments {
            p.f64s(&[w.t0, w.t1]);
            p.bytes(&w.shape.to_le_bytes());
            p.bytes(&w.reserved.to_le_bytes());
            p.f64s(&w.start);
            p.f64s(&w.twists);
        }
        buf
    }

    /// Decodes [`PlanMsg::to_bytes`]'s output (unchecked: pass it through [`check_plan`]).
    pub fn from_bytes(buf: &[u8]) -> Result<Self, DecodeError> {
        length(buf, PLAN_BYTES)?;
        let mut g = Get { buf, at: 0 };
        let mut m = PlanMsg::new(GroupKind::So3);
        m.version = g.u32();
        m.group = g.u32();
        m.seq = g.u64();
        m.stamp_ns = g.u64();
        m.first_index = g.u32();
        m.count = g.u32();
        m.planner_pid = g.u32();
        m.reserved = g.u32();
        for w in &mut m.segments {
            w.t0 = g.f64();
            w.t1 = g.f64();
            w.shape = g.u32();
            w.reserved = g.u32();
            g.f64s(&mut w.start);
            g.f64s(&mut w.twists);
        }
        Ok(m)
    }
}

/// Whether the top-left 3×3 block of the row-major n×n `q` is a rotation, and (n = 4) the
/// last row is `0 0 0 1`.
fn on_group(q: &[f64], n: usize) -> bool {
    let r = |i: usize, j: usize| q[i * n + j];
    for i in 0..3 {
        for j in 0..3 {
            let dot: f64 = (0..3).map(|k| r(k, i) * r(k, j)).sum();
            let want = if i == j { 1.0 } else { 0.0 };
            if (dot - want).abs().is_nan() || (dot - want).abs() > POSE_TOLERANCE {
                return false;
            }
        }
    }
    let det = r(0, 0) * (r(1, 1) * r(2, 2) - r(1, 2) * r(2, 1))
        - r(0, 1) * (r(1, 0) * r(2, 2) - r(1, 2) * r(2, 0))
        + r(0, 2) * (r(1, 0) * r(2, 1) - r(1, 1) * r(2, 0));
    det > 0.0 && (n == 3 || (r(3, 0) == 0.0 && r(3, 1) == 0.0 && r(3, 2) == 0.0 && r(3, 3) == 1.0))
}

/// Checks a plan message against the receiver's group and control period: version, group,
/// count, shape codes, finite numbers, increasing non-overlapping times, every segment at
/// least `period` long, start poses on the group.
pub fn check_plan(msg: &PlanMsg, group: GroupKind, period: f64) -> Result<(), PlanReject> {
    if msg.version != PROTOCOL_VERSION {
        return Err(PlanReject::Version);
    }
    let (n, m) = own_dims(msg.group, group).map_err(|_| PlanReject::Group)?;
    if msg.count as usize > PLAN_WINDOW {
        return Err(PlanReject::Count);
    }
    let mut end = f64::NEG_INFINITY;
    for s in msg.used() {
        let twists = match s.shape {
            SHAPE_REST => 1,
            SHAPE_THROUGH => 5,
            _ => return Err(PlanReject::Shape),
        };
        if !(s.t0.is_finite()
            && s.t1.is_finite()
            && all_finite(&s.start[..n * n])
            && (0..twists).all(|k| all_finite(s.twist(k, m))))
        {
            return Err(PlanReject::NonFinite);
        }
        if s.t1 <= s.t0 || s.t0 < end {
            return Err(PlanReject::Times);
        }
        // the times are finite here; a NaN period refuses too
        if s.t1 - s.t0 < period || period.is_nan() {
            return Err(PlanReject::ShortLeg);
        }
        end = s.t1;
        if !on_group(&s.start, n) {
            return Err(PlanReject::NotOnGroup);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller::group::{MatrixLieGroup, Se3, So3};
    use nalgebra::{Matrix3, Vector3, Vector6};

    fn so3_segment(t0: f64, t1: f64) -> Segment<f64, 3, 3> {
        let a = So3::exp(&Vector3::new(0.3, -1.0, 2.0));
        let b = So3::exp(&Vector3::new(-2.5, 0.4, 0.1));
        Segment::between::<So3>(t0, &a, t1, &b)
    }

    #[test]
    fn segments_cross_the_wire_unchanged_on_both_groups() {
        let s = so3_segment(1.0, 2.5);
        assert_eq!(WireSegment::from_segment(&s).segment::<3, 3>(), s);
        let a = Se3::exp(&Vector6::new(0.1, 0.2, -3.0, 1.0, 2.0, 3.0));
        let b = Se3::exp(&Vector6::new(2.0, -0.2, 0.3, -1.0, 0.5, 0.0));
        let s = Segment::between::<Se3>(0.0, &a, 4.0, &b);
        assert_eq!(WireSegment::from_segment(&s).segment::<4, 6>(), s);
        // through-waypoint pieces too
        let knot = |q, v: Vector6<f64>| controller::PathSample {
            q,
            v,
            v_dot: v * 0.5,
        };
        let s = Segment::hermite::<Se3>(
            0.0,
            &knot(a, Vector6::new(0.1, 0.2, 0.3, 0.4, 0.5, 0.6)),
            4.0,
            &knot(b, Vector6::new(-0.3, 0.2, 0.1, 0.0, 0.5, -0.6)),
        );
        let w = WireSegment::from_segment(&s);
        assert_eq!(w.shape, SHAPE_THROUGH);
        assert_eq!(w.segment::<4, 6>(), s);
        let t = So3::exp(&Vector3::new(0.3, 0.0, 0.1));
        let s = Segment::hermite::<So3>(1.0, &controller::PathSample::rest(t), 2.0, &knot3(t));
        assert_eq!(WireSegment::from_segment(&s).segment::<3, 3>(), s);
    }

    fn knot3(q: Matrix3<f64>) -> controller::PathSample<f64, 3, 3> {
        controller::PathSample {
            q: q * So3::exp(&Vector3::new(0.0, 1.0, 0.0)),
            v: Vector3::new(0.5, -0.1, 0.0),
            v_dot: Vector3::new(0.0, 0.2, 0.1),
        }
    }

    #[test]
    fn plan_messages_round_trip_through_their_bytes() {
        let mut m = PlanMsg::new(GroupKind::So3);
        m.seq = 12;
        m.stamp_ns = 34;
        m.planner_pid = 56;
        m.first_index = 2;
        m.count = 1;
        m.segments[0] = WireSegment::from_segment(&so3_segment(0.5, 1.5));
        m.segments[3].twists[29] = f64::NAN;
        let b = m.to_bytes();
        let back = PlanMsg::from_bytes(&b).unwrap();
        assert_eq!(back.to_bytes(), b);
        assert_eq!(
            (back.seq, back.planner_pid, back.segments[0]),
            (12, 56, m.segments[0])
        );
        assert!(back.segments[3].twists[29].is_nan());
        assert!(PlanMsg::from_bytes(&b[1..]).is_err());
    }

    #[test]
    fn plans_are_checked() {
        let mut p = PlanMsg::new(GroupKind::So3);
        p.count = 2;
        p.segments[0] = WireSegment::from_segment(&so3_segment(0.0, 1.0));
        p.segments[1] = WireSegment::from_segment(&so3_segment(1.0, 2.0));
        assert_eq!(check_plan(&p, GroupKind::So3, 0.01), Ok(()));
        assert_eq!(check_plan(&p, GroupKind::Se3, 0.01), Err(PlanReject::Group));
        // a leg shorter than the control period, or a period that is not a number
        assert_eq!(check_plan(&p, GroupKind::So3, 1.0), Ok(()));
        assert_eq!(
            check_plan(&p, GroupKind::So3, 1.0 + 1e-9),
            Err(PlanReject::ShortLeg)
        );
        assert_eq!(
            check_plan(&p, GroupKind::So3, f64::NAN),
            Err(PlanReject::ShortLeg)
        );
        let bad = |f: &dyn Fn(&mut PlanMsg)| {
            let mut q = p;
            f(&mut q);
            check_plan(&q, GroupKind::So3, 0.01)
        };
        assert_eq!(bad(&|q| q.segments[1].shape = 2), Err(PlanReject::Shape));
        // a through piece's later twists are checked, a rest piece's are not used
        assert_eq!(
            bad(&|q| {
                q.segments[1].shape = SHAPE_THROUGH;
                q.segments[1].twists[4 * MAX_M + 2] = f64::NAN
            }),
            Err(PlanReject::NonFinite)
        );
        assert_eq!(
            bad(&|q| q.segments[1].twists[4 * MAX_M + 2] = f64::NAN),
            Ok(())
        );
        assert_eq!(bad(&|q| q.version = 0), Err(PlanReject::Version));
        assert_eq!(bad(&|q| q.count = 9), Err(PlanReject::Count));
        assert_eq!(
            bad(&|q| q.segments[1].twists[2] = f64::NAN),
            Err(PlanReject::NonFinite)
        );
        assert_eq!(bad(&|q| q.segments[1].t0 = 0.5), Err(PlanReject::Times));
        assert_eq!(bad(&|q| q.segments[0].t1 = 0.0), Err(PlanReject::Times));
        assert_eq!(
            bad(&|q| q.segments[1].start[0] *= 1.001),
            Err(PlanReject::NotOnGroup)
        );
        // a reflection is orthonormal but not a rotation
        let flip = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0);
        let mut s = so3_segment(1.0, 2.0);
        s.start = flip;
        assert_eq!(
            bad(&|q| q.segments[1] = WireSegment::from_segment(&s)),
            Err(PlanReject::NotOnGroup)
        );
        // unused entries are not looked at
        assert_eq!(bad(&|q| q.segments[5].t0 = f64::NAN), Ok(()));
        // SE(3): the last row must be 0 0 0 1
        let mut p = PlanMsg::new(GroupKind::Se3);
        p.count = 1;
        let a = Se3::exp(&Vector6::new(0.1, 0.2, -3.0, 1.0, 2.0, 3.0));
        p.segments[0] = WireSegment::from_segment(&Segment::between::<Se3>(0.0, &a, 1.0, &a));
        assert_eq!(check_plan(&p, GroupKind::Se3, 0.01), Ok(()));
        p.segments[0].start[14] = 0.5;
        assert_eq!(
            check_plan(&p, GroupKind::Se3, 0.01),
            Err(PlanReject::NotOnGroup)
        );
    }
}
