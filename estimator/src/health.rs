//! The innovation gate and the estimator's health
//! (docs/estimators.md, "The innovation gate and health"): each direction sample and each position fix is tested before the filter
//! uses it, by its normalised innovation squared (NIS) against the χ² threshold of a stated
//! false-alarm rate, and rejected when it fails; a monitor over a sliding window of ticks
//! turns the rejections, the gaps in each sensor's samples and the mean NIS of each block of
//! passed samples against its χ² band into `healthy`, `degraded` or `lost`, with the reason. `no_std`, allocation-free: fixed arrays, no clock (it counts ticks).

use crate::complementary::SLOTS;
use crate::{AttitudeConfig, AttitudeFilter, Directions};
use eqtrack_controller::Real;
use nalgebra::{Matrix3, Vector3};

/// At most this many rejections within a window are kept per source.
pub const MAX_REJECTIONS: usize = 8;

/// The sources the monitor watches: the direction slots (on SE(3) the accelerometer's "up"
/// is the slot after the direction sensors), then the gyro, then the position fixes.
const SOURCES: usize = SLOTS + 2;
const GYRO: usize = SLOTS;
const POSITION: usize = SLOTS + 1;

/// A sensor the monitor names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub enum Source {
    /// Direction sensor `i` (in the scenario's list).
    Direction(u8),
    /// The accelerometer as the direction "up" (SE(3)).
    Accelerometer,
    /// The gyro.
    Gyro,
    /// The position fixes (SE(3)).
    Position,
    /// The attitude as a whole: fewer than two direction sources usable.
    Attitude,
}

/// What is wrong.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub enum Reason {
    /// The gate rejected at least the configured number of the source's samples within the
    /// window.
    Rejected(Source),
    /// The source gave no usable sample (present and finite) for a whole window; for
    /// [`Source::Attitude`], fewer than two direction sources passed the gate within it.
    Missing(Source),
    /// A sample was taken without the test within the window: position fixes after a window
    /// in which none passed (the estimate had drifted from them, or they jumped).
    Reset(Source),
    /// The last block of the source's passed samples had a summed NIS above its χ² band:
    /// each sample passed the gate, but together they sit further from the estimate than
    /// the filter's covariance and the noise allow (a small bias, or noise above its model).
    Inconsistent(Source),
}

/// The estimator's health at a tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Health {
    /// Every source is giving samples that pass the gate.
    Healthy,
    /// A source is missing or rejected; the estimate goes on without it.
    Degraded(Reason),
    /// The estimate has lost what it needs: the gyro, or two usable directions.
    Lost(Reason),
}

impl Health {
    /// 0 healthy, 1 degraded, 2 lost: the code in `trajectory.csv`'s `health` column.
    pub fn code(&self) -> u8 {
        match self {
            Health::Healthy => 0,
            Health::Degraded(_) => 1,
            Health::Lost(_) => 2,
        }
    }

    /// The reason, if not healthy.
    pub fn reason(&self) -> Option<Reason> {
        match self {
            Health::Healthy => None,
            Health::Degraded(r) | Health::Lost(r) => Some(*r),
        }
    }
}

/// The gate's thresholds and the monitor's window, from the scenario's false-alarm rate
/// (docs/estimators.md, "The innovation gate and health").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GateConfig<T: Real> {
    /// The χ² threshold of a direction sample's NIS (two degrees of freedom).
    pub direction: T,
    /// The χ² threshold of a position fix's NIS (three degrees of freedom).
    pub position: T,
    /// The complementary filter's test: each direction source's noise `σ_i` (unitless; the
    /// accelerometer's "up" in its slot). The EqF tests against its own noise model.
    pub noise: [T; SLOTS],
    /// The monitor's window (ticks, ≥ 1).
    pub window: u32,
    /// Rejections of one source within a window that make it degraded (1 to
    /// [`MAX_REJECTIONS`]).
    pub rejections: u32,
    /// The band on each direction source's summed NIS.
    pub direction_band: Band<T>,
    /// The band on the position fixes' summed NIS.
    pub position_band: Band<T>,
}

/// The χ² band on the mean NIS (docs/estimators.md, "The innovation gate and health"): a
/// source's passed samples are summed in blocks of `samples` in a row (a rejection or a reset
/// starts a block again); a consistent filter's block
/// sum is χ² with `samples` times the sample's degrees of freedom, and a sum above `upper`
/// (that distribution's upper quantile at the stated false-alarm rate) makes the source
/// inconsistent until a block passes. `samples = 0` turns the band off.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Band<T: Real> {
    /// Passed samples per block (0: no band).
    pub samples: u32,
    /// The upper bound on a block's summed NIS.
    pub upper: T,
}

