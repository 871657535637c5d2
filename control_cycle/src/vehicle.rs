//! A vehicle on the controller's side (docs/vehicles.md, "In the pair"): the law's wrench
//! less the known restoring wrench, allocated to the actuators within their bounds, with the
//! rate limit and the failures the controller is told of. The command carries the answer.

use allocation::{Commands, VehicleControl};
use controller::group::MatrixLieGroup;
use ipc_types::{CommandMsg, MAX_ACTUATORS, StateMsg};
use nalgebra::SVector;
use scenario::vehicle::VehicleSpec;

/// The controller's vehicle between cycles.
#[derive(Debug, Clone)]
pub struct ControllerVehicle<const M: usize> {
    control: VehicleControl<f64, M>,
    spec: VehicleSpec,
    count: usize,
}

impl<const M: usize> ControllerVehicle<M> {
    /// The scenario's vehicle (`Err`: its tables do not make an allocator on this group,
    /// which the scenario's load already refuses).
    pub fn new(spec: &VehicleSpec, period: f64) -> Result<Self, String> {
        Ok(ControllerVehicle {
            control: spec.control::<M>(period)?,
            count: spec.actuators.len(),
            spec: spec.clone(),
        })
    }

    /// The actuator count.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Allocates the law's wrench `tau` for state `msg` (attitude from its configuration,
    /// told failures from its `t_k`) and writes the vehicle's fields of `cmd`, the command
    /// the limit narrowed around included. Allocation-free.
    pub fn answer<G: MatrixLieGroup<N, M>, const N: usize>(
        &mut self,
        msg: &StateMsg,
        tau: &SVector<f64, M>,
        cmd: &mut CommandMsg,
    ) {
        self.control.set_period(msg.control_period);
        self.spec
            .tell_failures(&mut self.control, msg.t, msg.control_period);
        let r_hat = G::rotation(&msg.configuration::<N>());
        if let Some(p) = self.control.previous() {
            cmd.u_previous.copy_from_slice(p.as_slice());
        }
        let a = self.control.actuate(tau, &r_hat);
        let accounted = a.applied(&self.control.restoring(&r_hat));
        cmd.actuators = self.count as u32;
        cmd.alloc_status = u32::from(a.allocation.status.code());
        for i in 0..M.min(ipc_types::MAX_M) {
            cmd.demand[i] = a.demand[i];
            cmd.achieved[i] = a.allocation.achieved[i];
            cmd.accounted[i] = accounted[i];
        }
        cmd.u_cmd.copy_from_slice(a.allocation.u.as_slice());
    }

    /// Restores the rate limit's memory from a recorded command (replay): the command it
    /// narrowed around, when the controller had answered before.
    pub fn restore(&mut self, cmd: &CommandMsg) {
        let previous = (cmd.previous_seq != ipc_types::NO_PREVIOUS)
            .then(|| Commands::<f64>::from_fn(|j, _| cmd.u_previous[j.min(MAX_ACTUATORS - 1)]));
        self.control.set_previous(previous);
    }
}
