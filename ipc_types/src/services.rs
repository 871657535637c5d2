//! The service names of a run.

use core::fmt::Write;

/// A service name, at most 200 bytes.
pub type Name = heapless::String<200>;

/// The names of one run's services: `eqtrack/<run>/{state, command, state_event,
/// command_event, plan, status}`, and the nodes. Several runs with different names never share a
/// service.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ServiceNames {
    /// Plant → controller states.
    pub state: Name,
    /// Controller → plant commands.
    pub command: Name,
    /// Notified after each state (event wake-up).
    pub state_event: Name,
    /// Notified after each command (event wake-up).
    pub command_event: Name,
    /// Planner → controller pieces of a streamed reference.
    pub plan: Name,
    /// The plant's flight recorder → monitors: the run's live status.
    pub status: Name,
    /// Plant → controller: the gains in force ([`ParamMsg`](crate::ParamMsg)), in a run started
    /// with `--tunable`.
    pub params: Name,
    /// The run's request-response service for reading and changing gains
    /// ([`ParamRequest`](crate::ParamRequest)).
    pub param: Name,
    /// The plant's node name.
    pub plant_node: Name,
    /// The controller's node name.
    pub controller_node: Name,
    /// The planner's node name.
    pub planner_node: Name,
    /// The node of the plant's flight-recorder thread.
    pub recorder_node: Name,
    /// A monitor's node name.
    pub monitor_node: Name,
    /// The live Foxglove bridge's node name (`plant_sim live`: a reader of the state, command
    /// and status boards).
    pub live_node: Name,
    /// The node of the plant's parameter thread (the `param` service's server).
    pub tuning_node: Name,
    /// The node of a `plant_sim param` client.
    pub param_node: Name,
}

/// Whether `run` is a usable run name: 1 to 64 characters of `[A-Za-z0-9_-]`.
pub fn valid_run_name(run: &str) -> bool {
    !run.is_empty()
        && run.len() <= 64
        && run
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
}

/// The service names of run `run`; `None` if the name is not [`valid_run_name`].
pub fn service_names(run: &str) -> Option<ServiceNames> {
    if !valid_run_name(run) {
        return None;
    }
    let make = |prefix: &str, sep: &str, suffix: &str| {
        let mut s = Name::new();
        // at most 64 + 30 bytes: always fits in 200
        let _ = write!(s, "{prefix}{sep}{run}{suffix}");
        s
    };
    Some(ServiceNames {
        state: make("eqtrack", "/", "/state"),
        command: make("eqtrack", "/", "/command"),
        state_event: make("eqtrack", "/", "/state_event"),
        command_event: make("eqtrack", "/", "/command_event"),
        plan: make("eqtrack", "/", "/plan"),
        status: make("eqtrack", "/", "/status"),
        params: make("eqtrack", "/", "/params"),
        param: make("eqtrack", "/", "/param"),
        plant_node: make("eqtrack-plant", "-", ""),
        controller_node: make("eqtrack-controller", "-", ""),
        planner_node: make("eqtrack-planner", "-", ""),
        recorder_node: make("eqtrack-recorder", "-", ""),
        monitor_node: make("eqtrack-monitor", "-", ""),
        live_node: make("eqtrack-live", "-", ""),
        tuning_node: make("eqtrack-tuning", "-", ""),
        param_node: make("eqtrack-param", "-", ""),
    })
}
