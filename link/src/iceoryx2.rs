//! Opening a run's services with iceoryx2 (`std` feature). Both processes call
//! [`PlantPorts::open`] / [`ControllerPorts::open`], so their settings are identical by
//! construction.
//!
//! Each direction is an iceoryx2 **blackboard** entry in shared memory — a latest-value slot
//! that the writer updates in place and the reader loads, both with atomics only, so a cycle
//! allocates nothing. (In iceoryx2 0.10 every publish-subscribe send allocates a reference
//! count for the loaned sample; the blackboard's entry handles do not.) Messages carry a
//! sequence number and a timestamp, so a reader tells a new message from one it has seen.
//! Two event services wake a sleeping reader in event mode.

use crate::{CommandMsg, StateMsg, service_names};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::reader::{EntryHandle, Reader};
use iceoryx2::port::writer::{EntryHandleMut, Writer};
use iceoryx2::prelude::*;
use iceoryx2::service::builder::blackboard::{BlackboardCreateError, BlackboardOpenError};
use iceoryx2::service::port_factory::blackboard::PortFactory as BoardFactory;
use iceoryx2::service::port_factory::event::PortFactory as EventFactory;
use std::time::{Duration, Instant};

/// CLOCK_MONOTONIC in nanoseconds: the clock of every timestamp in the messages (one clock
/// for all processes on a machine).
pub fn monotonic_ns() -> u64 {
    match nix::time::clock_gettime(nix::time::ClockId::CLOCK_MONOTONIC) {
        Ok(ts) => ts.tv_sec() as u64 * 1_000_000_000 + ts.tv_nsec() as u64,
        Err(_) => 0,
    }
}

/// Entries (writer slots) per board.
pub const SLOTS: u32 = 8;

/// What one side of the pair needs from a transport: iceoryx2 ([`Ports`]) or the Unix-socket
/// baseline ([`crate::uds::UdsLink`]).
pub trait Link<Out, In> {
    /// Stamps and sends a message; returns its timestamp.
    fn send(&self, msg: Out) -> u64;
    /// A message not seen yet, or `None`.
    fn receive(&self) -> Option<In>;
    /// Wakes the other side if it sleeps (event mode).
    fn notify(&self);
    /// Sleeps until a message may have arrived or `timeout` passes, with high-resolution
    /// timing (for a waiter with a deadline; may allocate).
    fn wait_notified(&self, timeout: Duration) -> bool;
    /// Sleeps until a message may have arrived or roughly `timeout` passes; allocation-free
    /// (for the controller, which has no deadline of its own).
    fn wait(&self, timeout: Duration);
    /// Sends the last message again, unchanged (for a peer that connects late).
    fn resend(&self);
}

/// A message type that can travel on a board.
pub trait Message: Copy + core::fmt::Debug + ZeroCopySend + 'static {
    /// The value the slot holds before anything was written (version 0: "nothing yet").
    fn empty() -> Self;
    /// `(seq, stamp_ns)`: identifies one write.
    fn identity(&self) -> (u64, u64);
    /// Stamps the message with the current time just before it is written.
    fn stamp(&mut self);
}

impl Message for StateMsg {
    fn empty() -> Self {
        let mut m = StateMsg::new(0);
        m.version = 0;
        m
    }
    fn identity(&self) -> (u64, u64) {
        (self.seq, self.stamp_ns)
    }
    fn stamp(&mut self) {
        self.stamp_ns = monotonic_ns();
    }
}

impl Message for CommandMsg {
    fn empty() -> Self {
        let mut m = CommandMsg::new(0);
        m.version = 0;
        m
    }
    fn identity(&self) -> (u64, u64) {
        (self.seq, self.stamp_ns)
    }
    fn stamp(&mut self) {
        self.stamp_ns = monotonic_ns();
    }
}

/// The services a side keeps open while it runs.
type Factories = (
    BoardFactory<ipc::Service, u32>,
    BoardFactory<ipc::Service, u32>,
    EventFactory<ipc::Service>,
    EventFactory<ipc::Service>,
);

/// The ports of one side of a run.
pub struct Ports<Out: Message, In: Message> {
    out: EntryHandleMut<ipc::Service, u32, Out>,
    /// The slot this side writes.
    pub slot: u32,
    inp: Vec<EntryHandle<ipc::Service, u32, In>>,
    last_in: Vec<core::cell::Cell<(u64, u64)>>,
    /// Wakes the other side (event mode).
    pub notifier: Notifier<ipc::Service>,
    /// Wakes this side (event mode).
    pub listener: Listener<ipc::Service>,
    _ports: (Writer<ipc::Service, u32>, Reader<ipc::Service, u32>),
    _factories: Factories,
}

