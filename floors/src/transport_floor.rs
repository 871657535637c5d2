//! `transport_floor ping --wake spin|event --rate-hz F --duration S [--name N]`
//!
//! The transport floor of `plant_sim bench-loop`: the least two processes can do to exchange
//! the pair's messages over iceoryx2 at the loop's pace, written with nothing but iceoryx2
//! (and the clock), no project code beyond the message layout (`ipc_types::StateMsg`,
//! `ipc_types::CommandMsg`). It uses the same mechanism as the pair: one blackboard entry per
//! direction, written with a copy, and an event service per direction when the waiting side
//! sleeps. `ping` (the plant's role) creates the services, starts `pong` (the controller's
//! role; this same executable), and at every tick `t0 + k/F` (an absolute-time
//! `clock_nanosleep` to 40 µs before it, then a spin — the plant's pacing) writes state k and
//! waits for the reply carrying k. It prints one line:
//!
//! `floor wake=spin rate_hz=1000 cycles=5000 p50_us=.. p99_us=.. p99_9_us=.. max_us=.. missed=..`
//!
//! where the round trip is state written → reply seen, like the pair's, and `missed` counts
//! replies not seen by the next tick; `leg1_p50_us` (state written → seen by pong) and
//! `leg2_p50_us` (reply stamped → seen by ping) split it as the pair's summary does.
#![cfg_attr(not(test), warn(clippy::too_many_lines))]
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;
use ipc_types::{CommandMsg, StateMsg};
use std::process::{Command, ExitCode};
use std::time::Duration;

type Board = iceoryx2::service::port_factory::blackboard::PortFactory<ipc::Service, u32>;
type Events = iceoryx2::service::port_factory::event::PortFactory<ipc::Service>;

const SPIN_NS: u64 = 40_000;

fn now_ns() -> u64 {
    nix::time::clock_gettime(nix::time::ClockId::CLOCK_MONOTONIC).map_or(0, |ts| {
        ts.tv_sec() as u64 * 1_000_000_000 + ts.tv_nsec() as u64
    })
}

fn sleep_until(deadline: u64) {
    let early = deadline.saturating_sub(SPIN_NS);
    if now_ns() < early {
        let ts = nix::sys::time::TimeSpec::new(
            (early / 1_000_000_000) as i64,
            (early % 1_000_000_000) as i64,
        );
        let _ = nix::time::clock_nanosleep(
            nix::time::ClockId::CLOCK_MONOTONIC,
            nix::time::ClockNanosleepFlags::TIMER_ABSTIME,
            &ts,
        );
    }
    while now_ns() < deadline {
        std::hint::spin_loop();
    }
}

struct Args {
    role: String,
    spin: bool,
    rate_hz: f64,
    duration: f64,
    name: String,
}

fn args() -> Result<Args, String> {
    let mut a = Args {
        role: String::new(),
        spin: true,
        rate_hz: 1000.0,
        duration: 1.0,
        name: format!("floor{}", std::process::id()),
    };
    let mut it = std::env::args().skip(1);
    a.role = it.next().unwrap_or_default();
    while let Some(key) = it.next() {
        let value = it.next().ok_or(format!("{key}: missing value"))?;
        let num = || {
            value
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite() && *x > 0.0)
                .ok_or(format!("{key}: `{value}` is not a positive number"))
        };
        match key.as_str() {
            "--wake" if value == "spin" || value == "event" => a.spin = value == "spin",
            "--rate-hz" => a.rate_hz = num()?,
            "--duration" => a.duration = num()?,
            "--name" => a.name = value,
            _ => return Err(format!("unknown argument `{key} {value}`")),
        }
    }
    if a.role != "ping" && a.role != "pong" {
        return Err("usage: transport_floor ping|pong --wake spin|event --rate-hz F --duration S [--name N]".into());
    }
    Ok(a)
}

fn name(s: &str) -> Result<ServiceName, String> {
    s.try_into().map_err(|e| format!("{s}: {e:?}"))
}

