//! Run-time parameters (docs/wire.md, "Run-time parameters"): the gains a running pair can
//! change, and the messages that carry a change.
//!
//! * [`ParamMsg`]: the plant's `params` board. In a run started with `plant_sim run
//!   --tunable` every state has [`flags::TUNABLE`](crate::flags::TUNABLE) set, and the
//!   controller reads this board before it answers: the gains to use for state k are the
//!   set with the largest `cycle` ≤ k. Each answer then has
//!   [`flags::TUNED`](crate::flags::TUNED) set, so the plant knows the controller reads the
//!   board.
//! * [`ParamRequest`] and [`ParamResponse`]: the run's `param` request-response service,
//!   which `plant_sim param` uses to read and change a gain by its scenario key.

use crate::{MAX_M, MAX_N, PROTOCOL_VERSION, WireGroup};
#[cfg(feature = "zero-copy")]
use iceoryx2_bb_derive_macros::ZeroCopySend;
#[cfg(feature = "zero-copy")]
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// The controller's gains from one cycle on: the scenario's `controller.kp` (`K`, n×n),
/// `controller.kd` (`K_d`, m×m), and the disturbance-rejection gains (zeros where the
/// scenario has no such term). Matrices row-major; entries past the group's size are 0.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "zero-copy",
    derive(ZeroCopySend),
    type_name("eqtrack::Gains1")
)]
#[repr(C)]
pub struct Gains {
    /// The first cycle these gains answer.
    pub cycle: u64,
    /// `K`, n×n row-major.
    pub k: [f64; MAX_N * MAX_N],
    /// `K_d`, m×m row-major.
    pub kd: [f64; MAX_M * MAX_M],
    /// The disturbance observer's `L` per axis.
    pub observer: [f64; MAX_M],
    /// The integral's `K_I` per axis.
    pub ki: [f64; MAX_M],
    /// The integral's `c` per axis.
    pub c: [f64; MAX_M],
}

impl Gains {
    /// Zero gains from cycle 0 (no set: a board nothing was written to).
    pub const ZERO: Gains = Gains {
        cycle: 0,
        k: [0.0; MAX_N * MAX_N],
        kd: [0.0; MAX_M * MAX_M],
        observer: [0.0; MAX_M],
        ki: [0.0; MAX_M],
        c: [0.0; MAX_M],
    };

    /// The gains of a scenario's slices (`kp`: n² entries, `kd`: m², the others m or
    /// `None`) from `cycle` on. Entries beyond the message's room are dropped; a short slice
    /// leaves zeros (which the controller refuses).
    pub fn from_slices(
        cycle: u64,
        k: &[f64],
        kd: &[f64],
        observer: Option<&[f64]>,
        integral: Option<(&[f64], &[f64])>,
    ) -> Gains {
        fn fill<const L: usize>(to: &mut [f64; L], from: &[f64]) {
            for (t, f) in to.iter_mut().zip(from) {
                *t = *f;
            }
        }
        let mut g = Gains {
            cycle,
            ..Gains::ZERO
        };
        fill(&mut g.k, k);
        fill(&mut g.kd, kd);
        if let Some(o) = observer {
            fill(&mut g.observer, o);
        }
        if let Some((ki, c)) = integral {
            fill(&mut g.ki, ki);
            fill(&mut g.c, c);
        }
        g
    }

    /// Whether every entry is finite.
    pub fn finite(&self) -> bool {
        self.k
            .iter()
            .chain(&self.kd)
            .chain(&self.observer)
            .chain(&self.ki)
            .chain(&self.c)
            .all(|x| x.is_finite())
    }
}

/// The plant's `params` board: the gains in force and the set before them, so that a
/// controller that answers an older state than the newest still finds that state's gains.
/// The plant changes the gains at most once a cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "zero-copy",
    derive(ZeroCopySend),
    type_name("eqtrack::ParamMsg1")
)]
#[repr(C)]
pub struct ParamMsg {
    /// [`PROTOCOL_VERSION`]; 0: nothing written yet.
    pub version: u32,
    /// The group code.
    pub group: u32,
    /// How many changes the run has had (0: the scenario's gains).
    pub seq: u64,
    /// CLOCK_MONOTONIC ns of the write (a reader takes the newest slot by it).
    pub stamp_ns: u64,
    /// The run's scenario fingerprint, as the handshake checked it: a controller takes only
    /// the board of its own run.
    pub fingerprint: u64,
    /// The gains from `current.cycle` on.
    pub current: Gains,
    /// The gains before `current.cycle` (from `previous.cycle` on).
    pub previous: Gains,
}

