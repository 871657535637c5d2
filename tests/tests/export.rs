//! `plant_sim export`: a run's flight recording to MCAP, read back with the `mcap` crate (a
//! reader this project did not write), against the project's own reading of the log; a log
//! cut short by a SIGKILL exports up to its last whole record; a log of another format
//! version is refused with both versions named. The Python and TypeScript readers run in
//! `scripts/mcap-readers.sh` (CI). Tests run one at a time ([`serial`]).

use pair_tests::{Proc, TempDir, run, scenario, serial, wait_for_cycles};
use recorder::{HEADER_BYTES, LOG_FILE, LogReader, RECORD_BYTES};
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;

const LONG: Duration = Duration::from_secs(120);

/// What the `mcap` crate reads back: messages per topic, log times in file order, and the
/// distinct (schema encoding, message encoding) pairs.
#[derive(Default)]
struct ReadBack {
    topics: BTreeMap<String, u64>,
    times: Vec<u64>,
    encodings: Vec<(String, String)>,
}

/// Reads `path` with the `mcap` crate (which checks the CRCs it finds).
fn read_mcap(path: &Path) -> ReadBack {
    let bytes = std::fs::read(path).unwrap();
    let ReadBack {
        mut topics,
        mut times,
        mut encodings,
    } = ReadBack::default();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        *topics.entry(m.channel.topic.clone()).or_default() += 1;
        times.push(m.log_time);
        let schema = m
            .channel
            .schema
            .as_ref()
            .map_or("", |s| s.encoding.as_str());
        let pair = (schema.to_owned(), m.channel.message_encoding.clone());
        if !encodings.contains(&pair) {
            encodings.push(pair);
        }
    }
    ReadBack {
        topics,
        times,
        encodings,
    }
}

/// A lockstep run of `plant_sim run` for `seconds` into `out`, with `extra` arguments.
fn lockstep(name: &str, out: &str, seconds: &str, extra: &[&str]) {
    let mut args = vec![
        "run",
        "--mode",
        "lockstep",
        "--duration",
        seconds,
        "--name",
        name,
        "--out",
        out,
    ];
    args.extend_from_slice(extra);
    let (code, text) = run("plant_sim", &args, LONG);
    assert_eq!(code, 0, "{text}");
}

fn records(dir: &str) -> u64 {
    LogReader::open(&Path::new(dir).join(LOG_FILE))
        .unwrap()
        .records
}

#[test]
fn a_run_exports_to_mcap_with_one_message_per_channel_and_cycle() {
    let _g = serial();
    let d = TempDir::new("export");
    // the observer's scenario, so the terms channel is there too
    let out = d.join("lock");
    lockstep(
        "t-export",
        &out,
        "2",
        &["--scenario", &scenario("reject_so3")],
    );
    let (code, text) = run("plant_sim", &["export", &out], LONG);
    assert_eq!(code, 0, "{text}");
    let n = records(&out);
    assert!(text.contains(&format!("exported {n} records")), "{text}");
    let ReadBack {
        topics,
        times,
        encodings,
    } = read_mcap(&Path::new(&out).join("run.mcap"));
    eprintln!("{n} records: {topics:?}");
    for topic in [
        "/eqtrack/state",
        "/eqtrack/cycle",
        "/eqtrack/command",
        "/eqtrack/terms",
    ] {
        assert_eq!(topics.get(topic), Some(&n), "{topic}: {topics:?}");
    }
    assert!(times.windows(2).all(|w| w[0] <= w[1]), "log_time decreases");
    // the last sample time: 2 s
    assert_eq!(times.last(), Some(&2_000_000_000));
    assert_eq!(encodings, vec![("ros2msg".to_owned(), "cdr".to_owned())]);
    // the JSONL form holds the same messages
    let (code, text) = run("plant_sim", &["export", &out, "--format", "jsonl"], LONG);
    assert_eq!(code, 0, "{text}");
    let lines = std::fs::read_to_string(Path::new(&out).join("run.jsonl")).unwrap();
    assert_eq!(lines.lines().count() as u64, 4 * n);
    // the seed has no terms: no terms channel
    let out = d.join("seed");
    lockstep("t-export-seed", &out, "1", &[]);
    let (code, text) = run("plant_sim", &["export", &out], LONG);
    assert_eq!(code, 0, "{text}");
    let topics = read_mcap(&Path::new(&out).join("run.mcap")).topics;
    assert!(!topics.contains_key("/eqtrack/terms"), "{topics:?}");
}

