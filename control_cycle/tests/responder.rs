//! The stateful responder (docs/maths.md, "Disturbance rejection"): a controller that skipped
//! states and answered one too late to be recorded is still checked command by command, by
//! restoring its terms from each recorded command.

use control_cycle::Responder;
use eqtrack_controller::group::So3;
use eqtrack_controller::{Source, Trajectory};
use ipc_types::{CommandMsg, NO_PREVIOUS, StateMsg};
use nalgebra::Vector3;
use scenario::Scenario;
use std::path::Path;

/// The set-point with the observer and the integral both on.
fn scenario() -> Scenario {
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/reject_so3.toml");
    let text = std::fs::read_to_string(Path::new(file)).unwrap().replace(
        "disturbance_observer = { gain = 20.0 }",
        "disturbance_observer = { gain = 20.0 }\nintegral = { ki = 1.0, c = 5.0 }",
    );
    Scenario::from_toml(&text, "test", "reject_both").unwrap()
}

fn responder(s: &Scenario) -> Responder<f64, So3, 3, 3> {
    Responder::new(s.controller().unwrap(), s.rejection_config()).unwrap()
}

/// The plant's state `k` of scenario `s`: the body's pose and velocity, and the torque it
/// applied over the period before.
fn state_msg(
    s: &Scenario,
    k: u64,
    body: &eqtrack_controller::integrator::RigidBody<f64, So3, 3, 3>,
    applied: &Vector3<f64>,
) -> StateMsg {
    let mut msg = StateMsg::new(ipc_types::WireGroup::So3);
    msg.seq = k;
    msg.t = k as f64 * s.control_period;
    msg.control_period = s.control_period;
    msg.set_state(body.configuration(), &body.velocity());
    msg.set_applied(applied);
    msg
}

#[test]
fn a_skipped_gap_and_an_unrecorded_late_command_do_not_stop_replay() {
    let s = scenario();
    let mut live = responder(&s);
    let mut reference: Source<f64, So3, 3, 3> = s.reference_source().unwrap();
    let mut body = s.plant_body::<So3, 3, 3>().unwrap();
    let mut applied = Vector3::zeros();
    let (mut states, mut commands): (Vec<StateMsg>, Vec<Option<CommandMsg>>) = (vec![], vec![]);
    for k in 0..200u64 {
        let msg = state_msg(&s, k, &body, &applied);
        states.push(msg);
        // the controller is stopped over ticks 80..95: the plant holds the last torque
        let cmd = (!(80..95).contains(&k)).then(|| live.respond(&mut reference, &msg).unwrap());
        if let Some(c) = &cmd {
            applied = c.torque::<3>();
        }
        commands.push(cmd);
        body.advance(
            &(applied + s.disturbance_vector::<3>()),
            s.control_period,
            10,
        );
    }
    let c95 = commands[95].unwrap();
    assert_eq!(
        c95.previous_seq, 79,
        "the first command after the gap names the state before it"
    );
    assert_eq!(commands[96].unwrap().previous_seq, 95);
    assert_eq!(commands[0].unwrap().previous_seq, NO_PREVIOUS);
    assert!(c95.observer.iter().any(|x| *x != 0.0) && c95.integral.iter().any(|x| *x != 0.0));
    // replay as `plant_sim replay` does: command 95 was too late to be recorded, so nothing
    // says that 80..95 were skipped; each recorded command restores the terms on its own
    let mut replay = responder(&s);
    let mut reference: Source<f64, So3, 3, 3> = s.reference_source().unwrap();
    let mut compared = 0;
    for k in 0..200usize {
        let recorded = commands[k].filter(|_| k != 95);
        if let Some(c) = &recorded {
            let previous = (c.previous_seq != NO_PREVIOUS).then(|| states[c.previous_seq as usize]);
            replay.restore(c, previous.as_ref());
        }
        let again = replay.respond(&mut reference, &states[k]).unwrap();
        reference.advance();
        if let Some(c) = recorded {
            for i in 0..3 {
                assert_eq!(c.tau[i].to_bits(), again.tau[i].to_bits(), "tick {k}");
                assert_eq!(
                    c.observer[i].to_bits(),
                    again.observer[i].to_bits(),
                    "tick {k}"
                );
                assert_eq!(
                    c.integral[i].to_bits(),
                    again.integral[i].to_bits(),
                    "tick {k}"
                );
            }
            assert_eq!(c.lyapunov.to_bits(), again.lyapunov.to_bits(), "tick {k}");
            compared += 1;
        }
    }
    assert_eq!(compared, 200 - 15 - 1);
    // and without the restoring, running every state shows the difference the gap makes
    let mut naive = responder(&s);
    let mut reference: Source<f64, So3, 3, 3> = s.reference_source().unwrap();
    let mut differ = 0;
    for (k, st) in states.iter().enumerate() {
        let again = naive.respond(&mut reference, st).unwrap();
        reference.advance();
        if let Some(c) = commands[k].filter(|_| k > 95) {
            differ += usize::from(c.tau[0].to_bits() != again.tau[0].to_bits());
        }
    }
    assert!(differ > 0, "the test must be able to fail");
}

