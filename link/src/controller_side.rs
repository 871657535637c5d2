//! The controller's handle on a run: wait for states, publish commands, learn that the plant
//! is gone. Nothing here allocates after [`ControllerEndpoint::open`].

use crate::invalid::{InvalidCounts, InvalidMessage};
use crate::transport::{ControllerTransport, open};
use crate::wire::group_code;
use crate::{LinkError, Refusal, Role, TransportKind, check_run_name, clock};
use eqtrack_controller::GroupKind;
use ipc_types::{CommandMsg, Identity, PROTOCOL_VERSION, StateMsg, check_state, flags};
use std::time::{Duration, Instant};

/// How to open the controller's side of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerEndpointConfig {
    /// The run name.
    pub run: String,
    /// The transport.
    pub transport: TransportKind,
    /// The controller's group.
    pub group: GroupKind,
    /// A control period the controller insists on (s); `None`: it follows the plant's.
    pub period: Option<f64>,
    /// The fingerprint of the controller's scenario (0: none, accept any plant).
    pub fingerprint: u64,
    /// The scenario's name.
    pub scenario: String,
}

/// What [`ControllerEndpoint::wait_state`] saw.
#[derive(Debug, Clone, Copy, PartialEq)]
// the state is returned by value: boxing it would allocate on every cycle
#[allow(clippy::large_enum_variant)]
pub enum Incoming {
    /// A state that passed the checks, and when it was received (CLOCK_MONOTONIC ns).
    State(StateMsg, u64),
    /// The plant ended the run.
    Shutdown,
    /// The first state's settings differ from the controller's: the plant has been told
    /// (it stops), and so should the controller.
    Mismatch(Refusal),
    /// The plant's process is gone (checked when it has been silent for 100 ms).
    PlantGone,
    /// Nothing within the timeout.
    Nothing,
}

/// How long a silence lasts before the plant's liveness is checked, and how often.
const LIVENESS_EVERY: Duration = Duration::from_millis(100);

/// The controller's side of a run.
///
/// A controller process in outline (`controller_node` is the whole thing, with the law):
///
/// ```no_run
/// use eqtrack_controller::GroupKind;
/// use link::{ControllerEndpointConfig, ControllerEndpoint, Incoming, TransportKind};
/// use nalgebra::Vector3;
/// use std::time::Duration;
///
/// let mut ctl = ControllerEndpoint::open(ControllerEndpointConfig {
///     run: "board1".into(),
///     transport: TransportKind::Iceoryx2,
///     group: GroupKind::So3,
///     period: None,       // follow the plant's control period
///     fingerprint: 0,     // no scenario: accept any plant of the group
///     scenario: String::new(),
/// })?;
/// loop {
///     match ctl.wait_state(Duration::from_secs(1)) {
///         Incoming::State(state, _received_ns) => {
///             let (_q, _v) = (state.configuration::<3>(), state.velocity::<3>());
///             let mut cmd = ctl.command(state.seq);
///             cmd.set_torque(&Vector3::<f64>::zeros()); // the law's torque for (q, v)
///             ctl.publish(&cmd)?;
///         }
///         Incoming::Nothing => continue,
///         Incoming::Shutdown | Incoming::PlantGone | Incoming::Mismatch(_) => break,
///     }
/// }
/// # Ok::<(), link::LinkError>(())
/// ```
pub struct ControllerEndpoint {
    transport: ControllerTransport,
    config: ControllerEndpointConfig,
    identity: Identity,
    rejections: InvalidCounts<StateMsg>,
    last_seq: Option<u64>,
    period: Option<f64>,
    plant_pid: u32,
    plant_sleeps: bool,
    last_heard: Instant,
    last_check: Instant,
}

impl ControllerEndpoint {
    /// Opens the controller's side of run `config.run` (a plant may come before or after).
    pub fn open(config: ControllerEndpointConfig) -> Result<ControllerEndpoint, LinkError> {
        check_run_name(&config.run)?;
        let transport = open(config.transport, &config.run, Role::Controller)?;
        let identity = Identity::new(
            crate::wire::wire_group(config.group),
            config.period.unwrap_or(0.0),
            config.fingerprint,
            &config.scenario,
        );
        Ok(ControllerEndpoint {
            transport,
            config,
            identity,
            rejections: InvalidCounts::new(),
            last_seq: None,
            period: None,
            plant_pid: 0,
            plant_sleeps: false,
            last_heard: Instant::now(),
            last_check: Instant::now(),
        })
    }

    /// The controller's identity as it tells a plant that does not match.
    pub fn identity(&self) -> &Identity {
        &self.identity
    }

