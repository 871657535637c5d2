//! The simulated board's sensors (docs/maths.md, "Sensor models"): a gyro with a drifting
//! bias, direction sensors, and on SE(3) an accelerometer and position fixes, sampled at every
//! control tick `t_k` from the true state, from one seeded ChaCha8 stream.
//!
//! The numbers are drawn in a fixed order at each tick — gyro noise (3), each direction's
//! noise (3 each, in the list's order), the accelerometer's (3), the position fix's (3, only
//! on a tick that takes a fix), then the bias walk (3) — so the plant of the pair and the
//! in-process simulation draw the same numbers.
//!
//! Scripted faults (`[[sensors.fault]]`, docs/scenario.md, "Sensor faults") are applied to
//! the samples after the draws, so they change nothing outside their own sensor and time.

use eqtrack_controller::group::BuiltinGroup;
use eqtrack_controller::integrator::RigidBody;
use nalgebra::{Matrix3, SVector, Vector3};
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use scenario::SensorsSpec;
use scenario::sensing::{GRAVITY, MAX_DIRECTIONS, Sensor, SensorFaultKind};

pub use recorder::Samples;

// the sensor block of a record holds as many directions as a scenario may have
const _: () = assert!(recorder::MAX_DIRECTIONS == MAX_DIRECTIONS);

/// Test-build faults planted in a tick's samples (`plant_sim --fault-sample K:KIND`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleFault {
    /// A NaN in the gyro.
    GyroNan,
    /// An infinite gyro entry.
    GyroInf,
    /// A gyro spike of 100 rad/s on every axis.
    GyroSpike,
    /// A NaN in the first direction.
    DirectionNan,
    /// An infinite entry in the first direction.
    DirectionInf,
    /// The first direction of zero length.
    DirectionZero,
    /// An accelerometer sample far from `g` (10 g straight up in the body frame).
    AccelFar,
    /// A position fix scaled by `1 + 1e-6` about the world origin: a reading that depends on
    /// where the origin is (the moved-flight check must catch it).
    PositionScaled,
}

impl SampleFault {
    /// The name on the command line.
    pub fn parse(text: &str) -> Option<SampleFault> {
        Some(match text {
            "gyro-nan" => SampleFault::GyroNan,
            "gyro-inf" => SampleFault::GyroInf,
            "gyro-spike" => SampleFault::GyroSpike,
            "dir-nan" => SampleFault::DirectionNan,
            "dir-inf" => SampleFault::DirectionInf,
            "dir-zero" => SampleFault::DirectionZero,
            "accel-far" => SampleFault::AccelFar,
            "pos-scaled" => SampleFault::PositionScaled,
            _ => return None,
        })
    }

    /// Plants the fault.
    pub fn apply(self, s: &mut Samples) {
        match self {
            SampleFault::GyroNan => s.gyro[1] = f64::NAN,
            SampleFault::GyroInf => s.gyro[0] = f64::INFINITY,
            SampleFault::GyroSpike => s.gyro += Vector3::repeat(100.0),
            SampleFault::DirectionNan => s.directions[0][2] = f64::NAN,
            SampleFault::DirectionInf => s.directions[0][0] = f64::NEG_INFINITY,
            SampleFault::DirectionZero => s.directions[0] = Vector3::zeros(),
            SampleFault::AccelFar => {
                if let Some(a) = &mut s.accel {
                    *a = Vector3::new(0.0, 0.0, 10.0 * GRAVITY);
                }
            }
            SampleFault::PositionScaled => {
                if let Some(x) = &mut s.position {
                    *x *= 1.0 + 1e-6;
                }
            }
        }
    }
}

/// Three independent `N(0, σ²)` draws.
fn normal3(rng: &mut ChaCha8Rng, sigma: f64) -> Vector3<f64> {
    let n: [f64; 3] = std::array::from_fn(|_| StandardNormal.sample(rng));
    Vector3::from(n) * sigma
}

/// The sensors of one run.
#[derive(Debug, Clone)]
pub struct Sensors {
    spec: SensorsSpec,
    rng: ChaCha8Rng,
    bias: Vector3<f64>,
    period: f64,
    /// The next position fix is due at `next_fix · (1/rate_hz)`.
    next_fix: u64,
    /// Each sensor's last sample outside a fault (what a `stuck` fault repeats).
    last: Last,
}

/// The last sample of each sensor given outside a fault (`None`: none yet).
#[derive(Debug, Clone, Copy, Default)]
struct Last {
    gyro: Option<Vector3<f64>>,
    directions: [Option<Vector3<f64>>; MAX_DIRECTIONS],
    accel: Option<Vector3<f64>>,
    position: Option<Vector3<f64>>,
}

/// A sample of NaNs: what a dropped-out gyro, direction or accelerometer gives.
fn nothing() -> Vector3<f64> {
    Vector3::repeat(f64::NAN)
}

impl Sensors {
    /// The sensors of `spec`, sampled every `period` seconds.
    pub fn new(spec: &SensorsSpec, period: f64) -> Sensors {
        Sensors {
            rng: ChaCha8Rng::seed_from_u64(spec.seed),
            bias: Vector3::from(spec.gyro.bias),
            spec: spec.clone(),
            period,
            next_fix: 0,
            last: Last::default(),
        }
    }

