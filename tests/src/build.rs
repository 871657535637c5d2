//! The workspace binaries the pair tests run, built as `cargo test --workspace` builds them.
//!
//! `cargo test -p pair_tests` builds this crate's tests, not the binaries they spawn: cargo
//! builds another package's binaries only for that package's own tests. And a binary built
//! by `cargo build --workspace` lacks the test-only `fault-injection` flags, which only the
//! dev-dependencies of this crate turn on. So before the first binary is started, [`ensure`]
//! runs `cargo test --workspace --no-run` in the same target directory and profile: the
//! build `cargo test --workspace` makes, with the same features, so the two flows share
//! every artifact and never rebuild each other's. After a `cargo test --workspace` it has
//! nothing to do (half a second here); on a fresh clone it builds the workspace.
//!
//! It runs once per `cargo test` invocation, not once per test binary: the first test binary
//! that builds leaves a stamp naming the process that ran it (its parent: cargo), and the
//! test binaries cargo runs after it see the stamp and skip the check. A test binary started
//! by anything but cargo (by hand, from a shell that outlives edits) checks every time.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// The binaries the pair tests start, directly or through `plant_sim` (`export`, `live`).
pub const BINARIES: [&str; 5] = [
    "plant_sim",
    "controller_node",
    "eqtrack-export",
    "eqtrack-live",
    "planner",
];

/// The directory of the test's profile (`target/debug`), where cargo puts the binaries.
pub fn profile_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("the test executable's path");
    exe.parent()
        .and_then(Path::parent)
        .expect("a test executable lives in <target>/<profile>/deps")
        .to_path_buf()
}

/// Builds the binaries once (see the module's documentation); panics naming the command to
/// run when the build fails.
pub fn ensure() {
    static BUILT: OnceLock<Result<(), String>> = OnceLock::new();
    if let Err(e) = BUILT.get_or_init(|| build(&profile_dir())) {
        panic!("{e}");
    }
}

/// The `cargo test` that ran this test binary: its id and its start time
/// (`/proc/<pid>/stat`, field 22), which tell it from a later process given the same id;
/// `None` when the parent is not cargo.
fn parent() -> Option<String> {
    let pid = std::os::unix::process::parent_id();
    let comm = std::fs::read_to_string(format!("/proc/{pid}/comm")).ok()?;
    if comm.trim_end() != "cargo" {
        return None;
    }
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // the fields after the command's name, which is in parentheses and may hold spaces
    let rest = &stat[stat.rfind(')')? + 1..];
    let start = rest.split_whitespace().nth(19)?;
    Some(format!("{pid} {start}"))
}

/// `cargo test --workspace --no-run` for the profile directory `dir`, unless this `cargo test`
/// already ran it.
fn build(dir: &Path) -> Result<(), String> {
    let stamp = dir.join("pair_tests-built");
    let me = parent();
    if me.is_some() && std::fs::read_to_string(&stamp).ok() == me {
        return Ok(());
    }
    let profile = dir
        .file_name()
        .and_then(|n| n.to_str())
        .ok_or_else(|| format!("{}: not a profile directory", dir.display()))?;
    let target = dir
        .parent()
        .ok_or_else(|| format!("{}: not in a target directory", dir.display()))?;
    let root = Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ is in the workspace");
    let mut cargo = Command::new(std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into()));
    cargo
        .current_dir(root)
        .env("CARGO_TARGET_DIR", target)
        .args(["test", "--workspace", "--no-run", "--locked", "--quiet"]);
    // the test profile's binaries come from its build profile: dev for `debug`
    match profile {
        "debug" => {}
        "release" => {
            cargo.arg("--release");
        }
        other => {
            cargo.args(["--profile", other]);
        }
    }
    let what = format!(
        "the pair's binaries ({}): cargo test --workspace --no-run --locked (in {})",
        BINARIES.join(", "),
        root.display()
    );
    // straight to stderr: the test harness captures `eprintln!`, and on a fresh clone this
    // build takes minutes
    let _ = writeln!(std::io::stderr(), "pair_tests: building {what}");
    let status = cargo
        .status()
        .map_err(|e| format!("cannot run cargo to build {what}: {e}"))?;
    if !status.success() {
        return Err(format!(
            "building {what} failed ({status}): run it to see why"
        ));
    }
    for name in BINARIES {
        if !dir.join(name).is_file() {
            return Err(format!(
                "{} is missing after building {what}",
                dir.join(name).display()
            ));
        }
    }
    if let Some(me) = me {
        // a stamp that cannot be written only costs the next test binary the check
        let _ = std::fs::write(&stamp, me);
    }
    Ok(())
}
