//! The desired-trajectory generator (docs/maths.md, "Tracking error and its dynamics" and
//! "Integrating on the group").

use crate::error::{Error, Quantity};
use crate::group::MatrixLieGroup;
use crate::integrator::physical_step;
use crate::law::Desired;
use crate::semidirect::Phase;
use crate::validate::{finite, spd_inverse};
use crate::{Real, real};
use nalgebra::{SMatrix, SVector};

/// What the loop asks of any desired-trajectory source, stepped at the control period: the
/// time `t_k = k·period`, the desired state `(Q_d, p_d, V_d, τ_d)` at `t_k`, and the step to
/// `t_{k+1}`. Implemented by the feedforward-series [`Reference`], by
/// [`crate::path::PathReference`] (set-point, waypoints, streamed pieces) and by [`Source`].
pub trait Trajectory<T: Real, const N: usize, const M: usize> {
    /// The current time `t_k = k·period`.
    fn time(&self) -> T;
    /// The control period.
    fn period(&self) -> T;
    /// The index k of the current control step.
    fn step_index(&self) -> u64;
    /// The desired state at `t_k`.
    fn desired(&self) -> Desired<T, N, M>;
    /// Advances from `t_k` to `t_{k+1}`.
    fn advance(&mut self);
}

/// Any of the sources, chosen at run time (the scenario's `[reference]`).
#[derive(Debug, Clone, PartialEq)]
pub enum Source<T: Real, G, const N: usize, const M: usize> {
    /// The feedforward cosine series, integrated.
    Series(Reference<T, G, N, M>),
    /// A set-point, a path through waypoints, or streamed pieces.
    Path(crate::path::PathReference<T, G, N, M>),
}

impl<T, G, const N: usize, const M: usize> Trajectory<T, N, M> for Source<T, G, N, M>
where
    T: Real,
    G: MatrixLieGroup<N, M>,
{
    fn time(&self) -> T {
        match self {
            Source::Series(r) => r.time(),
            Source::Path(r) => r.time(),
        }
    }
    fn period(&self) -> T {
        match self {
            Source::Series(r) => r.period(),
            Source::Path(r) => r.period(),
        }
    }
    fn step_index(&self) -> u64 {
        match self {
            Source::Series(r) => r.step_index(),
            Source::Path(r) => r.step_index(),
        }
    }
    fn desired(&self) -> Desired<T, N, M> {
        match self {
            Source::Series(r) => r.desired(),
            Source::Path(r) => r.desired(),
        }
    }
    fn advance(&mut self) {
        match self {
            Source::Series(r) => r.advance(),
            Source::Path(r) => r.advance(),
        }
    }
}

/// The number of cosine terms each feedforward axis can hold.
pub const MAX_TERMS: usize = 8;

/// One term `amplitude·cos(frequency·t + phase)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CosTerm<T> {
    /// Amplitude (torque units).
    pub amplitude: T,
    /// Angular frequency (rad/s).
    pub frequency: T,
    /// Phase (rad).
    pub phase: T,
}

/// One axis of the feedforward torque: `offset + Σ amplitude·cos(frequency·t + phase)`.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisTorque<T> {
    /// Constant part.
    pub offset: T,
    /// Cosine terms (at most [`MAX_TERMS`]).
    pub terms: heapless::Vec<CosTerm<T>, MAX_TERMS>,
}

impl<T: Real> AxisTorque<T> {
    /// A constant torque.
    pub fn constant(offset: T) -> Self {
        AxisTorque {
            offset,
            terms: heapless::Vec::new(),
        }
    }

    /// An axis from an offset and terms; errors when there are more than [`MAX_TERMS`]
    /// (`axis` is only used in the error).
    pub fn new(axis: usize, offset: T, terms: &[CosTerm<T>]) -> Result<Self, Error> {
        let terms = heapless::Vec::from_slice(terms).map_err(|_| Error::TooManyTerms {
            axis,
            capacity: MAX_TERMS,
        })?;
        Ok(AxisTorque { offset, terms })
    }

