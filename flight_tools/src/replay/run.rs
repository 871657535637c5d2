//! One replay: the recorded states answered again by the controller's cycle, in order, with
//! the node's own checks and bookkeeping (the terms restored from each command, the law each
//! command names, the streamed reference's plan messages), and the estimator stepped again
//! over the recorded samples.

use super::output::{Row, figure, write_csv};
use super::{Difference, EstimatorCheck, ReplayOptions, ReplayReport};
use control_cycle::PlanIntake;
use eqtrack_controller::Source;
use eqtrack_controller::group::BuiltinGroup;
use eqtrack_controller::{Law, Trajectory as _};
use ipc_types::{CommandMsg, StateMsg};
use plant::SimError;
use plant::output::ensure_dir;
use recorder::{LogReader, PlanEntry, Record};
use scenario::Scenario;

/// The recorded plan messages handed to a streamed run's reference, as the node took them.
struct Plans<'a> {
    entries: &'a [PlanEntry],
    intake: PlanIntake,
    /// Entries before this one were handed over (or passed by).
    next: usize,
    taken: u64,
}

impl Plans<'_> {
    /// Before state k is answered (the reference still at the previous state's time, as
    /// the node pulls after answering): hands over what the controller had taken by the
    /// time it answered, as recorded command `c` says.
    fn catch_up<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
        &mut self,
        c: &CommandMsg,
        cycle: u64,
        reference: &mut Source<f64, G, N, M>,
    ) -> Result<(), SimError> {
        if c.plans_received == self.intake.received {
            return Ok(());
        }
        let Source::Path(path) = reference else {
            return Ok(());
        };
        let named = (c.plan_pid, c.plan_seq);
        let Some(j) = (self.next..self.entries.len())
            .find(|&i| (self.entries[i].msg.planner_pid, self.entries[i].msg.seq) == named)
        else {
            return Err(SimError::Input(format!(
                "cycle {cycle}: the controller had taken plan message seq {} from planner pid {}, which plans.log does not hold (the recorder did not see it on the plan board): this streamed run cannot be checked",
                c.plan_seq, c.plan_pid
            )));
        };
        // the messages taken since the last command: the last `new` seen up to the named one
        let new = c.plans_received.wrapping_sub(self.intake.received) as usize;
        for e in &self.entries[(j + 1).saturating_sub(new).max(self.next)..=j] {
            // a refused message counts as taken; the node refuses it the same way
            let _ = self.intake.take(&e.msg, path);
            self.taken += 1;
        }
        self.intake.received = c.plans_received;
        self.next = j + 1;
        Ok(())
    }
}

pub(super) fn replay_group<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    opts: &ReplayOptions,
    log: &mut LogReader,
    s: &Scenario,
    plans: Option<&[PlanEntry]>,
) -> Result<ReplayReport, SimError> {
    let mut run = ReplayRun::<G, N, M>::new(opts, log, s, plans)?;
    while let Some(r) = log.next_record()? {
        run.record(&r)?;
    }
    run.finish(log)
}

/// A `(responder, law)` pair: the controller's cycle answering with one law.
type LawResponder<G, const N: usize, const M: usize> =
    (Law, control_cycle::Responder<f64, G, N, M>);

