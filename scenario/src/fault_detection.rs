//! `[fault_detection]`: the detector of actuator failures nobody announces (docs/scenario.md,
//! docs/maths.md "Failure detection"). An empty table turns it on with the design's defaults;
//! it needs a `[vehicle]`. Every key is checked, naming it.

use crate::validate::Validator;
use crate::{Scenario, ScenarioError};
use detection::threshold::{chi2_upper, per_test};
use eqtrack_allocation::Commands;
use nalgebra::{SMatrix, SVector};
use serde::Deserialize;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawFaultDetection {
    window: Option<f64>,
    false_alarm_rate: Option<f64>,
    warmup: Option<f64>,
    calibration: Option<f64>,
    memory: Option<f64>,
    floor: Option<f64>,
    confirm: Option<f64>,
    unexplained: Option<f64>,
    model_error: Option<f64>,
    ambiguity: Option<f64>,
}

/// `[fault_detection]`, checked: times in seconds, rates and probabilities as given.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaultDetectionSpec {
    /// `window` (s): each of the two windows the residual is averaged over.
    pub window: f64,
    /// `false_alarm_rate`: alarms expected per hour of nominal flight, at most.
    pub false_alarm_rate: f64,
    /// `warmup` (s): the start, in which the detector neither learns nor tests.
    pub warmup: f64,
    /// `calibration` (s): nominal flight the spread is learned over before the first test.
    pub calibration: f64,
    /// `memory` (s): the time over which the spread keeps learning afterwards.
    pub memory: f64,
    /// `floor`: the least spread per axis, as a fraction of the most any one actuator gives
    /// along it.
    pub floor: f64,
    /// `confirm` (s): how long one actuator must lead before it is named (it passes every gate
    /// but in the last period, which names it without a test).
    pub confirm: f64,
    /// `unexplained`: the chance that a failure's unexplained part fails the isolation gate.
    pub unexplained: f64,
    /// `ambiguity`: the chance of naming the runner-up instead of the failed actuator.
    pub ambiguity: f64,
    /// `model_error`: the model's relative error, as a fraction of what the residual sees.
    pub model_error: f64,
}

/// The defaults of an empty `[fault_detection]`.
pub const DEFAULTS: FaultDetectionSpec = FaultDetectionSpec {
    window: 0.1,
    false_alarm_rate: 1e-3,
    warmup: 2.0,
    calibration: 2.0,
    memory: 10.0,
    floor: 0.005,
    confirm: 0.05,
    unexplained: 1e-6,
    ambiguity: 1e-3,
    model_error: 0.1,
};

/// Periods in `seconds` at period `h` (rounded).
fn periods(seconds: f64, h: f64) -> usize {
    (seconds / h).round().max(0.0) as usize
}

/// The control periods averaged into each of the detector's entries, so that a window fits
/// in half its ring: `⌈periods / (CAPACITY / 2)⌉`.
fn decimation(window_periods: usize) -> usize {
    window_periods.div_ceil(detection::CAPACITY / 2).max(1)
}

