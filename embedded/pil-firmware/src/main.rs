//! eqtrack's processor-in-the-loop firmware (docs/pil.md): the controller's cycle
//! (`firmware_cycle`: the estimator, the law with its rejection terms and a vehicle's
//! allocation, in `f32`) on a Cortex-M4F, answering
//! the plant over a UART with `eqtrack-serial-wire` frames. QEMU's mps2-an386 runs it with the UART on
//! a TCP socket; a board runs it on its own UART.
//!
//! The shape of a real application, with RTIC:
//!
//! - `uart_rx`, the UART's receive interrupt (priority 2): drains the received bytes into a
//!   channel. It does no other work, so a byte is never lost while the law runs.
//! - `control`, an async task (priority 1): takes the bytes, finds the frames (COBS, CRC,
//!   version: a corrupted frame is dropped and counted), and answers each one: its `Hello`
//!   to the plant's, a command to each state (the estimator on its samples, the reference
//!   stepped to the state's k, the law and its terms, the allocation), nothing to noise. It writes the answer to the UART.
//! - `tick`, SysTick at 1 kHz: QEMU's UART model does not always wake the emulator when the
//!   guest empties its receive register; a periodic interrupt does (measured: without it
//!   one frame in a few thousand waited a second).
//! - idle: `wfi`.
//!
//! With the feature `timer`, the timer-driven mode of a board: the control period, not the
//! plant's frames, paces the cycle. A received state is kept as the newest sample set (what
//! a board's sensor drivers would leave), and every control period `tick` releases the
//! cycle on it; its command goes out then (what a board would write to its actuators). A
//! state is answered once, on the first tick after it arrived. The handshake and `Bye` are
//! answered at once, as before. At `Bye` it prints `PIL TIMER ticks <n> answered <n>`.
//!
//! The watchdog (the board's CMSDK APB watchdog, which QEMU models): the control task arms
//! it when it completes the first cycle of a run and feeds it at every cycle it completes,
//! and nowhere else; `Bye` stops it. A control task that stops completing cycles (hung, or
//! starved of states) raises the watchdog's interrupt, the NMI, after `PIL_WATCHDOG_MS`
//! (default 500 ms), and the watchdog resets the board after twice that. The firmware then
//! starts again and waits for the plant's handshake, as after a power cycle.
//!
//! The scenario's configuration is built in (`PIL_CONFIG`, from `plant_sim pil-config`).
//! Over semihosting it prints `PIL READY <identity> watchdog <ms> ms` at start, at each
//! `Bye` the counts and the stack's high-water mark (`STACK <bytes>`), and `PIL WATCHDOG`
//! in the NMI when the watchdog's first stage expires.
#![no_std]
#![no_main]

mod an386;
// the fast word copies and clears of the instruction-count firmware (BENCHMARKS.md, section
// 17), shared, so that this firmware runs what was counted
#[path = "../../firmware-cortex-m/src/memcopy.rs"]
mod memcopy;
mod stack;
/// The build's settings (`build.rs`: `PIL_WATCHDOG_MS`, `PIL_HANG_AT`).
mod settings {
    include!(concat!(env!("OUT_DIR"), "/settings.rs"));
}

use core::panic::PanicInfo;
use cortex_m_semihosting::debug::{self, EXIT_FAILURE};
use cortex_m_semihosting::hprintln;

/// The scenario's configuration (postcard bytes of `firmware_cycle::Config`).
static CONFIG: &[u8] = include_bytes!(env!("PIL_CONFIG"));

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    hprintln!("PANIC {}", info);
    debug::exit(EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}

/// The watchdog's first stage expired: no cycle completed for `PIL_WATCHDOG_MS`. Says so
/// once; the reset follows at the second stage (the interrupt stays uncleared).
// SAFETY: cortex-m-rt asks an NMI handler not to touch what a critical section guards, as the
// NMI preempts any: this one reads and writes only its own atomic, and writes through a host
// stream of its own (`hio::hstdout` opens one per call), not `hprintln!`'s shared one.
#[cortex_m_rt::exception]
unsafe fn NonMaskableInt() {
    use core::fmt::Write;
    static TOLD: core::sync::atomic::AtomicBool = core::sync::atomic::AtomicBool::new(false);
    if !TOLD.swap(true, core::sync::atomic::Ordering::Relaxed)
        && let Ok(mut out) = cortex_m_semihosting::hio::hstdout()
    {
        let _ = writeln!(
            out,
            "PIL WATCHDOG no cycle completed for {} ms: reset follows",
            crate::settings::WATCHDOG_MS
        );
    }
}

