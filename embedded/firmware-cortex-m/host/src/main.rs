//! Prints the firmware's report on the host: the same inputs and the same code
//! (`firmware_cases::report`), in f32 on this machine. Exits 1 when a number is not finite.
//!
//! `cargo run --release -p firmware-host --target host-tuple` (from `firmware-cortex-m/`).

use std::process::ExitCode;

fn main() -> ExitCode {
    let mut out = String::new();
    let finite = firmware_cases::report(&mut out).expect("writing to a String cannot fail");
    print!("{out}");
    if finite {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}
