//! Stack high-water mark of one call, by painting.
//!
//! [`used_by`] fills [`PAINTED`] bytes below its own stack pointer with [`PATTERN`], calls the
//! function (whose frames all lie below that stack pointer), then finds the lowest word that
//! no longer holds the pattern. No interrupt is enabled in this firmware, so nothing else
//! writes there. A call that happens to store the pattern itself at its deepest word would be
//! under-counted by that word; one that uses more than [`PAINTED`] bytes is reported as `None`.

/// The paint pattern.
const PATTERN: u32 = 0xDEAD_BEEF;
/// Bytes painted below the stack pointer (the RAM is 4 MiB; the law needs far less).
const PAINTED: usize = 64 * 1024;

// SAFETY (extern block): cortex-m-rt's link.x defines `_stack_end`; only its address is
// taken (never read through), so its declared type does not matter.
unsafe extern "C" {
    /// The lowest address the stack may grow to (end of the statics), from cortex-m-rt's
    /// `link.x`.
    static _stack_end: u32;
}

/// Calls `f` once and returns the bytes of stack it used, or `None` when the measurement is
/// not possible (not enough room to paint) or `f` used all of the painted region.
///
/// `f` is called through an opaque `dyn` pointer so that it cannot be inlined into this
/// function's own frame (which is allocated before the stack pointer is read).
#[inline(never)]
pub fn used_by(f: &mut dyn FnMut()) -> Option<usize> {
    let sp = cortex_m::register::msp::read() as usize;
    let limit = &raw const _stack_end as usize;
    let bottom = sp.checked_sub(PAINTED)? & !3;
    if bottom < limit {
        return None;
    }
    let words = (sp & !3).wrapping_sub(bottom) / 4;
    let base = bottom as *mut u32;
    for i in 0..words {
        // SAFETY: `bottom..sp` lies in RAM between the end of the statics (`_stack_end`,
        // checked above) and the current stack pointer: memory that no Rust object owns
        // while this function runs, since the stack grows down and this function calls
        // nothing while painting. Volatile, so the stores are not elided.
        unsafe { core::ptr::write_volatile(base.add(i), PATTERN) };
    }
    core::hint::black_box(&mut *f)();
    // The first word, scanning up from the bottom, that `f` overwrote.
    let lowest = (0..words).find(|&i| {
        // SAFETY: the same words as painted above; `f` has returned, so nothing below the
        // stack pointer is in use.
        unsafe { core::ptr::read_volatile(base.add(i)) != PATTERN }
    })?;
    if lowest == 0 {
        return None; // the whole region was used: more than PAINTED bytes
    }
    Some(sp - (bottom + 4 * lowest))
}
