//! The poller: what the bridge makes of the run's boards. Each poll reads the newest state,
//! command and status; a write already seen (same `seq` and stamp) is not sent again, and
//! each new one becomes one [`Sample`], encoded once for every client. The boards hold the
//! newest write only: a state or command replaced before the poller read it is not shown, and
//! is counted ([`SeqGaps`], [`Poller::replaced_states`]). It also follows the run: it waits for a live plant (a previous run's last state, left on a board some
//! process kept open, is not taken for it), and notices the run's end (see [`RunEnd`]).

use ipc_types::{CommandMsg, StateMsg, StatusMsg, WireGroup, flags, name_str, status_flags};
use std::time::{Duration, Instant};

/// Where the poller reads: a run's boards ([`link::watch::PairWatch`]), or a test's fake.
pub trait Boards {
    /// The newest state of the current protocol.
    fn state(&self) -> Option<StateMsg>;
    /// The newest command of the current protocol.
    fn command(&self) -> Option<CommandMsg>;
    /// The newest status of the current protocol.
    fn status(&self) -> Option<StatusMsg>;
}

impl Boards for link::watch::PairWatch {
    fn state(&self) -> Option<StateMsg> {
        link::watch::PairWatch::state(self)
    }
    fn command(&self) -> Option<CommandMsg> {
        link::watch::PairWatch::command(self)
    }
    fn status(&self) -> Option<StatusMsg> {
        link::watch::PairWatch::status(self)
    }
}

/// One message for the clients: its channel (an index into [`crate::LIVE_CHANNELS`]), its time
/// (`channels::time_ns` of the cycle's `t_k`) and its CDR encoding.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// Index into [`crate::LIVE_CHANNELS`] (the channel id is this + 1): 0 state, 1 command,
    /// 2 status.
    pub channel: usize,
    /// The cycle k it belongs to.
    pub cycle: u64,
    /// `t_k` in ns.
    pub log_time: u64,
    /// The message, CDR-encoded.
    pub cdr: Vec<u8>,
}

/// How a run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunEnd {
    /// Its plant said so: the status board's "ended" flag, or the plant's shutdown state
    /// (then at most [`SHUTDOWN_GRACE`] later, or when the plant's process is gone).
    Ended {
        /// The last cycle seen.
        cycle: u64,
    },
    /// The plant's process is gone without ending the run (killed).
    PlantGone {
        /// Its process id.
        pid: u32,
    },
}

/// What a poll found.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A live plant's first state: the bridge follows its run from here.
    Attached {
        /// The scenario's name.
        scenario: String,
        /// The group's name.
        group: &'static str,
        /// 1 / control period (Hz).
        rate_hz: f64,
        /// The plant's process id.
        plant_pid: u32,
        /// The cycle of that state.
        cycle: u64,
    },
    /// A new message for the clients.
    Sample(Sample),
    /// The run ended.
    Ended(RunEnd),
}

/// After the plant's shutdown state, how long the poller waits for the status board's
/// "ended" (the flight recorder's last figures) before it calls the run ended.
pub const SHUTDOWN_GRACE: Duration = Duration::from_secs(1);

/// How often the plant's process is checked (`kill(pid, 0)`).
const LIVENESS_EVERY: Duration = Duration::from_millis(100);

/// `(seq, stamp)`: one write.
type Id = (u64, u64);

/// Counts the writes of a board that a reader did not see, from the `seq` of those it did:
/// a state's `seq` is its cycle, one more each cycle, and a command's the cycle it answers,
/// so between two writes read with `seq` `a` and `b > a`, `b - a - 1` were replaced before
/// the reader came. A `seq` that does not grow (the same write again, or a smaller one: a
/// restarted plant counting from 0) counts nothing and is the new reference.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SeqGaps {
    last: Option<u64>,
    total: u64,
}

impl SeqGaps {
    /// None read yet.
    pub fn new() -> SeqGaps {
        SeqGaps::default()
    }

