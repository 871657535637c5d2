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
    assert_eq!(s["realtime"]["plant"]["applied"][0], "cpu 0", "{s}");
    assert_eq!(
        s["realtime"]["plant"]["cpus_allowed"],
        serde_json::json!([0]),
        "{s}"
    );
    assert_eq!(
        s["realtime"]["plant"]["refused"],
        serde_json::json!([]),
        "{s}"
    );
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
    let refused = s["realtime"]["plant"]["refused"].as_array().unwrap();
    assert!(
        refused
            .iter()
            .any(|r| r["setting"] == "cpu" && r["reason"].as_str().unwrap().contains("EINVAL")),
        "{s}"
    );
    assert!(s["cycles"].as_u64().unwrap() >= 1000, "{s}");
    // SCHED_FIFO 99 needs CAP_SYS_NICE or RLIMIT_RTPRIO: whichever happened is recorded,
    // and what is read back agrees with it
    let fifo_applied = s["realtime"]["plant"]["applied"]
        .as_array()
        .unwrap()
        .iter()
        .any(|a| a == "SCHED_FIFO priority 99");
    let fifo_refused = refused.iter().any(|r| r["setting"] == "rt-priority");
    assert!(fifo_applied ^ fifo_refused, "{s}");
    assert_eq!(
        s["realtime"]["plant"]["scheduler"] == "SCHED_FIFO 99",
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
    // the watchdogs (docs/pair-on-a-board.md, "Watchdogs"): both notify, the controller is
    // restarted on a failure or its watchdog, the plant on its watchdog only
    // (whole lines: a key commented out, or one inside another's value, does not count)
    let controller = std::fs::read_to_string(&units[0]).unwrap();
    let plant = std::fs::read_to_string(&units[1]).unwrap();
    let has = |text: &str, key: &str| {
        text.lines()
            .any(|l| l.trim_end() == key || (key.ends_with('=') && l.starts_with(key)))
    };
    for text in [&controller, &plant] {
        for key in [
            "Type=notify",
            "WatchdogSec=500ms",
            "RestartSec=",
            "StartLimitBurst=",
        ] {
            assert!(has(text, key), "no {key}:\n{text}");
        }
    }
    assert!(has(&controller, "Restart=on-failure"), "{controller}");
    // a configuration the controller refuses (exit 2) is not restarted over and over
    assert!(
        has(&controller, "RestartPreventExitStatus=2"),
        "{controller}"
    );
    assert!(has(&plant, "Restart=on-watchdog"), "{plant}");
    assert!(!has(
        &controller.replace("Type=notify", "# Type=notify"),
        "Type=notify"
    ));
    // and the check can fail: systemd-analyze names a bad value (it exits 0 all the same)
    for (unit, from, to) in [
        (0, "WatchdogSec=500ms", "WatchdogSec=banana"),
        (1, "Restart=on-watchdog", "Restart=sometimes"),
    ] {
        let text = std::fs::read_to_string(&units[unit]).unwrap();
        let planted = d.join(&format!("planted-{unit}.service"));
        std::fs::write(&planted, text.replace(from, to)).unwrap();
        let out = std::process::Command::new("systemd-analyze")
            .arg("verify")
            .arg(&planted)
            .output()
            .unwrap();
        let said = String::from_utf8_lossy(&out.stderr);
        assert!(said.contains(to.split('=').nth(1).unwrap()), "{to}: {said}");
    }
}

