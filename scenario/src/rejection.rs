//! Disturbances and their rejection: `[controller] disturbance_observer` and `integral`,
//! `[plant] disturbance_world` and `disturbance_steps` (docs/maths.md, "Disturbance
//! rejection").
//!
//! ```toml
//! [plant]
//! disturbance_world = [0.0, 0.0, 0.0]                # optional, m entries, world axes at the
//!                                                    # body's origin (se3: torque then force)
//! disturbance_steps = [{ t = 5.0, value = [...] }]   # optional: from the first tick at or
//!                                                    # after t, `value` adds to `disturbance`
//! [controller]
//! disturbance_observer = { gain = 20.0, limit = 0.5, frame = "body" }   # frame: "body" | "world"
//! integral = { ki = 1.0, c = 5.0, limit = 0.15, anti_windup = true }
//! ```
//!
//! `gain`, `ki`, `c` and `limit`: a number (every axis) or one per axis, each finite and > 0.

use crate::{NumberOrList, Scenario, ScenarioError, Validator};
use controller::disturbance::rotate_blocks;
use controller::{Frame, IntegralConfig, ObserverConfig, RejectionConfig};
use nalgebra::{Matrix3, SVector};
use serde::Deserialize;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawObserver {
    gain: NumberOrList,
    limit: Option<NumberOrList>,
    frame: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawIntegral {
    ki: NumberOrList,
    c: NumberOrList,
    limit: Option<NumberOrList>,
    anti_windup: Option<bool>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawStep {
    t: f64,
    value: Vec<f64>,
}

/// `[controller] disturbance_observer`.
#[derive(Debug, Clone, PartialEq)]
pub struct ObserverSpec {
    /// `L` per axis (1/s).
    pub gain: Vec<f64>,
    /// The clamp of the estimate per axis, if any.
    pub limit: Option<Vec<f64>>,
    /// The frame of the estimate.
    pub frame: Frame,
}

/// `[controller] integral`.
#[derive(Debug, Clone, PartialEq)]
pub struct IntegralSpec {
    /// `K_I` per axis.
    pub ki: Vec<f64>,
    /// `c` per axis.
    pub c: Vec<f64>,
    /// The clamp of `|K_I z|` per axis (default: half the torque limit).
    pub limit: Option<Vec<f64>>,
    /// Anti-windup (default on).
    pub anti_windup: bool,
}

/// The controller's disturbance-rejection terms (both `None`: the plain law).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RejectionSpec {
    /// The momentum observer.
    pub observer: Option<ObserverSpec>,
    /// The geometric integral.
    pub integral: Option<IntegralSpec>,
}

/// One step of the body disturbance.
#[derive(Debug, Clone, PartialEq)]
pub struct StepSpec {
    /// When it starts (s): at the first control tick `t_k ≥ t`.
    pub t: f64,
    /// What adds to the constant body disturbance from then on (m entries).
    pub value: Vec<f64>,
}

impl Validator<'_> {
    /// A number (every axis) or `m` numbers, each finite and > 0.
    fn per_axis(&self, key: &str, raw: &NumberOrList, m: usize) -> Result<Vec<f64>, ScenarioError> {
        let v = match raw {
            NumberOrList::Number(x) => vec![*x; m],
            NumberOrList::List(xs) => self.vector(key, xs, m, "a number, or one per axis")?,
        };
        match v.iter().find(|x| !(x.is_finite() && **x > 0.0)) {
            Some(x) => Err(self.err(key, format!("must be a finite number > 0, got {x}"))),
            None => Ok(v),
        }
    }

    /// `[controller] disturbance_observer` and `integral`.
    pub(crate) fn rejection(
        &self,
        observer: Option<&RawObserver>,
        integral: Option<&RawIntegral>,
        m: usize,
    ) -> Result<RejectionSpec, ScenarioError> {
        let observer = match observer {
            None => None,
            Some(o) => {
                let key = "controller.disturbance_observer";
                let frame = match o.frame.as_deref() {
                    None => Frame::Body,
                    Some(f) => Frame::from_name(f).ok_or_else(|| {
                        self.err(
                            &format!("{key}.frame"),
                            format!("unknown frame `{f}` (expected \"body\" or \"world\")"),
                        )
                    })?,
                };
                Some(ObserverSpec {
                    gain: self.per_axis(&format!("{key}.gain"), &o.gain, m)?,
                    limit: o
                        .limit
                        .as_ref()
                        .map(|l| self.per_axis(&format!("{key}.limit"), l, m))
                        .transpose()?,
                    frame,
                })
            }
        };
        let integral = match integral {
            None => None,
            Some(i) => Some(IntegralSpec {
                ki: self.per_axis("controller.integral.ki", &i.ki, m)?,
                c: self.per_axis("controller.integral.c", &i.c, m)?,
                limit: i
                    .limit
                    .as_ref()
                    .map(|l| self.per_axis("controller.integral.limit", l, m))
                    .transpose()?,
                anti_windup: i.anti_windup.unwrap_or(true),
            }),
        };
        Ok(RejectionSpec { observer, integral })
    }

    /// `[plant] disturbance_steps`: times finite, ≥ 0 and increasing; values of m finite
    /// entries.
    pub(crate) fn steps(
        &self,
        raw: Option<&[RawStep]>,
        m: usize,
    ) -> Result<Vec<StepSpec>, ScenarioError> {
        let mut out: Vec<StepSpec> = Vec::new();
        for (i, s) in raw.unwrap_or_default().iter().enumerate() {
            let key = format!("plant.disturbance_steps[{i}]");
            if !(s.t.is_finite() && s.t >= 0.0) {
                return Err(self.err(
                    &format!("{key}.t"),
                    format!("must be a finite time ≥ 0, got {}", s.t),
                ));
            }
            if let Some(prev) = out.last().filter(|p| p.t >= s.t) {
                return Err(self.err(
                    &format!("{key}.t"),
                    format!("times must increase: {} follows {}", s.t, prev.t),
                ));
            }
            let value = self.vector(&format!("{key}.value"), &s.value, m, "one entry per axis")?;
            out.push(StepSpec { t: s.t, value });
        }
        Ok(out)
    }
}

