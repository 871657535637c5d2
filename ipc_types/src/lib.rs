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
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

pub mod codes;
pub use codes::{WireGroup, WireLaw};
pub mod decision;
pub use decision::Decision;
pub mod params;
pub use params::{Gains, ParamInvalid, ParamMsg, ParamRequest, ParamResponse, param_op};
pub mod plan;
pub use plan::{PLAN_BYTES, PLAN_WINDOW, PlanInvalid, PlanMsg, WireSegment, check_plan};
pub mod status;
pub use status::{StatusMsg, status_flags};

mod checks;
mod command;
mod encoding;
mod identity;
mod services;
mod state;
pub use checks::{Invalid, MAX_SEQ_JUMP, check_command, check_state};
pub(crate) use checks::{all_finite, own_dims};
pub use command::{CommandMsg, detected_kind_name, failsafe_names};
pub use encoding::{COMMAND_BYTES, DecodeError, STATE_BYTES};
pub(crate) use encoding::{Get, Put, length};
pub use identity::{Identity, name_bytes, name_str, padded_bytes, padded_str};
pub use services::*;
pub use state::StateMsg;

/// Bumped whenever a message layout or meaning changes.
pub const PROTOCOL_VERSION: u32 = 10;
/// [`CommandMsg::previous_seq`] when the controller processed no state before.
pub const NO_PREVIOUS: u64 = u64::MAX;
/// The largest n (configuration matrices are n×n) any supported group needs.
pub const MAX_N: usize = 4;
/// The largest m (algebra dimension) any supported group needs.
pub const MAX_M: usize = 6;
/// The most actuators a vehicle's command carries (the allocation crate's capacity).
pub const MAX_ACTUATORS: usize = 12;
/// The most reaction wheels a state carries speeds for (the allocation crate's wheel
/// capacity).
pub const MAX_WHEELS: usize = 6;
/// Bytes of the scenario name carried in the messages (UTF-8, NUL-padded).
pub const NAME_BYTES: usize = 32;

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
    /// [`StateMsg::flags`](crate::StateMsg::flags): the run's gains may change while it runs
    /// (`plant_sim run --tunable`): read the run's `params` board ([`ParamMsg`](crate::ParamMsg))
    /// before answering.
    pub const TUNABLE: u32 = 16;
    /// [`CommandMsg::flags`](crate::CommandMsg::flags): the controller answered with the
    /// gains the `params` board gives for the state (the answer to [`TUNABLE`]).
    pub const TUNED: u32 = 32;
    /// [`CommandMsg::flags`](crate::CommandMsg::flags): the controller runs the failure
    /// detector; the command's detection fields are its (docs/wire.md).
    pub const DETECTING: u32 = 64;
    /// [`StateMsg::flags`](crate::StateMsg::flags): the estimator's innovation gate runs
    /// and its health is `degraded` (docs/estimators.md; protocol 9).
    pub const ESTIMATE_DEGRADED: u32 = 128;
    /// [`StateMsg::flags`](crate::StateMsg::flags): the estimator's innovation gate runs
    /// and its health is `lost` (protocol 9).
    pub const ESTIMATE_LOST: u32 = 256;
    /// [`CommandMsg::flags`](crate::CommandMsg::flags): the controller runs the failsafe
    /// manager; the command's `failsafe` word is its (protocol 9).
    pub const SUPERVISED: u32 = 512;
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

#[cfg(test)]
mod tests {
    use super::*;
    use WireGroup::{Se3, So3};
    use core::fmt::Write;

