//! `plant_sim replay OUT_DIR`: the controller, in-process, over the states a run recorded
//! (docs/architecture.md, "The flight recorder").
//!
//! Each recorded state goes through `control_cycle::Responder::respond` — the very cycle
//! the controller process runs — with the scenario the run stored beside its log, the reference
//! built at the plant's period and stepped exactly as the node steps it. The controller is
//! deterministic, so every recorded command must come out again bit for bit: a difference is
//! a bug (or a different build, or a corrupted log), and replay names the first cycle that
//! differs and by how much. With another law, scenario or gains it is a what-if: the same
//! states, the other controller's answers, written to `replay.csv` and a figure. (Open loop:
//! the body would have moved differently under the other torques; the states are the
//! recorded ones.)
//!
//! The disturbance-rejection terms are the controller's state between cycles. Each recorded
//! command carries the terms' state before it (`estimate_before`, `z_before`) and the state
//! processed before it (`previous_seq`), so replay restores them from the record and checks
//! every command on its own, whatever states the controller skipped or answered too late to
//! be recorded. A what-if runs its own terms over every recorded state.
//!
//! A streamed run (its commands carry `STREAMED`) starts from the streamed reference's held
//! pose, and each recorded command says how many plan messages the controller had taken and
//! which was the last: replay hands the recorded plan messages (`plans.log`) to the same
//! `control_cycle::PlanIntake` at the cycle they were taken, before it moves the reference
//! on, as the node does. A command naming a message the recorder never saw is a log replay
//! cannot check, and it says so.
//!
//! A run with sensors recorded each tick's samples and true state: replay steps a fresh copy
//! of the run's estimator over the recorded samples and checks that it publishes the
//! recorded estimate (`Q̂`, `V̂` in the state message, the bias) bit for bit, up to the first
//! gap in the log (the filter's state after a gap is not in the record).

use recorder::{LOG_FILE, LogReader, PlanEntry, Record, read_plans};
use plant::SimError;
use plant::output::ensure_dir;
use plant::plot::{Line, Panel, law_color, render};
use controller::Source;
use controller::group::{MatrixLieGroup, OnGroup};
use controller::{Law, Trajectory as _};
use control_cycle::PlanIntake;
use ipc_types::{CommandMsg, MAX_M, StateMsg, flags};
use link::Decision;
use link::wire::group_code;
use scenario::Scenario;
use std::path::{Path, PathBuf};

/// What to replay, and what to change.
#[derive(Debug, Clone, Default)]
pub struct ReplayOptions {
    /// The run's output directory (`messages.log`, `scenario.toml`).
    pub dir: PathBuf,
    /// What-if: another law.
    pub law: Option<Law>,
    /// What-if: another scenario file (the controller's law, gains, model and reference).
    pub scenario: Option<PathBuf>,
    /// What-if: the potential weight K (`X` for X·I, or the n diagonal entries).
    pub kp: Option<Vec<f64>>,
    /// What-if: the damping K_d (`X` for X·I, or the m diagonal entries).
    pub kd: Option<Vec<f64>>,
    /// Where replay.csv and the figure go (default: the run's directory).
    pub out: Option<PathBuf>,
}

impl ReplayOptions {
    /// Whether anything is changed (a what-if) rather than checked.
    pub fn what_if(&self) -> bool {
        self.law.is_some() || self.scenario.is_some() || self.kp.is_some() || self.kd.is_some()
    }
}

/// The first command that came out differently.
#[derive(Debug, Clone, PartialEq)]
pub struct Difference {
    /// The cycle k.
    pub cycle: u64,
    /// Its time (s).
    pub t: f64,
    /// Which value: `tau[i]`, `L`, or why no command came out.
    pub what: String,
    /// The recorded value.
    pub recorded: f64,
    /// The replayed value.
    pub replayed: f64,
}

impl Difference {
    /// |replayed − recorded| (NaN when no command came out).
    pub fn by(&self) -> f64 {
        (self.replayed - self.recorded).abs()
    }

