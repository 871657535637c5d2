//! The fixed inputs of the Cortex-M comparison, and the report both sides print.
//!
//! `no_std`, no alloc, f32 only. The firmware (thumbv7em-none-eabihf under QEMU) and the host
//! program (x86_64) both call [`report`], so the two outputs differ only where the arithmetic
//! of the two machines does. Every line is one record, space-separated, numbers in Rust's
//! shortest round-trip `{:e}` form:
//!
//! ```text
//! TAU so3 <i> <τ0> <τ1> <τ2>            EqT torque for SO(3) test state i
//! TAU se3 <i> <τ0> … <τ5>               EqT wrench for SE(3) test state i
//! V   so3|se3 <i> <L>                   the Lyapunov function at that state
//! TAU|V so3_reference|se3_reference …   the same with `error_frame` reference (the above: world)
//! L   <t> <L>                           the seed closed loop's Lyapunov function at time t
//! ERR <what> <i> <error>                the controller returned an error (a failure)
//! DONE <finite>                         last line: 1 when every number above is finite
//! ```
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod demands;

use eqtrack_controller::closed_loop::ClosedLoop;
use eqtrack_controller::group::{MatrixLieGroup, Se3, So3};
use eqtrack_controller::integrator::RigidBody;
use eqtrack_controller::law::Desired;
use eqtrack_controller::{
    Controller, ControllerConfig, Error, ErrorFrame, Law, Reference, so3_seed_feedforward,
};
use core::fmt::{self, Write};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3, Vector6};

/// One state at which the law is evaluated: configuration, velocity, and the desired state.
#[derive(Debug, Clone, Copy)]
pub struct Case<const N: usize, const M: usize> {
    /// The measured configuration `Q`.
    pub q: SMatrix<f32, N, N>,
    /// The measured body velocity `V`.
    pub v: SVector<f32, M>,
    /// `Q_d`, `p_d = I V_d`, `V_d`, `τ_d`.
    pub desired: Desired<f32, N, M>,
}

/// The seed paper's inertia (kg·m²).
pub fn so3_inertia() -> Matrix3<f32> {
    Matrix3::new(0.824, 0.0, 0.12, 0.0, 1.135, 0.0, 0.12, 0.0, 1.759)
}

/// The SO(3) EqT controller of the seed scenario: `K = K_d = 0.5·I`, no saturation, the
/// papers' law (`error_frame` world, as the seed scenario pins it).
pub fn so3_controller() -> Result<Controller<f32, So3, 3, 3>, Error> {
    so3_controller_in(ErrorFrame::World)
}

/// [`so3_controller`] with its error formed in `error_frame`.
pub fn so3_controller_in(error_frame: ErrorFrame) -> Result<Controller<f32, So3, 3, 3>, Error> {
    Controller::new(ControllerConfig {
        law: Law::Eqt,
        error_frame,
        inertia: so3_inertia(),
        k: Matrix3::identity() * 0.5,
        kd: Matrix3::identity() * 0.5,
        torque_limit: None,
    })
}

/// An SE(3) EqT controller: the seed inertia for rotation, mass 2.5 kg, `K = diag(0.5, 0.5,
/// 0.5, 1)`, `K_d = diag(0.5, 0.5, 0.5, 1, 1, 1)`, no saturation; the papers' law
/// (`error_frame` world).
pub fn se3_controller() -> Result<Controller<f32, Se3, 4, 6>, Error> {
    se3_controller_in(ErrorFrame::World)
}

/// [`se3_controller`] with its error formed in `error_frame`.
pub fn se3_controller_in(error_frame: ErrorFrame) -> Result<Controller<f32, Se3, 4, 6>, Error> {
    let mut inertia = SMatrix::<f32, 6, 6>::zeros();
    inertia
        .fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&so3_inertia());
    inertia
        .fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(Matrix3::identity() * 2.5));
    Controller::new(ControllerConfig {
        law: Law::Eqt,
        error_frame,
        inertia,
        k: SMatrix::<f32, 4, 4>::from_diagonal(&nalgebra::Vector4::new(0.5, 0.5, 0.5, 1.0)),
        kd: SMatrix::<f32, 6, 6>::from_diagonal(&Vector6::new(0.5, 0.5, 0.5, 1.0, 1.0, 1.0)),
        torque_limit: None,
    })
}

/// An SO(3) case from rotation vectors: `R = exp(r)`, `R_d = exp(r_d)`, `p_d = I ω_d`.
fn so3_case(r: [f32; 3], w: [f32; 3], r_d: [f32; 3], w_d: [f32; 3], tau_d: [f32; 3]) -> Case<3, 3> {
    let v_d = Vector3::from(w_d);
    Case {
        q: So3::exp(&Vector3::from(r)),
        v: Vector3::from(w),
        desired: Desired {
            q: So3::exp(&Vector3::from(r_d)),
            p: so3_inertia() * v_d,
            v: v_d,
            tau: Vector3::from(tau_d),
        },
    }
}

