//! What a pair run reports: `summary.json`'s figures and the loop's histograms.

use crate::SimError;
use crate::output::Summary;
use hdrhistogram::Histogram;
use link::Command;
use recorder::RecordingReport;
use serde::Serialize;

/// The summary's note on a lockstep run's deadline figures.
pub const LOCKSTEP_NOTE: &str = "lockstep: the plant waits for every command, so deadline misses, late commands and safe mode do not apply (none are counted)";

/// Percentiles of a latency histogram, in microseconds.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Percentiles {
    /// Samples.
    pub count: u64,
    /// Median.
    pub p50_us: f64,
    /// 99th percentile.
    pub p99_us: f64,
    /// 99.9th percentile.
    pub p99_9_us: f64,
    /// Maximum.
    pub max_us: f64,
}

impl Percentiles {
    pub(super) fn of(h: &Histogram<u64>) -> Percentiles {
        let us = |ns: u64| ns as f64 / 1000.0;
        Percentiles {
            count: h.len(),
            p50_us: us(h.value_at_quantile(0.5)),
            p99_us: us(h.value_at_quantile(0.99)),
            p99_9_us: us(h.value_at_quantile(0.999)),
            max_us: us(h.max()),
        }
    }
}

/// `summary.json` of `plant_sim run`: the simulation summary plus the loop's figures.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct PairSummary {
    /// As `plant_sim sim`.
    #[serde(flatten)]
    pub sim: Summary,
    /// `lockstep` or `realtime`.
    pub mode: String,
    /// `spin` or `event`.
    pub wake: String,
    /// Run name.
    pub run: String,
    /// Real time: the rate (Hz).
    pub rate_hz: Option<f64>,
    /// Control cycles run.
    pub cycles: u64,
    /// trajectory.csv keeps every Nth cycle (and the last).
    pub record_every: u64,
    /// Whether SIGINT/SIGTERM stopped the run before its end.
    pub interrupted: bool,
    /// The signal that stopped it (`SIGINT`, `SIGTERM`).
    pub signal: Option<String>,
    /// Round trip: state published → command received (excludes the connection cycle).
    pub latency: Percentiles,
    /// The round trip's first leg: state published → received by the controller (its
    /// wake-up and read; the clock is the machine's one CLOCK_MONOTONIC).
    pub leg_to_controller: Percentiles,
    /// The controller's compute time (state received → command published).
    pub controller_compute: Percentiles,
    /// The round trip's last leg: command published → received by the plant.
    pub leg_to_plant: Percentiles,
    /// Real time: how late the plant woke for its ticks (scheduling). A tick more than a
    /// period late makes the controller's command for it arrive too late by construction.
    pub tick_lateness: Option<Percentiles>,
    /// Commands that missed their deadline (real time).
    pub deadline_misses: u64,
    /// Times safe mode was entered.
    pub safe_mode_entries: u64,
    /// Cycles spent in safe mode.
    pub safe_mode_cycles: u64,
    /// Commands rejected by the plant's checks (never applied).
    pub commands_rejected: u64,
    /// Commands that arrived after their deadline (ignored).
    pub late_commands: u64,
    /// Lockstep: why the deadline figures above are zero (the plant waits for every
    /// command: deadlines, late commands and safe mode do not apply). Absent in real time.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub deadline_note: Option<String>,
    /// Exit status of the spawned controller (`None`: not spawned or killed).
    pub controller_exit: Option<i32>,
    /// `iceoryx2` or `uds`.
    pub transport: String,
    /// Heap allocations the controller reported making after its first cycle (from its last
    /// command).
    pub controller_heap_allocations: Option<u64>,
    /// The real-time settings of both processes: applied, refused (with the OS's reason),
    /// and the CPUs and scheduler read back.
    pub realtime: Realtime,
    /// The flight recording (`None`: `--no-record`).
    pub recording: Option<RecordingReport>,
    /// Heap allocations made by the plant's loop thread from the end of its first cycle (the
    /// first state published to the connected controller) to the end of the loop (`None`:
    /// not counted).
    pub plant_loop_heap_allocations: Option<u64>,
    /// `--tunable`: the gains changed while the run ran, each with the cycle it took effect
    /// at (absent without `--tunable`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub parameter_changes: Option<Vec<recorder::ParamChange>>,
}

/// What the real-time settings did in each process
/// (docs/architecture.md, "Real-time settings").
#[derive(Debug, Clone, Default, Serialize, PartialEq)]
pub struct Realtime {
    /// The plant's own report.
    pub plant: link::rt::RtReport,
    /// The report of the controller `plant_sim run` started (`controller_node --rt-report`),
    /// read when it answered; `None` for a controller started by hand (`--no-spawn`), whose
    /// settings only it knows.
    pub controller: Option<link::rt::RtReport>,
}

/// The loop's figures.
pub(super) struct Stats {
    pub(super) latency: Histogram<u64>,
    pub(super) to_controller: Histogram<u64>,
    pub(super) to_plant: Histogram<u64>,
    pub(super) compute: Histogram<u64>,
    pub(super) lateness: Histogram<u64>,
    pub(super) last_allocations: Option<u64>,
}

impl Stats {
    pub(super) fn new() -> Result<Stats, SimError> {
        let h = Histogram::<u64>::new_with_bounds(1, 60_000_000_000, 3)
            .map_err(|e| SimError::Run(e.to_string()))?;
        Ok(Stats {
            latency: h.clone(),
            to_controller: h.clone(),
            to_plant: h.clone(),
            compute: h.clone(),
            lateness: h,
            last_allocations: None,
        })
    }

    pub(super) fn command(&mut self, c: &Command, published: u64, first: bool) {
        if !first {
            let _ = self
                .latency
                .record(c.received_ns.saturating_sub(published).max(1));
            let _ = self
                .to_controller
                .record(c.msg.state_received_ns.saturating_sub(published).max(1));
            let _ = self
                .to_plant
                .record(c.received_ns.saturating_sub(c.msg.stamp_ns).max(1));
        }
        let _ = self.compute.record(c.msg.compute_ns.max(1));
        self.last_allocations = Some(c.msg.heap_allocations);
    }
}