    /// The difference in words: `tau[2] recorded …, replayed …, by …`.
    pub fn describe(&self) -> String {
        if self.replayed.is_nan() && !self.recorded.is_nan() {
            return format!("{} (recorded tau[0] {:e})", self.what, self.recorded);
        }
        format!(
            "{} recorded {:e}, replayed {:e}, by {:e}",
            self.what,
            self.recorded,
            self.replayed,
            self.by()
        )
    }
}

/// What a replay found.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayReport {
    /// Records replayed (whole records in the log).
    pub cycles: u64,
    /// Records with a recorded command (compared).
    pub compared: u64,
    /// Compared commands that differ in any bit of the torque, of L or of the
    /// disturbance-rejection terms.
    pub differing: u64,
    /// The first of them.
    pub first: Option<Difference>,
    /// The largest torque difference over all compared cycles.
    pub max_torque_difference: f64,
    /// Cycles missing from the log (the recorder dropped them).
    pub missing: u64,
    /// Bytes after the last whole record (a log cut short, e.g. by SIGKILL).
    pub trailing_bytes: u64,
    /// What-if: `replay.csv` and the figure written.
    pub written: Option<PathBuf>,
    /// The laws the recorded commands name, when one differs from the scenario's (a
    /// controller started by hand with `--law`): replay answered each state with the law
    /// its recorded command names.
    pub recorded_laws: Vec<Law>,
    /// A streamed run: the plan messages replay handed to the controller (`None`: not a
    /// streamed run).
    pub plans_taken: Option<u64>,
    /// A run with sensors: the estimates checked (the estimator stepped over the recorded
    /// samples), how many differ in any bit, the first difference, and the cycle of the
    /// first gap in the log, after which the estimator cannot be checked.
    pub estimator: Option<EstimatorCheck>,
}

/// What replaying the estimator found.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct EstimatorCheck {
    /// Estimates checked.
    pub compared: u64,
    /// Estimates that differ in any bit of `Q̂`, `V̂` or the bias.
    pub differing: u64,
    /// The first of them.
    pub first: Option<Difference>,
    /// The cycle of the first gap in the log (the rest is not checked).
    pub stopped_at: Option<u64>,
}

/// Replays `opts.dir`'s log.
pub fn replay(opts: &ReplayOptions) -> Result<ReplayReport, SimError> {
    let path = opts.dir.join(LOG_FILE);
    let streamed = first_command(&path)?.is_some_and(|c| c.flags & flags::STREAMED != 0);
    let plans = if streamed {
        Some(read_plans(&opts.dir)?)
    } else {
        None
    };
    let mut log = LogReader::open(&path)?;
    let s = scenario_for(opts, &log)?;
    s.group.dispatch(Replay {
        opts,
        log: &mut log,
        s: &s,
        plans: plans.as_deref(),
    })
}

/// The first recorded command of the log at `path`.
fn first_command(path: &Path) -> Result<Option<CommandMsg>, SimError> {
    let mut log = LogReader::open(path)?;
    while let Some(r) = log.next_record()? {
        if let Some((c, _)) = r.command {
            return Ok(Some(c));
        }
    }
    Ok(None)
}