/// The replay of one recording on group `G`: the controller's cycle (and the estimator) run
/// again over the records in order, with the node's own checks and bookkeeping.
struct ReplayRun<'a, G: BuiltinGroup<N, M>, const N: usize, const M: usize> {
    opts: &'a ReplayOptions,
    s: &'a Scenario,
    what_if: bool,
    /// One responder per law the recorded commands name (protocol 5 commands say which law
    /// computed them); a what-if answers every state with its own law.
    responders: Vec<LawResponder<G, N, M>>,
    /// The law the last recorded command named.
    law: Law,
    plans: Option<Plans<'a>>,
    /// The run's estimator, fresh, at the run's period: stepped over the recorded samples.
    estimation: Option<plant::estimation::Estimation>,
    /// The recorded states since the last one a command named as its previous.
    states: std::collections::BTreeMap<u64, StateMsg>,
    /// The reference's time at each of those states, as the controller answered them.
    times: std::collections::BTreeMap<u64, f64>,
    reference: Option<Source<f64, G, N, M>>,
    /// The cycle the next record should have.
    next: u64,
    /// The node's own checks on each state (sequence, period): what it would have rejected
    /// gets no command in replay either.
    last_seq: Option<u64>,
    period: Option<f64>,
    /// The last recorded command (its `u_cmd` is what the controller's next rate limit
    /// narrowed around).
    last_recorded: Option<CommandMsg>,
    rows: Vec<Row>,
    report: ReplayReport,
    /// `params.log`'s changes (a run started with `--tunable`), applied at their cycles with
    /// the run's own check, the tuner of its stored scenario; the next one to apply.
    params: Vec<recorder::ParamChange>,
    next_param: usize,
    tuner: Option<scenario::tuning::Tuner>,
    /// The controller's gains in force after the last change (`None`: the scenario's).
    gains: Option<ipc_types::Gains>,
    /// Not a what-if, and the recording has no `params.log`.
    params_missing: bool,
    /// With a failure detector: each state answered since the last recorded command without
    /// a command of its own, and the responder before it answered (the controller may have
    /// missed the state, which the next command's `previous_seq` tells).
    unseen: Vec<(u64, usize, control_cycle::Responder<f64, G, N, M>)>,
}

impl<'a, G: BuiltinGroup<N, M>, const N: usize, const M: usize> ReplayRun<'a, G, N, M> {
    fn new(
        opts: &'a ReplayOptions,
        log: &LogReader,
        s: &'a Scenario,
        plans: Option<&'a [PlanEntry]>,
    ) -> Result<Self, SimError> {
        let what_if = opts.what_if();
        // run-time parameter changes: replayed at their cycles (a what-if keeps its own gains)
        let params = if what_if {
            Vec::new()
        } else {
            recorder::read_params(&opts.dir)?
        };
        // a tunable run (its states say so) whose params.log is gone cannot replay its
        // changes: say so rather than report the differences they make
        let params_missing = !what_if && !opts.dir.join(recorder::PARAMS_FILE).exists();
        let tuner = if params.is_empty() {
            None
        } else {
            let source = scenario::cli::ScenarioSource {
                scenario: Some(opts.dir.join("scenario.toml")),
                builtin: None,
            };
            Some(
                scenario::tuning::Tuner::from_source(&source, &s.name)
                    .map_err(|e| SimError::Input(e.to_string()))?,
            )
        };
        let responders = vec![(s.law, responder_for::<G, N, M>(s, s.law)?)];
        let estimation = match (log.header.sensors, what_if) {
            (true, false) => {
                let mut at = s.clone();
                at.control_period = log.header.control_period;
                plant::estimation::Estimation::new(&at, at.control_period, &[])?
            }
            _ => None,
        };
        let report = ReplayReport {
            cycles: 0,
            compared: 0,
            differing: 0,
            first: None,
            max_torque_difference: 0.0,
            missing: 0,
            trailing_bytes: log.trailing_bytes,
            written: None,
            recorded_laws: Vec::new(),
            plans_taken: None,
            estimator: estimation.as_ref().map(|_| EstimatorCheck::default()),
            detector_lost_at: None,
        };
        Ok(ReplayRun {
            opts,
            s,
            what_if,
            responders,
            law: s.law,
            plans: plans.map(|entries| Plans {
                entries,
                intake: PlanIntake::default(),
                next: 0,
                taken: 0,
            }),
            estimation,
            states: std::collections::BTreeMap::new(),
            times: std::collections::BTreeMap::new(),
            reference: None,
            next: 0,
            last_seq: None,
            period: None,
            last_recorded: None,
            rows: Vec::new(),
            report,
            params,
            next_param: 0,
            tuner,
            gains: None,
            params_missing,
            unseen: Vec::new(),
        })
    }

