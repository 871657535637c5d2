//! The plant's deadline policy (docs/architecture.md, "The deadline policy"): a pure state
//! machine — no clock, no IPC — that decides, for each tick, whether the controller's command
//! arrived in time:
//!
//! * **Fresh**: the command for tick k arrived by the tick's deadline: apply it; the miss
//!   counter resets and safe mode, if on, ends.
//! * **Held**: no such command (none, one for an older tick, or one after the deadline): hold
//!   the previous torque.
//! * **Safe**: the N-th consecutive miss and every one after it: apply the safe-mode torque
//!   (`eqtrack_controller::law::safe_mode_torque`) until the next fresh command.

/// A command as it arrived: the tick it answers and when it arrived (CLOCK_MONOTONIC ns).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Arrival {
    /// The command's sequence number.
    pub seq: u64,
    /// When it was received.
    pub at_ns: u64,
}

pub use ipc_types::Decision;

/// A change of mode, for the log.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Transition {
    /// Safe mode started at this tick (after `miss_limit` consecutive misses).
    EnteredSafe,
    /// A fresh command ended safe mode.
    LeftSafe,
}

/// One tick's outcome.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Step {
    /// What to apply.
    pub decision: Decision,
    /// A change of mode at this tick, if any.
    pub transition: Option<Transition>,
    /// Consecutive misses up to and including this tick.
    pub misses_in_row: u32,
}

impl Step {
    /// What a lockstep plant applies at every tick: the command it waited for. Lockstep has
    /// no deadline, so it never asks the policy; nothing is held and safe mode never starts
    /// (docs/architecture.md, "One control cycle").
    pub const LOCKSTEP: Step = Step {
        decision: Decision::Fresh,
        transition: None,
        misses_in_row: 0,
    };
}

/// The policy and its counters.
///
/// Data in, decision out: no clock and no IPC, so each transition is a line of code to test.
///
/// ```
/// use link::{Arrival, DeadlinePolicy, Decision, Transition};
///
/// let mut policy = DeadlinePolicy::new(3);
/// let deadline = |k: u64| (k + 1) * 1_000_000; // 1 kHz
/// let on_time = |k: u64| Some(Arrival { seq: k, at_ns: deadline(k) - 200_000 });
/// assert_eq!(policy.step(0, deadline(0), on_time(0)).decision, Decision::Fresh);
/// // the controller falls silent: held, held, then safe mode at the third miss
/// assert_eq!(policy.step(1, deadline(1), None).decision, Decision::Held);
/// assert_eq!(policy.step(2, deadline(2), None).decision, Decision::Held);
/// let third = policy.step(3, deadline(3), None);
/// assert_eq!((third.decision, third.transition), (Decision::Safe, Some(Transition::EnteredSafe)));
/// // a command for an older tick does not count; the next fresh one ends safe mode
/// assert_eq!(policy.step(4, deadline(4), on_time(3)).decision, Decision::Safe);
/// let back = policy.step(5, deadline(5), on_time(5));
/// assert_eq!(back.transition, Some(Transition::LeftSafe));
/// assert_eq!((policy.misses(), policy.safe_entries()), (4, 1));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeadlinePolicy {
    miss_limit: u32,
    in_row: u32,
    safe: bool,
    misses: u64,
    late: u64,
    safe_entries: u64,
    safe_cycles: u64,
}

impl DeadlinePolicy {
    /// A policy that enters safe mode at the `miss_limit`-th consecutive miss (at least 1).
    pub fn new(miss_limit: u32) -> DeadlinePolicy {
        DeadlinePolicy {
            miss_limit: miss_limit.max(1),
            in_row: 0,
            safe: false,
            misses: 0,
            late: 0,
            safe_entries: 0,
            safe_cycles: 0,
        }
    }

    /// Decides tick `k`, whose deadline is `deadline_ns`, given the command that arrived for
    /// it (if any). A command for another tick, or one that arrived after the deadline, is
    /// ignored (counted as late).
    pub fn step(&mut self, k: u64, deadline_ns: u64, arrival: Option<Arrival>) -> Step {
        let fresh = match arrival {
            Some(a) if a.seq == k && a.at_ns <= deadline_ns => true,
            Some(_) => {
                self.late += 1;
                false
            }
            None => false,
        };
        let mut transition = None;
        let decision = if fresh {
            self.in_row = 0;
            if self.safe {
                self.safe = false;
                transition = Some(Transition::LeftSafe);
            }
            Decision::Fresh
        } else {
            self.misses += 1;
            self.in_row = self.in_row.saturating_add(1);
            if self.in_row >= self.miss_limit && !self.safe {
                self.safe = true;
                self.safe_entries += 1;
                transition = Some(Transition::EnteredSafe);
            }
            if self.safe {
                self.safe_cycles += 1;
                Decision::Safe
            } else {
                Decision::Held
            }
        };
        Step {
            decision,
            transition,
            misses_in_row: self.in_row,
        }
    }

