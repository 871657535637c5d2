//! The word-aligned copies and clears LLVM emits for moves of matrices and frames
//! (`__aeabi_memcpy4`, `__aeabi_memcpy8`, `__aeabi_memclr4`, `__aeabi_memclr8`), several
//! words per `ldm`/`stm` instead of `compiler_builtins`' one word per loop iteration
//! (BENCHMARKS.md, section 17: its copies were an eighth of a processor-in-the-loop cycle),
//! and the unaligned copy (`__aeabi_memcpy`) a word at a time instead of a byte (section 22:
//! the decoded frame's short vectors). `compiler_builtins` defines these symbols weak on ARM, so these
//! strong definitions replace them in this binary; everything else keeps the builtins. Each
//! keeps the ABI's contract (r0 the destination, r1 the source or the length, r2 the length;
//! only r0 to r3, r12 and the flags clobbered; the callee-saved r4 to r9 it uses pushed and
//! popped), so the result is the builtins' byte for byte.
//!
//! Written in assembly: a copy loop in Rust would be recognised by LLVM as a `memcpy` and
//! compiled into a call to itself.

use core::arch::global_asm;

// __aeabi_memcpy4(dest: r0, src: r1, n: r2), dest and src 4-byte aligned (the ABI's promise
// for these entry points): 32 bytes per iteration with ldm/stm of r3, r12 and six saved
// registers; then 16 bytes once; then whole words; then the last 0 to 3 bytes.
global_asm!(
    ".section .text.__aeabi_memcpy4,\"ax\",%progbits",
    ".global __aeabi_memcpy4",
    ".global __aeabi_memcpy8",
    ".type __aeabi_memcpy4,%function",
    ".type __aeabi_memcpy8,%function",
    ".thumb_func",
    "__aeabi_memcpy4:",
    ".thumb_func",
    "__aeabi_memcpy8:",
    "    push {{r4, r5, r6, r7, r8, r9}}",
    "    subs r2, r2, #32",
    "    blo 2f",
    "1:",
    "    ldm r1!, {{r3, r4, r5, r6, r7, r8, r9, r12}}",
    "    subs r2, r2, #32",
    "    stm r0!, {{r3, r4, r5, r6, r7, r8, r9, r12}}",
    "    bhs 1b",
    "2:",
    "    adds r2, r2, #32",
    "    subs r2, r2, #16",
    "    blo 7f",
    "    ldm r1!, {{r3, r4, r5, r12}}",
    "    subs r2, r2, #16",
    "    stm r0!, {{r3, r4, r5, r12}}",
    "7:",
    "    adds r2, r2, #16",
    "    subs r2, r2, #4",
    "    blo 4f",
    "3:",
    "    ldr r3, [r1], #4",
    "    subs r2, r2, #4",
    "    str r3, [r0], #4",
    "    bhs 3b",
    "4:",
    "    adds r2, r2, #4",
    "    beq 6f",
    "5:",
    "    ldrb r3, [r1], #1",
    "    subs r2, r2, #1",
    "    strb r3, [r0], #1",
    "    bne 5b",
    "6:",
    "    pop {{r4, r5, r6, r7, r8, r9}}",
    "    bx lr",
    ".size __aeabi_memcpy4, . - __aeabi_memcpy4",
    ".size __aeabi_memcpy8, . - __aeabi_memcpy8",
);

// __aeabi_memclr4(dest: r0, n: r1), dest 4-byte aligned: 16 zero bytes per stm, then words,
// then bytes.
global_asm!(
    ".section .text.__aeabi_memclr4,\"ax\",%progbits",
    ".global __aeabi_memclr4",
    ".global __aeabi_memclr8",
    ".type __aeabi_memclr4,%function",
    ".type __aeabi_memclr8,%function",
    ".thumb_func",
    "__aeabi_memclr4:",
    ".thumb_func",
    "__aeabi_memclr8:",
    "    push {{r4, r5}}",
    "    movs r2, #0",
    "    movs r3, #0",
    "    movs r4, #0",
    "    movs r5, #0",
    "    subs r1, r1, #16",
    "    blo 2f",
    "1:",
    "    stm r0!, {{r2, r3, r4, r5}}",
    "    subs r1, r1, #16",
    "    bhs 1b",
    "2:",
    "    adds r1, r1, #16",
    "    subs r1, r1, #4",
    "    blo 4f",
    "3:",
    "    str r2, [r0], #4",
    "    subs r1, r1, #4",
    "    bhs 3b",
    "4:",
    "    adds r1, r1, #4",
    "    beq 6f",
    "5:",
    "    strb r2, [r0], #1",
    "    subs r1, r1, #1",
    "    bne 5b",
    "6:",
    "    pop {{r4, r5}}",
    "    bx lr",
    ".size __aeabi_memclr4, . - __aeabi_memclr4",
    ".size __aeabi_memclr8, . - __aeabi_memclr8",
);

// __aeabi_memcpy(dest: r0, src: r1, n: r2), no alignment promised: LLVM calls it for moves
// it starts at an odd address, such as a frame's short vectors copied with their padding
// right after their length byte (27 bytes from one byte past a word). When both addresses are
// word aligned, the aligned copy above does it. Otherwise whole words with `ldr`/`str`, which
// the Cortex-M4 performs at any address (as LLVM's own code for this target assumes; a
// firmware that sets CCR.UNALIGN_TRP must not link this file), then the last 0 to 3 bytes:
// the same bytes as `compiler_builtins`' byte-wise `memcpy`, at a quarter of the instructions.
global_asm!(
    ".section .text.__aeabi_memcpy,\"ax\",%progbits",
    ".global __aeabi_memcpy",
    ".type __aeabi_memcpy,%function",
    ".thumb_func",
    "__aeabi_memcpy:",
    "    orr r3, r0, r1",
    "    lsls r3, r3, #30",
    "    beq.w __aeabi_memcpy4",
    "    subs r2, r2, #4",
    "    blo 2f",
    "1:",
    "    ldr r3, [r1], #4",
    "    subs r2, r2, #4",
    "    str r3, [r0], #4",
    "    bhs 1b",
    "2:",
    "    adds r2, r2, #4",
    "    beq 4f",
    "3:",
    "    ldrb r3, [r1], #1",
    "    subs r2, r2, #1",
    "    strb r3, [r0], #1",
    "    bne 3b",
    "4:",
    "    bx lr",
    ".size __aeabi_memcpy, . - __aeabi_memcpy",
);
