//! The iceoryx2 transport, and the node housekeeping of a run.
//!
//! Each direction is an iceoryx2 **blackboard** entry in shared memory — a latest-value slot
//! that the writer updates in place and the reader loads, both with atomics only, so a cycle
//! allocates nothing. (In iceoryx2 0.10 every publish-subscribe send allocates a reference
//! count for the loaned sample; the blackboard's entry handles do not.) Messages carry a
//! sequence number and a timestamp, so a reader tells a new message from one it has seen.
//! A blackboard entry's "has a writer" flag is never released by a writer killed with
//! SIGKILL, so each board has [`SLOTS`] writer slots: a restarted process takes the next free
//! one and the reader scans them all. Two event services wake a sleeping reader.

use crate::transport::{Message, Transport};
use crate::{LinkError, Role, check_run_name, clock};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::reader::{EntryHandle, Reader};
use iceoryx2::port::writer::{EntryHandleMut, Writer};
use iceoryx2::prelude::*;
use iceoryx2::service::builder::blackboard::{BlackboardCreateError, BlackboardOpenError};
use iceoryx2::service::builder::event::{EventCreateError, EventOpenError, EventOpenOrCreateError};
use iceoryx2::service::port_factory::blackboard::PortFactory as BoardFactory;
use iceoryx2::service::port_factory::event::PortFactory as EventFactory;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;
use iceoryx2_bb_posix::file_descriptor_set::{FileDescriptorSet, FileEvent};
use ipc_types::WireGroup;
use std::time::{Duration, Instant};

/// Writer slots (entries) per board.
pub const SLOTS: u32 = 8;

/// A receiving side reads every slot once per this many polls (and the slot that delivered
/// last at every poll).
const FULL_SCAN_EVERY: u32 = 16;

/// Readers and nodes a board admits: the two sides, a planner and observers.
const MAX_READERS: usize = 6;
const MAX_NODES: usize = 8;

/// iceoryx2 logs at error level unless `IOX2_LOG_LEVEL` says otherwise.
fn init() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        set_log_level_from_env_or(LogLevel::Error);
        clock::precise_sleeps();
    });
}

/// Removes the stale resources of every dead iceoryx2 node (a crashed process leaves shared
/// memory behind); returns how many nodes were cleaned. Allocates: for start-up only.
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

/// Whether `role`'s node of run `run` exists and is alive. Allocates: for start-up only.
pub fn node_alive(run: &str, role: Role) -> Result<bool, LinkError> {
    use iceoryx2::node::NodeView;
    let names = check_run_name(run)?;
    let name = node_name(&names, role);
    init();
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
    Ok(alive)
}

fn node_name(names: &ipc_types::ServiceNames, role: Role) -> &str {
    match role {
        Role::Plant => names.plant_node.as_str(),
        Role::Controller => names.controller_node.as_str(),
    }
}

/// One side's ports of a run over iceoryx2. Fields drop in order: the boards (each its
/// ports, then its service), the event ports, the event services, then the node.
pub struct Iceoryx2<Out: Message, In: Message> {
    out: BoardWriter<Out>,
    inp: BoardReader<In>,
    notifier: Notifier<ipc::Service>,
    /// Holds the listener's descriptor (added once at start-up, so waiting never allocates).
    wait_set: FileDescriptorSet,
    listener: Listener<ipc::Service>,
    _events: (EventFactory<ipc::Service>, EventFactory<ipc::Service>),
    _node: Node<ipc::Service>,
}

impl<Out: Message, In: Message> Iceoryx2<Out, In> {
    /// Opens `role`'s side of run `run`: its node (after removing dead nodes' leftovers), the
    /// two boards and the two event services, with the same settings on both sides.
    pub fn open(run: &str, role: Role) -> Result<Self, LinkError> {
        let names = check_run_name(run)?;
        let node = create_node(node_name(&names, role))?;
        let (out_name, in_name, notify_name, listen_name) = match role {
            Role::Plant => (
                &names.state,
                &names.command,
                &names.state_event,
                &names.command_event,
            ),
            Role::Controller => (
                &names.command,
                &names.state,
                &names.command_event,
                &names.state_event,
            ),
        };
        let out = BoardWriter::open(&node, out_name, " (is another process writing this run?)")?;
        let inp = BoardReader::open(&node, in_name, "")?;
        let notify = event(&node, notify_name)?;
        let listen = event(&node, listen_name)?;
        let listener = listen
            .listener_builder()
            .create()
            .map_err(|e| LinkError::iceoryx2(format!("{listen_name}: listener"), e))?;
        let wait_set = FileDescriptorSet::new();
        // The guard would remove the descriptor when dropped; the listener lives exactly as
        // long as the set (both are fields of this struct), so it stays.
        std::mem::forget(
            wait_set
                .add(&listener)
                .map_err(|e| LinkError::iceoryx2("listener descriptor", e))?,
        );
        Ok(Iceoryx2 {
            out,
            inp,
            notifier: notify
                .notifier_builder()
                .create()
                .map_err(|e| LinkError::iceoryx2(format!("{notify_name}: notifier"), e))?,
            wait_set,
            listener,
            _events: (notify, listen),
            _node: node,
        })
    }

