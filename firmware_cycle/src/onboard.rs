//! The estimator and the vehicle a firmware carries: their settings in `f32` as postcard
//! fields, and what they become on the board (the `eqtrack-estimator` crate's filter, the
//! `eqtrack-allocation` crate's vehicle control).

use crate::ConfigError;
use eqtrack_allocation::{
    Actuator, Allocator, Commands, Geometry, MAX_WHEELS, Priority, Restoring, VehicleControl,
};
use eqtrack_estimator::{FilterKind, MAX_DIRECTIONS, Settings};
use heapless::Vec;
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use serde::{Deserialize, Serialize};

/// The estimator's settings (docs/maths.md, "Estimators"), as [`eqtrack_estimator::Settings`] in
/// `f32`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Estimator {
    /// The equivariant filter (else the complementary filter).
    pub eqf: bool,
    /// Complementary: `(k_P, k_I)`; EqF: `(σ_ω, σ_b)`.
    pub gains: [f32; 2],
    /// Complementary: the weights; EqF: the directions' noises (on SE(3) the
    /// accelerometer's last).
    pub values: Vec<f32, 5>,
    /// EqF: the attitude's and the bias's standard deviations at the start.
    pub initial_std: [f32; 2],
    /// The direction sensors' world directions.
    pub world: Vec<[f32; 3], 4>,
    /// The attitude to start from, row-major (`None`: TRIAD).
    pub initial_attitude: Option<[f32; 9]>,
    /// Clamp of each bias component.
    pub bias_limit: Option<f32>,
    /// SE(3): the accelerometer's gate.
    pub accel_gate: Option<f32>,
    /// SE(3): the accelerometer's noise.
    pub accel_noise: f32,
    /// SE(3): the position fixes' noise.
    pub position_noise: f32,
    /// The innovation gate and the health monitor (`[estimator] gate = true`; `None`: off).
    pub gate: Option<Gate>,
}

/// The innovation gate's thresholds and the health monitor's window
/// (docs/estimators.md, "The innovation gate and health"), as
/// [`eqtrack_estimator::health::GateConfig`] in `f32`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Gate {
    /// The χ²₂ threshold of a direction sample's NIS.
    pub direction: f32,
    /// The χ²₃ threshold of a position fix's NIS.
    pub position: f32,
    /// The noise each direction source is tested against (the complementary filter's test;
    /// 0 in the slots no sensor uses).
    pub noise: Vec<f32, 5>,
    /// The window (ticks, ≥ 1).
    pub window: u32,
    /// Rejections within a window that degrade a source (1 to 8).
    pub rejections: u32,
    /// The directions' χ² band: `(samples per block, bound)`; 0 samples: none.
    pub direction_band: (u32, f32),
    /// The fixes' χ² band.
    pub position_band: (u32, f32),
}

impl Gate {
    /// The host's configuration cast to `f32`.
    pub fn of(c: &eqtrack_estimator::health::GateConfig<f64>) -> Gate {
        Gate {
            direction: c.direction as f32,
            position: c.position as f32,
            noise: c.noise.iter().map(|x| *x as f32).collect(),
            window: c.window,
            rejections: c.rejections,
            direction_band: (c.direction_band.samples, c.direction_band.upper as f32),
            position_band: (c.position_band.samples, c.position_band.upper as f32),
        }
    }

