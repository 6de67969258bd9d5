//! Bare-metal image: runs the determinism workload and prints its digest, then
//! the relocalization's result (through the HAL runner and the device set in
//! `src/workload.rs`), the engine's instruction count and the stack
//! high-water mark, and exits QEMU. See `src/workload.rs`.
//!
//! The same logic runs on every target; only the start-up differs, in
//! `src/start/<arch>.rs` (selected by `target_arch`), with its linker script
//! chosen in `build.rs`. Each start-up module provides:
//!
//! - `NAME`: the target, as printed;
//! - `print(args)`: console output (semihosting or UART);
//! - `exit(ok)`: ends the QEMU run with a pass or fail status;
//! - `ticks()`: a monotonic counter that advances with executed instructions
//!   under `-icount shift=0` (SysTick, `minstret`, `PMCCNTR_EL0`);
//! - `calibration_loop(n)`: exactly `2 * n` instructions, to find instructions
//!   per tick;
//! - `stack_bounds()`: lowest and one-past-highest address of the stack;
//! - `stack_pointer()`: the current stack pointer.
//!
//! Stack high-water mark: before any work, `paint_stack` fills the stack from
//! its lowest address up to just below the current frame with a pattern; after
//! the workload, `stack_used` finds the lowest word no longer holding it. The
//! figure is measured from the top of the stack, so it includes start-up frames.
#![no_std]
#![no_main]

#[cfg_attr(target_arch = "arm", path = "start/arm.rs")]
#[cfg_attr(target_arch = "riscv64", path = "start/riscv64.rs")]
#[cfg_attr(target_arch = "aarch64", path = "start/aarch64.rs")]
mod start;

#[cfg_attr(vtsm_flight, allow(dead_code))]
mod workload_mod {
    use vtsm_core::nalgebra;
    include!("workload.rs");
}

#[cfg(vtsm_flight)]
mod flight {
    use vtsm_core::nalgebra;
    include!("flight.rs");
}

macro_rules! out {
    ($($arg:tt)*) => { start::print(format_args!($($arg)*)) };
}

const CAL_LOOPS: u32 = 50_000_000;

/// Stack paint pattern.
const PAINT: u32 = 0x5AC3_A55A;

/// Bytes left unpainted below the painter's own stack pointer, for anything
/// (an exception entry) that might push while it runs.
const PAINT_MARGIN: usize = 256;

/// Fills the stack from `bottom` up to `PAINT_MARGIN` below the current stack
/// pointer with `PAINT`; returns the end of the painted region.
#[inline(never)]
fn paint_stack(bottom: usize) -> usize {
    let limit = (start::stack_pointer() - PAINT_MARGIN) & !3;
    let mut p = (bottom + 3) & !3;
    while p < limit {
        // SAFETY: [bottom, limit) is the stack's unused part, below every live
        // frame (this function is a leaf); no Rust object lives there.
        unsafe { (p as *mut u32).write_volatile(PAINT) };
        p += 4;
    }
    limit
}

/// Bytes of stack used so far: from the top down to the lowest word that no
/// longer holds `PAINT`.
#[inline(never)]
fn stack_used(bottom: usize, top: usize) -> usize {
    let mut p = (bottom + 3) & !3;
    // SAFETY: reads of the stack region given by the linker script, word-aligned.
    while p < top && unsafe { (p as *const u32).read_volatile() } == PAINT {
        p += 4;
    }
    top - p
}

/// The shared body, called by each target's start-up once its clock and
/// floating point are ready.
pub fn run() -> ! {
    let (bottom, top) = start::stack_bounds();
    #[cfg_attr(vtsm_flight, allow(unused_variables))]
    let painted_to = paint_stack(bottom);
    // Calibration: a loop of exactly 2·CAL_LOOPS instructions.
    let c0 = start::ticks();
    start::calibration_loop(CAL_LOOPS);
    let cal_ticks = start::ticks() - c0;
    #[cfg(vtsm_flight)]
    run_flight(bottom, top, cal_ticks);
    #[cfg(not(vtsm_flight))]
    run_workload(bottom, top, painted_to, cal_ticks);
}

/// The determinism workload and the timed relocalization: reports and exits.
#[cfg(not(vtsm_flight))]
fn run_workload(bottom: usize, top: usize, painted_to: usize, cal_ticks: u64) -> ! {
    let t0 = start::ticks();
    let digest = workload_mod::workload();
    let t1 = start::ticks();
    let s = workload_mod::relocalization(&start::ticks);
    let t2 = start::ticks();
    let used = stack_used(bottom, top);
    out!("VTSM-TARGET {}\n", start::NAME);
    out!("VTSM-DIGEST {:016x}\n", digest);
    out!(
        "relocalization: success {} (code 0x{:04x}), error {} um -> {} um, {} attempts\n",
        s.success,
        s.failure,
        s.initial_error_um,
        s.final_error_um,
        s.attempts
    );
    out!(
        "VTSM-RUNNER {} engine steps, {} telemetry frames ({} payload bytes)\n",
        s.steps,
        s.telemetry_frames,
        s.telemetry_bytes
    );
    let cal_instructions = 2 * u64::from(CAL_LOOPS);
    out!(
        "VTSM-TICKS calibration {} per {} instructions; workload {} relocalization-block {}\n",
        cal_ticks,
        cal_instructions,
        t1 - t0,
        t2 - t1
    );
    if cal_ticks > 0 {
        let per_tick = (cal_instructions + cal_ticks / 2) / cal_ticks;
        out!(
            "VTSM-INSTRUCTIONS workload {} relocalization-block {} engine {} ({} per tick)\n",
            (t1 - t0) * per_tick,
            (t2 - t1) * per_tick,
            s.engine_ticks * per_tick,
            per_tick
        );
    }
    // The whole painted region overwritten means the stack may have overflowed.
    let overflow = used >= top - bottom;
    out!(
        "VTSM-STACK high-water {} bytes of {} (painted {} bytes){}\n",
        used,
        top - bottom,
        painted_to.saturating_sub(bottom),
        if overflow { " EXHAUSTED" } else { "" }
    );
    start::exit(!overflow)
}

/// The flight-profile run (images built with `VTSM_FLIGHT_BUNDLE`): reports
/// and exits instead of running the determinism workload.
#[cfg(vtsm_flight)]
fn run_flight(bottom: usize, top: usize, cal_ticks: u64) -> ! {
    let f = flight::run(&start::ticks);
    let used = stack_used(bottom, top);
    let per_tick = (2 * u64::from(CAL_LOOPS) + cal_ticks / 2) / cal_ticks.max(1);
    out!("VTSM-TARGET {}\n", start::NAME);
    out!(
        "VTSM-FLIGHT-DIGEST {:016x} (host {:016x})\n",
        f.digest,
        flight::scene::HOST_DIGEST
    );
    out!(
        "flight relocalization: code 0x{:04x}, error {} um -> {} um, {} attempts (host {}), {} steps\n",
        f.failure,
        f.initial_error_um,
        f.final_error_um,
        f.attempts,
        flight::scene::HOST_ATTEMPTS,
        f.steps
    );
    out!(
        "VTSM-FLIGHT-INSTRUCTIONS engine {} ({} per tick)\n",
        f.engine_ticks * per_tick,
        per_tick
    );
    out!(
        "VTSM-FLIGHT-RAM workspace {} bytes; stack high-water {} bytes (static RAM: see the image's .data + .bss)\n",
        f.workspace_bytes,
        used
    );
    start::exit(f.digest == flight::scene::HOST_DIGEST && used < top - bottom)
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    start::exit(false)
}
