//! `[vehicle]` and `[allocation]`: the body's actuators, gravity, buoyancy, added mass and
//! drag, and how the law's wrench is shared out among the actuators
//! (docs/maths.md, "Control allocation" and "Vehicle physics"; docs/scenario.md lists every
//! key).
//!
//! ```toml
//! [vehicle]
//! gravity = 9.81                  # m/s², world −z (default 0)
//! buoyancy = 0.0                  # N, world +z (default 0)
//! buoyancy_centre = [0.0, 0.0, 0.0]
//! added_mass = [[...m×m...]]      # optional, body frame, symmetric
//! damping_linear = [m values]     # optional, (ω, v) order
//! damping_quadratic = [m values]  # optional
//! actuator_time_constant = 0.0    # s
//! actuator_rate_limit = 0.0       # N/s, 0 = none
//! [[vehicle.actuator]]            # one table per actuator, 1..12
//! position = [x, y, z]
//! axis = [ax, ay, az]
//! torque_per_thrust = 0.0
//! min = 0.0
//! max = 8.0
//! [[vehicle.failure]]             # optional
//! actuator = 3                    # 0-based
//! t = 10.0
//! kind = "stuck"                  # or "dead" (no output), "effectiveness" (output × factor)
//! value = 0.0                     # stuck: N, within the actuator's range
//! factor = 0.5                    # effectiveness: in (0, 1)
//! reconfigure = true
//! [allocation]                    # optional
//! weights = [...]
//! preferred = [...]
//! priority = "torque"             # or "tilt" or "none"
//! budget = 36                     # active-set iterations per cycle, 1..=1000 (default 36)
//! ```

use crate::{Scenario, ScenarioError, Validator};
use eqtrack_allocation::{
    Actuator, Allocator, DEFAULT_BUDGET, Geometry, GeometryError, Priority, Restoring,
    VehicleControl,
};

