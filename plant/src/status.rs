//! The run's live figures (docs/architecture.md, "The flight recorder"): on the plant's
//! flight-recorder thread, [`status_sink`] turns the records into the figures `plant_sim
//! monitor` shows (rate, round-trip percentiles over the last second, misses, safe mode, the
//! Lyapunov value, the newest command) and publishes them about 20 times a second on the run's
//! `status` board ([`link::status`]). The reader is the flight tools' monitor.

use ipc_types::{StatusMsg, status_flags};
use link::status::StatusWriter;
use link::{Decision, clock};
use recorder::{Header, Record, SinkFactory, StatusSink};
use std::collections::VecDeque;

/// How often the recorder thread publishes the status (ns).
const PUBLISH_EVERY_NS: u64 = 50_000_000;
/// The window of "the last second" (ns).
const WINDOW_NS: u64 = 1_000_000_000;

/// The flight recorder's status publisher for run `run` (opened on the recorder thread).
pub fn status_sink(run: &str, header: &Header) -> SinkFactory {
    let run = run.to_owned();
    let mut msg = StatusMsg::new(
        ipc_types::WireGroup::from_code(header.group).unwrap_or(ipc_types::WireGroup::So3),
        &header.scenario,
    );
    msg.target_rate_hz = header.rate_hz;
    msg.plant_pid = header.plant_pid;
    if header.realtime {
        msg.flags |= status_flags::REALTIME;
    }
    // two seconds of cycles at the nominal rate
    let capacity = ((2.0 / header.control_period) as usize).clamp(1024, 1 << 18);
    Box::new(move || match StatusWriter::open(&run) {
        Ok(writer) => Some(Box::new(LiveStatus {
            writer,
            msg,
            window: VecDeque::with_capacity(capacity),
            sorted: Vec::with_capacity(capacity),
            last_publish: 0,
            last_decision: Decision::Fresh,
        }) as Box<dyn StatusSink>),
        Err(e) => {
            eprintln!("plant_sim: no live status for monitors (recording goes on): {e}");
            None
        }
    })
}

/// The live figures, kept on the recorder thread.
struct LiveStatus {
    writer: StatusWriter,
    msg: StatusMsg,
    /// `(state published, round trip)` of the cycles of the last second (round trip 0:
    /// no command in time).
    window: VecDeque<(u64, u64)>,
    sorted: Vec<u64>,
    last_publish: u64,
    last_decision: Decision,
}

impl StatusSink for LiveStatus {
    fn record(&mut self, r: &Record) {
        let m = &mut self.msg;
        m.cycle = r.cycle;
        m.t = r.state.t;
        if r.decision != Decision::Fresh {
            m.misses += 1;
        }
        if r.decision == Decision::Safe && self.last_decision != Decision::Safe {
            m.safe_mode_entries += 1;
        }
        self.last_decision = r.decision;
        if r.decision == Decision::Safe {
            m.flags |= status_flags::SAFE_MODE;
        } else {
            m.flags &= !status_flags::SAFE_MODE;
        }
        let published = r.state.stamp_ns;
        let mut rtt = 0;
        if let Some((c, received)) = &r.command {
            m.lyapunov = c.lyapunov;
            m.last_command_ns = *received;
            m.note_detection(c);
            m.note_failsafe(c);
            // the first command answers the connection, not a timed cycle
            if r.cycle > 0 {
                rtt = received.saturating_sub(published).max(1);
            }
        }
        // the writer thread may allocate: a loop faster than its nominal rate (lockstep)
        // grows the window
        self.window.push_back((published, rtt));
        while self
            .window
            .front()
            .is_some_and(|(p, _)| *p + WINDOW_NS <= published)
        {
            self.window.pop_front();
        }
    }

    fn tick(&mut self) {
        let now = clock::monotonic_ns();
        if now.saturating_sub(self.last_publish) < PUBLISH_EVERY_NS {
            return;
        }
        self.last_publish = now;
        self.publish();
    }

    fn end(&mut self) {
        self.msg.flags |= status_flags::ENDED;
        self.publish();
    }
}

impl LiveStatus {
    fn publish(&mut self) {
        self.sorted.clear();
        self.sorted
            .extend(self.window.iter().map(|w| w.1).filter(|r| *r > 0));
        self.sorted.sort_unstable();
        let q = |f: f64| match self.sorted.len() {
            0 => 0,
            n => self.sorted[((f * (n - 1) as f64).round() as usize).min(n - 1)],
        };
        let m = &mut self.msg;
        (m.rtt_p50_ns, m.rtt_p99_ns, m.rtt_max_ns) = (q(0.5), q(0.99), q(1.0));
        // the cycles of the last second, counted (in the first second of a run: so far)
        m.rate_hz = self.window.len() as f64;
        self.writer.publish(m);
    }
}