/// The scenario of the run (its stored copy, checked against the log's fingerprint) with the
/// what-if changes applied.
fn scenario_for(opts: &ReplayOptions, log: &LogReader) -> Result<Scenario, SimError> {
    let h = &log.header;
    let stored = opts.dir.join("scenario.toml");
    let mut s = match &opts.scenario {
        Some(p) => Scenario::from_file(p)?,
        None if stored.exists() => Scenario::from_file(&stored)?,
        None => {
            return Err(SimError::Input(format!(
                "{} is missing: the run's scenario is stored there; give one with --scenario FILE",
                stored.display()
            )));
        }
    };
    if group_code(s.group) != h.group {
        return Err(SimError::Input(format!(
            "scenario `{}` is on {}, the recorded run is not (group code {})",
            s.name,
            s.group.name(),
            h.group
        )));
    }
    if opts.scenario.is_none() && s.fingerprint() != h.fingerprint {
        return Err(SimError::Input(format!(
            "{}: fingerprint {:#x} differs from the recorded run's {:#x}: this is not the scenario the run used",
            stored.display(),
            s.fingerprint(),
            h.fingerprint
        )));
    }
    if let Some(l) = opts.law {
        s = s.with_law(l)?;
    }
    let (n, m) = s.group.dims();
    if let Some(kp) = &opts.kp {
        s.kp = gain("--kp", kp, n)?;
    }
    if let Some(kd) = &opts.kd {
        s.kd = gain("--kd", kd, m)?;
    }
    Ok(s)
}

/// A gain override as a row-major `dim`×`dim` matrix: one positive number X (X·I) or `dim`
/// positive diagonal entries.
fn gain(flag: &str, values: &[f64], dim: usize) -> Result<Vec<f64>, SimError> {
    let diag: Vec<f64> = match values.len() {
        1 => vec![values[0]; dim],
        l if l == dim => values.to_vec(),
        l => {
            return Err(SimError::Input(format!(
                "{flag}: expected one number (times the identity) or {dim} diagonal entries, got {l}"
            )));
        }
    };
    if let Some(x) = diag.iter().find(|x| !(x.is_finite() && **x > 0.0)) {
        return Err(SimError::Input(format!(
            "{flag}: gains must be positive and finite, got {x}"
        )));
    }
    let mut g = vec![0.0; dim * dim];
    for (i, x) in diag.iter().enumerate() {
        g[i * dim + i] = *x;
    }
    Ok(g)
}

struct Replay<'a> {
    opts: &'a ReplayOptions,
    log: &'a mut LogReader,
    s: &'a Scenario,
    plans: Option<&'a [PlanEntry]>,
}

impl OnGroup for Replay<'_> {
    type Output = Result<ReplayReport, SimError>;
    fn run<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
        replay_group::<G, N, M>(self.opts, self.log, self.s, self.plans)
    }
}

/// One cycle of `replay.csv`.
struct Row {
    cycle: u64,
    t: f64,
    decision: Decision,
    recorded: Option<CommandMsg>,
    replayed: Option<CommandMsg>,
}

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
    fn catch_up<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
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