/// The largest `[allocation] budget` accepted.
const MAX_BUDGET: i64 = 1000;
use crate::wheels::WheelSpec;
use nalgebra::{SMatrix, Vector3};
use serde::Deserialize;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawVehicle {
    gravity: Option<f64>,
    buoyancy: Option<f64>,
    buoyancy_centre: Option<Vec<f64>>,
    added_mass: Option<Vec<Vec<f64>>>,
    damping_linear: Option<Vec<f64>>,
    damping_quadratic: Option<Vec<f64>>,
    actuator_time_constant: Option<f64>,
    actuator_rate_limit: Option<f64>,
    #[serde(default)]
    actuator: Vec<RawActuator>,
    failure: Option<Vec<RawFailure>>,
    wheel: Option<Vec<crate::wheels::RawWheel>>,
    momentum: Option<crate::wheels::RawMomentum>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawActuator {
    position: Vec<f64>,
    axis: Vec<f64>,
    torque_per_thrust: Option<f64>,
    min: f64,
    max: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawFailure {
    actuator: i64,
    t: f64,
    kind: Option<String>,
    value: Option<f64>,
    factor: Option<f64>,
    reconfigure: Option<bool>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawAllocation {
    weights: Option<Vec<f64>>,
    preferred: Option<Vec<f64>>,
    priority: Option<String>,
    budget: Option<i64>,
}

/// Each command's range: the actuators', then the wheels' motors' (the wheels follow the
/// actuators, so a failure may name one).
fn command_ranges(actuators: &[Actuator<f64>], wheels: &[WheelSpec]) -> Vec<(f64, f64)> {
    (actuators.iter().map(|a| (a.min, a.max)))
        .chain(wheels.iter().map(|w| (-w.max_torque, w.max_torque)))
        .collect()
}

/// The first key of a vehicle or an allocation that a planar (SE(2)) scenario cannot take:
/// what needs a third dimension (gravity, buoyancy, reaction wheels and their momentum, a
/// thruster's reaction torque about its own axis, the tilt priority). `None`: all planar.
pub(crate) fn planar_refusal(
    vehicle: Option<&RawVehicle>,
    allocation: Option<&RawAllocation>,
) -> Option<String> {
    if let Some(v) = vehicle {
        let named = [
            ("vehicle.gravity", v.gravity.is_some()),
            ("vehicle.buoyancy", v.buoyancy.is_some()),
            ("vehicle.buoyancy_centre", v.buoyancy_centre.is_some()),
            ("vehicle.wheel", v.wheel.is_some()),
            ("vehicle.momentum", v.momentum.is_some()),
        ];
        if let Some((key, _)) = named.iter().find(|(_, given)| *given) {
            return Some((*key).to_owned());
        }
        if let Some(i) =
            (v.actuator.iter()).position(|a| a.torque_per_thrust.is_some_and(|c| c != 0.0))
        {
            return Some(format!("vehicle.actuator[{i}].torque_per_thrust"));
        }
    }
    allocation
        .filter(|a| a.priority.as_deref() == Some("tilt"))
        .map(|_| "allocation.priority".to_owned())
}

/// How an actuator fails (`[[vehicle.failure]] kind`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FailureKind {
    /// `"stuck"` (the default): its output is held at the failure's `value`.
    Stuck,
    /// `"dead"`: no output at all, whatever its range (the failure's `value` is 0).
    Dead,
    /// `"effectiveness"`: its output is its lagged command multiplied by `factor`, in (0, 1).
    Effectiveness {
        /// The factor.
        factor: f64,
    },
}

impl FailureKind {
    /// The scenario's name of the kind.
    pub fn name(&self) -> &'static str {
        match self {
            FailureKind::Stuck => "stuck",
            FailureKind::Dead => "dead",
            FailureKind::Effectiveness { .. } => "effectiveness",
        }
    }
}

/// `[[vehicle.failure]]`: an actuator that fails at `t`, stuck, dead or less effective.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FailureSpec {
    /// The actuator (0-based).
    pub actuator: usize,
    /// When (s): from the first tick `t_k ≥ t − h/2`.
    pub t: f64,
    /// How it fails.
    pub kind: FailureKind,
    /// The output it is held at (N): the stuck value, 0 when dead; not used for a loss of
    /// effectiveness.
    pub value: f64,
    /// Whether the allocator is told (and redistributes over the rest).
    pub reconfigure: bool,
}

impl FailureSpec {
    /// Whether the failure has started at tick `t_k` of period `h` (from the first
    /// `t_k ≥ t − h/2`).
    pub fn active(&self, t_k: f64, h: f64) -> bool {
        t_k >= self.t - h / 2.0
    }
}

/// `[vehicle]` with its actuators and failures, and `[allocation]`.
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleSpec {
    /// `g` (m/s²), along world −z.
    pub gravity: f64,
    /// The mass `m` of the rigid body (SE(3): its inertia's force block; 0 on SO(3)).
    pub mass: f64,
    /// `B` (N), along world +z.
    pub buoyancy: f64,
    /// Where buoyancy acts (body axes, m).
    pub buoyancy_centre: [f64; 3],
    /// The added mass (m×m, row-major, symmetric), if any.
    pub added_mass: Option<Vec<f64>>,
    /// `D_l` (m entries).
    pub damping_linear: Vec<f64>,
    /// `D_q` (m entries).
    pub damping_quadratic: Vec<f64>,
    /// The actuators' lag (s; 0: none).
    pub actuator_time_constant: f64,
    /// The actuators' rate limit (N/s; 0: none).
    pub actuator_rate_limit: f64,
    /// The actuators.
    pub actuators: Vec<Actuator<f64>>,
    /// The reaction wheels (`[[vehicle.wheel]]`), after the actuators in `u_cmd`.
    pub wheels: Vec<WheelSpec>,
    /// Their momentum management (`[vehicle.momentum]`), if any.
    pub momentum: Option<eqtrack_allocation::Momentum<f64>>,
    /// The failures, in time order.
    pub failures: Vec<FailureSpec>,
    /// `[allocation] weights` (empty: all 1).
    pub weights: Vec<f64>,
    /// `[allocation] preferred` (empty: 0).
    pub preferred: Vec<f64>,
    /// `[allocation] priority`.
    pub priority: Priority,
    /// `[allocation] budget`: active-set iterations per allocation (docs/vehicles.md,
    /// "Bounded time").
    pub budget: u32,
    /// A planar vehicle (an SE(2) scenario): its actuators' columns are `(τ_z, f_x, f_y)`
    /// ([`Geometry::planar`]).
    pub planar: bool,
}

