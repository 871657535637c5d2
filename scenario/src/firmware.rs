//! The processor-in-the-loop firmware's configuration from a scenario (docs/pil.md): the
//! controller's settings cast to `f32` once, here, so that the firmware and the in-process
//! `f32` simulation start from the same numbers.

use crate::vehicle::VehicleSpec;
use crate::{Scenario, ScenarioError};
use eqtrack_controller::{ErrorFrame, Frame, GroupKind, Law};
use firmware_cycle::{
    Axis, Config, Detector, Estimator, Failure, Integral, Momentum, Observer, Series, Term,
    Thruster, Vehicle, Wheel,
};
use heapless::Vec as HVec;

fn f32s<const C: usize>(xs: &[f64]) -> HVec<f32, C> {
    // the scenario's vectors are the group's sizes (at most C entries), validated at load
    xs.iter().take(C).map(|x| *x as f32).collect()
}

impl Scenario {
    /// The configuration the processor-in-the-loop firmware is built with, and the
    /// in-process `f32` controller runs: the law, `I`, `K`, `K_d`, the torque limit, the
    /// reference's start and feedforward, the rejection terms, and the identity the
    /// handshake compares (group, control period, fingerprint, name), and where the scenario
    /// has them the estimator (its filter on the sensors' samples), the vehicle (its
    /// allocation, with the failures the controller is told of) and the failure detector
    /// (`[fault_detection]`). Refused, naming the key,
    /// for what the firmware does not run: a waypoint or set-point reference.
    pub fn firmware_config(&self) -> Result<Config, ScenarioError> {
        self.firmware_refusals()?;
        let origin = self.local_origin();
        let q0_rows = self.local_start();
        let name: String = self.name.chars().take(32).collect();
        let mut scenario = heapless::String::<32>::new();
        for c in name.chars() {
            if scenario.push(c).is_err() {
                break;
            }
        }
        Ok(Config {
            identity: eqtrack_serial_wire::Hello {
                group: match self.group {
                    GroupKind::So3 => 1,
                    GroupKind::Se3 => 2,
                    GroupKind::Se2 => 3,
                },
                period: self.control_period,
                fingerprint: self.fingerprint(),
                scenario,
            },
            law: Law::ALL.iter().position(|l| *l == self.law).unwrap_or(0) as u8,
            error_frame: ErrorFrame::ALL
                .iter()
                .position(|f| *f == self.error_frame)
                .unwrap_or(0) as u8,
            origin,
            inertia: f32s(&self.model_inertia),
            k: f32s(&self.kp),
            kd: f32s(&self.kd),
            torque_limit: self.torque_limit.as_deref().map(f32s),
            reference: Series {
                q0: f32s(&q0_rows),
                v0: f32s(&self.reference.velocity),
                axes: self
                    .feedforward
                    .iter()
                    .map(|a| Axis {
                        offset: a.offset as f32,
                        terms: a
                            .terms
                            .iter()
                            .take(8)
                            .map(|t| Term {
                                amplitude: t.amplitude as f32,
                                frequency: t.frequency as f32,
                                phase: t.phase as f32,
                            })
                            .collect(),
                    })
                    .collect(),
                substeps: self.reference_substeps as u32,
            },
            observer: self.rejection.observer.as_ref().map(|o| Observer {
                gain: f32s(&o.gain),
                limit: o.limit.as_deref().map(f32s),
                world: o.frame == Frame::World,
            }),
            integral: self.rejection.integral.as_ref().map(|i| Integral {
                ki: f32s(&i.ki),
                c: f32s(&i.c),
                limit: i.limit.as_deref().map(f32s),
                anti_windup: i.anti_windup,
            }),
            estimator: self.firmware_estimator()?,
            vehicle: self.vehicle.as_ref().map(firmware_vehicle),
            detector: self.firmware_detector()?,
            failsafe: self.firmware_failsafe(),
        })
    }

    /// The estimator's settings in `f32`, with the innovation gate's where `gate = true`.
    fn firmware_estimator(&self) -> Result<Option<Estimator>, ScenarioError> {
        Ok(self.filter_settings()?.as_ref().map(|f| Estimator {
            gate: self.gate_config().as_ref().map(firmware_cycle::Gate::of),
            ..Estimator::of(f)
        }))
    }

    /// The failsafe manager's settings in `f32` (`[failsafe]`), with the actuators' time
    /// constant the thrust-axis law turns its torques ahead by.
    fn firmware_failsafe(&self) -> Option<firmware_cycle::Failsafe> {
        self.failsafe.map(|f| firmware_cycle::Failsafe {
            actions: f.actions.map(|a| a.map_or(0, |a| a.code() as u8)),
            clear_ticks: f.config(self.control_period).clear_ticks,
            descend_rate: f.descend_rate as f32,
            ascend_rate: f.ascend_rate as f32,
            limit_attitude: f.tracking_limit_attitude.map(|x| x as f32),
            limit_position: f.tracking_limit_position.map(|x| x as f32),
            lag: self
                .vehicle
                .as_ref()
                .map_or(0.0, |v| v.actuator_time_constant as f32),
            actuators_residual: f.actuators_residual.map(|x| x as f32),
        })
    }

