//! The controller's side of a vehicle (docs/maths.md, "Control allocation"): the known
//! gravity and buoyancy compensated from the model and the attitude, the rest of the law's
//! wrench allocated to the actuators within their bounds, a rate limit and the failures it
//! has been told of.

use crate::allocator::{Allocation, Allocator, Bounds, Reweighting};
use crate::restoring::Restoring;
use crate::wheels::{Momentum, Wheel, WheelSet};
use crate::{Commands, MAX_ACTUATORS};
use nalgebra::{Matrix3, RealField, SVector};

/// What one cycle asks of the actuators and what it got.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Actuation<T, const K: usize> {
    /// The wrench asked of the allocator: the law's minus the known restoring wrench.
    pub demand: SVector<T, K>,
    /// The allocator's answer (`u_cmd`, the wrench `B u_cmd`, the status).
    pub allocation: Allocation<T, K>,
}

impl<T: RealField + Copy, const K: usize> Actuation<T, K> {
    /// The wrench the law takes as applied over the period (for its disturbance-rejection
    /// terms): the actuators' `B u_cmd` plus the known restoring wrench it compensated.
    pub fn applied(&self, restoring: &SVector<T, K>) -> SVector<T, K> {
        self.allocation.achieved + restoring
    }

    /// The torque the allocation could not give, `|τ_demand − τ_achieved|` (the first three
    /// rows; on SO(3) the whole demand), its square root the FPU's on a Cortex-M4F (the bits
    /// of nalgebra's `norm`).
    pub fn torque_residual(&self) -> T {
        let rows = K.min(3);
        eqtrack_hw_sqrt::norm(&(self.demand - self.allocation.achieved).rows(0, rows))
    }
}

/// The controller's vehicle: an allocator, the restoring model, the rate limit per period
/// and the bounds as narrowed by the failures it was told of.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleControl<T, const K: usize> {
    allocator: Allocator<T, K>,
    /// The allocator of the healthy vehicle, which a loss of effectiveness reweights.
    nominal: Allocator<T, K>,
    /// The effectiveness of each actuator as told (1: healthy).
    factors: Commands<T>,
    /// Whether a factor told is not 1: the allocator is then posed in the actuators' thrust
    /// ([`VehicleControl::weaken`]).
    weak: bool,
    restoring: Restoring<T>,
    /// The rate limit (per second; 0: none).
    rate_limit: T,
    /// The most a command may change in one period (0: no limit).
    rate_step: T,
    bounds: Bounds<T>,
    previous: Option<Commands<T>>,
    /// The reaction wheels among the actuators (none by default).
    wheels: WheelSet<T>,
    /// Their momentum management (none by default).
    momentum: Option<Momentum<T>>,
    /// The control period (s).
    period: T,
    /// How many times the bounds have been told ([`VehicleControl::fail`],
    /// [`VehicleControl::heal`]).
    told: u32,
}

impl<T: RealField + Copy, const K: usize> VehicleControl<T, K> {
    /// The controller's vehicle: `rate_limit` (per second; 0 none) over periods of `period`.
    pub fn new(
        allocator: Allocator<T, K>,
        restoring: Restoring<T>,
        rate_limit: T,
        period: T,
    ) -> Self {
        VehicleControl {
            bounds: allocator.bounds(),
            nominal: allocator,
            factors: Commands::from_element(T::one()),
            weak: false,
            allocator,
            restoring,
            rate_limit,
            rate_step: rate_limit * period,
            previous: None,
            wheels: WheelSet::none(),
            momentum: None,
            period,
            told: 0,
        }
    }

    /// The same vehicle whose actuators from column `first` on are the reaction wheels
    /// `wheels` (as [`crate::Geometry::with_wheels`] put them; unit axes): its allocations
    /// then cancel their gyroscopic torque and keep them below their top speed
    /// ([`VehicleControl::actuate_wheeled`]).
    pub fn with_wheels(mut self, wheels: &[Wheel<T>], first: usize) -> Self {
        self.wheels = WheelSet::of(wheels, first);
        self
    }