/// Run-time gains (docs/live.md, "Tuning a running pair"): a retune changes every gain at
/// once and keeps the terms' state; gains the law refuses (not finite, not positive
/// definite, a term's gain ≤ 0) leave the responder exactly as it was.
#[test]
fn retune_changes_the_gains_at_once_or_not_at_all() {
    let s = scenario();
    let mut live = responder(&s);
    let mut reference: Source<f64, So3, 3, 3> = s.reference_source().unwrap();
    let mut msg = StateMsg::new(ipc_types::WireGroup::So3);
    msg.control_period = s.control_period;
    let body = s.plant_body::<So3, 3, 3>().unwrap();
    msg.set_state(body.configuration(), &body.velocity());
    for k in 0..20 {
        msg.seq = k;
        msg.t = k as f64 * s.control_period;
        live.respond(&mut reference, &msg).unwrap();
    }
    let gains = |kd: f64, observer: f64| {
        let mut t = s.clone();
        t.kd = vec![kd, 0.0, 0.0, 0.0, kd, 0.0, 0.0, 0.0, kd];
        if let Some(o) = &mut t.rejection.observer {
            o.gain = vec![observer; 3];
        }
        ipc_types::Gains::from_slices(
            20,
            &t.kp,
            &t.kd,
            t.rejection.observer.as_ref().map(|o| o.gain.as_slice()),
            t.rejection
                .integral
                .as_ref()
                .map(|i| (i.ki.as_slice(), i.c.as_slice())),
        )
    };
    let before = live.clone();
    for bad in [
        gains(f64::NAN, 20.0),
        gains(-1.0, 20.0),
        gains(0.8, 0.0),
        gains(0.8, f64::INFINITY),
    ] {
        assert!(live.retune(&bad).is_err(), "{bad:?}");
        assert_eq!(
            format!("{live:?}"),
            format!("{before:?}"),
            "a refused retune changed it"
        );
    }
    live.retune(&gains(0.8, 7.0)).unwrap();
    assert_eq!(live.controller().config().kd[(1, 1)], 0.8);
    let r = live.rejection().unwrap();
    assert_eq!(r.config().observer.unwrap().gain[2], 7.0);
    // the terms' state carried over
    let was = before.rejection().unwrap();
    assert_eq!(r.estimate(), was.estimate());
    assert_eq!(r.integral_state(), was.integral_state());
    // a new K_I keeps the integral's torque −K_I z where it was
    let mut doubled = gains(0.8, 7.0);
    for x in &mut doubled.ki[..3] {
        *x *= 2.0;
    }
    let mut twice = live.clone();
    twice.retune(&doubled).unwrap();
    let torque = |r: &control_cycle::Responder<f64, So3, 3, 3>| {
        let t = r.rejection().unwrap();
        -t.config()
            .integral
            .unwrap()
            .ki
            .component_mul(t.integral_state())
    };
    assert!(live.rejection().unwrap().integral_state().norm() > 0.0);
    assert!((torque(&twice) - torque(&live)).norm() <= 1e-15 * torque(&live).norm());
    // and the next answer differs from the untuned one
    msg.seq = 20;
    msg.t = 20.0 * s.control_period;
    msg.v[..3].copy_from_slice(&[0.05, -0.02, 0.01]);
    let mut other = before.clone();
    let mut ref2 = reference.clone();
    let tuned = live.respond(&mut reference, &msg).unwrap();
    let plain = other.respond(&mut ref2, &msg).unwrap();
    assert_ne!(tuned.tau, plain.tau);
}

/// The failsafe's `link` cause (docs/failsafe.md, "Causes"): a command that reaches the plant
/// after its deadline is not applied (the plant holds the one before), and the next state
/// says so in its `applied` wrench. That state follows the last one answered, yet it raises
/// `link`, and the hold is left once the commands have been applied for `clear_time`.
#[test]
fn a_command_the_plant_did_not_apply_raises_link() {
    use failsafe::{Action, Cause, Mode, State};
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/reject_so3.toml"
    ))
    .unwrap()
        + "\n[failsafe]\nlink = \"hold\"\nclear_time = 0.1\n";
    let s = Scenario::from_toml(&text, "test", "reject_link").unwrap();
    // the modes of the commands of a run in which the plant applied every command but `late`
    let modes = |late: Option<u64>| -> Vec<Mode> {
        let sup = control_cycle::Supervisor::of(&s).unwrap();
        let mut live = responder(&s).with_supervisor(sup);
        let mut reference: Source<f64, So3, 3, 3> = s.reference_source().unwrap();
        let mut body = s.plant_body::<So3, 3, 3>().unwrap();
        let mut applied = Vector3::zeros();
        let mut modes = vec![];
        for k in 0..100u64 {
            let msg = state_msg(&s, k, &body, &applied);
            let c = live.respond(&mut reference, &msg).unwrap();
            reference.advance();
            modes.push(State::read_word(c.failsafe).unwrap().0);
            if late != Some(k) {
                applied = c.torque::<3>();
            }
            body.advance(&applied, s.control_period, 10);
        }
        modes
    };
    let hold = Mode::Engaged {
        cause: Cause::Link,
        action: Action::Hold,
    };
    let on_time = modes(None);
    assert!(on_time.iter().all(|m| *m == Mode::Nominal), "{on_time:?}");
    let late = modes(Some(40));
    assert!(late[..41].iter().all(|m| *m == Mode::Nominal), "{late:?}");
    assert_eq!(
        late[41], hold,
        "the state after the late command raises link"
    );
    // clear_time 0.1 s: that many ticks with every command applied
    let ticks = (0.1 / s.control_period).round() as usize;
    let held = late.iter().filter(|m| **m == hold).count();
    assert!(
        (ticks..=ticks + 1).contains(&held),
        "held {held} ticks: {late:?}"
    );
    assert_eq!(late[99], Mode::Nominal);
}