    /// The torque at time `t`.
    pub fn eval(&self, t: T) -> T {
        self.terms.iter().fold(self.offset, |acc, c| {
            acc + c.amplitude * crate::trig::cos(c.frequency * t + c.phase)
        })
    }

    fn is_finite(&self) -> bool {
        self.offset.is_finite()
            && self
                .terms
                .iter()
                .all(|c| c.amplitude.is_finite() && c.frequency.is_finite() && c.phase.is_finite())
    }
}

/// The feedforward torque `τ_d(t)`, one [`AxisTorque`] per axis.
#[derive(Debug, Clone, PartialEq)]
pub struct Feedforward<T, const M: usize> {
    /// The axes.
    pub axes: [AxisTorque<T>; M],
}

impl<T: Real, const M: usize> Feedforward<T, M> {
    /// No feedforward torque (a set-point, when the initial velocity is zero too).
    pub fn zero() -> Self {
        Feedforward {
            axes: core::array::from_fn(|_| AxisTorque::constant(T::zero())),
        }
    }

    /// `τ_d(t)`.
    pub fn eval(&self, t: T) -> SVector<T, M> {
        SVector::<T, M>::from_fn(|i, _| self.axes[i].eval(t))
    }
}

/// The seed paper's feedforward `τ_d(t) = (cos t, sin t, sin t cos t)`, written as cosine
/// series: `sin t = cos(t − π/2)`, `sin t cos t = ½ cos(2t − π/2)`.
pub fn so3_seed_feedforward<T: Real>() -> Feedforward<T, 3> {
    let h = real::<T>(-core::f64::consts::FRAC_PI_2);
    let term = |amplitude: f64, frequency: f64, phase: T| CosTerm {
        amplitude: real(amplitude),
        frequency: real(frequency),
        phase,
    };
    let axis = |t: CosTerm<T>| {
        let mut terms = heapless::Vec::new();
        // Capacity is MAX_TERMS ≥ 1: this push cannot fail.
        let _ = terms.push(t);
        AxisTorque {
            offset: T::zero(),
            terms,
        }
    };
    Feedforward {
        axes: [
            axis(term(1.0, 1.0, T::zero())),
            axis(term(1.0, 1.0, h)),
            axis(term(0.5, 2.0, h)),
        ],
    }
}

/// The desired trajectory `(Q_d, p_d)`: the physical system with the model inertia driven by
/// the feedforward torque, integrated with RKMK4 at `substeps` steps per control period, the
/// feedforward evaluated at each stage's own time.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference<T: Real, G, const N: usize, const M: usize> {
    state: Phase<T, N, M>,
    inertia_inv: SMatrix<T, M, M>,
    feedforward: Feedforward<T, M>,
    period: T,
    substeps: usize,
    step: u64,
    _group: core::marker::PhantomData<G>,
}