    /// Whether safe mode is on.
    pub fn in_safe_mode(&self) -> bool {
        self.safe
    }

    /// Ticks without a fresh command.
    pub fn misses(&self) -> u64 {
        self.misses
    }

    /// Commands ignored because they answered another tick or came after the deadline.
    pub fn late(&self) -> u64 {
        self.late
    }

    /// Times safe mode was entered.
    pub fn safe_entries(&self) -> u64 {
        self.safe_entries
    }

    /// Ticks spent in safe mode.
    pub fn safe_cycles(&self) -> u64 {
        self.safe_cycles
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: u64 = 1_000_000; // a 1 ms period on the fake clock

    /// Tick k's deadline on a fake clock starting at 0.
    fn deadline(k: u64) -> u64 {
        (k + 1) * P
    }

    fn on_time(k: u64) -> Option<Arrival> {
        Some(Arrival {
            seq: k,
            at_ns: deadline(k) - P / 2,
        })
    }

    #[test]
    fn a_command_on_time_is_fresh() {
        let mut p = DeadlinePolicy::new(3);
        for k in 0..5 {
            let s = p.step(k, deadline(k), on_time(k));
            assert_eq!(s.decision, Decision::Fresh);
            assert_eq!(s.transition, None);
        }
        assert_eq!((p.misses(), p.late(), p.safe_entries()), (0, 0, 0));
        // exactly at the deadline still counts
        let s = p.step(
            5,
            deadline(5),
            Some(Arrival {
                seq: 5,
                at_ns: deadline(5),
            }),
        );
        assert_eq!(s.decision, Decision::Fresh);
    }

    #[test]
    fn a_miss_holds_and_safe_mode_starts_at_exactly_the_nth_miss() {
        let mut p = DeadlinePolicy::new(3);
        assert_eq!(p.step(0, deadline(0), on_time(0)).decision, Decision::Fresh);
        let s1 = p.step(1, deadline(1), None);
        let s2 = p.step(2, deadline(2), None);
        assert_eq!((s1.decision, s1.misses_in_row), (Decision::Held, 1));
        assert_eq!((s2.decision, s2.misses_in_row), (Decision::Held, 2));
        assert!(!p.in_safe_mode());
        let s3 = p.step(3, deadline(3), None);
        assert_eq!(s3.decision, Decision::Safe);
        assert_eq!(s3.transition, Some(Transition::EnteredSafe));
        assert!(p.in_safe_mode());
        assert_eq!((p.misses(), p.safe_entries(), p.safe_cycles()), (3, 1, 1));
    }

    #[test]
    fn safe_mode_stays_while_misses_continue() {
        let mut p = DeadlinePolicy::new(2);
        p.step(0, deadline(0), None);
        assert_eq!(
            p.step(1, deadline(1), None).transition,
            Some(Transition::EnteredSafe)
        );
        for k in 2..10 {
            let s = p.step(k, deadline(k), None);
            assert_eq!(s.decision, Decision::Safe);
            assert_eq!(s.transition, None, "entered once only");
        }
        assert_eq!((p.safe_entries(), p.safe_cycles(), p.misses()), (1, 9, 10));
    }

    #[test]
    fn the_first_fresh_command_recovers() {
        let mut p = DeadlinePolicy::new(1);
        assert_eq!(p.step(0, deadline(0), None).decision, Decision::Safe);
        let s = p.step(1, deadline(1), on_time(1));
        assert_eq!(s.decision, Decision::Fresh);
        assert_eq!(s.transition, Some(Transition::LeftSafe));
        assert!(!p.in_safe_mode());
        // and the miss counter starts again from zero
        assert_eq!(p.step(2, deadline(2), None).decision, Decision::Safe);
        assert_eq!(p.safe_entries(), 2);
    }

    #[test]
    fn a_late_command_for_an_old_sequence_number_is_ignored() {
        let mut p = DeadlinePolicy::new(3);
        p.step(0, deadline(0), on_time(0));
        // command 0 shows up again during tick 1 (a slow controller): not tick 1's command
        let old = Some(Arrival {
            seq: 0,
            at_ns: deadline(1) - 10,
        });
        let s = p.step(1, deadline(1), old);
        assert_eq!(s.decision, Decision::Held);
        assert_eq!(p.late(), 1);
        // the right command after its deadline is a miss too
        let after = Some(Arrival {
            seq: 2,
            at_ns: deadline(2) + 1,
        });
        assert_eq!(p.step(2, deadline(2), after).decision, Decision::Held);
        assert_eq!((p.late(), p.misses()), (2, 2));
        // and three misses in a row, however they came, start safe mode
        let s3 = p.step(3, deadline(3), None);
        assert_eq!(s3.transition, Some(Transition::EnteredSafe));
    }

    #[test]
    fn a_miss_limit_of_zero_means_one() {
        let mut p = DeadlinePolicy::new(0);
        assert_eq!(p.step(0, deadline(0), None).decision, Decision::Safe);
    }
}
