//! The live view of a running pair (docs/architecture.md, "The flight recorder"):
//! `plant_sim monitor --name RUN` reads the run's `status` board (which the plant's
//! `plant::status::status_sink` publishes), and only that board, in a terminal UI (ratatui),
//! redrawn 10 times a second; it never touches the pair's own boards, so it cannot change the
//! loop's timing. It exits when the run ends, on `q`, Esc or Ctrl-C, and on SIGINT/SIGTERM.

use ipc_types::{StatusMsg, name_str, status_flags};
use link::status::StatusReader;
use link::{StopFlag, clock};
use plant::SimError;
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// `plant_sim monitor`'s options.
#[derive(Debug, Clone)]
pub struct MonitorOptions {
    /// The run to watch.
    pub run: String,
    /// How long to wait for the run to publish its first status.
    pub wait: Duration,
    /// One line per second on stdout instead of the terminal UI (for logs and scripts).
    pub plain: bool,
    /// Set by SIGINT/SIGTERM.
    pub stop: StopFlag,
}

/// How the monitor ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MonitorEnd {
    /// The run ended (its plant said so).
    RunEnded,
    /// The user quit (`q`, Esc, Ctrl-C, SIGINT/SIGTERM).
    Quit,
    /// The plant's process is gone without ending the run (killed).
    PlantGone,
}

/// What the screen shows, kept between redraws.
struct View {
    run: String,
    status: Option<StatusMsg>,
    /// Lyapunov values, one per new status (newest last).
    history: VecDeque<f64>,
    end: Option<MonitorEnd>,
}

const HISTORY: usize = 240;

impl View {
    fn update(&mut self, s: StatusMsg) {
        if self
            .status
            .is_none_or(|old| old.seq != s.seq || old.stamp_ns != s.stamp_ns)
        {
            if s.lyapunov.is_finite() {
                if self.history.len() == HISTORY {
                    self.history.pop_front();
                }
                self.history.push_back(s.lyapunov);
            }
            self.status = Some(s);
        }
    }

    /// The figures as text lines (the terminal UI and the plain mode share them).
    fn lines(&self) -> Vec<String> {
        let Some(s) = &self.status else {
            return vec![format!(
                "waiting for run `{}` to publish its status ...",
                self.run
            )];
        };
        let now = clock::monotonic_ns();
        let us = |ns: u64| ns as f64 / 1000.0;
        let target = if s.flags & status_flags::REALTIME != 0 {
            format!("target {} Hz", s.target_rate_hz)
        } else {
            "lockstep".to_owned()
        };
        // as of the newest status (the recorder publishes 20 times a second); a status
        // that stops coming is the plant's own silence, said as such
        let since = if s.last_command_ns == 0 {
            "none yet".to_owned()
        } else {
            format!(
                "{:.1} ms ago",
                s.stamp_ns.saturating_sub(s.last_command_ns) as f64 / 1e6
            )
        };
        let age = now.saturating_sub(s.stamp_ns);
        let since = if age > 500_000_000 && s.flags & status_flags::ENDED == 0 {
            format!(
                "{since} (no status from the plant for {:.1} s)",
                age as f64 / 1e9
            )
        } else {
            since
        };
        let mut lines = vec![
            format!(
                "t            {:.3} s (cycle {}), scenario {}, plant pid {}",
                s.t,
                s.cycle,
                name_str(&s.scenario),
                s.plant_pid
            ),
            format!(
                "rate         {:.0} Hz: cycles in the last second ({target})",
                s.rate_hz
            ),
            format!(
                "round trip   p50 {:.1} us   p99 {:.1} us   max {:.1} us   (last second)",
                us(s.rtt_p50_ns),
                us(s.rtt_p99_ns),
                us(s.rtt_max_ns)
            ),
            format!("misses       {}", s.misses),
            format!(
                "safe mode    {} (entered {} times)",
                if s.flags & status_flags::SAFE_MODE != 0 {
                    "ON: damping only"
                } else {
                    "off"
                },
                s.safe_mode_entries
            ),
            format!("last command {since}"),
            format!("Lyapunov L   {:.6e}", s.lyapunov),
        ];
        if s.flags & status_flags::DETECTING != 0 {
            let newest = match s.last_detected.checked_sub(1) {
                None => "none".to_owned(),
                Some(j) => format!(
                    "actuator {j} {} ({:.3})",
                    ipc_types::detected_kind_name(s.last_detected_kind),
                    s.last_detected_value
                ),
            };
            lines.push(format!(
                "detector     {} found, newest {newest}; {} alarms",
                s.detections, s.alarms
            ));
        }
        lines.extend(failsafe_line(s));
        lines
    }

    /// The sparkline's bars for a panel `width` columns wide: log10(L) mapped onto 1..=100
    /// over the shown range, exactly `width` bars once there is any history. With more
    /// values than columns the newest `width` are shown; with fewer, each value is stretched
    /// over several columns, so the history always fills the panel's width.
    fn bars(&self, width: usize) -> (Vec<u64>, f64, f64) {
        let shown = self.history.len().min(width);
        let logs: Vec<f64> = self
            .history
            .iter()
            .skip(self.history.len() - shown)
            .map(|l| l.max(1e-300).log10())
            .collect();
        let lo = logs.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = logs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let span = (hi - lo).max(1e-9);
        let bar = |x: f64| 1 + ((x - lo) / span * 99.0).round() as u64;
        let bars = if logs.is_empty() {
            Vec::new()
        } else {
            (0..width)
                .map(|c| bar(logs[c * logs.len() / width]))
                .collect()
        };
        (bars, lo, hi)
    }
}