    /// The writer slot this side took (0 unless crashed processes hold earlier ones).
    pub fn slot(&self) -> u32 {
        self.out.slot()
    }
}

impl<Out: Message, In: Message> Transport<Out, In> for Iceoryx2<Out, In> {
    fn send(&mut self, msg: &Out, wake_peer: bool) -> Result<u64, LinkError> {
        let mut m = *msg;
        let stamp = clock::monotonic_ns();
        m.set_stamp(stamp);
        self.out.write(m);
        if wake_peer {
            // no listener (a peer that crashed or has not come yet) is not an error: the
            // slot keeps the message for it
            let _ = self.notifier.notify();
            // Hand the CPU to the peer just woken: when both share a CPU, whatever this
            // process does next would otherwise delay the peer's wake-up (measured on a
            // 2-vCPU VM: round trip p50 32-36 µs -> 19-20 µs at 1 kHz; BENCHMARKS.md,
            // section 5). With the peer on another CPU it returns at once.
            std::thread::yield_now();
        }
        Ok(stamp)
    }

    fn receive(&mut self) -> Option<In> {
        self.inp.receive()
    }

    fn wait(&mut self, timeout: Duration) {
        self.inp.woken();
        // select(2) on the listener's descriptor: high-resolution timers, unlike the
        // listener's own timed wait (a socket timeout that counts in scheduler ticks)
        let _ = self.wait_set.timed_wait(timeout, FileEvent::Read, |_| {});
        let _ = self.listener.try_wait(|_| {});
    }
}

/// Creates the node `name` after removing dead nodes' leftovers.
pub(crate) fn create_node(name: &str) -> Result<Node<ipc::Service>, LinkError> {
    init();
    remove_stale_nodes();
    let node_name: NodeName = name
        .try_into()
        .map_err(|e| LinkError::iceoryx2("node name", e))?;
    NodeBuilder::new()
        .name(&node_name)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|e| LinkError::iceoryx2("cannot create the node", e))
}

/// The first writer slot of a board nobody holds (crashed writers keep theirs).
fn free_slot<T: Slot>(
    writer: &Writer<ipc::Service, u32>,
    service: &str,
) -> Result<(u32, EntryHandleMut<ipc::Service, u32, T>), LinkError> {
    (0..SLOTS)
        .find_map(|slot| writer.entry::<T>(&slot).ok().map(|h| (slot, h)))
        .ok_or_else(|| LinkError::SlotsTaken {
            service: service.to_string(),
            slots: SLOTS,
        })
}

/// Read handles on every slot of a board.
fn entries<T: Slot>(
    reader: &Reader<ipc::Service, u32>,
    service: &str,
) -> Result<Vec<EntryHandle<ipc::Service, u32, T>>, LinkError> {
    (0..SLOTS)
        .map(|slot| {
            reader
                .entry::<T>(&slot)
                .map_err(|e| LinkError::iceoryx2(format!("{service}: entry {slot}"), e))
        })
        .collect()
}

/// A reader's view of a board's writer slots. The slot that delivered last is read alone at
/// each poll, so a busy-polling wait reads one entry per poll instead of all of them. Every
/// slot is read after a wake-up ([`Slots::woken`]), after a message found by such a scan
/// (until one finds nothing), and every [`FULL_SCAN_EVERY`] polls, so a peer restarted into
/// another slot is found within microseconds. Allocation-free after `new`.
struct Slots<T: Slot> {
    entries: Vec<EntryHandle<ipc::Service, u32, T>>,
    /// Per slot, the `(seq, stamp)` of the last write seen.
    seen: Vec<(u64, u64)>,
    /// The id of a slot nobody wrote.
    empty: (u64, u64),
    /// The slot that delivered last.
    active: usize,
    /// Polls since start (for the periodic full scan).
    polls: u32,
    /// Read every slot at the next poll.
    scan_all: bool,
}

impl<T: Slot> Slots<T> {
    /// Read handles on every slot.
    fn new(entries: Vec<EntryHandle<ipc::Service, u32, T>>) -> Self {
        let empty = T::empty().write_id();
        Slots {
            seen: vec![empty; entries.len()],
            entries,
            empty,
            active: 0,
            polls: 0,
            scan_all: true,
        }
    }

    /// Read every slot at the next poll (a notification came).
    fn woken(&mut self) {
        self.scan_all = true;
    }

