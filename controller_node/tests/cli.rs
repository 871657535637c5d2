//! controller_node's own command line (the pair is tested in the workspace's `tests/`).

use std::process::Command;

fn run(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_controller_node"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn bad_input_exits_2_with_a_message() {
    for (args, needle) in [
        (
            vec!["--builtin", "nope"],
            "unknown built-in scenario `nope`",
        ),
        (
            vec!["--builtin", "se3_circle", "--law", "gt"],
            "not defined for group se3",
        ),
        (
            vec!["--name", "has space", "--startup-timeout", "0.5"],
            "invalid run name",
        ),
        (
            vec!["--silence-timeout=-1"],
            "'--silence-timeout <S>': must be a positive number of seconds",
        ),
    ] {
        let out = run(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!err.contains("panicked"));
    }
}

#[test]
fn without_a_plant_it_gives_up_after_the_startup_timeout() {
    let started = std::time::Instant::now();
    let out = run(&["--name", "nobody-here", "--startup-timeout", "0.5"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("no plant appeared on run `nobody-here`"),
        "{err}"
    );
    assert!(started.elapsed().as_secs_f64() < 5.0);
}
