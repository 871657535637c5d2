//! Reaction wheels on the plant side (docs/maths.md, "Reaction wheels"): balanced wheels
//! spinning about fixed body axes, their motors' torque and speed limits, their friction, and
//! the gyrostat they make with the body, integrated inside the same RKMK4 substeps.
//!
//! The state is the body's, `(Q, J V)` with `J = I − Σ J_s g gᵀ` the inertia with the wheels
//! free, and each wheel's absolute axial momentum `h_i = J_s,i (g_iᵀω + Ω_i)`, integrated with
//! the same stages. The motors' torques are internal: they move momentum between the body
//! and the wheels and leave the total `p = J V + (Σ h g, 0)` to the outside wrench, so with
//! none the world momentum is kept to the integrator's error.
//!
//! The limits and the friction follow Basilisk's `reactionWheelStateEffector` (its code, where
//! its documentation differs): the command is clipped to `±max_torque`, then to `max_power`
//! (`|u Ω| ≤ P`), then zeroed when the wheel is at its top speed and the command would speed it
//! up, once per control period from the speed at its start; friction is evaluated at every
//! stage from the stage's wheel speed.

use eqtrack_controller::group::BuiltinGroup;
use eqtrack_controller::integrator::RigidBody;
use nalgebra::{SMatrix, SVector, Vector3};

/// The most wheels a body carries.
pub const MAX_WHEELS: usize = eqtrack_allocation::MAX_WHEELS;
// the wire carries as many wheel speeds as the allocation has wheels
const _: () = assert!(MAX_WHEELS == ipc_types::MAX_WHEELS);

/// Below this speed (rad/s) friction is linear in the speed, as Basilisk's `omegaLimitCycle`
/// (its default), so that the sign change of Coulomb friction does not chatter.
pub const LIMIT_CYCLE_SPEED: f64 = 1e-4;

/// One reaction wheel: its spin axis, its spin inertia, its motor's limits and its friction
/// (docs/maths.md, "Reaction wheels").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wheel {
    /// The spin axis `g_s` in body axes (made unit by [`Gyrostat::new`]).
    pub axis: [f64; 3],
    /// The spin inertia `J_s` (kg·m², > 0).
    pub inertia: f64,
    /// The motor's largest torque (N·m, > 0).
    pub max_torque: f64,
    /// The top speed relative to the body (rad/s, > 0): at it, a command that would speed
    /// the wheel up is zeroed.
    pub max_speed: f64,
    /// The motor's largest power `|u Ω|` (W), if limited.
    pub max_power: Option<f64>,
    /// Coulomb friction `f_C` (N·m, ≥ 0).
    pub friction_coulomb: f64,
    /// Static friction `f_S` (N·m, ≥ 0): the peak of the Stribeck curve.
    pub friction_static: f64,
    /// The Stribeck speed `β` (rad/s, > 0), if the Stribeck effect is modelled.
    pub stribeck_speed: Option<f64>,
    /// Viscous friction `c_v` (N·m·s, ≥ 0).
    pub friction_viscous: f64,
}

impl Wheel {
    /// A frictionless wheel with no power limit.
    pub fn ideal(axis: [f64; 3], inertia: f64, max_torque: f64, max_speed: f64) -> Self {
        Wheel {
            axis,
            inertia,
            max_torque,
            max_speed,
            max_power: None,
            friction_coulomb: 0.0,
            friction_static: 0.0,
            stribeck_speed: None,
            friction_viscous: 0.0,
        }
    }

    /// The motor torque the wheel applies for the command `u_cmd` at relative speed `omega`,
    /// with Basilisk's limits in its order (`ConfigureRWRequests`): clipped to
    /// `±max_torque`; then, with a power limit `P`, `u = sgn(u) P/|Ω|` where `|u Ω| ≥ P`; then
    /// zero where `|Ω| ≥ max_speed` and `Ω u ≥ 0`. A command that is not a number gives 0.
    /// Returns the torque and whether it differs from the command.
    pub fn limit(&self, u_cmd: f64, omega: f64) -> (f64, bool) {
        let mut u = if u_cmd.is_nan() { 0.0 } else { u_cmd };
        if u > self.max_torque {
            u = self.max_torque;
        } else if u < -self.max_torque {
            u = -self.max_torque;
        }
        if let Some(p) = self.max_power
            && (u * omega).abs() >= p
        {
            u = (p / omega).abs().copysign(u);
        }
        if omega.abs() >= self.max_speed && omega * u >= 0.0 {
            u = 0.0;
        }
        (u, u != u_cmd)
    }

