//! The writer's tests: the files it writes, read back; lockstep's and real time's channel.

use super::*;
use crate::format::Samples;
use crate::format::{HEADER_BYTES, SensorRecord, torque_byte_offset};
use crate::reader::{LogReader, read_plans};
use ipc_types::Decision;
use ipc_types::{CommandMsg, MAX_M, StateMsg};
use nalgebra::Vector3;

fn f64_at(b: &[u8], at: usize) -> f64 {
    f64::from_le_bytes(b[at..at + 8].try_into().unwrap())
}

/// The header of a lockstep run of group `group`.
fn lockstep_header(group: u32, sensors: bool) -> Header {
    Header {
        group,
        control_period: 0.001,
        rate_hz: 0.0,
        realtime: false,
        event_wake: true,
        miss_limit: 3,
        fingerprint: 1,
        run: "x".into(),
        scenario: "y".into(),
        law: "eqt".into(),
        plant_pid: 1,
        sensors,
    }
}

fn sensors(k: u64) -> SensorRecord {
    SensorRecord {
        samples: Samples {
            gyro: Vector3::new(0.1, k as f64, f64::NAN),
            directions: [Vector3::new(0.0, 0.0, 1.0); 4],
            count: 2,
            accel: k.is_multiple_of(2).then(|| Vector3::new(0.0, 0.0, 9.81)),
            position: None,
            bias: Vector3::new(1e-3, -2e-3, 0.0),
        },
        q_true: [0.5; 16],
        v_true: [-0.25; 6],
        bias_hat: [1e-3, 0.0, -0.0],
        estimate_error: 0.01,
        covariance: Some([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]),
        nees: None,
    }
}

fn record(k: u64, with_command: bool) -> Record {
    let mut state = StateMsg::new(ipc_types::WireGroup::Se3);
    state.seq = k;
    state.t = k as f64 * 0.001;
    state.v = [0.1, -0.2, 0.3, 1e-300, f64::MIN_POSITIVE, -0.0];
    state.stamp_ns = 1_000 + k;
    let mut cmd = CommandMsg::new(ipc_types::WireGroup::Se3);
    cmd.seq = k;
    cmd.tau = [1.0, -2.0, 3.5, 0.25, -0.125, 7.0];
    cmd.lyapunov = 0.5;
    Record {
        cycle: k,
        decision: if with_command {
            Decision::Fresh
        } else {
            Decision::Safe
        },
        misses_in_row: if with_command { 0 } else { 4 },
        deadline_ns: 5_000 + k,
        applied: [0.5; MAX_M],
        state,
        command: with_command.then_some((cmd, 4_000 + k)),
        sensors: None,
    }
}

#[test]
fn records_and_headers_round_trip_bit_for_bit() {
    // the sizes docs/architecture.md's tables give
    assert_eq!(
        (RECORD_BYTES, SENSOR_BYTES, crate::format::PLAN_ENTRY_BYTES),
        (1216, 464, 3192)
    );
    for r in [record(7, true), record(8, false)] {
        let back = Record::from_bytes(&r.to_bytes()).unwrap();
        assert_eq!(back.to_bytes(), r.to_bytes());
        assert_eq!(back.command.is_some(), r.command.is_some());
    }
    // with the sensor block: every bit back, NaN included, and absent parts absent
    for k in [4, 5] {
        let r = Record {
            sensors: Some(sensors(k)),
            ..record(k, true)
        };
        let mut b = vec![0u8; RECORD_BYTES + SENSOR_BYTES];
        r.write_into(&mut b);
        let back = Record::from_bytes(&b).unwrap();
        let mut again = vec![0u8; b.len()];
        back.write_into(&mut again);
        assert_eq!(again, b);
        let got = back.sensors.unwrap();
        assert!(got.samples.gyro[2].is_nan());
        assert_eq!(got.samples.accel.is_some(), k.is_multiple_of(2));
        assert_eq!((got.nees, got.covariance), (None, sensors(k).covariance));
        assert_eq!(got.q_true, [0.5; 16]);
    }
    let h = Header {
        group: 2,
        control_period: 0.001,
        rate_hz: 1000.0,
        realtime: true,
        event_wake: false,
        miss_limit: 3,
        fingerprint: 0xdead_beef,
        run: "board-7".into(),
        scenario: "se3_circle".into(),
        law: "eqt".into(),
        plant_pid: 42,
        sensors: false,
    };
    assert_eq!(Header::from_bytes(&h.to_bytes()).unwrap(), h);
    let mut bad = h.to_bytes();
    bad[8] = 9;
    assert!(Header::from_bytes(&bad).unwrap_err().contains("version 9"));
    assert!(Header::from_bytes(b"not a log at all, no").is_err());
    let with = Header { sensors: true, ..h };
    assert_eq!(with.record_bytes(), RECORD_BYTES + SENSOR_BYTES);
    assert_eq!(Header::from_bytes(&with.to_bytes()).unwrap(), with);
    // a header whose record size does not match its sensor flag is not ours
    let mut bad = with.to_bytes();
    bad[42] = 0;
    assert!(Header::from_bytes(&bad).unwrap_err().contains("records of"));
}