    /// Puts in force every recorded parameter change that took effect by cycle `k`, as the
    /// run did: checked by the scenario's own validation, the controller's gains (every
    /// law's responder) and the estimator's, all at once. A change the check refuses, or
    /// whose recorded numbers differ from what its value gives, stops replay naming its
    /// cycle.
    fn retune(&mut self, r: &Record) -> Result<(), SimError> {
        if self.params_missing && r.state.flags & ipc_types::flags::TUNABLE != 0 {
            return Err(SimError::Input(format!(
                "{}: the run was started with --tunable (its states say so), and its params.log, which holds the gains it changed, is missing: it cannot be replayed without it",
                self.opts.dir.display()
            )));
        }
        let k = r.cycle;
        while let Some(p) = self.params.get(self.next_param).filter(|p| p.cycle <= k) {
            let bad = |what: String| {
                SimError::Input(format!(
                    "params.log: the change at cycle {} ({} = {}): {what}",
                    p.cycle, p.key, p.value
                ))
            };
            let Some(tuner) = &mut self.tuner else {
                return Err(bad("no tuner".to_owned()));
            };
            let change = tuner.apply(&p.key, &p.value).map_err(&bad)?;
            let numbers = scenario::tuning::numbers(&change.scenario, change.key);
            if numbers.len() != p.numbers.len()
                || numbers
                    .iter()
                    .zip(&p.numbers)
                    .any(|(a, b)| a.to_bits() != b.to_bits())
            {
                return Err(bad(format!(
                    "the value gives {numbers:?}, the log says {:?}",
                    p.numbers
                )));
            }
            match change.acts() {
                scenario::tuning::Acts::Controller => {
                    let gains = plant::tuning::gains(&change.scenario, p.cycle);
                    for (_, r) in &mut self.responders {
                        r.retune(&gains).map_err(|e| bad(e.to_string()))?;
                    }
                    self.gains = Some(gains);
                }
                scenario::tuning::Acts::Estimator => {
                    if let Some(e) = &mut self.estimation {
                        let est = &change.scenario.estimator;
                        e.retune(est.kp, est.ki)?;
                    }
                }
            }
            self.next_param += 1;
        }
        Ok(())
    }

    /// Replays one record: the estimator's check, the node's checks on the state, the
    /// controller's state restored from the command, the reference moved on, the answer
    /// compared with the recorded command.
    fn record(&mut self, r: &Record) -> Result<(), SimError> {
        self.report.cycles += 1;
        self.report.missing += r.cycle.saturating_sub(self.next);
        if r.cycle > self.next && self.detector_followed() {
            // records the recorder dropped: the controller saw states replay does not have
            self.lose_detector(self.next);
        }
        self.retune(r)?;
        self.check_estimator(r);
        self.next = r.cycle + 1;
        if ipc_types::check_state(
            &r.state,
            link::wire::wire_group(G::KIND),
            self.last_seq,
            self.period,
        )
        .is_err()
        {
            if let Some((rec, _)) = &r.command {
                compare::<M>(&mut self.report, true, r, rec, None);
            }
            return Ok(());
        }
        (self.last_seq, self.period) = (Some(r.state.seq), Some(r.state.control_period));
        self.note_law(r);
        let at = self.responder_index()?;
        if self.what_if {
            // a what-if runs no failure detector (its commands are not the ones the plant
            // applied, so no period is as the detector would believe): its allocator hears
            // what the run's detector found
            self.responders[at].1.lose_detector();
            if let Some((c, _)) = &r.command {
                self.responders[at].1.follow(c);
            }
        }
        if let (Some((c, _)), false) = (&r.command, self.what_if) {
            self.follow_detector(c, at)?;
            // the controller's state before it answered: from the command and the recorded
            // state it processed before (states it never saw, or answered too late to be
            // recorded, change nothing)
            let previous = self.states.get(&c.previous_seq).copied();
            self.responders[at].1.restore(c, previous.as_ref());
            if self.report.detector_lost_at.is_some() {
                self.follow_manager(r, at, c);
            }
            self.states.retain(|k, _| *k >= c.previous_seq);
            self.times.retain(|k, _| *k >= c.previous_seq);
        } else if r.command.is_none() && !self.what_if && self.responders[at].1.carries_state() {
            // the controller may not have seen this state: its responder before answering
            self.unseen
                .push((r.state.seq, at, self.responders[at].1.clone()));
        }
        self.states.insert(r.state.seq, r.state);
        let mut replayed = self.answer(r, at)?;
        if let (Some(now), Some(before)) = (&mut replayed, &self.last_recorded)
            && before.seq == now.previous_seq
        {
            // the limit's memory as the controller's own previous command says it was, not as
            // this record restores it (a replayed answer to a state whose command was not
            // recorded may differ from the one the controller sent)
            now.u_previous = before.u_cmd;
        }
        if let Some((c, _)) = &r.command {
            self.last_recorded = Some(*c);
        }
        let recorded = r.command.map(|c| c.0);
        if let Some(rec) = &recorded {
            let followed = self.report.detector_lost_at.is_none();
            compare::<M>(&mut self.report, followed, r, rec, replayed.as_ref());
        }
        if self.what_if {
            self.rows.push(Row {
                cycle: r.cycle,
                t: r.state.t,
                decision: r.decision,
                recorded,
                replayed,
            });
        }
        Ok(())
    }

