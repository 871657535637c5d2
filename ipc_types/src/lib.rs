//! The wire contract between the plant and the controller processes: fixed-size `#[repr(C)]`
//! messages, the group codes, the checks every receiver applies, a little-endian byte
//! encoding (for transports that carry bytes), the service names of a run and the protocol
//! version. `#![no_std]` with no `alloc`, and no transport: opening services is the `link`
//! crate's job. Feature `zero-copy` (default) derives iceoryx2's `ZeroCopySend` on the
//! messages (iceoryx2's trait crate links `alloc`).
//!
//! One control cycle (docs/architecture.md, "One control cycle"): the plant publishes
//! [`StateMsg`] `{seq k, t_k, Q, V}`; the controller answers with [`CommandMsg`]
//! `{seq k, τ_k, L, compute time}`.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

use controller::{GroupKind, Law};
use core::fmt::Write;
#[cfg(feature = "zero-copy")]
use iceoryx2_bb_derive_macros::ZeroCopySend;
#[cfg(feature = "zero-copy")]
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;
use nalgebra::{SMatrix, SVector};

pub mod decision;
pub use decision::Decision;
pub mod plan;
pub use plan::{PLAN_BYTES, PLAN_WINDOW, PlanMsg, PlanReject, WireSegment, check_plan};
pub mod status;
pub use status::{StatusMsg, status_flags};

/// Bumped whenever a message layout or meaning changes.
pub const PROTOCOL_VERSION: u32 = 6;
/// [`CommandMsg::previous_seq`] when the controller processed no state before.
pub const NO_PREVIOUS: u64 = u64::MAX;
/// The largest n (configuration matrices are n×n) any supported group needs.
pub const MAX_N: usize = 4;
/// The largest m (algebra dimension) any supported group needs.
pub const MAX_M: usize = 6;
/// Bytes of the scenario name carried in the messages (UTF-8, NUL-padded).
pub const NAME_BYTES: usize = 32;

/// The group's code on the wire: the one mapping between [`GroupKind`] and a `u32`.
pub fn group_code(kind: GroupKind) -> u32 {
    match kind {
        GroupKind::So3 => 1,
        GroupKind::Se3 => 2,
    }
}

/// The group of a wire code; `None` for an unknown code.
pub fn group_kind(code: u32) -> Option<GroupKind> {
    GroupKind::ALL.into_iter().find(|k| group_code(*k) == code)
}

/// Bits of [`StateMsg::flags`].
pub mod flags {
    /// The plant waits for commands on the event service: notify after each command.
    pub const WAKE_EVENT: u32 = 1;
    /// The run is over: the controller exits cleanly.
    pub const SHUTDOWN: u32 = 2;
    /// [`CommandMsg::flags`](crate::CommandMsg::flags): the controller refuses the run (configuration mismatch, see
    /// [`CommandMsg::mismatch`](crate::CommandMsg::mismatch)); the plant stops.
    pub const REFUSED: u32 = 4;
    /// [`CommandMsg::flags`](crate::CommandMsg::flags): the controller tracks a streamed reference (`--reference
    /// stream`); [`CommandMsg::plans_received`](crate::CommandMsg::plans_received) says what it had taken from the plan board.
    pub const STREAMED: u32 = 8;
}

/// Bits of [`CommandMsg::mismatch`]: what differs between the two sides' settings.
pub mod mismatch {
    /// The group.
    pub const GROUP: u32 = 1;
    /// The control period (only when the controller insists on one).
    pub const PERIOD: u32 = 2;
    /// The scenario (only when both sides send a fingerprint).
    pub const SCENARIO: u32 = 4;
}

/// The plant's state at `t_k`: configuration and body velocity (what a gyro measures), and
/// the identity of what the plant runs.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "zero-copy",
    derive(ZeroCopySend),
    type_name("eqtrack::StateMsg6")
)]
#[repr(C)]
pub struct StateMsg {
    /// [`PROTOCOL_VERSION`].
    pub version: u32,
    /// [`group_code`].
    pub group: u32,
    /// Control step k (strictly increasing).
    pub seq: u64,
    /// Time `t_k = k·control_period` (s).
    pub t: f64,
    /// The plant's control period (s); the controller's reference steps with it.
    pub control_period: f64,
    /// CLOCK_MONOTONIC at publication (ns).
    pub stamp_ns: u64,
    /// `Q`, row-major n×n in the first n² entries.
    pub q: [f64; MAX_N * MAX_N],
    /// Body velocity `V` in the first m entries (SE(3): ω then v).
    pub v: [f64; MAX_M],
    /// The torque the plant applied over `[t_{k−1}, t_k)` (after saturation, held commands
    /// or safe mode; without the disturbance), first m entries; zero at k = 0. The
    /// disturbance-rejection terms need it.
    pub applied: [f64; MAX_M],
    /// [`flags`] bits.
    pub flags: u32,
    /// The plant's process id (the controller's liveness check; 0: unknown).
    pub plant_pid: u32,
    /// Fingerprint of the plant's scenario settings (0: none, e.g. a hardware plant).
    pub fingerprint: u64,
    /// The plant's scenario name, UTF-8, NUL-padded (empty: none).
    pub scenario: [u8; NAME_BYTES],
}