#[rtic::app(device = crate::an386, peripherals = true, dispatchers = [TIMER0, TIMER1])]
mod app {
    use crate::an386::{uart0, watchdog};
    use crate::settings::{HANG_AT, WATCHDOG_MS};
    use crate::stack;
    use cortex_m::peripheral::syst::SystClkSource;
    use cortex_m_semihosting::debug::{self, EXIT_FAILURE};
    use cortex_m_semihosting::hprintln;
    use firmware_cycle::Cycle;
    use rtic_sync::channel::{Receiver, Sender};
    use rtic_sync::make_channel;
    use eqtrack_serial_wire::{Deframer, Frame, MAX_ENCODED, encode};

    /// Events the channel holds (rtic-sync's maximum).
    const CAPACITY: usize = 255;
    /// Whether the control period's timer paces the cycle (the feature `timer`).
    const TIMER: bool = cfg!(feature = "timer");

    /// What wakes the control task.
    #[derive(Clone, Copy)]
    pub enum Event {
        /// A byte from the UART.
        Byte(u8),
        /// A control period has passed (timer-driven mode).
        Tick,
    }
    /// The core clock of QEMU's mps2 boards (Hz).
    const CORE_HZ: u32 = 25_000_000;

    #[shared]
    struct Shared {
        /// SysTick ticks since start (ms).
        ticks: u64,
    }

    #[local]
    struct Local {
        tx: Sender<'static, Event, CAPACITY>,
        timer: Sender<'static, Event, CAPACITY>,
        /// Milliseconds a control period (timer-driven mode).
        period_ms: u64,
        rx: Receiver<'static, Event, CAPACITY>,
        /// The newest state not answered yet (timer-driven mode).
        latest: Option<eqtrack_serial_wire::StateFrame>,
        /// Timer ticks, and states answered on them (timer-driven mode).
        released: (u64, u64),
        cycle: Cycle,
        deframer: Deframer,
        out: [u8; MAX_ENCODED],
        painted: Option<stack::Painted>,
        corrupt: u64,
        guard: Guard,
    }

    /// The control task's side of the watchdog.
    pub struct Guard {
        /// Whether the watchdog runs (from a run's first completed cycle to its `Bye`).
        armed: bool,
        /// The first state this boot answered (the planted hang's condition).
        first: Option<u64>,
    }

    impl Guard {
        /// The cycle on `state`: its command written to the UART, and the watchdog armed or
        /// fed when the cycle completed with a command. With the feature `hang`, the task
        /// hangs here instead at the first state numbered `PIL_HANG_AT` or later, in a boot
        /// whose first state came before it (so the firmware the watchdog reset flies on).
        fn cycle(&mut self, cycle: &mut Cycle, state: eqtrack_serial_wire::StateFrame, out: &mut [u8; MAX_ENCODED]) {
            let first = *self.first.get_or_insert(state.seq);
            if let Some(at) = HANG_AT
                && first < at
                && state.seq >= at
            {
                hprintln!("PIL HANG at state {}", state.seq);
                loop {
                    core::hint::spin_loop();
                }
            }
            let Some(reply) = cycle.on_frame(&Frame::State(state)) else {
                return;
            };
            if let Ok(n) = encode(&reply, out) {
                uart0::write_all(&out[..n]);
            }
            if matches!(reply, Frame::Command(_)) {
                if self.armed {
                    watchdog::feed();
                } else {
                    watchdog::arm(WATCHDOG_MS * (watchdog::CLOCK_HZ / 1000));
                    self.armed = true;
                }
            }
        }

        /// The run is over: the watchdog stops until the next run's first cycle.
        fn bye(&mut self) {
            if self.armed {
                watchdog::disarm();
                self.armed = false;
            }
        }
    }