/// The four services: ping's board, pong's board, ping's events, pong's events.
fn services(
    node: &Node<ipc::Service>,
    run: &str,
    create: bool,
) -> Result<(Board, Board, Events, Events), String> {
    let board = |suffix: &str, empty_state: bool| -> Result<Board, String> {
        let b = node.service_builder(&name(&format!("eqtrack-floor/{run}/{suffix}"))?);
        if create {
            let c = b.blackboard_creator::<u32>();
            let c = if empty_state {
                c.add::<StateMsg>(0, StateMsg::new(ipc_types::WireGroup::So3))
            } else {
                c.add::<CommandMsg>(0, CommandMsg::new(ipc_types::WireGroup::So3))
            };
            c.create().map_err(|e| format!("{suffix}: {e:?}"))
        } else {
            b.blackboard_opener::<u32>()
                .open()
                .map_err(|e| format!("{suffix}: {e:?}"))
        }
    };
    let events = |suffix: &str| -> Result<Events, String> {
        node.service_builder(&name(&format!("eqtrack-floor/{run}/{suffix}"))?)
            .event()
            .open_or_create()
            .map_err(|e| format!("{suffix}: {e:?}"))
    };
    Ok((
        board("ping", true)?,
        board("pong", false)?,
        events("ping_event")?,
        events("pong_event")?,
    ))
}

fn wait(listener: &Listener<ipc::Service>, timeout: Duration) {
    let _ = listener.timed_wait(|_| {}, timeout);
}

fn run() -> Result<(), String> {
    let a = args()?;
    set_log_level_from_env_or(LogLevel::Error);
    let _ = nix::sys::prctl::set_timerslack(1);
    let node = NodeBuilder::new()
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|e| format!("node: {e:?}"))?;
    let ping = a.role == "ping";
    let (ping_board, pong_board, ping_events, pong_events) = services(&node, &a.name, ping)?;
    let (out_board, in_board, out_events, in_events) = if ping {
        (&ping_board, &pong_board, &ping_events, &pong_events)
    } else {
        (&pong_board, &ping_board, &pong_events, &ping_events)
    };
    let writer = out_board
        .writer_builder()
        .create()
        .map_err(|e| format!("writer: {e:?}"))?;
    let reader = in_board
        .reader_builder()
        .create()
        .map_err(|e| format!("reader: {e:?}"))?;
    let notifier: Notifier<ipc::Service> = out_events
        .notifier_builder()
        .create()
        .map_err(|e| format!("notifier: {e:?}"))?;
    let listener = in_events
        .listener_builder()
        .create()
        .map_err(|e| format!("listener: {e:?}"))?;
    let ports = Ports {
        writer,
        reader,
        notifier,
        listener,
    };
    if ping {
        ping_side(&a, &ports)
    } else {
        pong_side(&a, &ports)
    }
}

/// One side's ports: the board it writes, the board it reads, and the two events.
struct Ports {
    writer: iceoryx2::port::writer::Writer<ipc::Service, u32>,
    reader: iceoryx2::port::reader::Reader<ipc::Service, u32>,
    notifier: Notifier<ipc::Service>,
    listener: Listener<ipc::Service>,
}

/// The plant's role: starts pong, hand-shakes, then runs the paced loop and prints the line.
fn ping_side(a: &Args, p: &Ports) -> Result<(), String> {
    let period_ns = (1e9 / a.rate_hz).round() as u64;
    let cycles = (a.duration * a.rate_hz).round() as u64;
    let out = p
        .writer
        .entry::<StateMsg>(&0)
        .map_err(|e| format!("entry: {e:?}"))?;
    let inp = p
        .reader
        .entry::<CommandMsg>(&0)
        .map_err(|e| format!("entry: {e:?}"))?;
    let wake = if a.spin { "spin" } else { "event" };
    let mut pong = Command::new(std::env::current_exe().map_err(|e| e.to_string())?)
        .args(["pong", "--wake", wake, "--name", &a.name])
        .args([
            "--rate-hz",
            &a.rate_hz.to_string(),
            "--duration",
            &a.duration.to_string(),
        ])
        .spawn()
        .map_err(|e| format!("cannot start pong: {e}"))?;
    // the hand-shake: state 1, answered within 10 s, then the paced loop
    let mut msg = StateMsg::new(ipc_types::WireGroup::So3);
    msg.seq = 1; // 0 is the empty slot's
    let give_up = now_ns() + 10_000_000_000;
    while inp.get().seq != 1 {
        if now_ns() > give_up {
            let _ = pong.kill();
            return Err("pong did not answer within 10 s".into());
        }
        msg.stamp_ns = now_ns();
        out.update_with_copy(msg);
        let _ = p.notifier.notify();
        std::thread::sleep(Duration::from_millis(1));
    }
    let samples = Vec::with_capacity(cycles as usize);
    measure(
        a,
        &out,
        &inp,
        &p.notifier,
        &p.listener,
        period_ns,
        cycles,
        msg,
        samples,
        &mut pong,
    )
}