/// The controller's answer to state k (or its refusal of the run).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "zero-copy",
    derive(ZeroCopySend),
    type_name("eqtrack::CommandMsg6")
)]
#[repr(C)]
pub struct CommandMsg {
    /// [`PROTOCOL_VERSION`].
    pub version: u32,
    /// [`group_code`] of the controller's group.
    pub group: u32,
    /// The state's k.
    pub seq: u64,
    /// CLOCK_MONOTONIC when the state was received (ns).
    pub state_received_ns: u64,
    /// CLOCK_MONOTONIC at publication (ns).
    pub stamp_ns: u64,
    /// Time spent from receiving the state to publishing this command (ns).
    pub compute_ns: u64,
    /// Torque `τ_k` after saturation, first m entries (SE(3): torque then force).
    pub tau: [f64; MAX_M],
    /// Lyapunov function at `t_k` (diagnostic).
    pub lyapunov: f64,
    /// The disturbance observer's estimate `d̂` in the body frame, subtracted from the law's
    /// torque (zeros without the observer), first m entries.
    pub observer: [f64; MAX_M],
    /// The integral's torque `−K_I z` in the body frame, added to the law's torque (zeros
    /// without the integral), first m entries.
    pub integral: [f64; MAX_M],
    /// The sequence number of the state the controller processed before this one
    /// ([`NO_PREVIOUS`]: none; states in between it never saw).
    pub previous_seq: u64,
    /// The observer's estimate before this state updated it, in the observer's own frame
    /// (zeros without the observer), first m entries. With `previous_seq` and the recorded
    /// states, replay restores the terms from it and checks this command on its own.
    pub estimate_before: [f64; MAX_M],
    /// The integral `z` before this state updated it (zeros without the integral), first m.
    pub z_before: [f64; MAX_M],
    /// Heap allocations the controller made since the end of its first cycle (diagnostic).
    pub heap_allocations: u64,
    /// [`flags`] bits ([`flags::REFUSED`]).
    pub flags: u32,
    /// With [`flags::REFUSED`]: the [`mismatch`] bits.
    pub mismatch: u32,
    /// The controller's scenario fingerprint (0: none).
    pub fingerprint: u64,
    /// The control period the controller insists on (0: it follows the plant).
    pub expected_period: f64,
    /// The controller's scenario name, UTF-8, NUL-padded.
    pub scenario: [u8; NAME_BYTES],
    /// The law that computed `tau` ([`law_code`]; 0: not said): a controller started by hand
    /// may run another law than the scenario's, and replay must know which.
    pub law: u32,
    /// With a streamed reference ([`flags::STREAMED`]): how many plan messages the controller
    /// had taken from the plan board (accepted or refused) before it answered this state.
    pub plans_received: u32,
    /// The sequence number of the last of them (0: none).
    pub plan_seq: u64,
    /// Its planner's process id (0: none). With `plans_received`, what replay needs to
    /// apply the recorded plan messages at the cycles the controller took them.
    pub plan_pid: u32,
    /// Zero.
    pub reserved: u32,
}

/// The wire code of a law in [`CommandMsg::law`]: 1 eqt, 2 gt, 3 nog, 4 asym.
pub fn law_code(law: Law) -> u32 {
    match law {
        Law::Eqt => 1,
        Law::Gt => 2,
        Law::Nog => 3,
        Law::Asym => 4,
    }
}

/// The law of a wire code (`None`: 0 or unknown).
pub fn law_from_code(code: u32) -> Option<Law> {
    Law::ALL.into_iter().find(|l| law_code(*l) == code)
}

/// What one side runs: compared once, on the first state, to catch two processes started with
/// different settings (docs/architecture.md, "Configuration identity").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Identity {
    /// The group.
    pub group: u32,
    /// The control period (s); 0 on the controller's side: it follows the plant.
    pub period: f64,
    /// The scenario fingerprint; 0: none (accepted by anyone).
    pub fingerprint: u64,
    /// The scenario name, NUL-padded.
    pub scenario: [u8; NAME_BYTES],
}

