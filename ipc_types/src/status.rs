//! The live status of a run: what `plant_sim monitor` shows, published by the plant's
//! flight-recorder thread (never by its loop) about 20 times a second on the run's `status`
//! board. Figures over "the last second" cover the cycles whose states were published in the
//! second before the newest one.

use crate::WireGroup;
use crate::{NAME_BYTES, PROTOCOL_VERSION, name_bytes};
#[cfg(feature = "zero-copy")]
use iceoryx2_bb_derive_macros::ZeroCopySend;
#[cfg(feature = "zero-copy")]
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// [`StatusMsg::flags`] bits.
pub mod status_flags {
    /// The last cycle ran in safe mode.
    pub const SAFE_MODE: u32 = 1;
    /// The run has ended (the last status of the run).
    pub const ENDED: u32 = 2;
    /// The plant runs in real time (else lockstep).
    pub const REALTIME: u32 = 4;
}

/// A run's live figures.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "zero-copy",
    derive(ZeroCopySend),
    type_name("eqtrack::StatusMsg4")
)]
#[repr(C)]
pub struct StatusMsg {
    /// [`PROTOCOL_VERSION`] (0: nothing written yet).
    pub version: u32,
    /// [`WireGroup::code`].
    pub group: u32,
    /// Increases with every publication.
    pub seq: u64,
    /// CLOCK_MONOTONIC at publication (ns).
    pub stamp_ns: u64,
    /// The newest cycle k recorded.
    pub cycle: u64,
    /// Its time `t_k` (s).
    pub t: f64,
    /// The rate the plant runs at (Hz; 0: lockstep).
    pub target_rate_hz: f64,
    /// Cycles in the last second, counted (in a run's first second: the cycles so far).
    pub rate_hz: f64,
    /// Round trip (state published → command received), median over the last second (ns).
    pub rtt_p50_ns: u64,
    /// Its 99th percentile over the last second (ns).
    pub rtt_p99_ns: u64,
    /// Its maximum over the last second (ns).
    pub rtt_max_ns: u64,
    /// Deadline misses since the start.
    pub misses: u64,
    /// Times safe mode was entered.
    pub safe_mode_entries: u64,
    /// The Lyapunov value of the newest command (NaN: none yet).
    pub lyapunov: f64,
    /// CLOCK_MONOTONIC when the newest command arrived (ns; 0: none yet).
    pub last_command_ns: u64,
    /// [`status_flags`] bits.
    pub flags: u32,
    /// The plant's process id.
    pub plant_pid: u32,
    /// The scenario's name, UTF-8, NUL-padded.
    pub scenario: [u8; NAME_BYTES],
}

impl StatusMsg {
    /// A status of the current protocol with nothing measured yet.
    pub fn new(group: WireGroup, scenario: &str) -> StatusMsg {
        StatusMsg {
            version: PROTOCOL_VERSION,
            group: group.code(),
            seq: 0,
            stamp_ns: 0,
            cycle: 0,
            t: 0.0,
            target_rate_hz: 0.0,
            rate_hz: 0.0,
            rtt_p50_ns: 0,
            rtt_p99_ns: 0,
            rtt_max_ns: 0,
            misses: 0,
            safe_mode_entries: 0,
            lyapunov: f64::NAN,
            last_command_ns: 0,
            flags: 0,
            plant_pid: 0,
            scenario: name_bytes(scenario),
        }
    }
}
