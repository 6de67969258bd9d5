//! Bare-metal image: runs the determinism workload and prints its digest over
//! semihosting, then the relocalization's result and its cost in SysTick ticks,
//! and exits QEMU. See `src/workload.rs`.
//!
//! Instruction counting: under `qemu-system-arm -icount shift=0` virtual time
//! advances exactly 1 ns per executed instruction, and SysTick runs from the
//! MPS2 board clock (25 MHz), so one tick is 40 instructions. The image prints
//! raw ticks; `.ci/run` and `fsw-docs/budgets/cycles.md` convert them.
#![no_std]
#![no_main]

use core::sync::atomic::{AtomicU32, Ordering};
use cortex_m::peripheral::{syst::SystClkSource, SCB, SYST};
use cortex_m_rt::{entry, exception};
use cortex_m_semihosting::{debug, hprintln};

mod workload_mod {
    use vtsm_core::nalgebra;
    include!("workload.rs");
}

const RELOAD: u32 = 0x00FF_FFFF;
static WRAPS: AtomicU32 = AtomicU32::new(0);

#[exception]
fn SysTick() {
    WRAPS.fetch_add(1, Ordering::Relaxed);
}

/// Ticks since SysTick was started. Wraps are counted by the exception; a wrap
/// that happened but is still pending is counted here, with the counter re-read.
fn ticks() -> u64 {
    cortex_m::interrupt::free(|_| {
        let mut wraps = WRAPS.load(Ordering::Acquire);
        let mut current = SYST::get_current();
        if SCB::is_pendst_pending() {
            wraps += 1;
            current = SYST::get_current();
        }
        u64::from(wraps) * u64::from(RELOAD + 1) + u64::from(RELOAD - current)
    })
}

const CAL_LOOPS: u32 = 50_000_000;

/// Exactly `2 * n` instructions: `subs` and `bne` per iteration.
fn calibration_loop(n: u32) {
    // SAFETY: a register-only countdown loop; touches no memory.
    unsafe {
        core::arch::asm!("1:", "subs {0}, {0}, #1", "bne 1b", inout(reg) n => _, options(nomem, nostack));
    }
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
    // Calibration: a loop of exactly 2·CAL_LOOPS instructions (`subs` + `bne`).
    let c0 = ticks();
    calibration_loop(CAL_LOOPS);
    let cal_ticks = ticks() - c0;
    let t0 = ticks();
    let digest = workload_mod::workload();
    let t1 = ticks();
    let s = workload_mod::relocalization(&ticks);
    let t2 = ticks();
    hprintln!("VTSM-DIGEST {:016x}", digest);
    hprintln!(
        "relocalization: success {} (code 0x{:04x}), error {} um -> {} um, {} attempts",
        s.success,
        s.failure,
        s.initial_error_um,
        s.final_error_um,
        s.attempts
    );
    let cal_instructions = 2 * u64::from(CAL_LOOPS);
    hprintln!(
        "VTSM-TICKS calibration {} per {} instructions; workload {} relocalization-block {}",
        cal_ticks,
        cal_instructions,
        t1 - t0,
        t2 - t1
    );
    if cal_ticks > 0 {
        let per_tick = (cal_instructions + cal_ticks / 2) / cal_ticks;
        hprintln!(
            "VTSM-INSTRUCTIONS workload {} relocalization-block {} engine {} ({} per tick)",
            (t1 - t0) * per_tick,
            (t2 - t1) * per_tick,
            s.engine_ticks * per_tick,
            per_tick
        );
    }
    debug::exit(debug::EXIT_SUCCESS);
    loop {}
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    debug::exit(debug::EXIT_FAILURE);
    loop {}
}