    /// How many direction sensors.
    pub fn directions(&self) -> usize {
        self.spec.directions.len()
    }

    /// The samples at tick `k` from the true body. `torque` is what the plant held over the
    /// previous period (command plus disturbance; zero at k = 0): the accelerometer at `t_k`
    /// sees the acceleration it causes at `t_k`.
    pub fn sample<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
        &mut self,
        k: u64,
        body: &RigidBody<f64, G, N, M>,
        torque: &SVector<f64, M>,
    ) -> Samples {
        let q = body.configuration();
        let v = body.velocity();
        let r = Matrix3::from_fn(|i, j| q[(i, j)]);
        let omega = Vector3::new(v[0], v[1], v[2]);
        let h = self.period;
        let Sensors { spec, rng, .. } = self;
        let gyro = omega + self.bias + normal3(rng, spec.gyro.noise / h.sqrt());
        let mut directions = [Vector3::zeros(); MAX_DIRECTIONS];
        for (y, d) in directions.iter_mut().zip(&spec.directions) {
            let body_dir = r.tr_mul(&Vector3::from(d.world)) + normal3(rng, d.noise);
            let n = body_dir.norm();
            *y = if n > 0.0 { body_dir / n } else { body_dir };
        }
        let accel = spec.accelerometer.map(|sigma| {
            // the specific force f = Rᵀ(ẍ − g) = ω × v + v̇ − Rᵀg, with v̇ from the
            // Euler–Poincaré equations (the body velocity's linear part)
            let v_dot = body.velocity_rate(torque);
            let lin = Vector3::new(v[3], v[4], v[5]);
            let lin_dot = Vector3::new(v_dot[3], v_dot[4], v_dot[5]);
            let g = Vector3::new(0.0, 0.0, -GRAVITY);
            omega.cross(&lin) + lin_dot - r.tr_mul(&g) + normal3(rng, sigma)
        });
        let position = match spec.position {
            Some(p) if k as f64 * h + 1e-9 * h >= self.next_fix as f64 / p.rate_hz => {
                // the fix taken at or before this tick arrives now; later ones are due at
                // their own times: the first fix due after now, found from just below it
                // (the same fix as counting one by one, in bounded time at any rate)
                let now = k as f64 * h + 1e-9 * h;
                let below = (now * p.rate_hz).floor() - 1.0;
                self.next_fix = self.next_fix.max(below.max(0.0) as u64);
                while self.next_fix as f64 / p.rate_hz <= now && self.next_fix < u64::MAX {
                    self.next_fix += 1;
                }
                let x = Vector3::new(q[(0, 3)], q[(1, 3)], q[(2, 3)]);
                Some(x + normal3(rng, p.noise))
            }
            _ => None,
        };
        let bias = self.bias;
        let walk = self.spec.gyro.bias_walk * h.sqrt();
        self.bias += normal3(&mut self.rng, walk);
        let mut samples = Samples {
            gyro,
            directions,
            count: self.spec.directions.len(),
            accel,
            position,
            bias,
        };
        self.fault(k as f64 * h, &mut samples);
        samples
    }

    /// Applies the scripted faults on at `t_k` to the tick's samples, and keeps each healthy
    /// sensor's sample for a later `stuck` fault.
    fn fault(&mut self, t_k: f64, s: &mut Samples) {
        let h = self.period;
        let on = |sensor: Sensor| {
            self.spec
                .faults
                .iter()
                .find(|f| f.sensor == sensor && f.active(t_k, h))
                .map(|f| f.kind)
        };
        let last = &mut self.last;
        // the gyro, a direction and the accelerometer sample every tick
        let every = |kind: Option<SensorFaultKind>, x: &mut Vector3<f64>, last: &mut Option<_>| {
            match kind {
                None => *last = Some(*x),
                Some(SensorFaultKind::Bias(b)) => *x += Vector3::from(b),
                Some(SensorFaultKind::Dropout) => *x = nothing(),
                Some(SensorFaultKind::Stuck) => *x = last.unwrap_or_else(nothing),
            }
        };
        every(on(Sensor::Gyro), &mut s.gyro, &mut last.gyro);
        for i in 0..s.count {
            let kind = on(Sensor::Direction(i));
            if let Some(SensorFaultKind::Bias(r)) = kind {
                // a direction's bias turns it (body axes)
                s.directions[i] =
                    eqtrack_controller::group::so3::exp_so3(&Vector3::from(r)) * s.directions[i];
            } else {
                every(kind, &mut s.directions[i], &mut last.directions[i]);
            }
        }
        if let Some(a) = &mut s.accel {
            every(on(Sensor::Accelerometer), a, &mut last.accel);
        }
        // position fixes come only on the ticks that take one
        if let Some(x) = s.position {
            s.position = match on(Sensor::Position) {
                None => {
                    last.position = Some(x);
                    Some(x)
                }
                Some(SensorFaultKind::Bias(b)) => Some(x + Vector3::from(b)),
                Some(SensorFaultKind::Dropout) => None,
                Some(SensorFaultKind::Stuck) => last.position,
            };
        }
    }
}