impl Identity {
    /// An identity; `scenario` is cut to [`NAME_BYTES`] bytes (at a character boundary).
    pub fn new(group: GroupKind, period: f64, fingerprint: u64, scenario: &str) -> Identity {
        Identity {
            group: group_code(group),
            period,
            fingerprint,
            scenario: name_bytes(scenario),
        }
    }

    /// The [`mismatch`] bits of a plant's identity against this controller's.
    pub fn mismatch(&self, plant: &Identity) -> u32 {
        let mut bits = 0;
        if plant.group != self.group {
            bits |= mismatch::GROUP;
        }
        if self.period != 0.0 && plant.period != self.period {
            bits |= mismatch::PERIOD;
        }
        if self.fingerprint != 0 && plant.fingerprint != 0 && plant.fingerprint != self.fingerprint
        {
            bits |= mismatch::SCENARIO;
        }
        bits
    }
}

impl core::fmt::Display for Identity {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match group_kind(self.group) {
            Some(g) => write!(f, "group {}", g.name())?,
            None => write!(f, "group code {}", self.group)?,
        }
        if self.period == 0.0 {
            write!(f, ", period: the plant's")?;
        } else {
            write!(f, ", period {} s", self.period)?;
        }
        match (name_str(&self.scenario), self.fingerprint) {
            (_, 0) => write!(f, ", no scenario fingerprint"),
            ("", fp) => write!(f, ", scenario {fp:016x}"),
            (name, fp) => write!(f, ", scenario `{name}` ({fp:016x})"),
        }
    }
}

/// `text` as `N` NUL-padded bytes, cut at a character boundary to fit.
pub fn padded_bytes<const N: usize>(text: &str) -> [u8; N] {
    let mut out = [0u8; N];
    let mut end = text.len().min(N);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    out[..end].copy_from_slice(&text.as_bytes()[..end]);
    out
}

/// The text of NUL-padded bytes (`"?"` if they are not UTF-8).
pub fn padded_str<const N: usize>(bytes: &[u8; N]) -> &str {
    let end = bytes.iter().position(|b| *b == 0).unwrap_or(N);
    core::str::from_utf8(&bytes[..end]).unwrap_or("?")
}

/// `text` as NUL-padded name bytes ([`NAME_BYTES`]), cut at a character boundary to fit.
pub fn name_bytes(text: &str) -> [u8; NAME_BYTES] {
    padded_bytes(text)
}

/// The text of NUL-padded name bytes (`"?"` if they are not UTF-8).
pub fn name_str(bytes: &[u8; NAME_BYTES]) -> &str {
    padded_str(bytes)
}

impl StateMsg {
    /// A zeroed message of `group` with the version filled in.
    pub fn new(group: GroupKind) -> Self {
        StateMsg {
            version: PROTOCOL_VERSION,
            group: group_code(group),
            seq: 0,
            t: 0.0,
            control_period: 0.0,
            stamp_ns: 0,
            q: [0.0; MAX_N * MAX_N],
            v: [0.0; MAX_M],
            applied: [0.0; MAX_M],
            flags: 0,
            plant_pid: 0,
            fingerprint: 0,
            scenario: [0; NAME_BYTES],
        }
    }

    /// Writes the configuration `Q` (row-major) and the body velocity `V`.
    pub fn set_state<const N: usize, const M: usize>(
        &mut self,
        q: &SMatrix<f64, N, N>,
        v: &SVector<f64, M>,
    ) {
        for i in 0..N.min(MAX_N) {
            for j in 0..N.min(MAX_N) {
                self.q[i * N + j] = q[(i, j)];
            }
        }
        for i in 0..M.min(MAX_M) {
            self.v[i] = v[i];
        }
    }

    /// The configuration `Q` (n×n, from the row-major entries).
    pub fn configuration<const N: usize>(&self) -> SMatrix<f64, N, N> {
        SMatrix::from_fn(|i, j| self.q.get(i * N + j).copied().unwrap_or(f64::NAN))
    }

    /// The body velocity `V` (m entries).
    pub fn velocity<const M: usize>(&self) -> SVector<f64, M> {
        SVector::from_fn(|i, _| self.v.get(i).copied().unwrap_or(f64::NAN))
    }

    /// The torque applied over the last period (m entries).
    pub fn applied_torque<const M: usize>(&self) -> SVector<f64, M> {
        SVector::from_fn(|i, _| self.applied.get(i).copied().unwrap_or(f64::NAN))
    }

    /// Writes the torque applied over the last period.
    pub fn set_applied<const M: usize>(&mut self, tau: &SVector<f64, M>) {
        for i in 0..M.min(MAX_M) {
            self.applied[i] = tau[i];
        }
    }

    /// The plant's identity carried by this state.
    pub fn identity(&self) -> Identity {
        Identity {
            group: self.group,
            period: self.control_period,
            fingerprint: self.fingerprint,
            scenario: self.scenario,
        }
    }
}

