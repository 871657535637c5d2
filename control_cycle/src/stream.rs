//! A streamed reference: the plan board's messages taken into the path, and the path the node starts from.

use eqtrack_controller::group::BuiltinGroup;
use eqtrack_controller::path::{Path, PathReference};
use eqtrack_controller::{Source, Trajectory};
use ipc_types::{CommandMsg, PlanInvalid, PlanMsg, check_plan, flags};
use scenario::Scenario;

/// The reference a streamed run starts from (docs/maths.md, "Streamed pieces"): a path that
/// holds, at rest, the pose the scenario's own reference starts from, at the scenario's
/// control period, until plan messages append pieces ([`PlanIntake::take`]). The node and
/// `plant_sim replay` start from it.
pub fn streamed_reference<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    s: &Scenario,
) -> Result<Source<f64, G, N, M>, eqtrack_controller::Error> {
    let start = s.reference_source::<G, N, M>()?.desired().q;
    let held = PathReference::new(
        Path::hold(start)?,
        nalgebra::SMatrix::from_row_slice(&s.model_inertia),
        s.control_period,
    )?;
    Ok(Source::Path(held))
}

/// What a streamed reference has taken from the plan board: the pieces appended so far and
/// the messages taken. The node and `plant_sim replay` append pieces through it, so replay
/// repeats the node's path bit for bit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanIntake {
    /// The end time of the last segment appended (pieces that start earlier are old).
    high_water: f64,
    /// Plan messages taken (accepted or refused).
    pub received: u32,
    /// `(planner pid, seq)` of the last message taken (`(0, 0)`: none).
    pub last: (u32, u64),
}

impl Default for PlanIntake {
    fn default() -> Self {
        PlanIntake {
            high_water: f64::NEG_INFINITY,
            received: 0,
            last: (0, 0),
        }
    }
}

impl PlanIntake {
    /// Takes plan message `msg`: checks it ([`check_plan`] at the reference's period) and
    /// appends its pieces that start no earlier than the last piece appended ends and end no
    /// earlier than the reference's time. Allocation-free.
    pub fn take<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
        &mut self,
        msg: &PlanMsg,
        reference: &mut PathReference<f64, G, N, M>,
    ) -> Result<(), PlanInvalid> {
        self.received = self.received.wrapping_add(1);
        self.last = (msg.planner_pid, msg.seq);
        check_plan(msg, link::wire::wire_group(G::KIND), reference.period())?;
        let now = reference.time();
        for w in msg.used() {
            let seg = link::wire::segment::<N, M>(w);
            if seg.t0 < self.high_water || seg.t1 < now {
                continue;
            }
            if reference.path_mut().push(seg).is_err() {
                // full: the planner republishes the window as time moves on
                break;
            }
            self.high_water = seg.t1;
        }
        Ok(())
    }

    /// Writes what was taken into a command ([`flags::STREAMED`], `plans_received`,
    /// `plan_seq`, `plan_pid`).
    pub fn stamp(&self, cmd: &mut CommandMsg) {
        cmd.flags |= flags::STREAMED;
        cmd.plans_received = self.received;
        (cmd.plan_pid, cmd.plan_seq) = self.last;
    }
}