    /// The gate's configuration on the board: refused unless every threshold is a finite
    /// number > 0 (a band's bound too, where it has samples), every noise a finite number
    /// ≥ 0 (0 in the slots no sensor uses), the window at least 1 and the rejections 1 to 8.
    pub fn config(&self) -> Result<eqtrack_estimator::health::GateConfig<f32>, ConfigError> {
        let positive = |x: f32| x.is_finite() && x > 0.0;
        let band =
            |(samples, upper): (u32, f32)| eqtrack_estimator::health::Band { samples, upper };
        let bands_ok = [self.direction_band, self.position_band]
            .iter()
            .all(|(n, upper)| *n == 0 || positive(*upper));
        if !(positive(self.direction)
            && positive(self.position)
            && self.noise.iter().all(|x| x.is_finite() && *x >= 0.0)
            && self.window >= 1
            && (1..=eqtrack_estimator::health::MAX_REJECTIONS as u32).contains(&self.rejections)
            && bands_ok)
        {
            return Err(ConfigError::Gate);
        }
        let mut noise = [0.0f32; MAX_DIRECTIONS + 1];
        for (o, x) in noise.iter_mut().zip(&self.noise) {
            *o = *x;
        }
        Ok(eqtrack_estimator::health::GateConfig {
            direction: self.direction,
            position: self.position,
            noise,
            window: self.window,
            rejections: self.rejections,
            direction_band: band(self.direction_band),
            position_band: band(self.position_band),
        })
    }
}

impl Estimator {
    /// The settings cast to `f32`.
    pub fn of(s: &Settings<f64>) -> Estimator {
        let cast = |xs: &[f64]| xs.iter().map(|x| *x as f32).collect::<Vec<f32, 5>>();
        let (eqf, gains, values, initial_std) = match &s.kind {
            FilterKind::Complementary {
                kp,
                ki,
                weights,
                count,
            } => (
                false,
                [*kp as f32, *ki as f32],
                cast(&weights[..*count]),
                [0.0; 2],
            ),
            FilterKind::Eqf {
                gyro_noise,
                bias_walk,
                direction_noise,
                count,
                initial_attitude_std,
                initial_bias_std,
            } => (
                true,
                [*gyro_noise as f32, *bias_walk as f32],
                cast(&direction_noise[..*count]),
                [*initial_attitude_std as f32, *initial_bias_std as f32],
            ),
        };
        Estimator {
            eqf,
            gains,
            values,
            initial_std,
            world: s.world[..s.directions]
                .iter()
                .map(|w| [w[0] as f32, w[1] as f32, w[2] as f32])
                .collect(),
            initial_attitude: s
                .initial_attitude
                .map(|r| core::array::from_fn(|i| r[(i / 3, i % 3)] as f32)),
            bias_limit: s.bias_limit.map(|x| x as f32),
            accel_gate: s.accel_gate.map(|x| x as f32),
            accel_noise: s.accel_noise as f32,
            position_noise: s.position_noise as f32,
            gate: None,
        }
    }

    /// The settings the firmware builds its filter from.
    pub fn settings(&self) -> Settings<f32> {
        let mut five = [0.0f32; MAX_DIRECTIONS + 1];
        for (o, x) in five.iter_mut().zip(&self.values) {
            *o = *x;
        }
        let count = self.values.len();
        let [a, b] = self.gains;
        let mut world = [Vector3::zeros(); MAX_DIRECTIONS];
        for (o, w) in world.iter_mut().zip(&self.world) {
            *o = Vector3::from(*w);
        }
        Settings {
            kind: if self.eqf {
                FilterKind::Eqf {
                    gyro_noise: a,
                    bias_walk: b,
                    direction_noise: five,
                    count,
                    initial_attitude_std: self.initial_std[0],
                    initial_bias_std: self.initial_std[1],
                }
            } else {
                FilterKind::Complementary {
                    kp: a,
                    ki: b,
                    weights: five,
                    count,
                }
            },
            world,
            directions: self.world.len(),
            initial_attitude: self.initial_attitude.map(|r| Matrix3::from_row_slice(&r)),
            bias_limit: self.bias_limit,
            accel_gate: self.accel_gate,
            accel_noise: self.accel_noise,
            position_noise: self.position_noise,
        }
    }
}

/// One actuator (docs/maths.md, "Control allocation").
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Thruster {
    /// Where it acts (body, m).
    pub position: [f32; 3],
    /// Its thrust's direction.
    pub axis: [f32; 3],
    /// The reaction torque per unit thrust about its axis (m).
    pub torque_per_thrust: f32,
    /// The least command.
    pub min: f32,
    /// The largest command.
    pub max: f32,
}