    /// The friction force `f(Ω)` Basilisk's code computes (the friction torque on the wheel is
    /// `−f`): with the Stribeck effect on (`stribeck`, and a Stribeck speed `β`),
    /// `√(2e) (f_S − f_C) e^{−(Ω/β)²/2} Ω/(β√2) + f_C tanh(10 Ω/β) + c_v Ω`; otherwise
    /// `f_C sgn Ω + c_v Ω`. Below [`LIMIT_CYCLE_SPEED`] it is the line through 0 and its value
    /// there (for Coulomb friction, `f_C + c_v ω_lc`).
    pub fn friction(&self, omega: f64, stribeck: bool) -> f64 {
        let (fc, cv) = (self.friction_coulomb, self.friction_viscous);
        let curve = |w: f64| match self.stribeck_speed {
            Some(beta) if stribeck => {
                (2.0 * core::f64::consts::E).sqrt()
                    * (self.friction_static - fc)
                    * (-(w / beta) * (w / beta) / 2.0).exp()
                    * w
                    / (beta * core::f64::consts::SQRT_2)
                    + fc * (w * 10.0 / beta).tanh()
                    + cv * w
            }
            _ => sign(w) * fc + cv * w,
        };
        if omega.abs() < LIMIT_CYCLE_SPEED {
            let at = if stribeck && self.stribeck_speed.is_some() {
                curve(LIMIT_CYCLE_SPEED)
            } else {
                fc + cv * LIMIT_CYCLE_SPEED
            };
            at / LIMIT_CYCLE_SPEED * omega
        } else {
            curve(omega)
        }
    }

    /// Whether the Stribeck branch holds at speed `omega`, from whether it held (`was`) and
    /// the speed `before` at the start of the period, as Basilisk decides it at every
    /// evaluation: it starts when the wheel is within a tenth of [`LIMIT_CYCLE_SPEED`] of rest
    /// and lasts while the wheel speeds up (the signs of `Ω` and `Ω − Ω_before` not opposite).
    pub fn stribeck(&self, was: bool, omega: f64, before: f64) -> bool {
        let Some(beta) = self.stribeck_speed else {
            return false;
        };
        let on = was || (omega.abs() < 0.1 * LIMIT_CYCLE_SPEED && beta > 0.0);
        on && (sign(omega) - sign(omega - before)).abs() < 2.0
    }
}

/// `sgn x`, 0 at 0 (Basilisk's `(x > 0) − (x < 0)`).
fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Why a gyrostat cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WheelError {
    /// More wheels than [`MAX_WHEELS`].
    #[error("{0} wheels: at most {MAX_WHEELS}")]
    Count(usize),
    /// A wheel's axis is zero or not finite.
    #[error("wheel {0}: its axis is zero or not a finite vector")]
    Axis(usize),
    /// A wheel's inertia is not positive and finite.
    #[error("wheel {0}: its inertia must be positive and finite")]
    Inertia(usize),
    /// A wheel's limit is not positive, or a friction coefficient not finite and ≥ 0, or
    /// its Stribeck speed not positive and finite (the field is named).
    #[error("wheel {0}: {1} is out of range")]
    Parameter(usize, &'static str),
    /// The initial speeds are not one per wheel, or not finite.
    #[error("the initial speeds must be one finite number per wheel")]
    Speeds,
    /// The body with its wheels free, `I − Σ J_s g gᵀ`, is not positive definite.
    #[error(
        "the body's inertia less the wheels' spin inertias (I − Σ J_s g gᵀ) is not positive definite"
    )]
    FreeInertia,
}

/// The wheels a body carries, their state and their motors' commands (docs/maths.md,
/// "Reaction wheels"). The body itself is a [`RigidBody`] of the inertia with the wheels free,
/// `J = I − Σ J_s g gᵀ` ([`Wheels::free_inertia`]); [`Wheels::advance`] integrates the two
/// together.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wheels {
    /// The wheels' absolute axial momenta `h_i` (0 past the count).
    momenta: SVector<f64, MAX_WHEELS>,
    wheels: [Wheel; MAX_WHEELS],
    count: usize,
    /// The motor torques held over the period.
    applied: [f64; MAX_WHEELS],
    /// Failed motors: the torque each is stuck at (0: dead).
    stuck: [Option<f64>; MAX_WHEELS],
    /// Each motor's effectiveness (1 until it loses some).
    factor: [f64; MAX_WHEELS],
    /// The wheels' speeds at the start of the period.
    before: [f64; MAX_WHEELS],
    /// Whether each wheel's friction is on its Stribeck branch.
    stribeck: [bool; MAX_WHEELS],
}

