//! The streamed reference: a planner process publishes the pieces of a path ahead of time,
//! [`PLAN_WINDOW`] segments per [`PlanMsg`], and the controller appends the ones it does not
//! have yet to its `eqtrack_controller::path::Path` (docs/maths.md, "Streamed pieces"). A segment is
//! exactly `eqtrack_controller::path::Segment`: start time, end time, start pose, its shape (a
//! rest-to-rest geodesic or a through-waypoint quintic Hermite piece) and the shape's
//! body-frame displacements — so the controller evaluates it at any `t_k` without allocating,
//! and a streamed path equals, bit for bit, the same path built from a file.

use crate::WireGroup;
use crate::{DecodeError, Get, MAX_M, MAX_N, PROTOCOL_VERSION, Put, all_finite, length, own_dims};
#[cfg(feature = "zero-copy")]
use iceoryx2_bb_derive_macros::ZeroCopySend;
#[cfg(feature = "zero-copy")]
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

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

/// One piece of a path on the wire (`eqtrack_controller::path::Segment`, padded to the largest
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
    /// [`WireGroup::code`].
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
pub enum PlanInvalid {
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

impl PlanInvalid {
    /// How many kinds there are (for counters indexed by `kind as usize`).
    pub const KINDS: usize = 8;
}

impl core::fmt::Display for PlanInvalid {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            PlanInvalid::Version => "wrong protocol version",
            PlanInvalid::Group => "wrong group",
            PlanInvalid::Count => "more segments than a plan message holds",
            PlanInvalid::NonFinite => "non-finite number",
            PlanInvalid::Times => "segment times not increasing",
            PlanInvalid::NotOnGroup => "a start pose is not on the group",
            PlanInvalid::Shape => "unknown segment shape",
            PlanInvalid::ShortLeg => "a segment is shorter than the control period",
        })
    }
}

impl WireSegment {
    /// A zeroed segment (no shape: refused until filled in).
    pub const EMPTY: WireSegment = EMPTY_SEGMENT;
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
}

impl PlanMsg {
    /// An empty plan of `group` with the version filled in.
    pub fn new(group: WireGroup) -> Self {
        PlanMsg {
            version: PROTOCOL_VERSION,
            group: group.code(),
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
        let mut m = PlanMsg::new(WireGroup::So3);
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

/// Whether the row-major `q` is on `group`: SO(3) and SE(3), the top-left 3×3 block a
/// rotation and (SE(3)) the last row `0 0 0 1`; SE(2), the top-left 2×2 block a rotation and
/// the last row `0 0 1`.
fn on_group(q: &[f64], group: WireGroup) -> bool {
    let (n, _) = group.dims();
    let r = |i: usize, j: usize| q[i * n + j];
    if group == WireGroup::Se2 {
        let orthonormal = [(0, 0, 1.0), (0, 1, 0.0), (1, 1, 1.0)]
            .iter()
            .all(|&(i, j, want)| {
                let dot: f64 = (0..2).map(|k| r(k, i) * r(k, j)).sum();
                (dot - want).abs() <= POSE_TOLERANCE
            });
        let det = r(0, 0) * r(1, 1) - r(0, 1) * r(1, 0);
        return orthonormal && det > 0.0 && r(2, 0) == 0.0 && r(2, 1) == 0.0 && r(2, 2) == 1.0;
    }
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
pub fn check_plan(msg: &PlanMsg, group: WireGroup, period: f64) -> Result<(), PlanInvalid> {
    if msg.version != PROTOCOL_VERSION {
        return Err(PlanInvalid::Version);
    }
    let (n, m) = own_dims(msg.group, group).map_err(|_| PlanInvalid::Group)?;
    if msg.count as usize > PLAN_WINDOW {
        return Err(PlanInvalid::Count);
    }
    let mut end = f64::NEG_INFINITY;
    for s in msg.used() {
        let twists = match s.shape {
            SHAPE_REST => 1,
            SHAPE_THROUGH => 5,
            _ => return Err(PlanInvalid::Shape),
        };
        if !(s.t0.is_finite()
            && s.t1.is_finite()
            && all_finite(&s.start[..n * n])
            && (0..twists).all(|k| all_finite(s.twist(k, m))))
        {
            return Err(PlanInvalid::NonFinite);
        }
        if s.t1 <= s.t0 || s.t0 < end {
            return Err(PlanInvalid::Times);
        }
        // the times are finite here; a NaN period refuses too
        if s.t1 - s.t0 < period || period.is_nan() {
            return Err(PlanInvalid::ShortLeg);
        }
        end = s.t1;
        if !on_group(&s.start, group) {
            return Err(PlanInvalid::NotOnGroup);
        }
    }
    Ok(())
}
