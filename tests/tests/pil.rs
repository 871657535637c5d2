//! Processor in the loop, with the firmware's cycle on the host (docs/pil.md): a TCP server
//! in this test runs `firmware_cycle::Cycle` from the configuration bytes the firmware is
//! built with, behind the serial protocol, as QEMU's UART would carry it. `plant_sim run
//! --transport tcp:…` drives it. `scripts/pil.sh` does the same with the firmware on the
//! emulated Cortex-M4F.

use eqtrack_serial_wire::{Deframer, Frame, MAX_ENCODED, encode};
use firmware_cycle::{Cycle, MAX_CONFIG};
use pair_tests::{TempDir, plant, serial, summary};
use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::thread::JoinHandle;

/// How the fake firmware misbehaves.
#[derive(Clone, Copy, PartialEq)]
enum Behaviour {
    /// It answers every frame.
    Normal,
    /// Before each reply it writes a burst of seeded random bytes (line noise, a truncated
    /// frame, a frame of another version).
    Garbage,
    /// After answering state `at` it is silent for `silence` states (it resets), then
    /// greets unasked with a fresh cycle.
    ResetAfter { at: u64, silence: u64 },
}

struct Firmware {
    port: u16,
    thread: JoinHandle<(firmware_cycle::Counts, u64)>,
}

fn config_bytes(s: &scenario::Scenario) -> Vec<u8> {
    let mut buf = [0u8; MAX_CONFIG];
    let n = s.firmware_config().unwrap().to_bytes(&mut buf).unwrap();
    buf[..n].to_vec()
}

fn send(stream: &mut TcpStream, frame: &Frame) {
    let mut out = [0u8; MAX_ENCODED];
    let n = encode(frame, &mut out).unwrap();
    // the plant may have gone: the test's assertions are on the plant's side
    let _ = stream.write_all(&out[..n]);
}

/// Starts a fake firmware for `config` on a free port; the thread returns the cycle's
/// counts and the frames it could not decode.
fn firmware(config: Vec<u8>, behaviour: Behaviour) -> Firmware {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let thread = std::thread::spawn(move || {
        let (mut stream, _) = listener.accept().unwrap();
        stream.set_nodelay(true).unwrap();
        let mut cycle = Cycle::from_bytes(&config).unwrap();
        let mut deframer = Deframer::new();
        let mut bad = 0u64;
        let mut rng = 0x2545_f491_4f6c_dd1du64;
        let mut silent_until = None;
        let mut back = false;
        let mut buf = [0u8; 512];
        loop {
            let n = match stream.read(&mut buf) {
                Ok(0) | Err(_) => break,
                Ok(n) => n,
            };
            for b in &buf[..n] {
                let frame = match deframer.push(*b) {
                    None => continue,
                    Some(Err(_)) => {
                        bad += 1;
                        continue;
                    }
                    Some(Ok(f)) => f,
                };
                if let (Behaviour::ResetAfter { at, silence }, Frame::State(s)) =
                    (behaviour, &frame)
                    && !back
                {
                    match silent_until {
                        None if s.seq > at => {
                            silent_until = Some(s.seq + silence);
                            continue;
                        }
                        Some(end) if s.seq < end => continue,
                        Some(_) => {
                            // back from the reset: a fresh cycle, not greeted yet, answers
                            // the state with its Hello
                            cycle = Cycle::from_bytes(&config).unwrap();
                            back = true;
                        }
                        None => {}
                    }
                }
                if behaviour == Behaviour::Garbage {
                    let mut noise = [0u8; 24];
                    for x in &mut noise {
                        rng ^= rng << 13;
                        rng ^= rng >> 7;
                        rng ^= rng << 17;
                        *x = rng as u8;
                    }
                    let _ = stream.write_all(&noise[..(rng % 24) as usize]);
                    let _ = stream.write_all(&[0]);
                    // a truncated frame (a Hello cut short, closed by a zero) and a whole
                    // frame of another protocol version
                    let mut out = [0u8; MAX_ENCODED];
                    let n = encode(&cycle.hello(), &mut out).unwrap();
                    let _ = stream.write_all(&out[..n / 2]);
                    let _ = stream.write_all(&[0]);
                    let n = eqtrack_serial_wire::encode_raw(
                        eqtrack_serial_wire::SERIAL_VERSION + 1,
                        &[4],
                        &mut out,
                    )
                    .unwrap();
                    let _ = stream.write_all(&out[..n]);
                }
                if let Some(reply) = cycle.on_frame(&frame) {
                    send(&mut stream, &reply);
                }
            }
        }
        (cycle.counts(), bad)
    });
    Firmware { port, thread }
}

