//! `plant_sim bench-loop`: the round trip of the real controller loop (plant_sim and
//! controller_node as two processes, the same messages) over iceoryx2 with busy polling,
//! iceoryx2 with event wake-up, and a Unix-domain-socket baseline (blocking, and busy-polled),
//! at each requested rate; and, in the same run at the same rates and durations, the floors
//! it is measured against ([`crate::os_floor`]): cyclictest's wake-up latency and a bare
//! iceoryx2 exchange.

use crate::os_floor::{OsFloor, TransportFloor, os_floor, transport_floor};
use link::{StopFlag, TransportKind as Transport, Wake};
use plant::SimError;
use plant::output::{ensure_dir, write_json};
use plant::pair::{Mode, PairOptions, run_pair};
use scenario::cli::ScenarioSource;
use serde::Serialize;
use std::path::Path;
use std::time::Duration;

/// The compared set-ups: label, transport, wake-up, flight recorder on. The Unix-socket
/// baseline runs both as people usually write it (blocking reads: event) and busy-polled, so
/// that the transport's own cost can be told apart from the cost of waking a sleeping
/// process. The loop is measured without the flight recorder, and once more with it (event
/// wake-up, the default of `plant_sim run`), so its cost shows in the same run.
pub const CASES: [(&str, Transport, Wake, bool); 5] = [
    ("iceoryx2 busy-poll", Transport::Iceoryx2, Wake::Spin, false),
    ("iceoryx2 event", Transport::Iceoryx2, Wake::Event, false),
    (
        "iceoryx2 event, recorded",
        Transport::Iceoryx2,
        Wake::Event,
        true,
    ),
    ("unix socket", Transport::Uds, Wake::Event, false),
    ("unix socket busy-poll", Transport::Uds, Wake::Spin, false),
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
    /// The plant's tick lateness p50, µs (how late it woke for its ticks).
    pub tick_lateness_p50_us: f64,
    /// The plant's tick lateness p99, µs.
    pub tick_lateness_p99_us: f64,
    /// The plant's tick lateness p99.9, µs (scheduling noise of the machine).
    pub tick_lateness_p99_9_us: f64,
    /// The plant's tick lateness maximum, µs.
    pub tick_lateness_max_us: f64,
    /// Median of the first leg (state published → received by the controller), µs.
    pub leg_to_controller_p50_us: f64,
    /// Median of the controller's compute time, µs.
    pub compute_p50_us: f64,
    /// Median of the last leg (command published → received by the plant), µs.
    pub leg_to_plant_p50_us: f64,
    /// p50 divided by the iceoryx2 busy-poll p50 at the same rate.
    pub p50_ratio_to_busy_poll: f64,
    /// Heap allocations the controller reported after its first cycle.
    pub controller_heap_allocations: Option<u64>,
}

/// The floors at one rate (a floor that could not be measured says why).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct RateFloors {
    /// Loop rate (Hz).
    pub rate_hz: f64,
    /// cyclictest at the loop's period.
    pub os: Result<OsFloor, String>,
    /// The bare iceoryx2 exchange, busy-polled.
    pub transport_spin: Result<TransportFloor, String>,
    /// The bare iceoryx2 exchange with event wake-up.
    pub transport_event: Result<TransportFloor, String>,
}

/// What `bench-loop` measured.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct BenchLoop {
    /// The scenario's name.
    pub scenario: String,
    /// The pair, per case and rate.
    pub cases: Vec<LoopRow>,
    /// The floors, per rate.
    pub floors: Vec<RateFloors>,
}

/// Measures the floors at `rate` for `duration` s each (`cyclictest`: the program to run).
fn floors(cyclictest: &Path, rate: f64, duration: f64) -> RateFloors {
    eprintln!("bench-loop: OS floor (cyclictest) at {rate} Hz for {duration} s ...");
    let os = os_floor(cyclictest, rate, duration);
    eprintln!("bench-loop: transport floor (bare iceoryx2) at {rate} Hz, busy-poll and event ...");
    let transport_spin = transport_floor(true, rate, duration);
    let transport_event = transport_floor(false, rate, duration);
    for e in [
        os.as_ref().err(),
        transport_spin.as_ref().err(),
        transport_event.as_ref().err(),
    ]
    .into_iter()
    .flatten()
    {
        eprintln!("bench-loop: warning: a floor could not be measured: {e}");
    }
    RateFloors {
        rate_hz: rate,
        os,
        transport_spin,
        transport_event,
    }
}

