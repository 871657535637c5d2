//! SO(3) × ℝ³, "attitude and world-frame position": a group eqtrack does not ship, written
//! outside eqtrack (the tutorial is this crate's README).
//!
//! An element is the 7 × 7 block-diagonal matrix `diag(R, T(x))`, `R ∈ SO(3)` and
//! `T(x) = [[I₃, x], [0, 1]]`; an algebra element is `(ω, v)`, `hat(ω, v) = diag(ω×, [[0, v],
//! [0, 0]])`. The product is the direct one: `(R₁, x₁)(R₂, x₂) = (R₁R₂, x₁ + x₂)`, so `Q̇ =
//! Q hat(V)` turns the body with `ω` (body axes) and moves the position with `v` (world
//! axes). Unlike SE(3), the attitude does not turn the velocity: the model of a vehicle
//! whose translational dynamics are written in world axes.
#![no_std]
#![forbid(unsafe_code)]

use eqtrack_controller::Real;
use eqtrack_controller::group::MatrixLieGroup;
use eqtrack_controller::group::so3::{exp_so3, log_so3, skew};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// SO(3) × ℝ³ as 7 × 7 matrices, algebra coordinates `(ω, v)`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct So3xR3;

/// The attitude block `R`.
pub fn attitude_block<T: Real>(q: &SMatrix<T, 7, 7>) -> Matrix3<T> {
    q.fixed_view::<3, 3>(0, 0).into_owned()
}

/// The position `x`.
pub fn position<T: Real>(q: &SMatrix<T, 7, 7>) -> Vector3<T> {
    q.fixed_view::<3, 1>(3, 6).into_owned()
}

/// `diag(R, T(x))`.
pub fn element<T: Real>(r: &Matrix3<T>, x: &Vector3<T>) -> SMatrix<T, 7, 7> {
    let mut q = SMatrix::<T, 7, 7>::identity();
    q.fixed_view_mut::<3, 3>(0, 0).copy_from(r);
    q.fixed_view_mut::<3, 1>(3, 6).copy_from(x);
    q
}

fn parts<T: Real>(v: &SVector<T, 6>) -> (Vector3<T>, Vector3<T>) {
    (
        v.fixed_rows::<3>(0).into_owned(),
        v.fixed_rows::<3>(3).into_owned(),
    )
}

impl MatrixLieGroup<7, 6> for So3xR3 {
    const NAME: &'static str = "so3xr3";

    fn hat<T: Real>(v: &SVector<T, 6>) -> SMatrix<T, 7, 7> {
        let (w, u) = parts(v);
        let mut x = SMatrix::<T, 7, 7>::zeros();
        x.fixed_view_mut::<3, 3>(0, 0).copy_from(&skew(&w));
        x.fixed_view_mut::<3, 1>(3, 6).copy_from(&u);
        x
    }

    fn vee<T: Real>(x: &SMatrix<T, 7, 7>) -> SVector<T, 6> {
        SVector::<T, 6>::new(
            x[(2, 1)],
            x[(0, 2)],
            x[(1, 0)],
            x[(3, 6)],
            x[(4, 6)],
            x[(5, 6)],
        )
    }

    /// `exp(ω, v) = diag(exp(ω×), T(v))`: the blocks do not mix.
    fn exp<T: Real>(v: &SVector<T, 6>) -> SMatrix<T, 7, 7> {
        let (w, u) = parts(v);
        element(&exp_so3(&w), &u)
    }

    fn log<T: Real>(q: &SMatrix<T, 7, 7>) -> SVector<T, 6> {
        let w = log_so3(&attitude_block(q));
        let x = position(q);
        SVector::<T, 6>::new(w[0], w[1], w[2], x[0], x[1], x[2])
    }

    fn inverse<T: Real>(q: &SMatrix<T, 7, 7>) -> SMatrix<T, 7, 7> {
        element(&attitude_block(q).transpose(), &(-position(q)))
    }

    /// `Ad_(R, x) = diag(R, I₃)`: a translation commutes with everything.
    fn adjoint<T: Real>(q: &SMatrix<T, 7, 7>) -> SMatrix<T, 6, 6> {
        let mut a = SMatrix::<T, 6, 6>::identity();
        a.fixed_view_mut::<3, 3>(0, 0).copy_from(&attitude_block(q));
        a
    }

    /// `ad_(ω, v) = diag(ω×, 0)`.
    fn ad<T: Real>(v: &SVector<T, 6>) -> SMatrix<T, 6, 6> {
        let mut a = SMatrix::<T, 6, 6>::zeros();
        a.fixed_view_mut::<3, 3>(0, 0).copy_from(&skew(&parts(v).0));
        a
    }

    /// The attitude turns body axes into world axes (the observer's world frame works).
    fn attitude<T: Real>(q: &SMatrix<T, 7, 7>) -> Option<Matrix3<T>> {
        Some(attitude_block(q))
    }

    /// Only the torque is in body axes: the force already is in world axes.
    fn rotate_coordinates<T: Real>(r: &Matrix3<T>, w: &SVector<T, 6>) -> SVector<T, 6> {
        let mut out = *w;
        out.fixed_rows_mut::<3>(0)
            .copy_from(&(r * w.fixed_rows::<3>(0)));
        out
    }
}

