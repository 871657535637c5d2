//! The real-time settings of both binaries (`--rt-priority`, `--cpu`, `--lock-memory`):
//! applied ones take effect (read back from /proc), refused ones are warnings and the run goes
//! on, and `summary.json` records both. Tests run one at a time ([`serial`]).

use pair_tests::{Proc, TempDir, serial, summary};
use std::path::Path;
use std::time::Duration;

/// `Cpus_allowed_list` of a running process, from /proc.
fn cpus_allowed(pid: u32) -> String {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .unwrap_or_default()
        .lines()
        .find_map(|l| l.strip_prefix("Cpus_allowed_list:"))
        .map(|s| s.trim().to_owned())
        .unwrap_or_default()
}

#[test]
fn cpu_0_pins_both_processes_and_the_summary_records_it() {
    let _g = serial();
    let d = TempDir::new("rt-pin");
    let out = d.join("run");
    let mut plant = Proc::start(
        "plant_sim",
        &[
            "run",
            "--no-spawn",
            "--duration",
            "1.5",
            "--name",
            "t-rt-pin",
            "--out",
            &out,
            "--cpu",
            "0",
        ],
    );
    let mut ctl = Proc::start(
        "controller_node",
        &["--name", "t-rt-pin", "--cpu", "0", "--lock-memory"],
    );
    assert!(
        plant.wait_for_line("controller connected", Duration::from_secs(20)),
        "{}",
        plant.output()
    );
    std::thread::sleep(Duration::from_millis(300));
    let (pp, cp) = (plant.pid().unwrap(), ctl.pid().unwrap());
    assert_eq!(cpus_allowed(pp), "0", "the plant is pinned to CPU 0");
    assert_eq!(cpus_allowed(cp), "0", "the controller is pinned to CPU 0");
    assert_eq!(
        plant
            .wait_timeout(Duration::from_secs(30))
            .and_then(|s| s.code()),
        Some(0),
        "{}",
        plant.output()
    );
    assert_eq!(
        ctl.wait_timeout(Duration::from_secs(5))
            .and_then(|s| s.code()),
        Some(0),
        "{}",
        ctl.output()
    );
    assert!(
        plant
            .output()
            .contains("real-time settings: applied: cpu 0"),
        "{}",
        plant.output()
    );
    let c = ctl.output();
    assert!(c.contains("real-time settings: applied: cpu 0"), "{c}");
    // mlockall needs CAP_IPC_LOCK or RLIMIT_MEMLOCK: either applied or a warning with a reason
    assert!(
        c.contains("applied: memory locked") || c.contains("warning: --lock-memory refused ("),
        "{c}"
    );
    let s = summary(Path::new(&out));
    assert_eq!(s["realtime"]["applied"][0], "cpu 0", "{s}");
    assert_eq!(s["realtime"]["cpus_allowed"], serde_json::json!([0]), "{s}");
    assert_eq!(s["realtime"]["refused"], serde_json::json!([]), "{s}");
}

#[test]
fn impossible_settings_warn_and_the_run_goes_on() {
    let _g = serial();
    let d = TempDir::new("rt-refused");
    let out = d.join("run");
    let mut plant = Proc::start(
        "plant_sim",
        &[
            "run",
            "--duration",
            "1",
            "--name",
            "t-rt-refused",
            "--out",
            &out,
            "--cpu",
            "1000",
            "--rt-priority",
            "99",
        ],
    );
    let status = plant.wait_timeout(Duration::from_secs(30));
    let o = plant.output();
    assert_eq!(
        status.and_then(|s| s.code()),
        Some(0),
        "the run goes on:\n{o}"
    );
    assert!(o.contains("warning: --cpu refused (EINVAL"), "{o}");
    let s = summary(Path::new(&out));
    let refused = s["realtime"]["refused"].as_array().unwrap();
    assert!(
        refused
            .iter()
            .any(|r| r["setting"] == "cpu" && r["reason"].as_str().unwrap().contains("EINVAL")),
        "{s}"
    );
    assert!(s["cycles"].as_u64().unwrap() >= 1000, "{s}");
    // SCHED_FIFO 99 needs CAP_SYS_NICE or RLIMIT_RTPRIO: whichever happened is recorded,
    // and what is read back agrees with it
    let fifo_applied = s["realtime"]["applied"]
        .as_array()
        .unwrap()
        .iter()
        .any(|a| a == "SCHED_FIFO priority 99");
    let fifo_refused = refused.iter().any(|r| r["setting"] == "rt-priority");
    assert!(fifo_applied ^ fifo_refused, "{s}");
    assert_eq!(
        s["realtime"]["scheduler"] == "SCHED_FIFO 99",
        fifo_applied,
        "{s}"
    );
    eprintln!(
        "rt-priority 99 here: {}",
        if fifo_applied { "applied" } else { "refused" }
    );
}

#[test]
fn bad_real_time_arguments_are_clear_errors() {
    for (args, needle) in [
        (
            &["--rt-priority", "0"][..],
            "invalid value '0' for '--rt-priority",
        ),
        (
            &["--rt-priority", "100"][..],
            "invalid value '100' for '--rt-priority",
        ),
        (&["--cpu", "3-1"][..], "upwards"),
        (&["--cpu", "x"][..], "`x`"),
    ] {
        for bin in ["plant_sim", "controller_node"] {
            let mut full: Vec<&str> = if bin == "plant_sim" {
                vec!["run"]
            } else {
                vec![]
            };
            full.extend_from_slice(args);
            let (code, out) = pair_tests::run(bin, &full, Duration::from_secs(20));
            assert_eq!(code, 2, "{bin} {full:?}: {out}");
            assert!(out.contains(needle), "{bin} {full:?}: {out}");
        }
    }
}

#[test]
fn the_systemd_units_verify_against_the_built_binaries() {
    let d = TempDir::new("units");
    let deploy = concat!(env!("CARGO_MANIFEST_DIR"), "/../deploy");
    let bin_dir = pair_tests::bin("plant_sim")
        .parent()
        .unwrap()
        .display()
        .to_string();
    let mut units = Vec::new();
    for name in ["eqtrack-controller.service", "eqtrack-plant.service"] {
        let text = std::fs::read_to_string(format!("{deploy}/{name}")).unwrap();
        for key in [
            "CPUAffinity=",
            "LimitRTPRIO=",
            "LimitMEMLOCK=",
            "--rt-priority",
            "--cpu",
        ] {
            assert!(text.contains(key), "{name} lacks {key}");
        }
        let path = d.join(name);
        std::fs::write(&path, text.replace("/opt/eqtrack", &bin_dir)).unwrap();
        units.push(path);
    }
    let out = std::process::Command::new("systemd-analyze")
        .arg("verify")
        .args(&units)
        .output()
        .expect("systemd-analyze (systemd) is needed to check the units");
    let text =
        String::from_utf8_lossy(&out.stderr).to_string() + &String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && text.trim().is_empty(),
        "systemd-analyze verify:\n{text}"
    );
    let controller = std::fs::read_to_string(&units[0]).unwrap();
    assert!(controller.contains("Restart=always"));
}