    /// Steps the estimator over the record's samples, or stops checking it at the first
    /// gap (the filter's state after a gap is not in the record).
    fn check_estimator(&mut self, r: &Record) {
        if let (Some(e), Some(check)) = (&mut self.estimation, &mut self.report.estimator) {
            match (&r.sensors, r.cycle == self.next) {
                (Some(sr), true) => check_estimate::<N, M>(e, sr, r, check),
                _ => {
                    check.stopped_at = Some(r.cycle);
                    self.estimation = None;
                }
            }
        }
    }

    /// Follows the law the recorded command names (not in a what-if).
    fn note_law(&mut self, r: &Record) {
        if let (Some((c, _)), false) = (&r.command, self.what_if)
            && let Some(named) = link::wire::law_from_code(c.law)
        {
            self.law = named;
            if !self.report.recorded_laws.contains(&named) {
                self.report.recorded_laws.push(named);
            }
        }
    }

    /// The responder of the current law, made on its first use.
    fn responder_index(&mut self) -> Result<usize, SimError> {
        Ok(
            match self.responders.iter().position(|(l, _)| *l == self.law) {
                Some(i) => i,
                None => {
                    let mut responder = responder_for::<G, N, M>(self.s, self.law)?;
                    if let Some(g) = &self.gains {
                        // the run-time gains in force reach a law first named after a change
                        responder
                            .retune(g)
                            .map_err(|e| SimError::Input(format!("run-time gains: {e}")))?;
                    }
                    self.responders.push((self.law, responder));
                    self.responders.len() - 1
                }
            },
        )
    }

    /// Follows the failure detector, whose state is in no command, before recorded command
    /// `c` restores the rest ([`unseen_fate`]): back to before the states the controller
    /// never saw, or lost where the log cannot say, or afresh after a restart.
    fn follow_detector(&mut self, c: &CommandMsg, at: usize) -> Result<(), SimError> {
        let seqs: Vec<u64> = self.unseen.iter().map(|(k, _, _)| *k).collect();
        match unseen_fate(&seqs, c.previous_seq) {
            Unseen::Keep => {}
            Unseen::Back(i) => self.take_back(i)?,
            Unseen::Lost => {
                // back to before the first state the log cannot say the controller saw: what
                // replay's own manager made of the states after it is no guide to the
                // controller's, whose recorded words are flown from here
                self.take_back(0)?;
                self.lose_detector(seqs[0]);
            }
            Unseen::Restart if self.s.fault_detection.is_some() || self.s.failsafe.is_some() => {
                // a controller started again: its detector and failsafe manager start afresh,
                // as replay's
                let mut fresh = responder_for::<G, N, M>(self.s, self.law)?;
                if let Some(g) = &self.gains {
                    fresh
                        .retune(g)
                        .map_err(|e| SimError::Input(format!("run-time gains: {e}")))?;
                }
                if self.report.detector_lost_at.is_some() {
                    fresh.lose_detector();
                }
                self.responders[at].1 = fresh;
            }
            Unseen::Restart => {}
        }
        self.unseen.clear();
        Ok(())
    }