impl<T: Real> Band<T> {
    /// No band.
    pub fn off() -> Self {
        Band {
            samples: 0,
            upper: T::zero(),
        }
    }
}

/// One tick's verdict on each source.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Verdicts<T: Real> {
    /// Bit `s` set: source `s` gave a usable sample this tick (direction slots, then the
    /// gyro, then the position fix).
    pub present: u8,
    /// Bit `s` set: the gate rejected source `s`'s sample this tick.
    pub rejected: u8,
    /// Bit `s` set: source `s`'s sample was present but not used, and not for the gate's
    /// reasons (the accelerometer kept out by `accel_gate` while the body accelerates).
    pub unused: u8,
    /// Bit `s` set: source `s`'s sample was taken without the test (a reset).
    pub reset: u8,
    /// The NIS of each source's sample that passed the gate this tick (0 otherwise).
    pub nis: [T; SOURCES],
}

impl<T: Real> Default for Verdicts<T> {
    fn default() -> Self {
        Verdicts {
            present: 0,
            rejected: 0,
            unused: 0,
            reset: 0,
            nis: [T::zero(); SOURCES],
        }
    }
}

/// The gate and the health monitor of one filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gate<T: Real> {
    cfg: GateConfig<T>,
    /// Direction slots in use (the sensors, and on SE(3) the accelerometer's "up" last).
    slots: usize,
    se3: bool,
    tick: u64,
    /// The tick each source last gave a usable sample, last passed the gate, and was last
    /// reset (`u64::MAX`: never).
    present_at: [u64; SOURCES],
    passed_at: [u64; SOURCES],
    reset_at: [u64; SOURCES],
    /// The ticks of each source's latest rejections, a ring (`u64::MAX`: none).
    rejected_at: [[u64; MAX_REJECTIONS]; SOURCES],
    rejected_next: [usize; SOURCES],
    /// Rejections since the start, per source.
    totals: [u64; SOURCES],
    /// The block being summed: each source's NIS and its count of passed samples.
    block_sum: [T; SOURCES],
    block_count: [u32; SOURCES],
    /// Whether the source's last complete block was above its band.
    inconsistent: [bool; SOURCES],
    /// Blocks above the band since the start, and every passed sample's NIS summed and
    /// counted (after the first window), per source.
    inconsistent_blocks: [u64; SOURCES],
    nis_total: [T; SOURCES],
    nis_samples: [u64; SOURCES],
    health: Health,
}

impl<T: Real> Gate<T> {
    /// A gate over `directions` direction sensors (and on SE(3) the accelerometer and
    /// position fixes). The window and the rejection count are clamped into their ranges.
    pub fn new(mut cfg: GateConfig<T>, directions: usize, se3: bool) -> Self {
        cfg.window = cfg.window.max(1);
        cfg.rejections = cfg.rejections.clamp(1, MAX_REJECTIONS as u32);
        Gate {
            cfg,
            slots: (directions + usize::from(se3)).min(SLOTS),
            se3,
            tick: 0,
            present_at: [0; SOURCES],
            passed_at: [0; SOURCES],
            reset_at: [u64::MAX; SOURCES],
            rejected_at: [[u64::MAX; MAX_REJECTIONS]; SOURCES],
            rejected_next: [0; SOURCES],
            totals: [0; SOURCES],
            block_sum: [T::zero(); SOURCES],
            block_count: [0; SOURCES],
            inconsistent: [false; SOURCES],
            inconsistent_blocks: [0; SOURCES],
            nis_total: [T::zero(); SOURCES],
            nis_samples: [0; SOURCES],
            health: Health::Healthy,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &GateConfig<T> {
        &self.cfg
    }

    /// The health after the last tick.
    pub fn health(&self) -> Health {
        self.health
    }

    /// Rejections since the start: each direction sensor's (in order), the accelerometer's
    /// (SE(3)), and the position fixes'.
    pub fn rejections(&self) -> impl Iterator<Item = (Source, u64)> + '_ {
        (0..self.slots)
            .map(|s| (self.source(s), self.totals[s]))
            .chain(self.se3.then(|| (Source::Position, self.totals[POSITION])))
    }

    /// Per watched source (as [`Self::rejections`] orders them): the blocks whose summed
    /// NIS was above the band, and the mean NIS of the passed samples after the first window
    /// (`None` without one). A consistent filter's mean is the sample's degrees of freedom:
    /// 2 for a direction, 3 for a fix.
    pub fn consistency(&self) -> impl Iterator<Item = (Source, u64, Option<T>)> + '_ {
        let mean = |s: usize| {
            (self.nis_samples[s] > 0).then(|| {
                self.nis_total[s] / eqtrack_controller::real::<T>(self.nis_samples[s] as f64)
            })
        };
        (0..self.slots)
            .chain(self.se3.then_some(POSITION))
            .map(move |s| (self.source(s), self.inconsistent_blocks[s], mean(s)))
    }