/// The number of SO(3) test states.
pub const SO3_CASES: usize = 8;

/// The SO(3) test states (rotation vectors in rad, velocities in rad/s, torques in N·m).
pub fn so3_cases() -> [Case<3, 3>; SO3_CASES] {
    const Z: [f32; 3] = [0.0; 3];
    // The seed scenario's initial attitude: angle π − 0.1 about (0.8, 0.6, 0).
    let a = core::f32::consts::PI - 0.1;
    [
        // 0: at the goal, at rest: the torque is exactly zero.
        so3_case(Z, Z, Z, Z, Z),
        // 1: attitude error, fixed goal.
        so3_case([0.3, -0.2, 1.0], [1.0, 0.0, 0.5], Z, Z, Z),
        // 2: the seed scenario's initial state with τ_d(0) = (1, 0, 0).
        so3_case(
            [0.8 * a, 0.6 * a, 0.0],
            [4.0, -3.0, 2.0],
            Z,
            Z,
            [1.0, 0.0, 0.0],
        ),
        // 3: moving goal, all inputs non-zero.
        so3_case(
            [0.1, 0.2, 0.3],
            [0.5, -0.4, 0.3],
            [-0.4, 0.1, 0.7],
            [0.2, 0.1, -0.3],
            [0.1, -0.2, 0.05],
        ),
        // 4: error angle near π.
        so3_case(
            [3.0, 0.0, 0.5],
            [-2.0, 1.0, 0.5],
            [0.0, 0.2, 0.0],
            [1.0, 1.0, 1.0],
            [0.3, 0.3, -0.3],
        ),
        // 5: fast spin and a fast goal.
        so3_case(
            [1.2, -0.7, 0.4],
            [10.0, -8.0, 6.0],
            [0.5, 0.5, -0.5],
            [-5.0, 4.0, 3.0],
            [2.0, -1.0, 0.5],
        ),
        // 6: tiny errors (the small-angle branches).
        so3_case([1e-3, -2e-3, 5e-4], [1e-3, 0.0, -1e-3], Z, Z, Z),
        // 7: on the trajectory (R = R_d, ω = ω_d): τ = τ_d.
        so3_case(
            [0.2, -1.1, 0.6],
            [0.7, -0.3, 0.9],
            [0.2, -1.1, 0.6],
            [0.7, -0.3, 0.9],
            [0.4, 0.5, -0.6],
        ),
    ]
}

/// An SE(3) case from twists `(ω, v)`: `Q = exp(x)`, `Q_d = exp(x_d)`, `p_d = I V_d`.
fn se3_case(
    inertia: &SMatrix<f32, 6, 6>,
    x: [f32; 6],
    v: [f32; 6],
    x_d: [f32; 6],
    v_d: [f32; 6],
    tau_d: [f32; 6],
) -> Case<4, 6> {
    let v_d = Vector6::from(v_d);
    Case {
        q: Se3::exp(&Vector6::from(x)),
        v: Vector6::from(v),
        desired: Desired {
            q: Se3::exp(&Vector6::from(x_d)),
            p: inertia * v_d,
            v: v_d,
            tau: Vector6::from(tau_d),
        },
    }
}

/// The number of SE(3) test states.
pub const SE3_CASES: usize = 3;

/// The SE(3) test states; `inertia` is the controller's (for `p_d`).
pub fn se3_cases(inertia: &SMatrix<f32, 6, 6>) -> [Case<4, 6>; SE3_CASES] {
    const Z: [f32; 6] = [0.0; 6];
    [
        // 0: pose error only, fixed goal at the identity.
        se3_case(inertia, [0.1, 0.2, 0.3, 0.4, 0.5, 0.6], Z, Z, Z, Z),
        // 1: moving goal, all inputs non-zero.
        se3_case(
            inertia,
            [0.3, -0.2, 0.5, 1.0, -0.5, 0.25],
            [0.5, -0.2, 0.1, 1.0, 0.3, -0.4],
            [-0.1, 0.4, 0.2, 0.3, 0.2, -0.1],
            [0.1, 0.2, -0.1, 0.5, 0.0, 0.2],
            [0.1, 0.0, -0.1, 0.2, 0.3, 0.5],
        ),
        // 2: large rotation and translation, gravity-like feedforward force.
        se3_case(
            inertia,
            [2.5, 0.5, -1.0, 3.0, -2.0, 1.0],
            [3.0, -2.0, 1.0, -1.0, 2.0, 0.5],
            [0.0, 0.0, 1.5, 0.0, 0.0, 0.0],
            [0.0, 0.0, 0.5, 1.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 0.0, 0.0, 24.525],
        ),
    ]
}

/// The control period of the seed scenario (s).
pub const PERIOD: f32 = 0.01;
/// Control steps the closed loop runs: 2 s of simulated time.
pub const LOOP_STEPS: usize = 200;
/// Print `L` every this many steps (0.5 s).
pub const LOOP_PRINT_EVERY: usize = 50;