/// A reaction wheel as the controller sees it (docs/maths.md, "Reaction wheels"): its
/// motor is the allocator's column after the thrusters; friction and power are the plant's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Wheel {
    /// The spin axis in body axes (made unit on the board).
    pub axis: [f32; 3],
    /// The spin inertia `J_s` (kg·m²).
    pub inertia: f32,
    /// The motor's largest torque (N·m).
    pub max_torque: f32,
    /// The top speed relative to the body (rad/s).
    pub max_speed: f32,
}

impl Wheel {
    /// The wheel as the allocation takes it, its axis made unit (the gyroscopic torque, the
    /// null space and the detector's balance take `g` as a unit vector): refused (naming the
    /// key) unless the axis is finite with a finite, non-zero length, and the inertia and the
    /// limits finite and positive.
    fn allocation(&self) -> Result<eqtrack_allocation::Wheel<f32>, ConfigError> {
        let finite = |x: f32| x.is_finite();
        let axis = Vector3::from(self.axis);
        let length = axis.norm();
        if !(self.axis.iter().all(|x| finite(*x)) && finite(length) && length > 0.0) {
            return Err(ConfigError::Vehicle("wheel.axis"));
        }
        if !(finite(self.inertia) && self.inertia > 0.0) {
            return Err(ConfigError::Vehicle("wheel.inertia"));
        }
        if !(finite(self.max_torque) && self.max_torque > 0.0) {
            return Err(ConfigError::Vehicle("wheel.max_torque"));
        }
        if !(finite(self.max_speed) && self.max_speed > 0.0) {
            return Err(ConfigError::Vehicle("wheel.max_speed"));
        }
        let unit = axis / length;
        Ok(eqtrack_allocation::Wheel {
            axis: [unit[0], unit[1], unit[2]],
            inertia: self.inertia,
            max_torque: self.max_torque,
            max_speed: self.max_speed,
        })
    }
}

/// Momentum management (docs/maths.md, "Momentum management"), as
/// [`eqtrack_allocation::Momentum`] in `f32`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Momentum {
    /// The null space's gain `k_n` (1/s; 0: off).
    pub null_gain: f32,
    /// Each wheel's bias speed (rad/s; one per wheel).
    pub bias: Vec<f32, MAX_WHEELS>,
    /// `|h_w|` (N·m·s) above which the thrusters dump it.
    pub dump_threshold: f32,
    /// The dump's gain `k_d` (1/s; 0: off).
    pub dump_gain: f32,
}

impl Momentum {
    /// The host's settings cast to `f32`, for `wheels` wheels.
    pub fn of(m: &eqtrack_allocation::Momentum<f64>, wheels: usize) -> Momentum {
        Momentum {
            null_gain: m.null_gain as f32,
            bias: m.bias[..wheels.min(MAX_WHEELS)]
                .iter()
                .map(|x| *x as f32)
                .collect(),
            dump_threshold: m.dump_threshold as f32,
            dump_gain: m.dump_gain as f32,
        }
    }

    /// The settings on the board, for `wheels` wheels: refused (naming the key) unless the
    /// gains and the threshold are finite and not negative and there is a finite bias per
    /// wheel.
    fn allocation(&self, wheels: usize) -> Result<eqtrack_allocation::Momentum<f32>, ConfigError> {
        let at_least_0 = |x: f32| x.is_finite() && x >= 0.0;
        if !at_least_0(self.null_gain) {
            return Err(ConfigError::Vehicle("momentum.null_gain"));
        }
        if !at_least_0(self.dump_threshold) {
            return Err(ConfigError::Vehicle("momentum.dump_threshold"));
        }
        if !at_least_0(self.dump_gain) {
            return Err(ConfigError::Vehicle("momentum.dump_gain"));
        }
        if self.bias.len() != wheels || !self.bias.iter().all(|x| x.is_finite()) {
            return Err(ConfigError::Vehicle("momentum.bias"));
        }
        let mut bias = [0.0; MAX_WHEELS];
        bias[..wheels].copy_from_slice(&self.bias);
        Ok(eqtrack_allocation::Momentum {
            null_gain: self.null_gain,
            bias,
            dump_threshold: self.dump_threshold,
            dump_gain: self.dump_gain,
        })
    }
}