/// Watches run `opts.run` until it ends or the user quits.
pub fn monitor(opts: &MonitorOptions) -> Result<MonitorEnd, SimError> {
    link::check_run_name(&opts.run)?;
    let reader = StatusReader::open(&opts.run)?;
    let mut view = View {
        run: opts.run.clone(),
        status: None,
        history: VecDeque::with_capacity(HISTORY),
        end: None,
    };
    let started = Instant::now();
    // a status that had ended, or whose plant was dead, when the monitor came is a previous
    // run's: wait for a new one
    let stale = reader
        .latest()
        .filter(|s| s.flags & status_flags::ENDED != 0 || !link::process_alive(s.plant_pid))
        .map(|s| (s.plant_pid, s.stamp_ns));
    let mut ui = if opts.plain {
        None
    } else {
        Some(ratatui::try_init().map_err(|e| {
            SimError::Run(format!(
                "monitor: cannot take the terminal ({e}); use --plain for line output"
            ))
        })?)
    };
    let mut last_line = Instant::now() - Duration::from_secs(1);
    let result = loop {
        if let Some(s) = reader
            .latest()
            .filter(|s| stale != Some((s.plant_pid, s.stamp_ns)))
        {
            view.update(s);
        }
        if let Err(e) = view.watch_end(started, opts) {
            break Err(e);
        }
        if let Err(e) = present(&mut ui, &mut view, &mut last_line) {
            break Err(e);
        }
        if let Some(end) = view.end {
            break Ok(end);
        }
    };
    if ui.is_some() {
        ratatui::restore();
    }
    if let Ok(end) = &result {
        for line in view.lines() {
            println!("{line}");
        }
        println!(
            "monitor: {}",
            match end {
                MonitorEnd::RunEnded => "the run ended",
                MonitorEnd::Quit => "quit",
                MonitorEnd::PlantGone =>
                    "the plant's process is gone (the run did not end cleanly)",
            }
        );
    }
    result
}

/// Whether `q`, Esc or Ctrl-C was pressed within `wait` (in raw mode Ctrl-C is a key).
impl View {
    /// Notes how the run ended (its plant said so, or is gone), or that the user asked to
    /// quit; fails when no status came within `opts.wait`.
    fn watch_end(&mut self, started: Instant, opts: &MonitorOptions) -> Result<(), SimError> {
        if let Some(s) = self.status {
            if s.flags & status_flags::ENDED != 0 {
                self.end = Some(MonitorEnd::RunEnded);
            } else if !link::process_alive(s.plant_pid) {
                self.end = Some(MonitorEnd::PlantGone);
            }
        } else if started.elapsed() > opts.wait {
            return Err(SimError::Run(format!(
                "monitor: run `{}` published no status within {:.0} s (is it running? a run started with --no-record publishes none)",
                opts.run,
                opts.wait.as_secs_f64()
            )));
        }
        if opts.stop.requested().is_some() {
            self.end = Some(MonitorEnd::Quit);
        }
        Ok(())
    }
}

