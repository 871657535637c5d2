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
    /// The controller runs the failure detector (its commands say so).
    pub const DETECTING: u32 = 8;
    /// The controller runs the failsafe manager (its commands say so).
    pub const SUPERVISED: u32 = 16;
}

/// A run's live figures.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "zero-copy",
    derive(ZeroCopySend),
    type_name("eqtrack::StatusMsg6")
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
    /// Failures the controller's detector has found so far, refinements included (the
    /// recorded commands' findings).
    pub detections: u32,
    /// The newest finding's actuator, plus one (0: none yet).
    pub last_detected: u32,
    /// Its kind: 1 dead, 2 stuck, 3 effectiveness (0: none yet).
    pub last_detected_kind: u32,
    /// The detector's alarms so far, as its newest command says.
    pub alarms: u32,
    /// The newest finding's stuck value or factor (0: dead, or none yet).
    pub last_detected_value: f64,
    /// The failsafe manager's state word of the newest command ([`CommandMsg::failsafe`](crate::CommandMsg::failsafe);
    /// 0: nominal, or no manager runs). Protocol 9.
    pub failsafe: u32,
    /// The failsafe's transitions so far: changes of the engaged cause or action among the
    /// recorded commands.
    pub failsafe_transitions: u32,
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
            detections: 0,
            last_detected: 0,
            last_detected_kind: 0,
            alarms: 0,
            last_detected_value: 0.0,
            failsafe: 0,
            failsafe_transitions: 0,
        }
    }

    /// Takes the failsafe manager's state from command `c` (a controller that does not run it
    /// leaves it as it is): its word, and a transition counted when the engaged cause or
    /// action (the word's low byte) changed.
    pub fn note_failsafe(&mut self, c: &crate::CommandMsg) {
        if c.flags & crate::flags::SUPERVISED == 0 {
            return;
        }
        self.flags |= status_flags::SUPERVISED;
        if c.failsafe & 0xff != self.failsafe & 0xff {
            self.failsafe_transitions = self.failsafe_transitions.saturating_add(1);
        }
        self.failsafe = c.failsafe;
    }

    /// Takes the failure detector's figures from command `c` (a controller that does not run
    /// it leaves them as they are): its alarms, and its finding, if it has one, counted and
    /// kept as the newest.
    pub fn note_detection(&mut self, c: &crate::CommandMsg) {
        if c.flags & crate::flags::DETECTING == 0 {
            return;
        }
        self.flags |= status_flags::DETECTING;
        self.alarms = c.alarms;
        if c.detected > 0 {
            self.detections = self.detections.saturating_add(1);
            self.last_detected = c.detected;
            self.last_detected_kind = c.detected_kind;
            self.last_detected_value = c.detected_value;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{CommandMsg, WireGroup, flags};

    #[test]
    fn the_status_counts_the_detectors_findings() {
        let mut s = StatusMsg::new(WireGroup::Se3, "rov");
        let mut c = CommandMsg::new(WireGroup::Se3);
        // no detector: nothing taken
        c.alarms = 3;
        c.detected = 2;
        s.note_detection(&c);
        assert_eq!((s.flags, s.detections, s.alarms), (0, 0, 0));
        c.flags |= flags::DETECTING;
        c.detected = 0;
        s.note_detection(&c);
        assert_eq!((s.detections, s.alarms, s.last_detected), (0, 3, 0));
        assert_eq!(s.flags, status_flags::DETECTING);
        (c.detected, c.detected_kind, c.detected_value, c.alarms) = (7, 2, -20.0, 4);
        s.note_detection(&c);
        (c.detected, c.detected_kind, c.detected_value) = (2, 1, 0.0);
        s.note_detection(&c);
        assert_eq!(
            (
                s.detections,
                s.last_detected,
                s.last_detected_kind,
                s.alarms
            ),
            (2, 2, 1, 4)
        );
        assert_eq!(s.last_detected_value, 0.0);
    }
}