impl CommandMsg {
    /// A zeroed message of `group` with the version filled in.
    pub fn new(group: GroupKind) -> Self {
        CommandMsg {
            version: PROTOCOL_VERSION,
            group: group_code(group),
            seq: 0,
            state_received_ns: 0,
            stamp_ns: 0,
            compute_ns: 0,
            tau: [0.0; MAX_M],
            lyapunov: 0.0,
            observer: [0.0; MAX_M],
            integral: [0.0; MAX_M],
            previous_seq: NO_PREVIOUS,
            estimate_before: [0.0; MAX_M],
            z_before: [0.0; MAX_M],
            heap_allocations: 0,
            flags: 0,
            mismatch: 0,
            fingerprint: 0,
            expected_period: 0.0,
            law: 0,
            plans_received: 0,
            plan_seq: 0,
            plan_pid: 0,
            reserved: 0,
            scenario: [0; NAME_BYTES],
        }
    }

    /// The torque `τ` (m entries).
    pub fn torque<const M: usize>(&self) -> SVector<f64, M> {
        SVector::from_fn(|i, _| self.tau.get(i).copied().unwrap_or(f64::NAN))
    }

    /// Writes the torque `τ`.
    pub fn set_torque<const M: usize>(&mut self, tau: &SVector<f64, M>) {
        for i in 0..M.min(MAX_M) {
            self.tau[i] = tau[i];
        }
    }

    /// The controller's identity carried by this command.
    pub fn identity(&self) -> Identity {
        Identity {
            group: self.group,
            period: self.expected_period,
            fingerprint: self.fingerprint,
            scenario: self.scenario,
        }
    }

    /// A refusal of state `seq`: the controller's identity and what differs.
    pub fn refusal(controller: &Identity, seq: u64, mismatch: u32) -> Self {
        let mut c = CommandMsg::new(GroupKind::So3);
        c.group = controller.group;
        c.seq = seq;
        c.flags = flags::REFUSED;
        c.mismatch = mismatch;
        c.fingerprint = controller.fingerprint;
        c.expected_period = controller.period;
        c.scenario = controller.scenario;
        c
    }
}

/// Bytes of an encoded [`StateMsg`] (little-endian, field by field).
pub const STATE_BYTES: usize =
    4 + 4 + 8 + 8 + 8 + 8 + 8 * MAX_N * MAX_N + 8 * MAX_M * 2 + 4 + 4 + 8 + NAME_BYTES;
/// Bytes of an encoded [`CommandMsg`].
pub const COMMAND_BYTES: usize = 4
    + 4
    + 8 * 4
    + 8 * MAX_M
    + 8
    + 8 * MAX_M * 2
    + 8
    + 8 * MAX_M * 2
    + 8
    + 4
    + 4
    + 8
    + 8
    + NAME_BYTES
    + 4
    + 4
    + 8
    + 4
    + 4;

/// Why bytes are not a message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DecodeError {
    /// The buffer's length is not the message's.
    Length {
        /// The message's encoded length.
        expected: usize,
        /// The buffer's.
        got: usize,
    },
}

impl core::fmt::Display for DecodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            DecodeError::Length { expected, got } => {
                write!(f, "a message of {got} bytes, expected {expected}")
            }
        }
    }
}

/// Writes fields into a byte buffer in order.
pub(crate) struct Put<'a> {
    pub(crate) buf: &'a mut [u8],
    pub(crate) at: usize,
}

impl Put<'_> {
    pub(crate) fn bytes(&mut self, b: &[u8]) {
        self.buf[self.at..self.at + b.len()].copy_from_slice(b);
        self.at += b.len();
    }
    pub(crate) fn f64s(&mut self, xs: &[f64]) {
        for x in xs {
            self.bytes(&x.to_le_bytes());
        }
    }
}

/// Reads fields back in the same order (the length was checked first).
pub(crate) struct Get<'a> {
    pub(crate) buf: &'a [u8],
    pub(crate) at: usize,
}

impl Get<'_> {
    pub(crate) fn take<const K: usize>(&mut self) -> [u8; K] {
        let mut b = [0u8; K];
        b.copy_from_slice(&self.buf[self.at..self.at + K]);
        self.at += K;
        b
    }
    pub(crate) fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    pub(crate) fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take())
    }
    pub(crate) fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.take())
    }
    pub(crate) fn f64s(&mut self, xs: &mut [f64]) {
        for x in xs {
            *x = self.f64();
        }
    }
}

pub(crate) fn length(buf: &[u8], expected: usize) -> Result<(), DecodeError> {
    if buf.len() == expected {
        Ok(())
    } else {
        Err(DecodeError::Length {
            expected,
            got: buf.len(),
        })
    }
}

