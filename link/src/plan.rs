//! The streamed reference over iceoryx2: a planner process publishes windows of path segments
//! ([`PlanMsg`]) on the run's `plan` board and watches the plant's clock on its `state` board;
//! the controller reads the plan board after each command. Like the pair's boards, the plan
//! board has [`SLOTS`](crate::iceoryx2::SLOTS) writer slots, so a planner started after one
//! was killed takes a free slot, and the reader picks up whichever slot was written last.
//! Nothing here allocates after `open`.

use crate::iceoryx2::{Slots, board, create_node, entries, free_slot, newest};
use crate::{LinkError, check_run_name, clock};
use iceoryx2::port::reader::{EntryHandle, Reader};
use iceoryx2::port::writer::{EntryHandleMut, Writer};
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::blackboard::PortFactory as BoardFactory;
use ipc_types::{PROTOCOL_VERSION, PlanMsg, StateMsg};

/// An empty slot: version 0.
fn empty_plan() -> PlanMsg {
    let mut m = PlanMsg::new(ipc_types::WireGroup::So3);
    m.version = 0;
    m.group = 0;
    m
}

fn empty_state() -> StateMsg {
    <StateMsg as crate::Message>::empty()
}

/// `(seq, stamp)` of a write.
fn plan_id(m: &PlanMsg) -> (u64, u64) {
    (m.seq, m.stamp_ns)
}

/// The planner's side of a run: publishes plans, watches the plant's states.
pub struct PlanWriter {
    out: EntryHandleMut<ipc::Service, u32, PlanMsg>,
    states: Vec<EntryHandle<ipc::Service, u32, StateMsg>>,
    _ports: (Writer<ipc::Service, u32>, Reader<ipc::Service, u32>),
    _services: (
        BoardFactory<ipc::Service, u32>,
        BoardFactory<ipc::Service, u32>,
    ),
    _node: Node<ipc::Service>,
    seq: u64,
    slot: u32,
}

impl PlanWriter {
    /// Opens the planner's side of run `run` (before or after the pair).
    pub fn open(run: &str) -> Result<PlanWriter, LinkError> {
        let names = check_run_name(run)?;
        let node = create_node(&names.planner_node)?;
        let plan_board = board(&node, &names.plan, empty_plan())?;
        let state_board = board(&node, &names.state, empty_state())?;
        let writer = plan_board.writer_builder().create().map_err(|e| {
            LinkError::iceoryx2(
                format!(
                    "{}: writer (is another planner running on this run?)",
                    names.plan
                ),
                e,
            )
        })?;
        let reader = state_board
            .reader_builder()
            .create()
            .map_err(|e| LinkError::iceoryx2(format!("{}: reader", names.state), e))?;
        let (slot, out) = free_slot::<PlanMsg>(&writer, &names.plan)?;
        let states = entries::<StateMsg>(&reader, &names.state)?;
        Ok(PlanWriter {
            out,
            states,
            _ports: (writer, reader),
            _services: (plan_board, state_board),
            _node: node,
            seq: 0,
            slot,
        })
    }

    /// Publishes `msg` with the next sequence number, a stamp and this process's id.
    pub fn publish(&mut self, msg: &PlanMsg) {
        let mut m = *msg;
        self.seq += 1;
        m.seq = self.seq;
        m.stamp_ns = clock::monotonic_ns();
        m.planner_pid = std::process::id();
        self.out.update_with_copy(m);
    }

    /// The plant's newest state on the board (any slot), if it has published one.
    pub fn plant(&self) -> Option<StateMsg> {
        newest(&self.states, |m| {
            (m.version == PROTOCOL_VERSION).then_some(m.stamp_ns)
        })
    }

    /// The writer slot this planner took (0 unless crashed planners hold earlier ones).
    pub fn slot(&self) -> u32 {
        self.slot
    }
}

/// The controller's side of the plan board.
pub struct PlanReader {
    slots: Slots<PlanMsg>,
    _reader: Reader<ipc::Service, u32>,
    _service: BoardFactory<ipc::Service, u32>,
    _node: Node<ipc::Service>,
}

impl PlanReader {
    /// Opens the plan board of run `run` for reading (a planner may come before or after).
    pub fn open(run: &str) -> Result<PlanReader, LinkError> {
        let names = check_run_name(run)?;
        Self::open_as(run, &names.controller_node)
    }

    /// Opens the plan board of run `run` for the plant's flight recorder, which keeps every
    /// plan message it sees so that a streamed run replays (its own node, beside the
    /// controller's reader).
    pub fn for_recorder(run: &str) -> Result<PlanReader, LinkError> {
        let names = check_run_name(run)?;
        Self::open_as(run, &names.recorder_node)
    }

    fn open_as(run: &str, node_name: &str) -> Result<PlanReader, LinkError> {
        let names = check_run_name(run)?;
        let node = create_node(node_name)?;
        let service = board(&node, &names.plan, empty_plan())?;
        let reader = service
            .reader_builder()
            .create()
            .map_err(|e| LinkError::iceoryx2(format!("{}: reader", names.plan), e))?;
        let slots = Slots::new(
            entries::<PlanMsg>(&reader, &names.plan)?,
            plan_id(&empty_plan()),
        );
        Ok(PlanReader {
            slots,
            _reader: reader,
            _service: service,
            _node: node,
        })
    }

    /// A plan message not seen yet, or `None`; call until `None`. Unchecked: pass it through
    /// [`ipc_types::check_plan`].
    pub fn receive(&mut self) -> Option<PlanMsg> {
        self.slots.receive(plan_id)
    }
}