    /// Notes a write read with `seq`; returns how many were skipped since the last one read.
    pub fn read(&mut self, seq: u64) -> u64 {
        let gap = match self.last {
            Some(last) if seq > last => seq - last - 1,
            _ => 0,
        };
        self.last = Some(seq);
        self.total = self.total.saturating_add(gap);
        gap
    }

    /// All skipped so far.
    pub fn total(&self) -> u64 {
        self.total
    }
}

enum Phase {
    /// No live plant yet. `stale`: the state on the board when the poller came, if it was a
    /// finished run's.
    Waiting { stale: Option<Id> },
    /// Following plant `pid`; commands stamped before `since` (its first state's stamp)
    /// are a previous run's or before the bridge came.
    Live {
        pid: u32,
        since: u64,
        shutdown_at: Option<Instant>,
        last_check: Instant,
    },
    /// Reported.
    Over,
}

/// The board poller (see the module's documentation).
pub struct Poller<B: Boards> {
    boards: B,
    alive: fn(u32) -> bool,
    phase: Phase,
    seen_state: Option<Id>,
    seen_command: Option<Id>,
    seen_status: Option<Id>,
    /// States replaced on the board before they were read.
    state_gaps: SeqGaps,
    /// Commands replaced on the board before they were read.
    command_gaps: SeqGaps,
    /// The last cycle whose state was seen.
    last_cycle: u64,
    /// The last cycle as the run's end says it: the shutdown state's `seq` less one, or the
    /// status board's last `cycle`.
    end_cycle: u64,
    /// `(seq, t)` of recent states, for the commands' times.
    times: [(u64, f64); 64],
    period: f64,
}

impl<B: Boards> Poller<B> {
    /// A poller over `boards`; `alive(pid)` says whether a process exists
    /// ([`link::process_alive`]).
    pub fn new(boards: B, alive: fn(u32) -> bool) -> Poller<B> {
        let stale = boards
            .state()
            .filter(|s| s.flags & flags::SHUTDOWN != 0 || !alive(s.plant_pid))
            .map(|s| (s.seq, s.stamp_ns));
        Poller {
            boards,
            alive,
            phase: Phase::Waiting { stale },
            seen_state: None,
            seen_command: None,
            seen_status: None,
            state_gaps: SeqGaps::new(),
            command_gaps: SeqGaps::new(),
            last_cycle: 0,
            end_cycle: 0,
            times: [(u64::MAX, 0.0); 64],
            period: 0.0,
        }
    }

    /// Whether the run has been found (and not yet ended).
    pub fn attached(&self) -> bool {
        matches!(self.phase, Phase::Live { .. })
    }

    /// States of the run the plant replaced on the board before the poller read them (never
    /// shown): the gaps in the `seq` of the states read, the shutdown state's included.
    pub fn replaced_states(&self) -> u64 {
        self.state_gaps.total()
    }

    /// Commands replaced on the board before the poller read them, the same way (a cycle the
    /// controller did not answer leaves a gap too).
    pub fn replaced_commands(&self) -> u64 {
        self.command_gaps.total()
    }

    /// Reads the boards once; appends what it found to `out`.
    pub fn poll(&mut self, now: Instant, out: &mut Vec<Event>) {
        match self.phase {
            Phase::Waiting { stale } => self.wait_for_run(stale, now, out),
            Phase::Live { .. } => self.follow(now, out),
            Phase::Over => {}
        }
    }

    fn wait_for_run(&mut self, stale: Option<Id>, now: Instant, out: &mut Vec<Event>) {
        let Some(s) = self.boards.state() else { return };
        let id = (s.seq, s.stamp_ns);
        if Some(id) == stale || s.flags & flags::SHUTDOWN != 0 || !(self.alive)(s.plant_pid) {
            return;
        }
        let Some(group) = WireGroup::from_code(s.group) else {
            return;
        };
        self.phase = Phase::Live {
            pid: s.plant_pid,
            since: s.stamp_ns,
            shutdown_at: None,
            last_check: now,
        };
        out.push(Event::Attached {
            scenario: name_str(&s.scenario).to_owned(),
            group: group.name(),
            rate_hz: if s.control_period > 0.0 {
                1.0 / s.control_period
            } else {
                0.0
            },
            plant_pid: s.plant_pid,
            cycle: s.seq,
        });
        self.follow(now, out);
    }

