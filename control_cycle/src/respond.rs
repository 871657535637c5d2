//! One answer to one state: the law (and the disturbance-rejection terms) at the state's time, as a command. The cycle the process runs and `plant_sim replay` runs again.

use eqtrack_controller::group::BuiltinGroup;
use eqtrack_controller::{Controller, Rejection, RejectionConfig, Trajectory};
use failsafe::monitor::applied_as_sent;
use ipc_types::{CommandMsg, StateMsg};

/// One controller cycle without IPC: steps the reference up to the state's k (normally it is
/// there already), runs the law through the controller crate (finite-state check,
/// saturation) with the state's configuration and body velocity, and fills the command.
/// Allocation-free; generic over the scalar so the same cycle can be measured in f32, and
/// over the reference source. The state must have passed `ipc_types::check_state` (its
/// sequence number jumps by at most `MAX_SEQ_JUMP`, which bounds the catching up). The plain
/// law only: with disturbance-rejection terms, see [`Responder`].
pub fn respond<T, G, R, const N: usize, const M: usize>(
    controller: &Controller<T, G, N, M>,
    reference: &mut R,
    msg: &StateMsg,
) -> Result<CommandMsg, eqtrack_controller::Error>
where
    T: eqtrack_controller::Real,
    G: BuiltinGroup<N, M>,
    R: Trajectory<T, N, M>,
{
    let (q, v) = catch_up(reference, msg);
    let out = controller.compute(&q, &v, &reference.desired())?;
    let mut cmd = CommandMsg::new(link::wire::wire_group(G::KIND));
    write_law::<T, N, M>(&mut cmd, msg.seq, &out, controller.config().law);
    Ok(cmd)
}

/// Steps `reference` to the state's k and reads the state in the scalar `T`.
pub(crate) fn catch_up<T, R, const N: usize, const M: usize>(
    reference: &mut R,
    msg: &StateMsg,
) -> (nalgebra::SMatrix<T, N, N>, nalgebra::SVector<T, M>)
where
    T: eqtrack_controller::Real,
    R: Trajectory<T, N, M>,
{
    while reference.step_index() < msg.seq {
        reference.advance();
    }
    (
        msg.configuration::<N>().map(eqtrack_controller::real::<T>),
        msg.velocity::<M>().map(eqtrack_controller::real::<T>),
    )
}

/// A scalar as `f64` (NaN if it cannot be converted).
pub(crate) fn to_f64<T: eqtrack_controller::Real>(x: T) -> f64 {
    nalgebra::try_convert::<T, f64>(x).unwrap_or(f64::NAN)
}

/// Writes the law's output for state `seq` into `cmd`, naming the law that computed it.
pub(crate) fn write_law<T, const N: usize, const M: usize>(
    cmd: &mut CommandMsg,
    seq: u64,
    out: &eqtrack_controller::LawOutput<T, N, M>,
    law: eqtrack_controller::Law,
) where
    T: eqtrack_controller::Real,
{
    cmd.seq = seq;
    cmd.law = link::wire::law_code(law);
    cmd.set_torque(&out.torque.map(to_f64::<T>));
    cmd.lyapunov = to_f64(out.lyapunov.total);
    for i in 0..M.min(ipc_types::MAX_M) {
        cmd.observer[i] = to_f64(out.observer[i]);
        cmd.integral[i] = to_f64(out.integral[i]);
    }
}

/// The controller's cycle with its state between cycles: the law, the disturbance-rejection
/// terms (docs/maths.md, "Disturbance rejection") fed with the torque each state says the
/// plant applied, and the sequence number of the last state processed. The node and
/// `plant_sim replay` answer states through it, so replay repeats the node bit for bit.
#[derive(Debug, Clone)]
pub struct Responder<T: eqtrack_controller::Real, G, const N: usize, const M: usize> {
    pub(crate) controller: Controller<T, G, N, M>,
    pub(crate) rejection: Option<Rejection<T, M>>,
    pub(crate) previous: Option<u64>,
    /// The wrench the plant reports in the next state's `applied` if it applied the last
    /// answer: its `accounted` with a vehicle, its `tau` without (docs/failsafe.md, "Causes").
    pub(crate) sent: Option<[f64; ipc_types::MAX_M]>,
    pub(crate) vehicle: Option<crate::ControllerVehicle<M>>,
    pub(crate) supervisor: Option<crate::Supervisor<T, G, N, M>>,
}