/// The plant's side: writes states, reads commands.
pub type PlantPorts = Ports<StateMsg, CommandMsg>;
/// The controller's side: writes commands, reads states.
pub type ControllerPorts = Ports<CommandMsg, StateMsg>;

/// Any failure while setting up IPC, as text (the caller adds context).
pub type SetupError = String;

fn err<E: core::fmt::Debug>(what: &str) -> impl Fn(E) -> SetupError + '_ {
    move |e| format!("{what}: {e:?}")
}

/// iceoryx2 logs at error level unless `IOX2_LOG_LEVEL` says otherwise, and sleeps end
/// when asked, not up to 50 µs later (the default timer slack). Called by every function
/// here that touches iceoryx2.
fn init() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        set_log_level_from_env_or(LogLevel::Error);
        let _ = nix::sys::prctl::set_timerslack(1);
    });
}

/// Creates this process's node for `run` (`plant` or `controller` role), after removing the
/// stale resources of dead nodes (a crashed process leaves shared memory behind).
pub fn node(run: &str, role: &str) -> Result<Node<ipc::Service>, SetupError> {
    let names = service_names(run)
        .ok_or_else(|| format!("invalid run name `{run}` (1-64 of A-Z a-z 0-9 _ -)"))?;
    init();
    remove_stale_nodes();
    let name = if role == "plant" {
        &names.plant_node
    } else {
        &names.controller_node
    };
    let node_name: NodeName = name.as_str().try_into().map_err(err("node name"))?;
    NodeBuilder::new()
        .name(&node_name)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(err("cannot create iceoryx2 node"))
}

/// Removes the stale resources of every dead node; returns how many were removed.
pub fn remove_stale_nodes() -> usize {
    init();
    let mut dead = Vec::new();
    let _ = Node::<ipc::Service>::list(Config::global_config(), |state| {
        if let NodeState::Dead(view) = state {
            dead.push(view);
        }
        CallbackProgression::Continue
    });
    dead.into_iter()
        .filter(|v| v.clone().try_remove_stale_resources().is_ok())
        .count()
}

/// Whether a node with this name exists and is alive.
pub fn node_alive(name: &str) -> bool {
    init();
    use iceoryx2::node::NodeView;
    let mut alive = false;
    let _ = Node::<ipc::Service>::list(Config::global_config(), |state| {
        if let NodeState::Alive(view) = &state
            && view
                .details()
                .as_ref()
                .is_some_and(|d| d.name().as_str() == name)
        {
            alive = true;
            return CallbackProgression::Stop;
        }
        CallbackProgression::Continue
    });
    alive
}

fn board<T: Message>(
    node: &Node<ipc::Service>,
    name: &str,
) -> Result<BoardFactory<ipc::Service, u32>, SetupError> {
    let service_name: ServiceName = name.try_into().map_err(err("service name"))?;
    let until = Instant::now() + Duration::from_secs(5);
    loop {
        match node
            .service_builder(&service_name)
            .blackboard_opener::<u32>()
            .max_readers(2)
            .max_nodes(4)
            .open()
        {
            Ok(f) => return Ok(f),
            Err(BlackboardOpenError::DoesNotExist) => {}
            Err(e) => return Err(format!("{name}: {e:?}")),
        }
        let mut creator = node
            .service_builder(&service_name)
            .blackboard_creator::<u32>()
            .max_readers(2)
            .max_nodes(4);
        for slot in 0..SLOTS {
            creator = creator.add::<T>(slot, T::empty());
        }
        match creator.create() {
            Ok(f) => return Ok(f),
            Err(BlackboardCreateError::AlreadyExists)
            | Err(BlackboardCreateError::IsBeingCreatedByAnotherInstance) => {}
            Err(e) => return Err(format!("{name}: {e:?}")),
        }
        if Instant::now() > until {
            return Err(format!("{name}: could neither open nor create the service"));
        }
        std::thread::sleep(Duration::from_millis(1));
    }
}

fn event(node: &Node<ipc::Service>, name: &str) -> Result<EventFactory<ipc::Service>, SetupError> {
    let service_name: ServiceName = name.try_into().map_err(err("service name"))?;
    node.service_builder(&service_name)
        .event()
        .max_notifiers(2)
        .max_listeners(2)
        .max_nodes(4)
        .open_or_create()
        .map_err(err(name))
}