impl Validator<'_> {
    /// `[fault_detection]` against the control period and the vehicle.
    pub(crate) fn fault_detection(
        &self,
        raw: Option<&RawFaultDetection>,
        actuators: Option<usize>,
        h: f64,
    ) -> Result<Option<FaultDetectionSpec>, ScenarioError> {
        let Some(raw) = raw else {
            return Ok(None);
        };
        let Some(count) = actuators else {
            return Err(self.err(
                "fault_detection",
                "needs a [vehicle] with its actuators (it watches their commands)",
            ));
        };
        let d = DEFAULTS;
        let probability = |key: &str, x: Option<f64>, default: f64| match x {
            None => Ok(default),
            Some(x) if x > 0.0 && x < 0.5 => Ok(x),
            Some(x) => Err(self.err(key, format!("must be a probability in (0, 0.5), got {x}"))),
        };
        let window = self.positive_or("fault_detection.window", raw.window, d.window)?;
        let n = periods(window, h);
        if n == 0 || window > 60.0 {
            return Err(self.err(
                "fault_detection.window",
                format!(
                    "{window} s is {n} control periods of {h} s; it must be at least one period and at most 60 s"
                ),
            ));
        }
        let rate = self.positive_or(
            "fault_detection.false_alarm_rate",
            raw.false_alarm_rate,
            d.false_alarm_rate,
        )?;
        // one test per entry of `decimation` periods, over every actuator
        let d_periods = decimation(n) as f64;
        if per_test(rate, h * d_periods, count) >= 0.5 {
            return Err(self.err(
                "fault_detection.false_alarm_rate",
                format!(
                    "{rate} an hour is a chance of half or more that each test alarms (one test every {} s over {count} actuators)",
                    h * d_periods
                ),
            ));
        }
        let (warmup, calibration, memory, confirm) = self.fault_periods(raw, window, h)?;
        let floor = self.positive_or("fault_detection.floor", raw.floor, d.floor)?;
        if floor >= 1.0 {
            return Err(self.err(
                "fault_detection.floor",
                format!("must be below 1, got {floor}"),
            ));
        }
        Ok(Some(FaultDetectionSpec {
            window,
            false_alarm_rate: rate,
            warmup,
            calibration,
            memory,
            floor,
            confirm,
            unexplained: probability(
                "fault_detection.unexplained",
                raw.unexplained,
                d.unexplained,
            )?,
            ambiguity: probability("fault_detection.ambiguity", raw.ambiguity, d.ambiguity)?,
            model_error: match raw.model_error {
                None => d.model_error,
                Some(x) if (0.0..1.0).contains(&x) => x,
                Some(x) => {
                    return Err(self.err(
                        "fault_detection.model_error",
                        format!("must be in [0, 1), got {x}"),
                    ));
                }
            },
        }))
    }

    /// `x` if finite and positive, `default` if absent; else refused naming `key`.
    fn positive_or(&self, key: &str, x: Option<f64>, default: f64) -> Result<f64, ScenarioError> {
        match x {
            None => Ok(default),
            Some(x) if x.is_finite() && x > 0.0 => Ok(x),
            Some(x) => Err(self.err(key, format!("must be finite and positive, got {x}"))),
        }
    }

    /// `warmup`, `calibration`, `memory` and `confirm` (s), each against the window and the
    /// period.
    fn fault_periods(
        &self,
        raw: &RawFaultDetection,
        window: f64,
        h: f64,
    ) -> Result<(f64, f64, f64, f64), ScenarioError> {
        let d = DEFAULTS;
        let n = periods(window, h);
        let calibration = self.positive_or(
            "fault_detection.calibration",
            raw.calibration,
            d.calibration,
        )?;
        if periods(calibration, h) < 2 * n {
            return Err(self.err(
                "fault_detection.calibration",
                format!(
                    "{calibration} s is shorter than two windows ({} s)",
                    2.0 * window
                ),
            ));
        }
        let memory = self.positive_or("fault_detection.memory", raw.memory, d.memory)?;
        if memory < h {
            return Err(self.err(
                "fault_detection.memory",
                format!("{memory} s is shorter than a control period ({h} s)"),
            ));
        }
        // by default half the window, and at least a period
        let confirm = self.positive_or(
            "fault_detection.confirm",
            raw.confirm,
            (window / 2.0).max(h),
        )?;
        let c = periods(confirm, h);
        if c == 0 || c > n {
            return Err(self.err(
                "fault_detection.confirm",
                format!("{confirm} s is {c} control periods; it must be 1 to the window's {n}"),
            ));
        }
        let warmup = match raw.warmup {
            None => d.warmup,
            Some(x) if x.is_finite() && x >= 0.0 => x,
            Some(x) => {
                return Err(self.err(
                    "fault_detection.warmup",
                    format!("must be finite and ≥ 0, got {x}"),
                ));
            }
        };
        Ok((warmup, calibration, memory, confirm))
    }
}

impl Scenario {
    /// The detector's settings on a group of wrench dimension `K`
    /// (docs/maths.md, "Failure detection"): the periods of each time, the thresholds from the probabilities, the
    /// floors from the actuators, the controller's model (inertia, drag, lag). `None` without
    /// `[fault_detection]` (or a vehicle).
    pub fn detector_config<const K: usize>(&self) -> Option<detection::Config<f64, K>> {
        let f = self.fault_detection.as_ref()?;
        let v = self.vehicle.as_ref()?;
        let h = self.control_period;
        let geometry = v.geometry::<K>().ok()?;
        let b = geometry.effectiveness();
        let (lo, hi) = geometry.bounds();
        let count = geometry.count();
        let reach = |j: usize| lo[j].abs().max(hi[j].abs());
        // the residual is kept in world axes: each axis of a block (torque, force) gets the
        // block's largest, which does not depend on the attitude
        let most = |i: usize| {
            (0..count)
                .map(|j| b[(i, j)].abs() * reach(j))
                .fold(0.0, f64::max)
        };
        let floor = SVector::<f64, K>::from_fn(|i, _| {
            let block = 3 * (i / 3);
            let m = (block..block + 3).map(most).fold(0.0, f64::max);
            // a block no actuator reaches (never on a spanning geometry) keeps a unit floor
            if m > 0.0 { f.floor * m } else { 1.0 }
        });
        let resolution = Commands::from_fn(|j, _| if j < count { f.floor * reach(j) } else { 1.0 });
        let diagonal =
            |d: &[f64]| SVector::<f64, K>::from_fn(|i, _| d.get(i).copied().unwrap_or(0.0));
        let d = decimation(periods(f.window, h));
        let entries = |seconds: f64| (periods(seconds, h) as f64 / d as f64).round() as usize;
        let window = entries(f.window).max(1);
        Some(detection::Config {
            decimation: d,
            window,
            // one test per entry
            threshold: chi2_upper(1, per_test(f.false_alarm_rate, h * d as f64, count)),
            isolation: chi2_upper(K - 1, f.unexplained),
            margin: chi2_upper(1, f.ambiguity),
            relative: f.model_error * f.model_error,
            confirm: entries(f.confirm).clamp(1, window),
            warmup: entries(f.warmup),
            calibration: entries(f.calibration).max(2 * window),
            memory: (h * d as f64 / f.memory).min(1.0),
            floor,
            resolution,
            inertia: SMatrix::<f64, K, K>::from_row_slice(&self.model_inertia),
            damping_linear: diagonal(&v.damping_linear),
            damping_quadratic: diagonal(&v.damping_quadratic),
            period: h,
            time_constant: v.actuator_time_constant,
        })
    }
}