/// A copy of `scenarios/<name>.toml` lasting `seconds`, with `edit` applied, in `d`
/// (`<name>_<seconds>.toml`; a second copy with another edit needs [`short_as`]).
fn short(d: &TempDir, name: &str, seconds: &str, edit: &dyn Fn(String) -> String) -> String {
    short_as(d, &format!("{name}_{seconds}"), name, seconds, edit)
}

/// [`short`], written to `d/<file>.toml`.
fn short_as(
    d: &TempDir,
    file: &str,
    name: &str,
    seconds: &str,
    edit: &dyn Fn(String) -> String,
) -> String {
    let text = std::fs::read_to_string(pair_tests::scenario(name)).unwrap();
    let (before, after) = text.split_once("duration = ").unwrap();
    let rest = after.split_once('\n').unwrap().1;
    let path = d.join(&format!("{file}.toml"));
    std::fs::write(&path, edit(format!("{before}duration = {seconds}\n{rest}"))).unwrap();
    path
}

fn read(path: &str) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

#[test]
fn pil_in_lockstep_equals_the_in_process_f32_simulation_byte_for_byte() {
    let _g = serial();
    let d = TempDir::new("pil-lockstep");
    // the seed; SE(3); the rejection terms; the estimator on board (the complementary filter
    // on SO(3), the EqF on SE(3)); a vehicle's allocation on SO(3) (thrusters, and four
    // reaction wheels saturating their motors, their speeds in the states) and on SE(3)
    // (rotors, with the EqF and the observer); the failure detector on board (the ROV, a
    // thruster dying unannounced)
    for name in [
        "seed",
        "se3_circle",
        "reject_se3",
        "sensors_so3",
        "eqf_se3",
        "spacecraft",
        "wheels_slew",
        "pil_hexarotor",
        "pil_rov_detect",
    ] {
        let file = short(&d, name, "2.0", &|t| t);
        let s = scenario::Scenario::from_file(std::path::Path::new(&file)).unwrap();
        let fw = firmware(config_bytes(&s), Behaviour::Normal);
        let f32_out = d.join(&format!("{name}-f32"));
        let (code, text) = plant(&[
            "sim",
            "--scenario",
            &file,
            "--controller-scalar",
            "f32",
            "--out",
            &f32_out,
        ]);
        assert_eq!(code, 0, "{text}");
        let pil_out = d.join(&format!("{name}-pil"));
        let tcp = format!("tcp:127.0.0.1:{}", fw.port);
        let (code, text) = plant(&[
            "run",
            "--mode",
            "lockstep",
            "--scenario",
            &file,
            "--transport",
            &tcp,
            "--no-record",
            "--out",
            &pil_out,
        ]);
        assert_eq!(code, 0, "{name}: {text}");
        assert!(text.contains("0 corrupted frames dropped"), "{text}");
        let (counts, bad) = fw.thread.join().unwrap();
        assert_eq!(bad, 0);
        assert_eq!(
            counts.answered,
            s.steps() + 1,
            "{name}: every state answered once"
        );
        let a = read(&format!("{f32_out}/trajectory.csv"));
        let b = read(&format!("{pil_out}/trajectory.csv"));
        assert!(
            a == b,
            "{name}: the PIL run's trajectory.csv differs from the f32 simulation's"
        );
        // the estimate and the allocation came from the controller's side of the link
        let header =
            String::from_utf8_lossy(&a[..a.iter().position(|b| *b == b'\n').unwrap()]).into_owned();
        assert_eq!(
            header.contains("qhat_00"),
            s.filter_settings().unwrap().is_some(),
            "{name}: {header}"
        );
        assert_eq!(header.contains("u_cmd_0"), s.vehicle.is_some(), "{name}");
        if name == "wheels_slew" {
            // the wheels' motors saturated on board, and their speeds came back in the states
            let csv =
                pair_tests::Csv::read(std::path::Path::new(&format!("{pil_out}/trajectory.csv")));
            let status = csv.col("alloc_status");
            assert!(status.contains(&1.0), "{name}: never saturated");
            assert!(
                csv.col("wheel_speed_0").iter().any(|x| x.abs() > 10.0),
                "{name}"
            );
        }
        if s.filter_settings().unwrap().is_some() {
            let csv =
                pair_tests::Csv::read(std::path::Path::new(&format!("{pil_out}/trajectory.csv")));
            let err = csv.col("estimate_error");
            assert!(
                err.iter().all(|e| e.is_finite()) && err[err.len() - 1] < 0.05,
                "{name}: the on-board estimate's error {:?}",
                err.last()
            );
        }
        // and f32 is not f64: the simulation in f64 differs, by f32's rounding
        let f64_out = d.join(&format!("{name}-f64"));
        let (code, text) = plant(&["sim", "--scenario", &file, "--out", &f64_out]);
        assert_eq!(code, 0, "{text}");
        assert!(
            read(&format!("{f64_out}/trajectory.csv")) != a,
            "{name}: f32 equals f64?"
        );
        let (l32, l64) = (
            summary(std::path::Path::new(&f32_out))["final"]["lyapunov"]
                .as_f64()
                .unwrap(),
            summary(std::path::Path::new(&f64_out))["final"]["lyapunov"]
                .as_f64()
                .unwrap(),
        );
        assert!(
            (l32 - l64).abs() <= 1e-3 * l64.abs().max(1e-3),
            "{name}: L {l32} (f32) vs {l64} (f64)"
        );
        if s.fault_detection.is_some() {
            found_on_board(name, &pil_out, &f32_out, &f64_out);
        }
    }
}

