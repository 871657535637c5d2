//! The failsafe manager in the in-process simulation (docs/failsafe.md): each tick, the
//! causes' flags from what the controller knows (the estimator's health, the actuators it can
//! still move, the tracking error of its estimate), the manager stepped, the reference told
//! the action, and every transition kept for `summary.json`.

use ::failsafe::setpoint::{Rates, Supervised, tracking_errors};
use ::failsafe::{Action, Inputs, Mode, State};
use controller::group::MatrixLieGroup;
use controller::reference::Trajectory;
use nalgebra::{SMatrix, SVector};
use scenario::Scenario;
use scenario::failsafe::FailsafeSpec;
use serde::Serialize;
use std::cmp::Ordering;

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
        match self.cause {
            Some(c) => format!("failsafe: t = {} s: {c} → {}", self.t, self.action),
            None => format!("failsafe: t = {} s: every cause cleared → nominal", self.t),
        }
    }
}

/// The manager's run: its configuration, state and transitions.
#[derive(Debug, Clone, PartialEq)]
pub struct Supervision {
    spec: FailsafeSpec,
    config: ::failsafe::Config,
    state: State,
    transitions: Vec<TransitionReport>,
    /// The tracking error that raised `tracking` first: (t, attitude rad, position m).
    runaway: Option<(f64, f64, f64)>,
    /// Per tick, the action flown ([`Supervision::code`]).
    codes: Vec<u8>,
    /// Whether the tracking error has been within its limits since the start or the last
    /// transition: only then does passing a limit raise `tracking`.
    armed: bool,
}

impl Supervision {
    /// Scenario `s`'s manager (`None`: no `[failsafe]`).
    pub fn of(s: &Scenario) -> Option<Self> {
        let spec = s.failsafe?;
        Some(Supervision {
            config: spec.config(s.control_period),
            spec,
            state: State::default(),
            transitions: Vec::new(),
            runaway: None,
            codes: Vec::new(),
            armed: false,
        })
    }

    /// Scenario `s`'s reference `inner` under supervision (nominal: `inner` bit for bit).
    pub fn supervise<G, R, const N: usize, const M: usize>(
        s: &Scenario,
        inner: R,
    ) -> SupervisedReference<G, R, N, M>
    where
        G: MatrixLieGroup<N, M>,
        R: Trajectory<f64, N, M>,
    {
        let (descend, ascend) = s
            .failsafe
            .map_or((0.0, 0.0), |f| (f.descend_rate, f.ascend_rate));
        Supervised::new(
            inner,
            SMatrix::<f64, M, M>::from_row_slice(&s.model_inertia),
            Rates { descend, ascend },
        )
    }

    /// One tick at `t`, before the law: the flags from the estimate `(q̂, v̂)` (the tracking
    /// error against what is flown: the reference, or the engaged action's set-point), `unhealthy` (the estimator's health is not `healthy`)
    /// and `lost` (the actuators no longer span every wrench); the manager stepped; the
    /// reference handed the estimate and, on a transition, the action.
    pub fn tick<G, R, const N: usize, const M: usize>(
        &mut self,
        t: f64,
        estimate: (&SMatrix<f64, N, N>, &SVector<f64, M>),
        unhealthy: bool,
        lost: bool,
        reference: &mut SupervisedReference<G, R, N, M>,
    ) where
        G: MatrixLieGroup<N, M>,
        R: Trajectory<f64, N, M>,
    {
        let (q_hat, v_hat) = estimate;
        reference.observe(q_hat, v_hat);
        // against what is flown: the reference, or the engaged action's set-point (which does
        // not run away while the reference goes on without the vehicle)
        let (angle, distance) = tracking_errors::<f64, G, N, M>(q_hat, &reference.desired().q);
        // past the limit, or not a number
        let beyond = |limit: Option<f64>, x: f64| {
            limit.is_some_and(|l| matches!(x.partial_cmp(&l), Some(Ordering::Greater) | None))
        };
        let within = !(beyond(self.spec.tracking_limit_attitude, angle)
            || beyond(self.spec.tracking_limit_position, distance));
        // a run that starts beyond a limit, or rejoins a reference beyond it after a failsafe,
        // is not a runaway until its error has once been within
        self.armed |= within;
        let tracking = self.armed && !within;
        if tracking && self.runaway.is_none() {
            self.runaway = Some((t, angle, distance));
        }
        let inputs = Inputs {
            link: false,
            estimator: unhealthy,
            actuators: lost,
            tracking,
        };
        let (next, transition) = ::failsafe::step(&self.config, &self.state, &inputs);
        self.state = next;
        self.codes.push(match next.mode() {
            Mode::Nominal => 0,
            Mode::Engaged { action, .. } => Action::ALL
                .iter()
                .position(|a| *a == action)
                .map_or(0, |i| i as u8 + 1),
        });
        if let Some(tr) = transition {
            let (cause, action) = match tr.to {
                Mode::Nominal => (None, None),
                Mode::Engaged { cause, action } => (Some(cause.name()), Some(action)),
            };
            reference.engage(action);
            self.armed = false;
            self.transitions.push(TransitionReport {
                t,
                cause,
                action: action.map_or("nominal", Action::name),
            });
        }
    }

    /// Whether the engaged action disarms (every actuator to its minimum).
    pub fn disarmed(&self) -> bool {
        matches!(
            self.state.mode(),
            Mode::Engaged {
                action: Action::Disarm,
                ..
            }
        )
    }

    /// The action flown at tick `k`, as `trajectory.csv`'s `failsafe` column gives it: 0
    /// nominal, then 1 `warn`, 2 `hold`, 3 `damp`, 4 `descend`, 5 `surface`, 6 `disarm`
    /// (`None`: no such tick).
    pub fn code(&self, k: usize) -> Option<u8> {
        self.codes.get(k).copied()
    }

    /// The transitions so far.
    pub fn transitions(&self) -> &[TransitionReport] {
        &self.transitions
    }

    /// When `tracking` was raised (it latches, so the run ends in its action, or under a more
    /// severe one): the time the tracking error first passed its limit, and the errors then
    /// (rad, m). Such a run exits non-zero.
    pub fn runaway(&self) -> Option<(f64, f64, f64)> {
        self.runaway
            .filter(|_| self.state.raised(::failsafe::Cause::Tracking))
    }
}