impl Wheels {
    /// `wheels` spinning at `speeds` relative to a body turning at `omega` (rad/s), each
    /// axis made unit, each checked.
    pub fn new(wheels: &[Wheel], speeds: &[f64], omega: &Vector3<f64>) -> Result<Self, WheelError> {
        if wheels.len() > MAX_WHEELS {
            return Err(WheelError::Count(wheels.len()));
        }
        if speeds.len() != wheels.len() || speeds.iter().any(|s| !s.is_finite()) {
            return Err(WheelError::Speeds);
        }
        let mut out = Wheels {
            momenta: SVector::zeros(),
            wheels: [Wheel::ideal([1.0, 0.0, 0.0], 1.0, 1.0, 1.0); MAX_WHEELS],
            count: wheels.len(),
            applied: [0.0; MAX_WHEELS],
            stuck: [None; MAX_WHEELS],
            factor: [1.0; MAX_WHEELS],
            before: [0.0; MAX_WHEELS],
            stribeck: [false; MAX_WHEELS],
        };
        for (i, w) in wheels.iter().enumerate() {
            let axis = Vector3::from(w.axis);
            let norm = axis.norm();
            if !(norm.is_finite() && norm > 0.0) {
                return Err(WheelError::Axis(i));
            }
            if !(w.inertia.is_finite() && w.inertia > 0.0) {
                return Err(WheelError::Inertia(i));
            }
            check(i, w)?;
            let g = axis / norm;
            out.wheels[i] = Wheel {
                axis: g.into(),
                ..*w
            };
            out.momenta[i] = w.inertia * (g.dot(omega) + speeds[i]);
            out.before[i] = speeds[i];
        }
        Ok(out)
    }

    /// The wheels.
    pub fn wheels(&self) -> &[Wheel] {
        &self.wheels[..self.count]
    }

    /// Sets the wheels spinning at `speeds` relative to a body turning at `omega` (a run that
    /// starts elsewhere than where they were made: a Monte Carlo draw). Speeds past the count
    /// are ignored; a missing one is 0.
    pub fn spin(&mut self, speeds: &[f64], omega: &Vector3<f64>) {
        for i in 0..self.count {
            let w = &self.wheels[i];
            let s = speeds.get(i).copied().unwrap_or(0.0);
            self.momenta[i] = w.inertia * (Vector3::from(w.axis).dot(omega) + s);
            self.before[i] = s;
        }
    }

    /// The body's inertia with the wheels free, `J = I − Σ J_s g gᵀ` on the rotation block,
    /// from the inertia `locked` with them locked; refused when not positive definite.
    pub fn free_inertia<const M: usize>(
        &self,
        locked: &SMatrix<f64, M, M>,
    ) -> Result<SMatrix<f64, M, M>, WheelError> {
        let mut free = *locked;
        for w in self.wheels() {
            let g = Vector3::from(w.axis);
            let mut block = free.fixed_view_mut::<3, 3>(0, 0);
            block -= g * g.transpose() * w.inertia;
        }
        match free.cholesky() {
            Some(_) => Ok(free),
            None => Err(WheelError::FreeInertia),
        }
    }

    /// The wheels' absolute axial momenta `h_i = J_s (gᵀω + Ω_i)`.
    pub fn momenta(&self) -> &[f64] {
        &self.momenta.as_slice()[..self.count]
    }

    /// The wheels' momentum in body axes on the rotation block, `(Σ h_i g_i, 0)`: what the
    /// body's momentum `J V` lacks of the total.
    pub fn momentum<const M: usize>(&self) -> SVector<f64, M> {
        carried(&self.wheels, self.count, &self.momenta)
    }

    /// The wheels' speeds relative to a body moving at `v`, `Ω_i = h_i/J_s − gᵀω`.
    pub fn speeds<const M: usize>(&self, v: &SVector<f64, M>) -> [f64; MAX_WHEELS] {
        speeds(&self.wheels, self.count, &self.momenta, v)
    }