    /// The failure detector's settings in `f32` (`[fault_detection]`, which needs a vehicle),
    /// as the pair's controller makes them at the scenario's period; `None` without the table.
    fn firmware_detector(&self) -> Result<Option<Detector>, ScenarioError> {
        if self.fault_detection.is_none() {
            return Ok(None);
        }
        let count = self.vehicle.as_ref().map_or(0, VehicleSpec::count);
        let settings = match self.group {
            GroupKind::So3 | GroupKind::Se2 => {
                self.detector_config::<3>().map(|c| Detector::of(&c, count))
            }
            GroupKind::Se3 => self.detector_config::<6>().map(|c| Detector::of(&c, count)),
        };
        settings.map(Some).ok_or_else(|| ScenarioError::Invalid {
            origin: format!("scenario `{}`", self.name),
            key: "fault_detection".to_owned(),
            message: "the vehicle does not make a detector on this group".to_owned(),
        })
    }

    /// What the firmware does not run, refused naming the key: a told loss of effectiveness,
    /// a waypoint or set-point reference, the tilt priority, and more than 12 told failures (what its
    /// configuration holds).
    fn firmware_refusals(&self) -> Result<(), ScenarioError> {
        let refuse = |key: &str, what: &str| ScenarioError::Invalid {
            origin: format!("scenario `{}`", self.name),
            key: key.to_owned(),
            message: format!("the processor-in-the-loop controller does not run {what} yet"),
        };
        if self.group == GroupKind::Se2 {
            return Err(refuse("group", "a planar (se2) scenario"));
        }
        let told_weaker = self.vehicle.as_ref().and_then(|v| {
            v.failures.iter().find(|f| {
                f.reconfigure && matches!(f.kind, crate::vehicle::FailureKind::Effectiveness { .. })
            })
        });
        if let Some(f) = told_weaker {
            return Err(refuse(
                "vehicle.failure.reconfigure",
                &format!(
                    "a loss of effectiveness told to the allocator (actuator {}; set `reconfigure = false`)",
                    f.actuator
                ),
            ));
        }
        if self.path.is_some() {
            return Err(refuse("reference", "a waypoint or set-point reference"));
        }
        if self
            .vehicle
            .as_ref()
            .is_some_and(|v| v.priority == eqtrack_allocation::Priority::Tilt)
        {
            return Err(refuse("allocation.priority", "the tilt priority"));
        }
        let told = self
            .vehicle
            .as_ref()
            .map_or(0, |v| v.failures.iter().filter(|f| f.reconfigure).count());
        if told > 12 {
            return Err(refuse(
                "vehicle.failure",
                &format!("more than 12 failures told to the allocator ({told})"),
            ));
        }
        Ok(())
    }

    /// `Q_d(0)` relative to the local origin, row-major: the position difference formed in
    /// `f64`, before the configuration is cast.
    fn local_start(&self) -> Vec<f64> {
        let (n, _) = self.group.dims();
        let mut local = self.reference.clone();
        for (x, o) in local.position.iter_mut().zip(self.local_origin()) {
            *x -= o;
        }
        let q0: Vec<f64> = match self.group {
            GroupKind::So3 | GroupKind::Se2 => {
                Scenario::configuration::<3>(&local).as_slice().to_vec()
            }
            GroupKind::Se3 => Scenario::configuration::<4>(&local).as_slice().to_vec(),
        };
        // nalgebra stores column-major: the config is row-major
        (0..n * n).map(|i| q0[(i % n) * n + i / n]).collect()
    }

    /// The local origin of the `f32` controller (m, world axes): the reference's start
    /// position on SE(3) when the law in force does not depend on where the world origin is
    /// (EqT with its error at the reference or re-centred), else zero (SO(3), the papers'
    /// world-frame form, the comparison laws). The firmware's configuration and the serial
    /// frames hold positions relative to it
    /// (docs/invariance.md, "In f32, far from the origin").
    pub fn local_origin(&self) -> [f64; 3] {
        let invariant = self.law == Law::Eqt
            && self.error_frame != ErrorFrame::World
            && self.group == GroupKind::Se3;
        if invariant {
            self.reference.position
        } else {
            [0.0; 3]
        }
    }
}

/// The vehicle's allocation settings in `f32`, with the failures the controller is told of.
fn firmware_vehicle(v: &VehicleSpec) -> Vehicle {
    Vehicle {
        actuators: v
            .actuators
            .iter()
            .take(12)
            .map(|a| Thruster {
                position: a.position.map(|x| x as f32),
                axis: a.axis.map(|x| x as f32),
                torque_per_thrust: a.torque_per_thrust as f32,
                min: a.min as f32,
                max: a.max as f32,
            })
            .collect(),
        weights: v.weights.iter().take(12).map(|x| *x as f32).collect(),
        preferred: v.preferred.iter().take(12).map(|x| *x as f32).collect(),
        torque_first: v.priority == eqtrack_allocation::Priority::Torque,
        weight: (v.mass * v.gravity) as f32,
        buoyancy: v.buoyancy as f32,
        centre: v.buoyancy_centre.map(|x| x as f32),
        rate_limit: v.actuator_rate_limit as f32,
        budget: v.budget,
        wheels: v
            .wheels
            .iter()
            .take(eqtrack_allocation::MAX_WHEELS)
            .map(|w| Wheel {
                axis: w.axis.map(|x| x as f32),
                inertia: w.inertia as f32,
                max_torque: w.max_torque as f32,
                max_speed: w.max_speed as f32,
            })
            .collect(),
        momentum: v.momentum.as_ref().map(|m| Momentum::of(m, v.wheels.len())),
        failures: v
            .failures
            .iter()
            .filter(|f| f.reconfigure)
            .take(12)
            .map(|f| Failure {
                actuator: f.actuator as u8,
                t: f.t,
                value: f.value as f32,
            })
            .collect(),
    }
}
