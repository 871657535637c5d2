//! Fixtures shared by the criterion and the instruction-count benchmarks: representative
//! states, the seed and SE(3) set-ups in f32 and f64, and a plain nalgebra EqT to compare
//! against in the same run.
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

use eqtrack_controller::group::{BuiltinGroup, MatrixLieGroup, Se3, So3};
use eqtrack_controller::integrator::RigidBody;
use eqtrack_controller::law::Desired;
use eqtrack_controller::law::so3::So3LawInput;
use eqtrack_controller::{
    Controller, ControllerConfig, Feedforward, Law, Real, Reference, real, so3_seed_feedforward,
};
use ipc_types::StateMsg;
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// The fixed-wing inertia of the papers.
pub fn fixed_wing<T: Real>() -> Matrix3<T> {
    Matrix3::new(0.824, 0.0, 0.12, 0.0, 1.135, 0.0, 0.12, 0.0, 1.759).map(real)
}

/// A representative SO(3) tracking state (large error, moving reference, non-diagonal gains).
pub fn so3_input<T: Real>() -> So3LawInput<T> {
    let k = Matrix3::new(1.0, 0.1, 0.0, 0.1, 0.8, 0.05, 0.0, 0.05, 1.2).map(real::<T>);
    So3LawInput {
        r: So3::exp(&Vector3::new(1.2, -0.7, 2.1).map(real::<T>)),
        omega: Vector3::new(0.9, -1.4, 0.3).map(real),
        r_d: So3::exp(&Vector3::new(-0.3, 0.5, 0.2).map(real::<T>)),
        omega_d: Vector3::new(0.2, 0.1, -0.4).map(real),
        tau_d: Vector3::new(0.5, -0.2, 0.1).map(real),
        inertia: fixed_wing(),
        k,
        kd: k * real::<T>(0.5),
    }
}

/// The same state as the generic law's arguments: `(q, v, p, desired, K, K_d)`.
#[allow(clippy::type_complexity)]
pub fn so3_generic<T: Real>() -> (
    Matrix3<T>,
    Vector3<T>,
    Vector3<T>,
    Desired<T, 3, 3>,
    Matrix3<T>,
    Matrix3<T>,
) {
    let x = so3_input::<T>();
    let desired = Desired {
        q: x.r_d,
        p: x.inertia * x.omega_d,
        v: x.omega_d,
        tau: x.tau_d,
    };
    (x.r, x.omega, x.inertia * x.omega, desired, x.k, x.kd)
}

/// SE(3) inertia: J = diag(0.8, 1.0, 1.2), m = 2.
pub fn se3_inertia<T: Real>() -> SMatrix<T, 6, 6> {
    SMatrix::<f64, 6, 6>::from_diagonal(&SVector::<f64, 6>::new(0.8, 1.0, 1.2, 2.0, 2.0, 2.0))
        .map(real)
}

/// A representative SE(3) state as the generic law's arguments.
#[allow(clippy::type_complexity)]
pub fn se3_generic<T: Real>() -> (
    SMatrix<T, 4, 4>,
    SVector<T, 6>,
    SVector<T, 6>,
    Desired<T, 4, 6>,
    SMatrix<T, 4, 4>,
    SMatrix<T, 6, 6>,
) {
    let i = se3_inertia::<T>();
    let q = Se3::exp(&SVector::<f64, 6>::new(1.2, -0.9, 1.3, 2.0, -1.0, 1.2).map(real::<T>));
    let q_d = Se3::exp(&SVector::<f64, 6>::new(0.1, 0.2, 0.4, 0.3, 0.1, -0.2).map(real::<T>));
    let v = SVector::<f64, 6>::new(1.0, -0.5, 0.3, 0.0, 0.5, -1.0).map(real::<T>);
    let v_d = SVector::<f64, 6>::new(0.0, 0.0, 0.4, 0.4, 0.0, 0.0).map(real::<T>);
    let desired = Desired {
        q: q_d,
        p: i * v_d,
        v: v_d,
        tau: SVector::<f64, 6>::new(0.0, 0.0, 0.0, 0.0, 0.32, 0.0).map(real),
    };
    let k = SMatrix::<f64, 4, 4>::from_diagonal(&nalgebra::Vector4::new(1.6, 1.2, 1.4, 2.0))
        .map(real::<T>);
    (
        q,
        v,
        i * v,
        desired,
        k,
        SMatrix::<T, 6, 6>::identity() * real::<T>(1.5),
    )
}

