//! The plant's handle on a run: publish states, wait for commands with a deadline.

use crate::deadline::Arrival;
use crate::invalid::{InvalidCounts, InvalidMessage};
use crate::transport::{PlantTransport, open};
use crate::{LinkError, Role, TransportKind, Wake, check_run_name, clock};
use eqtrack_controller::GroupKind;
use ipc_types::{
    CommandMsg, Identity, Invalid, PROTOCOL_VERSION, StateMsg, check_command, flags, mismatch,
};
use nalgebra::{SMatrix, SVector};
use std::fmt;
use std::time::Duration;

/// How to open the plant's side of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantEndpointConfig {
    /// The run name (services and sockets derive from it).
    pub run: String,
    /// The plant's group.
    pub group: GroupKind,
    /// The control period (s): states carry `t_k = k·period`, and the controller's reference
    /// steps with it.
    pub control_period: f64,
    /// The transport.
    pub transport: TransportKind,
    /// Whether this plant sleeps while it waits for a command (the controller then wakes
    /// it) or busy-polls.
    pub wake: Wake,
    /// A fingerprint of the scenario this plant simulates (0: none — a hardware plant).
    pub fingerprint: u64,
    /// The scenario's name (empty: none).
    pub scenario: String,
    /// The vehicle's actuator count (0: no vehicle, the commands carry the wrench to
    /// apply); a command with another count is rejected.
    pub actuators: u32,
}

impl PlantEndpointConfig {
    /// A hardware plant's configuration: iceoryx2, event wake-up, no scenario fingerprint.
    pub fn new(run: &str, group: GroupKind, control_period: f64) -> PlantEndpointConfig {
        PlantEndpointConfig {
            run: run.to_owned(),
            group,
            control_period,
            transport: TransportKind::Iceoryx2,
            wake: Wake::Event,
            fingerprint: 0,
            scenario: String::new(),
            actuators: 0,
        }
    }
}

/// A command that passed the checks, and when it arrived.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Command {
    /// The message.
    pub msg: CommandMsg,
    /// CLOCK_MONOTONIC when it was received (ns).
    pub received_ns: u64,
}

impl Command {
    /// The torque `τ_k` (m entries; the controller has saturated it with its own limit).
    pub fn torque<const M: usize>(&self) -> SVector<f64, M> {
        self.msg.torque()
    }

    /// What the [`crate::DeadlinePolicy`] needs to know about it.
    pub fn arrival(&self) -> Arrival {
        Arrival {
            seq: self.msg.seq,
            at_ns: self.received_ns,
        }
    }
}

/// The controller refused the run: the two sides' settings differ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refusal {
    /// The [`mismatch`] bits.
    pub mismatch: u32,
    /// The plant's settings.
    pub plant: Identity,
    /// The controller's settings.
    pub controller: Identity,
}

impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut what = Vec::new();
        for (bit, name) in [
            (mismatch::GROUP, "group"),
            (mismatch::PERIOD, "control period"),
            (mismatch::SCENARIO, "scenario"),
        ] {
            if self.mismatch & bit != 0 {
                what.push(name);
            }
        }
        write!(
            f,
            "configuration mismatch ({}): plant: {}; controller: {}",
            what.join(", "),
            self.plant,
            self.controller
        )
    }
}

/// Why [`PlantEndpoint::wait_command`] returned without a command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NoCommand {
    /// The deadline passed first.
    Missed,
    /// The controller refused the run (configuration mismatch): stop.
    Refused(Refusal),
}

/// The plant's side of a run (a plant process in outline is the crate documentation's example;
/// the whole one is `examples/example_plant.rs`).
pub struct PlantEndpoint {
    transport: PlantTransport,
    config: PlantEndpointConfig,
    identity: Identity,
    rejections: InvalidCounts<CommandMsg>,
    template: StateMsg,
    last_seq: u64,
    late: u64,
}

impl PlantEndpoint {
    /// Opens the plant's side of run `config.run`. With iceoryx2 it fails if a live plant
    /// already holds the run; shared memory left by crashed processes is removed first.
    pub fn open(config: PlantEndpointConfig) -> Result<PlantEndpoint, LinkError> {
        check_run_name(&config.run)?;
        if config.transport == TransportKind::Iceoryx2
            && crate::iceoryx2::node_alive(&config.run, Role::Plant)?
        {
            return Err(LinkError::AlreadyRunning {
                role: Role::Plant,
                run: config.run,
            });
        }
        let transport = open(config.transport, &config.run, Role::Plant)?;
        Ok(PlantEndpoint::with_transport(config, transport))
    }

