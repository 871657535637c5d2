//! The wire target: bytes through [`StateMsg::from_bytes`] / [`CommandMsg::from_bytes`], then
//! the receiver's checks, the identity helpers, and what each side does with an accepted
//! message (the controller evaluates its law on a state, the plant integrates a command).
//!
//! By concern: `layout` (the field tables of the two encodings, reading and writing a field
//! in place), `seeds` (the realistic seed messages), `mutation` (the case generator and its
//! mutations), `checks` (the oracle: decoding, receivers, identities, each side's use of an
//! accepted message).
//!
//! [`StateMsg::from_bytes`]: ipc_types::StateMsg::from_bytes
//! [`CommandMsg::from_bytes`]: ipc_types::CommandMsg::from_bytes

mod checks;
mod layout;
mod mutation;
mod seeds;
#[cfg(test)]
mod tests;

use crate::MsgKind;
use eqtrack_controller::GroupKind;

pub(crate) use checks::check;

/// One seed message.
#[derive(Debug, Clone)]
struct Item {
    kind: MsgKind,
    group: GroupKind,
    seq: u64,
    period: f64,
    /// A command's actuator count (0: none).
    actuators: u32,
    bytes: Vec<u8>,
}

/// The seed corpus and the mutator of the wire target.
pub(crate) struct Corpus {
    items: Vec<Item>,
}

/// Both disturbance-rejection terms, as a scenario would give them (observer in the world
/// frame, so the rotation enters; the integral clamped).
fn rejection<const M: usize>() -> eqtrack_controller::RejectionConfig<f64, M> {
    eqtrack_controller::RejectionConfig {
        observer: Some(eqtrack_controller::ObserverConfig {
            gain: nalgebra::SVector::repeat(20.0),
            limit: Some(nalgebra::SVector::repeat(5.0)),
            frame: eqtrack_controller::Frame::World,
        }),
        integral: Some(eqtrack_controller::IntegralConfig {
            ki: nalgebra::SVector::repeat(1.0),
            c: nalgebra::SVector::repeat(5.0),
            limit: Some(nalgebra::SVector::repeat(0.5)),
            anti_windup: true,
        }),
    }
}