    /// A write not seen yet, or `None`; call until `None`.
    fn receive(&mut self) -> Option<T> {
        if let Some(m) = self.read(self.active) {
            return Some(m);
        }
        self.polls = self.polls.wrapping_add(1);
        if !(self.scan_all || self.polls.is_multiple_of(FULL_SCAN_EVERY)) {
            return None;
        }
        for slot in 0..self.entries.len() {
            if let Some(m) = self.read(slot) {
                self.active = slot;
                self.scan_all = true;
                return Some(m);
            }
        }
        self.scan_all = false;
        None
    }

    /// Slot `slot`'s value if it holds a write not seen yet (remembered as seen).
    fn read(&mut self, slot: usize) -> Option<T> {
        let m: T = *self.entries[slot].get();
        let this = m.write_id();
        if this != self.seen[slot] && this != self.empty {
            self.seen[slot] = this;
            return Some(m);
        }
        None
    }
}

/// What a board's slots hold: a fixed-size, copyable, zero-copy-sendable message with a
/// protocol version, a sequence number and a stamp.
pub trait Slot: Copy + core::fmt::Debug + ZeroCopySend + 'static {
    /// A slot nobody wrote: version 0.
    fn empty() -> Self;
    /// `(seq, stamp)`: tells a write from the one before it.
    fn write_id(&self) -> (u64, u64);
    /// The stamp of a write of the current protocol; `None` for a slot never written or
    /// written by another protocol's process.
    fn current_stamp(&self) -> Option<u64>;
}

macro_rules! slot {
    ($msg:ty, $new:expr) => {
        impl Slot for $msg {
            fn empty() -> Self {
                let mut m: $msg = $new;
                m.version = 0;
                m.group = 0;
                m
            }
            fn write_id(&self) -> (u64, u64) {
                (self.seq, self.stamp_ns)
            }
            fn current_stamp(&self) -> Option<u64> {
                (self.version == ipc_types::PROTOCOL_VERSION).then_some(self.stamp_ns)
            }
        }
    };
}
slot!(
    ipc_types::StateMsg,
    ipc_types::StateMsg::new(WireGroup::So3)
);
slot!(
    ipc_types::CommandMsg,
    ipc_types::CommandMsg::new(WireGroup::So3)
);
slot!(
    ipc_types::StatusMsg,
    ipc_types::StatusMsg::new(WireGroup::So3, "")
);
slot!(ipc_types::PlanMsg, ipc_types::PlanMsg::new(WireGroup::So3));
slot!(
    ipc_types::ParamMsg,
    ipc_types::ParamMsg::new(WireGroup::So3, 0, ipc_types::Gains::ZERO)
);

/// One board opened for writing on a node its owner keeps (declared after this, so that it
/// drops after): the entry of a free writer slot, the writer port and the service. Fields
/// drop in that order.
pub(crate) struct BoardWriter<T: Slot> {
    entry: EntryHandleMut<ipc::Service, u32, T>,
    slot: u32,
    _writer: Writer<ipc::Service, u32>,
    _service: BoardFactory<ipc::Service, u32>,
}

impl<T: Slot> BoardWriter<T> {
    /// Opens (or creates) board `name` on `node` and takes its first free writer slot;
    /// `hint` follows the error when the writer port is refused.
    pub(crate) fn open(
        node: &Node<ipc::Service>,
        name: &str,
        hint: &str,
    ) -> Result<Self, LinkError> {
        let service = board(node, name, T::empty())?;
        let writer = service
            .writer_builder()
            .create()
            .map_err(|e| LinkError::iceoryx2(format!("{name}: writer{hint}"), e))?;
        let (slot, entry) = free_slot::<T>(&writer, name)?;
        Ok(BoardWriter {
            entry,
            slot,
            _writer: writer,
            _service: service,
        })
    }

    /// Writes `m` into this writer's slot: an atomic copy, no allocation.
    pub(crate) fn write(&mut self, m: T) {
        self.entry.update_with_copy(m);
    }

    /// The writer slot taken (0 unless crashed processes hold earlier ones).
    pub(crate) fn slot(&self) -> u32 {
        self.slot
    }
}

/// One board opened for reading on a node its owner keeps (declared after this): the read
/// handles on every slot, the reader port and the service. Fields drop in that order.
pub(crate) struct BoardReader<T: Slot> {
    slots: Slots<T>,
    _reader: Reader<ipc::Service, u32>,
    _service: BoardFactory<ipc::Service, u32>,
}

