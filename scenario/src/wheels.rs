//! `[[vehicle.wheel]]`: reaction wheels (docs/maths.md, "Reaction wheels"; docs/scenario.md
//! lists every key).
//!
//! ```toml
//! [[vehicle.wheel]]           # one table per wheel, up to 6; after the thrusters in `u_cmd`
//! axis = [0.0, 0.0, 1.0]      # spin axis, body axes (made unit)
//! inertia = 0.01              # J_s, kg·m²
//! max_torque = 0.1            # N·m
//! max_speed = 600.0           # rad/s, relative to the body
//! max_power = 20.0            # W, optional
//! friction_coulomb = 0.0      # N·m
//! friction_static = 0.0       # N·m, the Stribeck peak
//! stribeck_speed = 0.1        # rad/s, optional (absent: no Stribeck effect)
//! friction_viscous = 0.0      # N·m·s
//! speed = 0.0                 # initial speed relative to the body, rad/s
//!
//! [vehicle.momentum]          # optional: momentum management (docs/maths.md)
//! null_space_gain = 0.1       # 1/s: wheel speeds toward `bias` (four or more wheels)
//! bias = [0.0, 0.0, 0.0, 0.0] # rad/s, one per wheel (default 0)
//! dump_threshold = 0.05       # N·m·s: above it the thrusters dump the wheels' momentum
//! dump_gain = 1.0             # 1/s (needs thrusters)
//! ```

use crate::{ScenarioError, Validator};
use eqtrack_allocation::MAX_WHEELS;
use nalgebra::{SMatrix, Vector3};
use serde::Deserialize;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawWheel {
    axis: Vec<f64>,
    inertia: f64,
    max_torque: f64,
    max_speed: f64,
    max_power: Option<f64>,
    friction_coulomb: Option<f64>,
    friction_static: Option<f64>,
    stribeck_speed: Option<f64>,
    friction_viscous: Option<f64>,
    speed: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawMomentum {
    null_space_gain: Option<f64>,
    bias: Option<Vec<f64>>,
    dump_threshold: Option<f64>,
    dump_gain: Option<f64>,
}

/// One reaction wheel (`[[vehicle.wheel]]`), in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelSpec {
    /// The spin axis in body axes (unit).
    pub axis: [f64; 3],
    /// `J_s` (kg·m², > 0).
    pub inertia: f64,
    /// The motor's largest torque (N·m, > 0).
    pub max_torque: f64,
    /// The top speed relative to the body (rad/s, > 0).
    pub max_speed: f64,
    /// The motor's largest power (W), if limited.
    pub max_power: Option<f64>,
    /// Coulomb friction (N·m, ≥ 0).
    pub friction_coulomb: f64,
    /// Static friction, the Stribeck peak (N·m, ≥ 0).
    pub friction_static: f64,
    /// The Stribeck speed (rad/s, > 0), if the Stribeck effect is modelled.
    pub stribeck_speed: Option<f64>,
    /// Viscous friction (N·m·s, ≥ 0).
    pub friction_viscous: f64,
    /// The initial speed relative to the body (rad/s, within `±max_speed`).
    pub speed: f64,
}

impl WheelSpec {
    /// The wheel as the controller's allocation sees it.
    pub fn allocation(&self) -> eqtrack_allocation::Wheel<f64> {
        eqtrack_allocation::Wheel {
            axis: self.axis,
            inertia: self.inertia,
            max_torque: self.max_torque,
            max_speed: self.max_speed,
        }
    }
}

/// The speed below which the plant's wheel friction is linear (Basilisk's `omegaLimitCycle`).
const LIMIT_CYCLE_SPEED: f64 = 1e-4;

/// The slope of a wheel's friction below [`LIMIT_CYCLE_SPEED`]: the larger of its Coulomb
/// branch's, `f_C/ω_lc + c_v`, and (with a Stribeck speed `β`) its Stribeck branch's, the
/// curve's value at `ω_lc` over `ω_lc`.
fn friction_slope(w: &WheelSpec) -> f64 {
    let lc = LIMIT_CYCLE_SPEED;
    let coulomb = w.friction_coulomb / lc + w.friction_viscous;
    let stribeck = w.stribeck_speed.map_or(0.0, |beta| {
        ((2.0 * std::f64::consts::E).sqrt()
            * (w.friction_static - w.friction_coulomb)
            * (-(lc / beta) * (lc / beta) / 2.0).exp()
            * lc
            / (beta * std::f64::consts::SQRT_2)
            + w.friction_coulomb * (lc * 10.0 / beta).tanh()
            + w.friction_viscous * lc)
            / lc
    });
    coulomb.max(stribeck)
}

