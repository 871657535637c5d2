//! `plant_sim bench-loop`: the round trip of the real controller loop (plant_sim and
//! controller_node as two processes, the same messages) over iceoryx2 with busy polling,
//! iceoryx2 with event wake-up, and a Unix-domain-socket baseline (blocking, and busy-polled),
//! at each requested rate.

use crate::SimError;
use crate::output::{ensure_dir, write_json};
use crate::pair::{Mode, PairOptions, run_pair};
use link::{StopFlag, TransportKind as Transport, Wake};
use scenario::Scenario;
use serde::Serialize;
use std::path::Path;
use std::time::Duration;

/// The compared set-ups: label, transport, wake-up. The Unix-socket baseline runs both as
/// people usually write it (blocking reads: event) and busy-polled, so that the transport's
/// own cost can be told apart from the cost of waking a sleeping process.
pub const CASES: [(&str, Transport, Wake); 4] = [
    ("iceoryx2 busy-poll", Transport::Iceoryx2, Wake::Spin),
    ("iceoryx2 event", Transport::Iceoryx2, Wake::Event),
    ("unix socket", Transport::Uds, Wake::Event),
    ("unix socket busy-poll", Transport::Uds, Wake::Spin),
];

/// One line of the comparison.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct LoopRow {
    /// Set-up label.
    pub case: String,
    /// Loop rate (Hz).
    pub rate_hz: f64,
    /// Cycles run.
    pub cycles: u64,
    /// Round trip (state published → command received), µs.
    pub p50_us: f64,
    /// 99th percentile, µs.
    pub p99_us: f64,
    /// 99.9th percentile, µs.
    pub p99_9_us: f64,
    /// Maximum, µs.
    pub max_us: f64,
    /// Deadline misses.
    pub deadline_misses: u64,
    /// The plant's tick lateness p99.9, µs (scheduling noise of the machine).
    pub tick_lateness_p99_9_us: f64,
    /// p50 divided by the iceoryx2 busy-poll p50 at the same rate.
    pub p50_ratio_to_busy_poll: f64,
    /// Heap allocations the controller reported after its first cycle.
    pub controller_heap_allocations: Option<u64>,
}

/// Runs every case at every rate for `duration` seconds each; SIGINT/SIGTERM (`stop`) end
/// it after the current case's run directory is written.
pub fn bench_loop(
    scenario: &Scenario,
    scenario_args: &[String],
    rates: &[f64],
    duration: f64,
    out: &Path,
    stop: &StopFlag,
) -> Result<Vec<LoopRow>, SimError> {
    ensure_dir(out)?;
    let mut rows = Vec::new();
    for rate in rates {
        let mut base_p50 = None;
        for (i, (label, transport, wake)) in CASES.iter().enumerate() {
            let mut s = scenario.clone();
            s.duration = duration;
            let dir = out.join(format!("{}-{}hz", label.replace(' ', "-"), rate));
            eprintln!("bench-loop: {label} at {rate} Hz for {duration} s ...");
            let opts = PairOptions {
                scenario: s,
                scenario_args: scenario_args.to_vec(),
                mode: Mode::Realtime,
                rate_hz: *rate,
                wake: *wake,
                transport: *transport,
                spawn: true,
                run: format!("bench-loop-{i}"),
                out: dir,
                miss_limit: 3,
                rt: link::rt::RtSettings::default(),
                lockstep_timeout: Duration::from_secs(5),
                connect_timeout: Duration::from_secs(10),
                state_faults: Vec::new(),
                controller_fault_nan_torque: None,
                stop: stop.clone(),
            };
            let (_, sum) = run_pair(&opts)?;
            // a stopped case is not a measurement: stop here (its run directory is written)
            SimError::check(stop)?;
            let p50 = sum.latency.p50_us;
            let base = *base_p50.get_or_insert(p50);
            rows.push(LoopRow {
                case: label.to_string(),
                rate_hz: *rate,
                cycles: sum.cycles,
                p50_us: p50,
                p99_us: sum.latency.p99_us,
                p99_9_us: sum.latency.p99_9_us,
                max_us: sum.latency.max_us,
                deadline_misses: sum.deadline_misses,
                tick_lateness_p99_9_us: sum.tick_lateness.map(|t| t.p99_9_us).unwrap_or(f64::NAN),
                p50_ratio_to_busy_poll: p50 / base,
                controller_heap_allocations: sum.controller_heap_allocations,
            });
        }
    }
    write_json(&rows, &out.join("summary.json"))?;
    std::fs::write(out.join("table.md"), table(&rows)).map_err(|e| {
        SimError::Run(format!(
            "cannot write {}: {e}",
            out.join("table.md").display()
        ))
    })?;
    Ok(rows)
}

/// The comparison as a Markdown table.
pub fn table(rows: &[LoopRow]) -> String {
    let mut s = String::from(
        "| transport | rate | cycles | p50 µs | p99 µs | p99.9 µs | max µs | misses | tick lateness p99.9 µs | p50 / busy-poll p50 | controller heap allocations |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        s += &format!(
            "| {} | {} Hz | {} | {:.2} | {:.2} | {:.2} | {:.1} | {} | {:.1} | {:.1}× | {} |\n",
            r.case,
            r.rate_hz,
            r.cycles,
            r.p50_us,
            r.p99_us,
            r.p99_9_us,
            r.max_us,
            r.deadline_misses,
            r.tick_lateness_p99_9_us,
            r.p50_ratio_to_busy_poll,
            r.controller_heap_allocations
                .map(|a| a.to_string())
                .unwrap_or_else(|| "-".to_owned())
        );
    }
    s
}