    /// The motor torques held over the present period (after the limits).
    pub fn applied(&self) -> &[f64] {
        &self.applied[..self.count]
    }

    /// Wheel `i`'s motor fails, stuck at the torque `value` (0: dead) from the next command
    /// on, whatever it is commanded (the motor's limits still apply).
    pub fn fail(&mut self, i: usize, value: f64) {
        if i < self.count {
            self.stuck[i] = Some(value);
        }
    }

    /// Wheel `i`'s motor loses effectiveness: it gives `factor` times its limited command.
    pub fn lose(&mut self, i: usize, factor: f64) {
        if i < self.count {
            self.factor[i] = factor;
        }
    }

    /// Holds the motor commands `u_cmd` (one per wheel; missing ones 0) over the period that
    /// starts now on a body moving at `v`, each limited by [`Wheel::limit`] at the wheel's
    /// present speed (a failed motor's stuck torque in place of its command; one that lost
    /// effectiveness gives that fraction). Returns how many commands a limit changed.
    pub fn command<const M: usize>(&mut self, u_cmd: &[f64], v: &SVector<f64, M>) -> usize {
        let omega = self.speeds(v);
        let mut clamped = 0;
        for (i, (w, s)) in self.wheels.iter().zip(omega).take(self.count).enumerate() {
            let asked = self.stuck[i].unwrap_or(u_cmd.get(i).copied().unwrap_or(0.0));
            let (u, changed) = w.limit(asked, s);
            let u = if self.factor[i] == 1.0 {
                u
            } else {
                u * self.factor[i]
            };
            self.applied[i] = u;
            self.before[i] = s;
            clamped += usize::from(changed);
        }
        clamped
    }

    /// Advances `body` (of inertia [`Wheels::free_inertia`]) and the wheels by `period` in
    /// `substeps` RKMK4 steps, under the motor torques held by [`Wheels::command`] and the
    /// outside wrench `wrench(s, Q, V)`, evaluated at every stage: the body meets
    /// `ad_Vᵀ (Σ h g, 0) − (Σ ḣ g, 0)` besides the outside wrench, each wheel
    /// `ḣ_i = u_i − f_i(Ω_i)` (docs/maths.md, "Reaction wheels").
    pub fn advance<G, F, const N: usize, const M: usize>(
        &mut self,
        body: &mut RigidBody<f64, G, N, M>,
        period: f64,
        substeps: usize,
        mut wrench: F,
    ) where
        G: BuiltinGroup<N, M>,
        F: FnMut(f64, &SMatrix<f64, N, N>, &SVector<f64, M>) -> SVector<f64, M>,
    {
        let (wheels, count) = (self.wheels, self.count);
        let (applied, before) = (self.applied, self.before);
        let stribeck = &mut self.stribeck;
        body.advance_carrying(period, substeps, &mut self.momenta, |s, q, v, hw| {
            let omega = speeds(&wheels, count, hw, v);
            let mut hd = SVector::<f64, MAX_WHEELS>::zeros();
            for j in 0..count {
                let w = &wheels[j];
                stribeck[j] = w.stribeck(stribeck[j], omega[j], before[j]);
                hd[j] = applied[j] - w.friction(omega[j], stribeck[j]);
            }
            let inside =
                G::ad(v).tr_mul(&carried(&wheels, count, hw)) - carried::<M>(&wheels, count, &hd);
            (wrench(s, q, v) + inside, hd)
        });
    }
}

/// A rigid body with reaction wheels, for studying the pair alone: a [`RigidBody`] of the
/// inertia with the wheels free and its [`Wheels`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gyrostat<G, const N: usize, const M: usize> {
    body: RigidBody<f64, G, N, M>,
    wheels: Wheels,
    /// The inertia with the wheels locked, `I`.
    locked: SMatrix<f64, M, M>,
}

impl<G: BuiltinGroup<N, M>, const N: usize, const M: usize> Gyrostat<G, N, M> {
    /// A body of inertia `inertia` with its wheels locked (Basilisk's convention: the whole
    /// spacecraft's), carrying `wheels` spinning at `speeds` relative to it (rad/s), at
    /// configuration `q` with body velocity `v`.
    pub fn new(
        inertia: SMatrix<f64, M, M>,
        wheels: &[Wheel],
        speeds: &[f64],
        q: SMatrix<f64, N, N>,
        v: SVector<f64, M>,
    ) -> Result<Self, WheelError> {
        let omega = Vector3::new(v[0], v[1], v[2]);
        let set = Wheels::new(wheels, speeds, &omega)?;
        let free = set.free_inertia(&inertia)?;
        let body = RigidBody::new(free, q, v).map_err(|_| WheelError::FreeInertia)?;
        Ok(Gyrostat {
            body,
            wheels: set,
            locked: inertia,
        })
    }

