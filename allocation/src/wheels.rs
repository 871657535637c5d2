//! Reaction wheels as the controller sees them (docs/maths.md, "Reaction wheels"): each a
//! column `(−g, 0)` of `B` (a motor torque `u` on the wheel puts `−u g` on the body), the
//! gyroscopic torque the wheels' momentum puts on a turning body, which the allocator is
//! asked to cancel, and bounds that close on the side that would speed a wheel past its top
//! speed.

use crate::Commands;
use crate::allocator::Bounds;
use nalgebra::{RealField, SVector, Vector3};

/// The most reaction wheels a vehicle carries.
pub const MAX_WHEELS: usize = 6;

/// A reaction wheel: its spin axis, spin inertia and motor limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wheel<T> {
    /// The spin axis `g` in body axes (made unit by [`crate::Geometry::with_wheels`]).
    pub axis: [T; 3],
    /// The spin inertia `J_s` (kg·m²).
    pub inertia: T,
    /// The motor's largest torque (N·m): the command's bounds are `±max_torque`.
    pub max_torque: T,
    /// The top speed relative to the body (rad/s).
    pub max_speed: T,
}

/// Momentum management (docs/maths.md, "Momentum management"): the wheels' speeds steered
/// toward a bias through the allocation's null space, and their momentum dumped through the
/// thrusters above a threshold.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Momentum<T> {
    /// The null space's gain `k_n` (1/s; 0: off): each wheel's preferred torque is
    /// `−k_n J_s (Ω − Ω_bias)`.
    pub null_gain: T,
    /// Each wheel's bias speed `Ω_bias` (rad/s).
    pub bias: [T; MAX_WHEELS],
    /// The wheels' momentum `|h_w|` (N·m·s) above which the thrusters dump it.
    pub dump_threshold: T,
    /// The dump's gain `k_d` (1/s; 0: off): the thrusters' torque is
    /// `−k_d (|h_w| − h_thr) h_w/|h_w|` while `|h_w| > h_thr`.
    pub dump_gain: T,
}

/// A vehicle's wheels in the allocator's columns `first..first + count`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelSet<T> {
    wheels: [Wheel<T>; MAX_WHEELS],
    count: usize,
    first: usize,
}

impl<T: RealField + Copy> WheelSet<T> {
    /// No wheels.
    pub fn none() -> Self {
        WheelSet {
            wheels: [Wheel {
                axis: [T::zero(); 3],
                inertia: T::one(),
                max_torque: T::zero(),
                max_speed: T::zero(),
            }; MAX_WHEELS],
            count: 0,
            first: 0,
        }
    }

    /// `wheels` (unit axes, at most [`MAX_WHEELS`]: more are ignored) in the columns from
    /// `first`.
    pub(crate) fn of(wheels: &[Wheel<T>], first: usize) -> Self {
        let mut set = WheelSet::none();
        set.first = first;
        for (slot, w) in set.wheels.iter_mut().zip(wheels) {
            *slot = *w;
            set.count += 1;
        }
        set
    }

    /// The wheels.
    pub fn wheels(&self) -> &[Wheel<T>] {
        &self.wheels[..self.count]
    }

    /// The allocator's column of the first wheel (they follow the thrusters).
    pub fn first(&self) -> usize {
        self.first
    }

    /// Whether the allocator's column `j` is a wheel's.
    pub fn holds(&self, j: usize) -> bool {
        j >= self.first && j < self.first + self.count
    }

    /// The gyroscopic torque to cancel, `(ω × Σ h_i g_i, 0)` with each wheel's absolute
    /// momentum `h_i = J_s (g_iᵀω + Ω_i)` from the body rate `omega` and the wheels' measured
    /// speeds `speeds` relative to the body (docs/maths.md, "Reaction wheels": with it added
    /// to the law's torque, the body with its wheels answers as the rigid body of inertia
    /// `J = I − Σ J_s g gᵀ`). Zero without wheels.
    pub fn gyroscopic<const K: usize>(&self, omega: &Vector3<T>, speeds: &[T]) -> SVector<T, K> {
        let mut h = Vector3::zeros();
        for (w, s) in self.wheels().iter().zip(speeds) {
            let g = Vector3::from(w.axis);
            h += g * (w.inertia * (g.dot(omega) + *s));
        }
        let c = omega.cross(&h);
        let mut out = SVector::<T, K>::zeros();
        for i in 0..K.min(3) {
            out[i] = c[i];
        }
        out
    }

    /// The wheels' momentum in body axes, `h_w = Σ J_s (g_iᵀω + Ω_i) g_i`.
    pub fn momentum(&self, omega: &Vector3<T>, speeds: &[T]) -> Vector3<T> {
        let mut h = Vector3::zeros();
        for (w, s) in self.wheels().iter().zip(speeds) {
            let g = Vector3::from(w.axis);
            h += g * (w.inertia * (g.dot(omega) + *s));
        }
        h
    }

    /// Writes each wheel's preferred torque for the null space into `preferred`:
    /// `−k_n J_s (Ω − Ω_bias)`, which alone would bring its speed to the bias at the rate
    /// `k_n` (docs/maths.md, "Momentum management").
    pub fn null_space(&self, m: &Momentum<T>, speeds: &[T], preferred: &mut Commands<T>) {
        for (i, (w, s)) in self.wheels().iter().zip(speeds).enumerate() {
            preferred[self.first + i] = -(m.null_gain * w.inertia * (*s - m.bias[i]));
        }
    }

    /// The torque the thrusters are to put on the body to dump the wheels' momentum `h`:
    /// `−k_d (|h| − h_thr) h/|h|` above the threshold, else 0
    /// (docs/maths.md, "Momentum management").
    pub fn dump<const K: usize>(m: &Momentum<T>, h: &Vector3<T>) -> SVector<T, K> {
        let size = h.norm();
        let mut out = SVector::<T, K>::zeros();
        if m.dump_gain > T::zero() && size > m.dump_threshold {
            let d = h * (-(m.dump_gain * (size - m.dump_threshold)) / size);
            for i in 0..K.min(3) {
                out[i] = d[i];
            }
        }
        out
    }

    /// Narrows each wheel's bounds so that no command speeds it past its top speed within a
    /// period `h`: at speed `Ω ≥ 0` the upper bound becomes at most `J_s (Ω_max − Ω)/h` (and
    /// not below 0), at `Ω ≤ 0` the lower one at least `−J_s (Ω_max + Ω)/h` (docs/maths.md,
    /// "Reaction wheels"). A speed that is not a number closes both sides.
    pub fn narrow(&self, bounds: &mut Bounds<T>, speeds: &[T], h: T) {
        for (i, (w, s)) in self.wheels().iter().zip(speeds).enumerate() {
            let j = self.first + i;
            let s = *s;
            if !s.is_finite() {
                bounds.lo[j] = T::zero().max(bounds.lo[j]).min(bounds.hi[j]);
                bounds.hi[j] = bounds.lo[j];
                continue;
            }
            let room = |x: T| {
                let r = w.inertia * (w.max_speed - x) / h;
                if r > T::zero() { r } else { T::zero() }
            };
            if s >= T::zero() {
                let hi = room(s);
                if hi < bounds.hi[j] {
                    bounds.hi[j] = hi.max(bounds.lo[j]);
                }
            }
            if s <= T::zero() {
                let lo = -room(-s);
                if lo > bounds.lo[j] {
                    bounds.lo[j] = lo.min(bounds.hi[j]);
                }
            }
        }
    }
}
