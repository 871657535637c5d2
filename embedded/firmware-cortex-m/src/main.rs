//! The `controller` crate on a Cortex-M4F (thumbv7em-none-eabihf), run under QEMU's
//! mps2-an386 board. Everything is f32, on the FPU.
//!
//! Over semihosting it prints:
//! * the report of [`firmware_cases::report`]: the EqT torque and Lyapunov function at every
//!   fixed SO(3) and SE(3) test state, then the seed closed loop's Lyapunov function every
//!   0.5 s for 2 s of simulated time, then `DONE <finite>`;
//! * `STACK <what> <bytes>` lines: the stack used by one law evaluation (SO(3), SE(3)), by
//!   one closed-loop cycle and by the whole report, measured by painting the stack (see
//!   [`stack`]); then `END`.
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
    let _ = writeln!(out, "END");
    stack_ok && report_ok && report_stack_ok
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