#[test]
fn a_vehicle_run_exports_its_actuator_commands() {
    let _g = serial();
    let d = TempDir::new("export-vehicle");
    let out = d.join("rov");
    let rov = pair_tests::repo("scenarios/rov_failure.toml");
    lockstep(
        "t-export-rov",
        &out,
        "1",
        &["--scenario", rov.to_str().unwrap()],
    );
    let (code, text) = run("plant_sim", &["export", &out], LONG);
    assert_eq!(code, 0, "{text}");
    let n = records(&out);
    let topics = read_mcap(&Path::new(&out).join("run.mcap")).topics;
    assert_eq!(topics.get("/eqtrack/actuators"), Some(&n), "{topics:?}");
    let (code, text) = run("plant_sim", &["export", &out, "--format", "jsonl"], LONG);
    assert_eq!(code, 0, "{text}");
    let line = std::fs::read_to_string(Path::new(&out).join("run.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .find(|l| l["topic"] == "/eqtrack/actuators" && l["sequence"] == 30)
        .expect("an actuators message at cycle 30");
    let f = &line["fields"];
    assert_eq!(f["u_cmd"].as_array().map(Vec::len), Some(8), "{f}");
    assert_eq!(f["demand"].as_array().map(Vec::len), Some(6), "{f}");
    assert!(f["alloc_status"].as_u64().is_some(), "{f}");
    // no failure detector, no detection channel
    assert!(!topics.contains_key("/eqtrack/detection"), "{topics:?}");
}

#[test]
fn a_run_with_sensors_exports_its_samples_and_estimates() {
    let _g = serial();
    let d = TempDir::new("export-sensors");
    let out = d.join("eqf");
    lockstep(
        "t-export-eqf",
        &out,
        "1",
        &["--scenario", &scenario("eqf_se3")],
    );
    let (code, text) = run("plant_sim", &["export", &out], LONG);
    assert_eq!(code, 0, "{text}");
    let n = records(&out);
    let topics = read_mcap(&Path::new(&out).join("run.mcap")).topics;
    for topic in ["/eqtrack/sensors", "/eqtrack/estimate", "/eqtrack/state"] {
        assert_eq!(topics.get(topic), Some(&n), "{topic}: {topics:?}");
    }
    assert!(!topics.contains_key("/eqtrack/plan"), "{topics:?}");
    // the estimate channel holds what crossed the wire (the state's Q̂) and the EqF's
    // covariance; the sensor channel the samples (SE(3): accelerometer, position fixes)
    let (code, text) = run("plant_sim", &["export", &out, "--format", "jsonl"], LONG);
    assert_eq!(code, 0, "{text}");
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(Path::new(&out).join("run.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let at = |topic: &str, cycle: u64| {
        lines
            .iter()
            .find(|l| l["topic"] == topic && l["sequence"] == cycle)
            .unwrap_or_else(|| panic!("no {topic} at cycle {cycle}"))["fields"]
            .clone()
    };
    let (state, estimate, sensors) = (
        at("/eqtrack/state", 50),
        at("/eqtrack/estimate", 50),
        at("/eqtrack/sensors", 50),
    );
    assert_eq!(estimate["q_hat"], state["q"]);
    assert_eq!(estimate["covariance"].as_array().map(Vec::len), Some(6));
    assert_eq!(sensors["gyro"].as_array().map(Vec::len), Some(3));
    assert_eq!(sensors["accel"].as_array().map(Vec::len), Some(3));
    assert_eq!(sensors["true_q"].as_array().map(Vec::len), Some(16));
    assert_ne!(
        sensors["true_q"], state["q"],
        "the estimate is not the truth"
    );
}

#[test]
fn a_killed_runs_log_exports_up_to_its_last_whole_record() {
    let _g = serial();
    let d = TempDir::new("export-kill");
    let out = d.join("killed");
    let mut plant = Proc::start(
        "plant_sim",
        &[
            "run",
            "--duration",
            "30",
            "--name",
            "t-export-kill",
            "--out",
            &out,
        ],
    );
    assert!(
        plant.wait_for_line("controller connected", Duration::from_secs(20)),
        "{}",
        plant.output()
    );
    wait_for_cycles(&out, 400, LONG);
    plant.kill();
    // cut mid-record, as a kill during a write would
    let path = Path::new(&out).join(LOG_FILE);
    let whole = (std::fs::metadata(&path).unwrap().len() as usize - HEADER_BYTES) / RECORD_BYTES;
    assert!(whole > 300, "{whole} records");
    let f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    f.set_len((HEADER_BYTES + (whole - 1) * RECORD_BYTES + 100) as u64)
        .unwrap();
    let (code, text) = run("plant_sim", &["export", &out], LONG);
    assert_eq!(code, 0, "{text}");
    assert!(
        text.contains(&format!("exported {} records", whole - 1)),
        "{text}"
    );
    assert!(
        text.contains("the log ends 100 bytes into a record"),
        "{text}"
    );
    let topics = read_mcap(&Path::new(&out).join("run.mcap")).topics;
    assert_eq!(topics.get("/eqtrack/state"), Some(&(whole as u64 - 1)));
}

#[test]
fn a_log_of_another_format_version_is_refused_with_both_versions_named() {
    let _g = serial();
    let d = TempDir::new("export-old");
    let out = d.join("run");
    lockstep("t-export-old", &out, "0.2", &[]);
    let path = Path::new(&out).join(LOG_FILE);
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[8..12].copy_from_slice(&1u32.to_le_bytes());
    std::fs::write(&path, bytes).unwrap();
    let (code, text) = run("plant_sim", &["export", &out], LONG);
    assert_eq!(code, 2, "{text}");
    assert!(
        text.contains(&format!(
            "format version 1; this build reads version {}",
            recorder::FORMAT_VERSION
        )),
        "{text}"
    );
    assert!(!Path::new(&out).join("run.mcap").exists() || !text.contains("exported"));
}