impl StateMsg {
    /// Little-endian encoding.
    pub fn to_bytes(&self) -> [u8; STATE_BYTES] {
        let mut buf = [0u8; STATE_BYTES];
        let mut p = Put {
            buf: &mut buf,
            at: 0,
        };
        p.bytes(&self.version.to_le_bytes());
        p.bytes(&self.group.to_le_bytes());
        p.bytes(&self.seq.to_le_bytes());
        p.f64s(&[self.t, self.control_period]);
        p.bytes(&self.stamp_ns.to_le_bytes());
        p.f64s(&self.q);
        p.f64s(&self.v);
        p.f64s(&self.applied);
        p.bytes(&self.flags.to_le_bytes());
        p.bytes(&self.plant_pid.to_le_bytes());
        p.bytes(&self.fingerprint.to_le_bytes());
        p.bytes(&self.scenario);
        buf
    }

    /// Decodes [`StateMsg::to_bytes`]. Any bytes of the right length decode; whether the
    /// message makes sense is [`check_state`]'s question.
    pub fn from_bytes(buf: &[u8]) -> Result<StateMsg, DecodeError> {
        length(buf, STATE_BYTES)?;
        let mut g = Get { buf, at: 0 };
        let mut m = StateMsg::new(GroupKind::So3);
        m.version = g.u32();
        m.group = g.u32();
        m.seq = g.u64();
        m.t = g.f64();
        m.control_period = g.f64();
        m.stamp_ns = g.u64();
        g.f64s(&mut m.q);
        g.f64s(&mut m.v);
        g.f64s(&mut m.applied);
        m.flags = g.u32();
        m.plant_pid = g.u32();
        m.fingerprint = g.u64();
        m.scenario = g.take();
        Ok(m)
    }
}

impl CommandMsg {
    /// Little-endian encoding.
    pub fn to_bytes(&self) -> [u8; COMMAND_BYTES] {
        let mut buf = [0u8; COMMAND_BYTES];
        let mut p = Put {
            buf: &mut buf,
            at: 0,
        };
        p.bytes(&self.version.to_le_bytes());
        p.bytes(&self.group.to_le_bytes());
        for x in [
            self.seq,
            self.state_received_ns,
            self.stamp_ns,
            self.compute_ns,
        ] {
            p.bytes(&x.to_le_bytes());
        }
        p.f64s(&self.tau);
        p.f64s(&[self.lyapunov]);
        p.f64s(&self.observer);
        p.f64s(&self.integral);
        p.bytes(&self.previous_seq.to_le_bytes());
        p.f64s(&self.estimate_before);
        p.f64s(&self.z_before);
        p.bytes(&self.heap_allocations.to_le_bytes());
        p.bytes(&self.flags.to_le_bytes());
        p.bytes(&self.mismatch.to_le_bytes());
        p.bytes(&self.fingerprint.to_le_bytes());
        p.f64s(&[self.expected_period]);
        p.bytes(&self.scenario);
        p.bytes(&self.law.to_le_bytes());
        p.bytes(&self.plans_received.to_le_bytes());
        p.bytes(&self.plan_seq.to_le_bytes());
        p.bytes(&self.plan_pid.to_le_bytes());
        p.bytes(&self.reserved.to_le_bytes());
        buf
    }

    /// Decodes [`CommandMsg::to_bytes`] (see [`StateMsg::from_bytes`]).
    pub fn from_bytes(buf: &[u8]) -> Result<CommandMsg, DecodeError> {
        length(buf, COMMAND_BYTES)?;
        let mut g = Get { buf, at: 0 };
        let mut m = CommandMsg::new(GroupKind::So3);
        m.version = g.u32();
        m.group = g.u32();
        m.seq = g.u64();
        m.state_received_ns = g.u64();
        m.stamp_ns = g.u64();
        m.compute_ns = g.u64();
        g.f64s(&mut m.tau);
        m.lyapunov = g.f64();
        g.f64s(&mut m.observer);
        g.f64s(&mut m.integral);
        m.previous_seq = g.u64();
        g.f64s(&mut m.estimate_before);
        g.f64s(&mut m.z_before);
        m.heap_allocations = g.u64();
        m.flags = g.u32();
        m.mismatch = g.u32();
        m.fingerprint = g.u64();
        m.expected_period = g.f64();
        m.scenario = g.take();
        m.law = g.u32();
        m.plans_received = g.u32();
        m.plan_seq = g.u64();
        m.plan_pid = g.u32();
        m.reserved = g.u32();
        Ok(m)
    }
}