/// Why a [`ParamMsg`] cannot answer a state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamInvalid {
    /// Another protocol version (or nothing written yet).
    Version,
    /// Another group.
    Group,
    /// Another run's scenario.
    Fingerprint,
    /// A gain that is not finite.
    NotFinite,
    /// The state is older than both sets: its gains are gone from the board.
    TooOld,
}

impl core::fmt::Display for ParamInvalid {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            ParamInvalid::Version => "params board: another protocol version, or empty",
            ParamInvalid::Group => "params board: another group",
            ParamInvalid::Fingerprint => "params board: another run's scenario fingerprint",
            ParamInvalid::NotFinite => "params board: a gain is not finite",
            ParamInvalid::TooOld => {
                "params board: the state is older than both gain sets on the board"
            }
        })
    }
}

impl ParamMsg {
    /// The board of a run before any change: the scenario's gains from cycle 0, both sets.
    pub fn new(group: WireGroup, fingerprint: u64, gains: Gains) -> ParamMsg {
        ParamMsg {
            version: PROTOCOL_VERSION,
            group: group.code(),
            seq: 0,
            stamp_ns: 0,
            fingerprint,
            current: gains,
            previous: gains,
        }
    }

    /// The board after a change to `gains` (whose `cycle` is the first cycle they answer).
    pub fn changed(&self, gains: Gains) -> ParamMsg {
        ParamMsg {
            seq: self.seq.wrapping_add(1),
            previous: self.current,
            current: gains,
            ..*self
        }
    }

    /// The gains that answer state `seq` of a run with this `group` and `fingerprint`,
    /// checked (the receiver's check of this message).
    pub fn gains_for(
        &self,
        seq: u64,
        group: u32,
        fingerprint: u64,
    ) -> Result<&Gains, ParamInvalid> {
        if self.version != PROTOCOL_VERSION {
            return Err(ParamInvalid::Version);
        }
        if self.group != group {
            return Err(ParamInvalid::Group);
        }
        if self.fingerprint != fingerprint {
            return Err(ParamInvalid::Fingerprint);
        }
        let g = if seq >= self.current.cycle {
            &self.current
        } else if seq >= self.previous.cycle {
            &self.previous
        } else {
            return Err(ParamInvalid::TooOld);
        };
        if g.finite() {
            Ok(g)
        } else {
            Err(ParamInvalid::NotFinite)
        }
    }
}

/// Bytes of a parameter's key in a request.
pub const PARAM_KEY_BYTES: usize = 64;
/// Bytes of a parameter's value in a request (its TOML text).
pub const PARAM_VALUE_BYTES: usize = 512;
/// Bytes of a response's text.
pub const PARAM_TEXT_BYTES: usize = 1024;

/// What a [`ParamRequest`] asks.
pub mod param_op {
    /// Read the value in force.
    pub const GET: u32 = 1;
    /// Change it.
    pub const SET: u32 = 2;
}

/// A request on the run's `param` service: `op` ([`param_op`]), the scenario key and, to
/// set, the value as TOML text (UTF-8, NUL-padded).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "zero-copy",
    derive(ZeroCopySend),
    type_name("eqtrack::ParamRequest1")
)]
#[repr(C)]
pub struct ParamRequest {
    /// [`PROTOCOL_VERSION`].
    pub version: u32,
    /// [`param_op::GET`] or [`param_op::SET`].
    pub op: u32,
    /// The key, e.g. `controller.kd` or `kd`.
    pub key: [u8; PARAM_KEY_BYTES],
    /// The value's TOML text (set only).
    pub value: [u8; PARAM_VALUE_BYTES],
}

