//! Three vehicles' actuator layouts, as sugar over the actuator tables (docs/maths.md,
//! "Control allocation", "The presets").

use crate::geometry::Actuator;
use nalgebra::RealField;

fn c<T: RealField + Copy>(x: f64) -> T {
    T::from_subset(&x)
}

/// A hexarotor with tilted rotors (after Rajappa, Ryll, Bülthoff, Franchi, ICRA 2015): six
/// rotors at `arm` (m) from the centre, 60° apart starting on +x, each axis tilted by `tilt`
/// (rad) about its arm, alternately one way and the other, and spinning alternately
/// (`torque_per_thrust` = `drag`, −`drag`, …). Thrust pushes one way only: `[0, max_thrust]`
/// (N).
pub fn hexarotor<T: RealField + Copy>(arm: T, tilt: T, drag: T, max_thrust: T) -> [Actuator<T>; 6] {
    core::array::from_fn(|j| {
        let angle = c::<T>(core::f64::consts::FRAC_PI_3) * c(j as f64);
        let (s, co) = (angle.sin(), angle.cos());
        let sign = if j % 2 == 0 { T::one() } else { -T::one() };
        // tilted about the arm (radial) direction: the axis leans tangentially
        let (st, ct) = ((tilt * sign).sin(), (tilt * sign).cos());
        Actuator {
            position: [arm * co, arm * s, T::zero()],
            axis: [-st * s, st * co, ct],
            torque_per_thrust: drag * sign,
            min: T::zero(),
            max: max_thrust,
        }
    })
}

/// An eight-thruster ROV in the BlueROV2 Heavy layout: four horizontal thrusters at the
/// corners of a `length` × `width` (m) rectangle, vectored at 45°, and four vertical ones at
/// `(±vertical_x, ±vertical_y)`, all reversible: `[−max_thrust, max_thrust]` (N). Propeller
/// torque is neglected (`torque_per_thrust` 0).
pub fn rov_heavy<T: RealField + Copy>(
    length: T,
    width: T,
    vertical_x: T,
    vertical_y: T,
    max_thrust: T,
) -> [Actuator<T>; 8] {
    let h = c::<T>(core::f64::consts::FRAC_1_SQRT_2);
    let half = c::<T>(0.5);
    let corners = [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)];
    core::array::from_fn(|j| {
        let (sx, sy) = corners[j % 4];
        let (sx, sy) = (c::<T>(sx), c::<T>(sy));
        if j < 4 {
            Actuator {
                position: [sx * length * half, sy * width * half, T::zero()],
                // front thrusters point inward-forward, rear ones outward-forward
                axis: [h, -sx * sy * h, T::zero()],
                torque_per_thrust: T::zero(),
                min: -max_thrust,
                max: max_thrust,
            }
        } else {
            Actuator {
                position: [sx * vertical_x, sy * vertical_y, T::zero()],
                axis: [T::zero(), T::zero(), T::one()],
                torque_per_thrust: T::zero(),
                min: -max_thrust,
                max: max_thrust,
            }
        }
    })
}

/// Twelve one-way thrusters, `[0, max_thrust]` (N), at `arm` (m) from the centre of mass: two
/// per signed body axis, pushing across the arm, so that each opposite pair is a couple about
/// one body axis of up to `2 · arm · max_thrust` (N·m) (the spacecraft scenario's thrusters,
/// in its order). On SO(3) only their torque counts.
pub fn spacecraft_twelve<T: RealField + Copy>(arm: T, max_thrust: T) -> [Actuator<T>; 12] {
    // (position, axis) in units of arm and of the unit axis
    const TABLE: [([f64; 3], [f64; 3]); 12] = [
        ([0.0, 1.0, 0.0], [0.0, 0.0, 1.0]),
        ([0.0, -1.0, 0.0], [0.0, 0.0, 1.0]),
        ([0.0, 0.0, 1.0], [1.0, 0.0, 0.0]),
        ([0.0, 0.0, -1.0], [1.0, 0.0, 0.0]),
        ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
        ([-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
        ([0.0, -1.0, 0.0], [0.0, 0.0, -1.0]),
        ([0.0, 1.0, 0.0], [0.0, 0.0, -1.0]),
        ([0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]),
        ([0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]),
        ([-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]),
        ([1.0, 0.0, 0.0], [0.0, -1.0, 0.0]),
    ];
    core::array::from_fn(|j| {
        let (p, a) = TABLE[j];
        Actuator {
            position: p.map(|x| arm * c::<T>(x)),
            axis: a.map(c::<T>),
            torque_per_thrust: T::zero(),
            min: T::zero(),
            max: max_thrust,
        }
    })
}
