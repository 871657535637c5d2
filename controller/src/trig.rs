//! `sin` and `cos` for the scalar types: libm's for `f64` (unchanged), and for `f32` a
//! single-precision implementation (docs/maths.md, "Sine and cosine in f32").
//!
//! libm's `sinf`/`cosf` (like musl's) evaluate their kernels in `f64`. A Cortex-M4F has a
//! single-precision FPU only, so every such call runs in software double arithmetic: in one
//! controller cycle with a feedforward reference that was 81 % of the instructions
//! (BENCHMARKS.md, section 6). The `f32` path here is the classic Cephes `sinf`/`cosf`
//! scheme, all in `f32`: the argument reduced by multiples of π/4 with π/4 split into three
//! parts (Cody–Waite, exact products for `|x| < 8192`), then a degree-7 odd or degree-8 even
//! polynomial on `[−π/4, π/4]`. Error: at most 3e-7 absolute against the exact value
//! (tested). Beyond `|x| = 8192`, and for non-finite input, it defers to libm.

use crate::Real;
use core::any::Any;

/// `sin(x)`.
#[inline]
pub fn sin<T: Real>(x: T) -> T {
    match (&x as &dyn Any).downcast_ref::<f32>() {
        Some(&xf) => back(sin_f32(xf)).unwrap_or_else(|| x.sin()),
        None => x.sin(),
    }
}

/// `cos(x)`.
#[inline]
pub fn cos<T: Real>(x: T) -> T {
    match (&x as &dyn Any).downcast_ref::<f32>() {
        Some(&xf) => back(cos_f32(xf)).unwrap_or_else(|| x.cos()),
        None => x.cos(),
    }
}

/// `y` as `T` (which is `f32` whenever this is called).
#[inline]
fn back<T: Real>(y: f32) -> Option<T> {
    (&y as &dyn Any).downcast_ref::<T>().copied()
}

/// Where the three-part reduction stops being exact.
const LIMIT: f32 = 8192.0;
const FOUR_OVER_PI: f32 = 1.273_239_5;
const DP1: f32 = 0.785_156_25;
const DP2: f32 = 2.418_756_5e-4;
const DP3: f32 = 3.774_895e-8;

/// `(z, octant)`: `|x| = octant·π/4 + z` with `|z| ≤ π/4` and an even octant (mod 8).
#[inline]
fn reduce(ax: f32) -> (f32, u32) {
    let mut j = (ax * FOUR_OVER_PI) as u32;
    j += j & 1;
    let y = j as f32;
    (((ax - y * DP1) - y * DP2) - y * DP3, j & 7)
}

/// `sin z` on `[−π/4, π/4]`.
#[inline]
fn sin_poly(z: f32) -> f32 {
    let zz = z * z;
    ((-1.951_529_6e-4 * zz + 8.332_161e-3) * zz - 1.666_665_5e-1) * zz * z + z
}

/// `cos z` on `[−π/4, π/4]`.
#[inline]
fn cos_poly(z: f32) -> f32 {
    let zz = z * z;
    ((2.443_315_7e-5 * zz - 1.388_731_6e-3) * zz + 4.166_664_6e-2) * zz * zz - 0.5 * zz + 1.0
}

/// `sin x` in `f32` arithmetic only.
pub fn sin_f32(x: f32) -> f32 {
    let ax = x.abs();
    if ax.is_nan() || ax >= LIMIT {
        return libm::sinf(x);
    }
    let (z, mut j) = reduce(ax);
    let mut negative = x < 0.0;
    if j > 3 {
        negative = !negative;
        j -= 4;
    }
    let y = if j == 2 { cos_poly(z) } else { sin_poly(z) };
    if negative { -y } else { y }
}

/// `cos x` in `f32` arithmetic only.
pub fn cos_f32(x: f32) -> f32 {
    let ax = x.abs();
    if ax.is_nan() || ax >= LIMIT {
        return libm::cosf(x);
    }
    let (z, mut j) = reduce(ax);
    let mut negative = false;
    if j > 3 {
        negative = !negative;
        j -= 4;
    }
    if j > 1 {
        negative = !negative;
    }
    let y = if j == 2 { sin_poly(z) } else { cos_poly(z) };
    if negative { -y } else { y }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Largest |f32 result − exact| over a fine grid of `[-r, r]`.
    fn worst(f: fn(f32) -> f32, exact: fn(f64) -> f64, r: f32, n: usize) -> (f64, f32) {
        let mut w = (0.0f64, 0.0f32);
        for i in 0..=n {
            let x = -r + 2.0 * r * (i as f32 / n as f32);
            let e = (f(x) as f64 - exact(x as f64)).abs();
            if e > w.0 {
                w = (e, x);
            }
        }
        w
    }

    #[test]
    fn f32_sine_and_cosine_are_within_3e_7_of_the_exact_values() {
        for r in [1.0, 10.0, 1000.0, 8191.0] {
            let (es, xs) = worst(sin_f32, libm::sin, r, 400_000);
            let (ec, xc) = worst(cos_f32, libm::cos, r, 400_000);
            assert!(es < 3e-7, "sin: {es:e} at {xs}");
            assert!(ec < 3e-7, "cos: {ec:e} at {xc}");
        }
        // quadrant boundaries and exact values
        for k in -16..=16 {
            let x = k as f32 * core::f32::consts::FRAC_PI_4;
            assert!((sin_f32(x) as f64 - libm::sin(x as f64)).abs() < 3e-7);
            assert!((cos_f32(x) as f64 - libm::cos(x as f64)).abs() < 3e-7);
        }
        assert_eq!(sin_f32(0.0), 0.0);
        assert_eq!(cos_f32(0.0), 1.0);
    }

    #[test]
    fn large_and_non_finite_arguments_go_to_libm_and_f64_is_unchanged() {
        assert_eq!(sin_f32(1.0e5), libm::sinf(1.0e5));
        assert_eq!(cos_f32(-3.0e4), libm::cosf(-3.0e4));
        assert!(sin_f32(f32::NAN).is_nan() && cos_f32(f32::INFINITY).is_nan());
        for x in [0.3f64, -2.0, 100.5, 1e6] {
            assert_eq!(sin(x).to_bits(), libm::sin(x).to_bits());
            assert_eq!(cos(x).to_bits(), libm::cos(x).to_bits());
        }
        assert_eq!(sin(0.7f32), sin_f32(0.7));
        assert_eq!(cos(0.7f32), cos_f32(0.7));
    }
}