impl<T, G, const N: usize, const M: usize> Responder<T, G, N, M>
where
    T: eqtrack_controller::Real,
    G: BuiltinGroup<N, M>,
{
    /// A responder with the terms of `rejection` (none: the plain law).
    pub fn new(
        controller: Controller<T, G, N, M>,
        rejection: RejectionConfig<T, M>,
    ) -> Result<Self, eqtrack_controller::Error> {
        let rejection = Rejection::of(rejection, controller.config().torque_limit.as_ref())?;
        Ok(Responder {
            controller,
            rejection,
            previous: None,
            sent: None,
            vehicle: None,
            supervisor: None,
        })
    }

    /// The responder under the failsafe manager `supervisor` (docs/failsafe.md): each answer
    /// steps it first, flies the engaged action's set-point in place of the reference, and
    /// carries its state word.
    pub fn with_supervisor(mut self, supervisor: crate::Supervisor<T, G, N, M>) -> Self {
        self.supervisor = Some(supervisor);
        self
    }

    /// The failsafe manager, if one runs.
    pub fn supervisor(&self) -> Option<&crate::Supervisor<T, G, N, M>> {
        self.supervisor.as_ref()
    }

    /// The responder of a vehicle: each answer allocates the law's wrench to its actuators.
    pub fn with_vehicle(mut self, vehicle: crate::ControllerVehicle<M>) -> Self {
        self.vehicle = Some(vehicle);
        self
    }

    /// Puts run-time gains in force (docs/live.md, "Tuning a running pair"): `K`, `K_d`
    /// and, for the terms the responder runs, the observer's `L` and the integral's `K_I`
    /// and `c`, all at once, checked as at start-up (an error leaves the responder as it
    /// was). The law, the model, the limit and the terms' state carry over. Allocation-free.
    pub fn retune(&mut self, gains: &ipc_types::Gains) -> Result<(), eqtrack_controller::Error> {
        let mut config = *self.controller.config();
        config.k = nalgebra::SMatrix::from_fn(|i, j| eqtrack_controller::real(gains.k[i * N + j]));
        config.kd =
            nalgebra::SMatrix::from_fn(|i, j| eqtrack_controller::real(gains.kd[i * M + j]));
        let axes = |xs: &[f64; ipc_types::MAX_M]| {
            nalgebra::SVector::<T, M>::from_fn(|i, _| eqtrack_controller::real(xs[i]))
        };
        let rejection = match &self.rejection {
            None => None,
            Some(r) => {
                let mut c = *r.config();
                if let Some(o) = &mut c.observer {
                    o.gain = axes(&gains.observer);
                }
                if let Some(i) = &mut c.integral {
                    i.ki = axes(&gains.ki);
                    i.c = axes(&gains.c);
                }
                Some(r.retuned(c)?)
            }
        };
        self.controller = Controller::new(config)?;
        self.rejection = rejection;
        Ok(())
    }

    /// Whether a failure detector runs (its state is in no command: replay follows it state
    /// by state).
    pub fn detects(&self) -> bool {
        self.vehicle
            .as_ref()
            .is_some_and(|v| v.detector().is_some())
    }

    /// Whether it keeps state between cycles that no command carries, which replay must follow
    /// state by state: the failure detector's, or the failsafe manager's.
    pub fn carries_state(&self) -> bool {
        self.detects() || self.supervisor.is_some()
    }

    /// Stops running the failure detector (replay, when it can no longer follow it); what
    /// it told the allocator stays
    /// ([`ControllerVehicle::lose_detector`](crate::ControllerVehicle::lose_detector)).
    pub fn lose_detector(&mut self) {
        if let Some(v) = &mut self.vehicle {
            v.lose_detector();
        }
    }

    /// Tells the allocator what recorded command `cmd` found, as the controller's detector
    /// told it (replay, once it no longer runs the detector;
    /// [`ControllerVehicle::follow`](crate::ControllerVehicle::follow)).
    pub fn follow(&mut self, cmd: &CommandMsg) {
        if let Some(v) = &mut self.vehicle {
            v.follow(cmd);
        }
        if let Some(s) = &mut self.supervisor {
            s.follow(cmd.failsafe);
        }
    }

    /// [`Responder::follow`], with the change of mode `cmd` records engaged at the earlier
    /// state `at`, whose reference time was `t` (replay, once it has found the state the
    /// controller engaged it at; [`crate::Supervisor::follow_engaged_at`]).
    pub fn follow_engaged_at(&mut self, cmd: &CommandMsg, at: &StateMsg, t: T) {
        if let Some(v) = &mut self.vehicle {
            v.follow(cmd);
        }
        if let Some(s) = &mut self.supervisor {
            let q = at.configuration::<N>().map(eqtrack_controller::real::<T>);
            let v = at.velocity::<M>().map(eqtrack_controller::real::<T>);
            s.follow_engaged_at(cmd.failsafe, (q, v, t));
        }
    }

    /// Whether recorded command `cmd` changes the failsafe mode flown (replay).
    pub fn changes_failsafe_mode(&self, cmd: &CommandMsg) -> bool {
        self.supervisor
            .as_ref()
            .is_some_and(|s| s.changes_mode(cmd.failsafe))
    }

    /// The controller.
    pub fn controller(&self) -> &Controller<T, G, N, M> {
        &self.controller
    }

    /// The disturbance-rejection terms' state, if any run.
    pub fn rejection(&self) -> Option<&Rejection<T, M>> {
        self.rejection.as_ref()
    }

    /// Answers state `msg` (see [`respond`]). The terms update only when the state follows
    /// the last one processed (`seq = previous + 1`); after a gap they re-anchor. The command
    /// carries the estimate, the integral's torque and the previous sequence number.
    pub fn respond<R: Trajectory<T, N, M>>(
        &mut self,
        reference: &mut R,
        msg: &StateMsg,
    ) -> Result<CommandMsg, eqtrack_controller::Error> {
        if let Some(vehicle) = &self.vehicle {
            vehicle.check_wheels(msg)?;
        }
        let (q, v) = catch_up(reference, msg);
        let follows = self
            .previous
            .is_some_and(|p| p.checked_add(1) == Some(msg.seq));
        let mut cmd = CommandMsg::new(link::wire::wire_group(G::KIND));
        if let Some(vehicle) = &mut self.vehicle {
            vehicle.observe::<G, N>(msg, follows, &mut cmd);
        }
        let desired = match &mut self.supervisor {
            None => reference.desired(),
            Some(sup) => {
                let flags = failsafe::monitor::Flags {
                    // a state the controller never saw (the link lost it), or an answer the
                    // plant did not apply (it came too late)
                    link: (self.previous.is_some() && !follows)
                        || (follows
                            && !applied_as_sent(
                                self.sent.as_ref().map(|s| &s[..M]),
                                &msg.applied[..M],
                            )),
                    estimator: msg.flags
                        & (ipc_types::flags::ESTIMATE_DEGRADED | ipc_types::flags::ESTIMATE_LOST)
                        != 0,
                    actuators: self.vehicle.as_mut().is_some_and(|v| v.lost() || v.short()),
                };
                let (nominal, t) = (reference.desired(), reference.time());
                cmd.failsafe = sup.tick((&q, &v), (&nominal, t), msg.control_period, flags);
                cmd.flags |= ipc_types::flags::SUPERVISED;
                sup.desired(&nominal, t)
            }
        };
        let before = self
            .rejection
            .as_ref()
            .map(|r| (*r.estimate(), *r.integral_state()));
        let out = match &mut self.rejection {
            None => self.controller.compute(&q, &v, &desired)?,
            Some(r) => {
                let applied = msg.applied_torque::<M>().map(eqtrack_controller::real::<T>);
                self.controller.compute_rejecting(
                    r,
                    &q,
                    &v,
                    &desired,
                    &applied,
                    eqtrack_controller::real(msg.control_period),
                    follows,
                )?
            }
        };
        write_law::<T, N, M>(&mut cmd, msg.seq, &out, self.controller.config().law);
        cmd.previous_seq = self.previous.unwrap_or(ipc_types::NO_PREVIOUS);
        if let Some(vehicle) = &mut self.vehicle {
            let sup = self.supervisor.as_ref();
            let disarmed = sup.is_some_and(crate::Supervisor::disarmed);
            // the failsafe's thrust-axis law, when `descend` flies it (docs/failsafe.md)
            let thrust = sup
                .and_then(|s| s.thrust_demand((&q, &v), &desired))
                .map(|d| d.map(to_f64::<T>));
            vehicle.allocate::<G, N>(
                msg,
                (&out.torque.map(to_f64::<T>), thrust.as_ref()),
                disarmed,
                &mut cmd,
            );
        }
        if let Some((estimate, z)) = before {
            for i in 0..M.min(ipc_types::MAX_M) {
                cmd.estimate_before[i] = to_f64(estimate[i]);
                cmd.z_before[i] = to_f64(z[i]);
            }
        }
        self.previous = Some(msg.seq);
        self.sent = Some(if self.vehicle.is_some() {
            cmd.accounted
        } else {
            cmd.tau
        });
        Ok(cmd)
    }

    /// Restores the state this responder had before it answered the recorded command `cmd`
    /// (replay): the terms from the command's `estimate_before` and `z_before`, their anchor
    /// from `previous` (the recorded state `cmd.previous_seq`; `None` if there is none or it
    /// is not in the record), the vehicle's rate limit from `u_previous`, and the previous
    /// sequence number. Without terms or vehicle it only sets the sequence number.
    pub fn restore(&mut self, cmd: &CommandMsg, previous: Option<&StateMsg>) {
        self.previous = (cmd.previous_seq != ipc_types::NO_PREVIOUS).then_some(cmd.previous_seq);
        if let Some(vehicle) = &mut self.vehicle {
            vehicle.restore(cmd);
        }
        if let Some(r) = &mut self.rejection {
            let from = |xs: &[f64; ipc_types::MAX_M]| {
                nalgebra::SVector::<T, M>::from_fn(|i, _| eqtrack_controller::real::<T>(xs[i]))
            };
            let anchor = previous.map(|p| {
                (
                    p.configuration::<N>().map(eqtrack_controller::real::<T>),
                    p.velocity::<M>().map(eqtrack_controller::real::<T>),
                )
            });
            self.controller.restore_rejection(
                r,
                &from(&cmd.estimate_before),
                &from(&cmd.z_before),
                anchor.as_ref().map(|(q, v)| (q, v)),
            );
        }
    }
}