/// A failure the controller is told of: from the first `t_k ≥ t − h/2` the actuator is
/// stuck at `value` and the allocator redistributes over the rest.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Failure {
    /// The actuator.
    pub actuator: u8,
    /// When (s).
    pub t: f64,
    /// The stuck value.
    pub value: f32,
}

/// The vehicle's allocation (docs/maths.md, "Control allocation").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Vehicle {
    /// The actuators.
    pub actuators: Vec<Thruster, 12>,
    /// The allocation weights (empty: all 1).
    pub weights: Vec<f32, 12>,
    /// The preferred command (empty: 0).
    pub preferred: Vec<f32, 12>,
    /// Torque before force (else the whole wrench at once).
    pub torque_first: bool,
    /// The weight `m g` (N) the controller compensates.
    pub weight: f32,
    /// The buoyancy (N).
    pub buoyancy: f32,
    /// Where buoyancy acts (body, m).
    pub centre: [f32; 3],
    /// The actuators' rate limit (per second; 0: none).
    pub rate_limit: f32,
    /// The failures the controller is told of, in time order.
    pub failures: Vec<Failure, 12>,
    /// The allocation's budget of active-set iterations per cycle (1 or more).
    pub budget: u32,
    /// The reaction wheels, the allocator's columns after the thrusters (docs/maths.md,
    /// "Reaction wheels"): the states carry their speeds.
    pub wheels: Vec<Wheel, MAX_WHEELS>,
    /// The wheels' momentum management, where the scenario has `[vehicle.momentum]`.
    pub momentum: Option<Momentum>,
}

impl Vehicle {
    /// The actuators and wheels together: the allocator's columns, `u_cmd`'s entries.
    pub fn count(&self) -> usize {
        self.actuators.len() + self.wheels.len()
    }

    /// The vehicle's control on a group of dimension `K`, over periods of `period`: its
    /// thrusters, then its wheels (refused naming the key: a bad wheel or momentum setting,
    /// actuators that do not span the wrench space or number more than 12).
    pub fn control<const K: usize>(
        &self,
        period: f32,
    ) -> Result<VehicleControl<f32, K>, ConfigError> {
        let actuators: Vec<Actuator<f32>, 12> = self
            .actuators
            .iter()
            .map(|a| Actuator {
                position: a.position,
                axis: a.axis,
                torque_per_thrust: a.torque_per_thrust,
                min: a.min,
                max: a.max,
            })
            .collect();
        let mut wheels: Vec<eqtrack_allocation::Wheel<f32>, MAX_WHEELS> = Vec::new();
        for w in &self.wheels {
            // at most MAX_WHEELS by the type
            let _ = wheels.push(w.allocation()?);
        }
        let momentum = match &self.momentum {
            None => None,
            Some(m) => Some(m.allocation(wheels.len())?),
        };
        let geometry = Geometry::with_wheels(&actuators, &wheels)
            .map_err(|_| ConfigError::Vehicle("actuators"))?;
        let allocator = Allocator::new(
            geometry,
            &self.weights,
            &self.preferred,
            if self.torque_first {
                Priority::Torque
            } else {
                Priority::None
            },
        )
        .map_err(|_| ConfigError::Vehicle("allocation"))?;
        if self.budget == 0 {
            return Err(ConfigError::Vehicle("budget"));
        }
        let allocator = allocator.with_budget(self.budget);
        let restoring = Restoring {
            weight: self.weight,
            buoyancy: self.buoyancy,
            centre: Vector3::from(self.centre),
        };
        let control = VehicleControl::new(allocator, restoring, self.rate_limit, period)
            .with_wheels(&wheels, actuators.len());
        Ok(match momentum {
            Some(m) => control.with_momentum(m),
            None => control,
        })
    }
}

