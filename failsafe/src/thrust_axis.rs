//! The thrust-axis law (docs/failsafe.md, "The thrust-axis law"): what `descend` flies on a
//! vehicle with gravity that has lost a direction of control. The full law asks for a wrench
//! the actuators can no longer give (a hexarotor without one rotor cannot hold its yaw while
//! it holds its tilt and its thrust), so the vehicle is flown as an underactuated one: the
//! force the set-point needs points the thrust axis, the thrust is its component along the
//! body's axis, the yaw is left free and the body asks for no sideways force. On a vehicle
//! that spins (its yaw given up) the tilt is steered by precession, not against it.
//! `no_std`, allocation-free.

use crate::{Action, Cause, State};
use eqtrack_controller::Real;
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// The law's parameters: the model and the gains derived from the scenario's own.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThrustAxis<T> {
    /// The model's mass (kg): the position loop's natural frequency is `√(k_x/m)`.
    pub mass: T,
    /// The vehicle's net weight (N, along −z of the world): its weight less its buoyancy,
    /// what the thrust carries at rest.
    pub weight: T,
    /// The model's inertia about a horizontal body axis (the mean of `J_xx` and `J_yy`) and
    /// about the thrust axis, `J_zz` (kg m²).
    pub inertia: (T, T),
    /// The position loop's gains, the law's translational `K` and `K_d` (N/m, N s/m).
    pub position: (T, T),
    /// The attitude loop's bandwidth `ω_a` (rad/s): five times the position loop's
    /// natural frequency `√(k_x/m)`.
    pub bandwidth: T,
    /// The actuators' time constant (s): the lag a spinning body's torques are turned
    /// ahead by.
    pub lag: T,
}

/// The attitude loop's bandwidth over the position loop's natural frequency.
pub const SEPARATION: f64 = 5.0;

/// The least vertical share of the force asked for, as a fraction of the weight: the thrust
/// axis is never asked to point sideways or down.
const LEAST_LIFT: f64 = 0.25;

impl<T: Real> ThrustAxis<T> {
    /// The law for a model of `mass` and inertia `(J_xx, J_yy, J_zz)` whose net weight
    /// (weight less buoyancy) is `weight`, with the position gains `(k_x, k_v)` and the
    /// actuators' time constant `lag`. The attitude bandwidth is [`SEPARATION`] times
    /// `√(k_x/m)`. `None` unless the mass, the inertia and the net weight are finite and
    /// positive (a buoyant vehicle does not come down on its thrust), the gains finite and
    /// positive, and the lag finite and not negative.
    pub fn new(mass: T, weight: T, inertia: (T, T, T), position: (T, T), lag: T) -> Option<Self> {
        let positive = |x: T| x.is_finite() && x > T::zero();
        let all = [
            mass, weight, inertia.0, inertia.1, inertia.2, position.0, position.1,
        ];
        if !(all.iter().all(|x| positive(*x)) && lag.is_finite() && lag >= T::zero()) {
            return None;
        }
        let half: T = eqtrack_controller::real(0.5);
        let bandwidth = eqtrack_controller::real::<T>(SEPARATION) * (position.0 / mass).sqrt();
        Some(ThrustAxis {
            mass,
            weight,
            inertia: ((inertia.0 + inertia.1) * half, inertia.2),
            position,
            bandwidth,
            lag,
        })
    }

    /// Whether state word `word` flies this law: `descend` engaged while the actuators'
    /// cause is raised (a direction of control lost).
    pub fn flies(word: u32) -> bool {
        State::read_word(word).is_some_and(|(mode, raised)| {
            mode.action() == Some(Action::Descend) && raised[Cause::Actuators.index()]
        })
    }

    /// [`ThrustAxis::demand`] when state word `word` flies the law ([`ThrustAxis::flies`]);
    /// `None` otherwise: the law's own wrench is allocated.
    pub fn demand_when<const N: usize, const M: usize>(
        &self,
        word: u32,
        estimate: (&SMatrix<T, N, N>, &SVector<T, M>),
        set_point: (&SMatrix<T, N, N>, &SVector<T, M>),
    ) -> Option<SVector<T, M>> {
        if !Self::flies(word) {
            return None;
        }
        self.demand(estimate, set_point)
    }

