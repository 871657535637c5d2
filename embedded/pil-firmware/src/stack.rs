//! The stack's high-water mark, by painting: at start-up, with interrupts still off, the
//! region below the stack pointer is filled with a pattern; at the end of a run the lowest
//! word no longer holding it marks the deepest the stack went (interrupt handlers included:
//! they run on the same main stack).

/// The paint pattern.
const PATTERN: u32 = 0xDEAD_BEEF;
/// Bytes painted below the stack pointer at start-up.
const PAINTED: usize = 96 * 1024;

// SAFETY (extern block): cortex-m-rt's link.x defines `_stack_end`; only its address is
// taken (never read through), so its declared type does not matter.
unsafe extern "C" {
    static _stack_end: u32;
}

/// Where the painting starts (the stack pointer at [`paint`]) and ends.
#[derive(Clone, Copy)]
pub struct Painted {
    top: usize,
    bottom: usize,
}

/// Paints the stack below the current stack pointer (call once, with interrupts off).
#[inline(never)]
pub fn paint() -> Option<Painted> {
    let sp = cortex_m::register::msp::read() as usize;
    // leave this function's own frame alone
    let top = (sp - 64) & !3;
    let bottom = top.checked_sub(PAINTED)?;
    if bottom < &raw const _stack_end as usize {
        return None;
    }
    let base = bottom as *mut u32;
    for i in 0..(top - bottom) / 4 {
        // SAFETY: `bottom..top` lies in RAM between the end of the statics (checked above)
        // and this function's frame: memory no Rust object owns while the stack is this
        // shallow and interrupts are off. Volatile, so the stores are not elided.
        unsafe { core::ptr::write_volatile(base.add(i), PATTERN) };
    }
    Some(Painted { top, bottom })
}

/// The bytes of stack used below the painting's top since [`paint`] (`None`: all of it).
pub fn high_water(p: Painted) -> Option<usize> {
    let base = p.bottom as *mut u32;
    let words = (p.top - p.bottom) / 4;
    // SAFETY: the words painted by `paint`; reading them races with nothing (a stack in use
    // lies above the lowest overwritten word).
    let lowest =
        (0..words).find(|&i| unsafe { core::ptr::read_volatile(base.add(i)) } != PATTERN)?;
    (lowest > 0).then(|| p.top - (p.bottom + 4 * lowest))
}
