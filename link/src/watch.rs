//! A read-only watch on a running pair: the run's `state` and `command` boards and its
//! `status` board, read as an observer with a node of its own (`eqtrack-live-<run>`), for
//! the live Foxglove bridge (`plant_sim live`, docs/live.md). It writes nothing, notifies
//! nothing and listens to no event, so the pair's loop never waits for it: a read copies a
//! board's slots, each with its own consistency check, and touches no lock the two sides
//! take. Like every reader it scans the [`SLOTS`](crate::iceoryx2::SLOTS) writer slots and
//! takes the newest write of the current protocol.
//!
//! Each board admits six readers: here the state board has the controller, a planner and
//! the bridge (three), the command board the plant and the bridge (two), the status board
//! the monitors and the bridge; room is left for the Python observers.

use crate::iceoryx2::{BoardReader, create_node};
use crate::{LinkError, check_run_name};
use iceoryx2::prelude::*;
use ipc_types::{CommandMsg, StateMsg, StatusMsg};

/// The newest state, command and status of a run, read only. Fields drop in order: the
/// boards, then the node.
pub struct PairWatch {
    states: BoardReader<StateMsg>,
    commands: BoardReader<CommandMsg>,
    statuses: BoardReader<StatusMsg>,
    _node: Node<ipc::Service>,
}

impl PairWatch {
    /// Opens run `run`'s state, command and status boards as a reader (creating them empty
    /// when the run has not started: the pair opens them as they are).
    pub fn open(run: &str) -> Result<PairWatch, LinkError> {
        let names = check_run_name(run)?;
        let node = create_node(&names.live_node)?;
        let hint = " (does the board admit one more?)";
        Ok(PairWatch {
            states: BoardReader::open(&node, &names.state, hint)?,
            commands: BoardReader::open(&node, &names.command, hint)?,
            statuses: BoardReader::open(&node, &names.status, hint)?,
            _node: node,
        })
    }

    /// The newest state of the current protocol on any slot, if the plant published one.
    pub fn state(&self) -> Option<StateMsg> {
        self.states.newest()
    }

    /// The newest command of the current protocol on any slot, if a controller published
    /// one.
    pub fn command(&self) -> Option<CommandMsg> {
        self.commands.newest()
    }

    /// The newest status of the current protocol on any slot, if the plant's flight recorder
    /// published one (a run with `--no-record` publishes none).
    pub fn status(&self) -> Option<StatusMsg> {
        self.statuses.newest()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::status::StatusWriter;
    use crate::{PlantEndpoint, PlantEndpointConfig};
    use eqtrack_controller::GroupKind;
    use nalgebra::{Matrix3, Vector3};

    #[test]
    fn a_watch_reads_the_newest_state_and_status_and_refuses_a_bad_name() {
        assert!(PairWatch::open("no spaces").is_err());
        let run = format!("watch-{}", std::process::id());
        let watch = PairWatch::open(&run).expect("watch");
        assert!(watch.state().is_none() && watch.command().is_none());
        assert!(watch.status().is_none());
        let mut plant =
            PlantEndpoint::open(PlantEndpointConfig::new(&run, GroupKind::So3, 0.01)).unwrap();
        let torque = Vector3::zeros();
        for k in 0..3 {
            plant
                .publish(
                    k,
                    &Matrix3::identity(),
                    &Vector3::new(0.5, 0.0, 0.0),
                    &torque,
                )
                .unwrap();
        }
        let s = watch.state().expect("a state");
        assert_eq!((s.seq, s.v[0]), (2, 0.5));
        let mut status = StatusWriter::open(&run).unwrap();
        let mut msg = StatusMsg::new(ipc_types::WireGroup::So3, "x");
        msg.cycle = 9;
        status.publish(&msg);
        assert_eq!(watch.status().map(|s| s.cycle), Some(9));
        assert!(watch.command().is_none());
    }
}
