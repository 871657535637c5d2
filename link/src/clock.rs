//! The clock of every timestamp and deadline: CLOCK_MONOTONIC in nanoseconds (one clock for
//! all processes on a machine), and a precise absolute-time sleep for real-time loops.

/// CLOCK_MONOTONIC in nanoseconds.
pub fn monotonic_ns() -> u64 {
    match nix::time::clock_gettime(nix::time::ClockId::CLOCK_MONOTONIC) {
        Ok(ts) => ts.tv_sec() as u64 * 1_000_000_000 + ts.tv_nsec() as u64,
        Err(_) => 0,
    }
}

/// The final stretch before a deadline that [`sleep_until`] spins instead of sleeping.
pub const SPIN_NS: u64 = 40_000;

/// Sleeps until `deadline` (CLOCK_MONOTONIC ns): an absolute-time `clock_nanosleep` to
/// [`SPIN_NS`] before it, then a spin. Never an iceoryx2 timeout (those round to whole
/// milliseconds). Returns at once for a deadline in the past.
pub fn sleep_until(deadline: u64) {
    if deadline > SPIN_NS {
        let early = deadline - SPIN_NS;
        if monotonic_ns() < early {
            let ts = nix::sys::time::TimeSpec::new(
                (early / 1_000_000_000) as i64,
                (early % 1_000_000_000) as i64,
            );
            // interrupted by a signal: the spin below finishes the wait
            let _ = nix::time::clock_nanosleep(
                nix::time::ClockId::CLOCK_MONOTONIC,
                nix::time::ClockNanosleepFlags::TIMER_ABSTIME,
                &ts,
            );
        }
    }
    while monotonic_ns() < deadline {
        std::hint::spin_loop();
    }
}

/// Asks the kernel to end this thread's sleeps when asked, not up to 50 µs later (the default
/// timer slack). Called by every transport when it opens.
pub fn precise_sleeps() {
    let _ = nix::sys::prctl::set_timerslack(1);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sleep_until_reaches_its_deadline_and_not_much_later() {
        precise_sleeps();
        let start = monotonic_ns();
        let deadline = start + 2_000_000;
        sleep_until(deadline);
        let woke = monotonic_ns();
        assert!(woke >= deadline);
        // generous: a loaded 2-core machine can preempt us
        assert!(
            woke - deadline < 50_000_000,
            "woke {} ns late",
            woke - deadline
        );
        let t = monotonic_ns();
        sleep_until(start); // in the past
        assert!(monotonic_ns() - t < 1_000_000);
    }
}
