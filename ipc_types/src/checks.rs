//! The checks every receiver applies before a message is used, and why a message is rejected ([`Invalid`]).

use crate::{CommandMsg, PROTOCOL_VERSION, StateMsg, WireGroup};

/// Why a message is invalid (it failed its check; it is never used). Each kind is logged once and counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Invalid {
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
    /// A command's actuator count is not the receiver's vehicle's (0 without a vehicle), or
    /// a state carries more wheels than [`MAX_WHEELS`](crate::MAX_WHEELS).
    Actuators,
    /// A command's detection (or its last test's suspect) names no actuator of the vehicle or
    /// no kind, or has fields set when nothing was found or no detector runs.
    Detection,
    /// A command's failsafe word is not one the manager writes (docs/wire.md).
    Failsafe,
}

impl Invalid {
    /// How many kinds there are.
    pub const KINDS: usize = 8;
    /// All kinds, for counters.
    pub const ALL: [Invalid; Invalid::KINDS] = [
        Invalid::Version,
        Invalid::Group,
        Invalid::NonFinite,
        Invalid::Sequence,
        Invalid::Period,
        Invalid::Actuators,
        Invalid::Detection,
        Invalid::Failsafe,
    ];

    /// Index into a counter array.
    pub fn index(self) -> usize {
        self as usize
    }

    /// Lower-case name for logs.
    pub fn name(self) -> &'static str {
        match self {
            Invalid::Version => "wrong protocol version",
            Invalid::Group => "wrong group",
            Invalid::NonFinite => "non-finite number",
            Invalid::Sequence => "sequence number not increasing",
            Invalid::Period => "control period mismatch",
            Invalid::Actuators => "actuator count not the plant's, or a wheel count past 6",
            Invalid::Detection => "detection of no actuator or kind",
            Invalid::Failsafe => "failsafe word of no action or cause",
        }
    }
}

impl core::fmt::Display for Invalid {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

pub(crate) fn all_finite(xs: &[f64]) -> bool {
    xs.iter().all(|x| x.is_finite())
}

/// The `(n, m)` of a message's group code, if it is the receiver's group.
pub(crate) fn own_dims(code: u32, group: WireGroup) -> Result<(usize, usize), Invalid> {
    match WireGroup::from_code(code) {
        Some(g) if g == group => Ok(g.dims()),
        _ => Err(Invalid::Group),
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
    group: WireGroup,
    last_seq: Option<u64>,
    period: Option<f64>,
) -> Result<(), Invalid> {
    if msg.version != PROTOCOL_VERSION {
        return Err(Invalid::Version);
    }
    let (n, m) = own_dims(msg.group, group)?;
    if !all_finite(&msg.q[..n * n])
        || !all_finite(&msg.v[..m])
        || !all_finite(&msg.applied[..m])
        || !msg.t.is_finite()
        || !msg.control_period.is_finite()
    {
        return Err(Invalid::NonFinite);
    }
    if msg.wheels as usize > crate::MAX_WHEELS || msg.reserved_wheels != 0 {
        return Err(Invalid::Actuators);
    }
    if !all_finite(msg.wheel_speeds()) {
        return Err(Invalid::NonFinite);
    }
    let next = match last_seq {
        None => 0,
        Some(last) => last.checked_add(1).ok_or(Invalid::Sequence)?,
    };
    if msg.seq < next || msg.seq - next > MAX_SEQ_JUMP {
        return Err(Invalid::Sequence);
    }
    if msg.control_period <= 0.0 || period.is_some_and(|p| p != msg.control_period) {
        return Err(Invalid::Period);
    }
    Ok(())
}

/// Checks a command against the receiver's group, the sequence number it awaits and its
/// vehicle's actuator count (0: no vehicle).
pub fn check_command(
    msg: &CommandMsg,
    group: WireGroup,
    awaited: u64,
    actuators: u32,
) -> Result<(), Invalid> {
    if msg.version != PROTOCOL_VERSION {
        return Err(Invalid::Version);
    }
    let (_, m) = own_dims(msg.group, group)?;
    if msg.actuators != actuators || msg.actuators as usize > crate::MAX_ACTUATORS {
        return Err(Invalid::Actuators);
    }
    let count = msg.actuators as usize;
    if !all_finite(&msg.tau[..m])
        || !msg.lyapunov.is_finite()
        || !all_finite(&msg.observer[..m])
        || !all_finite(&msg.integral[..m])
        || !all_finite(&msg.estimate_before[..m])
        || !all_finite(&msg.z_before[..m])
        || !all_finite(&msg.demand[..m])
        || !all_finite(&msg.achieved[..m])
        || !all_finite(&msg.accounted[..m])
        || !all_finite(&msg.u_previous[..count])
        || !all_finite(&msg.u_cmd[..count])
        || !msg.detected_value.is_finite()
        || !msg.statistic.is_finite()
    {
        return Err(Invalid::NonFinite);
    }
    let found = msg.detected > 0;
    let detecting = msg.flags & crate::flags::DETECTING != 0;
    let silent = (
        msg.detected,
        msg.detected_kind,
        msg.detected_value,
        msg.detected_refined,
        msg.alarms,
        msg.statistic,
        msg.suspect,
    ) == (0, 0, 0.0, 0, 0, 0.0, 0);
    if (!detecting && !silent)
        || msg.reserved_detector != 0
        || msg.detected > msg.actuators
        || msg.suspect > msg.actuators
        || (found && !(1..=3).contains(&msg.detected_kind))
        || msg.detected_refined > 1
        || (!found && (msg.detected_kind, msg.detected_value, msg.detected_refined) != (0, 0.0, 0))
    {
        return Err(Invalid::Detection);
    }
    let supervised = msg.flags & crate::flags::SUPERVISED != 0;
    if !failsafe_word(msg.failsafe) || (!supervised && msg.failsafe != 0) {
        return Err(Invalid::Failsafe);
    }
    if msg.seq != awaited {
        return Err(Invalid::Sequence);
    }
    Ok(())
}

/// Whether `w` is a failsafe word the manager writes ([`CommandMsg::failsafe`]): no bit
/// above 11, an action code of at most 6 with a cause code of at most 4, both or neither,
/// and the engaged cause among the raised ones.
pub fn failsafe_word(w: u32) -> bool {
    let (action, cause) = (w & 0xf, w >> 4 & 0xf);
    w >> 12 == 0
        && action <= 6
        && cause <= 4
        && (action == 0) == (cause == 0)
        && (cause == 0 || w & 1 << (7 + cause) != 0)
}