    /// Puts back the responder kept before answering the `i`-th state the controller may not
    /// have seen, with the run-time gains changed since it was kept.
    fn take_back(&mut self, i: usize) -> Result<(), SimError> {
        let (_, slot, mut responder) = self.unseen.swap_remove(i);
        if let Some(g) = &self.gains {
            responder
                .retune(g)
                .map_err(|e| SimError::Input(format!("run-time gains: {e}")))?;
        }
        self.responders[slot].1 = responder;
        Ok(())
    }

    /// Follows the recorded command `c` of record `r` once replay has lost the manager's
    /// state (docs/failsafe.md, "In the pair and on the firmware"). A change of mode it
    /// records was engaged at one of the states the controller answered since the last
    /// recorded command, at that state's estimate: each is tried in turn, and the first
    /// whose answer to `r` gives `c`'s torques and commands bit for bit is taken. If none
    /// does (or a streamed reference makes a trial impossible), it is engaged at `r`.
    fn follow_manager(&mut self, r: &Record, at: usize, c: &CommandMsg) {
        let responder = &self.responders[at].1;
        let after = self.last_recorded.map_or(0, |l| l.seq.saturating_add(1));
        let engaged = match (
            &self.reference,
            &self.plans,
            responder.changes_failsafe_mode(c),
        ) {
            (Some(reference), None, true) => self
                .states
                .range(after..r.state.seq)
                .filter_map(|(k, st)| Some((st, *self.times.get(k)?)))
                .find(|(st, t)| {
                    let mut trial = responder.clone();
                    trial.follow_engaged_at(c, st, *t);
                    let mut reference = reference.clone();
                    reference.advance();
                    trial
                        .respond(&mut reference, &r.state)
                        .is_ok_and(|answer| same_answer::<M>(&answer, c))
                })
                .map(|(st, t)| (*st, t)),
            _ => None,
        };
        match engaged {
            Some((st, t)) => self.responders[at].1.follow_engaged_at(c, &st, t),
            None => self.responders[at].1.follow(c),
        }
    }

    /// Whether replay still follows the state no command carries: the failure detector's or
    /// the failsafe manager's (the scenario has one, and it has not been lost).
    fn detector_followed(&self) -> bool {
        !self.what_if
            && self.report.detector_lost_at.is_none()
            && self.responders.iter().any(|(_, r)| r.carries_state())
    }

    /// Stops running the failure detector from `cycle` on, a state the log cannot say the
    /// controller saw ([`ReplayReport::detector_lost_at`]).
    fn lose_detector(&mut self, cycle: u64) {
        self.report.detector_lost_at.get_or_insert(cycle);
        for (_, responder) in &mut self.responders {
            responder.lose_detector();
        }
        self.unseen.clear();
    }

    /// The node builds its reference on the first state, at the plant's period (a streamed
    /// one holds the start pose until pieces come); it moves it on after each answer, after
    /// taking the plan messages that came (replay: before the next answer). Then responder
    /// `at` answers the state.
    fn answer(&mut self, r: &Record, at: usize) -> Result<Option<CommandMsg>, SimError> {
        let (reference, fresh) = match &mut self.reference {
            Some(x) => (x, false),
            None => {
                let mut at = self.s.clone();
                at.control_period = r.state.control_period;
                let built = match self.plans {
                    Some(_) => control_cycle::streamed_reference::<G, N, M>(&at),
                    None => at.reference_source::<G, N, M>(),
                };
                (self.reference.insert(built.map_err(bad(self.s))?), true)
            }
        };
        if let (Some(p), Some((c, _))) = (&mut self.plans, &r.command) {
            p.catch_up(c, r.cycle, reference)?;
        }
        if !fresh {
            reference.advance();
        }
        let answer = self.responders[at].1.respond(reference, &r.state).ok();
        self.times.insert(r.state.seq, reference.time());
        Ok(answer)
    }