/// `Σ J_s g gᵀ` of `wheels` on the rotation block of an `m`×`m` inertia (row-major): what the
/// wheels' spin takes from the body's inertia when they turn free.
pub(crate) fn spin_inertia(wheels: &[WheelSpec], m: usize) -> Vec<f64> {
    let mut out = vec![0.0; m * m];
    for w in wheels {
        for r in 0..3 {
            for c in 0..3 {
                out[r * m + c] += w.inertia * w.axis[r] * w.axis[c];
            }
        }
    }
    out
}

impl Validator<'_> {
    /// `[vehicle.momentum]` for `wheels` and `thrusters` actuators besides them, at control
    /// period `h` on a group of dimension `m`: a null-space gain ≥ 0 below `1/h` (and then four or more wheels, whose
    /// null space it uses), one finite bias per wheel, a dump gain ≥ 0 below `1/h` with a
    /// positive threshold (and thrusters to dump with, on SO(3)).
    pub(crate) fn momentum(
        &self,
        raw: Option<&RawMomentum>,
        wheels: &[WheelSpec],
        thrusters: usize,
        (h, m): (f64, usize),
    ) -> Result<Option<eqtrack_allocation::Momentum<f64>>, ScenarioError> {
        let Some(raw) = raw else {
            return Ok(None);
        };
        if wheels.is_empty() {
            return Err(self.err(
                "vehicle.momentum",
                "needs reaction wheels ([[vehicle.wheel]])",
            ));
        }
        let gain = |key: &str, x: Option<f64>| -> Result<f64, ScenarioError> {
            let x = x.map_or(Ok(0.0), |x| self.non_negative(key, x))?;
            if x * h >= 1.0 {
                return Err(self.err(
                    key,
                    format!("{x} /s is not below 1/h = {} /s: the correction would overshoot in one period", 1.0 / h),
                ));
            }
            Ok(x)
        };
        let null_gain = gain("vehicle.momentum.null_space_gain", raw.null_space_gain)?;
        if null_gain > 0.0 && wheels.len() < 4 {
            return Err(self.err(
                "vehicle.momentum.null_space_gain",
                format!(
                    "needs four or more wheels (a null space to move them in), the vehicle has {}",
                    wheels.len()
                ),
            ));
        }
        let mut bias = [0.0; MAX_WHEELS];
        if let Some(b) = &raw.bias {
            let b = self.vector(
                "vehicle.momentum.bias",
                b,
                wheels.len(),
                "one speed per wheel, rad/s",
            )?;
            for (i, (x, w)) in b.iter().zip(wheels).enumerate() {
                if x.abs() > w.max_speed {
                    return Err(self.err(
                        "vehicle.momentum.bias",
                        format!(
                            "entry {i} ({x} rad/s) is beyond the wheel's max_speed {}",
                            w.max_speed
                        ),
                    ));
                }
                bias[i] = *x;
            }
        }
        let dump_gain = gain("vehicle.momentum.dump_gain", raw.dump_gain)?;
        let dump_threshold = match (raw.dump_threshold, dump_gain > 0.0) {
            (Some(t), _) => self.positive("vehicle.momentum.dump_threshold", t)?,
            (None, true) => {
                return Err(self.err(
                    "vehicle.momentum.dump_threshold",
                    "a dump needs its threshold (N·m·s)",
                ));
            }
            (None, false) => 0.0,
        };
        if dump_gain > 0.0 && m == 6 {
            return Err(self.err(
                "vehicle.momentum.dump_gain",
                "not on SE(3) yet: the thrusters, held at the dump's commands, would no longer give the force",
            ));
        }
        if dump_gain > 0.0 && thrusters == 0 {
            return Err(self.err(
                "vehicle.momentum.dump_gain",
                "a dump needs thrusters ([[vehicle.actuator]]) to put the torque on the body",
            ));
        }
        Ok(Some(eqtrack_allocation::Momentum {
            null_gain,
            bias,
            dump_threshold,
            dump_gain,
        }))
    }

    /// Each wheel's friction below the limit-cycle speed, where it is the line through 0 of
    /// slope `σ` (N·m·s/rad): with the substep `h` the plant integrates at, `σ h / J_s` must stay
    /// within RK4's stability interval on the negative real axis (about 2.785; 2.7 here), or
    /// the wheel's speed rings near rest (docs/maths.md, "Reaction wheels"). Refused naming
    /// the wheel's `friction_coulomb`, with the `plant_substeps` that would do.
    pub(crate) fn stiff_friction(&self, wheels: &[WheelSpec], h: f64) -> Result<(), ScenarioError> {
        const LIMIT: f64 = 2.7;
        for (i, w) in wheels.iter().enumerate() {
            let slope = friction_slope(w);
            let stiffness = slope * h / w.inertia;
            if stiffness > LIMIT {
                return Err(self.err(
                    &format!("vehicle.wheel[{i}].friction_coulomb"),
                    format!(
                        "friction below {LIMIT_CYCLE_SPEED} rad/s is a slope of {slope} N·m·s/rad, which with inertia {} and the plant's substep {h} s is {stiffness:.3} (more than RK4's {LIMIT}): raise plant_substeps {}-fold or lower the friction",
                        w.inertia,
                        (stiffness / LIMIT).ceil()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// `[[vehicle.wheel]]`: each with a non-zero finite axis (made unit), a positive finite
    /// inertia, torque and speed limit and power limit when given, friction finite and ≥ 0, a
    /// Stribeck speed positive and finite when given, an initial speed within the top speed;
    /// at most [`MAX_WHEELS`], and the body with them free, `I − Σ J_s g gᵀ` (`total`, the
    /// plant's inertia with any added mass), positive definite.
    pub(crate) fn wheels(
        &self,
        raw: &[RawWheel],
        total: &[f64],
        m: usize,
    ) -> Result<Vec<WheelSpec>, ScenarioError> {
        if raw.len() > MAX_WHEELS {
            return Err(self.err(
                "vehicle.wheel",
                format!("{} wheels: at most {MAX_WHEELS}", raw.len()),
            ));
        }
        let mut out = Vec::with_capacity(raw.len());
        for (i, w) in raw.iter().enumerate() {
            let key = |field: &str| format!("vehicle.wheel[{i}].{field}");
            let a = self.vector(&key("axis"), &w.axis, 3, "the spin axis in body axes")?;
            let axis = Vector3::new(a[0], a[1], a[2]);
            let norm = axis.norm();
            if !(norm > 0.0 && norm.is_finite()) {
                return Err(self.err(&key("axis"), "is zero (a wheel needs a spin axis)"));
            }
            let axis = axis / norm;
            let positive_or =
                |field: &str, x: Option<f64>| x.map(|x| self.positive(&key(field), x)).transpose();
            let friction = |field: &str, x: Option<f64>| {
                x.map_or(Ok(0.0), |x| self.non_negative(&key(field), x))
            };
            let max_speed = self.positive(&key("max_speed"), w.max_speed)?;
            let speed = w.speed.unwrap_or(0.0);
            if !speed.is_finite() || speed.abs() > max_speed {
                return Err(self.err(
                    &key("speed"),
                    format!(
                        "must be a finite number within ±max_speed = ±{max_speed}, got {speed}"
                    ),
                ));
            }
            out.push(WheelSpec {
                axis: axis.into(),
                inertia: self.positive(&key("inertia"), w.inertia)?,
                max_torque: self.positive(&key("max_torque"), w.max_torque)?,
                max_speed,
                max_power: positive_or("max_power", w.max_power)?,
                friction_coulomb: friction("friction_coulomb", w.friction_coulomb)?,
                friction_static: friction("friction_static", w.friction_static)?,
                stribeck_speed: positive_or("stribeck_speed", w.stribeck_speed)?,
                friction_viscous: friction("friction_viscous", w.friction_viscous)?,
                speed,
            });
        }
        if !out.is_empty() {
            let spin = spin_inertia(&out, m);
            let free: Vec<f64> = total.iter().zip(&spin).map(|(i, s)| i - s).collect();
            let spd = match m {
                3 => SMatrix::<f64, 3, 3>::from_row_slice(&free)
                    .cholesky()
                    .is_some(),
                _ => SMatrix::<f64, 6, 6>::from_row_slice(&free)
                    .cholesky()
                    .is_some(),
            };
            if !spd {
                return Err(self.err(
                    "vehicle.wheel",
                    "the body with its wheels free, plant.inertia − Σ inertia·axis·axisᵀ, is not positive definite (a wheel's spin inertia is as large as the body's about its axis)",
                ));
            }
        }
        Ok(out)
    }
}
