//! The run's live status over iceoryx2: the plant's flight-recorder thread writes a
//! [`StatusMsg`] on the run's `status` board; monitors read it. Nothing here touches the
//! pair's own boards, so a monitor cannot change the loop's timing. Like the other boards it
//! has [`SLOTS`](crate::iceoryx2::SLOTS) writer slots (a plant restarted after a SIGKILL takes
//! a free one); a reader takes the newest write of any slot.

use crate::iceoryx2::{BoardReader, BoardWriter, create_node};
use crate::{LinkError, check_run_name, clock};
use iceoryx2::prelude::*;
use ipc_types::StatusMsg;

/// The plant's side: publishes the status.
pub struct StatusWriter {
    out: BoardWriter<StatusMsg>,
    _node: Node<ipc::Service>,
    seq: u64,
}

impl StatusWriter {
    /// Opens (or creates) run `run`'s status board for writing.
    pub fn open(run: &str) -> Result<StatusWriter, LinkError> {
        let names = check_run_name(run)?;
        let node = create_node(&names.recorder_node)?;
        Ok(StatusWriter {
            out: BoardWriter::open(&node, &names.status, "")?,
            _node: node,
            seq: 0,
        })
    }

    /// Publishes `msg` with the next sequence number and a stamp. Allocation-free.
    pub fn publish(&mut self, msg: &StatusMsg) {
        let mut m = *msg;
        self.seq += 1;
        m.seq = self.seq;
        m.stamp_ns = clock::monotonic_ns();
        self.out.write(m);
    }
}

/// A monitor's side: reads the newest status.
pub struct StatusReader {
    board: BoardReader<StatusMsg>,
    _node: Node<ipc::Service>,
}

impl StatusReader {
    /// Opens (or creates) run `run`'s status board for reading: a monitor may start before
    /// the run.
    pub fn open(run: &str) -> Result<StatusReader, LinkError> {
        let names = check_run_name(run)?;
        let node = create_node(&names.monitor_node)?;
        Ok(StatusReader {
            board: BoardReader::open(&node, &names.status, "")?,
            _node: node,
        })
    }

    /// The newest status of the current protocol on any slot, if one was written.
    pub fn latest(&self) -> Option<StatusMsg> {
        self.board.newest()
    }
}
