//! What the binary's tests share: running `plant_sim` and describing how it went.

use std::process::{Command, Output};

/// Runs `plant_sim args...` to completion.
#[allow(dead_code)] // not every test file uses it
pub fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_plant_sim"))
        .args(args)
        .output()
        .expect("plant_sim starts")
}

/// The exit status and both outputs, for an assertion's message.
pub fn text(out: &Output) -> String {
    format!(
        "exit {:?}\nstdout: {}\nstderr: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// Requires a successful exit.
#[allow(dead_code)] // not every test file uses it
pub fn ok(out: &Output) {
    assert!(out.status.success(), "{}", text(out));
}
