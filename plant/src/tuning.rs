//! Run-time parameters on the plant's side (docs/live.md, "Tuning a running pair").
//!
//! A thread of its own serves the run's `param` request-response service: it checks each
//! `set` with the scenario's own validation (`scenario::tuning`), hands the checked change
//! to the loop, and waits until the loop has put it in force. The loop looks for a change
//! once a cycle (one atomic load; no allocation, no system call), before it publishes the
//! cycle's state: it then changes its own gains (the safe-mode damping, the rows'
//! Lyapunov function, the estimator's gains) and writes the `params` board, so the state of
//! that cycle is the first the controller answers with the new gains. The thread then
//! records the change in `params.log` with that cycle, and answers.

use crate::SimError;
use ipc_types::Gains;
use link::params::{Answer, Asked, ParamServer};
use recorder::ParamChange;
use scenario::Scenario;
use scenario::tuning::{Acts, Change, Tuner};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

fn log(msg: std::fmt::Arguments) {
    link::log_line(format_args!("plant_sim: {msg}"));
}

/// A checked change for the loop: what it touches, with its values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Retune {
    /// The controller's gains (`None`: the change is the estimator's).
    pub gains: Option<Gains>,
    /// The complementary filter's `(k_P, k_I)` (`None`: the change is the controller's).
    pub estimator: Option<(f64, f64)>,
}

impl Retune {
    /// What a change touches: the controller's gains of the changed scenario, or its
    /// estimator's gains.
    pub fn of(change: &Change) -> Retune {
        let s = &change.scenario;
        match change.acts() {
            Acts::Controller => Retune {
                gains: Some(gains(s, 0)),
                estimator: None,
            },
            Acts::Estimator => Retune {
                gains: None,
                estimator: Some((s.estimator.kp, s.estimator.ki)),
            },
        }
    }
}

/// The controller's gains of scenario `s` from `cycle` on, as the `params` board carries
/// them.
pub fn gains(s: &Scenario, cycle: u64) -> Gains {
    let r = &s.rejection;
    Gains::from_slices(
        cycle,
        &s.kp,
        &s.kd,
        r.observer.as_ref().map(|o| o.gain.as_slice()),
        r.integral
            .as_ref()
            .map(|i| (i.ki.as_slice(), i.c.as_slice())),
    )
}

/// The hand-over's states ([`Shared::state`]).
const EMPTY: u8 = 0;
/// `pending` holds a change for the loop.
const PENDING: u8 = 1;
/// The loop took it and is putting it in force.
const TAKEN: u8 = 2;
/// In force from `applied_cycle` on.
const APPLIED: u8 = 3;

/// Between the thread and the loop. The loop never waits for the thread: it moves the state
/// with compare-and-swap (`PENDING` → `TAKEN` → `APPLIED`), and touches the change's mutex
/// only once it owns the change (`TAKEN`), when nobody else holds it.
#[derive(Default)]
struct Shared {
    state: AtomicU8,
    pending: Mutex<Option<Retune>>,
    applied_cycle: AtomicU64,
    /// The loop has ended: no change can take effect any more.
    ended: AtomicBool,
}

/// The loop's handle on the parameter thread.
pub struct Tuning {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<Vec<ParamChange>>>,
}

impl Tuning {
    /// Starts the thread serving run `run`'s `param` service, checking changes with
    /// `tuner` (the run's scenario); changes are recorded in `record/params.log` (`None`:
    /// not recorded). `period` is the run's control period.
    pub fn start(
        run: &str,
        tuner: Tuner,
        record: Option<PathBuf>,
        period: f64,
    ) -> Result<Tuning, SimError> {
        if let Some(dir) = &record {
            recorder::create_params(dir).map_err(|e| SimError::Run(e.to_string()))?;
        }
        let shared = Arc::new(Shared::default());
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        let run = run.to_owned();
        let theirs = Arc::clone(&shared);
        let thread = std::thread::Builder::new()
            .name("params".into())
            .spawn(move || {
                let server = match ParamServer::create(&run) {
                    Ok(s) => {
                        let _ = ready_tx.send(Ok(()));
                        s
                    }
                    Err(e) => {
                        let _ = ready_tx.send(Err(e.to_string()));
                        return Vec::new();
                    }
                };
                let mut state = Thread {
                    tuner,
                    shared: theirs,
                    record,
                    period,
                    changes: Vec::new(),
                };
                while !state.shared.ended.load(Ordering::Acquire) {
                    server.serve(|asked| state.answer(asked));
                    std::thread::sleep(Duration::from_millis(2));
                }
                // the last requests: refused, the run is over
                server.serve(|asked| state.answer(asked));
                state.changes
            })
            .map_err(|e| SimError::Run(format!("cannot start the parameter thread: {e}")))?;
        match ready_rx.recv_timeout(Duration::from_secs(10)) {
            Ok(Ok(())) => {}
            Ok(Err(e)) => return Err(SimError::Run(format!("parameter service: {e}"))),
            Err(_) => {
                return Err(SimError::Run(
                    "the parameter thread did not start within 10 s".to_owned(),
                ));
            }
        }
        Ok(Tuning {
            shared,
            thread: Some(thread),
        })
    }

