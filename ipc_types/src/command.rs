//! The controller's answer, [`CommandMsg`], and its accessors.

use crate::{
    Identity, MAX_ACTUATORS, MAX_M, NAME_BYTES, NO_PREVIOUS, PROTOCOL_VERSION, WireGroup, flags,
};
#[cfg(feature = "zero-copy")]
use iceoryx2_bb_derive_macros::ZeroCopySend;
#[cfg(feature = "zero-copy")]
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;
use nalgebra::SVector;

/// The controller's answer to state k (or its refusal of the run).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "zero-copy",
    derive(ZeroCopySend),
    type_name("eqtrack::CommandMsg9")
)]
#[repr(C)]
pub struct CommandMsg {
    /// [`PROTOCOL_VERSION`].
    pub version: u32,
    /// [`WireGroup::code`] of the controller's group.
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
    /// With [`flags::REFUSED`]: the [`mismatch`](crate::mismatch) bits.
    pub mismatch: u32,
    /// The controller's scenario fingerprint (0: none).
    pub fingerprint: u64,
    /// The control period the controller insists on (0: it follows the plant).
    pub expected_period: f64,
    /// The controller's scenario name, UTF-8, NUL-padded.
    pub scenario: [u8; NAME_BYTES],
    /// The law that computed `tau` ([`WireLaw::code`](crate::WireLaw::code); 0: not said): a controller started by hand
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
    /// The failsafe manager's state after this state's tick (docs/failsafe.md; 0: nominal,
    /// or no manager runs): the engaged action's code in bits 0–3 (1 `warn`, 2 `hold`,
    /// 3 `damp`, 4 `descend`, 5 `surface`, 6 `disarm`), its cause's code in bits 4–7
    /// (1 `link`, 2 `estimator`, 3 `actuators`, 4 `tracking`), and one bit per raised cause
    /// from bit 8 (link) to bit 11 (tracking). Protocol 9.
    pub failsafe: u32,
    /// A vehicle's actuator count (0: no vehicle, and `tau` is the wrench to apply; at most
    /// [`MAX_ACTUATORS`]). With a vehicle, `tau` is the law's wrench and the plant applies
    /// `u_cmd` through its actuators (docs/vehicles.md).
    pub actuators: u32,
    /// The allocator's status code (docs/maths.md, "Control allocation"; 0 with no vehicle).
    pub alloc_status: u32,
    /// The wrench asked of the allocator: `tau` minus the known restoring wrench, body
    /// axes, first m entries.
    pub demand: [f64; MAX_M],
    /// `B u_cmd`, first m entries.
    pub achieved: [f64; MAX_M],
    /// The wrench the law counts as applied when this command is applied over the period
    /// (`B u_cmd` plus the restoring wrench it compensated), first m entries: the plant
    /// returns it in the next state's `applied` for the disturbance-rejection terms.
    pub accounted: [f64; MAX_M],
    /// The command the rate limit narrowed this one around (the controller's previous
    /// `u_cmd`; meaningful when `previous_seq` is not [`NO_PREVIOUS`]), first `actuators`
    /// entries. Replay restores the limit from it.
    pub u_previous: [f64; MAX_ACTUATORS],
    /// The actuator commands, first `actuators` entries.
    pub u_cmd: [f64; MAX_ACTUATORS],
    /// The failure detector's finding this cycle
    /// (docs/vehicles.md, "Failures nobody announces"): the actuator found failed, plus one (0: nothing found, or no detector).
    /// The allocation of this command already knows it.
    pub detected: u32,
    /// Its kind: 1 dead, 2 stuck, 3 effectiveness (0 when nothing was found).
    pub detected_kind: u32,
    /// The estimate the allocator was told: the stuck value, or the factor (0 when dead).
    pub detected_value: f64,
    /// 1 when the finding refines an earlier one of the same actuator, else 0.
    pub detected_refined: u32,
    /// The detector's alarms so far (0 without a detector).
    pub alarms: u32,
    /// The best hypothesis's statistic at the detector's last test (χ²₁ under no failure;
    /// 0 before it tests, or without a detector).
    pub statistic: f64,
    /// The best hypothesis's actuator at that test, plus one (0: no test yet).
    pub suspect: u32,
    /// Zero.
    pub reserved_detector: u32,
}

impl CommandMsg {
    /// A zeroed message of `group` with the version filled in.
    pub fn new(group: WireGroup) -> Self {
        CommandMsg {
            version: PROTOCOL_VERSION,
            group: group.code(),
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
            failsafe: 0,
            scenario: [0; NAME_BYTES],
            actuators: 0,
            alloc_status: 0,
            demand: [0.0; MAX_M],
            achieved: [0.0; MAX_M],
            accounted: [0.0; MAX_M],
            u_previous: [0.0; MAX_ACTUATORS],
            u_cmd: [0.0; MAX_ACTUATORS],
            detected: 0,
            detected_kind: 0,
            detected_value: 0.0,
            detected_refined: 0,
            alarms: 0,
            statistic: 0.0,
            suspect: 0,
            reserved_detector: 0,
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
        let mut c = CommandMsg::new(WireGroup::So3);
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

/// The names of a failsafe word's engaged action and its cause ([`CommandMsg::failsafe`]):
/// `("nominal", "")` when none is engaged; `"?"` for a code no action or cause has.
pub fn failsafe_names(word: u32) -> (&'static str, &'static str) {
    let name = |names: &[&'static str], code: u32| names.get(code as usize).copied().unwrap_or("?");
    (
        name(
            &[
                "nominal", "warn", "hold", "damp", "descend", "surface", "disarm",
            ],
            word & 0xf,
        ),
        name(
            &["", "link", "estimator", "actuators", "tracking"],
            word >> 4 & 0xf,
        ),
    )
}

/// The name of a detection kind's code ([`CommandMsg::detected_kind`]): `""` (nothing
/// found), `"dead"`, `"stuck"`, `"effectiveness"`, or `"?"` for a code no kind has.
pub fn detected_kind_name(code: u32) -> &'static str {
    ["", "dead", "stuck", "effectiveness"]
        .get(code as usize)
        .copied()
        .unwrap_or("?")
}