fn replay_group<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
    opts: &ReplayOptions,
    log: &mut LogReader,
    s: &Scenario,
    plans: Option<&[PlanEntry]>,
) -> Result<ReplayReport, SimError> {
    let bad = |e: controller::Error| SimError::Input(format!("scenario `{}`: {e}", s.name));
    let responder_for = |law: Law| -> Result<_, SimError> {
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
        with.controller::<G, N, M>()
            .and_then(|c| control_cycle::Responder::new(c, with.rejection_config()))
            .map_err(bad)
    };
    // one responder per law the recorded commands name (protocol 5 commands say which law
    // computed them); a what-if answers every state with its own law
    let mut responders = vec![(s.law, responder_for(s.law)?)];
    let mut law = s.law;
    let what_if = opts.what_if();
    let mut report = ReplayReport {
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
        estimator: None,
    };
    let mut plans = plans.map(|entries| Plans {
        entries,
        intake: PlanIntake::default(),
        next: 0,
        taken: 0,
    });
    // the run's estimator, fresh, at the run's period: stepped over the recorded samples
    let mut estimation = match (log.header.sensors, what_if) {
        (true, false) => {
            let mut at = s.clone();
            at.control_period = log.header.control_period;
            plant::estimation::Estimation::new(&at, at.control_period, &[])?
        }
        _ => None,
    };
    if estimation.is_some() {
        report.estimator = Some(EstimatorCheck::default());
    }
    let mut rows = Vec::new();
    // the recorded states since the last one a command named as its previous
    let mut states = std::collections::BTreeMap::<u64, ipc_types::StateMsg>::new();
    let mut reference = None;
    let mut next = 0u64;
    // the node's own checks on each state (sequence, period, finite numbers): what it would
    // have rejected gets no command in replay either
    let (mut last_seq, mut period) = (None, None);
    while let Some(r) = log.next_record()? {
        report.cycles += 1;
        report.missing += r.cycle.saturating_sub(next);
        if let (Some(e), Some(check)) = (&mut estimation, &mut report.estimator) {
            match (&r.sensors, r.cycle == next) {
                (Some(sr), true) => check_estimate::<N, M>(e, sr, &r, check),
                _ => {
                    check.stopped_at = Some(r.cycle);
                    estimation = None;
                }
            }
        }
        next = r.cycle + 1;
        if ipc_types::check_state(&r.state, link::wire::wire_group(G::KIND), last_seq, period)
            .is_err()
        {
            if let Some((rec, _)) = &r.command {
                compare::<M>(&mut report, &r, rec, None);
            }
            continue;
        }
        (last_seq, period) = (Some(r.state.seq), Some(r.state.control_period));
        if let (Some((c, _)), false) = (&r.command, what_if)
            && let Some(named) = link::wire::law_from_code(c.law)
        {
            law = named;
            if !report.recorded_laws.contains(&named) {
                report.recorded_laws.push(named);
            }
        }
        let at = match responders.iter().position(|(l, _)| *l == law) {
            Some(i) => i,
            None => {
                responders.push((law, responder_for(law)?));
                responders.len() - 1
            }
        };
        let responder = &mut responders[at].1;
        if let (Some((c, _)), false) = (&r.command, what_if) {
            // the controller's state before it answered: from the command and the recorded
            // state it processed before (states it never saw, or answered too late to be
            // recorded, change nothing)
            let previous = states.get(&c.previous_seq).copied();
            responder.restore(c, previous.as_ref());
            states.retain(|k, _| *k >= c.previous_seq);
        }
        states.insert(r.state.seq, r.state);
        // the node builds its reference on the first state, at the plant's period (a
        // streamed one holds the start pose until pieces come); it moves it on after each
        // answer, after taking the plan messages that came (replay: before the next answer)
        let (reference, fresh) = match &mut reference {
            Some(x) => (x, false),
            None => {
                let mut at = s.clone();
                at.control_period = r.state.control_period;
                let built = match plans {
                    Some(_) => control_cycle::streamed_reference::<G, N, M>(&at),
                    None => at.reference_source::<G, N, M>(),
                };
                (reference.insert(built.map_err(bad)?), true)
            }
        };
        if let (Some(p), Some((c, _))) = (&mut plans, &r.command) {
            p.catch_up(c, r.cycle, reference)?;
        }
        if !fresh {
            reference.advance();
        }
        let replayed = responder.respond(reference, &r.state).ok();
        let recorded = r.command.map(|c| c.0);
        if let Some(rec) = &recorded {
            compare::<M>(&mut report, &r, rec, replayed.as_ref());
        }
        if what_if {
            rows.push(Row {
                cycle: r.cycle,
                t: r.state.t,
                decision: r.decision,
                recorded,
                replayed,
            });
        }
    }
    report.plans_taken = plans.map(|p| p.taken);
    if report.recorded_laws == [s.law] {
        report.recorded_laws.clear();
    }
    if what_if {
        let out = opts.out.clone().unwrap_or_else(|| opts.dir.clone());
        ensure_dir(&out)?;
        write_csv::<M>(&rows, &out.join("replay.csv"))?;
        figure::<M>(&rows, opts, s, &log.header.law, &out.join("replay"))?;
        report.written = Some(out);
    }
    Ok(report)
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

/// Compares one recorded command with the replayed one, bit for bit (torque, L, the
/// observer's estimate and the integral's torque).
fn compare<const M: usize>(
    report: &mut ReplayReport,
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
                std::iter::once(("L".to_owned(), recorded.lyapunov, c.lyapunov))
                    .chain(terms)
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

fn num(x: f64) -> String {
    if x.is_finite() {
        format!("{x:e}")
    } else {
        String::new()
    }
}

fn write_csv<const M: usize>(rows: &[Row], path: &Path) -> Result<(), SimError> {
    let fail = |e: csv::Error| SimError::Run(format!("cannot write {}: {e}", path.display()));
    let mut w = csv::Writer::from_path(path).map_err(fail)?;
    let mut head = vec![
        "cycle".to_owned(),
        "t".to_owned(),
        "command_status".to_owned(),
    ];
    for side in ["recorded", "replayed"] {
        head.extend((0..M).map(|i| format!("{side}_tau_{i}")));
        head.push(format!("{side}_lyapunov"));
    }
    w.write_record(&head).map_err(fail)?;
    let side = |c: &Option<CommandMsg>| -> Vec<String> {
        let (tau, l) = match c {
            Some(c) => (c.tau, c.lyapunov),
            None => ([f64::NAN; MAX_M], f64::NAN),
        };
        tau[..M].iter().chain([&l]).map(|x| num(*x)).collect()
    };
    for r in rows {
        let mut rec = vec![
            r.cycle.to_string(),
            format!("{:e}", r.t),
            r.decision.code().to_string(),
        ];
        rec.extend(side(&r.recorded));
        rec.extend(side(&r.replayed));
        w.write_record(&rec).map_err(fail)?;
    }
    w.flush()
        .map_err(|e| SimError::Run(format!("cannot write {}: {e}", path.display())))
}

/// Recorded and replayed torque per axis and L, against time.
fn figure<const M: usize>(
    rows: &[Row],
    opts: &ReplayOptions,
    s: &Scenario,
    recorded_law: &str,
    stem: &Path,
) -> Result<(), SimError> {
    let (rec_color, mut rep_color) = (law_color(recorded_law), law_color(s.law.name()));
    if rec_color == rep_color {
        rep_color = plotters::style::RGBColor(214, 39, 40);
    }
    let series = |pick: &dyn Fn(&CommandMsg) -> f64, which: fn(&Row) -> &Option<CommandMsg>| {
        rows.iter()
            .filter_map(|r| which(r).as_ref().map(|c| (r.t, pick(c))))
            .collect::<Vec<_>>()
    };
    let rec_label = format!("recorded ({})", recorded_law.to_uppercase());
    let rep_label = format!("replayed ({})", describe(opts, s));
    let panel = |title: String, y: &str, pick: &dyn Fn(&CommandMsg) -> f64| Panel {
        title,
        y_label: y.to_owned(),
        lines: vec![
            Line {
                label: rec_label.clone(),
                color: rec_color,
                points: series(pick, |r| &r.recorded),
            },
            Line {
                label: rep_label.clone(),
                color: rep_color,
                points: series(pick, |r| &r.replayed),
            },
        ],
    };
    let mut panels: Vec<Panel> = (0..M)
        .map(|i| panel(format!("Torque τ_{i}"), &format!("tau_{i}"), &|c| c.tau[i]))
        .collect();
    panels.push(panel("Lyapunov value L".to_owned(), "L", &|c| c.lyapunov));
    let cols = if panels.len() > 4 { 2 } else { 1 };
    let height = 300 * panels.len().div_ceil(cols) as u32 + 100;
    let title = format!(
        "replay of {}: recorded vs what-if, same states",
        opts.dir.display()
    );
    render(stem, &title, &panels, cols, (1200, height))
}

/// The what-if, in words.
fn describe(opts: &ReplayOptions, s: &Scenario) -> String {
    let mut parts = vec![s.law.name().to_uppercase()];
    if let Some(p) = &opts.scenario {
        parts.push(format!("scenario {}", p.display()));
    }
    if opts.kp.is_some() {
        parts.push("K changed".to_owned());
    }
    if opts.kd.is_some() {
        parts.push("K_d changed".to_owned());
    }
    parts.join(", ")
}
