//! `[estimator] gate = true`: the innovation gate and the health monitor (docs/estimators.md,
//! "The innovation gate and health"), its keys checked, and its thresholds from the stated
//! false-alarm rate.

use super::{EstimatorKind, RawEstimator, SensorsSpec};
use crate::{Scenario, ScenarioError, Validator};
use detection::threshold::chi2_upper;
use eqtrack_estimator::health::{Band, GateConfig, MAX_REJECTIONS};

/// The gate's settings as the scenario gives them.
#[derive(Debug, Clone, PartialEq)]
pub struct GateSpec {
    /// Expected false rejections per hour of flight, per sensor (`false_alarm_rate`).
    pub false_alarm_rate: f64,
    /// The health monitor's window (s, `health_window`).
    pub window: f64,
    /// The noise each direction source is tested against (unitless; the accelerometer's
    /// "up" last on SE(3)): `direction_noise`, by default the sensors'. The EqF's own noise
    /// model is this list; the complementary filter has none, and the gate uses it.
    pub noise: Vec<f64>,
}

/// The default false-alarm rate: one false rejection per sensor in a hundred hours.
pub const DEFAULT_FALSE_ALARM_RATE: f64 = 0.01;
/// The default health window (s).
pub const DEFAULT_WINDOW: f64 = 0.5;
/// The most samples a window may span (of the control period, or of the position fixes).
pub const MAX_WINDOW_SAMPLES: f64 = 100_000.0;

impl Validator<'_> {
    /// `estimator.gate`, `false_alarm_rate` and `health_window` (and for the complementary
    /// filter `direction_noise`, the noise the gate tests against): a rate > 0, and a window
    /// of at least one control period and, with position fixes, two fixes.
    pub(crate) fn gate(
        &self,
        raw: &RawEstimator,
        kind: EstimatorKind,
        sensors: &SensorsSpec,
        sources: usize,
        period: f64,
    ) -> Result<Option<GateSpec>, ScenarioError> {
        let (rate, window) = (raw.false_alarm_rate, raw.health_window);
        if !raw.gate.unwrap_or(false) {
            for (key, given) in [
                ("false_alarm_rate", rate.is_some()),
                ("health_window", window.is_some()),
            ] {
                if given {
                    return Err(self.err(
                        &format!("estimator.{key}"),
                        "a setting of the innovation gate: give `gate = true` to turn it on",
                    ));
                }
            }
            return Ok(None);
        }
        let who = match kind {
            EstimatorKind::Complementary => "the gate",
            _ => "the EqF",
        };
        let noise = self.direction_noise(raw, sensors, sources, who)?;
        let false_alarm_rate = rate.unwrap_or(DEFAULT_FALSE_ALARM_RATE);
        if !(false_alarm_rate.is_finite() && false_alarm_rate > 0.0) {
            return Err(self.err(
                "estimator.false_alarm_rate",
                format!(
                    "must be finite and > 0 (false rejections per hour), got {false_alarm_rate}"
                ),
            ));
        }
        // a rate that rejects half the samples or more is no test
        let fastest = sensors
            .position
            .map_or(1.0 / period, |p| p.rate_hz.min(1.0 / period));
        let most = 1800.0 * fastest;
        if false_alarm_rate >= most {
            return Err(self.err(
                "estimator.false_alarm_rate",
                format!(
                    "must be below {most} an hour (half the samples of the sensor that gives \
                     fewest), got {false_alarm_rate}"
                ),
            ));
        }
        // by default a window spans at least two fixes
        let window = window.unwrap_or_else(|| {
            sensors
                .position
                .map_or(DEFAULT_WINDOW, |p| DEFAULT_WINDOW.max(2.0 / p.rate_hz))
        });
        self.window(window, period, sensors)?;
        Ok(Some(GateSpec {
            false_alarm_rate,
            window,
            noise,
        }))
    }

    /// `estimator.health_window`: finite, at least one control period and two position
    /// fixes, at most [`MAX_WINDOW_SAMPLES`] samples of the fastest sensor.
    fn window(&self, window: f64, period: f64, sensors: &SensorsSpec) -> Result<(), ScenarioError> {
        if !(window.is_finite() && window >= period) {
            return Err(self.err(
                "estimator.health_window",
                format!(
                    "must be finite and at least one control period ({period} s), got {window}"
                ),
            ));
        }
        // the band sums a window's samples, and its bound is a χ² quantile of twice (three
        // times) as many degrees of freedom: a bounded window keeps it computable
        let samples = (window / period).max(sensors.position.map_or(0.0, |p| window * p.rate_hz));
        if samples > MAX_WINDOW_SAMPLES {
            return Err(self.err(
                "estimator.health_window",
                format!(
                    "must span at most {MAX_WINDOW_SAMPLES} samples of the fastest sensor (control \
                 periods of {period} s, or position fixes), got {window} s: {samples} samples"
                ),
            ));
        }
        if let Some(p) = sensors.position
            && window < 2.0 / p.rate_hz
        {
            return Err(self.err(
                "estimator.health_window",
                format!(
                    "must span at least two position fixes ({} s at {} Hz), got {window}",
                    2.0 / p.rate_hz,
                    p.rate_hz
                ),
            ));
        }
        Ok(())
    }
}

