//! The short form of the fuzz run, for CI: a fixed number of cases per target in the dev
//! profile (a few seconds), no panic allowed, the generator checked for a spread of accepted
//! and rejected inputs, and a planted bug checked to be caught end to end. The long form is
//! the `fuzz` binary (`cargo build --release -p fuzz && target/release/fuzz --cases 1000000`).

use fuzz::{Case, Outcome, Report, Target};

/// Cases per target: about 3 s for both targets in the dev profile (opt-level 2).
const CASES: u64 = 100_000;
/// The seed of the short run (fixed: CI runs the same cases every time).
const SEED: u64 = 1;

/// Asserts no panic, and that the generator reaches both paths: at least 2 % of the cases
/// accepted, at least 20 % rejected, over at least `kinds` distinct rejection kinds.
fn assert_sound(r: &Report, kinds: usize) {
    eprintln!("{r}");
    assert!(r.passed(), "the fuzz run found panics:\n{r}");
    assert_eq!(r.cases, CASES);
    assert_eq!(r.accepted + r.rejected_total(), r.cases);
    assert!(
        r.accepted * 50 >= r.cases,
        "fewer than 2 % of the cases accepted: the generator no longer reaches the accepting path\n{r}"
    );
    assert!(
        r.rejected_total() * 5 >= r.cases,
        "fewer than 20 % of the cases rejected\n{r}"
    );
    assert!(
        r.rejected.len() >= kinds,
        "only {} rejection kinds (expected at least {kinds})\n{r}",
        r.rejected.len()
    );
}

#[test]
fn scenario_inputs_never_panic() {
    let r = fuzz::run(Target::Scenario, CASES, SEED);
    assert_sound(&r, 20);
    // the validator's and the parser's rejections are both reached
    assert!(
        r.rejected
            .keys()
            .any(|k| k.starts_with("ScenarioError::Invalid"))
    );
    assert!(
        r.rejected
            .keys()
            .any(|k| k.starts_with("ScenarioError::Parse"))
    );
    // the vehicle seeds' mutations reach every bad vehicle table: a geometry that loses a
    // direction or has too many actuators, a zero or non-finite axis, min > max, a failure
    // of an actuator that is not there, of a kind it does not know, stuck outside its range or
    // with a factor outside (0, 1), a bad allocation table, bad failure-detection keys, bad
    // reaction wheels
    for key in [
        "vehicle.actuator",
        "vehicle.actuator[*].axis",
        "vehicle.actuator[*].min",
        "vehicle.failure[*].actuator",
        "vehicle.failure[*].kind",
        "vehicle.failure[*].value",
        "vehicle.failure[*].factor",
        "allocation.weights",
        "fault_detection.window",
        "fault_detection.false_alarm_rate",
        "fault_detection.floor",
        "fault_detection.calibration",
        "fault_detection.memory",
        "fault_detection.confirm",
        "fault_detection.warmup",
        "fault_detection.model_error",
        "fault_detection.unexplained",
        "fault_detection.ambiguity",
        "failsafe.link",
        "failsafe.actuators",
        "failsafe.estimator",
        "failsafe.tracking",
        "failsafe.descend_rate",
        "failsafe.ascend_rate",
        "failsafe.tracking_limit_attitude",
        "failsafe.tracking_limit_position",
        "failsafe.clear_time",
        "failsafe.actuators_residual",
        // reaction wheels: too many, a zero or non-finite axis, a spin inertia, torque or speed
        // limit, friction or Stribeck speed out of range; momentum management's threshold
        "vehicle.wheel",
        "vehicle.wheel[*].axis",
        "vehicle.wheel[*].inertia",
        "vehicle.wheel[*].max_torque",
        "vehicle.wheel[*].max_speed",
        "vehicle.wheel[*].friction_coulomb",
        "vehicle.wheel[*].stribeck_speed",
        "vehicle.momentum.dump_threshold",
        // a planar scenario (the group mutated to se2, or the se2 seeds mutated) refuses
        // what needs a third dimension, naming the key
        "sensors, on se2",
        "vehicle.gravity, on se2",
    ] {
        assert!(
            r.rejected
                .keys()
                .any(|k| k == &format!("ScenarioError::Invalid ({key})")),
            "{key} never refused\n{r}"
        );
    }
}

#[test]
fn wire_inputs_never_panic() {
    let r = fuzz::run(Target::Wire, CASES, SEED);
    assert_sound(&r, 8);
    // every kind of the checks' rejections, and the decoder's, are reached
    for kind in [
        "StateMsg::from_bytes: DecodeError::Length",
        "CommandMsg::from_bytes: DecodeError::Length",
        "check_state: Invalid::Version",
        "check_state: Invalid::Group",
        "check_state: Invalid::NonFinite",
        "check_state: Invalid::Sequence",
        "check_state: Invalid::Period",
        "check_command: Invalid::Version",
        "check_command: Invalid::Group",
        "check_command: Invalid::NonFinite",
        "check_command: Invalid::Sequence",
        "check_command: Invalid::Actuators",
        "check_command: Invalid::Detection",
        "check_command: Invalid::Failsafe",
    ] {
        assert!(r.rejected.contains_key(kind), "{kind} never seen\n{r}");
    }
}

#[test]
fn serial_inputs_never_panic() {
    let r = fuzz::run(Target::Serial, CASES, SEED);
    assert_sound(&r, 5);
    // the line's every refusal is reached: broken COBS, a short frame, a CRC mismatch,
    // another version, a message that does not decode
    for kind in ["Cobs", "Short", "Crc", "Version", "Message"] {
        let key = format!("serial: FrameError::{kind}");
        assert!(r.rejected.contains_key(&key), "{key} never seen\n{r}");
    }
}