/// The detector on board found what the `f64` controller finds: the same findings in the
/// PIL run's and the `f32` simulation's summaries, the scripted failure's actuator and kind
/// within 0.2 s, and the same actuator, kind and time as in `f64`.
fn found_on_board(name: &str, pil: &str, f32_out: &str, f64_out: &str) {
    let found = |dir: &str| summary(std::path::Path::new(dir))["vehicle"]["detections"].clone();
    let (on_board, in_f32, in_f64) = (found(pil), found(f32_out), found(f64_out));
    assert_eq!(on_board, in_f32, "{name}: PIL and f32 findings");
    let first = &on_board[0];
    assert_eq!(
        (first["actuator"].as_u64(), first["kind"].as_str()),
        (Some(1), Some("dead")),
        "{name}: {on_board}"
    );
    let latency = first["latency"].as_f64().unwrap();
    assert!((0.0..=0.2).contains(&latency), "{name}: {on_board}");
    assert_eq!(
        (&in_f64[0]["actuator"], &in_f64[0]["kind"], &in_f64[0]["t"]),
        (&first["actuator"], &first["kind"], &first["t"]),
        "{name}: f64 {in_f64}"
    );
}

#[test]
fn a_fingerprint_mismatch_is_refused_on_both_sides() {
    let _g = serial();
    let d = TempDir::new("pil-mismatch");
    let file = short(&d, "seed", "1.0", &|t| t);
    let other = short_as(&d, "other", "seed", "1.0", &|t| {
        t.replace("kd = 0.5", "kd = 0.6")
    });
    assert_ne!(read(&file), read(&other));
    let built = scenario::Scenario::from_file(std::path::Path::new(&other)).unwrap();
    let fw = firmware(config_bytes(&built), Behaviour::Normal);
    let tcp = format!("tcp:127.0.0.1:{}", fw.port);
    let (code, text) = plant(&[
        "run",
        "--mode",
        "lockstep",
        "--scenario",
        &file,
        "--transport",
        &tcp,
        "--no-record",
        "--out",
        &d.join("out"),
    ]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("configuration mismatch (scenario)"), "{text}");
    let (counts, _) = fw.thread.join().unwrap();
    assert_eq!(counts.refused, 1, "the firmware refused the plant's Hello");
    assert_eq!(counts.answered, 0, "and answered no state");
}

