//! The oracle of the wire target: the decoders, the receivers' checks (the case's receiver and
//! a grid of others), the identity helpers, and what each side does with an accepted message.

use super::rejection;
use crate::scenario_target::controller_error_kind;
use crate::{MsgKind, Outcome, Receiver, WireCase};
use eqtrack_controller::group::OnGroup;
use eqtrack_controller::{BuiltinGroup, GroupKind};
use ipc_types::{
    CommandMsg, DecodeError, Identity, PROTOCOL_VERSION, StateMsg, check_command, check_state,
    name_bytes, name_str,
};
use link::wire::{group_kind, wire_group};
use scenario::Scenario;
use std::hint::black_box;
use std::sync::OnceLock;

/// What the checks compare against: the two sides of a seed and an se3_circle run.
struct Context {
    so3: Scenario,
    se3: Scenario,
    se2: Scenario,
    /// The ROV with its eight thrusters.
    vehicle: Scenario,
    identities: Vec<Identity>,
}

/// The checks' context, built on first use.
fn context() -> &'static Context {
    static CONTEXT: OnceLock<Context> = OnceLock::new();
    CONTEXT.get_or_init(|| {
        let so3 = Scenario::builtin("seed").expect("built-in scenario");
        let se3 = Scenario::builtin("se3_circle").expect("built-in scenario");
        let se2 = Scenario::builtin("se2_circle").expect("built-in scenario");
        let identities = vec![
            Identity::new(ipc_types::WireGroup::So3, 0.0, so3.fingerprint(), &so3.name),
            Identity::new(
                ipc_types::WireGroup::So3,
                0.01,
                so3.fingerprint(),
                &so3.name,
            ),
            Identity::new(ipc_types::WireGroup::Se3, 0.0, se3.fingerprint(), &se3.name),
            Identity::new(ipc_types::WireGroup::Se3, 0.01, 0, ""),
            Identity::new(ipc_types::WireGroup::Se2, 0.0, se2.fingerprint(), &se2.name),
        ];
        Context {
            so3,
            se3,
            se2,
            vehicle: super::seeds::shipped("rov_failure"),
            identities,
        }
    })
}

impl Context {
    /// The scenario of the side on `group`.
    fn scenario(&self, group: GroupKind) -> &Scenario {
        match group {
            GroupKind::So3 => &self.so3,
            GroupKind::Se3 => &self.se3,
            GroupKind::Se2 => &self.se2,
        }
    }
}

/// The controller's side of an accepted state: its reference built with the state's period
/// (as `controller_node` does on the first state), stepped once, and the law evaluated at the
/// state's configuration and velocity.
struct LawOnState<'a> {
    scenario: &'a Scenario,
    msg: &'a StateMsg,
}

impl OnGroup for LawOnState<'_> {
    type Output = Result<(), String>;

    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
        let stage = |name: &str, e: eqtrack_controller::Error| {
            format!(
                "{name}: eqtrack_controller::Error::{}",
                controller_error_kind(&e)
            )
        };
        let mut s = self.scenario.clone();
        s.control_period = self.msg.control_period;
        let c = s
            .controller::<G, N, M>()
            .map_err(|e| stage("controller()", e))?;
        let mut r = s
            .reference_generator::<G, N, M>()
            .map_err(|e| stage("reference_generator()", e))?;
        r.advance();
        let (q, v) = (self.msg.configuration::<N>(), self.msg.velocity::<M>());
        let out = c
            .compute(&q, &v, &r.desired())
            .map_err(|e| stage("compute()", e))?;
        assert!(
            out.torque.iter().all(|x| x.is_finite()),
            "Controller::compute returned a non-finite torque {:?}",
            out.torque.as_slice()
        );
        // with both disturbance-rejection terms: the state twice (anchor, then update) with
        // the torque it says was applied
        let mut terms =
            eqtrack_controller::Rejection::new(rejection::<M>(), c.config().torque_limit.as_ref())
                .map_err(|e| stage("Rejection::new()", e))?;
        let applied = self.msg.applied_torque::<M>();
        for _ in 0..2 {
            let out = c
                .compute_rejecting(
                    &mut terms,
                    &q,
                    &v,
                    &r.desired(),
                    &applied,
                    s.control_period,
                    true,
                )
                .map_err(|e| stage("compute_rejecting()", e))?;
            assert!(
                out.torque
                    .iter()
                    .chain(&out.observer)
                    .chain(&out.integral)
                    .all(|x| x.is_finite()),
                "Controller::compute_rejecting returned a non-finite number: {:?} {:?} {:?}",
                out.torque.as_slice(),
                out.observer.as_slice(),
                out.integral.as_slice()
            );
        }
        Ok(())
    }
}

