use super::*;
use proptest::prelude::*;

/// link → damp, estimator → hold, actuators → descend, tracking → disarm... as given.
fn config(actions: [Option<Action>; 4], clear_ticks: u32) -> Config {
    Config {
        actions,
        clear_ticks,
    }
}

fn inputs(link: bool, estimator: bool, actuators: bool, tracking: bool) -> Inputs {
    Inputs {
        link,
        estimator,
        actuators,
        tracking,
    }
}

fn engaged(cause: Cause, action: Action) -> Mode {
    Mode::Engaged { cause, action }
}

/// Steps through `flags`, returning each tick's mode and transition.
fn run(cfg: &Config, flags: &[Inputs]) -> Vec<(Mode, Option<Transition>)> {
    let mut s = State::default();
    flags
        .iter()
        .map(|f| {
            let (n, t) = step(cfg, &s, f);
            s = n;
            (s.mode(), t)
        })
        .collect()
}

#[test]
fn a_cause_engages_at_once_and_clears_after_its_hysteresis() {
    let cfg = config([Some(Action::Damp), Some(Action::Hold), None, None], 3);
    let quiet = Inputs::default();
    let est = inputs(false, true, false, false);
    let out = run(
        &cfg,
        &[quiet, est, quiet, quiet, est, quiet, quiet, quiet, quiet],
    );
    let modes: Vec<Mode> = out.iter().map(|(m, _)| *m).collect();
    let hold = engaged(Cause::Estimator, Action::Hold);
    assert_eq!(
        modes,
        [
            Mode::Nominal,
            hold,
            hold,
            hold,
            // the flag comes back before three quiet ticks: the count starts again
            hold,
            hold,
            hold,
            Mode::Nominal,
            Mode::Nominal
        ]
    );
    // a transition exactly where the mode changes
    let changes: Vec<usize> = out
        .iter()
        .enumerate()
        .filter_map(|(k, (_, t))| t.map(|_| k))
        .collect();
    assert_eq!(changes, [1, 7]);
    assert_eq!(
        out[7].1,
        Some(Transition {
            from: hold,
            to: Mode::Nominal
        })
    );
}

#[test]
fn the_most_severe_cause_is_engaged_and_the_milder_one_returns_when_it_clears() {
    let cfg = config(
        [
            Some(Action::Damp),
            Some(Action::Hold),
            Some(Action::Descend),
            None,
        ],
        2,
    );
    let est = inputs(false, true, false, false);
    let both = inputs(false, true, true, false);
    let out = run(&cfg, &[est, both, est, est, est]);
    let modes: Vec<Mode> = out.iter().map(|(m, _)| *m).collect();
    let (hold, descend) = (
        engaged(Cause::Estimator, Action::Hold),
        engaged(Cause::Actuators, Action::Descend),
    );
    assert_eq!(modes, [hold, descend, descend, hold, hold]);
    // a milder cause arriving under a severe one changes nothing
    let out = run(&cfg, &[both, both, inputs(true, true, true, false)]);
    assert!(out.iter().all(|(m, _)| *m == descend));
    assert_eq!(out.iter().filter(|(_, t)| t.is_some()).count(), 1);
    // a tie goes to the cause named first: link before actuators
    let cfg = config(
        [Some(Action::Descend), None, Some(Action::Descend), None],
        2,
    );
    let out = run(&cfg, &[inputs(true, false, true, false)]);
    assert_eq!(out[0].0, engaged(Cause::Link, Action::Descend));
    // ... but not against the cause already engaged: an equal cause does not take over
    let act = inputs(false, false, true, false);
    let out = run(&cfg, &[act, inputs(true, false, true, false), act]);
    assert!(
        out.iter()
            .all(|(m, _)| *m == engaged(Cause::Actuators, Action::Descend))
    );
    assert_eq!(out.iter().filter(|(_, t)| t.is_some()).count(), 1);
}

#[test]
fn tracking_and_disarm_latch_and_an_unconfigured_cause_is_ignored() {
    let cfg = config([None, Some(Action::Disarm), None, Some(Action::Damp)], 1);
    let quiet = Inputs::default();
    let out = run(
        &cfg,
        &[inputs(true, false, true, true), quiet, quiet, quiet],
    );
    assert!(
        out.iter()
            .all(|(m, _)| *m == engaged(Cause::Tracking, Action::Damp))
    );
    let out = run(&cfg, &[inputs(false, true, false, false), quiet, quiet]);
    assert!(
        out.iter()
            .all(|(m, _)| *m == engaged(Cause::Estimator, Action::Disarm))
    );
    assert!(cfg.latches(Cause::Tracking) && cfg.latches(Cause::Estimator));
    assert!(!cfg.latches(Cause::Link));
}

#[test]
fn names_parse_back_and_severity_orders_the_actions() {
    for c in Cause::ALL {
        assert_eq!(Cause::parse(c.name()), Some(c));
    }
    for a in Action::ALL {
        assert_eq!(Action::parse(a.name()), Some(a));
    }
    assert_eq!((Cause::parse("gps"), Action::parse("land")), (None, None));
    let s: Vec<u8> = Action::ALL.iter().map(|a| a.severity()).collect();
    assert_eq!(s, [0, 1, 2, 3, 3, 4]);
}

fn action() -> impl Strategy<Value = Option<Action>> {
    prop::option::of(prop::sample::select(Action::ALL.to_vec()))
}

proptest! {
    /// Over any configuration and any sequence of flags: the engaged action is at least as
    /// severe as every raised cause's; a raised cause is one whose flag was set within its
    /// hysteresis, or that latches; a transition is returned exactly when the mode changes;
    /// and the same inputs give the same outputs.
    #[test]
    fn the_rules_hold_on_any_sequence(
        actions in prop::array::uniform4(action()),
        clear_ticks in 1u32..6,
        flags in prop::collection::vec(prop::array::uniform4(any::<bool>()), 0..200),
    ) {
        let cfg = config(actions, clear_ticks);
        let mut s = State::default();
        let mut last_set: [Option<usize>; 4] = [None; 4];
        let mut ever: [bool; 4] = [false; 4];
        for (k, f) in flags.iter().enumerate() {
            let input = inputs(f[0], f[1], f[2], f[3]);
            let (n, t) = step(&cfg, &s, &input);
            prop_assert_eq!((n, t), step(&cfg, &s, &input));
            prop_assert_eq!(t.is_some(), n.mode() != s.mode());
            for c in Cause::ALL {
                let i = c as usize;
                if f[i] && cfg.action(c).is_some() {
                    last_set[i] = Some(k);
                    ever[i] = true;
                }
                let expected = cfg.action(c).is_some()
                    && ((ever[i] && cfg.latches(c))
                        || last_set[i].is_some_and(|j| k - j < clear_ticks as usize));
                prop_assert_eq!(n.raised(c), expected, "tick {} cause {:?}", k, c);
                if n.raised(c) {
                    let Mode::Engaged { action, .. } = n.mode() else {
                        return Err(TestCaseError::fail("a raised cause and no failsafe"));
                    };
                    prop_assert!(action.severity() >= cfg.action(c).unwrap().severity());
                }
            }
            if let Mode::Engaged { cause, action } = n.mode() {
                prop_assert!(n.raised(cause));
                prop_assert_eq!(cfg.action(cause), Some(action));
            }
            s = n;
        }
    }
}