/// The pid in the plant's `started controller_node (pid N)` line.
fn spawned_pid(plant: &Proc) -> u32 {
    assert!(
        plant.wait_for_line("controller connected", Duration::from_secs(20)),
        "{}",
        plant.output()
    );
    plant
        .output()
        .lines()
        .find_map(|l| l.split("started controller_node (pid ").nth(1))
        .and_then(|rest| rest.split(')').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no controller pid in:\n{}", plant.output()))
}

/// `chrt -p PID` (sched_getscheduler and sched_getparam): the policy and priority.
fn policy(pid: u32) -> (String, u32) {
    let out = std::process::Command::new("chrt")
        .args(["-p", &pid.to_string()])
        .output()
        .expect("chrt (util-linux)");
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    let after = |key: &str| {
        text.lines()
            .find_map(|l| l.split(key).nth(1))
            .map(|s| s.trim().to_owned())
            .unwrap_or_else(|| panic!("chrt -p {pid}: {text}"))
    };
    (
        after("scheduling policy:"),
        after("scheduling priority:").parse().unwrap(),
    )
}

/// `VmLck` of a running process (kB), from /proc: non-zero once mlockall has locked pages.
fn locked_kb(pid: u32) -> u64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .unwrap_or_default()
        .lines()
        .find_map(|l| l.strip_prefix("VmLck:"))
        .and_then(|s| s.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap_or(0)
}

/// Whether this machine grants SCHED_FIFO to this test's processes (root or CAP_SYS_NICE).
fn fifo_granted() -> bool {
    std::process::Command::new("chrt")
        .args(["-f", "80", "true"])
        .status()
        .is_ok_and(|s| s.success())
}

#[test]
fn plant_sim_run_gives_the_controller_it_starts_the_same_settings_and_its_own_cpus() {
    let _g = serial();
    let fifo = fifo_granted();
    for (extra, plant_cpus, controller_cpus) in [
        (&[][..], "0", "0"),
        (&["--controller-cpu", "1"][..], "0", "1"),
    ] {
        let d = TempDir::new("rt-spawned");
        let out = d.join("run");
        let mut args = vec![
            "run",
            "--duration",
            "1.5",
            "--name",
            "t-rt-spawned",
            "--out",
            &out,
            "--rt-priority",
            "80",
            "--lock-memory",
            "--cpu",
            "0",
        ];
        args.extend_from_slice(extra);
        let mut plant = Proc::start("plant_sim", &args);
        let cp = spawned_pid(&plant);
        let pp = plant.pid().unwrap();
        // read back from the kernel while both run
        assert_eq!(cpus_allowed(pp), plant_cpus, "{extra:?}: the plant's CPUs");
        assert_eq!(
            cpus_allowed(cp),
            controller_cpus,
            "{extra:?}: the controller's CPUs"
        );
        if fifo {
            assert_eq!(policy(cp), ("SCHED_FIFO".to_owned(), 80), "{extra:?}");
            assert_eq!(policy(pp), ("SCHED_FIFO".to_owned(), 80), "{extra:?}");
        }
        let locked = locked_kb(cp);
        assert_eq!(
            plant
                .wait_timeout(Duration::from_secs(30))
                .and_then(|s| s.code()),
            Some(0),
            "{}",
            plant.output()
        );
        let s = summary(Path::new(&out));
        let (p, c) = (&s["realtime"]["plant"], &s["realtime"]["controller"]);
        assert_eq!(c["pid"], cp, "{s}");
        assert_eq!(p["pid"], pp, "{s}");
        assert_eq!(
            p["cpus_allowed"],
            serde_json::json!([plant_cpus.parse::<u32>().unwrap()]),
            "{s}"
        );
        assert_eq!(
            c["cpus_allowed"],
            serde_json::json!([controller_cpus.parse::<u32>().unwrap()]),
            "{s}"
        );
        assert!(
            c["applied"]
                .as_array()
                .unwrap()
                .contains(&serde_json::json!(format!("cpu {controller_cpus}"))),
            "{s}"
        );
        let memory_locked = c["applied"]
            .as_array()
            .unwrap()
            .iter()
            .any(|a| a.as_str().unwrap().starts_with("memory locked"));
        assert_eq!(memory_locked, locked > 0, "VmLck {locked} kB; {s}");
        if fifo {
            for r in [p, c] {
                assert_eq!(r["scheduler"], "SCHED_FIFO 80", "{s}");
                assert_eq!(r["refused"], serde_json::json!([]), "{s}");
            }
            assert!(memory_locked, "{s}");
        } else {
            eprintln!("SCHED_FIFO is refused here: checking that both processes record it");
            for r in [p, c] {
                assert!(
                    r["refused"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .any(|x| x["setting"] == "rt-priority"),
                    "{s}"
                );
            }
        }
    }
}

#[test]
fn settings_the_os_refuses_the_spawned_controller_are_warnings_in_the_summary() {
    let _g = serial();
    let d = TempDir::new("rt-ctl-refused");
    let out = d.join("run");
    // without CAP_SYS_NICE (and with the default RLIMIT_RTPRIO of 0) SCHED_FIFO is refused,
    // even to root; CPU 1000 does not exist
    let setpriv = std::path::Path::new("/usr/bin/setpriv");
    let plant_sim = pair_tests::bin("plant_sim");
    let plant_sim = plant_sim.to_str().unwrap();
    let mut plant = Proc::start_path(
        setpriv,
        &[
            "--inh-caps=-sys_nice",
            "--bounding-set=-sys_nice",
            plant_sim,
            "run",
            "--duration",
            "1",
            "--name",
            "t-rt-ctl-refused",
            "--out",
            &out,
            "--rt-priority",
            "80",
            "--controller-cpu",
            "1000",
        ],
    );
    let status = plant.wait_timeout(Duration::from_secs(30));
    let o = plant.output();
    assert_eq!(
        status.and_then(|s| s.code()),
        Some(0),
        "the run goes on:\n{o}"
    );
    assert!(
        o.contains("controller_node: real-time settings: warning: --cpu refused (EINVAL"),
        "{o}"
    );
    assert!(
        o.contains("controller's real-time settings: warning: --rt-priority refused (EPERM"),
        "{o}"
    );
    let s = summary(Path::new(&out));
    assert!(s["cycles"].as_u64().unwrap() >= 1000, "{s}");
    let refused = |who: &str| -> Vec<(String, String)> {
        s["realtime"][who]["refused"]
            .as_array()
            .unwrap_or_else(|| panic!("{who}: {s}"))
            .iter()
            .map(|r| {
                (
                    r["setting"].as_str().unwrap().to_owned(),
                    r["reason"].as_str().unwrap().to_owned(),
                )
            })
            .collect()
    };
    let c = refused("controller");
    assert!(
        c.iter()
            .any(|(k, why)| k == "cpu" && why.contains("EINVAL")),
        "{s}"
    );
    assert!(
        c.iter()
            .any(|(k, why)| k == "rt-priority" && why.contains("EPERM")),
        "{s}"
    );
    // the plant asked for no CPU: only its priority was refused
    assert_eq!(
        refused("plant"),
        vec![("rt-priority".to_owned(), refused("plant")[0].1.clone())],
        "{s}"
    );
    assert_ne!(
        s["realtime"]["controller"]["scheduler"], "SCHED_FIFO 80",
        "{s}"
    );
}

#[test]
fn controller_cpu_needs_a_spawned_controller() {
    let (code, out) = pair_tests::run(
        "plant_sim",
        &["run", "--no-spawn", "--controller-cpu", "1"],
        Duration::from_secs(20),
    );
    assert_eq!(code, 2, "{out}");
    assert!(out.contains("--controller-cpu"), "{out}");
}