    /// The body wrench `(τ, f)` the actuators are asked for
    /// (docs/failsafe.md, "The thrust-axis law"), at the estimate `(q, v)` (SE(3): `q` the pose, `v = (ω, v_b)` the
    /// body twist) flying the set-point `(q_d, v_d)` (its pose and body twist). The
    /// restoring wrench (the weight) is not in it: it is the demand itself, which the
    /// allocation meets as well as it can. `None` off SE(3), or where it would not be finite
    /// (a non-finite estimate or set-point): the law's own wrench is allocated then.
    pub fn demand<const N: usize, const M: usize>(
        &self,
        (q, v): (&SMatrix<T, N, N>, &SVector<T, M>),
        (q_d, v_d): (&SMatrix<T, N, N>, &SVector<T, M>),
    ) -> Option<SVector<T, M>> {
        if N != 4 || M != 6 {
            return None;
        }
        let r = Matrix3::from_fn(|i, j| q[(i, j)]);
        let r_d = Matrix3::from_fn(|i, j| q_d[(i, j)]);
        let x = Vector3::new(q[(0, 3)], q[(1, 3)], q[(2, 3)]);
        let x_d = Vector3::new(q_d[(0, 3)], q_d[(1, 3)], q_d[(2, 3)]);
        let omega = Vector3::new(v[0], v[1], v[2]);
        let vel = r * Vector3::new(v[3], v[4], v[5]);
        let vel_d = r_d * Vector3::new(v_d[3], v_d[4], v_d[5]);
        let (tau, thrust) = self.wrench(&r, &omega, (&x, &vel), (&x_d, &vel_d));
        if !(tau.iter().all(|x| x.is_finite()) && thrust.is_finite()) {
            return None;
        }
        let mut out = SVector::<T, M>::zeros();
        for i in 0..3 {
            out[i] = tau[i];
        }
        out[5] = thrust;
        Some(out)
    }

    /// The body torque and the thrust at attitude `r`, body rate `omega`, world position and
    /// velocity `(x, vel)`, flying `(x_d, vel_d)`.
    fn wrench(
        &self,
        r: &Matrix3<T>,
        omega: &Vector3<T>,
        (x, vel): (&Vector3<T>, &Vector3<T>),
        (x_d, vel_d): (&Vector3<T>, &Vector3<T>),
    ) -> (Vector3<T>, T) {
        let (kx, kv) = self.position;
        let weight = self.weight;
        // (1) the force the set-point needs, Lee, Leok & McClamroch 2010 (its eq. 15),
        // never less than a quarter of the weight upward
        let mut force = Vector3::z() * weight - (x - x_d) * kx - (vel - vel_d) * kv;
        let least = weight * eqtrack_controller::real::<T>(LEAST_LIFT);
        if force[2] < least {
            force[2] = least;
        }
        // (2) the thrust: the force's component along the body's axis
        let axis = r * Vector3::z();
        let thrust = force.dot(&axis);
        // (3) the thrust axis asked for, in the body: b
        let b = r.transpose() * (force / force.norm());
        let (j_t, j_z) = self.inertia;
        let w_a = self.bandwidth;
        let two: T = eqtrack_controller::real(2.0);
        let half: T = eqtrack_controller::real(0.5);
        let zeta: T = eqtrack_controller::real(0.7);
        let spin = omega[2];
        let rates = Vector3::new(omega[0], omega[1], T::zero());
        // (4a) a body that does not spin: a PD on the reduced attitude, e₃ × b
        let still = Vector3::z().cross(&b) * (j_t * w_a * w_a) - rates * (two * zeta * w_a * j_t);
        // (4b) a spinning body precesses, ḃ₃ = τ⊥ / (J_zz Ω): turn the axis toward b at the
        // rate ω_a/2, and damp the nutation
        let tilt = Vector3::new(b[0], b[1], T::zero());
        let precess = tilt * (half * w_a * j_z * spin) - rates * (half * w_a * j_t);
        // (4c) the blend: precession once the spin's momentum is twice the tilt loop's,
        // J_zz |Ω| ≥ 2 J_t ω_a
        let share = (j_z * spin.abs() / (two * j_t * w_a)).min(T::one());
        let tau = still * (T::one() - share) + precess * share;
        // (5) the actuators lag by τ_a: a torque fixed in the world turns in the body at −Ω,
        // so it is asked for ahead, by atan(Ω τ_a), and larger by √(1 + (Ω τ_a)²)
        // (a lag of more than a turn's worth is no lag to turn ahead for: clamped there)
        let turn: T = eqtrack_controller::real(core::f64::consts::TAU);
        let phase = (spin * self.lag).max(-turn).min(turn);
        let (c, s) = {
            let angle = -phase.atan();
            (angle.cos(), angle.sin())
        };
        let gain = (T::one() + phase * phase).sqrt();
        let turned = Vector3::new(
            (c * tau[0] - s * tau[1]) * gain,
            (s * tau[0] + c * tau[1]) * gain,
            T::zero(),
        );
        (turned, thrust)
    }
}