/// A straightforward, non-generic nalgebra EqT for SO(3) in f64 — what an engineer would
/// write by hand — to compare the crate's closed form against in the same run.
pub fn plain_nalgebra_eqt(x: &So3LawInput<f64>) -> Vector3<f64> {
    let we = x.omega - x.omega_d;
    let re = x.r * x.r_d.transpose();
    let m = x.k * re - re.transpose() * x.k;
    let prop = x.r_d.transpose() * Vector3::new(m[(2, 1)], m[(0, 2)], m[(1, 0)]);
    x.tau_d + we.cross(&(x.inertia * x.omega_d)) + x.omega_d.cross(&(x.inertia * we))
        - x.r_d.transpose() * (x.kd * (x.r_d * we))
        - prop
}

/// The seed scenario's controller (K = K_d = 0.5, torque limit 5 so saturation runs).
pub fn seed_controller<T: Real>(law: Law) -> Controller<T, So3, 3, 3> {
    let h = real::<T>(0.5);
    Controller::new(ControllerConfig {
        law,
        error_frame: eqtrack_controller::ErrorFrame::World,
        inertia: fixed_wing(),
        k: Matrix3::identity() * h,
        kd: Matrix3::identity() * h,
        torque_limit: Some(Vector3::repeat(real(5.0))),
    })
    .expect("valid configuration")
}

/// The seed reference at 1 kHz with `substeps` RKMK4 steps per period (the seed scenario
/// uses 10; a scenario's default is 1).
pub fn seed_reference<T: Real>(substeps: usize) -> Reference<T, So3, 3, 3> {
    Reference::new(
        Matrix3::identity(),
        Vector3::zeros(),
        fixed_wing(),
        so3_seed_feedforward(),
        real(0.001),
        substeps,
    )
    .expect("valid reference")
}

/// The seed plant (fixed-wing inertia), tumbling.
pub fn seed_plant<T: Real>() -> RigidBody<T, So3, 3, 3> {
    let r0 =
        So3::exp(&(Vector3::new(0.8, 0.6, 0.0) * (core::f64::consts::PI - 0.1)).map(real::<T>));
    RigidBody::new(fixed_wing(), r0, Vector3::new(4.0, -3.0, 2.0).map(real)).expect("valid plant")
}

/// EqT on SO(3) with the gains and inertia of [`so3_generic`] (non-diagonal `K`,
/// `K_d = K/2`, no torque limit), its error formed in `error_frame`.
pub fn so3_law_controller<T: Real>(
    error_frame: eqtrack_controller::ErrorFrame,
) -> Controller<T, So3, 3, 3> {
    let x = so3_input::<T>();
    Controller::new(ControllerConfig {
        law: Law::Eqt,
        error_frame,
        inertia: x.inertia,
        k: x.k,
        kd: x.kd,
        torque_limit: None,
    })
    .expect("valid configuration")
}

/// EqT on SE(3) with the gains and inertia of [`se3_generic`] (no torque limit), its error
/// formed in `error_frame`.
pub fn se3_law_controller<T: Real>(
    error_frame: eqtrack_controller::ErrorFrame,
) -> Controller<T, Se3, 4, 6> {
    let (_, _, _, _, k, kd) = se3_generic::<T>();
    Controller::new(ControllerConfig {
        law: Law::Eqt,
        error_frame,
        inertia: se3_inertia(),
        k,
        kd,
        torque_limit: None,
    })
    .expect("valid configuration")
}

/// The SE(3) controller of the se3_circle scenario.
pub fn se3_controller<T: Real>() -> Controller<T, Se3, 4, 6> {
    let (_, _, _, _, k, kd) = se3_generic::<T>();
    Controller::new(ControllerConfig {
        law: Law::Eqt,
        error_frame: eqtrack_controller::ErrorFrame::World,
        inertia: se3_inertia(),
        k,
        kd,
        torque_limit: Some(SVector::repeat(real(10.0))),
    })
    .expect("valid configuration")
}

/// The se3_circle reference at 1 kHz with `substeps` RKMK4 steps per period.
pub fn se3_reference<T: Real>(substeps: usize) -> Reference<T, Se3, 4, 6> {
    let mut ff = Feedforward::<T, 6>::zero();
    ff.axes[4] = eqtrack_controller::AxisTorque::constant(real(0.32));
    let v_d = SVector::<f64, 6>::new(0.0, 0.0, 0.4, 0.4, 0.0, 0.0).map(real::<T>);
    Reference::new(
        SMatrix::identity(),
        v_d,
        se3_inertia(),
        ff,
        real(0.001),
        substeps,
    )
    .expect("valid reference")
}

/// The se3_circle plant.
pub fn se3_plant<T: Real>() -> RigidBody<T, Se3, 4, 6> {
    let (q, v, ..) = se3_generic::<T>();
    RigidBody::new(se3_inertia(), q, v).expect("valid plant")
}

/// A state message as the plant would publish it.
pub fn state_msg<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    q: &SMatrix<f64, N, N>,
    v: &SVector<f64, M>,
) -> StateMsg {
    let mut m = StateMsg::new(link::wire::wire_group(G::KIND));
    m.control_period = 0.001;
    m.set_state(q, v);
    m
}