    fn follow(&mut self, now: Instant, out: &mut Vec<Event>) {
        let Phase::Live {
            pid,
            since,
            shutdown_at,
            last_check,
        } = self.phase
        else {
            return;
        };
        let mut shutdown_at = shutdown_at;
        if let Some(s) = self.new_state() {
            if s.flags & flags::SHUTDOWN != 0 {
                // its seq is the last state's plus one (link::PlantEndpoint::shutdown)
                self.end_cycle = self.end_cycle.max(s.seq.saturating_sub(1));
                shutdown_at.get_or_insert(now);
            } else {
                self.offer_state(&s, out);
            }
        }
        if let Some(c) = self.new_command(since) {
            self.offer_command(&c, out);
        }
        let mut ended = false;
        if let Some(st) = self.new_status(pid) {
            ended = st.flags & status_flags::ENDED != 0;
            if ended {
                self.end_cycle = self.end_cycle.max(st.cycle);
            }
            out.push(Event::Sample(Sample {
                channel: 2,
                cycle: st.cycle,
                log_time: channels::time_ns(st.t),
                cdr: channels::status_message(&st).cdr(),
            }));
        }
        let mut last_check = last_check;
        let mut gone = false;
        if now.duration_since(last_check) >= LIVENESS_EVERY || shutdown_at.is_some() {
            last_check = now;
            gone = !(self.alive)(pid);
            if gone && !ended && shutdown_at.is_none() {
                // a last look: the plant may have ended the run just before it exited
                if let Some(s) = self.new_state().filter(|s| s.flags & flags::SHUTDOWN != 0) {
                    self.end_cycle = self.end_cycle.max(s.seq.saturating_sub(1));
                    shutdown_at = Some(now);
                }
                if let Some(st) = self.new_status(pid) {
                    ended = st.flags & status_flags::ENDED != 0;
                    if ended {
                        self.end_cycle = self.end_cycle.max(st.cycle);
                    }
                }
            }
        }
        let end = if ended
            || shutdown_at.is_some_and(|at| gone || now.duration_since(at) >= SHUTDOWN_GRACE)
        {
            Some(RunEnd::Ended {
                cycle: self.last_cycle.max(self.end_cycle),
            })
        } else if gone {
            Some(RunEnd::PlantGone { pid })
        } else {
            None
        };
        self.phase = match end {
            Some(e) => {
                out.push(Event::Ended(e));
                Phase::Over
            }
            None => Phase::Live {
                pid,
                since,
                shutdown_at,
                last_check,
            },
        };
    }

    /// The newest state if it was not seen yet.
    fn new_state(&mut self) -> Option<StateMsg> {
        let s = self.boards.state()?;
        let id = (s.seq, s.stamp_ns);
        (self.seen_state != Some(id)).then(|| {
            self.seen_state = Some(id);
            self.state_gaps.read(s.seq);
            s
        })
    }

    /// The newest command if it was not seen yet and was published after `since`.
    fn new_command(&mut self, since: u64) -> Option<CommandMsg> {
        let c = self.boards.command()?;
        let id = (c.seq, c.stamp_ns);
        (self.seen_command != Some(id) && c.stamp_ns > since).then(|| {
            self.seen_command = Some(id);
            self.command_gaps.read(c.seq);
            c
        })
    }

    /// The newest status of plant `pid` if it was not seen yet.
    fn new_status(&mut self, pid: u32) -> Option<StatusMsg> {
        let s = self.boards.status()?;
        let id = (s.seq, s.stamp_ns);
        (self.seen_status != Some(id) && s.plant_pid == pid).then(|| {
            self.seen_status = Some(id);
            s
        })
    }