/// The plant's side of an accepted command: the torque (plus the disturbance) applied for one
/// period, and the next state encoded.
struct PlantOnCommand<'a> {
    scenario: &'a Scenario,
    msg: &'a CommandMsg,
}

impl OnGroup for PlantOnCommand<'_> {
    type Output = ();

    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) {
        let s = self.scenario;
        let mut body = s.plant_body::<G, N, M>().expect("built-in plant");
        let applied = self.msg.torque::<M>() + s.disturbance_vector::<M>();
        body.advance(&applied, s.control_period, s.plant_substeps);
        let mut next = StateMsg::new(link::wire::wire_group(G::KIND));
        next.seq = self.msg.seq.wrapping_add(1);
        next.set_state(body.configuration(), &body.velocity());
        black_box(next.to_bytes());
    }
}

/// The identity helpers on one identity: `Display`, `mismatch` both ways, the name's round
/// trip through [`name_bytes`].
fn exercise_identity(id: &Identity) {
    black_box(id.to_string());
    for other in &context().identities {
        black_box(other.mismatch(id));
        black_box(id.mismatch(other));
    }
    black_box(id.mismatch(id));
    black_box(group_kind(id.group));
    let name = name_str(&id.scenario);
    assert_eq!(
        name_str(&name_bytes(name)),
        name,
        "name_str(name_bytes(name_str(x))) != name_str(x)"
    );
}

/// The report's name of a decoding error.
fn decode_kind(e: &DecodeError) -> &'static str {
    match e {
        DecodeError::Length { .. } => "DecodeError::Length",
    }
}

/// Checks one wire case.
pub(crate) fn check(case: &WireCase) -> Outcome {
    let r = &case.receiver;
    let ctx = context();
    match case.kind {
        MsgKind::State => check_state_bytes(&case.bytes, r, ctx),
        MsgKind::Command => check_command_bytes(&case.bytes, r, ctx),
    }
}

/// A state message: decoded, exercised, checked by the receiver grid and then by `r`; if
/// accepted, the controller's law evaluated on it.
fn check_state_bytes(bytes: &[u8], r: &Receiver, ctx: &Context) -> Outcome {
    let msg = match StateMsg::from_bytes(bytes) {
        Ok(m) => m,
        Err(e) => {
            return Outcome::Rejected(format!("StateMsg::from_bytes: {}", decode_kind(&e)));
        }
    };
    exercise_state(&msg, bytes);
    check_state_grid(&msg);
    match check_state(&msg, wire_group(r.group), r.last_seq, r.period) {
        Err(k) => Outcome::Rejected(format!("check_state: Invalid::{k:?}")),
        Ok(()) => {
            let law = LawOnState {
                scenario: ctx.scenario(r.group),
                msg: &msg,
            };
            match r.group.dispatch(law) {
                Ok(()) => Outcome::Accepted,
                Err(kind) => Outcome::Rejected(kind),
            }
        }
    }
}

/// A decoded state: encoding it gives back `bytes`; its accessors and identity helpers run.
fn exercise_state(msg: &StateMsg, bytes: &[u8]) {
    assert_eq!(
        &msg.to_bytes()[..],
        bytes,
        "StateMsg: decoding then encoding changed the bytes"
    );
    black_box(msg.configuration::<3>());
    black_box(msg.configuration::<4>());
    black_box(msg.velocity::<3>());
    black_box(msg.velocity::<6>());
    black_box(msg.wheel_speeds());
    exercise_identity(&msg.identity());
}

/// `check_state` for a grid of receivers (group, last sequence number, period): one that
/// accepts saw the right version and group and an older sequence number.
fn check_state_grid(msg: &StateMsg) {
    let seqs = [
        None,
        Some(0),
        Some(msg.seq.wrapping_sub(1)),
        Some(msg.seq),
        Some(u64::MAX),
    ];
    let periods = [None, Some(0.01), Some(msg.control_period), Some(f64::NAN)];
    for g in GroupKind::ALL {
        for last in seqs {
            for p in periods {
                let verdict = check_state(msg, wire_group(g), last, p);
                if verdict.is_ok() {
                    assert_eq!(msg.version, PROTOCOL_VERSION);
                    assert_eq!(group_kind(msg.group), Some(g));
                    assert!(last.is_none_or(|l| msg.seq > l));
                    // every wheel speed it carries is a number, and no more than the capacity
                    assert!(msg.wheels as usize <= ipc_types::MAX_WHEELS);
                    assert_eq!(msg.reserved_wheels, 0);
                    assert!(msg.wheel_speeds().iter().all(|w| w.is_finite()));
                }
                let _ = black_box(verdict);
            }
        }
    }
}