    /// The reaction wheels among the actuators.
    pub fn wheels(&self) -> &WheelSet<T> {
        &self.wheels
    }

    /// The same vehicle managing its wheels' momentum (docs/maths.md, "Momentum management"):
    /// steering their speeds toward a bias through the null space, and dumping their momentum
    /// through the thrusters, which then do nothing else.
    pub fn with_momentum(mut self, momentum: Momentum<T>) -> Self {
        self.momentum = Some(momentum);
        self
    }

    /// Sets the control period the rate limit applies over (a pair's controller learns it
    /// from the plant's first state).
    pub fn set_period(&mut self, period: T) {
        self.rate_step = self.rate_limit * period;
        self.period = period;
    }

    /// The previous command, which the rate limit narrows the next one around (`None`
    /// before the first cycle).
    pub fn previous(&self) -> Option<&Commands<T>> {
        self.previous.as_ref()
    }

    /// Restores the previous command (replay: from a recorded command).
    pub fn set_previous(&mut self, previous: Option<Commands<T>>) {
        self.previous = previous;
    }

    /// The allocator. Its geometry is the healthy one whatever the failures told: with an
    /// actuator told weak it is posed in the actuators' thrust ([`VehicleControl::weaken`]).
    pub fn allocator(&self) -> &Allocator<T, K> {
        &self.allocator
    }

    /// The bounds the next allocation starts from (the geometry's, with the failures told).
    pub fn bounds(&self) -> (Commands<T>, Commands<T>) {
        (self.bounds.lo, self.bounds.hi)
    }

    /// A count of the tells that changed the bounds so far ([`VehicleControl::fail`] and
    /// [`VehicleControl::heal`], wrapping): while it stays the same, so does every
    /// [`VehicleControl::held`], and a failure detector need not read them again.
    pub fn told(&self) -> u32 {
        self.told
    }

    /// The value actuator `j` is held at, when the failures told lock it (its bounds equal).
    #[inline]
    pub fn held(&self, j: usize) -> Option<T> {
        let (lo, hi) = (self.bounds.lo.get(j)?, self.bounds.hi.get(j)?);
        (lo == hi).then_some(*lo)
    }

    /// The wrench directions the actuators it may still move cannot produce (those the
    /// failures told hold are left out, and a weak one's column is scaled by its factor;
    /// none while the rest span every wrench): the control authority the failures took
    /// (docs/failsafe.md, "Causes").
    pub fn lost_directions(&self) -> crate::geometry::LostDirections<T, K> {
        let mut b = *self.allocator.geometry().effectiveness();
        for j in 0..MAX_ACTUATORS {
            if self.held(j).is_some() {
                b.column_mut(j).fill(T::zero());
            } else if self.factors[j] != T::one() {
                let c = b.column(j) * self.factors[j];
                b.set_column(j, &c);
            }
        }
        crate::geometry::lost_directions(&b)
    }

    /// The failsafe's `disarm` (docs/failsafe.md) applied to this cycle's actuation `a`: every
    /// actuator at its minimum (a held one where it is held, since the bounds hold it), the
    /// wrench that gives, and the rate limit's memory set to it.
    pub fn disarm(&mut self, a: &mut Actuation<T, K>) {
        let lo = self.bounds.lo;
        a.allocation.u = lo;
        a.allocation.achieved = self
            .allocator
            .geometry()
            .wrench(&lo.component_mul(&self.factors));
        self.previous = Some(lo);
    }

    /// The known restoring wrench at the attitude `r`.
    pub fn restoring(&self, r: &Matrix3<T>) -> SVector<T, K> {
        self.restoring.wrench(r)
    }

    /// Tells the allocator that actuator `j` has failed, stuck at `value`: from now on it is
    /// held there and the others take over.
    pub fn fail(&mut self, j: usize, value: T) {
        if j < self.nominal.geometry().count() {
            self.bounds.fail(j, value);
            self.told = self.told.wrapping_add(1);
        }
    }