    /// The plant's side over a transport opened by the caller (the processor-in-the-loop
    /// serial link, [`crate::serial::SerialTransport`]); `config.transport` is not used.
    pub fn with_transport(config: PlantEndpointConfig, transport: PlantTransport) -> PlantEndpoint {
        let identity = Identity::new(
            crate::wire::wire_group(config.group),
            config.control_period,
            config.fingerprint,
            &config.scenario,
        );
        let mut template = StateMsg::new(crate::wire::wire_group(config.group));
        template.control_period = config.control_period;
        template.flags = if config.wake == Wake::Event {
            flags::WAKE_EVENT
        } else {
            0
        };
        template.plant_pid = std::process::id();
        template.fingerprint = identity.fingerprint;
        template.scenario = identity.scenario;
        PlantEndpoint {
            transport,
            config,
            identity,
            rejections: InvalidCounts::new(),
            template,
            last_seq: 0,
            late: 0,
        }
    }

    /// The configuration it was opened with.
    pub fn config(&self) -> &PlantEndpointConfig {
        &self.config
    }

    /// Publishes the state of tick `seq`: configuration `q` and body velocity `v` at
    /// `t = seq·period`, and `applied`, the torque the actuators applied over the last
    /// period (zero at the first tick; the controller's disturbance-rejection terms need it).
    /// Returns its publication stamp (CLOCK_MONOTONIC ns).
    pub fn publish<const N: usize, const M: usize>(
        &mut self,
        seq: u64,
        q: &SMatrix<f64, N, N>,
        v: &SVector<f64, M>,
        applied: &SVector<f64, M>,
    ) -> Result<u64, LinkError> {
        let mut msg = self.template;
        msg.seq = seq;
        msg.t = seq as f64 * self.config.control_period;
        msg.set_state(q, v);
        msg.set_applied(applied);
        self.publish_message(&msg)
    }

    /// Publishes a state message as it is (for tests that need a malformed one; prefer
    /// [`PlantEndpoint::publish`], which fills in [`PlantEndpoint::state_template`]).
    pub fn publish_message(&mut self, msg: &StateMsg) -> Result<u64, LinkError> {
        self.last_seq = msg.seq;
        self.transport.send(msg, self.config.wake == Wake::Event)
    }

    /// The run's state message without a state: this plant's group, period, wake-up flag,
    /// pid and identity filled in.
    pub fn state_template(&self) -> StateMsg {
        self.template
    }

    /// Waits until the command for tick `seq` arrives or CLOCK_MONOTONIC reaches
    /// `deadline_ns`. Commands that fail the checks are never returned (see
    /// [`PlantEndpoint::next_invalid`]); commands for earlier ticks are skipped (counted in
    /// [`PlantEndpoint::late_commands`]).
    pub fn wait_command(&mut self, seq: u64, deadline_ns: u64) -> Result<Command, NoCommand> {
        loop {
            while let Some(msg) = self.transport.receive() {
                if let Some(outcome) = self.judge(msg, seq) {
                    return outcome;
                }
            }
            let now = clock::monotonic_ns();
            if now >= deadline_ns {
                return Err(NoCommand::Missed);
            }
            match self.config.wake {
                Wake::Spin => std::hint::spin_loop(),
                Wake::Event => self.transport.wait(Duration::from_nanos(deadline_ns - now)),
            }
        }
    }

    /// What one received command means for the wait for `seq` (`None`: keep waiting).
    fn judge(&mut self, msg: CommandMsg, seq: u64) -> Option<Result<Command, NoCommand>> {
        if msg.version == PROTOCOL_VERSION && msg.flags & flags::REFUSED != 0 {
            return Some(Err(NoCommand::Refused(Refusal {
                mismatch: msg.mismatch,
                plant: self.identity,
                controller: msg.identity(),
            })));
        }
        match check_command(
            &msg,
            crate::wire::wire_group(self.config.group),
            seq,
            self.config.actuators,
        ) {
            Ok(()) => Some(Ok(Command {
                msg,
                received_ns: clock::monotonic_ns(),
            })),
            Err(Invalid::Sequence) if msg.seq < seq => {
                self.late += 1;
                None
            }
            Err(kind) => {
                self.rejections.record(kind, &msg);
                None
            }
        }
    }

    /// The first rejected command of a kind not reported yet (log it; later ones of that kind
    /// are only counted).
    pub fn next_invalid(&mut self) -> Option<InvalidMessage<CommandMsg>> {
        self.rejections.next()
    }

    /// Commands rejected by the checks (never applied).
    pub fn invalid_commands(&self) -> u64 {
        self.rejections.counts().iter().sum()
    }

    /// Commands for earlier ticks that arrived while waiting for a later one.
    pub fn late_commands(&self) -> u64 {
        self.late
    }

    /// Ends the run: tells the controller (it exits cleanly). The services close when the
    /// endpoint is dropped.
    pub fn shutdown(&mut self) {
        let mut bye = self.template;
        bye.seq = self.last_seq.saturating_add(1);
        bye.flags |= flags::SHUTDOWN;
        // the controller also notices the plant's exit by itself if this cannot be sent
        let _ = self.transport.send(&bye, true);
    }
}
