//! Counting rejected messages, and handing the first of each kind to the caller to log.

use ipc_types::Reject;

/// A rejected message, the first of its kind (later ones are only counted).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rejected<M> {
    /// Why.
    pub kind: Reject,
    /// The message.
    pub msg: M,
}

/// Counters per [`Reject`] kind and the first message of each kind not yet handed out.
#[derive(Debug, Clone)]
pub(crate) struct Rejections<M> {
    counts: [u64; 5],
    first: [Option<M>; 5],
}

impl<M: Copy> Rejections<M> {
    pub(crate) fn new() -> Self {
        Rejections {
            counts: [0; 5],
            first: [None; 5],
        }
    }

    pub(crate) fn record(&mut self, kind: Reject, msg: &M) {
        let i = kind.index();
        if self.counts[i] == 0 {
            self.first[i] = Some(*msg);
        }
        self.counts[i] += 1;
    }

    /// The first rejection of a kind not handed out yet.
    pub(crate) fn next(&mut self) -> Option<Rejected<M>> {
        Reject::ALL.into_iter().find_map(|kind| {
            self.first[kind.index()]
                .take()
                .map(|msg| Rejected { kind, msg })
        })
    }

    pub(crate) fn counts(&self) -> [u64; 5] {
        self.counts
    }
}
