//! The seed paper's simulation (docs/maths.md, "The simulations") with the controller crate alone:
//! prints L, ‖Q_E − I‖_F and ‖p_E‖ once a second of simulated time.
//!
//! `cargo run --release -p eqtrack-controller --example seed`

use eqtrack_controller::closed_loop::ClosedLoop;
use eqtrack_controller::group::{MatrixLieGroup, So3};
use eqtrack_controller::integrator::RigidBody;
use eqtrack_controller::{Controller, ControllerConfig, Law, Reference, so3_seed_feedforward};
use nalgebra::{Matrix3, Vector3};

fn main() -> Result<(), eqtrack_controller::Error> {
    let inertia = Matrix3::new(0.824, 0.0, 0.12, 0.0, 1.135, 0.0, 0.12, 0.0, 1.759);
    let controller = Controller::new(ControllerConfig {
        law: Law::Eqt,
        error_frame: eqtrack_controller::ErrorFrame::World,
        inertia,
        k: Matrix3::identity() * 0.5,
        kd: Matrix3::identity() * 0.5,
        torque_limit: None,
    })?;
    let reference = Reference::new(
        Matrix3::identity(),
        Vector3::zeros(),
        inertia,
        so3_seed_feedforward(),
        0.01,
        10,
    )?;
    let r0 = So3::exp(&(Vector3::new(0.8, 0.6, 0.0) * (std::f64::consts::PI - 0.1)));
    let plant = RigidBody::new(inertia, r0, Vector3::new(4.0, -3.0, 2.0))?;
    let mut sim: ClosedLoop<f64, So3, 3, 3> = ClosedLoop::new(controller, reference, plant, 10)?;
    println!(
        "{:>6} {:>14} {:>14} {:>14}",
        "t", "L", "|Q_E - I|_F", "|p_E|"
    );
    for k in 0..=2000 {
        let s = sim.step()?;
        if k % 100 == 0 {
            let n = s.norms::<So3>();
            println!(
                "{:>6.2} {:>14.6e} {:>14.6e} {:>14.6e}",
                s.t, s.output.lyapunov.total, n.config_error, n.momentum_error
            );
        }
    }
    Ok(())
}
