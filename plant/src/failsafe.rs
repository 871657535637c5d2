//! The failsafe manager as a plant sees it (docs/failsafe.md). In the in-process simulation
//! it runs the manager: each tick the causes' flags from what the controller knows (the
//! estimator's health, the actuators it can still move, the tracking error of its estimate),
//! the manager stepped and the reference told the action. In the pair it follows the state
//! word each command carries. Either way every transition is kept for `summary.json`.

use ::failsafe::monitor::{Flags, Limits, Monitor};
use ::failsafe::setpoint::{Rates, Supervised};
use ::failsafe::thrust_axis::ThrustAxis;
use ::failsafe::{Action, Cause, State};
use eqtrack_controller::group::BuiltinGroup;
use eqtrack_controller::reference::Trajectory;
use nalgebra::{SMatrix, SVector};
use scenario::Scenario;
use scenario::failsafe::FailsafeSpec;
use serde::Serialize;

/// A reference under the failsafe manager in the simulation (f64).
pub type SupervisedReference<G, R, const N: usize, const M: usize> = Supervised<f64, G, R, N, M>;

/// One transition in `summary.json` → `failsafe`.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct TransitionReport {
    /// When (s).
    pub t: f64,
    /// The cause engaged (`null`: back to nominal).
    pub cause: Option<&'static str>,
    /// Its action, or `nominal`.
    pub action: &'static str,
}

impl TransitionReport {
    /// The line `plant_sim sim` prints for it.
    pub fn line(&self) -> String {
        self.to_string()
    }
}

impl std::fmt::Display for TransitionReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.cause {
            Some(c) => write!(f, "failsafe: t = {} s: {c} → {}", self.t, self.action),
            None => write!(
                f,
                "failsafe: t = {} s: every cause cleared → nominal",
                self.t
            ),
        }
    }
}

/// The manager's run as a plant sees it: in the in-process simulation it runs the manager
/// ([`Supervision::tick`]); in the pair it follows the state word each command carries
/// ([`Supervision::follow`]). Either way it keeps every transition, the action of each row and
/// when `tracking` was raised.
#[derive(Debug, Clone, PartialEq)]
pub struct Supervision {
    /// The manager, when this process runs it (the simulation).
    monitor: Option<Monitor<f64>>,
    /// The manager's state word after the last tick ([`::failsafe::State::word`]).
    word: u32,
    transitions: Vec<TransitionReport>,
    /// When `tracking` was first raised (s).
    tracking_at: Option<f64>,
    /// Per row, the action flown ([`Supervision::code`]).
    codes: Vec<u8>,
    /// The thrust-axis law `descend` flies once a direction of control is lost (SE(3) with
    /// gravity; the simulation).
    thrust: Option<ThrustAxis<f64>>,
}

impl Supervision {
    /// Scenario `s`'s manager, run in this process (`None`: no `[failsafe]`).
    pub fn of(s: &Scenario) -> Option<Self> {
        let spec = s.failsafe?;
        let mut sup = Self::with(Some(Monitor::new(
            spec.config(s.control_period),
            limits(&spec),
        )));
        sup.thrust = s.thrust_axis();
        Some(sup)
    }

    /// The thrust-axis law's demand at the estimate `(q̂, v̂)` flying what `reference` now
    /// flies, when the engaged action flies the law: `descend` with the actuators' cause
    /// raised (docs/failsafe.md, "The thrust-axis law"). `None`: the law's wrench is
    /// allocated.
    pub fn thrust_demand<G, R, const N: usize, const M: usize>(
        &self,
        (q, v): (&SMatrix<f64, N, N>, &SVector<f64, M>),
        reference: &SupervisedReference<G, R, N, M>,
    ) -> Option<SVector<f64, M>>
    where
        G: BuiltinGroup<N, M>,
        R: Trajectory<f64, N, M>,
    {
        let law = self.thrust.as_ref()?;
        if !ThrustAxis::<f64>::flies(self.word) {
            return None;
        }
        // (the reference's desired state is formed only when the law is flown)
        let desired = reference.desired();
        law.demand((q, v), (&desired.q, &desired.v))
    }

    /// A record of the manager the controller runs (the pair's plant; `None`: no
    /// `[failsafe]`), with room for `rows` rows (so that the plant's loop does not allocate
    /// for them).
    pub fn following(s: &Scenario, rows: usize) -> Option<Self> {
        s.failsafe.map(|_| {
            let mut sup = Self::with(None);
            sup.codes.reserve(rows);
            sup
        })
    }

