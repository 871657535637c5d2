//! `[failsafe]`: the failsafe manager's configuration (docs/failsafe.md, docs/scenario.md).
//! Each event names an action; the rates and the tracking limits are checked against the
//! vehicle they have to fit, each key named when it is refused. Off when the table is absent.

use crate::validate::Validator;
use crate::{GroupKind, ScenarioError};
use failsafe::{Action, Cause};
use serde::Deserialize;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawFailsafe {
    /// Read as any value, so that a number or a list is refused naming the actions.
    link: Option<toml::Value>,
    estimator: Option<toml::Value>,
    actuators: Option<toml::Value>,
    tracking: Option<toml::Value>,
    descend_rate: Option<f64>,
    ascend_rate: Option<f64>,
    tracking_limit_attitude: Option<f64>,
    tracking_limit_position: Option<f64>,
    actuators_residual: Option<f64>,
    clear_time: Option<f64>,
}

/// `[failsafe]`, checked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FailsafeSpec {
    /// The action of each event, indexed as [`failsafe::Cause::ALL`] (`None`: ignored).
    pub actions: [Option<Action>; 4],
    /// `descend_rate` (m/s): how fast `descend` comes down.
    pub descend_rate: f64,
    /// `ascend_rate` (m/s): how fast `surface` rises.
    pub ascend_rate: f64,
    /// `tracking_limit_attitude` (rad): the attitude error that raises `tracking`.
    pub tracking_limit_attitude: Option<f64>,
    /// `tracking_limit_position` (m): the position error that raises `tracking` (SE(3)).
    pub tracking_limit_position: Option<f64>,
    /// `actuators_residual` (N·m): an allocation that could not meet its torque and fell
    /// short of it by more than this raises `actuators` (`None`: only the span test does).
    pub actuators_residual: Option<f64>,
    /// `clear_time` (s): how long an event's condition must stay away before it clears.
    pub clear_time: f64,
}

/// `descend_rate`'s default (m/s).
pub const DESCEND_RATE: f64 = 0.5;
/// `ascend_rate`'s default (m/s).
pub const ASCEND_RATE: f64 = 0.3;
/// `clear_time`'s default (s).
pub const CLEAR_TIME: f64 = 1.0;
/// The largest rate accepted (m/s).
const MAX_RATE: f64 = 100.0;

impl FailsafeSpec {
    /// The manager's configuration at control period `h`: the hysteresis in ticks, at least one.
    pub fn config(&self, h: f64) -> failsafe::Config {
        let ticks = (self.clear_time / h)
            .round()
            .clamp(1.0, f64::from(u32::MAX));
        failsafe::Config {
            actions: self.actions,
            clear_ticks: ticks as u32,
        }
    }

    /// The action `cause` engages, if any.
    pub fn action(&self, cause: Cause) -> Option<Action> {
        self.actions[cause as usize]
    }

    /// Whether any event engages `action`.
    fn uses(&self, action: Action) -> bool {
        self.actions.contains(&Some(action))
    }
}

/// What `[failsafe]` is checked against.
pub(crate) struct Fit {
    pub(crate) group: GroupKind,
    /// `[vehicle]`'s gravity and buoyancy, if there is a vehicle.
    pub(crate) vehicle: Option<(f64, f64)>,
    /// Whether `[estimator] gate = true` (the health the `estimator` event watches).
    pub(crate) gated: bool,
    pub(crate) control_period: f64,
}