/// The seed at a 20 ms period: real time under a loaded test machine.
fn slow_seed(d: &TempDir, seconds: &str) -> String {
    short(d, "seed", seconds, &|t| {
        t.replace("control_period = 0.01", "control_period = 0.02")
    })
}

fn realtime(
    d: &TempDir,
    file: &str,
    port: u16,
    extra: &[&str],
) -> (i32, String, serde_json::Value) {
    let out = d.join("rt");
    let tcp = format!("tcp:127.0.0.1:{port}");
    let mut args = vec![
        "run",
        "--mode",
        "realtime",
        "--rate-hz",
        "50",
        "--scenario",
        file,
        "--transport",
        &tcp,
        "--no-record",
        "--out",
        &out,
    ];
    args.extend_from_slice(extra);
    let (code, text) = plant(&args);
    let s = if code == 0 {
        summary(std::path::Path::new(&out))
    } else {
        serde_json::Value::Null
    };
    (code, text, s)
}

#[test]
fn a_corrupted_frame_is_caught_by_the_crc_counted_and_treated_as_a_missing_command() {
    let _g = serial();
    let d = TempDir::new("pil-corrupt");
    let file = slow_seed(&d, "2.0");
    let s = scenario::Scenario::from_file(std::path::Path::new(&file)).unwrap();
    let fw = firmware(config_bytes(&s), Behaviour::Normal);
    // frame 12: the command of state 10
    let (code, text, summ) = realtime(&d, &file, fw.port, &["--fault-corrupt-frame", "12"]);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("1 corrupted frames dropped"), "{text}");
    assert!(summ["deadline_misses"].as_u64().unwrap() >= 1, "{summ}");
    assert_eq!(summ["commands_rejected"], 0);
    assert_eq!(
        summ["cycles"].as_u64().unwrap(),
        101,
        "the run went on to its end"
    );
    fw.thread.join().unwrap();
}

#[test]
fn a_firmware_reset_enters_safe_mode_and_the_handshake_brings_it_back() {
    let _g = serial();
    let d = TempDir::new("pil-reset");
    let file = slow_seed(&d, "3.0");
    let s = scenario::Scenario::from_file(std::path::Path::new(&file)).unwrap();
    let fw = firmware(
        config_bytes(&s),
        Behaviour::ResetAfter {
            at: 40,
            silence: 15,
        },
    );
    let (code, text, summ) = realtime(&d, &file, fw.port, &[]);
    let (counts, _) = fw.thread.join().unwrap();
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("1 firmware resets"), "{text}");
    assert!(summ["safe_mode_entries"].as_u64().unwrap() >= 1, "{summ}");
    let safe = summ["safe_mode_cycles"].as_u64().unwrap();
    assert!(
        (3..60).contains(&safe),
        "safe mode for {safe} cycles: it must end after the reset\n{counts:?}\n{text}\n{summ}"
    );
    // states 41 to 55 go unanswered (the reset), state 56 is answered with the fresh
    // cycle's Hello, and 57 to 150 with commands
    assert_eq!(
        counts.answered, 94,
        "the reset firmware answers every state after the handshake: {counts:?}"
    );
}

