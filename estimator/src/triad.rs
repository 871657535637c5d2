//! TRIAD (docs/maths.md, "TRIAD").

use crate::all_finite;
use eqtrack_controller::{Real, real};
use nalgebra::{Matrix3, Vector3};

/// The attitude `R` with `y₁ ∥ Rᵀd₁` exactly and `y₂` in the plane `Rᵀ{d₁, d₂}`, from two
/// body-frame samples `y₁, y₂` of the world directions `d₁, d₂` (docs/maths.md, "TRIAD"):
/// `R = [s₁ s₂ s₃][t₁ t₂ t₃]ᵀ` with `t₁ = ŷ₁`, `t₂ = (y₁ × y₂)/|y₁ × y₂|`, `t₃ = t₁ × t₂`, and
/// `s` the same triad of the world directions. `None` when a vector is not finite, or the
/// two directions (in either frame) are parallel to within `1e-6` of the sine of their angle.
pub fn triad<T: Real>(
    y1: &Vector3<T>,
    y2: &Vector3<T>,
    d1: &Vector3<T>,
    d2: &Vector3<T>,
) -> Option<Matrix3<T>> {
    let frame = |a: &Vector3<T>, b: &Vector3<T>| -> Option<Matrix3<T>> {
        if !all_finite(a) || !all_finite(b) {
            return None;
        }
        let (na, nb) = (
            eqtrack_controller::hw_sqrt::norm(a),
            eqtrack_controller::hw_sqrt::norm(b),
        );
        let tiny: T = real(1e-12);
        if na <= tiny || nb <= tiny {
            return None;
        }
        let t1 = a / na;
        let c = a.cross(b);
        let nc = eqtrack_controller::hw_sqrt::norm(&c);
        if nc <= na * nb * real(1e-6) {
            return None;
        }
        let t2 = c / nc;
        let t3 = t1.cross(&t2);
        Some(Matrix3::from_columns(&[t1, t2, t3]))
    };
    let t = frame(y1, y2)?;
    let s = frame(d1, d2)?;
    Some(s * t.transpose())
}
