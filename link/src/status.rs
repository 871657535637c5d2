//! The run's live status over iceoryx2: the plant's flight-recorder thread writes a
//! [`StatusMsg`] on the run's `status` board; monitors read it. Nothing here touches the
//! pair's own boards, so a monitor cannot change the loop's timing. Like the other boards it
//! has [`SLOTS`](crate::iceoryx2::SLOTS) writer slots (a plant restarted after a SIGKILL takes
//! a free one); a reader takes the newest write of any slot.

use crate::iceoryx2::{board, create_node, entries, free_slot, newest};
use crate::{LinkError, check_run_name, clock};
use iceoryx2::port::reader::{EntryHandle, Reader};
use iceoryx2::port::writer::{EntryHandleMut, Writer};
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::blackboard::PortFactory as BoardFactory;
use ipc_types::{PROTOCOL_VERSION, StatusMsg};

/// An empty slot: version 0.
pub(crate) fn empty_status() -> StatusMsg {
    let mut m = StatusMsg::new(ipc_types::WireGroup::So3, "");
    m.version = 0;
    m.group = 0;
    m
}

/// The plant's side: publishes the status.
pub struct StatusWriter {
    out: EntryHandleMut<ipc::Service, u32, StatusMsg>,
    _writer: Writer<ipc::Service, u32>,
    _service: BoardFactory<ipc::Service, u32>,
    _node: Node<ipc::Service>,
    seq: u64,
}

impl StatusWriter {
    /// Opens (or creates) run `run`'s status board for writing.
    pub fn open(run: &str) -> Result<StatusWriter, LinkError> {
        let names = check_run_name(run)?;
        let node = create_node(&names.recorder_node)?;
        let service = board(&node, &names.status, empty_status())?;
        let writer = service
            .writer_builder()
            .create()
            .map_err(|e| LinkError::iceoryx2(format!("{}: writer", names.status), e))?;
        let (_, out) = free_slot::<StatusMsg>(&writer, &names.status)?;
        Ok(StatusWriter {
            out,
            _writer: writer,
            _service: service,
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
        self.out.update_with_copy(m);
    }
}

/// A monitor's side: reads the newest status.
pub struct StatusReader {
    entries: Vec<EntryHandle<ipc::Service, u32, StatusMsg>>,
    _reader: Reader<ipc::Service, u32>,
    _service: BoardFactory<ipc::Service, u32>,
    _node: Node<ipc::Service>,
}

impl StatusReader {
    /// Opens (or creates) run `run`'s status board for reading: a monitor may start before
    /// the run.
    pub fn open(run: &str) -> Result<StatusReader, LinkError> {
        let names = check_run_name(run)?;
        let node = create_node(&names.monitor_node)?;
        let service = board(&node, &names.status, empty_status())?;
        let reader = service
            .reader_builder()
            .create()
            .map_err(|e| LinkError::iceoryx2(format!("{}: reader", names.status), e))?;
        let entries = entries::<StatusMsg>(&reader, &names.status)?;
        Ok(StatusReader {
            entries,
            _reader: reader,
            _service: service,
            _node: node,
        })
    }

    /// The newest status of the current protocol on any slot, if one was written.
    pub fn latest(&self) -> Option<StatusMsg> {
        newest(&self.entries, |m| {
            (m.version == PROTOCOL_VERSION).then_some(m.stamp_ns)
        })
    }
}