    /// The report, and a what-if's `replay.csv` and figure.
    fn finish(mut self, log: &LogReader) -> Result<ReplayReport, SimError> {
        self.report.plans_taken = self.plans.map(|p| p.taken);
        if self.report.recorded_laws == [self.s.law] {
            self.report.recorded_laws.clear();
        }
        if self.what_if {
            let out = self
                .opts
                .out
                .clone()
                .unwrap_or_else(|| self.opts.dir.clone());
            ensure_dir(&out)?;
            write_csv::<M>(&self.rows, &out.join("replay.csv"))?;
            figure::<M>(
                &self.rows,
                self.opts,
                self.s,
                &log.header.law,
                &out.join("replay"),
            )?;
            self.report.written = Some(out);
        }
        Ok(self.report)
    }
}

/// What replay does with the failure detector before a recorded command whose
/// `previous_seq` is `p`, given the states it answered since the last recorded command that
/// have no command of their own (`unseen`, in order): the controller may have answered them
/// too late to be recorded, or never seen them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Unseen {
    /// The controller saw them all (the last is `p`, or there are none).
    Keep,
    /// It saw none from the `i`-th on (they are after `p`): back to the responder kept
    /// before that one.
    Back(usize),
    /// One before `p`: whether it saw that one is not known.
    Lost,
    /// The controller started again (`p` is `NO_PREVIOUS`).
    Restart,
}

/// [`Unseen`] for `unseen` before a command naming `p` as its previous state.
fn unseen_fate(unseen: &[u64], p: u64) -> Unseen {
    if p == ipc_types::NO_PREVIOUS {
        return Unseen::Restart;
    }
    if unseen.iter().any(|k| *k < p) {
        return Unseen::Lost;
    }
    match unseen.iter().position(|k| *k > p) {
        Some(i) => Unseen::Back(i),
        None => Unseen::Keep,
    }
}

/// Whether `answer` has recorded command `c`'s torques and actuator commands, bit for bit.
fn same_answer<const M: usize>(answer: &CommandMsg, c: &CommandMsg) -> bool {
    let bits = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
    bits(&answer.tau[..M], &c.tau[..M]) && bits(&answer.u_cmd, &c.u_cmd)
}

/// A bad scenario, named.
fn bad(s: &Scenario) -> impl Fn(eqtrack_controller::Error) -> SimError + '_ {
    move |e| SimError::Input(format!("scenario `{}`: {e}", s.name))
}

/// The controller's cycle for scenario `s` with law `law` (the scenario's own, or another
/// one a recorded command names).
fn responder_for<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    s: &Scenario,
    law: Law,
) -> Result<control_cycle::Responder<f64, G, N, M>, SimError> {
    let with = if law == s.law {
        s.clone()
    } else {
        s.clone().with_law(law).map_err(|e| {
            SimError::Input(format!(
                "the recorded commands name law {}: {e}",
                law.name()
            ))
        })?
    };
    let responder = with
        .controller::<G, N, M>()
        .and_then(|c| control_cycle::Responder::new(c, with.rejection_config()))
        .map_err(bad(s))?;
    let responder = match control_cycle::Supervisor::of(&with) {
        Some(sup) => responder.with_supervisor(sup),
        None => responder,
    };
    Ok(match &with.vehicle {
        None => responder,
        Some(_) => responder.with_vehicle(
            control_cycle::ControllerVehicle::of(&with)
                .map_err(|e| SimError::Input(format!("scenario `{}`: {e}", s.name)))?,
        ),
    })
}

