//! Shared pieces of the QEMU measurement programs.
//!
//! A program calls [`mark`] right before each measured call and [`done`] after the last
//! one; `run.sh` counts the instructions QEMU executes from each `qemu_mark` to the next
//! (the last segment ends at `qemu_done`) and prints the per-segment mean and maximum.
//! Each segment therefore includes the measured call plus a few instructions of loop and
//! marker overhead (reported by the `overhead` segments: programs first call [`mark`]
//! back to back a few times).
#![no_std]

use core::sync::atomic::{compiler_fence, AtomicU32, Ordering};

use cortex_m_semihosting::{debug, hprintln};

/// Segments started (also keeps the two markers from being merged into one function).
static MARKS: AtomicU32 = AtomicU32::new(0);

/// Marker before each measured call (never inlined: its address is the segment boundary).
#[inline(never)]
#[no_mangle]
pub extern "C" fn qemu_mark() {
    MARKS.store(
        MARKS.load(Ordering::Relaxed).wrapping_add(1),
        Ordering::Relaxed,
    );
    compiler_fence(Ordering::SeqCst);
}

/// Marker after the last measured call.
#[inline(never)]
#[no_mangle]
pub extern "C" fn qemu_done() {
    MARKS.store(0, Ordering::Relaxed);
    compiler_fence(Ordering::SeqCst);
}

/// Start a segment.
#[inline(always)]
pub fn mark() {
    qemu_mark();
}

/// End the last segment here, before work that is not to be measured (checks, output);
/// a later [`done`] then ends nothing more.
#[inline(always)]
pub fn end() {
    qemu_done();
}

/// End the last segment, print `msg` and exit QEMU with success.
pub fn done(msg: &str) -> ! {
    qemu_done();
    hprintln!("{}", msg);
    debug::exit(debug::EXIT_SUCCESS);
    loop {
        core::hint::spin_loop();
    }
}

/// Exit QEMU with failure (e.g. from a panic handler).
pub fn fail(msg: &str) -> ! {
    hprintln!("FAILED: {}", msg);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        core::hint::spin_loop();
    }
}

/// Word written below the stack pointer by [`paint_stack`].
const PATTERN: u32 = 0xC0FF_EE55;

/// Fill the `bytes` below the current stack pointer with a pattern; returns the painted
/// range's low end and the stack pointer, for [`stack_used`]. Always inlined: the stack
/// pointer read is the caller's own (its frame is fixed), so everything its later callees
/// put on the stack lies in the painted range.
#[inline(always)]
pub fn paint_stack(bytes: usize) -> (usize, usize) {
    let sp = cortex_m::register::msp::read() as usize & !3;
    let lo = sp - bytes;
    for a in (lo..sp).step_by(4) {
        // SAFETY: unused stack memory below the live frames (64 KiB of RAM on the
        // lm3s6965; the programs' statics are far below).
        unsafe { (a as *mut u32).write_volatile(PATTERN) };
    }
    (lo, sp)
}

/// Bytes of stack used below `sp` since [`paint_stack`]: down to the lowest overwritten
/// word.
pub fn stack_used(lo: usize, sp: usize) -> usize {
    let mut a = lo;
    // SAFETY: reads of the painted region.
    while a < sp && unsafe { (a as *const u32).read_volatile() } == PATTERN {
        a += 4;
    }
    sp - a
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    fail("panic")
}