    fn source(&self, s: usize) -> Source {
        match s {
            GYRO => Source::Gyro,
            POSITION => Source::Position,
            s if self.se3 && s + 1 == self.slots => Source::Accelerometer,
            s => Source::Direction(s as u8),
        }
    }

    /// The direction test (docs/estimators.md, "The innovation gate and health"): removes
    /// from `y` each usable direction whose NIS against the filter's prior exceeds the
    /// threshold, and marks the tick's verdicts. Before the filter has started nothing is
    /// tested.
    pub(crate) fn directions<F: AttitudeFilter<T>>(
        &self,
        filter: &F,
        h: T,
        gyro: &Vector3<T>,
        y: &mut Directions<T>,
        verdicts: &mut Verdicts<T>,
    ) {
        let prior = filter.prior(h, gyro);
        for (s, slot) in y.iter_mut().enumerate().take(self.slots) {
            let Some(yi) = *slot else { continue };
            verdicts.present |= 1 << s;
            let Some((r, sigma)) = prior else { continue };
            let d = filter.config().world(s);
            let ry = r * yi;
            let innovation = ry - d;
            let s_matrix = match (sigma, filter.noise(s)) {
                // the EqF: S = M Σ_RR Mᵀ + σ² I with M = ½(d + R̂y)×
                (Some(p), noise) => {
                    let half: T = eqtrack_controller::real(0.5);
                    let m = eqtrack_controller::group::so3::skew(&((d + ry) * half));
                    m * p * m.transpose() + Matrix3::identity() * (noise * noise)
                }
                // the complementary filter: the sensors' noise model alone
                (None, _) => {
                    let noise = self.cfg.noise[s];
                    Matrix3::identity() * (noise * noise)
                }
            };
            let nis = match s_matrix.try_inverse() {
                Some(inv) => innovation.dot(&(inv * innovation)),
                None => continue,
            };
            // a NaN NIS fails too
            let pass = nis <= self.cfg.direction;
            if pass {
                verdicts.nis[s] = nis;
            } else {
                *slot = None;
                verdicts.rejected |= 1 << s;
            }
        }
    }

    /// The position test: whether a fix with innovation `z − x̂⁻` and scalar per-axis
    /// innovation variance `s` passes (NIS `|z − x̂⁻|²/s` within the χ²₃ threshold). When no
    /// fix has passed for a whole window a failing fix is taken all the same, a reset, and
    /// reported (`degraded`, "reset position", for a window): either the dead-reckoned
    /// position has drifted further than its covariance says (after a long loss of fixes,
    /// when without the reset the gate would keep out every fix for good) or the fixes have
    /// jumped, and the estimator cannot tell which (EKF2 resets an aiding source after a
    /// timeout in the same way). Directions have no such reset: a sensor turned for good
    /// stays rejected.
    pub(crate) fn position(
        &self,
        innovation: &Vector3<T>,
        s: T,
        verdicts: &mut Verdicts<T>,
    ) -> bool {
        verdicts.present |= 1 << POSITION;
        let now = self.tick + 1;
        let w = u64::from(self.cfg.window);
        let nis = innovation.dot(innovation) / s;
        let pass = s > T::zero() && nis <= self.cfg.position;
        if pass {
            verdicts.nis[POSITION] = nis;
        }
        let stale = now >= w && now - self.passed_at[POSITION] >= w;
        if !pass && stale {
            verdicts.reset |= 1 << POSITION;
            return true;
        }
        if !pass {
            verdicts.rejected |= 1 << POSITION;
        }
        pass
    }