#[test]
fn garbage_on_the_line_never_panics_either_side() {
    let _g = serial();
    let d = TempDir::new("pil-garbage");
    let file = slow_seed(&d, "2.0");
    let s = scenario::Scenario::from_file(std::path::Path::new(&file)).unwrap();
    let fw = firmware(config_bytes(&s), Behaviour::Garbage);
    let (code, text, summ) = realtime(&d, &file, fw.port, &[]);
    assert_eq!(code, 0, "{text}");
    assert_eq!(summ["cycles"].as_u64().unwrap(), 101, "{summ}");
    let dropped: u64 = text
        .split(" corrupted frames dropped")
        .next()
        .and_then(|t| t.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no count in {text}"));
    // before each of its ~100 replies: a noise burst (when not empty), a truncated frame
    // and a frame of another version, each refused and counted
    assert!(
        dropped >= 180,
        "the noise bursts, truncated frames and other versions were counted as corrupted frames: {dropped}\n{text}"
    );
    fw.thread.join().unwrap();
}

#[test]
fn bad_transports_and_scenarios_the_firmware_cannot_run_are_refused_naming_them() {
    let d = TempDir::new("pil-bad");
    for (args, says) in [
        (
            vec!["run", "--transport", "udp:1.2.3.4:5"],
            "expected iceoryx2, uds, tcp:HOST:PORT or serial:PATH[@BAUD]",
        ),
        (
            vec!["run", "--transport", "tcp:nohost"],
            "expected tcp:HOST:PORT",
        ),
        (
            vec!["run", "--transport", "serial:/dev/ttyX@fast"],
            "`fast` is not a baud rate",
        ),
    ] {
        let (code, text) = plant(&args);
        assert_eq!(code, 2, "{args:?}: {text}");
        assert!(text.contains(says), "{args:?}: {text}");
    }
    for (name, key) in [
        ("slew_so3", "key `reference`"),
        ("rov_failure", "key `reference`"),
    ] {
        let file = pair_tests::scenario(name);
        let (code, text) = plant(&[
            "sim",
            "--scenario",
            &file,
            "--controller-scalar",
            "f32",
            "--out",
            &d.join(name),
        ]);
        assert_eq!(code, 2, "{name}: {text}");
        assert!(
            text.contains(key) && text.contains("processor-in-the-loop"),
            "{name}: {text}"
        );
        let (code, text) = plant(&[
            "pil-config",
            "--scenario",
            &file,
            "--out",
            &d.join(&format!("{name}.config")),
        ]);
        assert_eq!(code, 2, "{name}: {text}");
    }
    // a firmware that is not there: a clear error, exit 1
    let (code, text) = plant(&[
        "run",
        "--mode",
        "lockstep",
        "--transport",
        "tcp:127.0.0.1:1",
        "--out",
        &d.join("none"),
    ]);
    assert_eq!(code, 1, "{text}");
    assert!(
        text.contains("connecting to the firmware at tcp:127.0.0.1:1"),
        "{text}"
    );
}

#[test]
fn the_instruction_count_firmware_carries_pil_hexarotors_configuration() {
    // scripts/cortex-m.sh counts one processor-in-the-loop cycle of pil_hexarotor, the
    // failure detector's cycle on pil_rov_detect's ROV and wheels_slew's cycle on its
    // reaction wheels, from these bytes: they must be the
    // scenarios', as `plant_sim pil-config` writes them
    for name in ["pil_hexarotor", "pil_rov_detect", "wheels_slew"] {
        let file = pair_tests::scenario(name);
        let s = scenario::Scenario::from_file(std::path::Path::new(&file)).unwrap();
        let committed = read(&format!(
            "{}/../embedded/firmware-cortex-m/{name}.config",
            env!("CARGO_MANIFEST_DIR")
        ));
        assert!(
            config_bytes(&s) == committed,
            "embedded/firmware-cortex-m/{name}.config is stale: plant_sim pil-config \
             --scenario scenarios/{name}.toml --out embedded/firmware-cortex-m/{name}.config"
        );
    }
}

/// A greeting starts a run afresh, the failure detector and the failures told included:
/// `pil_rov_detect` with thruster 3 told stuck at 5 N from 0.5 s, 150 states (the detector
/// tests from the 120th), then a `Hello` and the same 150 states again give the same
/// commands, bit for bit.
#[test]
fn a_greeting_starts_the_detector_and_the_told_failures_afresh() {
    let text = std::fs::read_to_string(pair_tests::scenario("pil_rov_detect")).unwrap();
    let text = format!(
        "{text}\n[[vehicle.failure]]\nactuator = 3\nt = 0.5\nvalue = 5.0\nreconfigure = true\n"
    );
    let s = scenario::Scenario::from_toml(&text, "restart", "restart").unwrap();
    let mut cycle = Cycle::from_bytes(&config_bytes(&s)).unwrap();
    let pass = |cycle: &mut Cycle| {
        let hello = cycle.hello();
        assert!(matches!(cycle.on_frame(&hello), Some(Frame::Hello(_))));
        let mut applied = vec![0.0f32; 6];
        let mut commands = Vec::new();
        for k in 0..150u64 {
            let t = k as f64 * 0.01;
            let mut q = [0.0f32; 16];
            for i in 0..4 {
                q[5 * i] = 1.0;
            }
            let v = [
                0.0,
                0.0,
                0.05 * (2.0 * t).sin(),
                0.2 * (3.0 * t).sin(),
                0.1,
                0.0,
            ];
            let state = eqtrack_serial_wire::StateFrame {
                seq: k,
                t,
                q: q.iter().copied().collect(),
                v: v.iter().map(|x| *x as f32).collect(),
                applied: applied.iter().copied().collect(),
                samples: None,
                wheel_speeds: Default::default(),
            };
            let Some(Frame::Command(c)) = cycle.on_frame(&Frame::State(state)) else {
                panic!("state {k}: no command");
            };
            applied = c.allocation.as_ref().unwrap().accounted.to_vec();
            commands.push(c);
        }
        commands
    };
    let first = pass(&mut cycle);
    let second = pass(&mut cycle);
    assert!(first == second, "the second run differs from the first");
    let u3 = |c: &eqtrack_serial_wire::CommandFrame| c.allocation.as_ref().unwrap().u_cmd[3];
    assert_ne!(u3(&first[40]), 5.0, "told before its time");
    assert_eq!(u3(&first[60]), 5.0, "not held at the told value");
    let detection = |c: &eqtrack_serial_wire::CommandFrame| c.detection.unwrap();
    assert_eq!(
        detection(&first[100]).suspect,
        0,
        "testing while calibrating"
    );
    assert!(
        detection(&first[140]).suspect > 0,
        "not testing once calibrated"
    );
}

/// Flies scenario `file` three ways into `d`: the firmware's code in process (`f32`), the
/// firmware over the serial protocol in lockstep (PIL), and the `f64` simulation. Asserts the
/// PIL run equals the `f32` one byte for byte, and returns the PIL run's directory and
/// output, and the `f64` run's directory.
fn f32_pil_f64(d: &TempDir, file: &str) -> (String, String, String) {
    let s = scenario::Scenario::from_file(std::path::Path::new(file)).unwrap();
    let fw = firmware(config_bytes(&s), Behaviour::Normal);
    let (f32_out, pil_out, f64_out) = (d.join("f32"), d.join("pil"), d.join("f64"));
    let (code, text) = plant(&[
        "sim",
        "--scenario",
        file,
        "--controller-scalar",
        "f32",
        "--out",
        &f32_out,
    ]);
    assert_eq!(code, 0, "{text}");
    let tcp = format!("tcp:127.0.0.1:{}", fw.port);
    let (code, pil_text) = plant(&[
        "run",
        "--mode",
        "lockstep",
        "--scenario",
        file,
        "--transport",
        &tcp,
        "--no-record",
        "--out",
        &pil_out,
    ]);
    assert_eq!(code, 0, "{pil_text}");
    let (_, bad) = fw.thread.join().unwrap();
    assert_eq!(bad, 0);
    assert!(
        read(&format!("{f32_out}/trajectory.csv")) == read(&format!("{pil_out}/trajectory.csv")),
        "the PIL run's trajectory.csv differs from the f32 simulation's"
    );
    let (code, text) = plant(&["sim", "--scenario", file, "--out", &f64_out]);
    assert_eq!(code, 0, "{text}");
    (pil_out, pil_text, f64_out)
}

/// The failsafe manager on board (docs/failsafe.md): `pil_rov_surface`'s ROV loses two
/// horizontal thrusters unannounced; the firmware's detector finds both, its manager raises
/// `actuators` and flies `surface`. The PIL run equals the in-process `f32` simulation byte for
/// byte, the transition is the `f64` simulation's at the same tick, and the ROV rises at the
/// set rate.
#[test]
fn the_failsafe_manager_runs_on_board_and_surfaces_the_rov_as_the_f64_simulation_does() {
    let _g = serial();
    let d = TempDir::new("pil-failsafe");
    let file = short(&d, "pil_rov_surface", "5.0", &|t| t);
    let (pil_out, text, f64_out) = f32_pil_f64(&d, &file);
    assert!(
        text.contains("failsafe: t = 2.57 s: actuators → surface"),
        "{text}"
    );
    let transitions = |dir: &str| summary(std::path::Path::new(dir))["failsafe"].clone();
    assert_eq!(transitions(&pil_out), transitions(&f64_out));
    assert_eq!(
        transitions(&pil_out),
        serde_json::json!([{ "t": 2.57, "cause": "actuators", "action": "surface" }])
    );
    // rising at the set rate after the transient, level, the failsafe column saying so
    let csv = pair_tests::Csv::read(std::path::Path::new(&format!("{pil_out}/trajectory.csv")));
    let (t, z, rzz, code) = (
        csv.col("t"),
        csv.col("q_23"),
        csv.col("q_22"),
        csv.col("failsafe"),
    );
    let at = |time: f64| t.iter().position(|x| *x >= time - 1e-9).unwrap();
    let (a, b) = (at(3.5), t.len() - 1);
    let rate = (z[b] - z[a]) / (t[b] - t[a]);
    assert!((rate - 0.3).abs() < 0.03, "rises at {rate} m/s");
    assert!(rzz[at(2.57)..].iter().all(|r| *r > 0.97), "tilted");
    assert!(code[..at(2.57)].iter().all(|c| *c == 0.0));
    assert!(code[at(2.57)..].iter().all(|c| *c == 5.0));
}

/// The innovation gate on board: `pil_hexarotor` with `gate = true`, its position fixes lost
/// from 2 s to 4 s, `estimator = "hold"`. The firmware's filter runs the gate, its health
/// degrades a window after the last fix, and the manager on board holds, then flies on: the
/// same transitions at the same ticks as the `f64` simulation, and the run equals the
/// in-process `f32` simulation byte for byte.
#[test]
fn the_innovation_gate_runs_on_board_and_the_manager_holds_on_its_health() {
    let _g = serial();
    let d = TempDir::new("pil-gate");
    let file = short(&d, "pil_hexarotor", "6.0", &|t| {
        t.replace("accel_gate = 1.0", "accel_gate = 1.0\ngate = true")
            .replace(
                "[estimator]",
                "[[sensors.fault]]\nsensor = \"position\"\nt = 2.0\nduration = 2.0\n\
                 kind = \"dropout\"\n\n[estimator]",
            )
            + "\n[failsafe]\nestimator = \"hold\"\n"
    });
    let (pil_out, _, f64_out) = f32_pil_f64(&d, &file);
    let transitions = |dir: &str| summary(std::path::Path::new(dir))["failsafe"].clone();
    assert_eq!(transitions(&pil_out), transitions(&f64_out));
    assert_eq!(
        transitions(&pil_out),
        serde_json::json!([
            { "t": 2.48, "cause": "estimator", "action": "hold" },
            { "t": 4.998, "cause": null, "action": "nominal" }
        ])
    );
}