    /// Whether a plant has been heard from.
    pub fn connected(&self) -> bool {
        self.period.is_some()
    }

    /// The plant's control period (after its first state).
    pub fn period(&self) -> Option<f64> {
        self.period
    }

    /// Whether the plant sleeps while waiting for commands (it is notified after each).
    pub fn plant_sleeps(&self) -> bool {
        self.plant_sleeps
    }

    /// Waits up to `timeout` for the next state. Before the first state it polls every
    /// millisecond; then it sleeps when the plant says it does, and busy-polls otherwise.
    pub fn wait_state(&mut self, timeout: Duration) -> Incoming {
        let until = Instant::now() + timeout;
        loop {
            while let Some(msg) = self.transport.receive() {
                if let Some(incoming) = self.judge(msg) {
                    return incoming;
                }
            }
            let now = Instant::now();
            if self.connected() && self.plant_gone_after_silence(now) {
                return Incoming::PlantGone;
            }
            if now >= until {
                // a last look: a state that came while this process was not running (stopped,
                // or preempted on a busy machine) is read, not taken for silence
                while let Some(msg) = self.transport.receive() {
                    if let Some(incoming) = self.judge(msg) {
                        return incoming;
                    }
                }
                return Incoming::Nothing;
            }
            let left = until - now;
            if !self.connected() {
                self.transport.wait(left.min(Duration::from_millis(1)));
            } else if self.plant_sleeps {
                self.transport.wait(left.min(LIVENESS_EVERY));
            } else {
                std::hint::spin_loop();
            }
        }
    }

    /// What one received state means (`None`: rejected, keep waiting).
    fn judge(&mut self, msg: StateMsg) -> Option<Incoming> {
        if msg.version == PROTOCOL_VERSION && msg.flags & flags::SHUTDOWN != 0 {
            return Some(Incoming::Shutdown);
        }
        let received = clock::monotonic_ns();
        if !self.connected() && msg.version == PROTOCOL_VERSION {
            let bits = self.identity.mismatch(&msg.identity());
            if bits != 0 {
                let refusal = CommandMsg::refusal(&self.identity, msg.seq, bits);
                let _ = self.transport.send(&refusal, true);
                return Some(Incoming::Mismatch(Refusal {
                    mismatch: bits,
                    plant: msg.identity(),
                    controller: self.identity,
                }));
            }
        }
        match check_state(
            &msg,
            crate::wire::wire_group(self.config.group),
            self.last_seq,
            self.period,
        ) {
            Ok(()) => {
                self.last_seq = Some(msg.seq);
                self.period = Some(msg.control_period);
                self.plant_pid = msg.plant_pid;
                self.plant_sleeps = msg.flags & flags::WAKE_EVENT != 0;
                self.last_heard = Instant::now();
                Some(Incoming::State(msg, received))
            }
            Err(kind) => {
                self.rejections.record(kind, &msg);
                None
            }
        }
    }

    /// After 100 ms of silence, every 100 ms: whether the plant's process is gone.
    fn plant_gone_after_silence(&mut self, now: Instant) -> bool {
        if now - self.last_heard < LIVENESS_EVERY || now - self.last_check < LIVENESS_EVERY {
            return false;
        }
        self.last_check = now;
        !self.plant_alive()
    }

    /// Whether the plant's process exists: `kill(pid, 0)` on the pid its states carry (no
    /// allocation; a plant that sent no pid counts as alive). A stopped (SIGSTOP) plant is
    /// alive; one that was killed and reaped is not.
    pub fn plant_alive(&self) -> bool {
        crate::process::process_alive(self.plant_pid)
    }

    /// How long since the last accepted state.
    pub fn silence(&self) -> Duration {
        self.last_heard.elapsed()
    }

    /// A command for the state of `seq` with this controller's group filled in.
    pub fn command(&self, seq: u64) -> CommandMsg {
        let mut c = CommandMsg::new(crate::wire::wire_group(self.config.group));
        c.group = group_code(self.config.group);
        c.seq = seq;
        c
    }

    /// Publishes a command (stamped now), waking the plant if it sleeps.
    pub fn publish(&mut self, cmd: &CommandMsg) -> Result<u64, LinkError> {
        self.transport.send(cmd, self.plant_sleeps)
    }

    /// The first rejected state of a kind not reported yet (log it; later ones of that kind
    /// are only counted).
    pub fn next_invalid(&mut self) -> Option<InvalidMessage<StateMsg>> {
        self.rejections.next()
    }

    /// Rejected states per [`ipc_types::Invalid`] kind.
    pub fn invalid_states(&self) -> [u64; ipc_types::Invalid::KINDS] {
        self.rejections.counts()
    }
}
