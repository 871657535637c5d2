//! The detector on a tumbling gyrostat (docs/maths.md, "Failure detection", with reaction
//! wheels): a body of inertia `J` with four wheels spinning fast and their motors idle, so the
//! body obeys `J ω̇ = (J ω + h_w) × ω` with the wheels' momentum `h_w` constant in body axes.
//! Integrated finely here, independently of the plant. Fed the wheels' speeds, the detector's
//! residual is its own integration error: no alarm and a spread near nothing. Without them
//! (the rigid body's balance) the residual carries `h_w × ω`, and its spread is orders of
//! magnitude larger: the test fails if the speeds are ignored.

use detection::{Config, Detector, threshold};
use eqtrack_allocation::{
    Allocator, Commands, Geometry, Priority, Restoring, VehicleControl, Wheel,
};
use eqtrack_controller::group::{MatrixLieGroup, So3};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

const H: f64 = 0.01;
const J_S: f64 = 2e-4;

/// Four wheels in a pyramid, each axis 30° off the x-y plane.
fn wheels() -> [Wheel<f64>; 4] {
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    [[c, 0.0, s], [0.0, c, s], [-c, 0.0, s], [0.0, -c, s]].map(|axis| Wheel {
        axis,
        inertia: J_S,
        max_torque: 0.01,
        max_speed: 600.0,
    })
}

fn inertia() -> Matrix3<f64> {
    Matrix3::new(0.5, 0.0, 0.02, 0.0, 0.6, 0.0, 0.02, 0.0, 0.4)
}

fn control() -> VehicleControl<f64, 3> {
    let w = wheels();
    let g = Geometry::<f64, 3>::with_wheels(&[], &w).unwrap();
    let a = Allocator::new(g, &[], &[], Priority::Torque).unwrap();
    let none = Restoring {
        weight: 0.0,
        buoyancy: 0.0,
        centre: Vector3::zeros(),
    };
    VehicleControl::new(a, none, 0.0, H).with_wheels(&w, 0)
}

fn config() -> Config<f64, 3> {
    let window = 10;
    Config {
        decimation: 1,
        window,
        threshold: threshold::chi2_upper(1, threshold::per_test(0.001, H, 4)),
        isolation: threshold::chi2_upper(2, 1e-6),
        margin: threshold::chi2_upper(1, 1e-3),
        relative: 0.01,
        confirm: window / 2,
        warmup: 0,
        calibration: 200,
        memory: H / 10.0,
        floor: SVector::from_element(1e-9),
        resolution: Commands::from_element(5e-5),
        inertia: inertia(),
        damping_linear: SVector::zeros(),
        damping_quadratic: SVector::zeros(),
        period: H,
        time_constant: 0.0,
    }
}

/// `ω̇ = J⁻¹ ((J ω + h) × ω)`.
fn rate(w: &Vector3<f64>, h: &Vector3<f64>) -> Vector3<f64> {
    let j = inertia();
    j.try_inverse().unwrap() * (j * w + h).cross(w)
}

/// Flies 30 s of free tumble; each period the detector sees the rate, the attitude and, when
/// `wheeled`, the wheels' speeds relative to the body. Returns the alarms and the largest
/// spread it learned.
fn tumble(wheeled: bool) -> (u32, f64) {
    let w = wheels();
    // each wheel's absolute momentum J_s (gᵀω + Ω), constant with its motor idle
    let absolute = [300.0, -250.0, 200.0, 350.0].map(|speed| J_S * speed);
    let h: Vector3<f64> = w
        .iter()
        .zip(absolute)
        .map(|(x, a)| Vector3::from(x.axis) * a)
        .sum();
    let mut omega = Vector3::new(0.5, -0.4, 0.3);
    let mut r = Matrix3::identity();
    let mut control = control();
    let mut d = Detector::new(config()).unwrap();
    let sub = 200;
    let dt = H / sub as f64;
    let mut spread = 0.0_f64;
    for _ in 0..3000 {
        let speeds: Vec<f64> = w
            .iter()
            .zip(absolute)
            .map(|(x, a)| a / J_S - Vector3::from(x.axis).dot(&omega))
            .collect();
        let v = SVector::<f64, 3>::from_column_slice(omega.as_slice());
        let given: &[f64] = if wheeled { &speeds } else { &[] };
        let found = d.observe_wheeled::<So3, 3>(&v, &r, given, &mut control);
        assert!(found.is_none(), "nothing failed: {found:?}");
        d.commanded(&Commands::zeros());
        spread = spread.max(d.variance().max());
        for _ in 0..sub {
            // RK4 for the rate, the attitude by the midpoint rate's exponential
            let k1 = rate(&omega, &h);
            let k2 = rate(&(omega + k1 * (dt / 2.0)), &h);
            let k3 = rate(&(omega + k2 * (dt / 2.0)), &h);
            let k4 = rate(&(omega + k3 * dt), &h);
            let mid = omega + k1 * (dt / 2.0);
            omega += (k1 + 2.0 * k2 + 2.0 * k3 + k4) * (dt / 6.0);
            let turn: SMatrix<f64, 3, 3> =
                So3::exp(&SVector::<f64, 3>::from_column_slice((mid * dt).as_slice()));
            r *= turn;
        }
    }
    (d.alarms(), spread)
}

#[test]
fn a_tumbling_gyrostat_is_nominal_only_with_its_wheels_momentum() {
    let (alarms, spread) = tumble(true);
    let (_, rigid) = tumble(false);
    eprintln!("spread with the wheels {spread:e}, without {rigid:e}");
    assert_eq!(alarms, 0, "a nominal tumble raised alarms");
    assert!(
        rigid > 1e4 * spread,
        "without the wheels' momentum the residual should carry h × ω: {rigid:e} vs {spread:e}"
    );
}
