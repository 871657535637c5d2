//! Vehicle physics on the plant side (docs/maths.md, "Vehicle physics"): what the world does
//! to the body — gravity, buoyancy, drag — and its actuators' lag and failures, integrated
//! inside the RKMK4 substeps with the rigid body (whose inertia includes any added mass:
//! Kirchhoff's equations are Euler–Poincaré on SE(3) with the total inertia).

use allocation::{Commands, MAX_ACTUATORS};
use controller::group::MatrixLieGroup;
use controller::integrator::RigidBody;
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// What the world does to the body: gravity and buoyancy (known to the controller, which
/// compensates them) and drag. `M` is the group's dimension: 3 (SO(3), torques only) or 6
/// (SE(3), torque then force).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Environment<const M: usize> {
    /// The weight `m g` (N), along world −z at the centre of mass (the body origin).
    pub weight: f64,
    /// The buoyancy `B` (N), along world +z at [`Environment::buoyancy_centre`].
    pub buoyancy: f64,
    /// Where buoyancy acts, in body axes (m).
    pub buoyancy_centre: Vector3<f64>,
    /// Fossen's linear damping `D_l` (diagonal), in `(ω, v)` order.
    pub damping_linear: SVector<f64, M>,
    /// Fossen's quadratic damping `D_q` (diagonal), in `(ω, v)` order.
    pub damping_quadratic: SVector<f64, M>,
}

impl<const M: usize> Environment<M> {
    /// No gravity, no buoyancy, no drag: the ideal floating body.
    pub fn none() -> Self {
        Environment {
            weight: 0.0,
            buoyancy: 0.0,
            buoyancy_centre: Vector3::zeros(),
            damping_linear: SVector::zeros(),
            damping_quadratic: SVector::zeros(),
        }
    }

    /// Gravity and buoyancy as a body wrench at rotation `r` (body to world): the weight
    /// `Rᵀ(0, 0, −mg)` at the centre of mass, the buoyancy `Rᵀ(0, 0, B)` at `r_B`, so the
    /// torque `r_B × Rᵀ(0, 0, B)` and the force their sum. On SO(3) the torque alone.
    pub fn restoring(&self, r: &Matrix3<f64>) -> SVector<f64, M> {
        let up = r.transpose() * Vector3::z();
        let buoyancy = up * self.buoyancy;
        let torque = self.buoyancy_centre.cross(&buoyancy);
        let force = buoyancy - up * self.weight;
        let mut w = SVector::<f64, M>::zeros();
        for i in 0..3 {
            w[i] = torque[i];
            if M == 6 {
                w[3 + i] = force[i];
            }
        }
        w
    }

    /// Drag at body velocity `v`, in Fossen's diagonal form: `−(D_l v + D_q |v|∘v)`.
    pub fn drag(&self, v: &SVector<f64, M>) -> SVector<f64, M> {
        -(self.damping_linear.component_mul(v)
            + self
                .damping_quadratic
                .component_mul(&v.abs().component_mul(v)))
    }

    /// Everything the world does: [`Environment::restoring`] plus [`Environment::drag`].
    pub fn wrench(&self, r: &Matrix3<f64>, v: &SVector<f64, M>) -> SVector<f64, M> {
        self.restoring(r) + self.drag(v)
    }
}

/// The actuators as the plant drives them: the command held over a period, the output
/// following it with a first-order lag, failed ones stuck.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Actuators<const M: usize> {
    /// The effectiveness matrix (`allocation::Geometry::effectiveness`).
    b: SMatrix<f64, M, MAX_ACTUATORS>,
    /// The lag's time constant `T` (s); 0: the output is the command.
    time_constant: f64,
    /// The output at the start of the period, `u(t_k)`.
    output: Commands<f64>,
    /// The command held over the period, `u_cmd`.
    command: Commands<f64>,
    /// Whether a command has come (at `t = 0` the output starts at the first command).
    started: bool,
    /// Failed actuators: their stuck values.
    stuck: [Option<f64>; MAX_ACTUATORS],
}

impl<const M: usize> Actuators<M> {
    /// Actuators with effectiveness `b` and lag time constant `time_constant` (s, ≥ 0).
    pub fn new(b: SMatrix<f64, M, MAX_ACTUATORS>, time_constant: f64) -> Self {
        Actuators {
            b,
            time_constant: time_constant.max(0.0),
            output: Commands::zeros(),
            command: Commands::zeros(),
            started: false,
            stuck: [None; MAX_ACTUATORS],
        }
    }

    /// Actuator `j` fails, stuck at `value` from now on: its output jumps there and stays.
    pub fn fail(&mut self, j: usize, value: f64) {
        if j < MAX_ACTUATORS {
            self.stuck[j] = Some(value);
            self.output[j] = value;
            self.command[j] = value;
        }
    }

    /// Holds command `u_cmd` over the period that starts now (a failed actuator keeps its
    /// stuck value). The first command is also the output at `t = 0`.
    pub fn command(&mut self, u_cmd: &Commands<f64>) {
        self.command = *u_cmd;
        for (j, s) in self.stuck.iter().enumerate() {
            if let Some(v) = s {
                self.command[j] = *v;
            }
        }
        if !self.started {
            self.output = self.command;
            self.started = true;
        }
    }

    /// The output `s` seconds into the period: the exact first-order response
    /// `u(s) = u_cmd + (u(t_k) − u_cmd) e^{−s/T}` (the command itself when `T` = 0).
    pub fn output_at(&self, s: f64) -> Commands<f64> {
        if self.time_constant <= 0.0 {
            return self.command;
        }
        let decay = (-s / self.time_constant).exp();
        self.command + (self.output - self.command) * decay
    }

    /// The output at the start of the period, `u(t_k)`.
    pub fn output(&self) -> &Commands<f64> {
        &self.output
    }

    /// The actuators' wrench `B u(s)`, `s` seconds into the period.
    pub fn wrench_at(&self, s: f64) -> SVector<f64, M> {
        self.b * self.output_at(s)
    }

    /// Ends a period of length `h`: the output moves on to `u(t_k + h)`.
    pub fn end_period(&mut self, h: f64) {
        self.output = self.output_at(h);
    }
}

/// Advances `body` by one period `h` in `substeps` RKMK4 steps under the actuators' wrench
/// (lagging inside the period), the environment's (at every stage's state) and a further
/// body wrench `extra` held over the period; then ends the actuators' period.
pub fn step<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
    body: &mut RigidBody<f64, G, N, M>,
    environment: &Environment<M>,
    actuators: &mut Actuators<M>,
    extra: &SVector<f64, M>,
    h: f64,
    substeps: usize,
) {
    let a = *actuators;
    body.advance_with(h, substeps, |s, q, v| {
        a.wrench_at(s) + environment.wrench(&G::rotation(q), v) + extra
    });
    actuators.end_period(h);
}