impl crate::Scenario {
    /// The failsafe's thrust-axis law for this scenario
    /// (docs/failsafe.md, "The thrust-axis law"): on SE(3), for a vehicle whose weight
    /// exceeds its buoyancy, from the model's mass and inertia, the vehicle's net weight
    /// (`m g` less the buoyancy), the law's translational gains (`K` and `K_d` at the first
    /// position entry) and the actuators' time constant. `None` elsewhere (a buoyant vehicle
    /// included: `descend` then flies the law's own wrench), or without `[failsafe]`.
    pub fn thrust_axis(&self) -> Option<failsafe::thrust_axis::ThrustAxis<f64>> {
        let vehicle = self.vehicle.as_ref()?;
        if self.failsafe.is_none() || self.group != GroupKind::Se3 {
            return None;
        }
        let inertia = |i: usize| self.model_inertia[i * 6 + i];
        failsafe::thrust_axis::ThrustAxis::new(
            inertia(3),
            vehicle.mass * vehicle.gravity - vehicle.buoyancy,
            (inertia(0), inertia(1), inertia(2)),
            (self.kp[3 * 4 + 3], self.kd[3 * 6 + 3]),
            vehicle.actuator_time_constant,
        )
    }
}

impl Validator<'_> {
    /// `[failsafe]` against the group, the vehicle and the estimator.
    pub(crate) fn failsafe(
        &self,
        raw: Option<&RawFailsafe>,
        fit: &Fit,
    ) -> Result<Option<FailsafeSpec>, ScenarioError> {
        let Some(raw) = raw else {
            return Ok(None);
        };
        let mut actions = [None; 4];
        for (cause, value) in [
            (Cause::Link, &raw.link),
            (Cause::Estimator, &raw.estimator),
            (Cause::Actuators, &raw.actuators),
            (Cause::Tracking, &raw.tracking),
        ] {
            if let Some(v) = value {
                let action = self.failsafe_action(cause, v)?;
                self.fits(cause, action, fit)?;
                actions[cause as usize] = Some(action);
            }
        }
        if actions.iter().all(Option::is_none) {
            return Err(self.err(
                "failsafe",
                "names no event: give an action to at least one of link, estimator, actuators, tracking",
            ));
        }
        let spec = FailsafeSpec {
            actions,
            descend_rate: self.failsafe_rate("descend_rate", raw.descend_rate, DESCEND_RATE)?,
            ascend_rate: self.failsafe_rate("ascend_rate", raw.ascend_rate, ASCEND_RATE)?,
            tracking_limit_attitude: self.failsafe_limit(
                "tracking_limit_attitude",
                raw.tracking_limit_attitude,
                (std::f64::consts::PI, false),
                "(0, π) rad: an attitude error is at most π",
            )?,
            tracking_limit_position: self.failsafe_limit(
                "tracking_limit_position",
                raw.tracking_limit_position,
                (1e6, true),
                "(0, 1e6] m",
            )?,
            actuators_residual: self.failsafe_limit(
                "actuators_residual",
                raw.actuators_residual,
                (1e6, true),
                "(0, 1e6] N·m",
            )?,
            clear_time: self.failsafe_clear_time(raw.clear_time, fit.control_period)?,
        };
        self.failsafe_consistent(&spec, raw, fit)?;
        Ok(Some(spec))
    }

    /// An event's action: a string naming one of the six.
    fn failsafe_action(&self, cause: Cause, value: &toml::Value) -> Result<Action, ScenarioError> {
        let key = format!("failsafe.{}", cause.name());
        let expected = Action::ALL.map(Action::name).join(", ");
        let toml::Value::String(name) = value else {
            return Err(self.err(
                &key,
                format!(
                    "must be a string, one of {expected} (got the {} `{value}`)",
                    value.type_str()
                ),
            ));
        };
        Action::parse(name).ok_or_else(|| {
            self.err(
                &key,
                format!("unknown action `{name}` (expected {expected})"),
            )
        })
    }

    /// Whether `action` fits the vehicle, and `cause` has what raises it.
    fn fits(&self, cause: Cause, action: Action, fit: &Fit) -> Result<(), ScenarioError> {
        let key = format!("failsafe.{}", cause.name());
        let se3 = fit.group == GroupKind::Se3;
        let refuse = |why: &str| Err(self.err(&key, format!("`{}` {why}", action.name())));
        match action {
            Action::Descend if !(se3 && fit.vehicle.is_some_and(|(g, _)| g > 0.0)) => {
                return refuse(
                    "comes down along gravity: it needs group = \"se3\" and a [vehicle] with gravity > 0",
                );
            }
            Action::Surface if !(se3 && fit.vehicle.is_some_and(|(_, b)| b > 0.0)) => {
                return refuse(
                    "rises to the surface: it needs group = \"se3\" and a buoyant [vehicle] (buoyancy > 0)",
                );
            }
            Action::Disarm if fit.vehicle.is_none() => {
                return refuse("sets every actuator to its minimum: it needs a [vehicle]");
            }
            _ => {}
        }
        match cause {
            Cause::Estimator if !fit.gated => Err(self.err(
                &key,
                "watches the estimator's health: it needs [sensors] and [estimator] gate = true",
            )),
            Cause::Actuators if fit.vehicle.is_none() => Err(self.err(
                &key,
                "watches the actuators and the allocation: it needs a [vehicle]",
            )),
            _ => Ok(()),
        }
    }

    /// `descend_rate` or `ascend_rate` (m/s): finite, positive, at most 100.
    fn failsafe_rate(
        &self,
        name: &str,
        x: Option<f64>,
        default: f64,
    ) -> Result<f64, ScenarioError> {
        match x {
            None => Ok(default),
            Some(x) if x.is_finite() && x > 0.0 && x <= MAX_RATE => Ok(x),
            Some(x) => Err(self.err(
                &format!("failsafe.{name}"),
                format!("must be a speed in (0, {MAX_RATE}] m/s, got {x}"),
            )),
        }
    }

    /// A tracking limit: finite, positive, below `most` (or at it, when `inclusive`).
    fn failsafe_limit(
        &self,
        name: &str,
        x: Option<f64>,
        (most, inclusive): (f64, bool),
        range: &str,
    ) -> Result<Option<f64>, ScenarioError> {
        match x {
            None => Ok(None),
            Some(x) if x.is_finite() && x > 0.0 && (x < most || (inclusive && x == most)) => {
                Ok(Some(x))
            }
            Some(x) => Err(self.err(
                &format!("failsafe.{name}"),
                format!("must be in {range}, got {x}"),
            )),
        }
    }

    /// `clear_time` (s): finite, at least one control period, at most an hour.
    fn failsafe_clear_time(&self, x: Option<f64>, h: f64) -> Result<f64, ScenarioError> {
        match x {
            None => Ok(CLEAR_TIME.max(h)),
            Some(x) if x.is_finite() && x >= h && x <= 3600.0 => Ok(x),
            Some(x) => Err(self.err(
                "failsafe.clear_time",
                format!("must be between one control period ({h} s) and 3600 s, got {x}"),
            )),
        }
    }

    /// The keys that only mean something with an action or a group: a rate without its
    /// action, a limit without `tracking`, `tracking` without a limit, a position limit off SE(3).
    fn failsafe_consistent(
        &self,
        spec: &FailsafeSpec,
        raw: &RawFailsafe,
        fit: &Fit,
    ) -> Result<(), ScenarioError> {
        if raw.descend_rate.is_some() && !spec.uses(Action::Descend) {
            return Err(self.err(
                "failsafe.descend_rate",
                "is given but no event's action is `descend`",
            ));
        }
        if raw.ascend_rate.is_some() && !spec.uses(Action::Surface) {
            return Err(self.err(
                "failsafe.ascend_rate",
                "is given but no event's action is `surface`",
            ));
        }
        if raw.actuators_residual.is_some() && spec.action(Cause::Actuators).is_none() {
            return Err(self.err(
                "failsafe.actuators_residual",
                "is given but `actuators` names no action",
            ));
        }
        let tracking = spec.action(Cause::Tracking).is_some();
        for (name, given) in [
            ("tracking_limit_attitude", raw.tracking_limit_attitude),
            ("tracking_limit_position", raw.tracking_limit_position),
        ] {
            if given.is_some() && !tracking {
                return Err(self.err(
                    &format!("failsafe.{name}"),
                    "is given but `tracking` names no action",
                ));
            }
        }
        if spec.tracking_limit_position.is_some() && fit.group != GroupKind::Se3 {
            return Err(self.err(
                "failsafe.tracking_limit_position",
                "is a position error: it needs group = \"se3\"",
            ));
        }
        if tracking
            && spec.tracking_limit_attitude.is_none()
            && spec.tracking_limit_position.is_none()
        {
            return Err(self.err(
                "failsafe.tracking",
                "needs a limit: tracking_limit_attitude (rad) or tracking_limit_position (m)",
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use crate::Scenario;
    use std::path::Path;

    /// A scenario of the repository's `scenarios/` with `extra` appended, loaded from there.
    fn load(file: &str, extra: &str) -> Result<Scenario, String> {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios");
        let text = std::fs::read_to_string(dir.join(file)).unwrap();
        Scenario::from_toml_in(&format!("{text}\n{extra}"), "t", "t", Some(&dir))
            .map_err(|e| e.to_string())
    }

    /// The error of `extra` on `file`, which must name `key`.
    fn refused(file: &str, extra: &str, key: &str) -> String {
        let e = load(file, extra).expect_err(extra);
        assert!(e.contains(&format!("key `{key}`")), "{extra}: {e}");
        e
    }

    #[test]
    fn a_table_that_fits_is_read_with_its_defaults() {
        let s = load(
            "rov_failure.toml",
            "[failsafe]\nactuators = \"surface\"\ntracking = \"disarm\"\ntracking_limit_position = 5.0",
        )
        .unwrap();
        let f = s.failsafe.unwrap();
        assert_eq!(
            f.action(failsafe::Cause::Actuators),
            Some(failsafe::Action::Surface)
        );
        assert_eq!(f.action(failsafe::Cause::Link), None);
        assert_eq!(
            (f.ascend_rate, f.descend_rate),
            (super::ASCEND_RATE, super::DESCEND_RATE)
        );
        assert_eq!(f.tracking_limit_position, Some(5.0));
        assert_eq!(f.config(s.control_period).clear_ticks, 100);
        // absent: off; given, the fingerprint the pair compares changes
        let plain = load("rov_failure.toml", "").unwrap();
        assert!(plain.failsafe.is_none());
        assert_ne!(plain.fingerprint(), s.fingerprint());
        let descend = load(
            "hexarotor_eqf.toml",
            "[failsafe]\ntracking = \"descend\"\ndescend_rate = 0.25\ntracking_limit_attitude = 0.5",
        )
        .unwrap();
        assert_eq!(descend.failsafe.unwrap().descend_rate, 0.25);
    }

    #[test]
    fn bad_tables_are_refused_naming_the_key() {
        let rov = "rov_failure.toml";
        let hexa = "hexarotor_eqf.toml";
        let seed = "seed.toml";
        for (file, extra, key, says) in [
            (rov, "[failsafe]", "failsafe", "names no event"),
            (
                rov,
                "[failsafe]\nactuators = \"land\"",
                "failsafe.actuators",
                "unknown action `land`",
            ),
            (
                rov,
                "[failsafe]\nactuators = 3",
                "failsafe.actuators",
                "must be a string",
            ),
            (
                seed,
                "[failsafe]\ntracking = \"descend\"\ntracking_limit_attitude = 1.0",
                "failsafe.tracking",
                "gravity",
            ),
            (
                hexa,
                "[failsafe]\nlink = \"surface\"",
                "failsafe.link",
                "buoyan",
            ),
            (
                seed,
                "[failsafe]\nlink = \"disarm\"",
                "failsafe.link",
                "needs a [vehicle]",
            ),
            (
                seed,
                "[failsafe]\nestimator = \"hold\"",
                "failsafe.estimator",
                "gate = true",
            ),
            (
                hexa,
                "[failsafe]\nestimator = \"hold\"",
                "failsafe.estimator",
                "gate = true",
            ),
            (
                seed,
                "[failsafe]\nactuators = \"warn\"",
                "failsafe.actuators",
                "needs a [vehicle]",
            ),
            (
                hexa,
                "[failsafe]\nlink = \"descend\"\ndescend_rate = -0.5",
                "failsafe.descend_rate",
                "got -0.5",
            ),
            (
                hexa,
                "[failsafe]\nlink = \"descend\"\ndescend_rate = 0",
                "failsafe.descend_rate",
                "(0, 100]",
            ),
            (
                hexa,
                "[failsafe]\nlink = \"descend\"\ndescend_rate = nan",
                "failsafe.descend_rate",
                "NaN",
            ),
            (
                rov,
                "[failsafe]\nlink = \"surface\"\nascend_rate = -1",
                "failsafe.ascend_rate",
                "got -1",
            ),
            (
                rov,
                "[failsafe]\nlink = \"warn\"\nascend_rate = 1",
                "failsafe.ascend_rate",
                "no event's action is `surface`",
            ),
            (
                hexa,
                "[failsafe]\nlink = \"warn\"\ndescend_rate = 1",
                "failsafe.descend_rate",
                "no event's action is `descend`",
            ),
            (
                hexa,
                "[failsafe]\ntracking = \"damp\"",
                "failsafe.tracking",
                "needs a limit",
            ),
            (
                hexa,
                "[failsafe]\nlink = \"damp\"\ntracking_limit_attitude = 1",
                "failsafe.tracking_limit_attitude",
                "`tracking` names no action",
            ),
            (
                hexa,
                "[failsafe]\ntracking = \"damp\"\ntracking_limit_attitude = 4",
                "failsafe.tracking_limit_attitude",
                "got 4",
            ),
            (
                hexa,
                "[failsafe]\ntracking = \"damp\"\ntracking_limit_attitude = 3.141592653589793",
                "failsafe.tracking_limit_attitude",
                "at most π",
            ),
            (
                hexa,
                "[failsafe]\ntracking = \"damp\"\ntracking_limit_position = -2",
                "failsafe.tracking_limit_position",
                "got -2",
            ),
            (
                seed,
                "[failsafe]\ntracking = \"damp\"\ntracking_limit_position = 2",
                "failsafe.tracking_limit_position",
                "se3",
            ),
            (
                hexa,
                "[failsafe]\nactuators = \"warn\"\nactuators_residual = -0.1",
                "failsafe.actuators_residual",
                "got -0.1",
            ),
            (
                hexa,
                "[failsafe]\nactuators = \"warn\"\nactuators_residual = nan",
                "failsafe.actuators_residual",
                "N·m",
            ),
            (
                hexa,
                "[failsafe]\nlink = \"warn\"\nactuators_residual = 0.1",
                "failsafe.actuators_residual",
                "`actuators` names no action",
            ),
            (
                hexa,
                "[failsafe]\nlink = \"damp\"\nclear_time = 0.0001",
                "failsafe.clear_time",
                "one control period",
            ),
            (
                hexa,
                "[failsafe]\nlink = \"damp\"\nclear_time = inf",
                "failsafe.clear_time",
                "inf",
            ),
        ] {
            let e = refused(file, extra, key);
            assert!(e.contains(says), "{extra}: {e}");
        }
        // an unknown event is the parser's: it names the key, its line and the events
        let e = load(rov, "[failsafe]\nlanding = \"hold\"").unwrap_err();
        assert!(
            e.contains("unknown field `landing`, expected one of `link`, `estimator`"),
            "{e}"
        );
    }
}
