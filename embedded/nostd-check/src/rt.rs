//! The freestanding runtime: entry point, exit and write syscalls, the memory functions LLVM
//! expects, and the panic handler. x86_64 Linux only.

use core::arch::{asm, naked_asm};

/// The process entry point: align the stack to 16 bytes (SSE stores need it) and call main.
// SAFETY (naked, no_mangle): `_start` is the one entry symbol of this freestanding binary
// (no C runtime defines it); its body is the single naked_asm block, which never returns.
#[unsafe(naked)]
#[unsafe(no_mangle)]
pub extern "C" fn _start() -> ! {
    naked_asm!("xor ebp, ebp", "and rsp, -16", "call {entry}", "ud2", entry = sym entry)
}

extern "C" fn entry() -> ! {
    exit(crate::run())
}

/// Exits the process with `code` (exit_group syscall).
pub fn exit(code: i32) -> ! {
    // SAFETY: exit_group (231) takes one integer argument and never returns.
    unsafe { asm!("syscall", in("rax") 231, in("rdi") code as isize, options(noreturn, nostack)) }
}

/// Writes bytes to standard output (write syscall; short writes are ignored).
pub fn write(bytes: &[u8]) {
    // SAFETY: write (1) reads `len` bytes from a valid slice; rcx and r11 are clobbered by
    // the syscall instruction and declared as such.
    unsafe {
        asm!(
            "syscall",
            inlateout("rax") 1isize => _,
            in("rdi") 1isize,
            in("rsi") bytes.as_ptr(),
            in("rdx") bytes.len(),
            lateout("rcx") _,
            lateout("r11") _,
            options(nostack)
        );
    }
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    write(b"nostd-check: panic\n");
    exit(101)
}

/// Unwinding is off (panic = "abort"); unoptimised builds still reference this symbol.
// SAFETY (no_mangle): no other object defines this symbol in a no-std, no-unwind binary.
#[unsafe(no_mangle)]
pub extern "C" fn rust_eh_personality() {}

// The memory functions, written with volatile accesses so that LLVM cannot turn the loops
// back into calls to themselves.
// SAFETY (no_mangle on each): linked with -nostdlib, nothing else provides memcpy, memmove,
// memset, memcmp or bcmp, and each follows the C contract for its symbol.

/// # Safety
/// `dest` and `src` valid for `n` bytes and not overlapping.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn memcpy(dest: *mut u8, src: *const u8, n: usize) -> *mut u8 {
    // SAFETY: the caller guarantees both ranges are valid for n bytes.
    unsafe {
        for i in 0..n {
            core::ptr::write_volatile(dest.add(i), core::ptr::read_volatile(src.add(i)));
        }
    }
    dest
}

/// # Safety
/// `dest` and `src` valid for `n` bytes; they may overlap.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn memmove(dest: *mut u8, src: *const u8, n: usize) -> *mut u8 {
    // SAFETY: the caller guarantees both ranges are valid; copying backwards when dest is
    // above src keeps overlapping bytes intact.
    unsafe {
        if (dest as usize) <= (src as usize) {
            for i in 0..n {
                core::ptr::write_volatile(dest.add(i), core::ptr::read_volatile(src.add(i)));
            }
        } else {
            for i in (0..n).rev() {
                core::ptr::write_volatile(dest.add(i), core::ptr::read_volatile(src.add(i)));
            }
        }
    }
    dest
}

/// # Safety
/// `dest` valid for `n` bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn memset(dest: *mut u8, c: i32, n: usize) -> *mut u8 {
    // SAFETY: the caller guarantees the range is valid for n bytes.
    unsafe {
        for i in 0..n {
            core::ptr::write_volatile(dest.add(i), c as u8);
        }
    }
    dest
}

/// # Safety
/// `a` and `b` valid for `n` bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn memcmp(a: *const u8, b: *const u8, n: usize) -> i32 {
    // SAFETY: the caller guarantees both ranges are valid for n bytes.
    unsafe {
        for i in 0..n {
            let (x, y) = (
                core::ptr::read_volatile(a.add(i)),
                core::ptr::read_volatile(b.add(i)),
            );
            if x != y {
                return x as i32 - y as i32;
            }
        }
    }
    0
}

/// # Safety
/// `a` and `b` valid for `n` bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bcmp(a: *const u8, b: *const u8, n: usize) -> i32 {
    // SAFETY: same contract as memcmp.
    unsafe { memcmp(a, b, n) }
}
