//! A hand-written device crate for QEMU's mps2-an386 (Arm's CMSDK Cortex-M4 board), as
//! RTIC needs one: the interrupt numbers, the priority bits, the vector table of the
//! device's interrupts, and the UART0 registers the firmware uses.
//!
//! The interrupt numbers are Arm's CMSDK header's (QEMU wires the UARTs, the timers and the
//! overflow line). `device.x` provides each handler as `DefaultHandler` unless the firmware
//! defines it.
#![allow(non_camel_case_types, clippy::upper_case_acronyms)]

pub use self::Interrupt as interrupt;
pub use cortex_m_rt::interrupt;

/// The NVIC's implemented priority bits (3, as in Arm's CMSDK CM4 header).
pub const NVIC_PRIO_BITS: u8 = 3;

/// The device's interrupts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u16)]
pub enum Interrupt {
    /// IRQ 0.
    UART0RX = 0,
    /// IRQ 1.
    UART0TX = 1,
    /// IRQ 2.
    UART1RX = 2,
    /// IRQ 3.
    UART1TX = 3,
    /// IRQ 4.
    UART2RX = 4,
    /// IRQ 5.
    UART2TX = 5,
    /// IRQ 6.
    GPIO0 = 6,
    /// IRQ 7.
    GPIO1 = 7,
    /// IRQ 8.
    TIMER0 = 8,
    /// IRQ 9.
    TIMER1 = 9,
    /// IRQ 10.
    DUALTIMER = 10,
    /// IRQ 11.
    SPI = 11,
    /// IRQ 12.
    UARTOVF = 12,
    /// IRQ 13.
    ETHERNET = 13,
    /// IRQ 14.
    I2S = 14,
    /// IRQ 15.
    TSC = 15,
    /// IRQ 16.
    GPIO2 = 16,
    /// IRQ 17.
    GPIO3 = 17,
    /// IRQ 18.
    UART3RX = 18,
    /// IRQ 19.
    UART3TX = 19,
    /// IRQ 20.
    UART4RX = 20,
    /// IRQ 21.
    UART4TX = 21,
    /// IRQ 22.
    ADCSPI = 22,
    /// IRQ 23.
    SHIELDSPI = 23,
    /// IRQ 24.
    GPIO0_0 = 24,
    /// IRQ 25.
    GPIO0_1 = 25,
    /// IRQ 26.
    GPIO0_2 = 26,
    /// IRQ 27.
    GPIO0_3 = 27,
    /// IRQ 28.
    GPIO0_4 = 28,
    /// IRQ 29.
    GPIO0_5 = 29,
    /// IRQ 30.
    GPIO0_6 = 30,
    /// IRQ 31.
    GPIO0_7 = 31,
}

// SAFETY: every variant is a valid interrupt number of this device (0 to 31), which is what
// `InterruptNumber` requires of `number`.
unsafe impl cortex_m::interrupt::InterruptNumber for Interrupt {
    #[inline(always)]
    fn number(self) -> u16 {
        self as u16
    }
}

/// The device's peripherals (the firmware reaches its registers through [`uart0`]).
pub struct Peripherals;

impl Peripherals {
    /// The peripherals, without checking that they were taken once (RTIC calls this once,
    /// in `init`).
    ///
    /// # Safety
    ///
    /// Call it once: two owners of a peripheral could race on its registers.
    pub unsafe fn steal() -> Self {
        Peripherals
    }
}

unsafe extern "C" {
    fn UART0RX();
    fn UART0TX();
    fn UART1RX();
    fn UART1TX();
    fn UART2RX();
    fn UART2TX();
    fn GPIO0();
    fn GPIO1();
    fn TIMER0();
    fn TIMER1();
    fn DUALTIMER();
    fn SPI();
    fn UARTOVF();
    fn ETHERNET();
    fn I2S();
    fn TSC();
    fn GPIO2();
    fn GPIO3();
    fn UART3RX();
    fn UART3TX();
    fn UART4RX();
    fn UART4TX();
    fn ADCSPI();
    fn SHIELDSPI();
    fn GPIO0_0();
    fn GPIO0_1();
    fn GPIO0_2();
    fn GPIO0_3();
    fn GPIO0_4();
    fn GPIO0_5();
    fn GPIO0_6();
    fn GPIO0_7();
}

/// One vector: a handler, or a reserved word.
#[derive(Clone, Copy)]
pub union Vector {
    handler: unsafe extern "C" fn(),
    _reserved: u32,
}