impl VehicleSpec {
    /// Gravity and buoyancy (docs/maths.md, "Vehicle physics").
    pub fn restoring(&self) -> Restoring<f64> {
        Restoring {
            weight: self.mass * self.gravity,
            buoyancy: self.buoyancy,
            centre: Vector3::from(self.buoyancy_centre),
        }
    }

    /// The actuators' geometry on a group of dimension `K` (checked at load).
    pub fn geometry<const K: usize>(&self) -> Result<Geometry<f64, K>, String> {
        if self.planar {
            Geometry::planar(&self.actuators)
        } else {
            Geometry::with_wheels(&self.actuators, &self.wheels_allocated())
        }
        .map_err(|e| format!("vehicle.actuator: {e}"))
    }

    /// The wheels as the allocation sees them.
    pub fn wheels_allocated(&self) -> Vec<eqtrack_allocation::Wheel<f64>> {
        self.wheels.iter().map(WheelSpec::allocation).collect()
    }

    /// The actuators and wheels together: the allocator's columns, `u_cmd`'s entries.
    pub fn count(&self) -> usize {
        self.actuators.len() + self.wheels.len()
    }

    /// The allocator (docs/maths.md, "Control allocation"; checked at load).
    pub fn allocator<const K: usize>(&self) -> Result<Allocator<f64, K>, String> {
        Allocator::new(
            self.geometry()?,
            &self.weights,
            &self.preferred,
            self.priority,
        )
        .map(|a| a.with_budget(self.budget))
        .map_err(|e| format!("allocation: {e}"))
    }

    /// The controller's side of the vehicle over periods of `h`: the allocator, the
    /// restoring model it compensates, the rate limit.
    pub fn control<const K: usize>(&self, h: f64) -> Result<VehicleControl<f64, K>, String> {
        Ok(VehicleControl::new(
            self.allocator()?,
            self.restoring(),
            self.actuator_rate_limit,
            h,
        )
        .with_wheels(&self.wheels_allocated(), self.actuators.len()))
        .map(|c| match self.momentum {
            Some(m) => c.with_momentum(m),
            None => c,
        })
    }

    /// Tells `control` of every failure it is to be told of (`reconfigure = true`) that has
    /// started at tick `t_k` of period `h` and is not marked in `told` (one flag per
    /// failure, in the table's order; set here): a stuck or dead actuator is held at its
    /// value, one that lost effectiveness has its column scaled by its factor. Each is told
    /// once, as the simulation tells it, so that what the failure detector finds later of
    /// the same actuator stands. A controller that starts afresh (a restart, replay) starts
    /// with no flags set and is told every failure already under way on its first tick.
    pub fn tell_failures<const K: usize>(
        &self,
        control: &mut VehicleControl<f64, K>,
        t_k: f64,
        h: f64,
        told: &mut [bool],
    ) {
        for (f, told) in self.failures.iter().zip(told.iter_mut()) {
            if f.reconfigure && !*told && f.active(t_k, h) {
                *told = true;
                match f.kind {
                    FailureKind::Effectiveness { factor } => control.weaken(f.actuator, factor),
                    FailureKind::Stuck | FailureKind::Dead => control.fail(f.actuator, f.value),
                }
            }
        }
    }
}