impl Default for ParamRequest {
    fn default() -> Self {
        ParamRequest {
            version: PROTOCOL_VERSION,
            op: 0,
            key: [0; PARAM_KEY_BYTES],
            value: [0; PARAM_VALUE_BYTES],
        }
    }
}

/// The answer to a [`ParamRequest`]: whether it was done, the cycle a change took effect
/// at, and a text: the value (get, set) or why it was refused, with the scenario's own
/// message for a bad value.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "zero-copy",
    derive(ZeroCopySend),
    type_name("eqtrack::ParamResponse1")
)]
#[repr(C)]
pub struct ParamResponse {
    /// [`PROTOCOL_VERSION`].
    pub version: u32,
    /// 1: done; 0: refused.
    pub ok: u32,
    /// A change: the first cycle it answered.
    pub cycle: u64,
    /// The value, or the reason (UTF-8, NUL-padded; cut at a character boundary).
    pub text: [u8; PARAM_TEXT_BYTES],
}

impl Default for ParamResponse {
    fn default() -> Self {
        ParamResponse {
            version: PROTOCOL_VERSION,
            ok: 0,
            cycle: 0,
            text: [0; PARAM_TEXT_BYTES],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gains(cycle: u64, kd: f64) -> Gains {
        Gains::from_slices(cycle, &[1.0; 9], &[kd; 9], None, None)
    }

    #[test]
    fn the_set_in_force_is_the_newest_not_after_the_state() {
        let board = ParamMsg::new(WireGroup::So3, 7, gains(0, 0.5));
        let changed = board.changed(gains(100, 0.8));
        let g = WireGroup::So3.code();
        assert_eq!(changed.seq, 1);
        assert_eq!(changed.gains_for(99, g, 7).unwrap().kd[0], 0.5);
        assert_eq!(changed.gains_for(100, g, 7).unwrap().kd[0], 0.8);
        assert_eq!(changed.gains_for(5000, g, 7).unwrap().kd[0], 0.8);
        let twice = changed.changed(gains(101, 0.9));
        assert_eq!(twice.gains_for(100, g, 7).unwrap().kd[0], 0.8);
        assert_eq!(twice.gains_for(99, g, 7), Err(ParamInvalid::TooOld));
    }

    #[test]
    fn another_run_group_version_or_a_nan_is_refused() {
        let board = ParamMsg::new(WireGroup::So3, 7, gains(0, 0.5));
        let g = WireGroup::So3.code();
        assert_eq!(board.gains_for(3, g, 8), Err(ParamInvalid::Fingerprint));
        assert_eq!(
            board.gains_for(3, WireGroup::Se3.code(), 7),
            Err(ParamInvalid::Group)
        );
        let mut old = board;
        old.version = 0;
        assert_eq!(old.gains_for(3, g, 7), Err(ParamInvalid::Version));
        let nan = board.changed(gains(2, f64::NAN));
        assert_eq!(nan.gains_for(3, g, 7), Err(ParamInvalid::NotFinite));
        assert!(nan.gains_for(1, g, 7).is_ok());
    }

    #[test]
    fn sizes_and_offsets_are_docs_wire_md_s() {
        assert_eq!(core::mem::size_of::<Gains>(), 568);
        assert_eq!(core::mem::size_of::<ParamMsg>(), 1168);
        assert_eq!(core::mem::offset_of!(ParamMsg, current), 32);
        assert_eq!(core::mem::offset_of!(ParamMsg, previous), 600);
        assert_eq!(core::mem::size_of::<ParamRequest>(), 584);
        assert_eq!(core::mem::size_of::<ParamResponse>(), 1040);
    }

    #[test]
    fn slices_fill_the_front_and_leave_zeros() {
        let g = Gains::from_slices(3, &[2.0; 9], &[1.0; 36], Some(&[4.0; 3]), None);
        assert_eq!(g.cycle, 3);
        assert_eq!(&g.k[..9], &[2.0; 9]);
        assert_eq!(&g.k[9..], &[0.0; 7]);
        assert_eq!(g.kd, [1.0; 36]);
        assert_eq!(&g.observer[..3], &[4.0; 3]);
        assert_eq!(g.ki, [0.0; 6]);
    }
}
