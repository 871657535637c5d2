//! What `plant_sim run` is asked to do: the mode, the options, the test-only faults.
use link::{StopFlag, TransportKind, Wake};
use scenario::Scenario;
use scenario::cli::ScenarioSource;
use std::path::PathBuf;
use std::time::Duration;

/// How the plant's clock runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Mode {
    /// Wait for each command; exact.
    Lockstep,
    /// Step on the wall clock.
    Realtime,
}

/// A corrupted state to publish instead of the real one (tests of the controller's checks).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StateFault {
    /// Wrong protocol version.
    Version,
    /// Wrong group code.
    Group,
    /// A NaN in the velocity.
    Nan,
}

/// The controller on a serial link (processor in the loop, docs/pil.md) instead of a
/// `controller_node` process: how to open the byte stream, what the link counts, and the
/// test hook that corrupts one received frame.
#[derive(Clone)]
pub struct SerialController {
    /// What it is, for the log (`tcp:127.0.0.1:5555`, `the in-process f32 controller`).
    pub name: String,
    /// Opens the byte stream.
    pub open: std::sync::Arc<
        dyn Fn() -> Result<Box<dyn link::serial::ByteLink>, link::LinkError> + Send + Sync,
    >,
    /// The link's counts (corrupted frames, resets, commands).
    pub counts: std::sync::Arc<link::serial::SerialCounts>,
    /// Test hook: flip a bit in this received frame.
    pub corrupt: Option<link::serial::CorruptCommand>,
    /// Test hook: noise on the line before every frame sent.
    pub noise: Option<link::serial::LineNoise>,
}

impl std::fmt::Debug for SerialController {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialController")
            .field("name", &self.name)
            .field("corrupt", &self.corrupt)
            .finish_non_exhaustive()
    }
}

/// Everything `plant_sim run` needs.
#[derive(Debug, Clone)]
pub struct PairOptions {
    /// The scenario.
    pub scenario: Scenario,
    /// Where the scenario came from: the spawned `controller_node` loads the same, and the
    /// flight recording keeps a copy of it.
    pub source: ScenarioSource,
    /// Lockstep or real time.
    pub mode: Mode,
    /// Real-time rate (Hz); the control period becomes 1/F.
    pub rate_hz: f64,
    /// Busy polling or events.
    pub wake: Wake,
    /// iceoryx2, or the Unix-socket baseline.
    pub transport: TransportKind,
    /// Spawn `controller_node` (else wait for one started by hand).
    pub spawn: bool,
    /// The controller on a serial link instead (no `controller_node`; `transport` and
    /// `spawn` unused).
    pub serial: Option<SerialController>,
    /// Run name.
    pub run: String,
    /// Output directory.
    pub out: PathBuf,
    /// Consecutive deadline misses that start safe mode.
    pub miss_limit: u32,
    /// Record every cycle in `messages.log` (the flight recorder, [`recorder`]) and
    /// publish the live status the monitor shows.
    pub record: bool,
    /// The calling thread's heap allocations so far (the binary's counting allocator; `None`
    /// without one). The loop's count is in the summary.
    pub thread_allocations: Option<fn() -> u64>,
    /// Keep every Nth cycle in trajectory.csv (and the last): long runs at a high rate
    /// otherwise hold every row in memory (1 = every cycle).
    pub record_every: u64,
    /// Real-time settings of the plant process (applied after the controller is spawned,
    /// which therefore does not inherit them).
    pub rt: link::rt::RtSettings,
    /// Real-time settings passed to the spawned controller (`plant_sim run` gives it the
    /// plant's priority and memory locking, and `--controller-cpu`, else the plant's CPUs).
    pub controller_rt: link::rt::RtSettings,
    /// Lockstep: how long to wait for a command.
    pub lockstep_timeout: Duration,
    /// How long to wait for the controller to appear.
    pub connect_timeout: Duration,
    /// Test only: corrupted states instead of the real ones at these steps.
    pub state_faults: Vec<(u64, StateFault)>,
    /// Test only: the spawned controller publishes a NaN torque instead of command k.
    pub controller_fault_nan_torque: Option<u64>,
    /// Test only: faults planted in the sensors' samples at these ticks.
    pub sample_faults: Vec<(u64, crate::sensors::SampleFault)>,
    /// `--tunable`: serve the run's `param` service and let gains change while it runs
    /// (docs/live.md, "Tuning a running pair").
    pub tunable: bool,
    /// Set by SIGINT/SIGTERM.
    pub stop: StopFlag,
}
