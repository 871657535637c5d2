//! A vehicle on the pair's plant side (docs/vehicles.md, "In the pair"): the controller's
//! command carries the actuator commands `u_cmd`; the plant drives its actuators with them
//! and integrates them with gravity, buoyancy, drag and the disturbances, exactly as the
//! in-process simulation does. In safe mode the plant allocates the damping wrench itself.

use crate::trajectory::VehicleRow;
use crate::vehicle::{VehicleReport, VehicleRun};
use crate::wheels::MAX_WHEELS;
use eqtrack_allocation::{Actuation, Allocation, Commands, Status};
use eqtrack_controller::group::BuiltinGroup;
use eqtrack_controller::integrator::RigidBody;
use ipc_types::CommandMsg;
use nalgebra::SVector;
use scenario::Scenario;

/// The plant's vehicle between cycles.
pub(super) struct PairVehicle<const M: usize> {
    run: VehicleRun<M>,
    /// The last actuator commands applied (held over a missed deadline).
    u_cmd: Commands<f64>,
    /// The wrench the law counts as applied over the period (the next state's `applied`).
    pub(super) accounted: SVector<f64, M>,
    /// The wrench the plant held over the last period, for the accelerometer (zero at k = 0).
    pub(super) held: SVector<f64, M>,
    /// The row's vehicle columns at `t_k`, and the actuators' wrench `B u(t_k)`.
    pub(super) row: Option<(VehicleRow, SVector<f64, M>)>,
    /// The controller's detector's alarms, as its last command says.
    alarms: u32,
}

impl<const M: usize> PairVehicle<M> {
    /// The scenario's vehicle, if it has one, its wheels spinning at their initial speeds
    /// relative to the body at its initial velocity `v`.
    pub(super) fn of(s: &Scenario, v: &SVector<f64, M>) -> Result<Option<Self>, crate::SimError> {
        Ok(VehicleRun::of(s)?
            .map(|mut run| {
                run.spin_wheels(s, v);
                run
            })
            .map(|run| PairVehicle {
                run,
                u_cmd: Commands::zeros(),
                accounted: SVector::zeros(),
                held: SVector::zeros(),
                row: None,
                alarms: 0,
            }))
    }

    /// The actuator count (what the plant's endpoint expects in every command).
    pub(super) fn count(&self) -> u32 {
        self.run.count() as u32
    }

    /// Tick `t_k`: the failures that start now.
    pub(super) fn failures_at(&mut self, t_k: f64) {
        self.run.failures_at(t_k);
    }

    /// Takes the detection a command received at tick `t_k` carries (applied or, after the
    /// deadline, held: the controller's allocator knew of it either way) into the summary.
    pub(super) fn heard(&mut self, c: &CommandMsg, t_k: f64) {
        if let Some(found) = detection_of(c) {
            self.run.found(t_k, &found);
        }
        self.alarms = c.alarms;
    }

    /// The wheels' speeds relative to the body at body velocity `v` (for the state), and how
    /// many there are.
    pub(super) fn wheel_speeds(&self, v: &SVector<f64, M>) -> ([f64; MAX_WHEELS], usize) {
        self.run.wheel_speeds(v)
    }

    /// Applies a fresh command at body velocity `v`: its `u_cmd` to the actuators and the
    /// wheels' motors (each within its range), and its columns to the row.
    pub(super) fn apply(&mut self, c: &CommandMsg, v: &SVector<f64, M>) {
        let mut a = Actuation {
            demand: SVector::zeros(),
            allocation: Allocation {
                u: Commands::from_fn(|j, _| c.u_cmd[j]),
                achieved: SVector::zeros(),
                status: Status::from_code(c.alloc_status).unwrap_or(Status::Stopped),
                iterations: 0,
            },
        };
        for i in 0..M {
            a.demand[i] = c.demand[i];
            a.allocation.achieved[i] = c.achieved[i];
            self.accounted[i] = c.accounted[i];
        }
        self.u_cmd = self.run.command_received(&a.allocation.u);
        self.run.command_wheels(&self.u_cmd, v);
        self.row_of(&a);
    }

    /// Holds the last command over a missed deadline (the wheels' motors limited anew at body
    /// velocity `v`).
    pub(super) fn hold(&mut self, v: &SVector<f64, M>) {
        let u = self.u_cmd;
        self.run.actuators.command(&u);
        self.run.command_wheels(&u, v);
        let out = self.run.produced();
        if let Some((row, wrench)) = &mut self.row {
            for (j, x) in row.u.iter_mut().enumerate() {
                *x = out[j];
            }
            // the wheels' speeds now and what their motors apply over the held period
            self.run.wheel_columns(row);
            *wrench = self.run.wrench_of(&out);
        }
    }

    /// Safe mode: the plant allocates `wrench` (the damping law) itself, compensating the
    /// restoring wrench at the body's true attitude.
    pub(super) fn safe<G: BuiltinGroup<N, M>, const N: usize>(
        &mut self,
        wrench: &SVector<f64, M>,
        body: &RigidBody<f64, G, N, M>,
    ) {
        let r = G::rotation(body.configuration());
        let v = body.velocity();
        // the rate limit narrows around what the actuators were last commanded
        self.run.control.set_previous(Some(self.u_cmd));
        let a = self.run.actuate(wrench, &r, &v, &v);
        self.accounted = self.run.applied(&a, &r);
        self.u_cmd = a.allocation.u;
        self.run.actuators.command(&a.allocation.u);
        self.run.command_wheels(&a.allocation.u, &v);
        self.row_of(&a);
    }

    fn row_of(&mut self, a: &Actuation<f64, M>) {
        let u = self.run.produced();
        self.row = Some((self.run.row(a, &u), self.run.wrench_of(&u)));
    }

    /// Integrates `[t_k, t_{k+1})` under the actuators, the environment and the scenario's
    /// disturbances of tick k, then takes the wrench held for the accelerometer at `t_{k+1}`.
    pub(super) fn advance<G: BuiltinGroup<N, M>, const N: usize>(
        &mut self,
        body: &mut RigidBody<f64, G, N, M>,
        s: &Scenario,
        k: u64,
    ) {
        let world = s.world_disturbance::<M>();
        self.run.step(
            body,
            (&s.disturbance_at::<M>(k), world.as_ref()),
            s.control_period,
            s.plant_substeps,
        );
        let r = G::rotation(body.configuration());
        self.held = self.run.wrench_of(&self.run.produced())
            + self.run.environment.wrench(&r, &body.velocity())
            + s.disturbance_wrench::<G, N, M>(k, &r);
    }

    /// `summary.json` → `vehicle` over the rows kept, `h` apart.
    pub(super) fn report(&self, rows: &[crate::trajectory::Row], h: f64) -> VehicleReport {
        self.run.report(rows, h, Some(self.alarms))
    }
}

/// The detection a command carries, if any (docs/wire.md; the statistic and the change point
/// are not on the wire: zero).
fn detection_of(c: &CommandMsg) -> Option<detection::Detection<f64>> {
    Some(detection::Detection {
        actuator: (c.detected as usize).checked_sub(1)?,
        kind: detection::Kind::from_code(c.detected_kind, c.detected_value)?,
        statistic: 0.0,
        since: 0,
        refined: c.detected_refined != 0,
    })
}