impl Validator<'_> {
    /// `[vehicle]` and `[allocation]`, checked against the group and the plant's inertia.
    pub(crate) fn vehicle(
        &self,
        raw: Option<&RawVehicle>,
        allocation: Option<&RawAllocation>,
        group: eqtrack_controller::GroupKind,
        plant_inertia: &[f64],
        h: f64,
    ) -> Result<Option<VehicleSpec>, ScenarioError> {
        let Some(raw) = raw else {
            return match allocation {
                Some(_) => Err(self.err("allocation", "needs a [vehicle] with its actuators")),
                None => Ok(None),
            };
        };
        let (_, m) = group.dims();
        let gravity = self.optional_non_negative("vehicle.gravity", raw.gravity)?;
        let buoyancy = self.optional_non_negative("vehicle.buoyancy", raw.buoyancy)?;
        let centre = match &raw.buoyancy_centre {
            None => [0.0; 3],
            Some(c) => {
                let c = self.vector("vehicle.buoyancy_centre", c, 3, "x, y, z in body axes")?;
                [c[0], c[1], c[2]]
            }
        };
        let mass = self.mass(group, gravity, plant_inertia)?;
        if !(mass * gravity).is_finite() {
            return Err(self.err(
                "vehicle.gravity",
                format!("the weight m·g = {mass} × {gravity} is not a finite number"),
            ));
        }
        if centre.iter().any(|c| !(c * buoyancy).is_finite()) {
            return Err(self.err(
                "vehicle.buoyancy_centre",
                format!("its torque r_B × B ({buoyancy} N at {centre:?}) is not a finite number"),
            ));
        }
        let added_mass = raw
            .added_mass
            .as_ref()
            .map(|a| self.added_mass(a, m, plant_inertia))
            .transpose()?;
        let damping = |key: &str, v: &Option<Vec<f64>>| -> Result<Vec<f64>, ScenarioError> {
            let v = match v {
                None => return Ok(vec![0.0; m]),
                Some(v) => self.vector(key, v, m, "one per velocity component, (ω, v) order")?,
            };
            match v.iter().position(|x| *x < 0.0) {
                Some(i) => Err(self.err(key, format!("entry {i} is negative ({})", v[i]))),
                None => Ok(v),
            }
        };
        let total = crate::validate::plus(plant_inertia, added_mass.as_deref());
        let wheels = self.wheels(raw.wheel.as_deref().unwrap_or(&[]), &total, m)?;
        let allocated: Vec<eqtrack_allocation::Wheel<f64>> =
            wheels.iter().map(WheelSpec::allocation).collect();
        let actuators = self.actuators(&raw.actuator, &allocated, group)?;
        let momentum = self.momentum(raw.momentum.as_ref(), &wheels, actuators.len(), (h, m))?;
        let ranges = command_ranges(&actuators, &wheels);
        let failures = self.failures(raw.failure.as_deref().unwrap_or(&[]), &ranges)?;
        let (weights, preferred, priority, budget) =
            self.allocation(allocation, actuators.len() + wheels.len())?;
        let spec = VehicleSpec {
            gravity,
            mass,
            buoyancy,
            buoyancy_centre: centre,
            added_mass,
            damping_linear: damping("vehicle.damping_linear", &raw.damping_linear)?,
            damping_quadratic: damping("vehicle.damping_quadratic", &raw.damping_quadratic)?,
            actuator_time_constant: self.optional_non_negative(
                "vehicle.actuator_time_constant",
                raw.actuator_time_constant,
            )?,
            actuator_rate_limit: self
                .optional_non_negative("vehicle.actuator_rate_limit", raw.actuator_rate_limit)?,
            actuators,
            wheels,
            momentum,
            failures,
            weights,
            preferred,
            priority,
            budget,
            planar: group == eqtrack_controller::GroupKind::Se2,
        };
        Ok(Some(spec))
    }

    /// An optional key that must be finite and ≥ 0 (default 0).
    fn optional_non_negative(&self, key: &str, x: Option<f64>) -> Result<f64, ScenarioError> {
        x.map_or(Ok(0.0), |x| self.non_negative(key, x))
    }

    /// The rigid body's mass: SE(3)'s force block `m·1₃` with no rotation–translation
    /// coupling, required when gravity acts; gravity is refused on SO(3).
    fn mass(
        &self,
        group: eqtrack_controller::GroupKind,
        gravity: f64,
        inertia: &[f64],
    ) -> Result<f64, ScenarioError> {
        if group == eqtrack_controller::GroupKind::Se2 {
            // gravity is refused on se2 before (vehicle.gravity): a plane has no up
            return Ok(0.0);
        }
        if group == eqtrack_controller::GroupKind::So3 {
            if gravity != 0.0 {
                return Err(self.err(
                    "vehicle.gravity",
                    "an SO(3) body has no position: its weight acts at the centre of mass and turns nothing; use group se3, or 0",
                ));
            }
            return Ok(0.0);
        }
        let i = SMatrix::<f64, 6, 6>::from_row_slice(inertia);
        let m = i[(3, 3)];
        let block = i.fixed_view::<3, 3>(3, 3) - SMatrix::<f64, 3, 3>::identity() * m;
        let coupling = i
            .fixed_view::<3, 3>(0, 3)
            .amax()
            .max(i.fixed_view::<3, 3>(3, 0).amax());
        if gravity != 0.0 && (block.amax() > 1e-12 * m.abs().max(1.0) || coupling != 0.0) {
            return Err(self.err(
                "plant.inertia",
                "with gravity, the inertia's force block must be m·1₃ and its rotation–translation blocks zero (the body origin at the centre of mass)",
            ));
        }
        Ok(m)
    }

    /// `added_mass`: m×m, finite, symmetric, and the total inertia positive definite.
    fn added_mass(
        &self,
        a: &[Vec<f64>],
        m: usize,
        plant: &[f64],
    ) -> Result<Vec<f64>, ScenarioError> {
        let key = "vehicle.added_mass";
        let flat = self.matrix(key, a, m, "body frame, (ω, v) order")?;
        for i in 0..m {
            for j in 0..i {
                let (x, y) = (flat[i * m + j], flat[j * m + i]);
                if (x - y).abs() > 1e-12 * x.abs().max(y.abs()).max(1.0) {
                    return Err(self.err(
                        key,
                        format!("must be symmetric: entry ({i}, {j}) is {x}, ({j}, {i}) is {y}"),
                    ));
                }
            }
        }
        let total: Vec<f64> = plant.iter().zip(&flat).map(|(p, a)| p + a).collect();
        self.spd(key, &total, m).map_err(|_| {
            self.err(
                key,
                "the rigid body's inertia plus the added mass is not positive definite",
            )
        })?;
        Ok(flat)
    }

    /// `[[vehicle.actuator]]`: each with finite numbers, `min ≤ max`, a non-zero axis; with
    /// the `wheels` (checked before), 1 to 12 together, spanning the group's wrench space.
    fn actuators(
        &self,
        raw: &[RawActuator],
        wheels: &[eqtrack_allocation::Wheel<f64>],
        group: eqtrack_controller::GroupKind,
    ) -> Result<Vec<Actuator<f64>>, ScenarioError> {
        let planar = group == eqtrack_controller::GroupKind::Se2;
        // a planar vehicle's positions and axes are (x, y) in the body plane, stored with z = 0
        let (d, place, direction) = if planar {
            (
                2,
                "x, y in the body plane",
                "its thrust direction in the body plane",
            )
        } else {
            (
                3,
                "x, y, z in body axes",
                "its thrust direction in body axes",
            )
        };
        let three = |v: Vec<f64>| [v[0], v[1], v.get(2).copied().unwrap_or(0.0)];
        let mut out = Vec::with_capacity(raw.len());
        for (j, a) in raw.iter().enumerate() {
            let key = |field: &str| format!("vehicle.actuator[{j}].{field}");
            let p = self.vector(&key("position"), &a.position, d, place)?;
            let axis = self.vector(&key("axis"), &a.axis, d, direction)?;
            out.push(Actuator {
                position: three(p),
                axis: three(axis),
                torque_per_thrust: a.torque_per_thrust.unwrap_or(0.0),
                min: a.min,
                max: a.max,
            });
        }
        let spans = match group {
            eqtrack_controller::GroupKind::Se2 => Geometry::<f64, 3>::planar(&out)
                .map(drop)
                .map_err(|e| self.geometry_refused(&e)),
            eqtrack_controller::GroupKind::So3 => Geometry::<f64, 3>::with_wheels(&out, wheels)
                .map(drop)
                .map_err(|e| self.geometry_refused(&e)),
            eqtrack_controller::GroupKind::Se3 => Geometry::<f64, 6>::with_wheels(&out, wheels)
                .map(drop)
                .map_err(|e| self.geometry_refused(&e)),
        };
        spans?;
        Ok(out)
    }

    /// A geometry refusal, under the key it belongs to.
    fn geometry_refused<const K: usize>(&self, e: &GeometryError<f64, K>) -> ScenarioError {
        let key = match e {
            GeometryError::Count { .. }
            | GeometryError::Dimension
            | GeometryError::DoesNotSpan(_) => "vehicle.actuator".to_owned(),
            GeometryError::NonFinite { index, field } => {
                format!("vehicle.actuator[{index}].{field}")
            }
            GeometryError::ZeroAxis { index } => format!("vehicle.actuator[{index}].axis"),
            GeometryError::MinAboveMax { index, .. } => format!("vehicle.actuator[{index}].min"),
            GeometryError::OutOfPlane { index, field } => {
                format!("vehicle.actuator[{index}].{field}")
            }
        };
        self.err(&key, e.to_string())
    }

    /// `[[vehicle.failure]]`: an actuator that exists, a finite `t ≥ 0`, a kind it knows with
    /// its own keys (a stuck value within the actuator's range, a factor in (0, 1)); in time
    /// order.
    fn failures(
        &self,
        raw: &[RawFailure],
        ranges: &[(f64, f64)],
    ) -> Result<Vec<FailureSpec>, ScenarioError> {
        let count = ranges.len();
        let mut out = Vec::with_capacity(raw.len());
        for (i, f) in raw.iter().enumerate() {
            let key = |field: &str| format!("vehicle.failure[{i}].{field}");
            if f.actuator < 0 || f.actuator as usize >= count {
                return Err(self.err(
                    &key("actuator"),
                    format!(
                        "no actuator {} (the vehicle has {count}, numbered from 0)",
                        f.actuator
                    ),
                ));
            }
            if !f.t.is_finite() || f.t < 0.0 {
                return Err(self.err(&key("t"), format!("must be finite and ≥ 0, got {}", f.t)));
            }
            let reconfigure = f.reconfigure.unwrap_or(true);
            let (kind, value) = self.failure_kind(f, ranges[f.actuator as usize], &key)?;
            out.push(FailureSpec {
                actuator: f.actuator as usize,
                t: f.t,
                kind,
                value,
                reconfigure,
            });
        }
        out.sort_by(|a, b| a.t.total_cmp(&b.t));
        Ok(out)
    }

    /// One failure's `kind` and the keys it takes, checked (docs/scenario.md): `"stuck"` (the
    /// default) at `value` (0 when absent) within the actuator's range `[min, max]`; `"dead"`
    /// with neither key; `"effectiveness"` with `factor` in (0, 1) and no `value`. Returns
    /// the kind and the output it is held at (0 when dead).
    fn failure_kind(
        &self,
        f: &RawFailure,
        (min, max): (f64, f64),
        key: &dyn Fn(&str) -> String,
    ) -> Result<(FailureKind, f64), ScenarioError> {
        let refuse = |field: &str, kind: &str| {
            Err(self.err(
                &key(field),
                format!("a \"{kind}\" failure takes no `{field}`"),
            ))
        };
        match f.kind.as_deref().unwrap_or("stuck") {
            "stuck" => {
                if f.factor.is_some() {
                    return refuse("factor", "stuck");
                }
                let value = f.value.unwrap_or(0.0);
                if !value.is_finite() {
                    return Err(self.err(&key("value"), format!("not a finite number ({value})")));
                }
                if value < min || value > max {
                    return Err(self.err(
                        &key("value"),
                        format!("{value} is outside the actuator's range [{min}, {max}]"),
                    ));
                }
                Ok((FailureKind::Stuck, value))
            }
            "dead" => match (f.value, f.factor) {
                (Some(_), _) => refuse("value", "dead"),
                (_, Some(_)) => refuse("factor", "dead"),
                _ => Ok((FailureKind::Dead, 0.0)),
            },
            "effectiveness" => {
                if f.value.is_some() {
                    return refuse("value", "effectiveness");
                }
                let Some(factor) = f.factor else {
                    return Err(self.err(&key("factor"), "an \"effectiveness\" failure needs a `factor` in (0, 1)"));
                };
                if !(factor > 0.0 && factor < 1.0) {
                    return Err(self.err(&key("factor"), format!("must be in (0, 1), got {factor}")));
                }
                Ok((FailureKind::Effectiveness { factor }, 0.0))
            }
            other => Err(self.err(
                &key("kind"),
                format!("unknown failure kind \"{other}\" (known: \"stuck\", \"dead\", \"effectiveness\")"),
            )),
        }
    }

    /// `[allocation]`: weights (positive) and preferred commands, one per actuator each, the
    /// priority and the budget.
    fn allocation(
        &self,
        raw: Option<&RawAllocation>,
        count: usize,
    ) -> Result<(Vec<f64>, Vec<f64>, Priority, u32), ScenarioError> {
        let Some(raw) = raw else {
            return Ok((Vec::new(), Vec::new(), Priority::Torque, DEFAULT_BUDGET));
        };
        let list = |key: &str, v: &Option<Vec<f64>>| -> Result<Vec<f64>, ScenarioError> {
            match v {
                None => Ok(Vec::new()),
                Some(v) => self.vector(key, v, count, "one per actuator"),
            }
        };
        let weights = list("allocation.weights", &raw.weights)?;
        if let Some(i) = weights.iter().position(|w| *w <= 0.0) {
            return Err(self.err(
                "allocation.weights",
                format!("entry {i} must be positive, got {}", weights[i]),
            ));
        }
        let preferred = list("allocation.preferred", &raw.preferred)?;
        let priority = match raw.priority.as_deref() {
            None | Some("torque") => Priority::Torque,
            Some("none") => Priority::None,
            Some("tilt") => Priority::Tilt,
            Some(other) => {
                return Err(self.err(
                    "allocation.priority",
                    format!("unknown priority `{other}` (expected torque, tilt or none)"),
                ));
            }
        };
        let budget = match raw.budget {
            None => DEFAULT_BUDGET,
            Some(b) if (1..=MAX_BUDGET).contains(&b) => b as u32,
            Some(b) => {
                return Err(self.err(
                    "allocation.budget",
                    format!("must be a whole number of iterations from 1 to {MAX_BUDGET}, got {b}"),
                ));
            }
        };
        Ok((weights, preferred, priority, budget))
    }
}

impl Scenario {
    /// The inertia of the body the plant integrates (m×m, row-major): the rigid body's plus
    /// any added mass, less the reaction wheels' spin inertias `Σ J_s g gᵀ` (they spin free:
    /// docs/maths.md, "Reaction wheels").
    pub fn total_inertia(&self) -> Vec<f64> {
        let mut total = match self.vehicle.as_ref().and_then(|v| v.added_mass.as_ref()) {
            None => self.plant_inertia.clone(),
            Some(a) => self
                .plant_inertia
                .iter()
                .zip(a)
                .map(|(p, x)| p + x)
                .collect(),
        };
        if let Some(v) = self.vehicle.as_ref().filter(|v| !v.wheels.is_empty()) {
            let m = self.group.dims().1;
            let spin = crate::wheels::spin_inertia(&v.wheels, m);
            for (t, s) in total.iter_mut().zip(spin) {
                *t -= s;
            }
        }
        total
    }
}
