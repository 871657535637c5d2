//! `plant_sim bench-loop` in quick mode: the floors (cyclictest, the bare iceoryx2 exchange)
//! appear in its output table and its summary beside the pair's cases. No timing is asserted.

use std::path::Path;
use std::process::Command;

/// cyclictest from Debian's rt-tests, fetched privately by the repository's script.
fn cyclictest() -> String {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/rt-tests.sh");
    let out = Command::new("bash").arg(script).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    let last = text.lines().last().unwrap_or_default().to_owned();
    assert!(
        out.status.success() && !last.starts_with("SKIPPED") && Path::new(&last).exists(),
        "scripts/rt-tests.sh could not provide cyclictest (the OS floor needs it):\n{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    last
}

#[test]
fn bench_loop_shows_the_floors_beside_the_pair() {
    let tmp = tempfile::tempdir().unwrap();
    let out_dir = tmp.path().to_path_buf();
    let out = Command::new(env!("CARGO_BIN_EXE_plant_sim"))
        .args([
            "bench-loop",
            "--rates",
            "1000",
            "--duration",
            "0.3",
            "--cyclictest",
        ])
        .arg(cyclictest())
        .arg("--out")
        .arg(&out_dir)
        .output()
        .unwrap();
    let table = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "{table}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for row in [
        "| 1000 Hz | OS: cyclictest wake-up latency |",
        "| 1000 Hz | transport: bare iceoryx2, spin |",
        "| 1000 Hz | transport: bare iceoryx2, event |",
    ] {
        let line = table
            .lines()
            .find(|l| l.starts_with(row))
            .unwrap_or_else(|| panic!("no `{row}` in:\n{table}"));
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        for c in &cells[3..6] {
            assert!(
                c.parse::<f64>().is_ok_and(|x| x >= 0.0),
                "floor figures are numbers: {line}"
            );
        }
        assert!(cells[10].contains('×'), "a ratio to the pair: {line}");
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("summary.json")).unwrap())
            .unwrap();
    let f = &summary["floors"][0];
    assert!(f["os"]["Ok"]["p99_us"].is_number(), "{f}");
    assert_eq!(
        f["os"]["Ok"]["cycles"], 300,
        "cyclictest ran the same number of cycles: {f}"
    );
    assert!(f["transport_spin"]["Ok"]["p50_us"].is_number(), "{f}");
    assert!(f["transport_event"]["Ok"]["p50_us"].is_number(), "{f}");
    assert_eq!(summary["cases"].as_array().unwrap().len(), 5);
    // the loop is measured without the flight recorder, and once with it
    assert!(table.contains("| iceoryx2 event, recorded |"), "{table}");
    assert!(
        out_dir
            .join("iceoryx2-event-recorded-1000hz/messages.log")
            .exists()
    );
    assert!(!out_dir.join("iceoryx2-event-1000hz/messages.log").exists());
}