impl<T: Slot> BoardReader<T> {
    /// Opens (or creates, empty) board `name` on `node` for reading; `hint` follows the
    /// error when the reader port is refused.
    pub(crate) fn open(
        node: &Node<ipc::Service>,
        name: &str,
        hint: &str,
    ) -> Result<Self, LinkError> {
        let service = board(node, name, T::empty())?;
        let reader = service
            .reader_builder()
            .create()
            .map_err(|e| LinkError::iceoryx2(format!("{name}: reader{hint}"), e))?;
        Ok(BoardReader {
            slots: Slots::new(entries::<T>(&reader, name)?),
            _reader: reader,
            _service: service,
        })
    }

    /// The newest write of the current protocol on any slot (the largest stamp), if any.
    pub(crate) fn newest(&self) -> Option<T> {
        self.slots
            .entries
            .iter()
            .map(|e| *e.get())
            .filter_map(|m| m.current_stamp().map(|s| (s, m)))
            .max_by_key(|(s, _)| *s)
            .map(|(_, m)| m)
    }

    /// A write not seen yet, or `None`; call until `None` (see [`Slots`]).
    pub(crate) fn receive(&mut self) -> Option<T> {
        self.slots.receive()
    }

    /// Read every slot at the next [`BoardReader::receive`] (a notification came).
    pub(crate) fn woken(&mut self) {
        self.slots.woken();
    }
}

/// Opens the board `name`, or creates it with [`SLOTS`] entries holding `empty`.
fn board<T: Slot>(
    node: &Node<ipc::Service>,
    name: &str,
    empty: T,
) -> Result<BoardFactory<ipc::Service, u32>, LinkError> {
    let service_name: ServiceName = name
        .try_into()
        .map_err(|e| LinkError::iceoryx2(format!("service name {name}"), e))?;
    let until = Instant::now() + Duration::from_secs(5);
    loop {
        match node
            .service_builder(&service_name)
            .blackboard_opener::<u32>()
            .max_readers(MAX_READERS)
            .max_nodes(MAX_NODES)
            .open()
        {
            Ok(f) => return Ok(f),
            Err(BlackboardOpenError::DoesNotExist) => {}
            // the other process is creating it (or a dead one's is being removed): a passing
            // state, longer on a loaded machine, so try again until the deadline
            Err(
                e @ (BlackboardOpenError::ServiceInCorruptedState
                | BlackboardOpenError::HangsInCreation
                | BlackboardOpenError::IsMarkedForDestruction),
            ) => {
                if Instant::now() > until {
                    return Err(LinkError::iceoryx2(format!("{name}: open"), e));
                }
                std::thread::sleep(Duration::from_millis(1));
                continue;
            }
            Err(e) => return Err(LinkError::iceoryx2(format!("{name}: open"), e)),
        }
        let mut creator = node
            .service_builder(&service_name)
            .blackboard_creator::<u32>()
            .max_readers(MAX_READERS)
            .max_nodes(MAX_NODES);
        for slot in 0..SLOTS {
            creator = creator.add::<T>(slot, empty);
        }
        match creator.create() {
            Ok(f) => return Ok(f),
            Err(BlackboardCreateError::AlreadyExists)
            | Err(BlackboardCreateError::IsBeingCreatedByAnotherInstance) => {}
            Err(e) => return Err(LinkError::iceoryx2(format!("{name}: create"), e)),
        }
        if Instant::now() > until {
            return Err(LinkError::iceoryx2(
                name,
                "could neither open nor create the service within 5 s",
            ));
        }
        std::thread::sleep(Duration::from_millis(1));
    }
}

pub(crate) fn event(
    node: &Node<ipc::Service>,
    name: &str,
) -> Result<EventFactory<ipc::Service>, LinkError> {
    let service_name: ServiceName = name
        .try_into()
        .map_err(|e| LinkError::iceoryx2(format!("service name {name}"), e))?;
    // as for a board: a service another process is still creating is retried, not an error
    let until = Instant::now() + Duration::from_secs(5);
    loop {
        match node
            .service_builder(&service_name)
            .event()
            .max_notifiers(2)
            .max_listeners(2)
            .max_nodes(MAX_NODES)
            .open_or_create()
        {
            Ok(f) => return Ok(f),
            Err(
                e @ (EventOpenOrCreateError::SystemInFlux
                | EventOpenOrCreateError::EventOpenError(
                    EventOpenError::ServiceInCorruptedState
                    | EventOpenError::HangsInCreation
                    | EventOpenError::DoesNotExist,
                )
                | EventOpenOrCreateError::EventCreateError(
                    EventCreateError::IsBeingCreatedByAnotherInstance
                    | EventCreateError::AlreadyExists,
                )),
            ) => {
                if Instant::now() > until {
                    return Err(LinkError::iceoryx2(name, e));
                }
                std::thread::sleep(Duration::from_millis(1));
            }
            Err(e) => return Err(LinkError::iceoryx2(name, e)),
        }
    }
}