/// Steps the estimator over record `r`'s samples and compares what it publishes with the
/// recorded state message's `Q̂`, `V̂` and the recorded bias, bit for bit.
fn check_estimate<const N: usize, const M: usize>(
    e: &mut plant::estimation::Estimation,
    sr: &recorder::SensorRecord,
    r: &Record,
    check: &mut EstimatorCheck,
) {
    let truth = StateMsg {
        q: sr.q_true,
        v: sr.v_true,
        ..r.state
    };
    let (q_hat, v_hat, row) = e.estimate::<N, M>(
        sr.samples,
        &truth.configuration::<N>(),
        &truth.velocity::<M>(),
    );
    let mut published = r.state;
    published.set_state(&q_hat, &v_hat);
    check.compared += 1;
    let pairs = (0..N * N)
        .map(|i| (format!("estimate Q̂[{i}]"), r.state.q[i], published.q[i]))
        .chain((0..M).map(|i| (format!("estimate V̂[{i}]"), r.state.v[i], published.v[i])))
        .chain((0..3).map(|i| {
            (
                format!("estimated bias[{i}]"),
                sr.bias_hat[i],
                row.bias_hat[i],
            )
        }));
    let mut found = None;
    for (what, a, b) in pairs {
        if a.to_bits() != b.to_bits() {
            found = Some(Difference {
                cycle: r.cycle,
                t: r.state.t,
                what,
                recorded: a,
                replayed: b,
            });
            break;
        }
    }
    if let Some(d) = found {
        check.differing += 1;
        check.first.get_or_insert(d);
    }
}

/// A vehicle's fields of a recorded and a replayed command, side by side: the actuator
/// count and status (as numbers), the demand, `B u_cmd`, the wrench the law counts as
/// applied, the actuator commands, and the command the rate limit narrowed around (the
/// replayed one is the previous recorded command's `u_cmd`, where that command is the one
/// `previous_seq` names: a record whose `u_previous` is not what the controller had
/// commanded is found), and the failure detector's finding and alarms (replay runs the
/// detector again over the states in order).
fn vehicle_fields<const M: usize>(
    recorded: &CommandMsg,
    c: &CommandMsg,
    detector: bool,
) -> impl Iterator<Item = (String, f64, f64)> {
    let allocation = [
        (
            "actuators".to_owned(),
            f64::from(recorded.actuators),
            f64::from(c.actuators),
        ),
        (
            "alloc_status".to_owned(),
            f64::from(recorded.alloc_status),
            f64::from(c.alloc_status),
        ),
    ];
    let detection = [
        (
            "detected".to_owned(),
            f64::from(recorded.detected),
            f64::from(c.detected),
        ),
        (
            "detected_kind".to_owned(),
            f64::from(recorded.detected_kind),
            f64::from(c.detected_kind),
        ),
        (
            "detected_value".to_owned(),
            recorded.detected_value,
            c.detected_value,
        ),
        (
            "detected_refined".to_owned(),
            f64::from(recorded.detected_refined),
            f64::from(c.detected_refined),
        ),
        (
            "alarms".to_owned(),
            f64::from(recorded.alarms),
            f64::from(c.alarms),
        ),
        ("statistic".to_owned(), recorded.statistic, c.statistic),
        (
            "suspect".to_owned(),
            f64::from(recorded.suspect),
            f64::from(c.suspect),
        ),
    ];
    // past the point replay could follow the detector, its fields are not compared
    let counts = allocation
        .into_iter()
        .chain(detection.into_iter().filter(move |_| detector));
    let wrenches = (0..M).flat_map(move |i| {
        [
            (format!("demand[{i}]"), recorded.demand[i], c.demand[i]),
            (
                format!("achieved[{i}]"),
                recorded.achieved[i],
                c.achieved[i],
            ),
            (
                format!("accounted[{i}]"),
                recorded.accounted[i],
                c.accounted[i],
            ),
        ]
    });
    let count = (recorded.actuators as usize).min(ipc_types::MAX_ACTUATORS);
    let commands = (0..count).flat_map(move |j| {
        [
            (format!("u_cmd[{j}]"), recorded.u_cmd[j], c.u_cmd[j]),
            (
                format!("u_previous[{j}]"),
                recorded.u_previous[j],
                c.u_previous[j],
            ),
        ]
    });
    counts.into_iter().chain(wrenches).chain(commands)
}