/// The pair's options for case `i` (`(transport, wake, record)`) at `rate_hz`: real time,
/// the controller spawned, 3 misses to safe mode, default real-time settings, no faults.
fn case_options(
    scenario: scenario::Scenario,
    source: &ScenarioSource,
    (transport, wake, record): (Transport, Wake, bool),
    (rate_hz, i): (f64, usize),
    out: std::path::PathBuf,
    thread_allocations: Option<fn() -> u64>,
    stop: &StopFlag,
) -> PairOptions {
    PairOptions {
        scenario,
        source: source.clone(),
        record,
        thread_allocations,
        mode: Mode::Realtime,
        rate_hz,
        wake,
        transport,
        spawn: true,
        serial: None,
        run: format!("bench-loop-{i}"),
        out,
        miss_limit: 3,
        rt: link::rt::RtSettings::default(),
        controller_rt: link::rt::RtSettings::default(),
        sample_faults: Vec::new(),
        record_every: 1,
        lockstep_timeout: Duration::from_secs(5),
        connect_timeout: Duration::from_secs(10),
        state_faults: Vec::new(),
        controller_fault_nan_torque: None,
        tunable: false,
        stop: stop.clone(),
    }
}

impl LoopRow {
    /// The row of case `label` at `rate_hz` from its pair summary; `base` is the busy-poll
    /// case's p50 at that rate.
    fn of(label: &str, rate_hz: f64, sum: &plant::pair::PairSummary, base: f64) -> LoopRow {
        let p50 = sum.latency.p50_us;
        let lateness = |f: fn(&plant::pair::Percentiles) -> f64| {
            sum.tick_lateness.as_ref().map(f).unwrap_or(f64::NAN)
        };
        LoopRow {
            case: label.to_string(),
            rate_hz,
            cycles: sum.cycles,
            p50_us: p50,
            p99_us: sum.latency.p99_us,
            p99_9_us: sum.latency.p99_9_us,
            max_us: sum.latency.max_us,
            deadline_misses: sum.deadline_misses,
            tick_lateness_p50_us: lateness(|t| t.p50_us),
            tick_lateness_p99_us: lateness(|t| t.p99_us),
            tick_lateness_p99_9_us: lateness(|t| t.p99_9_us),
            tick_lateness_max_us: lateness(|t| t.max_us),
            leg_to_controller_p50_us: sum.leg_to_controller.p50_us,
            compute_p50_us: sum.controller_compute.p50_us,
            leg_to_plant_p50_us: sum.leg_to_plant.p50_us,
            p50_ratio_to_busy_poll: p50 / base,
            controller_heap_allocations: sum.controller_heap_allocations,
        }
    }
}