/// The scenario this crate flies: a body of 1.5 kg with an anisotropic inertia, starting
/// 2 m and 1.2 rad away from a reference that turns at 0.3 rad/s about a tilted axis and
/// drifts at 0.4 m/s, pushed by a periodic torque and force; 20 s at 100 Hz, the plant
/// integrated in 10 RKMK4 substeps per period.
pub mod scenario {
    use super::{So3xR3, element};
    use eqtrack_controller::closed_loop::ClosedLoop;
    use eqtrack_controller::group::so3::exp_so3;
    use eqtrack_controller::integrator::RigidBody;
    use eqtrack_controller::reference::{AxisTorque, CosTerm, Feedforward, Reference};
    use eqtrack_controller::{Controller, ControllerConfig, Error, ErrorFrame, Law};
    use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

    /// The controller's period (s).
    pub const PERIOD: f64 = 0.01;
    /// Periods flown.
    pub const STEPS: usize = 2000;

    /// The model and the plant's inertia: `diag(J, m I₃)`.
    pub fn inertia() -> SMatrix<f64, 6, 6> {
        let mut i = SMatrix::<f64, 6, 6>::zeros();
        i.fixed_view_mut::<3, 3>(0, 0).copy_from(&Matrix3::new(
            0.08, 0.01, 0.0, 0.01, 0.1, 0.0, 0.0, 0.0, 0.12,
        ));
        i.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(Matrix3::identity() * 1.5));
        i
    }

    /// The law's gains: `K = diag(K_R, I₃, k_x)` (only `k_x` of the position block enters
    /// `Υ`, as `½ k_x |x|²`) and `K_d`.
    pub fn config() -> ControllerConfig<f64, 7, 6> {
        let mut k = SMatrix::<f64, 7, 7>::identity();
        k.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&Matrix3::from_diagonal(&Vector3::new(0.6, 0.8, 1.0)));
        k[(6, 6)] = 4.0;
        let mut kd = SMatrix::<f64, 6, 6>::identity() * 0.4;
        for i in 3..6 {
            kd[(i, i)] = 3.0;
        }
        ControllerConfig {
            law: Law::Eqt,
            error_frame: ErrorFrame::Reference,
            inertia: inertia(),
            k,
            kd,
            torque_limit: None,
        }
    }

    /// The closed loop at its start.
    pub fn closed_loop() -> Result<ClosedLoop<f64, So3xR3, 7, 6>, Error> {
        let term = |a: f64, w: f64| CosTerm {
            amplitude: a,
            frequency: w,
            phase: 0.0,
        };
        let mut ff = Feedforward::<f64, 6>::zero();
        ff.axes[0] = AxisTorque::new(0, 0.0, &[term(0.02, 0.5)])?;
        ff.axes[4] = AxisTorque::new(4, 0.0, &[term(0.3, 0.7)])?;
        let v_d0 = SVector::<f64, 6>::new(0.1, 0.0, 0.28, 0.4, 0.0, 0.0);
        let reference = Reference::new(SMatrix::identity(), v_d0, inertia(), ff, PERIOD, 10)?;
        let q0 = element(
            &exp_so3(&Vector3::new(0.8, -0.6, 0.6)),
            &Vector3::new(1.2, -1.6, 0.0),
        );
        let plant = RigidBody::new(inertia(), q0, SVector::zeros())?;
        ClosedLoop::new(Controller::new(config())?, reference, plant, 10)
    }
}

/// The flight's outcome: the largest attitude error `‖I − R_dᵀR‖_F` and position error over
/// the first and the last second, and the largest rise of `L` in one period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Flight {
    /// `(attitude, position)` errors at the start.
    pub first: (f64, f64),
    /// The largest `(attitude, position)` errors over the last second.
    pub last: (f64, f64),
    /// The largest rise of `L` over one period.
    pub worst_rise: f64,
}

/// Flies [`scenario`] and measures it.
pub fn fly() -> Result<Flight, eqtrack_controller::Error> {
    let mut sim = scenario::closed_loop()?;
    let mut flight = Flight {
        first: (0.0, 0.0),
        last: (0.0, 0.0),
        worst_rise: f64::NEG_INFINITY,
    };
    let mut last_l = f64::INFINITY;
    for k in 0..scenario::STEPS {
        let s = sim.step()?;
        let norms = s.norms::<So3xR3>();
        let errors = (
            norms.attitude_error,
            (position(&s.q) - position(&s.desired.q)).norm(),
        );
        if k == 0 {
            flight.first = errors;
        }
        if k + 100 >= scenario::STEPS {
            flight.last = (flight.last.0.max(errors.0), flight.last.1.max(errors.1));
        }
        let l = s.output.lyapunov.total;
        if k > 0 {
            flight.worst_rise = flight.worst_rise.max(l - last_l);
        }
        last_l = l;
    }
    Ok(flight)
}

/// This crate's README (the tutorial), its code run as doc tests.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