    fn offer_state(&mut self, s: &StateMsg, out: &mut Vec<Event>) {
        let Some((n, m)) = WireGroup::from_code(s.group).map(WireGroup::dims) else {
            return;
        };
        self.times[(s.seq % 64) as usize] = (s.seq, s.t);
        self.period = s.control_period;
        self.last_cycle = s.seq;
        out.push(Event::Sample(Sample {
            channel: 0,
            cycle: s.seq,
            log_time: channels::time_ns(s.t),
            cdr: channels::state_message(s.seq, s, n, m).cdr(),
        }));
    }

    fn offer_command(&mut self, c: &CommandMsg, out: &mut Vec<Event>) {
        let Some((_, m)) = WireGroup::from_code(c.group).map(WireGroup::dims) else {
            return;
        };
        // the time of the state it answers: that state's t_k when it was seen, else
        // k·period (docs/wire.md: t_k = k·control_period)
        let (seq, t) = self.times[(c.seq % 64) as usize];
        let t = if seq == c.seq {
            t
        } else {
            c.seq as f64 * self.period
        };
        // the plant's receive time is the plant's to know: 0 here (docs/live.md)
        out.push(Event::Sample(Sample {
            channel: 1,
            cycle: c.seq,
            log_time: channels::time_ns(t),
            cdr: channels::command_message(c.seq, c, 0, m).cdr(),
        }));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::RefCell;

    #[derive(Default)]
    struct Fake {
        state: RefCell<Option<StateMsg>>,
        command: RefCell<Option<CommandMsg>>,
        status: RefCell<Option<StatusMsg>>,
    }

    impl Boards for &Fake {
        fn state(&self) -> Option<StateMsg> {
            *self.state.borrow()
        }
        fn command(&self) -> Option<CommandMsg> {
            *self.command.borrow()
        }
        fn status(&self) -> Option<StatusMsg> {
            *self.status.borrow()
        }
    }

    const PLANT: u32 = 4242;
    const DEAD: u32 = 4343;

    fn alive(pid: u32) -> bool {
        pid != DEAD
    }

    fn state(k: u64, pid: u32) -> StateMsg {
        let mut s = StateMsg::new(WireGroup::So3);
        s.seq = k;
        s.t = k as f64 * 0.001;
        s.control_period = 0.001;
        s.stamp_ns = 1_000_000 + k * 1_000_000;
        s.plant_pid = pid;
        s.v[0] = k as f64;
        s
    }

    fn command(k: u64) -> CommandMsg {
        let mut c = CommandMsg::new(WireGroup::So3);
        c.seq = k;
        c.stamp_ns = 1_000_000 + k * 1_000_000 + 20_000;
        c.tau[0] = -(k as f64);
        c
    }

    fn samples(events: &[Event]) -> Vec<(usize, u64)> {
        events
            .iter()
            .filter_map(|e| match e {
                Event::Sample(s) => Some((s.channel, s.cycle)),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn each_new_state_and_command_is_offered_once_with_the_states_time() {
        let fake = Fake::default();
        let mut p = Poller::new(&fake, alive);
        let mut out = Vec::new();
        let t0 = Instant::now();
        p.poll(t0, &mut out);
        assert!(out.is_empty() && !p.attached());
        *fake.state.borrow_mut() = Some(state(5, PLANT));
        p.poll(t0, &mut out);
        assert!(matches!(
            out[0],
            Event::Attached {
                cycle: 5,
                plant_pid: PLANT,
                ..
            }
        ));
        assert_eq!(samples(&out), [(0, 5)]);
        out.clear();
        // nothing new: nothing sent again
        p.poll(t0, &mut out);
        assert!(out.is_empty());
        *fake.command.borrow_mut() = Some(command(5));
        p.poll(t0, &mut out);
        p.poll(t0, &mut out);
        assert_eq!(samples(&out), [(1, 5)]);
        let Event::Sample(c) = &out[0] else { panic!() };
        assert_eq!(c.log_time, 5_000_000);
        assert_eq!(c.cdr, channels::command_message(5, &command(5), 0, 3).cdr());
        out.clear();
        *fake.state.borrow_mut() = Some(state(6, PLANT));
        *fake.command.borrow_mut() = Some(command(6));
        p.poll(t0, &mut out);
        assert_eq!(samples(&out), [(0, 6), (1, 6)]);
        let Event::Sample(s) = &out[0] else { panic!() };
        assert_eq!(
            s.cdr,
            channels::state_message(6, &state(6, PLANT), 3, 3).cdr()
        );
    }

    #[test]
    fn seq_gaps_count_the_writes_not_read_and_a_restart_counts_none() {
        let mut g = SeqGaps::new();
        assert_eq!(g.read(5), 0, "the first read has nothing before it");
        assert_eq!(g.read(6), 0);
        assert_eq!(g.read(9), 2, "7 and 8 replaced");
        assert_eq!(g.read(9), 0, "the same write again");
        assert_eq!(g.total(), 2);
        // a restarted plant counts from 0 again: no gap, no overflow, and its own gaps count
        assert_eq!(g.read(0), 0);
        assert_eq!(g.read(3), 2);
        assert_eq!(g.total(), 4);
        // the extremes: a seq that goes back from the top, and the largest jump
        let mut g = SeqGaps::new();
        assert_eq!(g.read(u64::MAX), 0);
        assert_eq!(g.read(0), 0);
        assert_eq!(g.read(u64::MAX), u64::MAX - 1);
        assert_eq!(g.read(1), 0);
        assert_eq!(g.read(u64::MAX), u64::MAX - 2);
        assert_eq!(g.total(), u64::MAX, "the total saturates");
    }

    #[test]
    fn the_poller_counts_states_and_commands_replaced_before_it_read_them() {
        let fake = Fake::default();
        let mut p = Poller::new(&fake, alive);
        let mut out = Vec::new();
        let t0 = Instant::now();
        // before the run is found, nothing counts: the first state read is the reference
        *fake.state.borrow_mut() = Some(state(10, PLANT));
        *fake.command.borrow_mut() = Some(command(10));
        p.poll(t0, &mut out);
        p.poll(t0, &mut out);
        assert_eq!((p.replaced_states(), p.replaced_commands()), (0, 0));
        // 11 and 12 replaced before the poller came back; the command of 11 too
        *fake.state.borrow_mut() = Some(state(13, PLANT));
        *fake.command.borrow_mut() = Some(command(12));
        p.poll(t0, &mut out);
        assert_eq!((p.replaced_states(), p.replaced_commands()), (2, 1));
        for k in 14..20 {
            *fake.state.borrow_mut() = Some(state(k, PLANT));
            *fake.command.borrow_mut() = Some(command(k));
            p.poll(t0, &mut out);
        }
        assert_eq!((p.replaced_states(), p.replaced_commands()), (2, 2));
        assert_eq!(
            samples(&out).iter().filter(|s| s.0 == 0).count(),
            8,
            "states 10, 13 and 14 to 19 shown"
        );
        // a plant restarted under the run's name (seq back to 0): no gap counted, no panic
        // (its clock's stamps are later than the first plant's)
        let later = |mut c: CommandMsg| {
            c.stamp_ns += 1_000_000_000_000;
            c
        };
        *fake.state.borrow_mut() = Some(state(0, PLANT));
        *fake.command.borrow_mut() = Some(later(command(0)));
        p.poll(t0, &mut out);
        *fake.state.borrow_mut() = Some(state(1, PLANT));
        *fake.command.borrow_mut() = Some(later(command(1)));
        p.poll(t0, &mut out);
        assert_eq!((p.replaced_states(), p.replaced_commands()), (2, 2));
        assert_eq!(
            samples(&out).iter().filter(|s| s.0 == 1).count(),
            10,
            "commands 10, 12 and 14 to 19, then 0 and 1 of the new plant"
        );
        // a missed last state: the shutdown state's seq (the last state's plus one) shows it
        let mut bye = state(4, PLANT);
        bye.flags |= flags::SHUTDOWN;
        *fake.state.borrow_mut() = Some(bye);
        p.poll(t0, &mut out);
        assert_eq!(p.replaced_states(), 4, "states 2 and 3 replaced");
    }

    #[test]
    fn a_finished_runs_leftovers_are_not_a_run() {
        let fake = Fake::default();
        let mut bye = state(9, PLANT);
        bye.flags |= flags::SHUTDOWN;
        *fake.state.borrow_mut() = Some(bye);
        *fake.command.borrow_mut() = Some(command(8));
        let mut p = Poller::new(&fake, alive);
        let mut out = Vec::new();
        p.poll(Instant::now(), &mut out);
        // a dead plant's state is not one either
        *fake.state.borrow_mut() = Some(state(10, DEAD));
        p.poll(Instant::now(), &mut out);
        assert!(out.is_empty() && !p.attached());
        // the next run: the old command (stamped before its first state) is not sent
        *fake.state.borrow_mut() = Some(state(100, PLANT));
        p.poll(Instant::now(), &mut out);
        assert!(p.attached());
        assert_eq!(samples(&out), [(0, 100)]);
    }

    #[test]
    fn the_run_ends_on_the_status_flag_the_shutdown_state_or_a_dead_plant() {
        let t0 = Instant::now();
        // the status board's "ended"
        let fake = Fake::default();
        *fake.state.borrow_mut() = Some(state(1, PLANT));
        let mut p = Poller::new(&fake, alive);
        let mut out = Vec::new();
        p.poll(t0, &mut out);
        let mut st = StatusMsg::new(WireGroup::So3, "seed");
        st.plant_pid = PLANT;
        st.seq = 1;
        st.cycle = 1;
        *fake.status.borrow_mut() = Some(st);
        p.poll(t0, &mut out);
        assert_eq!(samples(&out), [(0, 1), (2, 1)]);
        st.seq = 2;
        st.flags = status_flags::ENDED;
        *fake.status.borrow_mut() = Some(st);
        p.poll(t0, &mut out);
        assert_eq!(out.last(), Some(&Event::Ended(RunEnd::Ended { cycle: 1 })));
        assert!(!p.attached());
        // the shutdown state, then the grace period
        let fake = Fake::default();
        *fake.state.borrow_mut() = Some(state(1, PLANT));
        let mut p = Poller::new(&fake, alive);
        let mut out = Vec::new();
        p.poll(t0, &mut out);
        let mut bye = state(2, PLANT);
        bye.flags |= flags::SHUTDOWN;
        *fake.state.borrow_mut() = Some(bye);
        p.poll(t0, &mut out);
        assert!(p.attached(), "ended before the grace period");
        assert_eq!(samples(&out), [(0, 1)], "the shutdown state is not a state");
        p.poll(t0 + SHUTDOWN_GRACE, &mut out);
        assert_eq!(out.last(), Some(&Event::Ended(RunEnd::Ended { cycle: 1 })));
        // a last state the poller missed: the shutdown state says which it was
        let fake = Fake::default();
        *fake.state.borrow_mut() = Some(state(1, PLANT));
        let mut p = Poller::new(&fake, alive);
        let mut out = Vec::new();
        p.poll(t0, &mut out);
        let mut bye = state(9, PLANT);
        bye.flags |= flags::SHUTDOWN;
        *fake.state.borrow_mut() = Some(bye);
        p.poll(t0, &mut out);
        p.poll(t0 + SHUTDOWN_GRACE, &mut out);
        assert_eq!(out.last(), Some(&Event::Ended(RunEnd::Ended { cycle: 8 })));
        // a plant that dies without a word
        let fake = Fake::default();
        *fake.state.borrow_mut() = Some(state(1, DEAD + 1));
        let mut p = Poller::new(&fake, |pid| pid != DEAD + 1);
        let mut out = Vec::new();
        p.poll(t0, &mut out);
        assert!(!p.attached(), "a dead plant's state was taken for a run");
        let mut p = Poller::new(&fake, alive);
        p.poll(t0, &mut out);
        assert!(p.attached());
        p.alive = |_| false;
        p.poll(t0 + LIVENESS_EVERY, &mut out);
        assert_eq!(
            out.last(),
            Some(&Event::Ended(RunEnd::PlantGone { pid: DEAD + 1 }))
        );
    }
}