#[test]
fn the_torque_offset_points_at_the_commands_torque() {
    let r = record(3, true);
    let b = r.to_bytes();
    for axis in 0..MAX_M {
        let at = torque_byte_offset(axis);
        assert_eq!(
            f64_at(&b, at),
            r.command.unwrap().0.tau[axis],
            "axis {axis}"
        );
    }
}

#[test]
fn the_writer_drains_everything_and_a_cut_log_reads_to_its_last_whole_record() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().to_path_buf();
    // real time: the loop never waits for the disk
    let h = Header {
        realtime: true,
        rate_hz: 1000.0,
        ..lockstep_header(2, false)
    };
    // a small channel: the loop outpaces the writer, pushes are dropped and counted
    let mut rec = Recorder::start(&dir, &h, 4, None, None).unwrap();
    let mut pushed = 0;
    for k in 0..2000 {
        rec.push(&record(k, k % 3 != 0));
        pushed += 1;
        if k % 50 == 0 {
            std::thread::sleep(Duration::from_millis(3));
        }
    }
    let report = rec.finish().unwrap();
    assert_eq!(report.records + report.dropped, pushed);
    assert!(report.records >= 40, "{report:?}");
    let path = dir.join(LOG_FILE);
    let mut log = LogReader::open(&path).unwrap();
    assert_eq!(log.header, h);
    assert_eq!((log.records, log.trailing_bytes), (report.records, 0));
    let mut last = None;
    while let Some(r) = log.next_record().unwrap() {
        assert!(last.is_none_or(|l| r.cycle > l), "cycles increase");
        assert_eq!(r.to_bytes(), record(r.cycle, r.cycle % 3 != 0).to_bytes());
        last = Some(r.cycle);
    }
    // cut mid-record, as after a SIGKILL
    let len = std::fs::metadata(&path).unwrap().len();
    let f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    f.set_len(len - 100).unwrap();
    let log = LogReader::open(&path).unwrap();
    assert_eq!(log.records, report.records - 1);
    assert_eq!(log.trailing_bytes, RECORD_BYTES as u64 - 100);
    // shorter than a header, or not a log: errors that name the file, no panic
    for len in [0, 10, HEADER_BYTES as u64 - 1] {
        f.set_len(len).unwrap();
        let e = LogReader::open(&path).err().unwrap().to_string();
        assert!(e.contains("messages.log") && e.contains("header"), "{e}");
    }
    std::fs::write(&path, [b'x'; 300]).unwrap();
    let e = LogReader::open(&path).err().unwrap().to_string();
    assert!(e.contains("not an eqtrack flight recording"), "{e}");
}