/// The seed scenario's closed loop in f32 (docs/maths.md, "The simulations"): EqT with
/// `K = K_d = 0.5·I`, reference from `R_d(0) = I`, `ω_d(0) = 0` driven by
/// [`so3_seed_feedforward`], 10 reference and 10 plant RKMK4 substeps per 0.01 s period,
/// plant from `R(0) = exp((π − 0.1)·(0.8, 0.6, 0))`, `ω(0) = (4, −3, 2)`.
pub fn seed_closed_loop() -> Result<ClosedLoop<f32, So3, 3, 3>, Error> {
    let inertia = so3_inertia();
    let reference = seed_reference(10)?;
    let a = core::f32::consts::PI - 0.1;
    let plant = RigidBody::new(
        inertia,
        So3::exp(&(Vector3::new(0.8, 0.6, 0.0) * a)),
        Vector3::new(4.0, -3.0, 2.0),
    )?;
    ClosedLoop::new(so3_controller()?, reference, plant, 10)
}

/// The seed scenario's reference generator in f32: `R_d(0) = I`, `ω_d(0) = 0`, driven by
/// [`so3_seed_feedforward`] with `substeps` RKMK4 steps per [`PERIOD`].
pub fn seed_reference(substeps: usize) -> Result<Reference<f32, So3, 3, 3>, Error> {
    Reference::new(
        Matrix3::identity(),
        Vector3::zeros(),
        so3_inertia(),
        so3_seed_feedforward(),
        PERIOD,
        substeps,
    )
}

/// Writes one number per field, space-separated, and ends the line.
fn numbers<W: Write>(out: &mut W, xs: impl Iterator<Item = f32>, finite: &mut bool) -> fmt::Result {
    for x in xs {
        *finite &= x.is_finite();
        write!(out, " {x:e}")?;
    }
    out.write_str("\n")
}

/// Evaluates the law at every case of one group and writes its `TAU` and `V` lines.
fn cases<W, G, const N: usize, const M: usize>(
    out: &mut W,
    group: &str,
    controller: &Controller<f32, G, N, M>,
    cases: &[Case<N, M>],
    finite: &mut bool,
) -> fmt::Result
where
    W: Write,
    G: MatrixLieGroup<N, M>,
{
    for (i, c) in cases.iter().enumerate() {
        match controller.compute(&c.q, &c.v, &c.desired) {
            Ok(o) => {
                write!(out, "TAU {group} {i}")?;
                numbers(out, o.torque.iter().copied(), finite)?;
                write!(out, "V {group} {i}")?;
                numbers(out, core::iter::once(o.lyapunov.total), finite)?;
            }
            Err(e) => {
                *finite = false;
                writeln!(out, "ERR {group} {i} {e}")?;
            }
        }
    }
    Ok(())
}

/// Runs the seed closed loop for [`LOOP_STEPS`] periods, writing `L <t> <L>` every
/// [`LOOP_PRINT_EVERY`] steps (t = 0, 0.5, …, 2).
fn closed_loop<W: Write>(out: &mut W, finite: &mut bool) -> fmt::Result {
    let mut sim = match seed_closed_loop() {
        Ok(s) => s,
        Err(e) => {
            *finite = false;
            return writeln!(out, "ERR loop 0 {e}");
        }
    };
    for k in 0..=LOOP_STEPS {
        match sim.step() {
            Ok(s) => {
                *finite &= s.output.torque.iter().all(|x| x.is_finite());
                if k % LOOP_PRINT_EVERY == 0 {
                    write!(out, "L {:.2}", s.t)?;
                    numbers(out, core::iter::once(s.output.lyapunov.total), finite)?;
                }
            }
            Err(e) => {
                *finite = false;
                return writeln!(out, "ERR loop {k} {e}");
            }
        }
    }
    Ok(())
}

/// Writes the whole report (every case of both groups with the papers' law, then with the law
/// at the reference, then the closed loop, then `DONE`). Returns whether every number was
/// finite and no call failed.
pub fn report<W: Write>(out: &mut W) -> Result<bool, fmt::Error> {
    let mut finite = true;
    for (frame, so3, se3) in [
        (ErrorFrame::World, "so3", "se3"),
        (ErrorFrame::Reference, "so3_reference", "se3_reference"),
    ] {
        match so3_controller_in(frame) {
            Ok(c) => cases(out, so3, &c, &so3_cases(), &mut finite)?,
            Err(e) => {
                finite = false;
                writeln!(out, "ERR {so3} - {e}")?;
            }
        }
        match se3_controller_in(frame) {
            Ok(c) => {
                let inertia = c.config().inertia;
                cases(out, se3, &c, &se3_cases(&inertia), &mut finite)?
            }
            Err(e) => {
                finite = false;
                writeln!(out, "ERR {se3} - {e}")?;
            }
        }
    }
    closed_loop(out, &mut finite)?;
    writeln!(out, "DONE {}", u8::from(finite))?;
    Ok(finite)
}