/// `P(X ≥ r)` for `X ~ Binomial(n, p)`, `0 < p < 1`, in bounded time whatever `n`: the terms
/// `P(X = k)` from `P(X = 0) = (1 − p)ⁿ` by `P(X = k + 1) = P(X = k) (n − k) p / ((k + 1)(1 − p))`.
/// When the first `r` hold at least half the mass the tail is summed from `r` on until its
/// terms no longer count (so a tail far below 1 keeps its digits); else it is one minus them.
pub fn binomial_tail(n: u64, p: f64, r: u64) -> f64 {
    if r == 0 {
        return 1.0;
    }
    if r > n {
        return 0.0;
    }
    let step = |term: f64, k: u64| term * (n - k) as f64 / (k + 1) as f64 * p / (1.0 - p);
    let mut term = (1.0 - p).powf(n as f64);
    let mut head = 0.0;
    for k in 0..r {
        head += term;
        term = step(term, k);
    }
    if head < 0.5 {
        return (1.0 - head).clamp(0.0, 1.0);
    }
    let mut tail = 0.0;
    let mut k = r;
    while k <= n && k < r + 100_000 {
        tail += term;
        if term <= tail * 1e-17 {
            break;
        }
        term = step(term, k);
        k += 1;
    }
    tail.min(1.0)
}

impl Scenario {
    /// The gate's thresholds (docs/estimators.md, "The innovation gate and health"), or
    /// `None` without `gate = true`. With `λ` false rejections per hour per sensor, a sample
    /// is rejected with probability `α = λ h / 3600` (a fix: `λ / (3600 f)`), so the
    /// direction threshold is the χ²₂ upper `α` quantile and the fix's the χ²₃; a source
    /// is degraded after the fewest rejections `r` within a sliding window of `n` ticks such
    /// that a nominal sensor reaches them no more than `λ` times an hour: a window reaches
    /// `r` at a tick whose sample is rejected with `r − 1` more among the `n − 1` before, so
    /// `(3600/h) · α · P(Binomial(n − 1, α) ≥ r − 1) ≤ λ`. The χ² band sums a source's
    /// passed NIS over blocks of a window's samples (`n` directions, `⌈window · f⌉` fixes);
    /// one test per block, so a block fails falsely with probability `λ` times the block's
    /// duration in hours, and its bound is that upper quantile of χ² with the block's
    /// degrees of freedom (2 or 3 per sample). The complementary filter's directions have no
    /// band: with no covariance, their NIS carries the estimate's error, correlated from one
    /// sample to the next.
    pub fn gate_config(&self) -> Option<GateConfig<f64>> {
        let spec = self.estimator.gate.as_ref()?;
        let sensors = self.sensors.as_ref()?;
        let h = self.control_period;
        let rate = spec.false_alarm_rate;
        let alpha = rate * h / 3600.0;
        let fix_rate = sensors.position.map_or(1.0 / h, |p| p.rate_hz);
        let ticks = ((spec.window / h).round() as u64).clamp(1, u64::from(u32::MAX));
        let ticks_per_hour = 3600.0 / h;
        // r = 1 is the gate's own rate, λ, up to rounding
        let rate_of = |r: u64| ticks_per_hour * alpha * binomial_tail(ticks - 1, alpha, r - 1);
        let rejections = (1..=MAX_REJECTIONS as u64)
            .find(|r| rate_of(*r) <= rate * (1.0 + 1e-9))
            .unwrap_or(MAX_REJECTIONS as u64);
        let mut noise = [0.0; eqtrack_estimator::MAX_DIRECTIONS + 1];
        for (n, x) in noise.iter_mut().zip(&spec.noise) {
            *n = *x;
        }
        let band = |samples: u64, dof: usize, per_second: f64| Band {
            samples: samples as u32,
            upper: chi2_upper(
                dof * samples as usize,
                rate * samples as f64 / (3600.0 * per_second),
            ),
        };
        let fixes = ((spec.window * fix_rate).round() as u64).clamp(2, u64::from(u32::MAX));
        Some(GateConfig {
            direction: chi2_upper(2, alpha),
            position: chi2_upper(3, rate / (3600.0 * fix_rate)),
            noise,
            window: ticks as u32,
            rejections: rejections as u32,
            // the complementary filter has no covariance to test: its samples' NIS, against
            // the noise alone, carries its estimate's error, the same from sample to sample
            direction_band: if self.estimator.kind == EstimatorKind::Complementary {
                Band::off()
            } else {
                band(ticks, 2, 1.0 / h)
            },
            position_band: band(fixes, 3, fix_rate),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::binomial_tail;

    #[test]
    fn the_binomial_tail_is_the_sum_of_its_terms() {
        // n = 3, p = ½: P(X ≥ 2) = 4/8
        assert!((binomial_tail(3, 0.5, 2) - 0.5).abs() < 1e-15);
        assert!((binomial_tail(3, 0.5, 0) - 1.0).abs() < 1e-15);
        assert!((binomial_tail(10, 0.1, 1) - (1.0 - 0.9f64.powi(10))).abs() < 1e-15);
        // far in the tail it is the first term, C(n, r) pʳ
        let t = binomial_tail(250, 1e-8, 2);
        assert!(
            (t / (250.0 * 249.0 / 2.0 * 1e-16) - 1.0).abs() < 1e-5,
            "{t}"
        );
        assert!(binomial_tail(250, 1e-8, 5) > 0.0);
        // huge counts in bounded time: far past its mean the tail is 1, far below it 0
        assert_eq!(binomial_tail(u64::MAX, 0.5, 8), 1.0);
        assert!(binomial_tail(u64::MAX, 1e-30, 8) < 1e-50);
        assert_eq!(binomial_tail(5, 0.5, 6), 0.0);
    }
}