#[test]
fn plan_messages_seen_on_the_board_are_written_to_plans_log_and_read_back() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().to_path_buf();
    let h = lockstep_header(1, true);
    // a board that shows five messages, one per poll, then nothing
    let board: PlanSourceFactory = Box::new(|| {
        let mut next = 0u64;
        Some(Box::new(move || {
            next += 1;
            (next <= 5).then(|| {
                let mut m = PlanMsg::new(ipc_types::WireGroup::So3);
                m.seq = next;
                m.planner_pid = 99;
                m
            })
        }) as PlanSource)
    });
    let mut rec = Recorder::start(&dir, &h, 64, None, Some(board)).unwrap();
    for k in 0..10 {
        rec.push(&Record {
            sensors: (k != 3).then(|| sensors(k)),
            ..record(k, true)
        });
    }
    let report = rec.finish().unwrap();
    assert_eq!((report.records, report.plans), (10, 5));
    let plans = read_plans(&dir).unwrap();
    let seqs: Vec<u64> = plans.iter().map(|p| p.msg.seq).collect();
    assert_eq!(seqs, [1, 2, 3, 4, 5]);
    // a lockstep log: the planner's pid is its ordinal
    assert!(plans.iter().all(|p| p.msg.planner_pid == 1));
    let mut log = LogReader::open(&dir.join(LOG_FILE)).unwrap();
    assert!(log.header.sensors);
    let mut k = 0;
    while let Some(r) = log.next_record().unwrap() {
        assert_eq!(r.sensors.is_some(), k != 3, "record {k}");
        k += 1;
    }
    assert_eq!(k, 10);
    // a plans.log cut mid-entry reads its whole entries; another version is refused
    let path = dir.join(PLANS_FILE);
    let len = std::fs::metadata(&path).unwrap().len();
    let f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    f.set_len(len - 7).unwrap();
    assert_eq!(read_plans(&dir).unwrap().len(), 4);
    let mut b = std::fs::read(&path).unwrap();
    b[8] = 3;
    std::fs::write(&path, b).unwrap();
    let e = read_plans(&dir).unwrap_err().to_string();
    assert!(
        e.contains("format version 3") && e.contains(&format!("version {}", crate::FORMAT_VERSION)),
        "{e}"
    );
}

#[test]
fn a_lockstep_log_keeps_nominal_times_and_pid_ordinals_and_drops_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().to_path_buf();
    let h = lockstep_header(2, false);
    let commanded = |k: u64| {
        let mut r = record(k, true);
        if let Some((c, _)) = r.command.as_mut() {
            c.compute_ns = 300 + k;
            c.state_received_ns = 2_000 + k;
            c.stamp_ns = 3_000 + k;
            // a planner replaced halfway through the run
            c.plan_pid = if k < 1000 { 4242 } else { 777 };
        }
        r.state.plant_pid = 31337;
        r
    };
    // the same small channel as in real time: here the loop waits, and nothing is lost
    let mut rec = Recorder::start(&dir, &h, 4, None, None).unwrap();
    for k in 0..2000 {
        rec.push(&commanded(k));
    }
    let report = rec.finish().unwrap();
    assert_eq!((report.records, report.dropped), (2000, 0));
    let mut log = LogReader::open(&dir.join(LOG_FILE)).unwrap();
    assert_eq!(log.header, Header { plant_pid: 0, ..h });
    let mut k = 0;
    while let Some(r) = log.next_record().unwrap() {
        let t_k = k * 1_000_000; // the tick's nominal time at 1 ms, in ns
        let (c, received) = r.command.unwrap();
        assert_eq!(
            (r.state.stamp_ns, c.state_received_ns, c.stamp_ns, received),
            (t_k, t_k, t_k, t_k),
            "cycle {k}"
        );
        assert_eq!((c.compute_ns, r.state.plant_pid), (0, 0));
        assert_eq!(c.plan_pid, if k < 1000 { 1 } else { 2 }, "cycle {k}");
        // everything else as it came
        let mut want = commanded(k);
        want.state.stamp_ns = t_k;
        want.state.plant_pid = 0;
        want.command = Some((
            CommandMsg {
                compute_ns: 0,
                state_received_ns: t_k,
                stamp_ns: t_k,
                plan_pid: c.plan_pid,
                ..want.command.unwrap().0
            },
            t_k,
        ));
        assert_eq!(r.to_bytes(), want.to_bytes(), "cycle {k}");
        k += 1;
    }
    assert_eq!(k, 2000);
    // no process id and no pid ordinal 0 for a real pid
    let mut ids = PidOrdinals::default();
    assert_eq!(
        [
            ids.ordinal(0),
            ids.ordinal(9),
            ids.ordinal(5),
            ids.ordinal(9)
        ],
        [0, 1, 2, 1]
    );
}
