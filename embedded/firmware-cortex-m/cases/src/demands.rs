//! The seeded allocation demands of the worst-case count (scripts/cortex-m.sh; docs/vehicles.md,
//! "Bounded time"): for the tilted hexarotor, the eight-thruster ROV and the twelve-thruster
//! spacecraft, [`PER_KIND`] demands of each of four kinds, and a saturating trajectory for the
//! warm-started mean. `no_std`, f32; the stream is splitmix64 from a fixed seed per vehicle.

use eqtrack_allocation::{Allocator, Bounds, Commands, Geometry, Priority, presets};
use nalgebra::SVector;

/// Demands of each kind per vehicle.
pub const PER_KIND: usize = 250;

/// The kinds, in the order the set runs them: a demand some command within the bounds
/// produces; one up to four times past such a wrench; one with a failed actuator (stuck at a
/// random value of its range), and one with two.
pub const KINDS: [&str; 4] = ["within reach", "saturated", "one failed", "two failed"];

/// Ticks of the saturating trajectory.
pub const TRAJECTORY: usize = 400;

/// splitmix64 (Steele, Lea and Flood, 2014): a seeded stream of 64-bit words.
#[derive(Debug, Clone)]
pub struct Seeded(u64);

impl Seeded {
    /// The stream from `seed`.
    pub fn new(seed: u64) -> Self {
        Seeded(seed)
    }

    /// The next word.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)` (24 bits).
    pub fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// The tilted hexarotor of the presets (arm 0.25 m, tilt 0.5 rad, drag 0.016 m, 0–8 N).
pub fn hexarotor() -> Option<Allocator<f32, 6>> {
    let g = Geometry::new(&presets::hexarotor(0.25f32, 0.5, 0.016, 8.0)).ok()?;
    Allocator::new(g, &[], &[], Priority::Torque).ok()
}

/// The eight-thruster ROV of the presets (±40 N).
pub fn rov() -> Option<Allocator<f32, 6>> {
    let g = Geometry::new(&presets::rov_heavy(0.4f32, 0.3, 0.12, 0.22, 40.0)).ok()?;
    Allocator::new(g, &[], &[], Priority::Torque).ok()
}

/// The twelve-thruster spacecraft (SO(3), 0–3 N at 0.5 m).
pub fn spacecraft() -> Option<Allocator<f32, 3>> {
    let g = Geometry::new(&presets::spacecraft_twelve(0.5f32, 3.0)).ok()?;
    Allocator::new(g, &[], &[], Priority::Torque).ok()
}

/// The seed of each vehicle's stream.
pub fn seed(vehicle: &str) -> u64 {
    vehicle.bytes().fold(43, |h, b| h.wrapping_mul(31).wrapping_add(u64::from(b)))
}

/// Demand `i` of the set (`0 ≤ i < 4 · PER_KIND`, kind `i / PER_KIND`) and the bounds it is
/// allocated within.
pub fn demand<const K: usize>(
    alloc: &Allocator<f32, K>,
    i: usize,
    rng: &mut Seeded,
) -> (SVector<f32, K>, Bounds<f32>) {
    let kind = i / PER_KIND;
    let m = alloc.geometry().count();
    let mut bounds = alloc.bounds();
    let (lo, hi) = (bounds.lo, bounds.hi);
    let mut u = Commands::<f32>::zeros();
    for j in 0..m {
        u[j] = lo[j] + (hi[j] - lo[j]) * rng.unit();
    }
    let scale = match kind {
        0 => 1.0,
        1 => 1.0 + 3.0 * rng.unit(),
        _ => 0.5 + 1.5 * rng.unit(),
    };
    let first = (rng.next_u64() % m as u64) as usize;
    let second = (first + 1 + (rng.next_u64() % (m as u64 - 1)) as usize) % m;
    for (n, j) in [first, second].into_iter().enumerate() {
        if n + 2 <= kind {
            bounds.fail(j, lo[j] + (hi[j] - lo[j]) * rng.unit());
        }
    }
    (alloc.geometry().wrench(&u) * scale, bounds)
}

/// Tick `k` of the saturating trajectory: each actuator swept sinusoidally through 1.6 times
/// its range about the middle, at its own frequency, and the wrench of that.
pub fn trajectory<const K: usize>(alloc: &Allocator<f32, K>, k: usize) -> SVector<f32, K> {
    let (lo, hi) = (alloc.bounds().lo, alloc.bounds().hi);
    let t = k as f32 * 0.01;
    let mut u = Commands::<f32>::zeros();
    for j in 0..alloc.geometry().count() {
        let (mid, half) = ((lo[j] + hi[j]) * 0.5, (hi[j] - lo[j]) * 0.5);
        let w = 0.7 + 0.23 * j as f32;
        u[j] = mid + 1.6 * half * nalgebra::ComplexField::sin(w * t + j as f32);
    }
    alloc.geometry().wrench(&u)
}
