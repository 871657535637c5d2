//! Counting messages that fail their checks (invalid ones), and handing the first of each kind
//! to the caller to log.

use ipc_types::Invalid;

/// An invalid message, the first of its kind (later ones are only counted).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InvalidMessage<M> {
    /// Why.
    pub kind: Invalid,
    /// The message.
    pub msg: M,
}

/// Counters per [`Invalid`] kind and the first message of each kind not yet handed out.
#[derive(Debug, Clone)]
pub(crate) struct InvalidCounts<M> {
    counts: [u64; ipc_types::Invalid::KINDS],
    first: [Option<M>; ipc_types::Invalid::KINDS],
}

impl<M: Copy> InvalidCounts<M> {
    pub(crate) fn new() -> Self {
        InvalidCounts {
            counts: [0; ipc_types::Invalid::KINDS],
            first: [None; ipc_types::Invalid::KINDS],
        }
    }

    pub(crate) fn record(&mut self, kind: Invalid, msg: &M) {
        let i = kind.index();
        if self.counts[i] == 0 {
            self.first[i] = Some(*msg);
        }
        self.counts[i] += 1;
    }

    /// The first rejection of a kind not handed out yet.
    pub(crate) fn next(&mut self) -> Option<InvalidMessage<M>> {
        Invalid::ALL.into_iter().find_map(|kind| {
            self.first[kind.index()]
                .take()
                .map(|msg| InvalidMessage { kind, msg })
        })
    }

    pub(crate) fn counts(&self) -> [u64; ipc_types::Invalid::KINDS] {
        self.counts
    }
}