impl Scenario {
    /// The controller's disturbance-rejection settings.
    pub fn rejection_config<const M: usize>(&self) -> RejectionConfig<f64, M> {
        let v = |x: &Vec<f64>| SVector::<f64, M>::from_row_slice(x);
        RejectionConfig {
            observer: self.rejection.observer.as_ref().map(|o| ObserverConfig {
                gain: v(&o.gain),
                limit: o.limit.as_ref().map(v),
                frame: o.frame,
            }),
            integral: self.rejection.integral.as_ref().map(|i| IntegralConfig {
                ki: v(&i.ki),
                c: v(&i.c),
                limit: i.limit.as_ref().map(v),
                anti_windup: i.anti_windup,
            }),
        }
    }

    /// The body-frame disturbance over the period that starts at tick `k`: the constant one
    /// plus the value of the last step that has started (at the first tick `t_k ≥ t`).
    pub fn disturbance_at<const M: usize>(&self, k: u64) -> SVector<f64, M> {
        let mut d = self.disturbance_vector::<M>();
        let t = k as f64 * self.control_period;
        // a step at t starts on the first tick whose time reaches it (to rounding)
        let tol = 1e-9 * self.control_period;
        if let Some(s) = self.disturbance_steps.iter().rev().find(|s| s.t <= t + tol) {
            d += SVector::<f64, M>::from_row_slice(&s.value);
        }
        d
    }

    /// What the body receives besides the torque over the period that starts at tick `k`
    /// at rotation `r`: [`Scenario::disturbance_at`] plus the world wrench rotated into the
    /// body (what the accelerometer model is told was applied).
    pub fn disturbance_wrench<const M: usize>(&self, k: u64, r: &Matrix3<f64>) -> SVector<f64, M> {
        let mut d = self.disturbance_at::<M>(k);
        if let Some(w) = self.world_disturbance::<M>() {
            d += rotate_blocks(&r.transpose(), &w);
        }
        d
    }

    /// The wrench constant in world axes, if any.
    pub fn world_disturbance<const M: usize>(&self) -> Option<SVector<f64, M>> {
        self.disturbance_world
            .as_ref()
            .map(|w| SVector::from_row_slice(w))
    }
}
