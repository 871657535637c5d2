//! The streamed reference's bookkeeping in the process: the plan board read each cycle, the
//! pieces taken through [`control_cycle::PlanIntake`], and the log lines when it runs dry.

use crate::{NodeError, log};
use control_cycle::PlanIntake;
use eqtrack_controller::Trajectory;
use eqtrack_controller::group::BuiltinGroup;
use eqtrack_controller::path::PathReference;
use ipc_types::PlanInvalid;
use link::plan::PlanReader;

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
    pub(crate) fn pull<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
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
    pub(crate) fn watch<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
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
