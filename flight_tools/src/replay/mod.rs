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

mod output;
mod run;

use eqtrack_controller::Law;
use eqtrack_controller::group::{BuiltinGroup, OnGroup};
use ipc_types::{CommandMsg, flags};
use link::wire::group_code;
use plant::SimError;
use recorder::{LOG_FILE, LogReader, PlanEntry, read_plans};
use run::replay_group;
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
    /// With a failure detector or a failsafe manager: the cycle from which replay could no
    /// longer follow their state, which no command carries: a state whose command was not
    /// recorded and which the controller may or may not have seen, or the first of the
    /// records the recorder dropped (`None`: followed to the end). From the next recorded
    /// command on, the allocator is told what the recorded commands found, the set-point flies
    /// the recorded failsafe word, and neither the detection fields nor the word are
    /// compared.
    pub detector_lost_at: Option<u64>,
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
    // a log written before `controller.error_frame` existed flew the papers' world frame,
    // and its stored scenario has no key: the fingerprint, which covers the key only when it
    // is not "world", tells the two apart
    if opts.scenario.is_none() && s.fingerprint() != h.fingerprint {
        let world = Scenario {
            error_frame: eqtrack_controller::ErrorFrame::World,
            ..s.clone()
        };
        if world.fingerprint() == h.fingerprint {
            s = world;
        }
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
    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
        replay_group::<G, N, M>(self.opts, self.log, self.s, self.plans)
    }
}
