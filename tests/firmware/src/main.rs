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
//!   under `-icount shift=0` (SysTick, `minstret`, `PMCCNTR_EL0`, `CNTPCT`);
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

#[cfg_attr(all(target_arch = "arm", not(vtsm_armv8r)), path = "start/arm.rs")]
#[cfg_attr(vtsm_armv8r, path = "start/armv8r.rs")]
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

mod console;
use console::Line;

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
    let limit = start::stack_pointer().saturating_sub(PAINT_MARGIN) & !3;
    let mut p = bottom.saturating_add(3) & !3;
    while p < limit {
        // SAFETY: [bottom, limit) is the stack's unused part, below every live
        // frame (this function is a leaf); no Rust object lives there.
        unsafe { (p as *mut u32).write_volatile(PAINT) };
        p = p.wrapping_add(4);
    }
    limit
}

/// Bytes of stack used so far: from the top down to the lowest word that no
/// longer holds `PAINT`.
#[inline(never)]
fn stack_used(bottom: usize, top: usize) -> usize {
    let mut p = bottom.saturating_add(3) & !3;
    // SAFETY: reads of the stack region given by the linker script, word-aligned.
    while p < top && unsafe { (p as *const u32).read_volatile() } == PAINT {
        p = p.wrapping_add(4);
    }
    top.saturating_sub(p)
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
    let cal_ticks = start::ticks().wrapping_sub(c0);
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
    Line::new().s("VTSM-TARGET ").s(start::NAME).end();
    Line::new().s("VTSM-DIGEST ").hex(digest, 16).end();
    Line::new()
        .s("relocalization: success ")
        .s(if s.success { "true" } else { "false" })
        .s(" (code 0x")
        .hex(u64::from(s.failure), 4)
        .s("), error ")
        .u(u64::from(s.initial_error_um))
        .s(" um -> ")
        .u(u64::from(s.final_error_um))
        .s(" um, ")
        .u(u64::from(s.attempts))
        .s(" attempts")
        .end();
    Line::new()
        .s("VTSM-RUNNER ")
        .u(u64::from(s.steps))
        .s(" engine steps, ")
        .u(u64::from(s.telemetry_frames))
        .s(" telemetry frames (")
        .u(u64::from(s.telemetry_bytes))
        .s(" payload bytes)")
        .end();
    let cal_instructions = 2 * u64::from(CAL_LOOPS);
    Line::new()
        .s("VTSM-TICKS calibration ")
        .u(cal_ticks)
        .s(" per ")
        .u(cal_instructions)
        .s(" instructions; workload ")
        .u(t1.wrapping_sub(t0))
        .s(" relocalization-block ")
        .u(t2.wrapping_sub(t1))
        .end();
    if cal_ticks > 0 {
        let per_tick = cal_instructions.wrapping_add(cal_ticks / 2) / cal_ticks;
        Line::new()
            .s("VTSM-INSTRUCTIONS workload ")
            .u(t1.wrapping_sub(t0).wrapping_mul(per_tick))
            .s(" relocalization-block ")
            .u(t2.wrapping_sub(t1).wrapping_mul(per_tick))
            .s(" engine ")
            .u(s.engine_ticks.wrapping_mul(per_tick))
            .s(" (")
            .u(per_tick)
            .s(" per tick)")
            .end();
    }
    // The whole painted region overwritten means the stack may have overflowed.
    let size = top.saturating_sub(bottom);
    let overflow = used >= size;
    Line::new()
        .s("VTSM-STACK high-water ")
        .u(used as u64)
        .s(" bytes of ")
        .u(size as u64)
        .s(" (painted ")
        .u(painted_to.saturating_sub(bottom) as u64)
        .s(" bytes)")
        .s(if overflow { " EXHAUSTED" } else { "" })
        .end();
    start::exit(!overflow)
}

/// The flight-profile run (images built with `VTSM_FLIGHT_BUNDLE`): reports
/// and exits instead of running the determinism workload.
#[cfg(vtsm_flight)]
fn run_flight(bottom: usize, top: usize, cal_ticks: u64) -> ! {
    let f = flight::run(&start::ticks);
    let used = stack_used(bottom, top);
    let per_tick = (2 * u64::from(CAL_LOOPS)).wrapping_add(cal_ticks / 2) / cal_ticks.max(1);
    Line::new().s("VTSM-TARGET ").s(start::NAME).end();
    Line::new()
        .s("VTSM-FLIGHT-DIGEST ")
        .hex(f.digest, 16)
        .s(" (host ")
        .hex(flight::scene::HOST_DIGEST, 16)
        .s(")")
        .end();
    Line::new()
        .s("flight relocalization: code 0x")
        .hex(u64::from(f.failure), 4)
        .s(", error ")
        .u(u64::from(f.initial_error_um))
        .s(" um -> ")
        .u(u64::from(f.final_error_um))
        .s(" um, ")
        .u(u64::from(f.attempts))
        .s(" attempts (host ")
        .u(u64::from(flight::scene::HOST_ATTEMPTS))
        .s("), ")
        .u(u64::from(f.steps))
        .s(" steps")
        .end();
    Line::new()
        .s("VTSM-FLIGHT-INSTRUCTIONS engine ")
        .u(f.engine_ticks.wrapping_mul(per_tick))
        .s(" (")
        .u(per_tick)
        .s(" per tick)")
        .end();
    Line::new()
        .s("VTSM-FLIGHT-RAM workspace ")
        .u(f.workspace_bytes as u64)
        .s(" bytes; stack high-water ")
        .u(used as u64)
        .s(" bytes (static RAM: see the image's .data + .bss)")
        .end();
    start::exit(f.digest == flight::scene::HOST_DIGEST && used < top.saturating_sub(bottom))
}

/// Ends the run as failed. Only images built without `panic-check` have it.
#[cfg(not(feature = "panic-check"))]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    start::exit(false)
}

/// The panic-freedom check: with `--features panic-check` the handler calls a
/// function that no object defines, so the image links only when the optimizer
/// removed every call to it, i.e. when no panic path remains in anything the
/// image runs (core, HAL, runner, devices, start-up). A remaining path fails
/// the link with `undefined symbol: vtsm_panic_path_remains`;
/// `panic-sites.sh TARGET` lists where the paths are, from a normal build.
#[cfg(feature = "panic-check")]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    extern "C" {
        fn vtsm_panic_path_remains() -> !;
    }
    // SAFETY: never executed: the symbol is undefined on purpose, so an image
    // in which this call survives optimization does not link.
    unsafe { vtsm_panic_path_remains() }
}