impl ThrustAxis<f64> {
    /// The same law in scalar `U` (the firmware's f32).
    pub fn cast<U: Real>(&self) -> ThrustAxis<U> {
        let r = eqtrack_controller::real::<U>;
        ThrustAxis {
            mass: r(self.mass),
            weight: r(self.weight),
            inertia: (r(self.inertia.0), r(self.inertia.1)),
            position: (r(self.position.0), r(self.position.1)),
            bandwidth: r(self.bandwidth),
            lag: r(self.lag),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    fn law() -> ThrustAxis<f64> {
        ThrustAxis::new(1.5, 1.5 * 9.81, (0.02, 0.02, 0.04), (6.0, 4.0), 0.02).unwrap()
    }

    fn pose(r: Matrix3<f64>, x: Vector3<f64>) -> SMatrix<f64, 4, 4> {
        let mut q = SMatrix::<f64, 4, 4>::identity();
        q.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
        q.fixed_view_mut::<3, 1>(0, 3).copy_from(&x);
        q
    }

    #[test]
    fn level_at_its_set_point_it_asks_for_its_weight_and_no_torque() {
        let l = law();
        assert!((l.bandwidth - 10.0).abs() < 1e-12);
        let q = pose(Matrix3::identity(), Vector3::new(1.0, 2.0, 3.0));
        let d = l
            .demand::<4, 6>((&q, &SVector::zeros()), (&q, &SVector::zeros()))
            .unwrap();
        assert!((d[5] - 1.5 * 9.81).abs() < 1e-12, "{d}");
        assert!(d.rows(0, 5).norm() < 1e-12, "{d}");
        // off SE(3) there is no such law
        let so3 = SMatrix::<f64, 3, 3>::identity();
        assert!(
            l.demand::<3, 3>((&so3, &SVector::zeros()), (&so3, &SVector::zeros()))
                .is_none()
        );
    }

    #[test]
    fn a_still_body_is_turned_toward_the_force_and_a_spinning_one_precesses() {
        let l = law();
        // tilted about x by 0.2 rad, at its set-point: the force is straight up, so the
        // torque turns the body back about −x (the thrust, the weight's share along the axis)
        let r = Rotation3::from_axis_angle(&Vector3::x_axis(), 0.2).into_inner();
        let q = pose(r, Vector3::zeros());
        let d = l
            .demand::<4, 6>((&q, &SVector::zeros()), (&q, &SVector::zeros()))
            .unwrap();
        assert!(d[0] < 0.0 && d[1].abs() < 1e-12 && d[2] == 0.0, "{d}");
        assert!((d[5] - 1.5 * 9.81 * 0.2f64.cos()).abs() < 1e-12);
        // the same, spinning at −40 rad/s about the body's axis: the torque points along
        // the way the axis must move (precession), turned ahead for the lag
        let mut v = SVector::<f64, 6>::zeros();
        v[2] = -40.0;
        let s = l.demand::<4, 6>((&q, &v), (&q, &SVector::zeros())).unwrap();
        // b in the body is (0, sin 0.2, cos 0.2): the precession torque is along +y times
        // J_zz Ω < 0, then turned by atan(0.8)
        let expect = 0.5 * 10.0 * 0.04 * -40.0 * 0.2f64.sin();
        let angle = (40.0f64 * 0.02).atan();
        let gain = (1.0 + 0.64f64).sqrt();
        assert!((s[0] - (-angle.sin()) * expect * gain).abs() < 1e-9, "{s}");
        assert!((s[1] - angle.cos() * expect * gain).abs() < 1e-9, "{s}");
        assert_eq!(s[2], 0.0);
        // never a sideways or downward force asked for: a set-point far below still lifts
        let below = pose(Matrix3::identity(), Vector3::new(0.0, 0.0, -100.0));
        let d = l
            .demand::<4, 6>((&q, &SVector::zeros()), (&below, &SVector::zeros()))
            .unwrap();
        assert!(d[5] > 0.0 && d.iter().all(|x| x.is_finite()), "{d}");
        // a set-point 1 m along −x of a level body: the force leans toward it, so the body is
        // pitched (about −y) to tilt its thrust that way, and the thrust is the force's
        // vertical part, the weight
        let level = pose(Matrix3::identity(), Vector3::new(1.0, 0.0, 0.0));
        let origin = pose(Matrix3::identity(), Vector3::zeros());
        let d = l
            .demand::<4, 6>((&level, &SVector::zeros()), (&origin, &SVector::zeros()))
            .unwrap();
        let force = Vector3::<f64>::new(-6.0, 0.0, 1.5 * 9.81);
        let b = force / force.norm();
        assert!(
            (d[1] - 0.02 * 100.0 * b[0]).abs() < 1e-12 && d[1] < 0.0,
            "{d}"
        );
        assert!(
            d[0].abs() < 1e-12 && (d[5] - 1.5 * 9.81).abs() < 1e-12,
            "{d}"
        );
    }

    #[test]
    fn bad_parameters_and_non_finite_states_give_no_law_and_no_nan() {
        let ok = (1.5, 14.7, (0.02, 0.02, 0.04), (6.0, 4.0), 0.02);
        assert!(ThrustAxis::new(ok.0, ok.1, ok.2, ok.3, ok.4).is_some());
        // a buoyant vehicle (no net weight), a zero mass or inertia, a NaN gain, a negative lag
        for (m, w, j, k, lag) in [
            (1.5, 0.0, ok.2, ok.3, ok.4),
            (1.5, -3.0, ok.2, ok.3, ok.4),
            (0.0, 14.7, ok.2, ok.3, ok.4),
            (1.5, 14.7, (0.02, 0.0, 0.04), ok.3, ok.4),
            (1.5, 14.7, ok.2, (f64::NAN, 4.0), ok.4),
            (1.5, 14.7, ok.2, ok.3, -0.01),
        ] {
            assert!(
                ThrustAxis::new(m, w, j, k, lag).is_none(),
                "{m} {w} {j:?} {k:?} {lag}"
            );
        }
        // a huge lag is clamped to a turn: finite
        let slow = ThrustAxis::new(1.5, 14.7, ok.2, ok.3, 1e30).unwrap();
        let q = pose(Matrix3::identity(), Vector3::zeros());
        let mut v = SVector::<f64, 6>::zeros();
        v[2] = -40.0;
        v[0] = 0.1;
        let d = slow
            .demand::<4, 6>((&q, &v), (&q, &SVector::zeros()))
            .unwrap();
        assert!(d.iter().all(|x| x.is_finite()), "{d}");
        // a NaN estimate: no demand (the law's own wrench is allocated)
        let mut bad = q;
        bad[(0, 3)] = f64::NAN;
        assert!(
            law()
                .demand::<4, 6>((&bad, &v), (&q, &SVector::zeros()))
                .is_none()
        );
    }

    #[test]
    fn it_flies_only_a_descent_for_lost_actuators() {
        use crate::{Config, Inputs, step};
        let mut cfg = Config {
            actions: [None; 4],
            clear_ticks: 3,
        };
        cfg.actions[Cause::Actuators as usize] = Some(Action::Descend);
        cfg.actions[Cause::Estimator as usize] = Some(Action::Descend);
        let nominal = State::default();
        assert!(!ThrustAxis::<f64>::flies(nominal.word()));
        let estimator = Inputs {
            estimator: true,
            ..Inputs::default()
        };
        let (est, _) = step(&cfg, &nominal, &estimator);
        assert!(!ThrustAxis::<f64>::flies(est.word()));
        let actuators = Inputs {
            actuators: true,
            ..Inputs::default()
        };
        let (act, _) = step(&cfg, &nominal, &actuators);
        assert!(ThrustAxis::<f64>::flies(act.word()));
        // a word the manager never writes flies nothing
        assert!(!ThrustAxis::<f64>::flies(u32::MAX));
    }
}
