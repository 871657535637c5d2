//! The only contract between the plant and the controller processes: fixed-size `#[repr(C)]`
//! messages that cross iceoryx2 shared memory, the service names of a run, and the protocol
//! version. `#![no_std]` with no `alloc`. Features: `zero-copy` (default) derives iceoryx2's
//! `ZeroCopySend` on the messages (iceoryx2's trait crate links `alloc`); `std` adds `ipc`,
//! the one place where the services are opened (both processes use identical settings).
//!
//! One control cycle (DESIGN.md): the plant publishes [`StateMsg`] `{seq k, t_k, Q, V}`; the
//! controller answers with [`CommandMsg`] `{seq k, τ_k, L, compute time}`.
#![cfg_attr(not(feature = "std"), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

use core::fmt::Write;
#[cfg(feature = "zero-copy")]
use iceoryx2_bb_derive_macros::ZeroCopySend;
#[cfg(feature = "zero-copy")]
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

#[cfg(feature = "std")]
pub mod ipc;
#[cfg(feature = "std")]
pub mod uds;

/// Bumped whenever a message layout or meaning changes.
pub const PROTOCOL_VERSION: u32 = 1;
/// The largest n (configuration matrices are n×n) any supported group needs.
pub const MAX_N: usize = 4;
/// The largest m (algebra dimension) any supported group needs.
pub const MAX_M: usize = 6;

/// Group codes on the wire.
pub mod group {
    /// SO(3): n = m = 3.
    pub const SO3: u32 = 1;
    /// SE(3): n = 4, m = 6.
    pub const SE3: u32 = 2;
}

/// Bits of [`StateMsg::flags`].
pub mod flags {
    /// The plant waits for commands on the event service: notify after each command.
    pub const WAKE_EVENT: u32 = 1;
    /// The run is over: the controller exits cleanly.
    pub const SHUTDOWN: u32 = 2;
}

/// The plant's state at `t_k`: configuration and body velocity (what a gyro measures).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "zero-copy",
    derive(ZeroCopySend),
    type_name("eqtrack::StateMsg")
)]
#[repr(C)]
pub struct StateMsg {
    /// [`PROTOCOL_VERSION`].
    pub version: u32,
    /// [`group`] code.
    pub group: u32,
    /// Control step k (strictly increasing).
    pub seq: u64,
    /// Simulated time `t_k = k·control_period` (s).
    pub t: f64,
    /// The plant's control period (s); the controller's reference steps with it.
    pub control_period: f64,
    /// CLOCK_MONOTONIC at publication (ns).
    pub stamp_ns: u64,
    /// `Q`, row-major n×n in the first n² entries.
    pub q: [f64; MAX_N * MAX_N],
    /// Body velocity `V` in the first m entries (SE(3): ω then v).
    pub v: [f64; MAX_M],
    /// [`flags`] bits.
    pub flags: u32,
    /// Reserved, zero.
    pub reserved: u32,
}

/// The controller's answer to state k.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "zero-copy",
    derive(ZeroCopySend),
    type_name("eqtrack::CommandMsg")
)]
#[repr(C)]
pub struct CommandMsg {
    /// [`PROTOCOL_VERSION`].
    pub version: u32,
    /// [`group`] code.
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
    /// Heap allocations the controller made since the end of its first cycle (diagnostic).
    pub heap_allocations: u64,
}

impl StateMsg {
    /// A zeroed message with the version and group filled in.
    pub fn new(group: u32) -> Self {
        StateMsg {
            version: PROTOCOL_VERSION,
            group,
            seq: 0,
            t: 0.0,
            control_period: 0.0,
            stamp_ns: 0,
            q: [0.0; MAX_N * MAX_N],
            v: [0.0; MAX_M],
            flags: 0,
            reserved: 0,
        }
    }
}

impl CommandMsg {
    /// A zeroed message with the version and group filled in.
    pub fn new(group: u32) -> Self {
        CommandMsg {
            version: PROTOCOL_VERSION,
            group,
            seq: 0,
            state_received_ns: 0,
            stamp_ns: 0,
            compute_ns: 0,
            tau: [0.0; MAX_M],
            lyapunov: 0.0,
            heap_allocations: 0,
        }
    }
}

/// Bytes of an encoded [`StateMsg`] (little-endian, field by field).
pub const STATE_BYTES: usize = 4 + 4 + 8 + 8 + 8 + 8 + 8 * MAX_N * MAX_N + 8 * MAX_M + 4 + 4;
/// Bytes of an encoded [`CommandMsg`].
pub const COMMAND_BYTES: usize = 4 + 4 + 8 * 4 + 8 * MAX_M + 8 + 8;

