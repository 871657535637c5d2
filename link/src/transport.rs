//! The one transport trait, the messages that travel on it, and [`open`], which picks an
//! implementation at run time.

use crate::iceoryx2::Slot;
use crate::{LinkError, Role, TransportKind};
use ipc_types::{CommandMsg, DecodeError, StateMsg};
use std::time::Duration;

/// What one side of a run needs from a transport. Every method does real work on every
/// implementation; none allocates after `open`.
pub trait Transport<Out: Message, In: Message> {
    /// Stamps `msg` with CLOCK_MONOTONIC, makes it visible to the peer and, when `wake_peer`,
    /// wakes a peer that sleeps in [`Transport::wait`] (a Unix datagram always wakes it).
    /// Returns the stamp. A peer that is not there yet gets the message when it comes.
    fn send(&mut self, msg: &Out, wake_peer: bool) -> Result<u64, LinkError>;

    /// A message this side has not seen yet, or `None`. Call it until `None` to see every
    /// new message.
    fn receive(&mut self) -> Option<In>;

    /// Sleeps until a message may have arrived or `timeout` passes, with the precision of
    /// the kernel's high-resolution timers (a signal also ends it).
    fn wait(&mut self, timeout: Duration);
}

/// The largest encoded message a socket transport carries (the command, since protocol 7).
pub const MAX_ENCODED: usize = if ipc_types::COMMAND_BYTES > ipc_types::STATE_BYTES {
    ipc_types::COMMAND_BYTES
} else {
    ipc_types::STATE_BYTES
};

/// A message that can travel on either transport: a board's [`Slot`] for iceoryx2 (its
/// empty value and write id) and byte-encodable for sockets.
pub trait Message: Slot {
    /// Sets the publication stamp.
    fn set_stamp(&mut self, ns: u64);
    /// The little-endian encoding into `buf`; returns its length.
    fn encode(&self, buf: &mut [u8; MAX_ENCODED]) -> usize;
    /// Decodes [`Message::encode`].
    fn decode(buf: &[u8]) -> Result<Self, DecodeError>;
}

/// Both messages share their byte encoding: one impl.
macro_rules! message {
    ($msg:ty) => {
        impl Message for $msg {
            fn set_stamp(&mut self, ns: u64) {
                self.stamp_ns = ns;
            }
            fn encode(&self, buf: &mut [u8; MAX_ENCODED]) -> usize {
                let b = self.to_bytes();
                buf[..b.len()].copy_from_slice(&b);
                b.len()
            }
            fn decode(buf: &[u8]) -> Result<Self, DecodeError> {
                <$msg>::from_bytes(buf)
            }
        }
    };
}
message!(StateMsg);
message!(CommandMsg);

/// The plant's side of a transport: sends states, receives commands.
pub type PlantTransport = Box<dyn Transport<StateMsg, CommandMsg>>;
/// The controller's side: sends commands, receives states.
pub type ControllerTransport = Box<dyn Transport<CommandMsg, StateMsg>>;

/// Opens `role`'s side of run `run` on the transport `kind`, as the `Out`/`In` message pair
/// of that role (the plant: `StateMsg` out; the controller: `CommandMsg` out).
pub fn open<Out: Message, In: Message>(
    kind: TransportKind,
    run: &str,
    role: Role,
) -> Result<Box<dyn Transport<Out, In>>, LinkError> {
    Ok(match kind {
        TransportKind::Iceoryx2 => Box::new(crate::iceoryx2::Iceoryx2::<Out, In>::open(run, role)?),
        TransportKind::Uds => Box::new(crate::uds::Uds::<Out, In>::open(run, role)?),
    })
}
