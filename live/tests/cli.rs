//! `eqtrack-live`'s command line, without a run: bad input is a clear error (exit 2), an
//! address that cannot be listened on fails (exit 1), a non-loopback address is warned
//! about, no run within `--wait` fails (exit 1), and SIGTERM stops it cleanly (143) with its
//! totals.

use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn live(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_eqtrack-live"))
        .args(args)
        .output()
        .expect("eqtrack-live runs")
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

#[test]
fn bad_addresses_and_run_names_are_clear_errors() {
    for bad in [
        "nonsense",
        "127.0.0.1",
        "127.0.0.1:99999",
        "999.1.1.1:80",
        "localhost:x",
        ":8765",
    ] {
        let o = live(&["--name", "x", "--listen", bad]);
        assert_eq!(o.status.code(), Some(2), "--listen {bad}: {}", text(&o));
        assert!(text(&o).contains("expected IP:PORT"), "{}", text(&o));
    }
    for bad in ["a b", "", "x/y", &"n".repeat(65)] {
        let o = live(&["--name", bad]);
        assert_eq!(o.status.code(), Some(2), "--name {bad:?}: {}", text(&o));
        assert!(text(&o).contains("run name"), "{}", text(&o));
    }
    let o = live(&["--name", "x", "--wait", "-1"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
}

#[test]
fn a_busy_port_fails_and_a_non_loopback_address_is_warned_about() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = taken.local_addr().unwrap().to_string();
    let o = live(&["--name", "t-live-busy", "--listen", &addr, "--wait", "1"]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("cannot listen on"), "{}", text(&o));
    assert!(!text(&o).contains("WARNING"), "{}", text(&o));
    // an address of the network (TEST-NET-1, never this machine's: nothing is listened on)
    let o = live(&["--name", "t-live-lan", "--listen", "192.0.2.1:8765"]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let t = text(&o);
    assert!(
        t.contains("WARNING") && t.contains("anyone who can reach this machine"),
        "{t}"
    );
}

#[test]
fn no_run_within_the_wait_fails_and_sigterm_stops_cleanly() {
    let started = Instant::now();
    let o = live(&[
        "--name",
        "t-live-none",
        "--listen",
        "127.0.0.1:0",
        "--wait",
        "0.5",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("did not start within"), "{}", text(&o));
    assert!(started.elapsed() < Duration::from_secs(10));

    let mut child = Command::new(env!("CARGO_BIN_EXE_eqtrack-live"))
        .args(["--name", "t-live-term", "--listen", "127.0.0.1:0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // once it serves (its signal handlers are in place)
    let mut stdout = std::io::BufReader::new(child.stdout.take().unwrap());
    let mut first = String::new();
    std::io::BufRead::read_line(&mut stdout, &mut first).unwrap();
    assert!(
        first.contains("serving run `t-live-term` on ws://127.0.0.1:"),
        "{first}"
    );
    let _ = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status();
    let until = Instant::now() + Duration::from_secs(10);
    while child.try_wait().unwrap().is_none() {
        assert!(Instant::now() < until, "eqtrack-live ignored SIGTERM");
        std::thread::sleep(Duration::from_millis(20));
    }
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut stdout, &mut rest).unwrap();
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(143), "{rest}{}", text(&o));
    let t = format!("{rest}{}", text(&o));
    assert!(
        t.contains("stopped by SIGTERM") && t.contains("0 dropped in all"),
        "{t}"
    );
}