/// Writes fields into a byte buffer in order (for transports that carry bytes, such as the
/// Unix-socket baseline).
struct Put<'a> {
    buf: &'a mut [u8],
    at: usize,
}

impl Put<'_> {
    fn bytes<const K: usize>(&mut self, b: [u8; K]) {
        self.buf[self.at..self.at + K].copy_from_slice(&b);
        self.at += K;
    }
}

/// Reads fields back in the same order.
struct Get<'a> {
    buf: &'a [u8],
    at: usize,
}

impl Get<'_> {
    fn bytes<const K: usize>(&mut self) -> [u8; K] {
        let mut b = [0u8; K];
        b.copy_from_slice(&self.buf[self.at..self.at + K]);
        self.at += K;
        b
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.bytes())
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.bytes())
    }
    fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.bytes())
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
        p.bytes(self.version.to_le_bytes());
        p.bytes(self.group.to_le_bytes());
        p.bytes(self.seq.to_le_bytes());
        p.bytes(self.t.to_le_bytes());
        p.bytes(self.control_period.to_le_bytes());
        p.bytes(self.stamp_ns.to_le_bytes());
        for x in self.q {
            p.bytes(x.to_le_bytes());
        }
        for x in self.v {
            p.bytes(x.to_le_bytes());
        }
        p.bytes(self.flags.to_le_bytes());
        p.bytes(self.reserved.to_le_bytes());
        buf
    }

    /// Decodes [`StateMsg::to_bytes`]; `None` for a buffer of the wrong length.
    pub fn from_bytes(buf: &[u8]) -> Option<StateMsg> {
        if buf.len() != STATE_BYTES {
            return None;
        }
        let mut g = Get { buf, at: 0 };
        let mut m = StateMsg::new(0);
        m.version = g.u32();
        m.group = g.u32();
        m.seq = g.u64();
        m.t = g.f64();
        m.control_period = g.f64();
        m.stamp_ns = g.u64();
        for x in m.q.iter_mut() {
            *x = g.f64();
        }
        for x in m.v.iter_mut() {
            *x = g.f64();
        }
        m.flags = g.u32();
        m.reserved = g.u32();
        Some(m)
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
        p.bytes(self.version.to_le_bytes());
        p.bytes(self.group.to_le_bytes());
        p.bytes(self.seq.to_le_bytes());
        p.bytes(self.state_received_ns.to_le_bytes());
        p.bytes(self.stamp_ns.to_le_bytes());
        p.bytes(self.compute_ns.to_le_bytes());
        for x in self.tau {
            p.bytes(x.to_le_bytes());
        }
        p.bytes(self.lyapunov.to_le_bytes());
        p.bytes(self.heap_allocations.to_le_bytes());
        buf
    }

    /// Decodes [`CommandMsg::to_bytes`]; `None` for a buffer of the wrong length.
    pub fn from_bytes(buf: &[u8]) -> Option<CommandMsg> {
        if buf.len() != COMMAND_BYTES {
            return None;
        }
        let mut g = Get { buf, at: 0 };
        let mut m = CommandMsg::new(0);
        m.version = g.u32();
        m.group = g.u32();
        m.seq = g.u64();
        m.state_received_ns = g.u64();
        m.stamp_ns = g.u64();
        m.compute_ns = g.u64();
        for x in m.tau.iter_mut() {
            *x = g.f64();
        }
        m.lyapunov = g.f64();
        m.heap_allocations = g.u64();
        Some(m)
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
    /// The sequence number did not increase (or, for commands, is not the one awaited).
    Sequence,
    /// The control period differs from the one the receiver runs with.
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

fn all_finite(xs: &[f64]) -> bool {
    xs.iter().all(|x| x.is_finite())
}

/// `(n, m)` of a group code, `None` for an unknown code.
pub fn dims(group: u32) -> Option<(usize, usize)> {
    match group {
        group::SO3 => Some((3, 3)),
        group::SE3 => Some((4, 6)),
        _ => None,
    }
}

/// Checks a state against the receiver's group and the last accepted sequence number.
pub fn check_state(msg: &StateMsg, group: u32, last_seq: Option<u64>) -> Result<(), Reject> {
    if msg.version != PROTOCOL_VERSION {
        return Err(Reject::Version);
    }
    let Some((n, m)) = dims(msg.group).filter(|_| msg.group == group) else {
        return Err(Reject::Group);
    };
    if !all_finite(&msg.q[..n * n])
        || !all_finite(&msg.v[..m])
        || !msg.t.is_finite()
        || !msg.control_period.is_finite()
    {
        return Err(Reject::NonFinite);
    }
    if let Some(last) = last_seq
        && msg.seq <= last
    {
        return Err(Reject::Sequence);
    }
    Ok(())
}

/// Checks a command against the receiver's group and the sequence number it awaits.
pub fn check_command(msg: &CommandMsg, group: u32, awaited: u64) -> Result<(), Reject> {
    if msg.version != PROTOCOL_VERSION {
        return Err(Reject::Version);
    }
    let Some((_, m)) = dims(msg.group).filter(|_| msg.group == group) else {
        return Err(Reject::Group);
    };
    if !all_finite(&msg.tau[..m]) || !msg.lyapunov.is_finite() {
        return Err(Reject::NonFinite);
    }
    if msg.seq != awaited {
        return Err(Reject::Sequence);
    }
    Ok(())
}

/// A service name, at most 200 bytes.
pub type Name = heapless::String<200>;

/// The names of one run's four services: `eqtrack/<run>/{state, command, state_event,
/// command_event}`. Several runs with different names never share a service.
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
    /// The plant's node name.
    pub plant_node: Name,
    /// The controller's node name.
    pub controller_node: Name,
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
    let make = |suffix: &str| {
        let mut s = Name::new();
        // 64 + 20 bytes always fit in 200.
        let _ = write!(s, "eqtrack/{run}/{suffix}");
        s
    };
    let node = |role: &str| {
        let mut s = Name::new();
        let _ = write!(s, "eqtrack-{role}-{run}");
        s
    };
    Some(ServiceNames {
        state: make("state"),
        command: make("command"),
        state_event: make("state_event"),
        command_event: make("command_event"),
        plant_node: node("plant"),
        controller_node: node("controller"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn states_are_checked() {
        let mut s = StateMsg::new(group::SO3);
        assert_eq!(check_state(&s, group::SO3, None), Ok(()));
        assert_eq!(check_state(&s, group::SE3, None), Err(Reject::Group));
        s.seq = 5;
        assert_eq!(check_state(&s, group::SO3, Some(5)), Err(Reject::Sequence));
        assert_eq!(check_state(&s, group::SO3, Some(4)), Ok(()));
        s.v[2] = f64::NAN;
        assert_eq!(check_state(&s, group::SO3, None), Err(Reject::NonFinite));
        s.v[2] = 0.0;
        s.v[5] = f64::NAN; // beyond m = 3: ignored
        assert_eq!(check_state(&s, group::SO3, None), Ok(()));
        s.version = 99;
        assert_eq!(check_state(&s, group::SO3, None), Err(Reject::Version));
        let mut u = StateMsg::new(77);
        u.group = 77;
        assert_eq!(check_state(&u, 77, None), Err(Reject::Group));
    }

    #[test]
    fn commands_are_checked() {
        let mut c = CommandMsg::new(group::SE3);
        c.seq = 3;
        assert_eq!(check_command(&c, group::SE3, 3), Ok(()));
        assert_eq!(check_command(&c, group::SE3, 4), Err(Reject::Sequence));
        c.tau[5] = f64::INFINITY;
        assert_eq!(check_command(&c, group::SE3, 3), Err(Reject::NonFinite));
    }

    #[test]
    fn byte_encoding_round_trips() {
        let mut s = StateMsg::new(group::SE3);
        s.seq = 77;
        s.t = 0.125;
        s.q[15] = -3.5;
        s.v[5] = 1e-300;
        s.flags = flags::WAKE_EVENT;
        assert_eq!(StateMsg::from_bytes(&s.to_bytes()), Some(s));
        assert_eq!(StateMsg::from_bytes(&[0u8; 3]), None);
        let mut c = CommandMsg::new(group::SO3);
        c.tau[2] = 2.5;
        c.heap_allocations = 9;
        assert_eq!(CommandMsg::from_bytes(&c.to_bytes()), Some(c));
    }

    #[test]
    fn run_names_map_to_disjoint_services() {
        let a = service_names("a").unwrap();
        let b = service_names("b").unwrap();
        assert_eq!(a.state.as_str(), "eqtrack/a/state");
        assert_ne!(a.state, b.state);
        assert!(service_names("no spaces").is_none());
        assert!(service_names("").is_none());
    }
}