/// The device's interrupt vectors, after the core's 16 exception vectors.
// SAFETY: cortex-m-rt's linker script places `.vector_table.interrupts` right after the
// exception vectors and expects exactly this symbol there; each entry is a handler symbol
// that device.x provides.
#[unsafe(link_section = ".vector_table.interrupts")]
#[unsafe(no_mangle)]
pub static __INTERRUPTS: [Vector; 32] = [
    Vector { handler: UART0RX },
    Vector { handler: UART0TX },
    Vector { handler: UART1RX },
    Vector { handler: UART1TX },
    Vector { handler: UART2RX },
    Vector { handler: UART2TX },
    Vector { handler: GPIO0 },
    Vector { handler: GPIO1 },
    Vector { handler: TIMER0 },
    Vector { handler: TIMER1 },
    Vector { handler: DUALTIMER },
    Vector { handler: SPI },
    Vector { handler: UARTOVF },
    Vector { handler: ETHERNET },
    Vector { handler: I2S },
    Vector { handler: TSC },
    Vector { handler: GPIO2 },
    Vector { handler: GPIO3 },
    Vector { handler: UART3RX },
    Vector { handler: UART3TX },
    Vector { handler: UART4RX },
    Vector { handler: UART4TX },
    Vector { handler: ADCSPI },
    Vector { handler: SHIELDSPI },
    Vector { handler: GPIO0_0 },
    Vector { handler: GPIO0_1 },
    Vector { handler: GPIO0_2 },
    Vector { handler: GPIO0_3 },
    Vector { handler: GPIO0_4 },
    Vector { handler: GPIO0_5 },
    Vector { handler: GPIO0_6 },
    Vector { handler: GPIO0_7 },
];

/// UART0 (CMSDK APB UART, QEMU's hw/char/cmsdk-apb-uart.c) at 0x4000_4000.
pub mod uart0 {
    const BASE: usize = 0x4000_4000;
    const DATA: *mut u32 = BASE as *mut u32;
    const STATE: *mut u32 = (BASE + 0x4) as *mut u32;
    const CTRL: *mut u32 = (BASE + 0x8) as *mut u32;
    const INTSTATUS: *mut u32 = (BASE + 0xC) as *mut u32;
    const BAUDDIV: *mut u32 = (BASE + 0x10) as *mut u32;

    fn write(reg: *mut u32, value: u32) {
        // SAFETY: `reg` is one of this UART's registers, a valid, aligned MMIO address on
        // this board; volatile, as hardware reads it.
        unsafe { reg.write_volatile(value) }
    }

    fn read(reg: *mut u32) -> u32 {
        // SAFETY: as in `write`.
        unsafe { reg.read_volatile() }
    }

    /// Transmit and receive on, the receive interrupt on, a valid baud divider.
    pub fn enable() {
        write(BAUDDIV, 217);
        write(CTRL, 0b1011);
    }

    /// Clears the receive interrupt (reading DATA does not).
    pub fn clear_rx_interrupt() {
        write(INTSTATUS, 2);
    }

    /// A received byte, if one is waiting.
    pub fn try_read() -> Option<u8> {
        (read(STATE) & 2 != 0).then(|| read(DATA) as u8)
    }

    /// Sends `bytes`, waiting while the transmitter is full.
    pub fn write_all(bytes: &[u8]) {
        for b in bytes {
            while read(STATE) & 1 != 0 {}
            write(DATA, u32::from(*b));
        }
    }
}

/// The watchdog (CMSDK APB watchdog, Arm DDI0479C section 4.5) at 0x4000_8000, which QEMU's
/// mps2-an386 models: a 32-bit counter on the 25 MHz system clock, counting down from LOAD.
/// At the first zero it raises its interrupt (the NMI on this board) and reloads; at the
/// second, with the interrupt still uncleared, it resets the system. A write to INTCLR clears
/// the interrupt and reloads the counter: that is the feed. Every register but LOCK ignores
/// writes while the lock is on.
pub mod watchdog {
    const BASE: usize = 0x4000_8000;
    const LOAD: *mut u32 = BASE as *mut u32;
    const CONTROL: *mut u32 = (BASE + 0x8) as *mut u32;
    const INTCLR: *mut u32 = (BASE + 0xC) as *mut u32;
    const LOCK: *mut u32 = (BASE + 0xC00) as *mut u32;
    /// The key that opens the lock (any other value closes it).
    const KEY: u32 = 0x1ACC_E551;
    /// CONTROL: the counter and its interrupt on (INTEN, bit 0), the reset on (RESEN, bit 1).
    const INTEN_RESEN: u32 = 0b11;
    /// The watchdog's clock (Hz): the board's system clock.
    pub const CLOCK_HZ: u32 = 25_000_000;

    /// Writes `value` to `reg` with the lock open, then closes it.
    fn unlocked(reg: *mut u32, value: u32) {
        // SAFETY: LOCK and `reg` are this watchdog's registers, valid, aligned MMIO addresses
        // on this board; volatile, as hardware reads them.
        unsafe {
            LOCK.write_volatile(KEY);
            reg.write_volatile(value);
            LOCK.write_volatile(0);
        }
    }

    /// Starts the watchdog: the interrupt after `ticks` clock ticks without a feed, the reset
    /// after twice that.
    pub fn arm(ticks: u32) {
        unlocked(LOAD, ticks.max(1));
        unlocked(INTCLR, 1);
        unlocked(CONTROL, INTEN_RESEN);
    }

    /// Feeds it: clears the interrupt and reloads the counter.
    pub fn feed() {
        unlocked(INTCLR, 1);
    }

    /// Stops it (the counter, the interrupt and the reset off).
    pub fn disarm() {
        unlocked(CONTROL, 0);
        unlocked(INTCLR, 1);
    }
}