/// Draws the view (and reads the quit key) in the terminal UI, or with `--plain` prints
/// it as one line a second; either way waits about 100 ms.
fn present(
    ui: &mut Option<ratatui::DefaultTerminal>,
    view: &mut View,
    last_line: &mut Instant,
) -> Result<(), SimError> {
    match ui {
        Some(term) => {
            term.draw(|f| draw(f, view))
                .map_err(|e| SimError::Run(format!("monitor: cannot draw: {e}")))?;
            if view.end.is_none() && quit_key(Duration::from_millis(100)) {
                view.end = Some(MonitorEnd::Quit);
            }
        }
        None => {
            if last_line.elapsed() >= Duration::from_secs(1) || view.end.is_some() {
                *last_line = Instant::now();
                println!("{}", view.lines().join(" | "));
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }
    Ok(())
}

fn quit_key(wait: Duration) -> bool {
    use ratatui::crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};
    let until = Instant::now() + wait;
    loop {
        let left = until.saturating_duration_since(Instant::now());
        if !event::poll(left).unwrap_or(false) {
            return false;
        }
        if let Ok(Event::Key(k)) = event::read()
            && k.kind == KeyEventKind::Press
            && (matches!(k.code, KeyCode::Char('q') | KeyCode::Esc)
                || (k.code == KeyCode::Char('c') && k.modifiers.contains(KeyModifiers::CONTROL)))
        {
            return true;
        }
    }
}

fn draw(f: &mut ratatui::Frame, view: &View) {
    use ratatui::layout::{Constraint, Layout};
    use ratatui::widgets::{Block, Borders, Paragraph, Sparkline};
    let lines = view.lines();
    let [top, spark, help] = Layout::vertical([
        Constraint::Length(lines.len() as u16 + 2),
        Constraint::Min(4),
        Constraint::Length(1),
    ])
    .areas(f.area());
    let title = format!(" eqtrack monitor: run `{}` ", view.run);
    f.render_widget(
        Paragraph::new(lines.join("\n")).block(Block::default().borders(Borders::ALL).title(title)),
        top,
    );
    // the panel's inside: its width less the two border columns
    let (bars, lo, hi) = view.bars(usize::from(spark.width.saturating_sub(2)));
    let title = if bars.is_empty() {
        " Lyapunov value L (log scale): no command yet ".to_owned()
    } else {
        format!(
            " Lyapunov value L, log scale, last {} updates: 1e{lo:.1} .. 1e{hi:.1} ",
            view.history.len().min(bars.len())
        )
    };
    f.render_widget(
        Sparkline::default()
            .block(Block::default().borders(Borders::ALL).title(title))
            .data(&bars)
            .max(100),
        spark,
    );
    let state = match view.end {
        Some(MonitorEnd::RunEnded) => "the run ended",
        Some(MonitorEnd::PlantGone) => "the plant is gone",
        _ => "q: quit",
    };
    f.render_widget(Paragraph::new(state), help);
}

/// The failsafe manager's line, when the controller runs it: the engaged action (upper case)
/// and its cause, or `nominal`, and the transitions so far.
fn failsafe_line(s: &ipc_types::StatusMsg) -> Option<String> {
    if s.flags & status_flags::SUPERVISED == 0 {
        return None;
    }
    let (action, cause) = ipc_types::failsafe_names(s.failsafe);
    let what = if cause.is_empty() {
        action.to_owned()
    } else {
        format!("{} ({cause})", action.to_uppercase())
    };
    Some(format!(
        "failsafe     {what}; {} transitions",
        s.failsafe_transitions
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(values: impl Iterator<Item = f64>) -> View {
        View {
            run: "t".to_owned(),
            status: None,
            history: values.collect(),
            end: None,
        }
    }

    #[test]
    fn the_history_fills_the_panel_width_whatever_its_length() {
        // 30 values in a 106-column panel: stretched over all of it, oldest left, newest right
        let v = view((0..30).map(|i| 10f64.powi(-i)));
        let (bars, lo, hi) = v.bars(106);
        assert_eq!(bars.len(), 106);
        assert_eq!((bars[0], bars[105]), (100, 1));
        assert!(bars.windows(2).all(|w| w[0] >= w[1]), "{bars:?}");
        assert_eq!((lo, hi), (-29.0, 0.0));
        // 240 values: the newest 106, one per column
        let v = view((0..240).map(|i| 10f64.powi(-i)));
        let (bars, lo, hi) = v.bars(106);
        assert_eq!(bars.len(), 106);
        assert_eq!((lo, hi), (-239.0, -134.0));
        assert_eq!((bars[0], bars[105]), (100, 1));
        // none yet, or no room
        assert!(view(std::iter::empty()).bars(106).0.is_empty());
        assert!(view((0..5).map(f64::from)).bars(0).0.is_empty());
    }

    #[test]
    fn the_detectors_line_shows_only_when_it_runs() {
        let mut v = view(std::iter::empty());
        let mut s = ipc_types::StatusMsg::new(ipc_types::WireGroup::Se3, "rov");
        v.status = Some(s);
        assert!(!v.lines().iter().any(|l| l.starts_with("detector")));
        let mut c = ipc_types::CommandMsg::new(ipc_types::WireGroup::Se3);
        c.flags = ipc_types::flags::DETECTING;
        (c.detected, c.detected_kind, c.detected_value, c.alarms) = (7, 2, -20.0, 1);
        s.note_detection(&c);
        v.status = Some(s);
        let lines = v.lines();
        let line = lines.iter().find(|l| l.starts_with("detector")).unwrap();
        assert_eq!(
            line,
            "detector     1 found, newest actuator 6 stuck (-20.000); 1 alarms"
        );
    }

    #[test]
    fn the_failsafes_line_shows_the_action_and_counts_the_transitions() {
        let mut v = view(std::iter::empty());
        let mut s = ipc_types::StatusMsg::new(ipc_types::WireGroup::Se3, "rov");
        let mut c = ipc_types::CommandMsg::new(ipc_types::WireGroup::Se3);
        // no manager: no line, whatever the word
        c.failsafe = 5 | 3 << 4 | 1 << 10;
        s.note_failsafe(&c);
        v.status = Some(s);
        assert!(!v.lines().iter().any(|l| l.starts_with("failsafe")));
        c.flags = ipc_types::flags::SUPERVISED;
        c.failsafe = 0;
        s.note_failsafe(&c);
        c.failsafe = 5 | 3 << 4 | 1 << 10;
        s.note_failsafe(&c);
        s.note_failsafe(&c);
        v.status = Some(s);
        let lines = v.lines();
        let line = lines.iter().find(|l| l.starts_with("failsafe")).unwrap();
        assert_eq!(line, "failsafe     SURFACE (actuators); 1 transitions");
    }
}
