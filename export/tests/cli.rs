//! `eqtrack-export` on hand-made logs (the binary itself, so `cargo test --workspace` builds it
//! for the cross-process tests too): a log of three cycles, one without a command and one
//! with a NaN in its torque, exports the messages it should, read back with the `mcap` crate;
//! the JSONL form writes NaN as "NaN"; a missing log exits 2.

use ipc_types::{CommandMsg, MAX_M, StateMsg};
use link::Decision;
use link::wire::group_code;
use recorder::{Header, Record};
use std::path::Path;
use std::process::Command;

fn export(args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_eqtrack-export"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ),
    )
}

/// A fresh temporary directory holding [`write_log`]'s log (removed when dropped).
fn hand_made_log() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    write_log(dir.path());
    dir
}

/// A log of three SO(3) cycles at 0.01 s: a command in cycles 0 and 2 (a NaN torque in 2),
/// none in 1.
fn write_log(dir: &Path) {
    let header = Header {
        group: group_code(eqtrack_controller::GroupKind::So3),
        control_period: 0.01,
        rate_hz: 0.0,
        realtime: false,
        event_wake: false,
        miss_limit: 3,
        fingerprint: 42,
        run: "hand".to_owned(),
        scenario: "made".to_owned(),
        law: "eqt".to_owned(),
        plant_pid: 1,
        sensors: false,
    };
    let mut bytes = header.to_bytes().to_vec();
    for k in 0..3u64 {
        let mut state = StateMsg::new(ipc_types::WireGroup::So3);
        state.seq = k;
        state.t = k as f64 * 0.01;
        state.q[0] = 1.0;
        state.v[1] = 0.5 * k as f64;
        let command = (k != 1).then(|| {
            let mut c = CommandMsg::new(ipc_types::WireGroup::So3);
            c.seq = k;
            c.tau[0] = if k == 2 { f64::NAN } else { 0.25 };
            c.lyapunov = 1.0 / (k + 1) as f64;
            (c, 1000 + k)
        });
        let r = Record {
            cycle: k,
            decision: if k == 1 {
                Decision::Held
            } else {
                Decision::Fresh
            },
            misses_in_row: u32::from(k == 1),
            deadline_ns: 10_000_000 * k,
            applied: [0.125; MAX_M],
            state,
            command,
            sensors: None,
        };
        bytes.extend_from_slice(&r.to_bytes());
    }
    std::fs::write(dir.join("messages.log"), bytes).unwrap();
}

#[test]
fn a_hand_made_log_exports_each_channel_and_nan_stays_nan() {
    let tmp = hand_made_log();
    let dir = tmp.path().to_path_buf();
    let d = dir.to_str().unwrap();
    let (code, text) = export(&[d]);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("exported 3 records"), "{text}");
    let bytes = std::fs::read(dir.join("run.mcap")).unwrap();
    let mut per_topic = std::collections::BTreeMap::<String, u64>::new();
    let mut nan_torques = 0;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        *per_topic.entry(m.channel.topic.clone()).or_default() += 1;
        assert_eq!(u64::from(m.sequence) * 10_000_000, m.log_time);
        if m.channel.topic == "/eqtrack/command" && m.sequence == 2 {
            // CDR: header 4; cycle, seq, four stamps (u64 each) = 48; tau's length (u32) at
            // 48, then the first element at 56 (8-aligned)
            let tau0 = f64::from_le_bytes(m.data[4 + 56..4 + 64].try_into().unwrap());
            assert!(tau0.is_nan(), "{tau0}");
            nan_torques += 1;
        }
    }
    assert_eq!(nan_torques, 1);
    let counts: Vec<(&str, u64)> = per_topic.iter().map(|(t, n)| (t.as_str(), *n)).collect();
    assert_eq!(
        counts,
        vec![
            ("/eqtrack/command", 2),
            ("/eqtrack/cycle", 3),
            ("/eqtrack/state", 3)
        ]
    );
    let (code, text) = export(&[d, "--format", "jsonl"]);
    assert_eq!(code, 0, "{text}");
    let jsonl = std::fs::read_to_string(dir.join("run.jsonl")).unwrap();
    assert_eq!(jsonl.lines().count(), 8);
    assert!(jsonl.contains(r#""tau":["NaN",0.0,0.0]"#), "{jsonl}");
    let (code, text) = export(&[dir.join("missing").to_str().unwrap()]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("cannot open"), "{text}");
}

/// `--out` writes where it is told (and only there); `--compress` writes zstd chunks that the
/// `mcap` crate reads back when the binary has the `zstd` feature, and is refused naming the
/// feature when it has not.
#[test]
fn out_names_the_file_and_compress_needs_the_zstd_feature() {
    let tmp = hand_made_log();
    let dir = tmp.path().to_path_buf();
    let d = dir.to_str().unwrap();
    let elsewhere = dir.join("elsewhere.mcap");
    let (code, text) = export(&[d, "--out", elsewhere.to_str().unwrap()]);
    assert_eq!(code, 0, "{text}");
    assert!(!dir.join("run.mcap").exists(), "--out writes no run.mcap");
    let plain = std::fs::read(&elsewhere).unwrap();
    assert_eq!(mcap::MessageStream::new(&plain).unwrap().count(), 8);

    let packed = dir.join("packed.mcap");
    let (code, text) = export(&[d, "--compress", "--out", packed.to_str().unwrap()]);
    if cfg!(feature = "zstd") {
        assert_eq!(code, 0, "{text}");
        let bytes = std::fs::read(&packed).unwrap();
        let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
        assert!(
            summary
                .chunk_indexes
                .iter()
                .all(|c| c.compression == "zstd"),
            "{:?}",
            summary.chunk_indexes
        );
        let read: Vec<_> = mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| m.unwrap().data.into_owned())
            .collect();
        let plain: Vec<_> = mcap::MessageStream::new(&plain)
            .unwrap()
            .map(|m| m.unwrap().data.into_owned())
            .collect();
        assert_eq!(read, plain, "the same messages, compressed");
    } else {
        assert_eq!(code, 2, "{text}");
        assert!(
            text.contains("--compress needs eqtrack-export built with the `zstd` feature"),
            "{text}"
        );
        assert!(!packed.exists(), "a refused export creates no file");
    }
}