    /// The monitor's tick: the verdicts of this tick (and whether the gyro sample was
    /// usable) turned into the health over the window
    /// (docs/estimators.md, "The innovation gate and health").
    pub(crate) fn observe(&mut self, mut verdicts: Verdicts<T>, gyro_ok: bool) -> Health {
        self.tick += 1;
        let now = self.tick;
        let judged = now > u64::from(self.cfg.window);
        if gyro_ok {
            verdicts.present |= 1 << GYRO;
        }
        for s in 0..SOURCES {
            let bit = 1 << s;
            if verdicts.present & bit != 0 {
                self.present_at[s] = now;
                if (verdicts.rejected | verdicts.unused) & bit == 0 {
                    self.passed_at[s] = now;
                    // the band: tested samples after the first window, a reset not among them
                    if judged && s != GYRO && verdicts.reset & bit == 0 {
                        self.band(s, verdicts.nis[s]);
                    }
                }
            }
            if verdicts.reset & bit != 0 {
                self.reset_at[s] = now;
            }
            // a block sums passed samples in a row: a rejection or a reset starts it again
            if (verdicts.rejected | verdicts.reset) & bit != 0 {
                self.block_sum[s] = T::zero();
                self.block_count[s] = 0;
            }
            if verdicts.rejected & (1 << s) != 0 {
                self.totals[s] += 1;
                let i = self.rejected_next[s];
                self.rejected_at[s][i] = now;
                self.rejected_next[s] = (i + 1) % MAX_REJECTIONS;
            }
        }
        self.health = self.judge();
        self.health
    }

    /// Adds a passed sample's NIS to source `s`'s block, and at the block's end tests its sum
    /// against the band (docs/estimators.md, "The innovation gate and health").
    fn band(&mut self, s: usize, nis: T) {
        self.nis_total[s] += nis;
        self.nis_samples[s] += 1;
        let band = if s == POSITION {
            self.cfg.position_band
        } else {
            self.cfg.direction_band
        };
        if band.samples == 0 {
            return;
        }
        self.block_sum[s] += nis;
        self.block_count[s] += 1;
        if self.block_count[s] >= band.samples {
            // a NaN sum fails too
            let inside = self.block_sum[s] <= band.upper;
            self.inconsistent[s] = !inside;
            self.inconsistent_blocks[s] += u64::from(!inside);
            self.block_sum[s] = T::zero();
            self.block_count[s] = 0;
        }
    }

