//! Disturbances and their rejection: `[controller] disturbance_observer` and `integral`,
//! `[plant] disturbance_world` and `disturbance_steps`
//! (docs/maths.md, "Disturbance rejection").
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
use eqtrack_controller::{Frame, IntegralConfig, ObserverConfig, RejectionConfig};
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
    pub fn disturbance_wrench<G, const N: usize, const M: usize>(
        &self,
        k: u64,
        r: &Matrix3<f64>,
    ) -> SVector<f64, M>
    where
        G: eqtrack_controller::MatrixLieGroup<N, M>,
    {
        let mut d = self.disturbance_at::<M>(k);
        if let Some(w) = self.world_disturbance::<M>() {
            d += G::rotate_coordinates(&r.transpose(), &w);
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn load(name: &str) -> Scenario {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../scenarios")
            .join(name);
        Scenario::from_file(&path).unwrap()
    }

    /// The seed scenario with `plant` and `controller` lines added.
    fn seed_with(plant: &str, controller: &str) -> Result<Scenario, ScenarioError> {
        let text = crate::BUILTINS[0]
            .1
            .replace("[plant]\n", &format!("[plant]\n{plant}\n"))
            .replace("[controller]\n", &format!("[controller]\n{controller}\n"));
        Scenario::from_toml(&text, "test", "seed")
    }

    #[test]
    fn the_rejection_scenarios_load_with_their_terms() {
        let s = load("reject_so3.toml");
        let o = s.rejection.observer.as_ref().unwrap();
        assert_eq!(
            (o.gain.clone(), o.limit.clone(), o.frame),
            (vec![20.0; 3], None, Frame::Body)
        );
        // the observer alone; the integral as the file's comment gives it
        assert_eq!(s.rejection.integral, None);
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/reject_so3.toml");
        let text = std::fs::read_to_string(path).unwrap().replace(
            "disturbance_observer = { gain = 20.0 }\n",
            "integral = { ki = 1.0, c = 5.0 }\n",
        );
        let with = Scenario::from_toml(&text, "test", "t").unwrap();
        assert_eq!(with.rejection.observer, None);
        let i = with.rejection.integral.unwrap();
        assert_eq!(
            (i.ki, i.c, i.limit, i.anti_windup),
            (vec![1.0; 3], vec![5.0; 3], None, true)
        );
        let c = s.rejection_config::<3>();
        assert!(c.any());
        assert_eq!(c.observer.unwrap().gain, SVector::<f64, 3>::repeat(20.0));

        let s = load("reject_se3.toml");
        let o = s.rejection.observer.as_ref().unwrap();
        assert_eq!(o.frame, Frame::World);
        assert_eq!(
            o.limit.as_deref(),
            Some(&[0.5, 0.5, 0.5, 2.0, 2.0, 2.0][..])
        );
        assert_eq!(
            s.disturbance_world.as_deref(),
            Some(&[0.0, 0.0, 0.0, 0.5, 0.0, 0.0][..])
        );
        assert_eq!(s.disturbance_steps.len(), 1);
        // the step starts at the first tick at or after t = 6 s (tick 3000 at 2 ms)
        let before = s.disturbance_at::<6>(2999);
        let after = s.disturbance_at::<6>(3000);
        assert_eq!(before, SVector::<f64, 6>::from_row_slice(&s.disturbance));
        assert_eq!(
            after - before,
            SVector::<f64, 6>::from_row_slice(&[0.0, 0.0, 0.01, 0.0, 0.2, 0.0])
        );
        // the world wrench enters the body rotated: a quarter turn about z
        let r = eqtrack_controller::group::so3::exp_so3(&nalgebra::Vector3::new(
            0.0,
            0.0,
            core::f64::consts::FRAC_PI_2,
        ));
        let w = s.disturbance_wrench::<eqtrack_controller::Se3, 4, 6>(0, &r) - before;
        assert!(
            (w - SVector::<f64, 6>::from_row_slice(&[0.0, 0.0, 0.0, 0.0, -0.5, 0.0])).amax()
                < 1e-15,
            "{w}"
        );
    }

    #[test]
    fn without_the_keys_nothing_changes_and_with_them_the_fingerprint_does() {
        let seed = Scenario::builtin("seed").unwrap();
        assert_eq!(seed.rejection, RejectionSpec::default());
        assert!(!seed.rejection_config::<3>().any());
        assert_eq!(seed.disturbance_world, None);
        assert!(seed.disturbance_steps.is_empty());
        assert_eq!(
            seed.disturbance_at::<3>(1_000_000),
            seed.disturbance_vector::<3>()
        );
        let base = seed.fingerprint();
        let with = |c: &str| seed_with("", c).unwrap().fingerprint();
        let observer = with("disturbance_observer = { gain = 20.0 }");
        let world = with("disturbance_observer = { gain = 20.0, frame = \"world\" }");
        let limited = with("disturbance_observer = { gain = 20.0, limit = 1.0 }");
        let integral = with("integral = { ki = 1.0, c = 5.0 }");
        let wound = with("integral = { ki = 1.0, c = 5.0, anti_windup = false }");
        let all = [base, observer, world, limited, integral, wound];
        for (i, a) in all.iter().enumerate() {
            for b in &all[i + 1..] {
                assert_ne!(a, b, "{all:x?}");
            }
        }
        // the plant's disturbances are the plant's: not in the fingerprint
        let plant = seed_with(
            "disturbance_world = [0.1, 0.0, 0.0]\ndisturbance_steps = [{ t = 1.0, value = [0.0, 0.1, 0.0] }]",
            "",
        )
        .unwrap();
        assert_eq!(plant.fingerprint(), base);
        // a number or one per axis
        let per_axis = seed_with(
            "",
            "integral = { ki = [1.0, 2.0, 3.0], c = 5.0, limit = [0.1, 0.2, 0.3] }",
        )
        .unwrap();
        let i = per_axis.rejection.integral.unwrap();
        assert_eq!(
            (i.ki, i.limit),
            (vec![1.0, 2.0, 3.0], Some(vec![0.1, 0.2, 0.3]))
        );
    }

    #[test]
    fn bad_values_name_the_key_and_what_is_wrong() {
        let observer = "controller.disturbance_observer";
        for (plant, controller, needle) in [
            (
                "",
                "disturbance_observer = { gain = 0.0 }",
                format!("key `{observer}.gain`: must be a finite number > 0, got 0"),
            ),
            (
                "",
                "disturbance_observer = { gain = -1.0 }",
                format!("key `{observer}.gain`: must be a finite number > 0"),
            ),
            (
                "",
                "disturbance_observer = { gain = nan }",
                format!("key `{observer}.gain`"),
            ),
            (
                "",
                "disturbance_observer = { gain = [1.0, 2.0] }",
                format!("key `{observer}.gain`: expected 3 numbers"),
            ),
            (
                "",
                "disturbance_observer = { gain = [1.0, inf, 2.0] }",
                format!("key `{observer}.gain`: entry 1 is not a finite number"),
            ),
            (
                "",
                "disturbance_observer = { gain = 1.0, limit = 0.0 }",
                format!("key `{observer}.limit`: must be a finite number > 0"),
            ),
            (
                "",
                "disturbance_observer = { gain = 1.0, frame = \"inertial\" }",
                format!(
                    "key `{observer}.frame`: unknown frame `inertial` (expected \"body\" or \"world\")"
                ),
            ),
            (
                "",
                "disturbance_observer = { limit = 1.0 }",
                "missing field `gain`".to_owned(),
            ),
            (
                "",
                "disturbance_observer = { gain = 1.0, gian = 2.0 }",
                "unknown field `gian`".to_owned(),
            ),
            (
                "",
                "integral = { ki = 0.0, c = 5.0 }",
                "key `controller.integral.ki`: must be a finite number > 0".to_owned(),
            ),
            (
                "",
                "integral = { ki = 1.0, c = -5.0 }",
                "key `controller.integral.c`: must be a finite number > 0".to_owned(),
            ),
            (
                "",
                "integral = { ki = 1.0, c = 5.0, limit = [1.0, 1.0, 1.0, 1.0] }",
                "key `controller.integral.limit`: expected 3 numbers".to_owned(),
            ),
            (
                "",
                "integral = { ki = 1.0 }",
                "missing field `c`".to_owned(),
            ),
            (
                "",
                "integral = { ki = 1.0, c = 1.0, anti_windup = \"no\" }",
                "anti_windup".to_owned(),
            ),
            (
                "disturbance_world = [0.1, 0.0]",
                "",
                "key `plant.disturbance_world`: expected 3 numbers (world axes), got 2".to_owned(),
            ),
            (
                "disturbance_world = [0.1, nan, 0.0]",
                "",
                "key `plant.disturbance_world`: entry 1 is not a finite number".to_owned(),
            ),
            (
                "disturbance_steps = [{ t = -1.0, value = [0.0, 0.0, 0.0] }]",
                "",
                "key `plant.disturbance_steps[0].t`: must be a finite time ≥ 0, got -1".to_owned(),
            ),
            (
                "disturbance_steps = [{ t = inf, value = [0.0, 0.0, 0.0] }]",
                "",
                "key `plant.disturbance_steps[0].t`".to_owned(),
            ),
            (
                "disturbance_steps = [{ t = 2.0, value = [0.0, 0.0, 0.0] }, { t = 1.0, value = [0.0, 0.0, 0.0] }]",
                "",
                "key `plant.disturbance_steps[1].t`: times must increase: 1 follows 2".to_owned(),
            ),
            (
                "disturbance_steps = [{ t = 1.0, value = [0.0, 0.0] }]",
                "",
                "key `plant.disturbance_steps[0].value`: expected 3 numbers".to_owned(),
            ),
            (
                "disturbance_steps = [{ t = 1.0, value = [0.0, 0.0, nan] }]",
                "",
                "key `plant.disturbance_steps[0].value`: entry 2".to_owned(),
            ),
            (
                "disturbance_steps = [{ t = 1.0 }]",
                "",
                "missing field `value`".to_owned(),
            ),
        ] {
            match seed_with(plant, controller) {
                Ok(_) => panic!("accepted: {plant} {controller}"),
                Err(e) => assert!(e.to_string().contains(&needle), "{e}\n  wanted: {needle}"),
            }
        }
    }
}
