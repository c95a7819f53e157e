//! Stack high-water mark by painting: every word between the end of static RAM and the
//! current stack pointer is filled with a pattern at the start of `init`; at the end of the
//! run the lowest word that no longer holds it marks the deepest the stack went. RTIC runs
//! every task and interrupt on the main stack, so this covers the preemption of `idle` by
//! `report`, `plant` and `control` stacked on each other.

use core::ptr::{addr_of, read_volatile, write_volatile};

const PAINT: u32 = 0xA5C3_5A3C;

extern "C" {
    // cortex-m-rt's linker script: the top of the stack and the end of static RAM.
    static _stack_start: u32;
    static _stack_end: u32;
}

fn bounds() -> (usize, usize) {
    // Only the symbols' addresses are taken, never their values.
    (addr_of!(_stack_end) as usize, addr_of!(_stack_start) as usize)
}

/// Paints the free stack below the caller's frame (a 64-byte margin under the current stack
/// pointer is left alone).
#[inline(never)]
pub fn paint() {
    let (bottom, _) = bounds();
    let top = (cortex_m::register::msp::read() as usize).saturating_sub(64) & !3;
    let mut p = bottom;
    while p < top {
        // SAFETY: `[bottom, top)` is RAM between the end of the statics and the live stack,
        // which nothing else uses (there is no heap).
        unsafe { write_volatile(p as *mut u32, PAINT) };
        p += 4;
    }
}

/// `(bytes of stack used at most, bytes of stack available)`.
pub fn high_water() -> (usize, usize) {
    let (bottom, top) = bounds();
    let mut p = bottom;
    // SAFETY: reads of words of RAM inside the stack region.
    while p < top && unsafe { read_volatile(p as *const u32) } == PAINT {
        p += 4;
    }
    (top - p, top - bottom)
}