    /// The health at the present tick: lost before degraded, and within each the first
    /// source in order (directions, accelerometer, gyro, position). Nothing is judged in the
    /// first window, while a filter started from TRIAD converges.
    fn judge(&self) -> Health {
        let (now, w) = (self.tick, u64::from(self.cfg.window));
        if now < w {
            return Health::Healthy;
        }
        let within = |at: u64| at != u64::MAX && now.saturating_sub(at) < w;
        let missing = |s: usize| !within(self.present_at[s]);
        if missing(GYRO) {
            return Health::Lost(Reason::Missing(Source::Gyro));
        }
        let passing = (0..self.slots)
            .filter(|s| within(self.passed_at[*s]))
            .count();
        if passing < 2 {
            return Health::Lost(Reason::Missing(Source::Attitude));
        }
        // rejections in the first window (the filter converging) do not count
        let rejected = |s: usize| {
            let late = |at: u64| within(at) && at > w;
            let n = self.rejected_at[s].iter().filter(|at| late(**at)).count();
            n as u32 >= self.cfg.rejections
        };
        let reset = |s: usize| within(self.reset_at[s]);
        let inconsistent = |s: usize| self.inconsistent[s];
        let mut sources = (0..self.slots).chain(self.se3.then_some(POSITION));
        match sources.find(|s| missing(*s) || rejected(*s) || inconsistent(*s) || reset(*s)) {
            None => Health::Healthy,
            Some(s) if missing(s) => Health::Degraded(Reason::Missing(self.source(s))),
            Some(s) if rejected(s) => Health::Degraded(Reason::Rejected(self.source(s))),
            Some(s) if inconsistent(s) => Health::Degraded(Reason::Inconsistent(self.source(s))),
            Some(s) => Health::Degraded(Reason::Reset(self.source(s))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two directions on SO(3), a window of 10 ticks, degraded at 2 rejections.
    fn gate(se3: bool) -> Gate<f64> {
        let cfg = GateConfig {
            direction: 20.0,
            position: 25.0,
            noise: [0.01; SLOTS],
            window: 10,
            rejections: 2,
            direction_band: Band::off(),
            position_band: Band::off(),
        };
        Gate::new(cfg, 2, se3)
    }

    /// Verdicts with `present` sources and `rejected` among them.
    fn v(present: &[usize], rejected: &[usize]) -> Verdicts<f64> {
        let bits = |s: &[usize]| s.iter().fold(0u8, |b, i| b | (1 << i));
        Verdicts {
            present: bits(present) | bits(rejected),
            rejected: bits(rejected),
            ..Verdicts::default()
        }
    }

    #[test]
    fn the_monitor_judges_over_its_window() {
        let mut g = gate(false);
        // the first window is not judged, even with nothing at all
        for _ in 0..9 {
            assert_eq!(g.observe(v(&[], &[]), false), Health::Healthy);
        }
        assert_eq!(
            g.observe(v(&[], &[]), false),
            Health::Lost(Reason::Missing(Source::Gyro))
        );
        let mut g = gate(false);
        for _ in 0..20 {
            assert_eq!(g.observe(v(&[0, 1], &[]), true), Health::Healthy);
        }
        // one rejection is the gate doing its work; two within a window degrade
        assert_eq!(g.observe(v(&[0], &[1]), true), Health::Healthy);
        for _ in 0..5 {
            g.observe(v(&[0, 1], &[]), true);
        }
        let degraded = Health::Degraded(Reason::Rejected(Source::Direction(1)));
        assert_eq!(g.observe(v(&[0], &[1]), true), degraded);
        // ... until the first of them leaves the window (ticks 21 and 27: at tick 31)
        for tick in 28..31 {
            assert_eq!(g.observe(v(&[0, 1], &[]), true), degraded, "{tick}");
        }
        assert_eq!(g.observe(v(&[0, 1], &[]), true), Health::Healthy);
        assert_eq!(
            g.rejections().collect::<Vec<_>>(),
            [(Source::Direction(0), 0), (Source::Direction(1), 2)]
        );
        // a direction that stops: missing a window after its last sample; with one source
        // passing the attitude is lost first
        for _ in 0..9 {
            assert_eq!(g.observe(v(&[0], &[]), true), Health::Healthy);
        }
        assert_eq!(
            g.observe(v(&[0], &[]), true),
            Health::Lost(Reason::Missing(Source::Attitude))
        );
        // the gyro's loss comes before everything
        for _ in 0..10 {
            g.observe(v(&[], &[]), false);
        }
        assert_eq!(g.health(), Health::Lost(Reason::Missing(Source::Gyro)));
        assert_eq!((g.health().code(), Health::Healthy.code()), (2, 0));
    }

    #[test]
    fn on_se3_the_accelerometer_and_the_fixes_are_watched_and_a_stale_fix_is_taken() {
        let mut g = gate(true);
        let mut fix = Verdicts::default();
        // a fix far outside its covariance is rejected ...
        assert!(!g.position(&Vector3::new(1.0, 0.0, 0.0), 1e-4, &mut fix));
        assert!(g.position(&Vector3::new(0.01, 0.0, 0.0), 1e-4, &mut fix));
        let all = [0, 1, 2];
        for _ in 0..20 {
            g.observe(v(&[0, 1, 2, POSITION], &[]), true);
        }
        // the accelerometer (slot 2) rejected twice
        g.observe(v(&[0, 1], &[2]), true);
        assert_eq!(
            g.observe(v(&[0, 1, POSITION], &[2]), true),
            Health::Degraded(Reason::Rejected(Source::Accelerometer))
        );
        // fixes stop: missing a window after the last
        for _ in 0..10 {
            g.observe(v(&all, &[]), true);
        }
        assert_eq!(
            g.health(),
            Health::Degraded(Reason::Missing(Source::Position))
        );
        // ... and the first fix after a window without one is taken whatever its NIS, a
        // reset reported for a window
        let mut fix = Verdicts::default();
        assert!(g.position(&Vector3::new(100.0, 0.0, 0.0), 1e-4, &mut fix));
        assert_eq!((fix.rejected, fix.reset), (0, 1 << POSITION));
        let reset = Health::Degraded(Reason::Reset(Source::Position));
        assert_eq!(g.observe(fix, true), reset);
        for _ in 0..9 {
            assert_eq!(g.observe(v(&[0, 1, 2, POSITION], &[]), true), reset);
        }
        assert_eq!(
            g.observe(v(&[0, 1, 2, POSITION], &[]), true),
            Health::Healthy
        );
        // an accelerometer kept out by its magnitude gate is present, not passed: with one
        // direction left the attitude is lost a window later
        let gated = Verdicts {
            unused: 1 << 2,
            ..v(&[0, 2, POSITION], &[])
        };
        for _ in 0..9 {
            assert_eq!(g.observe(gated, true), Health::Healthy);
        }
        assert_eq!(
            g.observe(gated, true),
            Health::Lost(Reason::Missing(Source::Attitude))
        );
        let names: Vec<Source> = g.rejections().map(|(s, _)| s).collect();
        assert_eq!(
            names,
            [
                Source::Direction(0),
                Source::Direction(1),
                Source::Accelerometer,
                Source::Position
            ]
        );
    }

    /// [`gate`]'s settings with a band on the directions: blocks of 5, bound 25.
    fn banded() -> GateConfig<f64> {
        GateConfig {
            direction_band: Band {
                samples: 5,
                upper: 25.0,
            },
            ..*gate(false).config()
        }
    }

    #[test]
    fn the_band_finds_samples_that_pass_one_by_one_but_not_together() {
        let mut g = Gate::new(banded(), 2, false);
        // each direction passes with a NIS of `a` (source 0) and `b` (source 1)
        let tick = |g: &mut Gate<f64>, a: f64, b: f64| {
            let mut v = v(&[0, 1], &[]);
            v.nis[0] = a;
            v.nis[1] = b;
            g.observe(v, true)
        };
        // the first window is not summed, however large
        for _ in 0..10 {
            assert_eq!(tick(&mut g, 1e3, 1e3), Health::Healthy);
        }
        // blocks of 5 at 2 (sum 10) and at 4.9 (24.5) pass
        for _ in 0..10 {
            assert_eq!(tick(&mut g, 2.0, 4.9), Health::Healthy);
        }
        // source 1 at 5.1: each sample far below the gate's 20, the block's 25.5 above 25;
        // the verdict comes at the block's end ...
        for _ in 0..4 {
            assert_eq!(tick(&mut g, 2.0, 5.1), Health::Healthy);
        }
        let inconsistent = Health::Degraded(Reason::Inconsistent(Source::Direction(1)));
        assert_eq!(tick(&mut g, 2.0, 5.1), inconsistent);
        // ... and holds until a block passes
        for _ in 0..4 {
            assert_eq!(tick(&mut g, 2.0, 1.0), inconsistent);
        }
        assert_eq!(tick(&mut g, 2.0, 1.0), Health::Healthy);
        // a NaN NIS fails its block
        for _ in 0..4 {
            tick(&mut g, 2.0, 1.0);
        }
        assert_eq!(
            tick(&mut g, f64::NAN, 1.0),
            Health::Degraded(Reason::Inconsistent(Source::Direction(0)))
        );
        let c: Vec<_> = g.consistency().map(|(s, n, _)| (s, n)).collect();
        assert_eq!(c, [(Source::Direction(0), 1), (Source::Direction(1), 1)]);
        // the mean over the passed samples after the first window: (10·4.9 + 5·5.1 + 10·1)/25
        let mean = g.consistency().nth(1).unwrap().2.unwrap();
        assert!((mean - (49.0 + 25.5 + 10.0) / 25.0).abs() < 1e-12, "{mean}");
    }

    #[test]
    fn a_rejection_starts_the_band_s_block_again() {
        let cfg = banded();
        let run = |reject: bool| {
            let mut g = Gate::new(cfg, 2, false);
            let tick = |g: &mut Gate<f64>, b: f64| {
                let mut x = v(&[0, 1], &[]);
                x.nis = [1.0, b, 0.0, 0.0, 0.0, 0.0, 0.0];
                g.observe(x, true)
            };
            for _ in 0..10 {
                tick(&mut g, 1.0);
            }
            // four samples at 6.2 (24.8), then (or not) a rejection of source 1
            for _ in 0..4 {
                tick(&mut g, 6.2);
            }
            if reject {
                let mut x = v(&[0], &[1]);
                x.nis[0] = 1.0;
                g.observe(x, true);
            }
            // five at 1: with the rejection a block of their own (5); without, the first
            // closes the block at 25.8, above the band
            for _ in 0..5 {
                tick(&mut g, 1.0);
            }
            g.consistency().nth(1).unwrap().1
        };
        assert_eq!(run(true), 0);
        assert_eq!(run(false), 1);
    }
}