    #[test]
    fn states_are_checked() {
        let mut s = StateMsg::new(So3);
        s.control_period = 0.01;
        assert_eq!(check_state(&s, So3, None, None), Ok(()));
        assert_eq!(check_state(&s, Se3, None, None), Err(Invalid::Group));
        s.seq = 5;
        assert_eq!(check_state(&s, So3, Some(5), None), Err(Invalid::Sequence));
        assert_eq!(check_state(&s, So3, Some(4), None), Ok(()));
        s.seq = 5 + MAX_SEQ_JUMP;
        assert_eq!(check_state(&s, So3, Some(4), None), Ok(()));
        s.seq += 1;
        assert_eq!(check_state(&s, So3, Some(4), None), Err(Invalid::Sequence));
        s.seq = MAX_SEQ_JUMP;
        assert_eq!(check_state(&s, So3, None, None), Ok(()));
        s.seq = u64::MAX;
        assert_eq!(check_state(&s, So3, None, None), Err(Invalid::Sequence));
        assert_eq!(
            check_state(&s, So3, Some(u64::MAX), None),
            Err(Invalid::Sequence)
        );
        s.seq = 5;
        assert_eq!(check_state(&s, So3, None, Some(0.02)), Err(Invalid::Period));
        assert_eq!(check_state(&s, So3, None, Some(0.01)), Ok(()));
        s.v[2] = f64::NAN;
        assert_eq!(check_state(&s, So3, None, None), Err(Invalid::NonFinite));
        s.v[2] = 0.0;
        s.applied[1] = f64::INFINITY;
        assert_eq!(check_state(&s, So3, None, None), Err(Invalid::NonFinite));
        s.applied[1] = 0.0;
        s.applied[4] = f64::NAN; // beyond m = 3: ignored
        s.v[5] = f64::NAN; // beyond m = 3: ignored
        assert_eq!(check_state(&s, So3, None, None), Ok(()));
        s.control_period = 0.0;
        assert_eq!(check_state(&s, So3, None, None), Err(Invalid::Period));
        s.version = 99;
        assert_eq!(check_state(&s, So3, None, None), Err(Invalid::Version));
        let mut u = StateMsg::new(So3);
        u.group = 77;
        assert_eq!(check_state(&u, So3, None, None), Err(Invalid::Group));
        // the wheels: a count past the capacity, a non-finite speed within the count
        let mut w = StateMsg::new(So3);
        w.control_period = 0.01;
        w.set_wheel_speeds(&[1.0, -2.0, 3.0, 4.0]);
        assert_eq!(w.wheel_speeds(), &[1.0, -2.0, 3.0, 4.0]);
        assert_eq!(check_state(&w, So3, None, None), Ok(()));
        w.wheel_speeds[3] = f64::NAN;
        assert_eq!(check_state(&w, So3, None, None), Err(Invalid::NonFinite));
        w.wheel_speeds[3] = 4.0;
        w.wheel_speeds[5] = f64::NAN; // beyond the count: ignored
        assert_eq!(check_state(&w, So3, None, None), Ok(()));
        w.reserved_wheels = 1;
        assert_eq!(check_state(&w, So3, None, None), Err(Invalid::Actuators));
        w.reserved_wheels = 0;
        w.wheels = MAX_WHEELS as u32 + 1;
        assert_eq!(check_state(&w, So3, None, None), Err(Invalid::Actuators));
        w.set_wheel_speeds(&[0.5; MAX_WHEELS + 2]);
        assert_eq!(w.wheels, MAX_WHEELS as u32 + 2);
        assert_eq!(w.wheel_speeds().len(), MAX_WHEELS);
        assert_eq!(check_state(&w, So3, None, None), Err(Invalid::Actuators));
    }