/// Why a message was rejected. Each kind is logged once and counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Reject {
    /// The protocol version differs.
    Version,
    /// The group differs from the receiver's.
    Group,
    /// A number is NaN or infinite.
    NonFinite,
    /// The sequence number did not increase, or jumped by more than [`MAX_SEQ_JUMP`] (for
    /// commands: is not the one awaited).
    Sequence,
    /// The control period is not positive, or differs from the one the receiver runs with.
    Period,
}

impl Reject {
    /// All kinds, for counters.
    pub const ALL: [Reject; 5] = [
        Reject::Version,
        Reject::Group,
        Reject::NonFinite,
        Reject::Sequence,
        Reject::Period,
    ];

    /// Index into a counter array.
    pub fn index(self) -> usize {
        self as usize
    }

    /// Lower-case name for logs.
    pub fn name(self) -> &'static str {
        match self {
            Reject::Version => "wrong protocol version",
            Reject::Group => "wrong group",
            Reject::NonFinite => "non-finite number",
            Reject::Sequence => "sequence number not increasing",
            Reject::Period => "control period mismatch",
        }
    }
}

impl core::fmt::Display for Reject {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

fn all_finite(xs: &[f64]) -> bool {
    xs.iter().all(|x| x.is_finite())
}

/// The `(n, m)` of a message's group code, if it is the receiver's group.
fn own_dims(code: u32, group: GroupKind) -> Result<(usize, usize), Reject> {
    match group_kind(code) {
        Some(g) if g == group => Ok(g.dims()),
        _ => Err(Reject::Group),
    }
}

/// How many sequence numbers a state may skip past the one expected next (0 for the first
/// state): 2²² ≈ 4.2 million cycles, 70 min at 1 kHz. A controller that joins late or
/// missed states steps its reference through every skipped cycle (≈ 0.2–0.5 µs each, so
/// at most about 2 s of catching up); an absurd jump (a corrupt or hostile sequence number
/// near 2⁶⁴) is refused instead of stalling it.
pub const MAX_SEQ_JUMP: u64 = 1 << 22;

/// Checks a state against the receiver's group, the last accepted sequence number and the
/// period the receiver runs with (`None`: any positive period). The sequence number must
/// increase, by at most [`MAX_SEQ_JUMP`] + 1.
pub fn check_state(
    msg: &StateMsg,
    group: GroupKind,
    last_seq: Option<u64>,
    period: Option<f64>,
) -> Result<(), Reject> {
    if msg.version != PROTOCOL_VERSION {
        return Err(Reject::Version);
    }
    let (n, m) = own_dims(msg.group, group)?;
    if !all_finite(&msg.q[..n * n])
        || !all_finite(&msg.v[..m])
        || !all_finite(&msg.applied[..m])
        || !msg.t.is_finite()
        || !msg.control_period.is_finite()
    {
        return Err(Reject::NonFinite);
    }
    let next = match last_seq {
        None => 0,
        Some(last) => last.checked_add(1).ok_or(Reject::Sequence)?,
    };
    if msg.seq < next || msg.seq - next > MAX_SEQ_JUMP {
        return Err(Reject::Sequence);
    }
    if msg.control_period <= 0.0 || period.is_some_and(|p| p != msg.control_period) {
        return Err(Reject::Period);
    }
    Ok(())
}

/// Checks a command against the receiver's group and the sequence number it awaits.
pub fn check_command(msg: &CommandMsg, group: GroupKind, awaited: u64) -> Result<(), Reject> {
    if msg.version != PROTOCOL_VERSION {
        return Err(Reject::Version);
    }
    let (_, m) = own_dims(msg.group, group)?;
    if !all_finite(&msg.tau[..m])
        || !msg.lyapunov.is_finite()
        || !all_finite(&msg.observer[..m])
        || !all_finite(&msg.integral[..m])
        || !all_finite(&msg.estimate_before[..m])
        || !all_finite(&msg.z_before[..m])
    {
        return Err(Reject::NonFinite);
    }
    if msg.seq != awaited {
        return Err(Reject::Sequence);
    }
    Ok(())
}

/// A service name, at most 200 bytes.
pub type Name = heapless::String<200>;

/// The names of one run's services: `eqtrack/<run>/{state, command, state_event,
/// command_event, plan, status}`, and the nodes. Several runs with different names never share a
/// service.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ServiceNames {
    /// Plant → controller states.
    pub state: Name,
    /// Controller → plant commands.
    pub command: Name,
    /// Notified after each state (event wake-up).
    pub state_event: Name,
    /// Notified after each command (event wake-up).
    pub command_event: Name,
    /// Planner → controller pieces of a streamed reference.
    pub plan: Name,
    /// The plant's flight recorder → monitors: the run's live status.
    pub status: Name,
    /// The plant's node name.
    pub plant_node: Name,
    /// The controller's node name.
    pub controller_node: Name,
    /// The planner's node name.
    pub planner_node: Name,
    /// The node of the plant's flight-recorder thread.
    pub recorder_node: Name,
    /// A monitor's node name.
    pub monitor_node: Name,
}