/// The failure detector's settings (docs/maths.md, "Failure detection"), as
/// [`detection::Config`] in `f32`: the host works out the periods and the thresholds from
/// the scenario's `[fault_detection]` in `f64`, and the firmware takes them as they are. The
/// model inertia and the control period are the configuration's own.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detector {
    /// Control periods averaged into each kept entry.
    pub decimation: u32,
    /// Entries per window.
    pub window: u32,
    /// The χ²₁ threshold of the best hypothesis.
    pub threshold: f32,
    /// The χ²_{K−1} gate on what the best hypothesis leaves unexplained.
    pub isolation: f32,
    /// The model's relative error, squared.
    pub relative: f32,
    /// The least lead of the best hypothesis over the runner-up.
    pub margin: f32,
    /// Entries the same actuator must pass every gate before it is named.
    pub confirm: u32,
    /// Entries of the start in which the detector neither learns nor tests.
    pub warmup: u32,
    /// Entries of nominal flight the spread is learned over before the first test.
    pub calibration: u32,
    /// The weight of each new entry in the spread's running estimate.
    pub memory: f32,
    /// The least spread per axis (m entries).
    pub floor: Vec<f32, 6>,
    /// The least shortfall resolved per actuator (one per actuator).
    pub resolution: Vec<f32, 12>,
    /// Fossen's linear damping, diagonal (m entries).
    pub damping_linear: Vec<f32, 6>,
    /// Fossen's quadratic damping, diagonal (m entries).
    pub damping_quadratic: Vec<f32, 6>,
    /// The actuators' lag (s; 0: none).
    pub time_constant: f32,
}

impl Detector {
    /// The host's settings `c` (`f64`) cast to `f32`, for `count` actuators.
    pub fn of<const K: usize>(c: &detection::Config<f64, K>, count: usize) -> Detector {
        let whole = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
        Detector {
            decimation: whole(c.decimation),
            window: whole(c.window),
            threshold: c.threshold as f32,
            isolation: c.isolation as f32,
            relative: c.relative as f32,
            margin: c.margin as f32,
            confirm: whole(c.confirm),
            warmup: whole(c.warmup),
            calibration: whole(c.calibration),
            memory: c.memory as f32,
            floor: f32s(c.floor.as_slice()),
            resolution: f32s(&c.resolution.as_slice()[..count.min(12)]),
            damping_linear: f32s(c.damping_linear.as_slice()),
            damping_quadratic: f32s(c.damping_quadratic.as_slice()),
            time_constant: c.time_constant as f32,
        }
    }

    /// The detector's settings on a group of wrench dimension `K`, with the model inertia
    /// and the control period (checked by [`detection::Detector::new`]).
    pub fn config<const K: usize>(
        &self,
        inertia: SMatrix<f32, K, K>,
        period: f32,
    ) -> Result<detection::Config<f32, K>, ConfigError> {
        let axes = |what: &'static str, xs: &Vec<f32, 6>| {
            if xs.len() == K {
                Ok(SVector::<f32, K>::from_row_slice(xs))
            } else {
                Err(ConfigError::Shape(what, xs.len()))
            }
        };
        let count = |n: u32| usize::try_from(n).unwrap_or(usize::MAX);
        // an actuator past the given ones keeps a unit resolution (it has no column)
        let resolution =
            Commands::<f32>::from_fn(|j, _| self.resolution.get(j).copied().unwrap_or(1.0));
        Ok(detection::Config {
            decimation: count(self.decimation),
            window: count(self.window),
            threshold: self.threshold,
            isolation: self.isolation,
            relative: self.relative,
            margin: self.margin,
            confirm: count(self.confirm),
            warmup: count(self.warmup),
            calibration: count(self.calibration),
            memory: self.memory,
            floor: axes("detector.floor", &self.floor)?,
            resolution,
            inertia,
            damping_linear: axes("detector.damping_linear", &self.damping_linear)?,
            damping_quadratic: axes("detector.damping_quadratic", &self.damping_quadratic)?,
            period,
            time_constant: self.time_constant,
        })
    }
}

/// `xs` cast to `f32`, as many as fit.
fn f32s<const C: usize>(xs: &[f64]) -> Vec<f32, C> {
    xs.iter().take(C).map(|x| *x as f32).collect()
}