impl<T, G, const N: usize, const M: usize> Reference<T, G, N, M>
where
    T: Real,
    G: MatrixLieGroup<N, M>,
{
    /// A reference starting at `Q_d(0) = q0`, `V_d(0) = v0`, with model inertia `inertia`.
    pub fn new(
        q0: SMatrix<T, N, N>,
        v0: SVector<T, M>,
        inertia: SMatrix<T, M, M>,
        feedforward: Feedforward<T, M>,
        period: T,
        substeps: usize,
    ) -> Result<Self, Error> {
        let inertia_inv = spd_inverse(Quantity::Inertia, &inertia)?;
        finite(Quantity::Reference, &q0)?;
        finite(Quantity::Reference, &v0)?;
        if !feedforward.axes.iter().all(AxisTorque::is_finite) {
            return Err(Error::NonFinite(Quantity::Feedforward));
        }
        crate::validate::period(period)?;
        if substeps == 0 {
            return Err(Error::NotPositive(Quantity::Substeps));
        }
        Ok(Reference {
            state: Phase {
                q: q0,
                p: inertia * v0,
            },
            inertia_inv,
            feedforward,
            period,
            substeps,
            step: 0,
            _group: core::marker::PhantomData,
        })
    }

    /// The current time `t_k = k·period`.
    pub fn time(&self) -> T {
        real::<T>(self.step as f64) * self.period
    }

    /// The control period.
    pub fn period(&self) -> T {
        self.period
    }

    /// The index k of the current control step.
    pub fn step_index(&self) -> u64 {
        self.step
    }

    /// The desired state at the current time: `Q_d`, `p_d`, `V_d = I⁻¹p_d`, `τ_d(t_k)`.
    pub fn desired(&self) -> Desired<T, N, M> {
        Desired {
            q: self.state.q,
            p: self.state.p,
            v: self.inertia_inv * self.state.p,
            tau: self.feedforward.eval(self.time()),
        }
    }

    /// Advances from `t_k` to `t_{k+1}`.
    pub fn advance(&mut self) {
        self.step_once();
    }

    fn step_once(&mut self) {
        let t0 = self.time();
        let h = self.period / real(self.substeps as f64);
        for j in 0..self.substeps {
            let t = t0 + real::<T>(j as f64) * h;
            let ff = &self.feedforward;
            self.state =
                physical_step::<G, T, _, N, M>(&self.state, t, h, &self.inertia_inv, |s| {
                    ff.eval(s)
                });
        }
        self.step += 1;
    }
}

impl<T, G, const N: usize, const M: usize> Trajectory<T, N, M> for Reference<T, G, N, M>
where
    T: Real,
    G: MatrixLieGroup<N, M>,
{
    fn time(&self) -> T {
        Reference::time(self)
    }
    fn period(&self) -> T {
        Reference::period(self)
    }
    fn step_index(&self) -> u64 {
        Reference::step_index(self)
    }
    fn desired(&self) -> Desired<T, N, M> {
        Reference::desired(self)
    }
    fn advance(&mut self) {
        self.step_once();
    }
}

/// A desired trajectory computed once and replayed: the states `desired[k]` at
/// `t_k = k·period`, read from a borrowed table (docs/maths.md, "Integrating on the group":
/// the table holds what a source produced, so a loop flown against it computes the same
/// numbers as one flown against the source). Many runs of one reference (a Monte Carlo
/// study) share one table instead of integrating the reference again for each run.
///
/// Past the table's end, [`Trajectory::desired`] repeats its last entry: make the table one
/// entry longer than the number of steps flown (the loop reads `t_0 … t_N`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tabulated<'a, T: Real, const N: usize, const M: usize> {
    table: &'a [Desired<T, N, M>],
    period: T,
    step: u64,
}

impl<'a, T: Real, const N: usize, const M: usize> Tabulated<'a, T, N, M> {
    /// Records `steps + 1` desired states of `source`, at `t_0 … t_steps`.
    pub fn record<S: Trajectory<T, N, M>>(
        source: &mut S,
        steps: usize,
        out: &mut impl Extend<Desired<T, N, M>>,
    ) {
        for k in 0..=steps {
            out.extend(core::iter::once(source.desired()));
            if k < steps {
                source.advance();
            }
        }
    }

    /// Replays `table` from `t_0 = 0` at `period`; an empty table is refused.
    pub fn new(table: &'a [Desired<T, N, M>], period: T) -> Result<Self, Error> {
        crate::validate::period(period)?;
        if table.is_empty() {
            return Err(Error::WrongShape {
                quantity: Quantity::Reference,
                expected: 1,
                found: 0,
            });
        }
        Ok(Tabulated {
            table,
            period,
            step: 0,
        })
    }
}

impl<T: Real, const N: usize, const M: usize> Trajectory<T, N, M> for Tabulated<'_, T, N, M> {
    fn time(&self) -> T {
        real::<T>(self.step as f64) * self.period
    }
    fn period(&self) -> T {
        self.period
    }
    fn step_index(&self) -> u64 {
        self.step
    }
    fn desired(&self) -> Desired<T, N, M> {
        let last = self.table.len() - 1;
        self.table[(self.step as usize).min(last)]
    }
    fn advance(&mut self) {
        self.step += 1;
    }
}
