//! The `eqtrack-controller` crate on a Cortex-M4F (thumbv7em-none-eabihf), run under QEMU's
//! mps2-an386 board. Everything is f32, on the FPU.
//!
//! Over semihosting it prints:
//! * the report of [`firmware_cases::report`]: the EqT torque and Lyapunov function at every
//!   fixed SO(3) and SE(3) test state, then the seed closed loop's Lyapunov function every
//!   0.5 s for 2 s of simulated time, then `DONE <finite>`;
//! * `STACK <what> <bytes>` lines: the stack used by one law evaluation (SO(3), SE(3)), by
//!   one closed-loop cycle and by the whole report, measured by painting the stack (see
//!   [`stack`]);
//! * `SQRT <n> inputs, <k> differ`: the FPU's square root (`eqtrack_hw_sqrt::sqrtf`, `VSQRT.F32`)
//!   against libm's `sqrtf` over `n` inputs (see [`sqrt_check`]); then `END`.
//!
//! It exits with `EXIT_SUCCESS` when every number is finite and every measurement worked,
//! `EXIT_FAILURE` otherwise, and on panic. `scripts/cortex-m.sh` builds it, runs it and
//! compares the report with the host program's.
#![no_std]
#![no_main]

#[cfg(feature = "icount")]
mod icount;
mod memcopy;
mod stack;

use core::fmt::Write;
use cortex_m_rt::entry;
use cortex_m_semihosting::debug::{self, EXIT_FAILURE, EXIT_SUCCESS};
use cortex_m_semihosting::{hio, hprintln};
use firmware_cases::{
    Case, se3_cases, se3_controller, seed_closed_loop, so3_cases, so3_controller,
};

#[entry]
fn main() -> ! {
    #[cfg(feature = "icount")]
    let ok = icount::run();
    #[cfg(not(feature = "icount"))]
    let ok = run();
    debug::exit(if ok { EXIT_SUCCESS } else { EXIT_FAILURE });
    // `exit` returns only when no debugger or emulator serves semihosting.
    loop {
        cortex_m::asm::wfi();
    }
}

/// Measures the stack, then writes the report; true when everything worked and was finite.
#[cfg_attr(feature = "icount", allow(dead_code))]
fn run() -> bool {
    // Each measurement paints the stack below its own caller, so the order does not matter.
    let stack_ok = measure_stack();
    let Ok(mut out) = hio::hstdout() else {
        return false;
    };
    // The report itself is measured too: the most stack this firmware needs.
    let mut report_ok = false;
    let used = stack::used_by(&mut || {
        report_ok = firmware_cases::report(&mut out).unwrap_or(false);
    });
    let report_stack_ok = match used {
        Some(bytes) => writeln!(out, "STACK report {bytes}").is_ok(),
        None => {
            let _ = writeln!(out, "ERR stack report measurement failed");
            false
        }
    };
    let sqrt_ok = sqrt_check(&mut out);
    let _ = writeln!(out, "END");
    stack_ok && report_ok && report_stack_ok && sqrt_ok
}

/// Holds the FPU's square root to libm's correctly rounded `sqrtf`: the same bits for every
/// input that is not a NaN, a NaN for a NaN. The inputs: the special values (±0, ±∞, NaNs of
/// both signs, the subnormals' ends, the normals' ends, negatives), 2²⁰ bit patterns spread
/// over all 2³² by a multiplicative hash (both signs, every exponent, NaNs among them), and
/// 2¹⁶ subnormals. Prints `SQRT <n> inputs, <k> differ` (and the first that differs); true
/// when none does.
fn sqrt_check(out: &mut hio::HostStream) -> bool {
    const SPECIAL: [u32; 14] = [
        0x0000_0000,
        0x8000_0000,
        0x7f80_0000,
        0xff80_0000,
        0x7fc0_0000,
        0xffc0_0000,
        0x7f80_0001,
        0x0000_0001,
        0x007f_ffff,
        0x0080_0000,
        0x7f7f_ffff,
        0x3f80_0000,
        0xbf80_0000,
        0x8000_0001,
    ];
    let hashed = (0u32..1 << 20).map(|i| i.wrapping_mul(0x9e37_79b1));
    let subnormal = (0u32..1 << 16).map(|i| i << 7 | 0x55);
    let (mut n, mut differ) = (0u32, 0u32);
    for bits in SPECIAL.into_iter().chain(hashed).chain(subnormal) {
        let x = f32::from_bits(bits);
        let (a, b) = (eqtrack_controller::hw_sqrt::sqrtf(x), libm::sqrtf(x));
        let same = if b.is_nan() {
            a.is_nan()
        } else {
            a.to_bits() == b.to_bits()
        };
        n += 1;
        if !same {
            if differ == 0 {
                let _ = writeln!(
                    out,
                    "ERR sqrt of {bits:#010x}: {:#010x} against libm's {:#010x}",
                    a.to_bits(),
                    b.to_bits()
                );
            }
            differ += 1;
        }
    }
    writeln!(out, "SQRT {n} inputs, {differ} differ").is_ok() && differ == 0 && n > 1_000_000
}

/// Prints `STACK so3_compute`, `STACK se3_compute` and `STACK loop_step` lines: the bytes of
/// stack each call used (from the caller's stack pointer down to the lowest word written).
fn measure_stack() -> bool {
    let (Ok(so3), Ok(se3), Ok(mut sim)) = (so3_controller(), se3_controller(), seed_closed_loop())
    else {
        hprintln!("ERR stack - construction failed");
        return false;
    };
    // The largest SO(3) case (fast spin) and the largest SE(3) one.
    let c: Case<3, 3> = so3_cases()[5];
    let d: Case<4, 6> = se3_cases(&se3.config().inertia)[2];
    let mut ok = true;
    // One `STACK` line, or an `ERR` line when the measurement or the result failed.
    let mut line = |name: &str, used: Option<usize>, result_ok: bool| match used {
        Some(bytes) if result_ok => hprintln!("STACK {} {}", name, bytes),
        _ => {
            ok = false;
            hprintln!(
                "ERR stack {} failed (measured: {:?}, result ok: {})",
                name,
                used,
                result_ok
            );
        }
    };

    // Each result is stored in this frame (above the painted region), as a control loop
    // would hold it, so the figures are the calls' own stack use.
    let mut so3_out = None;
    let used = stack::used_by(&mut || so3_out = Some(so3.compute(&c.q, &c.v, &c.desired)));
    line(
        "so3_compute",
        used,
        so3_out.is_some_and(|r| r.is_ok_and(|o| finite(&o.torque))),
    );

    let mut se3_out = None;
    let used = stack::used_by(&mut || se3_out = Some(se3.compute(&d.q, &d.v, &d.desired)));
    line(
        "se3_compute",
        used,
        se3_out.is_some_and(|r| r.is_ok_and(|o| finite(&o.torque))),
    );

    let mut step = None;
    let used = stack::used_by(&mut || step = Some(sim.step()));
    line(
        "loop_step",
        used,
        step.is_some_and(|r| r.is_ok_and(|s| finite(&s.output.torque))),
    );
    ok
}

/// Whether every entry is finite.
fn finite<const M: usize>(v: &nalgebra::SVector<f32, M>) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// On panic: print the message and exit with failure.
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("PANIC {}", info);
    debug::exit(EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