    #[init]
    fn init(cx: init::Context) -> (Shared, Local) {
        let painted = stack::paint();
        let mut syst = cx.core.SYST;
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(CORE_HZ / 1000 - 1);
        syst.clear_current();
        syst.enable_counter();
        syst.enable_interrupt();
        uart0::enable();
        let cycle = match Cycle::from_bytes(crate::CONFIG) {
            Ok(c) => c,
            Err(e) => {
                hprintln!("ERR configuration: {}", e);
                debug::exit(EXIT_FAILURE);
                loop {
                    cortex_m::asm::wfi();
                }
            }
        };
        let mut period_ms = 1;
        if let Frame::Hello(h) = cycle.hello() {
            // a whole number of milliseconds, at least one (SysTick counts them)
            period_ms = ((h.period * 1000.0) as u64).max(1);
            hprintln!(
                "PIL READY group {} period {} fingerprint {:016x} scenario {}{} watchdog {} ms",
                h.group,
                h.period,
                h.fingerprint,
                h.scenario.as_str(),
                if TIMER { " timer-driven" } else { "" },
                WATCHDOG_MS
            );
        }
        let (tx, rx) = make_channel!(Event, CAPACITY);
        let timer = tx.clone();
        if control::spawn().is_err() {
            hprintln!("ERR cannot start the control task");
        }
        (
            Shared { ticks: 0 },
            Local {
                tx,
                timer,
                period_ms,
                rx,
                latest: None,
                released: (0, 0),
                cycle,
                deframer: Deframer::new(),
                out: [0; MAX_ENCODED],
                painted,
                corrupt: 0,
                guard: Guard {
                    armed: false,
                    first: None,
                },
            },
        )
    }

    #[idle]
    fn idle(_: idle::Context) -> ! {
        loop {
            cortex_m::asm::wfi();
        }
    }

    /// The UART's receive interrupt: every waiting byte into the channel.
    #[task(binds = UART0RX, priority = 2, local = [tx])]
    fn uart_rx(cx: uart_rx::Context) {
        uart0::clear_rx_interrupt();
        while let Some(b) = uart0::try_read() {
            // a full channel drops the byte: its frame then fails the CRC and is counted
            let _ = cx.local.tx.try_send(Event::Byte(b));
        }
    }

    /// 1 kHz: keeps QEMU's event loop awake; counts time; in the timer-driven mode releases
    /// the cycle every control period.
    #[task(binds = SysTick, priority = 3, shared = [ticks], local = [timer, period_ms])]
    fn tick(mut cx: tick::Context) {
        let now = cx.shared.ticks.lock(|t| {
            *t += 1;
            *t
        });
        if TIMER && now.is_multiple_of(*cx.local.period_ms) {
            // a full channel drops the tick: the state waits for the next one
            let _ = cx.local.timer.try_send(Event::Tick);
        }
    }

    /// Frames in, answers out.
    #[task(priority = 1, local = [rx, cycle, deframer, out, painted, corrupt, latest, released, guard])]
    async fn control(cx: control::Context) {
        let control::LocalResources {
            rx,
            cycle,
            deframer,
            out,
            painted,
            corrupt,
            latest,
            released,
            guard,
            ..
        } = cx.local;
        while let Ok(event) = rx.recv().await {
            let b = match event {
                Event::Byte(b) => b,
                Event::Tick => {
                    // timer-driven: the cycle on the newest state, once
                    released.0 += 1;
                    if let Some(state) = latest.take() {
                        released.1 += 1;
                        guard.cycle(cycle, state, out);
                    }
                    continue;
                }
            };
            let frame = match deframer.push(b) {
                None => continue,
                Some(Err(_)) => {
                    *corrupt += 1;
                    continue;
                }
                Some(Ok(f)) => f,
            };
            let bye = frame == Frame::Bye;
            // timer-driven: a state of a greeted run waits for the next tick (a state before
            // the handshake is answered at once: it asks to be greeted)
            if TIMER && cycle.greeted() {
                if let Frame::State(state) = &frame {
                    *latest = Some(state.clone());
                    continue;
                }
            }
            if let Frame::State(state) = frame {
                guard.cycle(cycle, state, out);
                continue;
            }
            if bye {
                guard.bye();
            }
            if bye && TIMER {
                hprintln!("PIL TIMER ticks {} answered {}", released.0, released.1);
                *released = (0, 0);
                *latest = None;
            }
            if let Some(reply) = cycle.on_frame(&frame) {
                if let Frame::Refused { mismatch, .. } = &reply {
                    hprintln!("PIL REFUSED mismatch {}", mismatch);
                }
                if let Ok(n) = encode(&reply, out) {
                    uart0::write_all(&out[..n]);
                }
            }
            if bye {
                let c = cycle.counts();
                hprintln!(
                    "PIL BYE answered {} dropped {:?} refused {} corrupt {} overlong {}",
                    c.answered,
                    c.dropped,
                    c.refused,
                    *corrupt,
                    deframer.too_long
                );
                match painted.and_then(stack::high_water) {
                    Some(bytes) => hprintln!("STACK {}", bytes),
                    None => hprintln!("STACK unmeasured"),
                }
            }
        }
    }
}
