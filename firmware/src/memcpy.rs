//! A word-wise `__aeabi_memcpy` for ARMv7-M.
//!
//! Moving a decoded frame through `Result`s and `Option`s makes LLVM copy
//! most of it from an odd offset into an aligned slot. compiler-builtins
//! copies such a misaligned pair a byte at a time (about four instructions a
//! byte), which was 40% of a message's cost on the node. ARMv7-M (Cortex-M3,
//! M4) loads and stores single words at any address (`CCR.UNALIGN_TRP` is
//! clear out of reset, and nothing here sets it), so one loop of word moves
//! serves every alignment: about ten instructions per 16 bytes.
//!
//! compiler-builtins defines the `__aeabi_memcpy*` symbols weak so that a
//! program can supply its own; these strong ones take their place in the
//! firmware binaries. The copy never touches memory-mapped registers (the
//! compiler calls it for Rust values only). The `kernels` binary checks it
//! against a byte loop over every alignment and length up to 80 bytes.

core::arch::global_asm!(
    ".pushsection .text.__aeabi_memcpy,\"ax\",%progbits",
    ".global __aeabi_memcpy",
    ".global __aeabi_memcpy4",
    ".global __aeabi_memcpy8",
    ".type __aeabi_memcpy,%function",
    ".type __aeabi_memcpy4,%function",
    ".type __aeabi_memcpy8,%function",
    ".thumb_func",
    "__aeabi_memcpy:",
    ".thumb_func",
    "__aeabi_memcpy4:",
    ".thumb_func",
    "__aeabi_memcpy8:",
    // r0 = destination, r1 = source, r2 = length; r3 and r12 are scratch.
    "    subs r2, r2, #16",
    "    blo 2f",
    // Sixteen bytes per pass.
    "1:  ldr r3, [r1], #4",
    "    ldr r12, [r1], #4",
    "    str r3, [r0], #4",
    "    str r12, [r0], #4",
    "    ldr r3, [r1], #4",
    "    ldr r12, [r1], #4",
    "    str r3, [r0], #4",
    "    str r12, [r0], #4",
    "    subs r2, r2, #16",
    "    bhs 1b",
    // Up to fifteen bytes left: words, then bytes.
    "2:  adds r2, r2, #12",
    "    blo 4f",
    "3:  ldr r3, [r1], #4",
    "    str r3, [r0], #4",
    "    subs r2, r2, #4",
    "    bhs 3b",
    "4:  adds r2, r2, #4",
    "    beq 6f",
    "5:  ldrb r3, [r1], #1",
    "    strb r3, [r0], #1",
    "    subs r2, r2, #1",
    "    bne 5b",
    "6:  bx lr",
    ".size __aeabi_memcpy, . - __aeabi_memcpy",
    ".popsection",
);
