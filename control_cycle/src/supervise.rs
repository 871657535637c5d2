//! The failsafe manager on the controller's side (docs/failsafe.md, "In the pair and on the firmware"): the same
//! monitor and set-points the in-process simulation runs, fed from what the controller is sent
//! (the estimate, the estimator's health the state's flags carry, a gap in the states) and
//! what it knows (the actuators its allocator may still move).

use eqtrack_controller::Real;
use eqtrack_controller::group::BuiltinGroup;
use eqtrack_controller::law::Desired;
use failsafe::monitor::{Flags, Limits, Monitor};
use failsafe::setpoint::{Rates, Setpoint};
use failsafe::thrust_axis::ThrustAxis;
use nalgebra::SMatrix;
use scenario::Scenario;
use scenario::failsafe::FailsafeSpec;

/// Where a change of mode was engaged: the estimate `(q, v)` and the reference's time.
type Engagement<T, const N: usize, const M: usize> = (SMatrix<T, N, N>, nalgebra::SVector<T, M>, T);

/// The manager and what it flies, between cycles.
#[derive(Debug, Clone)]
pub struct Supervisor<T: Real, G, const N: usize, const M: usize> {
    spec: FailsafeSpec,
    /// Made at the first state: the hysteresis counts the plant's periods.
    monitor: Option<Monitor<T>>,
    setpoint: Setpoint<T, G, N, M>,
    /// The state word after the last tick.
    word: u32,
    /// Replay, once it can no longer follow the manager state by state: the recorded word of
    /// the state being answered, flown instead of the manager's own.
    recorded: Option<u32>,
    /// Replay, from then on: the manager is not stepped again, and a state without a
    /// recorded word flies the last one.
    following: bool,
    /// Replay: the estimate `(q, v)` and the reference's time of the state a recorded change
    /// of mode was engaged at, when it was not the state answered.
    engaged_at: Option<Engagement<T, N, M>>,
    /// The thrust-axis law `descend` flies once a direction of control is lost (SE(3) with
    /// gravity).
    thrust: Option<ThrustAxis<T>>,
}

impl<T: Real, G: BuiltinGroup<N, M>, const N: usize, const M: usize> Supervisor<T, G, N, M> {
    /// Scenario `s`'s manager (`None`: no `[failsafe]`).
    pub fn of(s: &Scenario) -> Option<Self> {
        let spec = s.failsafe?;
        let inertia = SMatrix::<f64, M, M>::from_row_slice(&s.model_inertia);
        Some(Supervisor {
            spec,
            monitor: None,
            setpoint: Setpoint::new(
                SMatrix::identity(),
                inertia.map(eqtrack_controller::real::<T>),
                Rates {
                    descend: eqtrack_controller::real(spec.descend_rate),
                    ascend: eqtrack_controller::real(spec.ascend_rate),
                },
            ),
            word: 0,
            recorded: None,
            following: false,
            engaged_at: None,
            thrust: s.thrust_axis().map(|t| t.cast::<T>()),
        })
    }

    /// The thrust-axis law's demand at the estimate `(q, v)` flying `desired`, when the
    /// engaged action flies it (docs/failsafe.md, "The thrust-axis law"); `None`: the law's
    /// wrench is allocated.
    pub(crate) fn thrust_demand(
        &self,
        (q, v): (&SMatrix<T, N, N>, &nalgebra::SVector<T, M>),
        desired: &Desired<T, N, M>,
    ) -> Option<nalgebra::SVector<T, M>> {
        self.thrust
            .as_ref()?
            .demand_when(self.word, (q, v), (&desired.q, &desired.v))
    }

    /// Flies the recorded `word` at the next tick instead of stepping the manager (replay,
    /// once it can no longer follow the manager's state, which no command carries, state by
    /// state): the set-point engaged when the recorded mode changes, at the estimate of the
    /// state answered, as the controller engaged it.
    pub fn follow(&mut self, word: u32) {
        self.recorded = Some(word);
        self.following = true;
    }

    /// [`Supervisor::follow`], with the change of mode `word` records engaged at an earlier
    /// state than the one answered: at its estimate `(q, v)` and the reference's time `t`
    /// there (replay, once it has found which state the controller engaged it at).
    pub fn follow_engaged_at(&mut self, word: u32, engaged: Engagement<T, N, M>) {
        self.follow(word);
        self.engaged_at = Some(engaged);
    }

    /// Whether recorded `word` changes the mode flown (a transition the controller made).
    pub fn changes_mode(&self, word: u32) -> bool {
        let mode = |w: u32| failsafe::State::read_word(w).map(|(m, _)| m);
        mode(word) != mode(self.word)
    }

    /// One tick before the law, at the reference's time `t` and control period `period`: the
    /// manager stepped on the estimate and `flags`, the new action engaged on a transition.
    /// Returns the manager's state word (the command's `failsafe` field).
    pub(crate) fn tick(
        &mut self,
        estimate: (&SMatrix<T, N, N>, &nalgebra::SVector<T, M>),
        (reference, t): (&Desired<T, N, M>, T),
        period: f64,
        flags: Flags,
    ) -> u32 {
        if self.following {
            let word = self.recorded.take().unwrap_or(self.word);
            // an engagement found for this word, and for no later one
            let engaged_at = self.engaged_at.take();
            if self.changes_mode(word) {
                let action = failsafe::State::read_word(word).and_then(|(m, _)| m.action());
                match engaged_at {
                    Some((q0, v0, t0)) => {
                        self.setpoint.observe(&q0, &v0);
                        self.setpoint.engage(action, t0);
                    }
                    None => {
                        self.setpoint.observe(estimate.0, estimate.1);
                        self.setpoint.engage(action, t);
                    }
                }
            }
            self.setpoint.observe(estimate.0, estimate.1);
            self.word = word;
            return word;
        }
        let spec = &self.spec;
        let monitor = self.monitor.get_or_insert_with(|| {
            let limit = |l: Option<f64>| l.map(eqtrack_controller::real::<T>);
            Monitor::new(
                spec.config(period),
                Limits {
                    attitude: limit(spec.tracking_limit_attitude),
                    position: limit(spec.tracking_limit_position),
                },
            )
        });
        self.setpoint
            .supervise(monitor, estimate, (reference, t), flags);
        self.word = monitor.state().word();
        self.word
    }

    /// The desired state flown at `t` in place of the reference's `reference`.
    pub(crate) fn desired(&self, reference: &Desired<T, N, M>, t: T) -> Desired<T, N, M> {
        self.setpoint.desired(reference, t)
    }

    /// Whether the engaged action disarms.
    pub fn disarmed(&self) -> bool {
        self.word & 0xf == failsafe::Action::Disarm.code()
    }

    /// The manager's state, once a state was answered.
    pub fn monitor(&self) -> Option<&Monitor<T>> {
        self.monitor.as_ref()
    }
}
