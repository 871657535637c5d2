//! The seed corpus: realistic states and commands from a few cycles of the built-in
//! scenarios' closed loops, a shutdown state and a refusal.

use super::{Corpus, Item, rejection};
use crate::MsgKind;
use eqtrack_controller::BuiltinGroup;
use eqtrack_controller::group::OnGroup;
use ipc_types::{CommandMsg, Identity, StateMsg, flags, mismatch, name_bytes};
use link::wire::wire_group;
use scenario::Scenario;

/// Realistic messages of one scenario: a few cycles of the closed loop, a shutdown state and
/// a refusal.
struct Realistic<'a>(&'a Scenario);

impl OnGroup for Realistic<'_> {
    type Output = Vec<Item>;

    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) -> Vec<Item> {
        let s = self.0;
        // The built-in scenarios are valid: the unit tests check it.
        let c = s.controller::<G, N, M>().expect("built-in controller");
        let mut r = s
            .reference_generator::<G, N, M>()
            .expect("built-in reference");
        let mut body = s.plant_body::<G, N, M>().expect("built-in plant");
        let name = name_bytes(&s.name);
        let fp = s.fingerprint();
        let item = |kind, seq, bytes: &[u8]| Item {
            kind,
            group: G::KIND,
            seq,
            period: s.control_period,
            actuators: 0,
            bytes: bytes.to_vec(),
        };
        let mut out = Vec::new();
        let mut last = StateMsg::new(link::wire::wire_group(G::KIND));
        // the realistic commands carry both disturbance-rejection terms
        let mut terms =
            eqtrack_controller::Rejection::new(rejection::<M>(), c.config().torque_limit.as_ref())
                .expect("valid terms");
        let mut applied = nalgebra::SVector::<f64, M>::zeros();
        for k in 0..4u64 {
            let mut st = StateMsg::new(link::wire::wire_group(G::KIND));
            st.seq = k;
            st.t = k as f64 * s.control_period;
            st.control_period = s.control_period;
            st.stamp_ns = 5_000_000_000 + k * 10_000_000;
            st.set_state(body.configuration(), &body.velocity());
            st.set_applied(&applied);
            st.flags = if k % 2 == 0 { flags::WAKE_EVENT } else { 0 };
            st.plant_pid = 4242;
            st.fingerprint = fp;
            st.scenario = name;
            if k == 2 {
                // a plant with reaction wheels: their speeds relative to the body
                st.set_wheel_speeds(&[120.0, -80.5, 0.0, 33.25]);
            }
            let law = c
                .compute_rejecting(
                    &mut terms,
                    body.configuration(),
                    &body.velocity(),
                    &r.desired(),
                    &applied,
                    s.control_period,
                    true,
                )
                .expect("built-in law");
            applied = law.torque;
            let mut cmd = CommandMsg::new(link::wire::wire_group(G::KIND));
            cmd.seq = k;
            cmd.state_received_ns = st.stamp_ns + 20_000;
            cmd.stamp_ns = st.stamp_ns + 55_000;
            cmd.compute_ns = 35_000;
            cmd.set_torque(&law.torque);
            cmd.lyapunov = law.lyapunov.total;
            for i in 0..M {
                cmd.observer[i] = law.observer[i];
                cmd.integral[i] = law.integral[i];
            }
            cmd.previous_seq = k.checked_sub(1).unwrap_or(ipc_types::NO_PREVIOUS);
            cmd.heap_allocations = k.saturating_sub(1);
            cmd.fingerprint = fp;
            cmd.scenario = name;
            out.push(item(MsgKind::State, k, &st.to_bytes()));
            out.push(item(MsgKind::Command, k, &cmd.to_bytes()));
            body.advance(&law.torque, s.control_period, s.plant_substeps);
            r.advance();
            last = st;
        }
        last.seq += 1;
        last.flags = flags::SHUTDOWN;
        out.push(item(MsgKind::State, last.seq, &last.to_bytes()));
        let me = Identity::new(wire_group(G::KIND), 0.001, fp ^ 1, &s.name);
        let refusal = CommandMsg::refusal(&me, 0, mismatch::PERIOD | mismatch::SCENARIO);
        out.push(item(MsgKind::Command, 0, &refusal.to_bytes()));
        out
    }
}

/// A scenario shipped in `scenarios/`.
pub(super) fn shipped(name: &str) -> Scenario {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenarios")
        .join(format!("{name}.toml"));
    Scenario::from_file(&path).expect("a shipped scenario loads")
}

/// A vehicle's commands as the controller's cycle answers them: the ROV of `rov_failure`,
/// states 0..4 of its body at rest, answered by the responder with its allocation.
fn vehicle_commands() -> Vec<Item> {
    type Se3 = eqtrack_controller::group::Se3;
    let s = shipped("rov_failure");
    let spec = s.vehicle.as_ref().expect("rov_failure has a vehicle");
    let mut responder = s
        .controller::<Se3, 4, 6>()
        .and_then(|c| control_cycle::Responder::new(c, s.rejection_config()))
        .expect("the shipped controller")
        .with_vehicle(
            control_cycle::ControllerVehicle::new(spec, s.control_period)
                .expect("the shipped vehicle"),
        );
    let mut reference = s
        .reference_source::<Se3, 4, 6>()
        .expect("the shipped reference");
    let body = s.plant_body::<Se3, 4, 6>().expect("the shipped plant");
    (0..4u64)
        .map(|k| {
            let mut st = StateMsg::new(wire_group(eqtrack_controller::GroupKind::Se3));
            st.seq = k;
            st.t = k as f64 * s.control_period;
            st.control_period = s.control_period;
            st.set_state(body.configuration(), &body.velocity());
            let cmd = responder
                .respond(&mut reference, &st)
                .expect("the law answers the body at rest");
            Item {
                kind: MsgKind::Command,
                group: eqtrack_controller::GroupKind::Se3,
                seq: k,
                period: s.control_period,
                actuators: cmd.actuators,
                bytes: cmd.to_bytes().to_vec(),
            }
        })
        .collect()
}

impl Corpus {
    /// Realistic states and commands of the three built-in scenarios (both groups), and a
    /// vehicle's commands.
    pub(crate) fn new() -> Corpus {
        let items = scenario::BUILTINS
            .iter()
            .flat_map(|(name, _)| {
                let s = Scenario::builtin(name).expect("built-in scenario");
                s.group.dispatch(Realistic(&s))
            })
            .chain(vehicle_commands())
            .collect();
        Corpus { items }
    }
}