/// A command message: decoded, exercised, checked by the receiver grid and then by `r`; if
/// accepted, the plant applies it.
fn check_command_bytes(bytes: &[u8], r: &Receiver, ctx: &Context) -> Outcome {
    let msg = match CommandMsg::from_bytes(bytes) {
        Ok(m) => m,
        Err(e) => {
            return Outcome::Rejected(format!("CommandMsg::from_bytes: {}", decode_kind(&e)));
        }
    };
    exercise_command(&msg, bytes);
    check_command_grid(&msg);
    match check_command(&msg, wire_group(r.group), r.awaited, r.actuators) {
        Err(k) => Outcome::Rejected(format!("check_command: Invalid::{k:?}")),
        // a command for the ROV's eight thrusters drives them; another vehicle's (accepted by
        // a receiver of its count) has no plant model here
        Ok(()) if msg.actuators > 0 => {
            if r.group == GroupKind::Se3 && msg.actuators == 8 {
                vehicle_on_command(&ctx.vehicle, &msg);
            }
            Outcome::Accepted
        }
        Ok(()) => {
            r.group.dispatch(PlantOnCommand {
                scenario: ctx.scenario(r.group),
                msg: &msg,
            });
            Outcome::Accepted
        }
    }
}

/// A decoded command: encoding it gives back `bytes`; its accessors and identity helpers run,
/// and a refusal built from its identity survives a round trip.
fn exercise_command(msg: &CommandMsg, bytes: &[u8]) {
    assert_eq!(
        &msg.to_bytes()[..],
        bytes,
        "CommandMsg: decoding then encoding changed the bytes"
    );
    black_box(msg.torque::<3>());
    black_box(msg.torque::<6>());
    let id = msg.identity();
    exercise_identity(&id);
    let refusal = CommandMsg::refusal(&id, msg.seq, msg.mismatch);
    assert_eq!(
        CommandMsg::from_bytes(&refusal.to_bytes()).map(|c| c.to_bytes()),
        Ok(refusal.to_bytes()),
        "refusal round trip"
    );
}

/// `check_command` for a grid of receivers (group, awaited sequence number, actuator
/// count): one that accepts awaited this sequence number on this group, with this many
/// actuators, at most 12.
fn check_command_grid(msg: &CommandMsg) {
    for g in GroupKind::ALL {
        for awaited in [0, msg.seq, msg.seq.wrapping_add(1), u64::MAX] {
            for actuators in [0, msg.actuators, 8, 12] {
                let verdict = check_command(msg, wire_group(g), awaited, actuators);
                if verdict.is_ok() {
                    assert_eq!(msg.seq, awaited);
                    assert_eq!(group_kind(msg.group), Some(g));
                    assert_eq!(msg.actuators, actuators);
                    assert!(actuators as usize <= ipc_types::MAX_ACTUATORS);
                }
                let _ = black_box(verdict);
            }
        }
    }
}

/// A vehicle plant (the ROV of `rov_failure`) applying an accepted command: its actuator
/// commands, each clamped to its range, drive the actuators over one period, and the state
/// it publishes next is finite.
fn vehicle_on_command(s: &Scenario, msg: &CommandMsg) {
    type Se3 = eqtrack_controller::group::Se3;
    let mut run = plant::vehicle::VehicleRun::<6>::of(s)
        .expect("the shipped vehicle loads")
        .expect("it has a vehicle");
    let mut body = s.plant_body::<Se3, 4, 6>().expect("the shipped plant");
    let u = nalgebra::SVector::<f64, { ipc_types::MAX_ACTUATORS }>::from_fn(|j, _| msg.u_cmd[j]);
    let applied = run.command_received(&u);
    assert!(
        applied.iter().all(|x| x.is_finite()),
        "clamped actuator commands: {applied:?}"
    );
    plant::vehicle::step::<Se3, 4, 6>(
        &mut body,
        &run.environment,
        &mut run.actuators,
        &nalgebra::SVector::zeros(),
        s.control_period,
        s.plant_substeps,
    );
    let mut next = StateMsg::new(ipc_types::WireGroup::Se3);
    next.set_state(body.configuration(), &body.velocity());
    assert!(
        next.q.iter().chain(&next.v).all(|x| x.is_finite()),
        "a vehicle under accepted commands left the finite numbers: {next:?}"
    );
}
