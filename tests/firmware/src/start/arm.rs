//! Cortex-M7 start-up (MPS2 AN500): cortex-m-rt, SysTick as the clock,
//! semihosting for output and exit.
//!
//! Instruction counting: under `qemu-system-arm -icount shift=0` virtual time
//! advances exactly 1 ns per executed instruction, and SysTick runs from the
//! MPS2 board clock (25 MHz), so one tick is 40 instructions (the calibration
//! loop measures it).

use core::sync::atomic::{AtomicU32, Ordering};
use cortex_m::peripheral::{syst::SystClkSource, SCB, SYST};
use cortex_m_rt::{entry, exception};
use cortex_m_semihosting::debug;

pub const NAME: &str = "thumbv7em-none-eabihf (Cortex-M7, mps2-an500)";

const RELOAD: u32 = 0x00FF_FFFF;
static WRAPS: AtomicU32 = AtomicU32::new(0);

#[exception]
fn SysTick() {
    WRAPS.fetch_add(1, Ordering::Relaxed);
}

/// Ticks since SysTick was started. Wraps are counted by the exception; a wrap
/// that happened but is still pending is counted here, with the counter re-read.
pub fn ticks() -> u64 {
    cortex_m::interrupt::free(|_| {
        let mut wraps = WRAPS.load(Ordering::Acquire);
        let mut current = SYST::get_current();
        if SCB::is_pendst_pending() {
            wraps = wraps.wrapping_add(1);
            current = SYST::get_current();
        }
        // A 24-bit counter below RELOAD: none of this can wrap in a u64.
        u64::from(wraps)
            .wrapping_mul(u64::from(RELOAD) + 1)
            .wrapping_add(u64::from(RELOAD.wrapping_sub(current)))
    })
}

/// Exactly `2 * n` instructions: `subs` and `bne` per iteration.
pub fn calibration_loop(n: u32) {
    // SAFETY: a register-only countdown loop; touches no memory.
    unsafe {
        core::arch::asm!("1:", "subs {0}, {0}, #1", "bne 1b", inout(reg) n => _, options(nomem, nostack));
    }
}

pub fn print(bytes: &[u8]) {
    if let Ok(mut out) = cortex_m_semihosting::hio::hstdout() {
        // Console output is best effort: a failed write loses the line, not the run.
        let _ = out.write_all(bytes);
    }
}

pub fn exit(ok: bool) -> ! {
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    loop {}
}

/// cortex-m-rt's link.x: the stack runs from `_stack_start` (top of RAM) down
/// to `__sheap` (end of .bss; the heap is unused).
pub fn stack_bounds() -> (usize, usize) {
    extern "C" {
        static __sheap: u8;
        static _stack_start: u8;
    }
    // Linker symbols: only their addresses are taken.
    (
        core::ptr::addr_of!(__sheap) as usize,
        core::ptr::addr_of!(_stack_start) as usize,
    )
}

pub fn stack_pointer() -> usize {
    cortex_m::register::msp::read() as usize
}

#[entry]
fn main() -> ! {
    if let Some(mut p) = cortex_m::Peripherals::take() {
        p.SYST.set_clock_source(SystClkSource::Core);
        p.SYST.set_reload(RELOAD);
        p.SYST.clear_current();
        p.SYST.enable_interrupt();
        p.SYST.enable_counter();
        // The counter holds 0 until its first reload; reading it then would
        // count a whole period that has not elapsed.
        while SYST::get_current() == 0 {}
    }
    crate::run()
}
