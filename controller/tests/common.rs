//! Shared helpers for the controller's integration tests.
#![allow(dead_code)]

use eqtrack_controller::closed_loop::ClosedLoop;
use eqtrack_controller::group::{MatrixLieGroup, So3};
use eqtrack_controller::integrator::RigidBody;
use eqtrack_controller::{
    Controller, ControllerConfig, Law, Real, Reference, so3_seed_feedforward,
};
use nalgebra::{Matrix3, Vector3};

/// The extended paper's fixed-wing inertia (the project's default).
pub fn fixed_wing<T: Real>() -> Matrix3<T> {
    Matrix3::new(0.824, 0.0, 0.12, 0.0, 1.135, 0.0, 0.12, 0.0, 1.759).map(eqtrack_controller::real)
}

/// The seed scenario (docs/maths.md, "The simulations") with K = K_d = 0.5·1₃, 10 substeps.
pub fn seed_loop<T: Real>(law: Law, period: f64, substeps: usize) -> ClosedLoop<T, So3, 3, 3> {
    let inertia = fixed_wing::<T>();
    let half: T = eqtrack_controller::real(0.5);
    let config = ControllerConfig {
        law,
        error_frame: eqtrack_controller::ErrorFrame::World,
        inertia,
        k: Matrix3::identity() * half,
        kd: Matrix3::identity() * half,
        torque_limit: None,
    };
    let axis = Vector3::new(0.8, 0.6, 0.0) * (core::f64::consts::PI - 0.1);
    let r0 = So3::exp(&axis.map(eqtrack_controller::real::<T>));
    let w0 = Vector3::new(4.0, -3.0, 2.0).map(eqtrack_controller::real::<T>);
    let controller = Controller::new(config).unwrap();
    let reference = Reference::new(
        Matrix3::identity(),
        Vector3::zeros(),
        inertia,
        so3_seed_feedforward(),
        eqtrack_controller::real(period),
        substeps,
    )
    .unwrap();
    let plant = RigidBody::new(inertia, r0, w0).unwrap();
    ClosedLoop::new(controller, reference, plant, substeps).unwrap()
}

/// `|a − b| ≤ tol·(1 + |b|)`.
pub fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + b.abs())
}