    /// The loop, before it publishes the state of a cycle: a change waiting to take effect
    /// at this cycle, if any. Allocation-free and wait-free (one atomic load when there is
    /// none; the change's mutex is free once the loop owns the change).
    pub fn take(&self) -> Option<Retune> {
        if self.shared.state.load(Ordering::Acquire) != PENDING
            || self
                .shared
                .state
                .compare_exchange(PENDING, TAKEN, Ordering::AcqRel, Ordering::Acquire)
                .is_err()
        {
            return None;
        }
        let got = self
            .shared
            .pending
            .try_lock()
            .ok()
            .and_then(|mut p| p.take());
        if got.is_none() {
            // cannot happen (the thread holds the mutex only outside PENDING); hand it back
            // as withdrawn: the thread answers that nothing changed
            self.shared.state.store(EMPTY, Ordering::Release);
        }
        got
    }

    /// The loop: the change [`Tuning::take`] gave is in force from `cycle` on.
    pub fn applied(&self, cycle: u64) {
        self.shared.applied_cycle.store(cycle, Ordering::Release);
        self.shared.state.store(APPLIED, Ordering::Release);
    }

    /// Ends the thread (the loop is over) and returns the changes that took effect.
    pub fn finish(mut self) -> Vec<ParamChange> {
        self.shared.ended.store(true, Ordering::Release);
        self.thread
            .take()
            .and_then(|t| t.join().ok())
            .unwrap_or_default()
    }
}

impl Drop for Tuning {
    fn drop(&mut self) {
        self.shared.ended.store(true, Ordering::Release);
    }
}

/// The thread's state.
struct Thread {
    tuner: Tuner,
    shared: Arc<Shared>,
    record: Option<PathBuf>,
    period: f64,
    changes: Vec<ParamChange>,
}

/// How long a change waits for the loop's next cycle before it is withdrawn (shorter than
/// `plant_sim param`'s default 10 s wait, so the client hears either way).
const GIVE_UP: Duration = Duration::from_secs(8);

fn refused(text: String) -> Answer {
    Answer {
        ok: false,
        cycle: 0,
        text,
    }
}

impl Thread {
    fn answer(&mut self, asked: &Asked) -> Answer {
        match asked.op {
            ipc_types::param_op::GET => match self.tuner.get(&asked.key) {
                Ok((key, value)) => Answer {
                    ok: true,
                    cycle: 0,
                    text: format!("{key} = {value}"),
                },
                Err(e) => refused(e),
            },
            _ => self.set(&asked.key, &asked.value),
        }
    }

    fn set(&mut self, key: &str, value: &str) -> Answer {
        if self.shared.ended.load(Ordering::Acquire) {
            return refused("the run is over: nothing was changed".to_owned());
        }
        let change = match self.tuner.check(key, value) {
            Ok(c) => c,
            Err(e) => {
                log(format_args!("parameter refused: {key} = {value}: {e}"));
                return refused(e);
            }
        };
        let retune = Retune::of(&change);
        match self.shared.pending.lock() {
            Ok(mut p) => *p = Some(retune),
            Err(_) => return refused("the plant's loop is gone".to_owned()),
        }
        self.shared.state.store(PENDING, Ordering::Release);
        // the loop takes it at its next cycle boundary; the client waits 10 s by default
        let give_up = Instant::now() + GIVE_UP;
        let cycle = loop {
            match self.shared.state.load(Ordering::Acquire) {
                APPLIED => {
                    let k = self.shared.applied_cycle.load(Ordering::Acquire);
                    self.shared.state.store(EMPTY, Ordering::Release);
                    break k;
                }
                PENDING
                    if (self.shared.ended.load(Ordering::Acquire) || Instant::now() > give_up)
                        && self
                            .shared
                            .state
                            .compare_exchange(PENDING, EMPTY, Ordering::AcqRel, Ordering::Acquire)
                            .is_ok() =>
                {
                    // withdrawn before the loop took it: nothing changed
                    if let Ok(mut p) = self.shared.pending.lock() {
                        *p = None;
                    }
                    return refused(format!(
                        "the run did not reach its next cycle within {} s (ended, or its controller is stopped): nothing was changed",
                        GIVE_UP.as_secs()
                    ));
                }
                // the loop could not take it (see `take`): nothing changed
                EMPTY => {
                    return refused(
                        "the plant's loop could not take the change: nothing was changed"
                            .to_owned(),
                    );
                }
                // TAKEN: the loop is putting it in force, within the cycle
                _ => std::thread::sleep(Duration::from_micros(200)),
            }
        };
        let previous_numbers = scenario::tuning::numbers(self.tuner.scenario(), change.key);
        if let Err(e) = self.tuner.commit(&change) {
            return refused(e);
        }
        let record = ParamChange {
            cycle,
            t: cycle as f64 * self.period,
            key: change.key.to_owned(),
            value: change.value.clone(),
            previous: change.previous.clone(),
            numbers: scenario::tuning::numbers(&change.scenario, change.key),
            previous_numbers,
        };
        log(format_args!(
            "parameter {} = {} (was {}) from cycle {cycle} (t = {:.3} s)",
            change.key, change.value, change.previous, record.t
        ));
        if let Some(dir) = &self.record
            && let Err(e) = recorder::append_param(dir, &record)
        {
            log(format_args!("warning: cannot record the change: {e}"));
        }
        self.changes.push(record);
        Answer {
            ok: true,
            cycle,
            text: format!(
                "{} = {} (was {}) from cycle {cycle}",
                change.key, change.value, change.previous
            ),
        }
    }
}
