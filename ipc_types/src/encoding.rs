//! The little-endian byte encoding of the messages, field by field (for transports that carry bytes and for the flight recorder), and its typed errors.

use crate::{CommandMsg, MAX_ACTUATORS, MAX_M, MAX_N, MAX_WHEELS, NAME_BYTES, StateMsg, WireGroup};

/// Bytes of an encoded [`StateMsg`] (little-endian, field by field).
pub const STATE_BYTES: usize = 4
    + 4
    + 8
    + 8
    + 8
    + 8
    + 8 * MAX_N * MAX_N
    + 8 * MAX_M * 2
    + 4
    + 4
    + 8
    + NAME_BYTES
    + 4
    + 4
    + 8 * MAX_WHEELS;
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
    + 4
    + 4
    + 4
    + 8 * MAX_M * 3
    + 8 * MAX_ACTUATORS * 2
    + 4
    + 4
    + 8
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
        p.bytes(&self.wheels.to_le_bytes());
        p.bytes(&self.reserved_wheels.to_le_bytes());
        p.f64s(&self.wheel_speeds);
        buf
    }

    /// Decodes [`StateMsg::to_bytes`]. Any bytes of the right length decode; whether the
    /// message makes sense is [`check_state`](crate::check_state)'s question.
    pub fn from_bytes(buf: &[u8]) -> Result<StateMsg, DecodeError> {
        length(buf, STATE_BYTES)?;
        let mut g = Get { buf, at: 0 };
        let mut m = StateMsg::new(WireGroup::So3);
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
        m.wheels = g.u32();
        m.reserved_wheels = g.u32();
        g.f64s(&mut m.wheel_speeds);
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
        p.bytes(&self.failsafe.to_le_bytes());
        p.bytes(&self.actuators.to_le_bytes());
        p.bytes(&self.alloc_status.to_le_bytes());
        p.f64s(&self.demand);
        p.f64s(&self.achieved);
        p.f64s(&self.accounted);
        p.f64s(&self.u_previous);
        p.f64s(&self.u_cmd);
        p.bytes(&self.detected.to_le_bytes());
        p.bytes(&self.detected_kind.to_le_bytes());
        p.f64s(&[self.detected_value]);
        p.bytes(&self.detected_refined.to_le_bytes());
        p.bytes(&self.alarms.to_le_bytes());
        p.f64s(&[self.statistic]);
        p.bytes(&self.suspect.to_le_bytes());
        p.bytes(&self.reserved_detector.to_le_bytes());
        buf
    }

    /// Decodes [`CommandMsg::to_bytes`] (see [`StateMsg::from_bytes`]).
    pub fn from_bytes(buf: &[u8]) -> Result<CommandMsg, DecodeError> {
        length(buf, COMMAND_BYTES)?;
        let mut g = Get { buf, at: 0 };
        let mut m = CommandMsg::new(WireGroup::So3);
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
        m.failsafe = g.u32();
        m.actuators = g.u32();
        m.alloc_status = g.u32();
        g.f64s(&mut m.demand);
        g.f64s(&mut m.achieved);
        g.f64s(&mut m.accounted);
        g.f64s(&mut m.u_previous);
        g.f64s(&mut m.u_cmd);
        m.detected = g.u32();
        m.detected_kind = g.u32();
        m.detected_value = g.f64();
        m.detected_refined = g.u32();
        m.alarms = g.u32();
        m.statistic = g.f64();
        m.suspect = g.u32();
        m.reserved_detector = g.u32();
        Ok(m)
    }
}