    /// The geometry's bounds, before any failure or rate limit narrowed them.
    pub fn nominal_bounds(&self) -> (Commands<T>, Commands<T>) {
        self.nominal.geometry().bounds()
    }

    /// Forgets what the allocator was told of actuator `j`: its bounds are the geometry's
    /// again and its column the healthy one (a detector's estimate replaced by a better one).
    pub fn heal(&mut self, j: usize) {
        self.release(j);
        self.weaken(j, T::one());
    }

    /// Forgets a failure told that holds actuator `j` ([`VehicleControl::fail`]): its bounds
    /// are the geometry's again. A loss of effectiveness told stays
    /// ([`VehicleControl::weaken`]; [`VehicleControl::heal`] forgets both).
    pub fn release(&mut self, j: usize) {
        if j < self.nominal.geometry().count() {
            let (lo, hi) = self.nominal.geometry().bounds();
            self.bounds.lo[j] = lo[j];
            self.bounds.hi[j] = hi[j];
            self.told = self.told.wrapping_add(1);
        }
    }

    /// Tells the allocator that actuator `j` produces only `factor` of its command (a loss
    /// of effectiveness): from now on it allocates as if its column of `B` were scaled by
    /// `factor` ([`Allocator::scaled`]), and the others make up the rest. It does so with
    /// the actuator's thrust `y = factor · u` as its variable
    /// (docs/maths.md, "Control allocation", a weak actuator's thrust as its variable): the healthy geometry, the
    /// bounds scaled by `factor` in each allocation and the command divided by it after,
    /// and only the last stage's weight and preferred command changed here, at the cost of a
    /// rank-one update of one Cholesky factor, not a formation of the allocator. Telling the
    /// same factor again changes nothing (the allocator is reweighted from the healthy one,
    /// never twice). A factor that is not finite and positive is ignored; one below the
    /// scalar's `ε` is taken as `ε` (so that the weight `w/k²` stays finite).
    pub fn weaken(&mut self, j: usize, factor: T) {
        let Some(factor) = self.weakening(j, factor) else {
            return;
        };
        let count = self.nominal.geometry().count();
        self.factors[j] = factor;
        // the healthy one reweighted for every told factor, in the actuators' order, whatever
        // the order told (with every factor 1 again, the healthy allocator, bit for bit)
        self.weak = (0..count).any(|i| self.factors[i] != T::one());
        self.allocator.pose_in_thrust(&self.nominal, &self.factors);
    }

    /// [`VehicleControl::weaken`] of actuator `j` by `factor` in steps, for a cycle that must
    /// stay short (a failure detector's; docs/maths.md, "Failure detection", *A weak actuator
    /// told over cycles*): the reweighting for the factors told now with `j`'s `factor`,
    /// begun. `None` where `weaken` would change nothing (the same factor, or one it
    /// ignores). Nothing is in force until [`VehicleControl::reweight`].
    pub fn reweighting(&self, j: usize, factor: T) -> Option<Reweighting<T, K>> {
        let factor = self.weakening(j, factor)?;
        let mut factors = self.factors;
        factors[j] = factor;
        Some(self.nominal.reweighting(&factors, j))
    }

    /// The factor [`VehicleControl::weaken`] would tell actuator `j` for `factor` (at least
    /// the scalar's `ε`), or `None` where it changes nothing: an actuator past the count, a
    /// factor that is not finite and positive, or the factor told already.
    fn weakening(&self, j: usize, factor: T) -> Option<T> {
        let count = self.nominal.geometry().count();
        if j >= count || !(factor.is_finite() && factor > T::zero()) {
            return None;
        }
        let factor = factor.max(T::default_epsilon());
        (self.factors[j] != factor).then_some(factor)
    }

    /// One step of `r`: up to `columns` more columns of its rank-one updates (`K` columns an
    /// update, an update for each weak actuator), or, once they are made, the weak actuators'
    /// weights in a step of their own; true when nothing is left, and
    /// [`VehicleControl::reweight`] only copies it in.
    pub fn advance(&self, r: &mut Reweighting<T, K>, columns: usize) -> bool {
        self.nominal.advance(r, columns)
    }

