//! A streamed reference: the plan board's messages taken into the path, and the path the node starts from.

use crate::{NodeError, log};
use controller::group::MatrixLieGroup;
use controller::path::{Path, PathReference};
use controller::{Source, Trajectory};
use ipc_types::{CommandMsg, PlanInvalid, PlanMsg, check_plan, flags};
use link::plan::PlanReader;
use scenario::Scenario;

/// The reference a streamed run starts from (docs/maths.md, "Streamed pieces"): a path that
/// holds, at rest, the pose the scenario's own reference starts from, at the scenario's
/// control period, until plan messages append pieces ([`PlanIntake::take`]). The node and
/// `plant_sim replay` start from it.
pub fn streamed_reference<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
    s: &Scenario,
) -> Result<Source<f64, G, N, M>, controller::Error> {
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
    pub(crate) high_water: f64,
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
    pub fn take<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
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

/// The streamed reference's bookkeeping: which pieces the path has, and whether it ran dry.
pub(crate) struct Stream {
    pub(crate) reader: PlanReader,
    /// The pieces and messages taken.
    pub(crate) intake: PlanIntake,
    /// No piece covers `t_k` or lies ahead of it (at the start: none came yet).
    pub(crate) dry: bool,
    /// Whether any piece has come.
    pub(crate) started: bool,
    /// Plan messages refused, per [`ipc_types::PlanInvalid`] kind (its discriminant) (each kind logged once).
    pub(crate) rejected: [u64; PlanInvalid::KINDS],
}

impl Stream {
    pub(crate) fn open(run: &str) -> Result<Stream, NodeError> {
        Ok(Stream {
            reader: PlanReader::open(run)?,
            intake: PlanIntake::default(),
            dry: true,
            started: false,
            rejected: [0; PlanInvalid::KINDS],
        })
    }

    /// Appends the new pieces of every unseen plan message: those that start no earlier
    /// than the last piece appended ends and end no earlier than now. Allocation-free.
    pub(crate) fn pull<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
        &mut self,
        reference: &mut PathReference<f64, G, N, M>,
    ) {
        while let Some(msg) = self.reader.receive() {
            if let Err(kind) = self.intake.take(&msg, reference) {
                let i = kind as usize;
                self.rejected[i] += 1;
                if self.rejected[i] == 1 {
                    // a short leg: say which (its index in the planner's path and its times)
                    let period = reference.period();
                    let which = msg
                        .used()
                        .iter()
                        .enumerate()
                        .find(|(_, w)| kind == PlanInvalid::ShortLeg && w.t1 - w.t0 < period)
                        .map_or(String::new(), |(j, w)| {
                            format!(
                                ": piece {} from t = {} s to t = {} s lasts {:e} s, less than the control period {period} s",
                                msg.first_index as usize + j,
                                w.t0,
                                w.t1,
                                w.t1 - w.t0
                            )
                        });
                    log(format_args!(
                        "refused a plan message from pid {} ({kind}{which}); its pieces are not used. Further refusals of this kind are counted, not logged",
                        msg.planner_pid
                    ));
                }
            }
        }
    }

    /// Logs once when the stream runs dry (the last pose given is held, at rest: every
    /// piece ends at rest) and once when pieces cover `t_k` again.
    pub(crate) fn watch<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
        &mut self,
        reference: &PathReference<f64, G, N, M>,
    ) {
        let t = reference.time();
        let dry = reference.path().end_time().is_none_or(|end| end < t);
        if dry == self.dry {
            return;
        }
        self.dry = dry;
        if dry {
            log(format_args!(
                "t = {t:.3} s: the stream ran dry (no piece covers t or lies ahead): holding the last pose given, at rest"
            ));
        } else {
            let end = reference.path().end_time().unwrap_or(t);
            log(format_args!(
                "t = {t:.3} s: stream {}: {} pieces, up to t = {end:.3} s",
                if self.started { "resumed" } else { "started" },
                reference.path().segments().count()
            ));
            self.started = true;
        }
    }
}
