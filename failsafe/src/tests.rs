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

#[test]
fn a_word_it_does_not_write_does_not_read() {
    // nominal, and hold engaged by the estimator (raised: bit 9)
    assert_eq!(State::read_word(0), Some((Mode::Nominal, [false; 4])));
    let hold = 2 | 2 << 4 | 1 << 9;
    assert_eq!(
        State::read_word(hold),
        Some((
            engaged(Cause::Estimator, Action::Hold),
            [false, true, false, false]
        ))
    );
    // an action without a cause, a cause without an action, codes out of range, the engaged
    // cause not raised, a bit above the raised causes'
    for bad in [
        2,
        2 << 4,
        7 | 1 << 4 | 1 << 8,
        1 | 5 << 4,
        2 | 2 << 4,
        hold | 1 << 12,
    ] {
        assert_eq!(State::read_word(bad), None, "{bad:#x}");
    }
}

/// The monitor raises `tracking` only once the error has been within its limits, and names
/// the tick it first passed them; an error that is not a number is beyond.
#[test]
fn the_monitor_arms_tracking_once_within_and_keeps_the_tick_it_tripped() {
    let cfg = config([None, None, None, Some(Action::Disarm)], 2);
    let limits = monitor::Limits {
        attitude: Some(0.5),
        position: None,
    };
    let mut m = monitor::Monitor::new(cfg, limits);
    let flags = monitor::Flags::default();
    // starting beyond: not a runaway
    assert_eq!(m.tick((1.0, 0.0), flags), None);
    assert_eq!(m.tick((0.6, 0.0), flags), None);
    // within once, then beyond at tick 3: disarm, latched
    assert_eq!(m.tick((0.4, 0.0), flags), None);
    let tr = m.tick((0.7, 0.0), flags).expect("a transition");
    assert_eq!(tr.to, engaged(Cause::Tracking, Action::Disarm));
    assert!(m.disarmed());
    assert_eq!(m.runaway(), Some((3, 0.7, 0.0)));
    for _ in 0..5 {
        assert_eq!(m.tick((0.0, 0.0), flags), None);
    }
    assert!(m.disarmed());
    // a NaN error is beyond
    let mut m = monitor::Monitor::new(cfg, limits);
    m.tick((0.1, 0.0), flags);
    assert!(m.tick((f64::NAN, 0.0), flags).is_some());
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
            // the wire's word says the mode and the raised causes, and reads back
            let (mode, raised) = State::read_word(n.word()).expect("a word it writes reads");
            prop_assert_eq!(mode, n.mode());
            for c in Cause::ALL {
                prop_assert_eq!(raised[c as usize], n.raised(c));
            }
            s = n;
        }
    }
}

#[test]
fn applied_as_sent_compares_bits_not_values() {
    use monitor::applied_as_sent;
    let sent = [1.0f64, -0.0, 2.5];
    assert!(applied_as_sent(Some(&sent[..]), &[1.0, -0.0, 2.5]));
    // no answer yet, a held command, and a zero of the other sign all differ
    assert!(!applied_as_sent(None, &[1.0, -0.0, 2.5]));
    assert!(!applied_as_sent(Some(&sent[..]), &[1.0, -0.0, 2.4]));
    assert!(!applied_as_sent(Some(&sent[..]), &[1.0, 0.0, 2.5]));
    // a NaN equals itself here, bit for bit, as the wire carries it; f32 the same way
    let nan = [f32::NAN, 3.0];
    assert!(applied_as_sent(Some(&nan[..]), &[f32::NAN, 3.0]));
    assert!(!applied_as_sent(Some(&nan[..]), &[-f32::NAN, 3.0]));
}