    /// Puts `r` in force, its steps left made first: from here on the vehicle is as if
    /// [`VehicleControl::weaken`] had been told now the actuator and factor that began it,
    /// bit for bit. If another factor was told since it began, it no longer fits, and `weaken`
    /// is told that actuator and factor at once instead.
    pub fn reweight(&mut self, r: &mut Reweighting<T, K>) {
        // (its factor was checked as `weaken` checks it when it began)
        let (j, factor) = r.tell();
        if self.factors[j] == factor {
            return;
        }
        let mut now = self.factors;
        now[j] = factor;
        if now != *r.factors() {
            self.weaken(j, factor);
            return;
        }
        self.factors = now;
        self.weak = r.weak();
        self.allocator.put(&self.nominal, r);
    }

    /// The effectiveness of each actuator as told (1: healthy, and past the count).
    pub fn factors(&self) -> &Commands<T> {
        &self.factors
    }

    /// One cycle: the demand `wrench − restoring(r̂)` allocated within the bounds, narrowed
    /// to the rate limit around the previous command, and warm-started from it (the same
    /// optimum as a cold start; [`Allocator::allocate_from`]). Allocation-free; never NaN.
    pub fn actuate(&mut self, wrench: &SVector<T, K>, r_hat: &Matrix3<T>) -> Actuation<T, K> {
        let demand = wrench - self.restoring(r_hat);
        self.actuate_demand(demand)
    }

    /// [`VehicleControl::actuate`] of a demand that is the actuators' wrench itself, the
    /// restoring wrench already in it (the failsafe's thrust-axis law asks for its thrust
    /// and torque directly).
    pub fn actuate_demand(&mut self, demand: SVector<T, K>) -> Actuation<T, K> {
        self.allocate(demand, None, None)
    }

    /// [`VehicleControl::actuate`] of a vehicle with reaction wheels, at body rate `omega` with
    /// the wheels' measured `speeds` (relative to the body, one per wheel): the demand gains
    /// the wheels' gyroscopic torque ([`WheelSet::gyroscopic`]), and each wheel's bounds close
    /// on the side that would speed it past its top speed within the period
    /// ([`WheelSet::narrow`]) (docs/maths.md, "Reaction wheels"). Without wheels it is
    /// [`VehicleControl::actuate`].
    pub fn actuate_wheeled(
        &mut self,
        wrench: &SVector<T, K>,
        r_hat: &Matrix3<T>,
        omega: &nalgebra::Vector3<T>,
        speeds: &[T],
    ) -> Actuation<T, K> {
        let demand = wrench - self.restoring(r_hat) + self.wheels.gyroscopic(omega, speeds);
        let thrust = self.momentum.map(|m| self.manage(&m, omega, speeds));
        self.allocate(demand, Some(speeds), thrust.flatten().as_ref())
    }

    /// Momentum management's part of a cycle (docs/maths.md, "Momentum management"): the
    /// wheels' preferred torques for the null space set in the allocator, and, when it
    /// dumps, the thrusters' commands for the dump torque alone (the wheels held at 0), which
    /// the cycle's allocation then holds them at.
    fn manage(
        &mut self,
        m: &Momentum<T>,
        omega: &nalgebra::Vector3<T>,
        speeds: &[T],
    ) -> Option<Commands<T>> {
        if m.null_gain > T::zero() {
            let mut up = *self.nominal.preferred();
            self.wheels.null_space(m, speeds, &mut up);
            self.allocator
                .set_preferred(&up.component_mul(&self.factors));
        }
        let first = self.wheels.first();
        if m.dump_gain <= T::zero() || first == 0 {
            return None;
        }
        let tau = WheelSet::dump::<K>(m, &self.wheels.momentum(omega, speeds));
        let mut bounds = self.bounds;
        for j in first..first + self.wheels.wheels().len() {
            bounds.fail(j, T::zero().max(bounds.lo[j]).min(bounds.hi[j]));
        }
        Some(self.solve(&tau, &bounds, None).u)
    }