    /// The wheels.
    pub fn wheels(&self) -> &[Wheel] {
        self.wheels.wheels()
    }

    /// The configuration `Q`.
    pub fn configuration(&self) -> &SMatrix<f64, N, N> {
        self.body.configuration()
    }

    /// The total momentum `p = J V + (Σ h g, 0)` (body and wheels, body axes).
    pub fn momentum(&self) -> SVector<f64, M> {
        self.body.state().p + self.wheels.momentum::<M>()
    }

    /// The inertia with the wheels locked.
    pub fn inertia(&self) -> &SMatrix<f64, M, M> {
        &self.locked
    }

    /// The body velocity `V`.
    pub fn velocity(&self) -> SVector<f64, M> {
        self.body.velocity()
    }

    /// The wheels' speeds relative to the body.
    pub fn wheel_speeds(&self) -> [f64; MAX_WHEELS] {
        self.wheels.speeds(&self.body.velocity())
    }

    /// The motor torques held over the present period.
    pub fn applied(&self) -> &[f64] {
        self.wheels.applied()
    }

    /// [`Wheels::command`].
    pub fn command(&mut self, u_cmd: &[f64]) -> usize {
        let v = self.body.velocity();
        self.wheels.command(u_cmd, &v)
    }

    /// [`Wheels::advance`].
    pub fn advance_with<F>(&mut self, period: f64, substeps: usize, wrench: F)
    where
        F: FnMut(f64, &SMatrix<f64, N, N>, &SVector<f64, M>) -> SVector<f64, M>,
    {
        self.wheels
            .advance(&mut self.body, period, substeps, wrench);
    }
}

/// A wheel's limits and friction in range: limits positive (infinite is no limit), friction
/// finite and ≥ 0, a Stribeck speed positive and finite.
fn check(i: usize, w: &Wheel) -> Result<(), WheelError> {
    let positive = |x: f64| x > 0.0;
    let friction = |x: f64| x.is_finite() && x >= 0.0;
    let bad = if !positive(w.max_torque) {
        Some("max_torque")
    } else if !positive(w.max_speed) {
        Some("max_speed")
    } else if w.max_power.is_some_and(|p| !positive(p)) {
        Some("max_power")
    } else if !friction(w.friction_coulomb) {
        Some("friction_coulomb")
    } else if !friction(w.friction_static) {
        Some("friction_static")
    } else if !friction(w.friction_viscous) {
        Some("friction_viscous")
    } else if w
        .stribeck_speed
        .is_some_and(|b| !(b.is_finite() && b > 0.0))
    {
        Some("stribeck_speed")
    } else {
        None
    };
    bad.map_or(Ok(()), |field| Err(WheelError::Parameter(i, field)))
}

/// `(Σ x_i g_i, 0)`: per-wheel axial quantities `x` as a body wrench or momentum.
fn carried<const M: usize>(
    wheels: &[Wheel; MAX_WHEELS],
    count: usize,
    x: &SVector<f64, MAX_WHEELS>,
) -> SVector<f64, M> {
    let mut out = SVector::<f64, M>::zeros();
    for (w, xi) in wheels.iter().zip(x.iter()).take(count) {
        for (r, g) in w.axis.iter().enumerate() {
            out[r] += g * xi;
        }
    }
    out
}

/// `Ω_i = h_i/J_s,i − g_iᵀω`.
fn speeds<const M: usize>(
    wheels: &[Wheel; MAX_WHEELS],
    count: usize,
    h: &SVector<f64, MAX_WHEELS>,
    v: &SVector<f64, M>,
) -> [f64; MAX_WHEELS] {
    let mut omega = [0.0; MAX_WHEELS];
    for i in 0..count {
        let w = &wheels[i];
        let spin = w.axis[0] * v[0] + w.axis[1] * v[1] + w.axis[2] * v[2];
        omega[i] = h[i] / w.inertia - spin;
    }
    omega
}
