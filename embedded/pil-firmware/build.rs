//! Puts `memory.x` and the device's `device.x` where the linker finds them, checks that
//! `PIL_CONFIG` names the scenario's configuration (`plant_sim pil-config`), and writes the
//! build's settings from the environment to `settings.rs`:
//!
//! - `PIL_WATCHDOG_MS`: the watchdog's interrupt after this many milliseconds without a
//!   completed cycle, its reset after twice as many (default 500; 1 to 85 000);
//! - `PIL_HANG_AT` (with the feature `hang` only, and required by it): the state at which the
//!   control task hangs, a test's planted fault.
use std::{env, fs, path::PathBuf};

/// The watchdog's default first stage (ms): the emulator's clock is the host's, and a loaded
/// host can hold a lockstep run's next state for a few hundred milliseconds.
const WATCHDOG_MS: u64 = 500;
/// The longest first stage (ms): twice it, in 25 MHz ticks, still fits the 32-bit counter.
const WATCHDOG_MS_MAX: u64 = 85_000;

/// The value of `name` as a whole number in `range`, or `default` when it is not set; a bad
/// value stops the build, naming the variable, the value and what is wrong.
fn number(name: &str, default: Option<u64>, range: std::ops::RangeInclusive<u64>) -> u64 {
    println!("cargo:rerun-if-env-changed={name}");
    let Ok(text) = env::var(name) else {
        return default.unwrap_or_else(|| panic!("{name} is not set: the feature `hang` needs the state to hang at"));
    };
    let value: u64 = text
        .trim()
        .parse()
        .unwrap_or_else(|_| panic!("{name}={text:?}: not a whole number"));
    assert!(
        range.contains(&value),
        "{name}={value}: outside {} to {}",
        range.start(),
        range.end()
    );
    value
}

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    fs::write(out.join("memory.x"), include_bytes!("memory.x")).expect("write memory.x");
    fs::write(out.join("device.x"), include_bytes!("device.x")).expect("write device.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=device.x");
    println!("cargo:rerun-if-env-changed=PIL_CONFIG");
    let watchdog_ms = number("PIL_WATCHDOG_MS", Some(WATCHDOG_MS), 1..=WATCHDOG_MS_MAX);
    let hang_at = env::var_os("CARGO_FEATURE_HANG")
        .map(|_| number("PIL_HANG_AT", None, 1..=u64::from(u32::MAX)));
    fs::write(
        out.join("settings.rs"),
        format!(
            "/// The watchdog's first stage (ms; `PIL_WATCHDOG_MS`).\n\
             pub const WATCHDOG_MS: u32 = {watchdog_ms};\n\
             /// The state the control task hangs at (`PIL_HANG_AT`, the feature `hang`).\n\
             pub const HANG_AT: Option<u64> = {hang_at:?};\n"
        ),
    )
    .expect("write settings.rs");
    match env::var("PIL_CONFIG") {
        Ok(p) if PathBuf::from(&p).is_file() => println!("cargo:rerun-if-changed={p}"),
        Ok(p) => panic!("PIL_CONFIG={p}: no such file (write it with plant_sim pil-config)"),
        Err(_) => panic!(
            "PIL_CONFIG is not set: the firmware needs a scenario's configuration (plant_sim pil-config --scenario FILE --out FILE)"
        ),
    }
}