    #[test]
    fn commands_are_checked() {
        let mut c = CommandMsg::new(Se3);
        c.seq = 3;
        assert_eq!(check_command(&c, Se3, 3, 0), Ok(()));
        assert_eq!(check_command(&c, So3, 3, 0), Err(Invalid::Group));
        assert_eq!(check_command(&c, Se3, 4, 0), Err(Invalid::Sequence));
        c.tau[5] = f64::INFINITY;
        assert_eq!(check_command(&c, Se3, 3, 0), Err(Invalid::NonFinite));
        c.tau[5] = 0.0;
        c.observer[5] = f64::NAN;
        assert_eq!(check_command(&c, Se3, 3, 0), Err(Invalid::NonFinite));
        c.observer[5] = 0.0;
        c.integral[0] = f64::NEG_INFINITY;
        assert_eq!(check_command(&c, Se3, 3, 0), Err(Invalid::NonFinite));
        c.integral[0] = 0.0;
        c.z_before[5] = f64::NAN;
        assert_eq!(check_command(&c, Se3, 3, 0), Err(Invalid::NonFinite));
        c.z_before[5] = 0.0;
        // the failsafe word: descend engaged by the actuators (raised: bit 10), from a controller
        // that runs the manager (not from one that does not), then words the manager never
        // writes
        c.failsafe = 4 | 3 << 4 | 1 << 10;
        assert_eq!(check_command(&c, Se3, 3, 0), Err(Invalid::Failsafe));
        c.flags |= flags::SUPERVISED;
        assert_eq!(check_command(&c, Se3, 3, 0), Ok(()));
        for bad in [
            4 | 3 << 4,
            4,
            3 << 4 | 1 << 10,
            7 | 1 << 4 | 1 << 8,
            1 | 5 << 4,
            1 << 12,
        ] {
            c.failsafe = bad;
            assert_eq!(
                check_command(&c, Se3, 3, 0),
                Err(Invalid::Failsafe),
                "{bad:#x}"
            );
        }
        c.failsafe = 0;
        c.flags &= !flags::SUPERVISED;
        assert_eq!(check_command(&c, Se3, 3, 0), Ok(()));
        // a vehicle's command: the count must be the plant's, its entries finite
        c.actuators = 8;
        assert_eq!(check_command(&c, Se3, 3, 0), Err(Invalid::Actuators));
        assert_eq!(check_command(&c, Se3, 3, 6), Err(Invalid::Actuators));
        assert_eq!(check_command(&c, Se3, 3, 8), Ok(()));
        c.u_cmd[7] = f64::NAN;
        assert_eq!(check_command(&c, Se3, 3, 8), Err(Invalid::NonFinite));
        c.u_cmd[7] = 0.0;
        c.u_cmd[8] = f64::NAN; // beyond the count: ignored
        c.u_previous[8] = f64::INFINITY;
        assert_eq!(check_command(&c, Se3, 3, 8), Ok(()));
        c.u_previous[0] = f64::INFINITY;
        assert_eq!(check_command(&c, Se3, 3, 8), Err(Invalid::NonFinite));
        c.u_previous[0] = 0.0;
        c.accounted[5] = f64::NAN;
        assert_eq!(check_command(&c, Se3, 3, 8), Err(Invalid::NonFinite));
        c.accounted[5] = 0.0;
        c.demand[0] = f64::NEG_INFINITY;
        assert_eq!(check_command(&c, Se3, 3, 8), Err(Invalid::NonFinite));
        c.demand[0] = 0.0;
        c.achieved[2] = f64::NAN;
        assert_eq!(check_command(&c, Se3, 3, 8), Err(Invalid::NonFinite));
        c.achieved[2] = 0.0;
        // a detection names one of the vehicle's actuators, a kind, a finite estimate, from a
        // controller that says it runs the detector
        c.detected = 8;
        c.detected_kind = 2;
        c.detected_value = -20.0;
        assert_eq!(check_command(&c, Se3, 3, 8), Err(Invalid::Detection));
        c.flags |= flags::DETECTING;
        assert_eq!(check_command(&c, Se3, 3, 8), Ok(()));
        c.reserved_detector = 1;
        assert_eq!(check_command(&c, Se3, 3, 8), Err(Invalid::Detection));
        c.reserved_detector = 0;
        c.detected = 9;
        assert_eq!(check_command(&c, Se3, 3, 8), Err(Invalid::Detection));
        c.detected = 1;
        c.detected_kind = 4;
        assert_eq!(check_command(&c, Se3, 3, 8), Err(Invalid::Detection));
        c.detected_kind = 0;
        assert_eq!(check_command(&c, Se3, 3, 8), Err(Invalid::Detection));
        c.detected_kind = 3;
        c.detected_refined = 2;
        assert_eq!(check_command(&c, Se3, 3, 8), Err(Invalid::Detection));
        c.detected_refined = 1;
        c.detected_value = f64::NAN;
        assert_eq!(check_command(&c, Se3, 3, 8), Err(Invalid::NonFinite));
        c.detected_value = 0.5;
        assert_eq!(check_command(&c, Se3, 3, 8), Ok(()));
        // nothing found: the other fields are zero
        c.detected = 0;
        assert_eq!(check_command(&c, Se3, 3, 8), Err(Invalid::Detection));
        (c.detected_kind, c.detected_value, c.detected_refined) = (0, 0.0, 0);
        assert_eq!(check_command(&c, Se3, 3, 8), Ok(()));
        // the last test's suspect is one of the actuators, its statistic finite
        c.suspect = 9;
        assert_eq!(check_command(&c, Se3, 3, 8), Err(Invalid::Detection));
        c.suspect = 8;
        c.statistic = f64::INFINITY;
        assert_eq!(check_command(&c, Se3, 3, 8), Err(Invalid::NonFinite));
        c.statistic = 12.0;
        assert_eq!(check_command(&c, Se3, 3, 8), Ok(()));
        // without the flag, every detection field is zero
        c.flags &= !flags::DETECTING;
        assert_eq!(check_command(&c, Se3, 3, 8), Err(Invalid::Detection));
        (c.statistic, c.suspect) = (0.0, 0);
        assert_eq!(check_command(&c, Se3, 3, 8), Ok(()));
        c.actuators = 13;
        assert_eq!(check_command(&c, Se3, 3, 13), Err(Invalid::Actuators));
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
        s.set_wheel_speeds(&[0.5, -1e3, 7.25]);
        s.reserved_wheels = 9;
        assert_eq!(StateMsg::from_bytes(&s.to_bytes()), Ok(s));
        assert_eq!(STATE_BYTES, core::mem::size_of::<StateMsg>());
        assert_eq!(core::mem::offset_of!(StateMsg, wheel_speeds), 320);
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
        c.law = WireLaw::Gt.code();
        c.plans_received = 3;
        c.plan_seq = 41;
        c.plan_pid = 77;
        c.actuators = 8;
        c.alloc_status = 2;
        c.demand[5] = 3.25;
        c.achieved[0] = -7.5;
        c.accounted[3] = 0.0625;
        c.u_previous[11] = 1.75;
        c.u_cmd[7] = -2.0;
        c.detected = 6;
        c.detected_kind = 3;
        c.detected_value = 0.625;
        c.detected_refined = 1;
        c.alarms = 4;
        c.statistic = 31.5;
        c.suspect = 7;
        assert_eq!(CommandMsg::from_bytes(&c.to_bytes()), Ok(c));
        let v = c.to_bytes();
        assert_eq!(u32::from_le_bytes(v[384..388].try_into().unwrap()), 8);
        assert_eq!(u32::from_le_bytes(v[388..392].try_into().unwrap()), 2);
        assert_eq!(f64::from_le_bytes(v[432..440].try_into().unwrap()), 3.25);
        assert_eq!(f64::from_le_bytes(v[624..632].try_into().unwrap()), 1.75);
        assert_eq!(f64::from_le_bytes(v[688..696].try_into().unwrap()), -2.0);
        assert_eq!(u32::from_le_bytes(v[728..732].try_into().unwrap()), 6);
        assert_eq!(u32::from_le_bytes(v[732..736].try_into().unwrap()), 3);
        assert_eq!(f64::from_le_bytes(v[736..744].try_into().unwrap()), 0.625);
        assert_eq!(u32::from_le_bytes(v[744..748].try_into().unwrap()), 1);
        assert_eq!(u32::from_le_bytes(v[748..752].try_into().unwrap()), 4);
        assert_eq!(f64::from_le_bytes(v[752..760].try_into().unwrap()), 31.5);
        assert_eq!(u32::from_le_bytes(v[760..764].try_into().unwrap()), 7);
        assert_eq!(COMMAND_BYTES, 768);
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