    /// The allocator's answer to `demand` within `bounds`, from `previous`, all of commands:
    /// with an actuator told weak, posed in its thrust, the bounds and `previous` scaled by
    /// the factors and the command divided by them after, kept within `bounds`
    /// (docs/maths.md, "Control allocation", a weak actuator's thrust as its variable).
    fn solve(
        &self,
        demand: &SVector<T, K>,
        bounds: &Bounds<T>,
        previous: Option<&Commands<T>>,
    ) -> Allocation<T, K> {
        if !self.weak {
            return self.allocator.allocate_from(demand, bounds, previous);
        }
        let k = &self.factors;
        let thrust = Bounds {
            lo: bounds.lo.component_mul(k),
            hi: bounds.hi.component_mul(k),
        };
        let previous = previous.map(|p| p.component_mul(k));
        let mut a = self
            .allocator
            .allocate_from(demand, &thrust, previous.as_ref());
        for j in 0..self.allocator.geometry().count() {
            a.u[j] = (a.u[j] / k[j]).max(bounds.lo[j]).min(bounds.hi[j]);
        }
        a
    }

    /// One allocation of `demand` within the bounds, narrowed to the rate limit and, given the
    /// wheels' `speeds`, to the wheels' top speeds, with the actuators before the wheels held
    /// at `thrust` when given (a momentum dump's).
    fn allocate(
        &mut self,
        demand: SVector<T, K>,
        speeds: Option<&[T]>,
        thrust: Option<&Commands<T>>,
    ) -> Actuation<T, K> {
        let mut bounds = self.bounds;
        if let (Some(prev), true) = (&self.previous, self.rate_step > T::zero()) {
            // the rate limit is the thrusters' (N/s): a wheel's motor torque is not limited
            for j in 0..self.allocator.geometry().count() {
                if bounds.hi[j] > bounds.lo[j] && !self.wheels.holds(j) {
                    bounds.limit_rate(j, prev[j], self.rate_step);
                }
            }
        }
        if let Some(speeds) = speeds {
            self.wheels.narrow(&mut bounds, speeds, self.period);
        }
        if let Some(thrust) = thrust {
            for j in 0..self.wheels.first() {
                bounds.fail(j, thrust[j].max(bounds.lo[j]).min(bounds.hi[j]));
            }
        }
        let allocation = self.solve(&demand, &bounds, self.previous.as_ref());
        self.previous = Some(allocation.u);
        Actuation { demand, allocation }
    }
}

/// The span test of a vehicle's actuators ([`VehicleControl::lost_directions`]) for a caller
/// that asks every cycle: it runs again only when the bounds, the geometry or a factor told changed
/// since the last answer (a failure told or found), since a rank test costs microseconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpanWatch<T, const K: usize> {
    last: Option<SpanAnswer<T, K>>,
}

/// What [`SpanWatch`] last answered, and the bounds (low, high), effectiveness and factors
/// it was for.
type SpanAnswer<T, const K: usize> = (
    Commands<T>,
    Commands<T>,
    nalgebra::SMatrix<T, K, MAX_ACTUATORS>,
    Commands<T>,
    bool,
);

impl<T: RealField + Copy, const K: usize> Default for SpanWatch<T, K> {
    fn default() -> Self {
        SpanWatch { last: None }
    }
}

impl<T: RealField + Copy, const K: usize> SpanWatch<T, K> {
    /// Whether the actuators `control` may still move no longer span every wrench (the
    /// failsafe's `actuators` cause; docs/failsafe.md, "Causes").
    pub fn lost(&mut self, control: &VehicleControl<T, K>) -> bool {
        let (lo, hi) = control.bounds();
        let b = *control.allocator().geometry().effectiveness();
        let k = *control.factors();
        if let Some((l, h, e, f, lost)) = &self.last
            && (*l, *h, *e, *f) == (lo, hi, b, k)
        {
            return *lost;
        }
        let lost = !control.lost_directions().directions().is_empty();
        self.last = Some((lo, hi, b, k, lost));
        lost
    }
}