/// The controller's role: answers each new state at once, until ping has been silent for a
/// second after the last cycle.
fn pong_side(a: &Args, p: &Ports) -> Result<(), String> {
    let inp = p
        .reader
        .entry::<StateMsg>(&0)
        .map_err(|e| format!("entry: {e:?}"))?;
    let out = p
        .writer
        .entry::<CommandMsg>(&0)
        .map_err(|e| format!("entry: {e:?}"))?;
    let mut reply = CommandMsg::new(ipc_types::WireGroup::So3);
    let mut last = 0u64;
    let mut quiet_since = now_ns();
    loop {
        let m = inp.get();
        if m.seq != last {
            last = m.seq;
            reply.seq = m.seq;
            reply.state_received_ns = now_ns();
            reply.stamp_ns = now_ns();
            out.update_with_copy(reply);
            if !a.spin {
                let _ = p.notifier.notify();
            }
            quiet_since = now_ns();
            continue;
        }
        if now_ns() - quiet_since > 1_000_000_000 {
            return Ok(());
        }
        if a.spin {
            std::hint::spin_loop();
        } else {
            wait(&p.listener, Duration::from_millis(100));
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn measure(
    a: &Args,
    out: &iceoryx2::port::writer::EntryHandleMut<ipc::Service, u32, StateMsg>,
    inp: &iceoryx2::port::reader::EntryHandle<ipc::Service, u32, CommandMsg>,
    notifier: &Notifier<ipc::Service>,
    listener: &Listener<ipc::Service>,
    period_ns: u64,
    cycles: u64,
    mut msg: StateMsg,
    mut samples: Vec<u64>,
    pong: &mut std::process::Child,
) -> Result<(), String> {
    let mut missed = 0u64;
    let (mut leg1, mut leg2) = (
        Vec::with_capacity(samples.capacity()),
        Vec::with_capacity(samples.capacity()),
    );
    let t0 = now_ns() + period_ns;
    for k in 0..cycles {
        let tick = t0 + k * period_ns;
        sleep_until(tick);
        msg.seq += 1;
        msg.stamp_ns = now_ns();
        out.update_with_copy(msg);
        if !a.spin {
            let _ = notifier.notify();
        }
        let deadline = tick + period_ns;
        loop {
            let reply = inp.get();
            if reply.seq == msg.seq {
                let seen = now_ns();
                samples.push(seen - msg.stamp_ns);
                leg1.push(reply.state_received_ns.saturating_sub(msg.stamp_ns));
                leg2.push(seen.saturating_sub(reply.stamp_ns));
                break;
            }
            let now = now_ns();
            if now >= deadline {
                missed += 1;
                break;
            }
            if a.spin {
                std::hint::spin_loop();
            } else {
                wait(listener, Duration::from_nanos(deadline - now));
            }
        }
    }
    let _ = pong.wait();
    for v in [&mut samples, &mut leg1, &mut leg2] {
        v.sort_unstable();
    }
    let at = |v: &[u64], p: f64| {
        v.get(((v.len() as f64 * p).ceil() as usize).saturating_sub(1))
            .map_or(f64::NAN, |&ns| ns as f64 / 1000.0)
    };
    let q = |p: f64| at(&samples, p);
    println!(
        "floor wake={} rate_hz={} cycles={} p50_us={:.3} p99_us={:.3} p99_9_us={:.3} max_us={:.3} missed={} leg1_p50_us={:.3} leg2_p50_us={:.3}",
        if a.spin { "spin" } else { "event" },
        a.rate_hz,
        samples.len(),
        q(0.5),
        q(0.99),
        q(0.999),
        q(1.0),
        missed,
        at(&leg1, 0.5),
        at(&leg2, 0.5)
    );
    Ok(())
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("transport_floor: error: {e}");
            ExitCode::from(1)
        }
    }
}