#[test]
fn shard_inputs_never_panic() {
    let r = fuzz::run(Target::Shard, CASES, SEED);
    assert_sound(&r, 3);
    // the decoder's refusals and the merge's are reached
    for kind in [
        "shard: CutShort",
        "shard: Magic",
        "shard: Version",
        "shard: NotWhole",
        "merge: NotItsShare",
    ] {
        assert!(r.rejected.contains_key(kind), "{kind} never seen\n{r}");
    }
}

#[test]
fn recording_inputs_never_panic() {
    let r = fuzz::run(Target::Recording, CASES, SEED);
    assert_sound(&r, 8);
    // the record's decoder, the plan entry's, and the intake's checks are all reached
    for kind in [
        "Record::from_bytes: sensor",
        "Record::from_bytes: decision",
        "PlanEntry::from_bytes",
        "PlanIntake::take: NonFinite",
        "PlanIntake::take: Group",
        "PlanIntake::take: NotOnGroup",
    ] {
        assert!(
            r.rejected.keys().any(|k| k.starts_with(kind)),
            "{kind} never seen\n{r}"
        );
    }
}

#[test]
fn run_time_parameters_never_panic() {
    let r = fuzz::run(Target::Params, CASES, SEED);
    assert_sound(&r, 30);
    // the board's every refusal, the controller's refusal of its gains, the request
    // reader's and the tuner's refusals, and the log reader's are reached
    for kind in [
        "ParamMsg::gains_for: ParamInvalid::Version",
        "ParamMsg::gains_for: ParamInvalid::Group",
        "ParamMsg::gains_for: ParamInvalid::Fingerprint",
        "ParamMsg::gains_for: ParamInvalid::NotFinite",
        "ParamMsg::gains_for: ParamInvalid::TooOld",
        "Responder::retune: eqtrack_controller::Error::NotPositiveDefinite",
        "Responder::retune: eqtrack_controller::Error::NotSymmetric",
        "read_request: Version",
        "read_request: Operation",
        "read_request: KeyNotUtf8",
        "read_request: ValueNotUtf8",
        "Tuner::get: NotTunable",
        "Tuner::check: ValueUnreadable",
        "Tuner::check: NotTunable",
        "Tuner::check: TermAbsent",
        "Tuner::check: scenario (controller.kp)",
        "Tuner::check: scenario (controller.kd)",
        "parse_params: header",
        "parse_params: format or version",
        "parse_params: change line",
        "parse_params: cycles",
    ] {
        assert!(
            r.rejected.keys().any(|k| k.starts_with(kind)),
            "{kind} never seen\n{r}"
        );
    }
}

#[test]
fn live_bridge_client_messages_never_panic() {
    let r = fuzz::run(Target::Live, CASES, SEED);
    assert_sound(&r, 10);
    // every refusal of the parser and of the session's subscriptions is reached
    for kind in [
        "NotJson",
        "NoOp",
        "NoList",
        "BadSubscription",
        "BadSubscriptionId",
        "UnknownChannel",
        "IdInUse",
        "ChannelTaken",
        "NotSubscribed",
        "Unsupported",
        "Binary",
    ] {
        let key = format!("live: {kind}");
        assert!(r.rejected.contains_key(&key), "{key} never seen\n{r}");
    }
}

/// A bug planted in the checked code (a panic on a NaN control period in an accepted-length
/// state, deep in the generated inputs) is caught: the run fails, the finding names the
/// planted panic and its location, and its input regenerates from (seed, case).
#[test]
fn a_planted_bug_is_caught() {
    let planted = |case: &Case| {
        if let Case::Wire(w) = case
            && let Ok(msg) = ipc_types::StateMsg::from_bytes(&w.bytes)
        {
            assert!(!msg.control_period.is_nan(), "planted: NaN period");
        }
        fuzz::check(case)
    };
    let r = fuzz::run_with(Target::Wire, SEED, 0..5_000, planted, |_| {});
    assert!(!r.passed(), "the planted bug was not caught:\n{r}");
    assert_eq!(r.panics.len(), 1, "{r}");
    let f = &r.panics[0];
    assert_eq!(f.panic.message, "planted: NaN period");
    assert!(
        f.panic.location.contains("short.rs"),
        "{}",
        f.panic.location
    );
    assert_eq!(fuzz::generate(Target::Wire, SEED, f.case), f.input);
    // the same case without the planted bug is an ordinary rejection
    assert!(matches!(fuzz::check(&f.input), Outcome::Rejected(_)));
}

#[test]
fn waypoint_files_and_streamed_segments_never_panic() {
    let r = fuzz::run(Target::Path, CASES / 4, SEED);
    eprintln!("{r}");
    assert!(r.passed(), "the fuzz run found panics:\n{r}");
    assert!(
        r.accepted * 20 >= r.cases,
        "fewer than 5 % of the waypoint files accepted\n{r}"
    );
    // the checks of the new inputs are reached: velocity columns, short legs
    for kind in [
        "Waypoints(t): the leg from",
        "Waypoints(wx)",
        "Waypoints(t): times must increase",
    ] {
        assert!(
            r.rejected.keys().any(|k| k.starts_with(kind)),
            "no `{kind}` rejection\n{r}"
        );
    }
}
