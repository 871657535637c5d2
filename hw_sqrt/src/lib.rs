//! The square root the controller's cycle takes
//! (docs/maths.md, "The square root on a microcontroller"):
//! on an ARM hard-float target (`target_abi = "eabihf"`, e.g. a Cortex-M4F,
//! `thumbv7em-none-eabihf`) the FPU's `VSQRT.F32`, elsewhere libm's `sqrtf`.
//!
//! Both are IEEE 754's correctly rounded square root (round to nearest, ties to even), so they
//! give the same bits for every input that is not a NaN, and a NaN for a NaN or a negative
//! number: `scripts/cortex-m.sh` checks it under QEMU on over a million inputs, subnormals,
//! ±0, infinities and negatives among them. The firmware's answers stay the host's byte for
//! byte, at five instructions a call instead of libm's fifty or so.
//!
//! This is the one crate of eqtrack's libraries with `unsafe` code: one `asm!` block.
//!
//! ## Features
//!
//! None. [`nalgebra`] is re-exported (the generic [`sqrt`] and [`norm`] take its types).
#![no_std]
#![deny(unsafe_code)]
#![deny(missing_docs)]

pub use nalgebra;

use core::any::Any;
use nalgebra::RealField;

/// The correctly rounded square root of `x`: `VSQRT.F32` on ARM hard-float, libm's `sqrtf`
/// elsewhere.
#[inline]
pub fn sqrtf(x: f32) -> f32 {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    {
        let r: f32;
        // SAFETY: the block reads `x` from a core register and writes `r` to one; it
        // touches only s0, which it saves on the stack first and restores last (the `vfp2`
        // feature that `sreg` operands need is not enabled on this toolchain's
        // thumbv7em-none-eabihf, so s0 cannot be named as an operand), and the stack below
        // the stack pointer, which the default options allow. VSQRT.F32 raises no trap: with
        // the FPU's exceptions untrapped (the reset state) an invalid input gives a NaN.
        #[allow(unsafe_code)]
        unsafe {
            core::arch::asm!(
                "vpush {{s0}}",
                "vmov s0, {x}",
                "vsqrt.f32 s0, s0",
                "vmov {r}, s0",
                "vpop {{s0}}",
                x = in(reg) x,
                r = lateout(reg) r,
            );
        }
        r
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    {
        libm::sqrtf(x)
    }
}

/// The square root of any scalar: [`sqrtf`] for `f32`, the scalar's own `sqrt` otherwise (for
/// `f64`, libm's `sqrt`, as before). The choice is made per type at compile time.
#[inline]
pub fn sqrt<T: RealField + Copy + 'static>(x: T) -> T {
    let mut y = x;
    if let Some(v) = (&mut y as &mut dyn Any).downcast_mut::<f32>() {
        *v = sqrtf(*v);
        return y;
    }
    x.sqrt()
}

/// The Euclidean norm of a vector or matrix through [`sqrt`]: the same bits as nalgebra's
/// `norm()`, which is the square root of `norm_squared()`.
#[inline]
pub fn norm<T, R, C, S>(m: &nalgebra::Matrix<T, R, C, S>) -> T
where
    T: RealField + Copy + 'static,
    R: nalgebra::Dim,
    C: nalgebra::Dim,
    S: nalgebra::Storage<T, R, C>,
{
    sqrt(m.norm_squared())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On the host both are libm's: the same bits, a NaN for a NaN or a negative number.
    #[test]
    fn the_generic_root_is_libms_on_both_scalars() {
        for x in [
            0.0f32,
            -0.0,
            1e-45,
            1.17e-38,
            2.0,
            1e30,
            f32::MAX,
            f32::INFINITY,
        ] {
            assert_eq!(sqrt(x).to_bits(), libm::sqrtf(x).to_bits(), "{x}");
            let d = f64::from(x);
            assert_eq!(sqrt(d).to_bits(), libm::sqrt(d).to_bits(), "{d}");
        }
        assert!(sqrt(-1.0f32).is_nan() && sqrt(f32::NAN).is_nan() && sqrt(-1.0f64).is_nan());
        let v = nalgebra::Vector3::new(3.0f32, -4.0, 12.0);
        assert_eq!(norm(&v).to_bits(), v.norm().to_bits());
        assert_eq!(norm(&v), 13.0);
    }
}

/// This crate's README (its example), compiled and run as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