/// Runs the floors and every case at every rate for `duration` seconds each; SIGINT/SIGTERM
/// (`stop`) end it after the current case's run directory is written.
pub fn bench_loop(
    source: &ScenarioSource,
    rates: &[f64],
    duration: f64,
    cyclictest: &Path,
    out: &Path,
    thread_allocations: Option<fn() -> u64>,
    stop: &StopFlag,
) -> Result<BenchLoop, SimError> {
    let scenario = source.load("seed")?;
    ensure_dir(out)?;
    let mut rows = Vec::new();
    let mut all_floors = Vec::new();
    for rate in rates {
        all_floors.push(floors(cyclictest, *rate, duration));
        SimError::check(stop)?;
        let mut base_p50 = None;
        for (i, (label, transport, wake, record)) in CASES.iter().enumerate() {
            let mut s = scenario.clone();
            s.duration = duration;
            let dir = out.join(format!(
                "{}-{}hz",
                label.replace(", ", "-").replace(' ', "-"),
                rate
            ));
            eprintln!("bench-loop: {label} at {rate} Hz for {duration} s ...");
            let case = (*transport, *wake, *record);
            let opts = case_options(s, source, case, (*rate, i), dir, thread_allocations, stop);
            let (_, sum) = run_pair(&opts)?;
            // a stopped case is not a measurement: stop here (its run directory is written)
            SimError::check(stop)?;
            let base = *base_p50.get_or_insert(sum.latency.p50_us);
            rows.push(LoopRow::of(label, *rate, &sum, base));
        }
    }
    let result = BenchLoop {
        scenario: scenario.name.clone(),
        cases: rows,
        floors: all_floors,
    };
    write_json(&result, &out.join("summary.json"))?;
    let text = table(&result.cases) + "\n" + &floors_table(&result);
    std::fs::write(out.join("table.md"), text).map_err(|e| {
        SimError::Run(format!(
            "cannot write {}: {e}",
            out.join("table.md").display()
        ))
    })?;
    Ok(result)
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

/// The floors beside the pair, per rate: cyclictest's wake-up latency against the plant's tick
/// lateness (in the iceoryx2 event case, where the plant sleeps as cyclictest does), and the
/// bare iceoryx2 exchange against the pair's round trip in the same wake-up mode.
pub fn floors_table(b: &BenchLoop) -> String {
    let mut s = String::from(
        "| rate | floor | floor p50 µs | floor p99 µs | floor max µs | the pair's figure | pair p50 µs | pair p99 µs | pair max µs | pair / floor | legs p50 µs: floor · pair |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let case = |rate: f64, label: &str| {
        b.cases
            .iter()
            .find(|r| r.rate_hz == rate && r.case == label)
    };
    for f in &b.floors {
        let r = f.rate_hz;
        for label in ["iceoryx2 event", "iceoryx2 busy-poll"] {
            match (&f.os, case(r, label)) {
                (Ok(os), Some(c)) => {
                    s += &format!(
                        "| {r} Hz | OS: cyclictest wake-up latency | {:.1} | {:.1} | {:.1} | plant tick lateness ({label}) | {:.1} | {:.1} | {:.1} | p99: {:.2}× | |\n",
                        os.p50_us,
                        os.p99_us,
                        os.max_us,
                        c.tick_lateness_p50_us,
                        c.tick_lateness_p99_us,
                        c.tick_lateness_max_us,
                        c.tick_lateness_p99_us / os.p99_us
                    )
                }
                (Err(e), _) if label == "iceoryx2 event" => {
                    s += &format!(
                        "| {r} Hz | OS: cyclictest | not measured: {e} | | | | | | | | |\n"
                    )
                }
                _ => {}
            }
        }
        for (floor, label) in [
            (&f.transport_spin, "iceoryx2 busy-poll"),
            (&f.transport_event, "iceoryx2 event"),
        ] {
            match (floor, case(r, label)) {
                (Ok(t), Some(c)) => {
                    s += &format!(
                        "| {r} Hz | transport: bare iceoryx2, {} | {:.2} | {:.2} | {:.1} | round trip ({label}) | {:.2} | {:.2} | {:.1} | p50: {:.2}× | {:.2} + {:.2} · {:.2} + {:.2} + {:.2} |\n",
                        t.wake,
                        t.p50_us,
                        t.p99_us,
                        t.max_us,
                        c.p50_us,
                        c.p99_us,
                        c.max_us,
                        c.p50_us / t.p50_us,
                        t.leg1_p50_us,
                        t.leg2_p50_us,
                        c.leg_to_controller_p50_us,
                        c.compute_p50_us,
                        c.leg_to_plant_p50_us
                    )
                }
                (Err(e), _) => {
                    s += &format!(
                        "| {r} Hz | transport ({label}) | not measured: {e} | | | | | | | | |\n"
                    )
                }
                (Ok(_), None) => {}
            }
        }
    }
    s
}
