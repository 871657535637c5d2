//! The plant's state message, [`StateMsg`], and its accessors.

use crate::{Identity, MAX_M, MAX_N, MAX_WHEELS, NAME_BYTES, PROTOCOL_VERSION, WireGroup};
#[cfg(feature = "zero-copy")]
use iceoryx2_bb_derive_macros::ZeroCopySend;
#[cfg(feature = "zero-copy")]
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;
use nalgebra::{SMatrix, SVector};

/// The plant's state at `t_k`: configuration and body velocity (what a gyro measures), and
/// the identity of what the plant runs.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "zero-copy",
    derive(ZeroCopySend),
    type_name("eqtrack::StateMsg7")
)]
#[repr(C)]
pub struct StateMsg {
    /// [`PROTOCOL_VERSION`].
    pub version: u32,
    /// [`WireGroup::code`].
    pub group: u32,
    /// Control step k (strictly increasing).
    pub seq: u64,
    /// Time `t_k = k·control_period` (s).
    pub t: f64,
    /// The plant's control period (s); the controller's reference steps with it.
    pub control_period: f64,
    /// CLOCK_MONOTONIC at publication (ns).
    pub stamp_ns: u64,
    /// `Q`, row-major n×n in the first n² entries.
    pub q: [f64; MAX_N * MAX_N],
    /// Body velocity `V` in the first m entries (SE(3): ω then v).
    pub v: [f64; MAX_M],
    /// The torque the plant applied over `[t_{k−1}, t_k)` (after saturation, held commands
    /// or safe mode; without the disturbance), first m entries; zero at k = 0. The
    /// disturbance-rejection terms need it.
    pub applied: [f64; MAX_M],
    /// [`flags`](crate::flags) bits.
    pub flags: u32,
    /// The plant's process id (the controller's liveness check; 0: unknown).
    pub plant_pid: u32,
    /// Fingerprint of the plant's scenario settings (0: none, e.g. a hardware plant).
    pub fingerprint: u64,
    /// The plant's scenario name, UTF-8, NUL-padded (empty: none).
    pub scenario: [u8; NAME_BYTES],
    /// How many reaction wheels the plant carries (0: none; at most [`MAX_WHEELS`]).
    pub wheels: u32,
    /// Zero (keeps the speeds 8-byte aligned).
    pub reserved_wheels: u32,
    /// The wheels' speeds `Ω_i` relative to the body at `t_k` (rad/s), first `wheels`
    /// entries in the scenario's `[[vehicle.wheel]]` order; the law's gyroscopic term needs
    /// them.
    pub wheel_speeds: [f64; MAX_WHEELS],
}

impl StateMsg {
    /// A zeroed message of `group` with the version filled in.
    pub fn new(group: WireGroup) -> Self {
        StateMsg {
            version: PROTOCOL_VERSION,
            group: group.code(),
            seq: 0,
            t: 0.0,
            control_period: 0.0,
            stamp_ns: 0,
            q: [0.0; MAX_N * MAX_N],
            v: [0.0; MAX_M],
            applied: [0.0; MAX_M],
            flags: 0,
            plant_pid: 0,
            fingerprint: 0,
            scenario: [0; NAME_BYTES],
            wheels: 0,
            reserved_wheels: 0,
            wheel_speeds: [0.0; MAX_WHEELS],
        }
    }

    /// Writes the configuration `Q` (row-major) and the body velocity `V`.
    pub fn set_state<const N: usize, const M: usize>(
        &mut self,
        q: &SMatrix<f64, N, N>,
        v: &SVector<f64, M>,
    ) {
        for i in 0..N.min(MAX_N) {
            for j in 0..N.min(MAX_N) {
                self.q[i * N + j] = q[(i, j)];
            }
        }
        for i in 0..M.min(MAX_M) {
            self.v[i] = v[i];
        }
    }

    /// The configuration `Q` (n×n, from the row-major entries).
    pub fn configuration<const N: usize>(&self) -> SMatrix<f64, N, N> {
        SMatrix::from_fn(|i, j| self.q.get(i * N + j).copied().unwrap_or(f64::NAN))
    }

    /// The body velocity `V` (m entries).
    pub fn velocity<const M: usize>(&self) -> SVector<f64, M> {
        SVector::from_fn(|i, _| self.v.get(i).copied().unwrap_or(f64::NAN))
    }

    /// The torque applied over the last period (m entries).
    pub fn applied_torque<const M: usize>(&self) -> SVector<f64, M> {
        SVector::from_fn(|i, _| self.applied.get(i).copied().unwrap_or(f64::NAN))
    }

    /// Writes the torque applied over the last period.
    pub fn set_applied<const M: usize>(&mut self, tau: &SVector<f64, M>) {
        for i in 0..M.min(MAX_M) {
            self.applied[i] = tau[i];
        }
    }

    /// Writes the wheel count and speeds (relative to the body, rad/s). More than
    /// [`MAX_WHEELS`] speeds keep the first [`MAX_WHEELS`] and set the count past it, which
    /// [`check_state`](crate::check_state) refuses.
    pub fn set_wheel_speeds(&mut self, speeds: &[f64]) {
        self.wheels = u32::try_from(speeds.len()).unwrap_or(u32::MAX);
        self.wheel_speeds = [0.0; MAX_WHEELS];
        for (slot, w) in self.wheel_speeds.iter_mut().zip(speeds) {
            *slot = *w;
        }
    }

    /// The wheel speeds carried (the first `wheels` entries, at most [`MAX_WHEELS`]).
    pub fn wheel_speeds(&self) -> &[f64] {
        let k = (self.wheels as usize).min(MAX_WHEELS);
        &self.wheel_speeds[..k]
    }

    /// The plant's identity carried by this state.
    pub fn identity(&self) -> Identity {
        Identity {
            group: self.group,
            period: self.control_period,
            fingerprint: self.fingerprint,
            scenario: self.scenario,
        }
    }
}