    fn with(monitor: Option<Monitor<f64>>) -> Self {
        Supervision {
            monitor,
            word: 0,
            transitions: Vec::new(),
            tracking_at: None,
            codes: Vec::new(),
            thrust: None,
        }
    }

    /// Scenario `s`'s reference `inner` under supervision (nominal: `inner` bit for bit).
    pub fn supervise<G, R, const N: usize, const M: usize>(
        s: &Scenario,
        inner: R,
    ) -> SupervisedReference<G, R, N, M>
    where
        G: BuiltinGroup<N, M>,
        R: Trajectory<f64, N, M>,
    {
        Supervised::new(
            inner,
            SMatrix::<f64, M, M>::from_row_slice(&s.model_inertia),
            rates(s),
        )
    }

    /// One tick at `t`, before the law (the simulation): the manager stepped on the estimate
    /// `(q̂, v̂)` and the flags (`Setpoint::supervise`), the reference told the action, and
    /// the tick recorded with its row.
    pub fn tick<G, R, const N: usize, const M: usize>(
        &mut self,
        t: f64,
        estimate: (&SMatrix<f64, N, N>, &SVector<f64, M>),
        flags: Flags,
        reference: &mut SupervisedReference<G, R, N, M>,
    ) where
        G: BuiltinGroup<N, M>,
        R: Trajectory<f64, N, M>,
    {
        if let Some(monitor) = &mut self.monitor {
            reference.supervise(monitor, estimate, flags);
            let word = monitor.state().word();
            self.follow(t, word);
            self.row();
        }
    }

    /// The manager's state `word` after the tick at `t` (a command's `failsafe` field in the
    /// pair): a transition is kept when the mode changed. A word that does not read keeps the
    /// last mode (the plant's checks refuse such a command before).
    pub fn follow(&mut self, t: f64, word: u32) {
        let Some((mode, raised)) = State::read_word(word) else {
            return;
        };
        let before = State::read_word(self.word).map(|(m, _)| m);
        if before != Some(mode) {
            self.transitions.push(TransitionReport {
                t,
                cause: mode.cause().map(Cause::name),
                action: mode.action().map_or("nominal", Action::name),
            });
        }
        if raised[3] && self.tracking_at.is_none() {
            self.tracking_at = Some(t);
        }
        self.word = word;
    }

    /// The engaged action (`None`: nominal).
    pub fn action(&self) -> Option<Action> {
        State::read_word(self.word).and_then(|(m, _)| m.action())
    }

    /// Records the action flown for the next row.
    pub fn row(&mut self) {
        self.codes.push((self.word & 0xf) as u8);
    }

    /// Whether the engaged action disarms (every actuator to its minimum).
    pub fn disarmed(&self) -> bool {
        self.word & 0xf == Action::Disarm.code()
    }

    /// The action flown at row `k`, as `trajectory.csv`'s `failsafe` column gives it: 0
    /// nominal, then 1 `warn`, 2 `hold`, 3 `damp`, 4 `descend`, 5 `surface`, 6 `disarm`
    /// (`None`: no such row).
    pub fn code(&self, k: usize) -> Option<u8> {
        self.codes.get(k).copied()
    }

    /// The transitions so far.
    pub fn transitions(&self) -> &[TransitionReport] {
        &self.transitions
    }

    /// When `tracking` was raised (it latches, so the run ends in its action, or under a more
    /// severe one): the time the tracking error first passed its limit and, when this process
    /// ran the manager, the errors then (rad, m). Such a run exits non-zero.
    pub fn runaway(&self) -> Option<(f64, Option<(f64, f64)>)> {
        let raised = State::read_word(self.word).is_some_and(|(_, r)| r[3]);
        let t = self.tracking_at.filter(|_| raised)?;
        let errors = self
            .monitor
            .as_ref()
            .and_then(Monitor::runaway)
            .map(|(_, a, d)| (a, d));
        Some((t, errors))
    }
}

/// `[failsafe]`'s tracking limits.
pub fn limits(spec: &FailsafeSpec) -> Limits<f64> {
    Limits {
        attitude: spec.tracking_limit_attitude,
        position: spec.tracking_limit_position,
    }
}

/// `[failsafe]`'s rates (zero without the table).
pub fn rates(s: &Scenario) -> Rates<f64> {
    let (descend, ascend) = s
        .failsafe
        .map_or((0.0, 0.0), |f| (f.descend_rate, f.ascend_rate));
    Rates { descend, ascend }
}