/// Whether `run` is a usable run name: 1 to 64 characters of `[A-Za-z0-9_-]`.
pub fn valid_run_name(run: &str) -> bool {
    !run.is_empty()
        && run.len() <= 64
        && run
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
}

/// The service names of run `run`; `None` if the name is not [`valid_run_name`].
pub fn service_names(run: &str) -> Option<ServiceNames> {
    if !valid_run_name(run) {
        return None;
    }
    let make = |prefix: &str, sep: &str, suffix: &str| {
        let mut s = Name::new();
        // at most 64 + 30 bytes: always fits in 200
        let _ = write!(s, "{prefix}{sep}{run}{suffix}");
        s
    };
    Some(ServiceNames {
        state: make("eqtrack", "/", "/state"),
        command: make("eqtrack", "/", "/command"),
        state_event: make("eqtrack", "/", "/state_event"),
        command_event: make("eqtrack", "/", "/command_event"),
        plan: make("eqtrack", "/", "/plan"),
        status: make("eqtrack", "/", "/status"),
        plant_node: make("eqtrack-plant", "-", ""),
        controller_node: make("eqtrack-controller", "-", ""),
        planner_node: make("eqtrack-planner", "-", ""),
        recorder_node: make("eqtrack-recorder", "-", ""),
        monitor_node: make("eqtrack-monitor", "-", ""),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use GroupKind::{Se3, So3};

    #[test]
    fn states_are_checked() {
        let mut s = StateMsg::new(So3);
        s.control_period = 0.01;
        assert_eq!(check_state(&s, So3, None, None), Ok(()));
        assert_eq!(check_state(&s, Se3, None, None), Err(Reject::Group));
        s.seq = 5;
        assert_eq!(check_state(&s, So3, Some(5), None), Err(Reject::Sequence));
        assert_eq!(check_state(&s, So3, Some(4), None), Ok(()));
        s.seq = 5 + MAX_SEQ_JUMP;
        assert_eq!(check_state(&s, So3, Some(4), None), Ok(()));
        s.seq += 1;
        assert_eq!(check_state(&s, So3, Some(4), None), Err(Reject::Sequence));
        s.seq = MAX_SEQ_JUMP;
        assert_eq!(check_state(&s, So3, None, None), Ok(()));
        s.seq = u64::MAX;
        assert_eq!(check_state(&s, So3, None, None), Err(Reject::Sequence));
        assert_eq!(
            check_state(&s, So3, Some(u64::MAX), None),
            Err(Reject::Sequence)
        );
        s.seq = 5;
        assert_eq!(check_state(&s, So3, None, Some(0.02)), Err(Reject::Period));
        assert_eq!(check_state(&s, So3, None, Some(0.01)), Ok(()));
        s.v[2] = f64::NAN;
        assert_eq!(check_state(&s, So3, None, None), Err(Reject::NonFinite));
        s.v[2] = 0.0;
        s.applied[1] = f64::INFINITY;
        assert_eq!(check_state(&s, So3, None, None), Err(Reject::NonFinite));
        s.applied[1] = 0.0;
        s.applied[4] = f64::NAN; // beyond m = 3: ignored
        s.v[5] = f64::NAN; // beyond m = 3: ignored
        assert_eq!(check_state(&s, So3, None, None), Ok(()));
        s.control_period = 0.0;
        assert_eq!(check_state(&s, So3, None, None), Err(Reject::Period));
        s.version = 99;
        assert_eq!(check_state(&s, So3, None, None), Err(Reject::Version));
        let mut u = StateMsg::new(So3);
        u.group = 77;
        assert_eq!(check_state(&u, So3, None, None), Err(Reject::Group));
    }

    #[test]
    fn commands_are_checked() {
        let mut c = CommandMsg::new(Se3);
        c.seq = 3;
        assert_eq!(check_command(&c, Se3, 3), Ok(()));
        assert_eq!(check_command(&c, So3, 3), Err(Reject::Group));
        assert_eq!(check_command(&c, Se3, 4), Err(Reject::Sequence));
        c.tau[5] = f64::INFINITY;
        assert_eq!(check_command(&c, Se3, 3), Err(Reject::NonFinite));
        c.tau[5] = 0.0;
        c.observer[5] = f64::NAN;
        assert_eq!(check_command(&c, Se3, 3), Err(Reject::NonFinite));
        c.observer[5] = 0.0;
        c.integral[0] = f64::NEG_INFINITY;
        assert_eq!(check_command(&c, Se3, 3), Err(Reject::NonFinite));
        c.integral[0] = 0.0;
        c.z_before[5] = f64::NAN;
        assert_eq!(check_command(&c, Se3, 3), Err(Reject::NonFinite));
        c.z_before[5] = 0.0;
        assert_eq!(check_command(&c, Se3, 3), Ok(()));
    }

    #[test]
    fn group_codes_round_trip_and_unknown_codes_are_none() {
        for g in GroupKind::ALL {
            assert_eq!(group_kind(group_code(g)), Some(g));
        }
        assert_eq!(group_kind(0), None);
        assert_eq!(group_kind(99), None);
    }

    #[test]
    fn byte_encoding_round_trips() {
        let mut s = StateMsg::new(Se3);
        s.seq = 77;
        s.t = 0.125;
        s.q[15] = -3.5;
        s.v[5] = 1e-300;
        s.applied[4] = -0.25;
        s.flags = flags::WAKE_EVENT;
        s.plant_pid = 4242;
        s.fingerprint = 0xdead_beef_0123_4567;
        s.scenario = name_bytes("se3_circle");
        assert_eq!(StateMsg::from_bytes(&s.to_bytes()), Ok(s));
        assert_eq!(
            StateMsg::from_bytes(&[0u8; 3]),
            Err(DecodeError::Length {
                expected: STATE_BYTES,
                got: 3
            })
        );
        let mut c = CommandMsg::new(So3);
        c.tau[2] = 2.5;
        c.observer[1] = -0.125;
        c.integral[0] = 0.5;
        c.previous_seq = 41;
        c.estimate_before[3] = 0.375;
        c.z_before[2] = -1.5;
        c.heap_allocations = 9;
        c.mismatch = mismatch::SCENARIO;
        c.expected_period = 0.001;
        c.law = law_code(Law::Gt);
        c.plans_received = 3;
        c.plan_seq = 41;
        c.plan_pid = 77;
        assert_eq!(CommandMsg::from_bytes(&c.to_bytes()), Ok(c));
        let b = c.to_bytes();
        assert_eq!(u32::from_le_bytes(b[364..368].try_into().unwrap()), 3);
        assert_eq!(u64::from_le_bytes(b[368..376].try_into().unwrap()), 41);
        assert_eq!(u32::from_le_bytes(b[376..380].try_into().unwrap()), 77);
        assert_eq!(
            u32::from_le_bytes(c.to_bytes()[360..364].try_into().unwrap()),
            2
        );
        assert!(CommandMsg::from_bytes(&[0u8; COMMAND_BYTES + 1]).is_err());
    }

    #[test]
    fn law_codes_round_trip_and_zero_says_nothing() {
        for law in Law::ALL {
            assert_eq!(law_from_code(law_code(law)), Some(law));
        }
        assert_eq!(law_from_code(0), None);
        assert_eq!(law_from_code(5), None);
    }

    #[test]
    fn identities_name_what_differs() {
        let plant = Identity::new(So3, 0.001, 11, "seed");
        let follows = Identity::new(So3, 0.0, 11, "seed");
        assert_eq!(follows.mismatch(&plant), 0);
        assert_eq!(
            Identity::new(Se3, 0.0, 11, "seed").mismatch(&plant),
            mismatch::GROUP
        );
        assert_eq!(
            Identity::new(So3, 0.01, 11, "seed").mismatch(&plant),
            mismatch::PERIOD
        );
        assert_eq!(
            Identity::new(So3, 0.0, 12, "montecarlo").mismatch(&plant),
            mismatch::SCENARIO
        );
        // a plant without a fingerprint (hardware) is accepted
        let board = Identity::new(So3, 0.001, 0, "");
        assert_eq!(Identity::new(So3, 0.0, 12, "x").mismatch(&board), 0);
        // names are cut at a character boundary
        let long = "é".repeat(40);
        assert_eq!(name_str(&name_bytes(&long)), "é".repeat(16));
        let mut text = heapless::String::<200>::new();
        let _ = write!(text, "{plant}");
        assert_eq!(
            text.as_str(),
            "group so3, period 0.001 s, scenario `seed` (000000000000000b)"
        );
    }

    #[test]
    fn run_names_map_to_disjoint_services() {
        let a = service_names("a").unwrap();
        let b = service_names("b").unwrap();
        assert_eq!(a.state.as_str(), "eqtrack/a/state");
        assert_eq!(a.plant_node.as_str(), "eqtrack-plant-a");
        assert_ne!(a.state, b.state);
        assert!(service_names("no spaces").is_none());
        assert!(service_names("").is_none());
    }
}