impl<Out: Message, In: Message> Ports<Out, In> {
    fn open_named(
        node: &Node<ipc::Service>,
        out_name: &str,
        in_name: &str,
        notify_name: &str,
        listen_name: &str,
    ) -> Result<Self, SetupError> {
        let out_board = board::<Out>(node, out_name)?;
        let in_board = board::<In>(node, in_name)?;
        let notify = event(node, notify_name)?;
        let listen = event(node, listen_name)?;
        let writer = out_board.writer_builder().create().map_err(err(
            "blackboard writer (is another process writing this run?)",
        ))?;
        let reader = in_board
            .reader_builder()
            .create()
            .map_err(err("blackboard reader"))?;
        let (slot, out) = (0..SLOTS)
            .find_map(|slot| writer.entry::<Out>(&slot).ok().map(|h| (slot, h)))
            .ok_or_else(|| format!("{out_name}: all {SLOTS} writer slots are taken (held by running or crashed processes of this run); end both processes or use another run name"))?;
        let inp = (0..SLOTS)
            .map(|slot| reader.entry::<In>(&slot).map_err(err("blackboard entry")))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Ports {
            out,
            slot,
            last_in: inp
                .iter()
                .map(|_| core::cell::Cell::new(In::empty().identity()))
                .collect(),
            inp,
            notifier: notify
                .notifier_builder()
                .create()
                .map_err(err("notifier"))?,
            listener: listen
                .listener_builder()
                .create()
                .map_err(err("listener"))?,
            _ports: (writer, reader),
            _factories: (out_board, in_board, notify, listen),
        })
    }

    /// Stamps and writes a message; returns its timestamp. Allocation-free.
    pub fn send(&self, msg: Out) -> u64 {
        let mut m = msg;
        m.stamp();
        self.out.update_with_copy(m);
        m.identity().1
    }

    /// Waits until the other side notifies or `timeout` passes, with the precision of
    /// select(2) on the listener's descriptor (high-resolution timers) — unlike the
    /// listener's own timed wait, whose socket timeout counts in scheduler ticks. Drains the
    /// listener; true when a notification arrived. (iceoryx2's descriptor set allocates: this
    /// is for the plant, not for the controller's loop.)
    pub fn wait_notified(&self, timeout: Duration) -> bool {
        use iceoryx2_bb_posix::file_descriptor_set::{FileDescriptorSet, FileEvent};
        let set = FileDescriptorSet::new();
        let notified = match set.add(&self.listener) {
            Ok(_guard) => {
                set.timed_wait(timeout, FileEvent::Read, |_| {})
                    .unwrap_or(0)
                    > 0
            }
            Err(_) => false,
        };
        let _ = self.listener.try_wait(|_| {});
        notified
    }

    /// A message this side has not seen yet, from any slot (`None`: nothing new). Call it
    /// until `None` to see every new message. Allocation-free.
    pub fn receive(&self) -> Option<In> {
        for (entry, last) in self.inp.iter().zip(&self.last_in) {
            let m: In = *entry.get();
            let id = m.identity();
            if id != last.get() && id != In::empty().identity() {
                last.set(id);
                return Some(m);
            }
        }
        None
    }
}

impl<Out: Message, In: Message> Link<Out, In> for Ports<Out, In> {
    fn send(&self, msg: Out) -> u64 {
        Ports::send(self, msg)
    }
    fn receive(&self) -> Option<In> {
        Ports::receive(self)
    }
    fn notify(&self) {
        let _ = self.notifier.notify();
    }
    fn wait_notified(&self, timeout: Duration) -> bool {
        Ports::wait_notified(self, timeout)
    }
    fn wait(&self, timeout: Duration) {
        let _ = self.listener.timed_wait(|_| {}, timeout);
    }
    fn resend(&self) {
        // the slot keeps its last value: a late reader finds it there
    }
}

impl PlantPorts {
    /// The plant's ports of run `run`.
    pub fn open(node: &Node<ipc::Service>, run: &str) -> Result<Self, SetupError> {
        let n = service_names(run).ok_or_else(|| format!("invalid run name `{run}`"))?;
        Self::open_named(node, &n.state, &n.command, &n.state_event, &n.command_event)
    }
}

impl ControllerPorts {
    /// The controller's ports of run `run`.
    pub fn open(node: &Node<ipc::Service>, run: &str) -> Result<Self, SetupError> {
        let n = service_names(run).ok_or_else(|| format!("invalid run name `{run}`"))?;
        Self::open_named(node, &n.command, &n.state, &n.command_event, &n.state_event)
    }
}
