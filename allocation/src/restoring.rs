//! Gravity and buoyancy as a body wrench (docs/maths.md, "Vehicle physics"): what the
//! controller compensates from its model and the attitude, and what the plant integrates.

use nalgebra::{Matrix3, RealField, SVector, Vector3};

/// The known restoring forces: the weight at the centre of mass (the body origin) and the
/// buoyancy at the centre of buoyancy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Restoring<T> {
    /// The weight `m g` (N), along world −z.
    pub weight: T,
    /// The buoyancy `B` (N), along world +z.
    pub buoyancy: T,
    /// The centre of buoyancy `r_B`, in body axes (m).
    pub centre: Vector3<T>,
}

impl<T: RealField + Copy> Restoring<T> {
    /// Neither weight nor buoyancy.
    pub fn none() -> Self {
        Restoring {
            weight: T::zero(),
            buoyancy: T::zero(),
            centre: Vector3::zeros(),
        }
    }

    /// The body wrench at rotation `r` (body to world): the force `Rᵀ(0, 0, B − mg)` and the
    /// torque `r_B × Rᵀ(0, 0, B)`, in (torque, force) order; with `K` = 3 the torque alone.
    pub fn wrench<const K: usize>(&self, r: &Matrix3<T>) -> SVector<T, K> {
        // `Rᵀ e_z`: the third row of `R`
        let up = Vector3::new(r[(2, 0)], r[(2, 1)], r[(2, 2)]);
        let buoyancy = up * self.buoyancy;
        let torque = self.centre.cross(&buoyancy);
        let force = buoyancy - up * self.weight;
        let mut w = SVector::<T, K>::zeros();
        for i in 0..3.min(K) {
            w[i] = torque[i];
            if K == 6 {
                w[3 + i] = force[i];
            }
        }
        w
    }
}
