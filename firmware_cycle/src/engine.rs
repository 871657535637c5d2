//! The law on one group: the reference, the controller and its rejection terms, and the last
//! state answered (the terms update only on consecutive states, as in the pair).

use crate::{Config, ConfigError, Dropped, MAX_SEQ_JUMP};
use controller::group::MatrixLieGroup;
use controller::{Controller, Reference, Rejection};
use heapless::Vec;
use nalgebra::{SMatrix, SVector};
use serial_wire::{CommandFrame, StateFrame};

pub(crate) struct Engine<G, const N: usize, const M: usize> {
    controller: Controller<f32, G, N, M>,
    start: Reference<f32, G, N, M>,
    reference: Reference<f32, G, N, M>,
    rejection_start: Option<Rejection<f32, M>>,
    rejection: Option<Rejection<f32, M>>,
    previous: Option<u64>,
    law: u8,
}

fn vec<const C: usize>(xs: &[f32]) -> Vec<f32, C> {
    // every caller's slice fits: at most 6 entries into capacity 6
    Vec::from_slice(&xs[..xs.len().min(C)]).unwrap_or_default()
}

impl<G: MatrixLieGroup<N, M>, const N: usize, const M: usize> Engine<G, N, M> {
    pub(crate) fn new(config: &Config) -> Result<Self, ConfigError> {
        let controller = config.controller::<G, N, M>()?;
        let reference = config.reference::<G, N, M>()?;
        let rejection = config.rejection::<M>()?;
        let rejection = Rejection::of(rejection, controller.config().torque_limit.as_ref())?;
        Ok(Engine {
            controller,
            start: reference.clone(),
            reference,
            rejection_start: rejection,
            rejection,
            previous: None,
            law: config.law,
        })
    }

    /// A new run: the reference at `t = 0`, the terms as at start.
    pub(crate) fn restart(&mut self) {
        self.reference = self.start.clone();
        self.rejection = self.rejection_start;
        self.previous = None;
    }

    pub(crate) fn answer(&mut self, s: &StateFrame, period: f32) -> Result<CommandFrame, Dropped> {
        if s.q.len() != N * N || s.v.len() != M || s.applied.len() != M {
            return Err(Dropped::Shape);
        }
        let at = self.reference.step_index();
        if s.seq < at {
            return Err(Dropped::Backwards);
        }
        if s.seq - at > MAX_SEQ_JUMP {
            return Err(Dropped::Jump);
        }
        while self.reference.step_index() < s.seq {
            self.reference.advance();
        }
        let q = SMatrix::<f32, N, N>::from_row_slice(&s.q);
        let v = SVector::<f32, M>::from_row_slice(&s.v);
        let desired = self.reference.desired();
        let out = match &mut self.rejection {
            None => self.controller.compute(&q, &v, &desired),
            Some(r) => {
                let applied = SVector::<f32, M>::from_row_slice(&s.applied);
                let follows = self
                    .previous
                    .is_some_and(|p| p.checked_add(1) == Some(s.seq));
                self.controller
                    .compute_rejecting(r, &q, &v, &desired, &applied, period, follows)
            }
        }
        .map_err(|_| Dropped::Law)?;
        self.previous = Some(s.seq);
        let terms = self.rejection.is_some();
        Ok(CommandFrame {
            seq: s.seq,
            law: self.law,
            tau: vec(out.torque.as_slice()),
            lyapunov: out.lyapunov.total,
            observer: if terms {
                vec(out.observer.as_slice())
            } else {
                Vec::new()
            },
            integral: if terms {
                vec(out.integral.as_slice())
            } else {
                Vec::new()
            },
            estimate: None,
            allocation: None,
        })
    }
}
