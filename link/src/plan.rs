//! The streamed reference over iceoryx2: a planner process publishes windows of path segments
//! ([`PlanMsg`]) on the run's `plan` board and watches the plant's clock on its `state` board;
//! the controller reads the plan board after each command. Like the pair's boards, the plan
//! board has [`SLOTS`](crate::iceoryx2::SLOTS) writer slots, so a planner started after one
//! was killed takes a free slot, and the reader picks up whichever slot was written last.
//! Nothing here allocates after `open`.

use crate::iceoryx2::{BoardReader, BoardWriter, create_node};
use crate::{LinkError, check_run_name, clock};
use iceoryx2::prelude::*;
use ipc_types::{PlanMsg, StateMsg};

/// The planner's side of a run: publishes plans, watches the plant's states.
pub struct PlanWriter {
    out: BoardWriter<PlanMsg>,
    states: BoardReader<StateMsg>,
    _node: Node<ipc::Service>,
    seq: u64,
}

impl PlanWriter {
    /// Opens the planner's side of run `run` (before or after the pair).
    pub fn open(run: &str) -> Result<PlanWriter, LinkError> {
        let names = check_run_name(run)?;
        let node = create_node(&names.planner_node)?;
        Ok(PlanWriter {
            out: BoardWriter::open(
                &node,
                &names.plan,
                " (is another planner running on this run?)",
            )?,
            states: BoardReader::open(&node, &names.state, "")?,
            _node: node,
            seq: 0,
        })
    }

    /// Publishes `msg` with the next sequence number, a stamp and this process's id.
    pub fn publish(&mut self, msg: &PlanMsg) {
        let mut m = *msg;
        self.seq += 1;
        m.seq = self.seq;
        m.stamp_ns = clock::monotonic_ns();
        m.planner_pid = std::process::id();
        self.out.write(m);
    }

    /// The plant's newest state on the board (any slot), if it has published one.
    pub fn plant(&self) -> Option<StateMsg> {
        self.states.newest()
    }

    /// The writer slot this planner took (0 unless crashed planners hold earlier ones).
    pub fn slot(&self) -> u32 {
        self.out.slot()
    }
}

/// The controller's side of the plan board.
pub struct PlanReader {
    board: BoardReader<PlanMsg>,
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
        Ok(PlanReader {
            board: BoardReader::open(&node, &names.plan, "")?,
            _node: node,
        })
    }

    /// A plan message not seen yet, or `None`; call until `None`. Unchecked: pass it through
    /// [`ipc_types::check_plan`].
    pub fn receive(&mut self) -> Option<PlanMsg> {
        self.board.receive()
    }
}