/// Compares one recorded command with the replayed one, bit for bit (torque, L, the
/// observer's estimate, the integral's torque, and a vehicle's allocation).
fn compare<const M: usize>(
    report: &mut ReplayReport,
    followed: bool,
    r: &Record,
    recorded: &CommandMsg,
    replayed: Option<&CommandMsg>,
) {
    report.compared += 1;
    let diff = |what: String, a: f64, b: f64| Difference {
        cycle: r.cycle,
        t: r.state.t,
        what,
        recorded: a,
        replayed: b,
    };
    let found = match replayed {
        None => Some(diff(
            "no command: the controller would reject or refuse this state".to_owned(),
            recorded.tau[0],
            f64::NAN,
        )),
        Some(c) => {
            let mut worst: Option<Difference> = None;
            for i in 0..M {
                let (a, b) = (recorded.tau[i], c.tau[i]);
                let d = (b - a).abs();
                if d.is_finite() {
                    report.max_torque_difference = report.max_torque_difference.max(d);
                }
                if a.to_bits() != b.to_bits()
                    && worst.as_ref().is_none_or(|w| d.total_cmp(&w.by()).is_gt())
                {
                    worst = Some(diff(format!("tau[{i}]"), a, b));
                }
            }
            worst.or_else(|| {
                let terms = (0..M).flat_map(|i| {
                    [
                        (
                            format!("observer[{i}]"),
                            recorded.observer[i],
                            c.observer[i],
                        ),
                        (
                            format!("integral[{i}]"),
                            recorded.integral[i],
                            c.integral[i],
                        ),
                    ]
                });
                // the failsafe manager's word, while replay follows the state no command
                // carries (as the detector's fields)
                let failsafe = (
                    "failsafe".to_owned(),
                    f64::from(recorded.failsafe),
                    f64::from(c.failsafe),
                );
                std::iter::once(("L".to_owned(), recorded.lyapunov, c.lyapunov))
                    .chain(std::iter::once(failsafe).filter(|_| followed))
                    .chain(terms)
                    .chain(vehicle_fields::<M>(recorded, c, followed))
                    .find(|(_, a, b)| a.to_bits() != b.to_bits())
                    .map(|(what, a, b)| diff(what, a, b))
            })
        }
    };
    if let Some(d) = found {
        report.differing += 1;
        if report.first.is_none() {
            report.first = Some(d);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{Unseen, unseen_fate};

    #[test]
    fn states_without_a_recorded_command_are_kept_taken_back_or_lost() {
        // none: nothing to do
        assert_eq!(unseen_fate(&[], 41), Unseen::Keep);
        // 42 answered late, and 43's command names it: seen
        assert_eq!(unseen_fate(&[42], 42), Unseen::Keep);
        // 43's command names 41: 42 never reached the controller
        assert_eq!(unseen_fate(&[42], 41), Unseen::Back(0));
        // 42 and 43 without commands, 44's names 42: 43 never seen, 42 seen
        assert_eq!(unseen_fate(&[42, 43], 42), Unseen::Back(1));
        // 44's names 43: seen, but whether 42 was is not known
        assert_eq!(unseen_fate(&[42, 43], 43), Unseen::Lost);
        // a controller started again
        assert_eq!(unseen_fate(&[42], ipc_types::NO_PREVIOUS), Unseen::Restart);
        assert_eq!(unseen_fate(&[], ipc_types::NO_PREVIOUS), Unseen::Restart);
    }
}
