//! Cortex-R52 start-up (QEMU `mps3-an536`, entered in Hyp mode (EL2) with the
//! MPU off): a hand-written `_start` below, the CPU's own CMSDK UART at
//! 0xE7C0_0000 for output and semihosting `SYS_EXIT` to exit.
//!
//! The image stays in Hyp mode: nothing in it needs a lower exception level,
//! and EL2 owns every control the start-up sets. With the EL2 MPU off the
//! PMSAv8 default memory map applies, in which RAM and flash are Normal
//! memory, so unaligned accesses do not fault.
//!
//! Instruction counting: the generic timer's physical count `CNTPCT`
//! (64 bits). QEMU's Cortex-R52 model has no PMU (its cycle counter reads
//! 0), so the AArch64 image's `PMCCNTR` is not available here. The timer runs
//! at QEMU's fixed 62.5 MHz for this CPU, one tick per 16 ns of virtual time,
//! and under `-icount shift=0` virtual time advances 1 ns per executed
//! instruction, so one tick is 16 instructions (the calibration loop measures
//! it); counts are exact to that tick, as the Cortex-M7's are to SysTick's 40.
//!
//! Floating point: the target's baseline FPU (single precision, 16 D
//! registers; `f64` arithmetic is done in software), enabled by the start-up
//! before any Rust code runs.

pub const NAME: &str = "armv8r-none-eabihf (Cortex-R52, mps3-an536)";

const UART_DATA: *mut u32 = 0xE7C0_0000 as *mut u32;
const UART_STATE: *const u32 = 0xE7C0_0004 as *const u32;
const UART_CTRL: *mut u32 = 0xE7C0_0008 as *mut u32;
const UART_BAUDDIV: *mut u32 = 0xE7C0_0010 as *mut u32;
/// The board's 50 MHz peripheral clock over 115200 baud.
const BAUDDIV: u32 = 50_000_000 / 115_200;

/// Semihosting `SYS_EXIT` reasons: the A32 call takes the reason itself (not
/// a block), and QEMU exits with status 0 for `ApplicationExit`, 1 otherwise.
const ADP_STOPPED_APPLICATION_EXIT: u32 = 0x2_0026;
const ADP_STOPPED_RUN_TIME_ERROR_UNKNOWN: u32 = 0x2_0023;

// Boot (A32): park all but core 0; install the exception vectors (HVBAR in
// Hyp mode, VBAR too); let EL2 use the FPU and Advanced SIMD (HCPTR TCP10,
// TCP11, TASE clear; CPACR cp10/cp11 full access for EL1) and switch the FPU
// on (FPEXC.EN) before any Rust code, which may use FP registers anywhere;
// set the stack; copy .data from flash; zero .bss; call `armv8r_main`. The
// generic timer counts from reset (EL2 may always read it).
core::arch::global_asm!(
    ".section .text.boot, \"ax\"",
    ".arm",
    ".global _start",
    "_start:",
    "    mrc p15, 0, r0, c0, c0, 5", // MPIDR
    "    ands r0, r0, #0xff",
    "    bne 9f",
    "    ldr r0, =vtsm_vectors",
    "    mcr p15, 0, r0, c12, c0, 0", // VBAR
    "    mrs r1, cpsr",
    "    and r1, r1, #0x1f",
    "    cmp r1, #0x1a", // Hyp mode
    "    bne 1f",
    "    mcr p15, 4, r0, c12, c0, 0", // HVBAR
    "    mrc p15, 4, r0, c1, c1, 2",  // HCPTR
    "    bic r0, r0, #(3 << 10)",     // TCP10, TCP11
    "    bic r0, r0, #(1 << 15)",     // TASE
    "    mcr p15, 4, r0, c1, c1, 2",
    "1:  mrc p15, 0, r0, c1, c0, 2", // CPACR
    "    orr r0, r0, #(0xf << 20)",
    "    mcr p15, 0, r0, c1, c0, 2",
    "    isb",
    "    mov r0, #(1 << 30)", // FPEXC.EN
    "    vmsr fpexc, r0",
    "    ldr sp, =__stack_top",
    "    ldr r0, =__data_start",
    "    ldr r1, =__data_end",
    "    ldr r2, =__data_load",
    "2:  cmp r0, r1",
    "    bhs 3f",
    "    ldr r3, [r2], #4",
    "    str r3, [r0], #4",
    "    b 2b",
    "3:  ldr r0, =__bss_start",
    "    ldr r1, =__bss_end",
    "    mov r2, #0",
    "4:  cmp r0, r1",
    "    bhs 5f",
    "    str r2, [r0], #4",
    "    b 4b",
    "5:  bl armv8r_main",
    "9:  wfe",
    "    b 9b",
    // Exception vectors (Hyp and PL1 layouts are alike): the image enables no
    // interrupt, so any exception is a fault. The handler prints a line
    // without touching the stack and exits with the failure status.
    ".balign 32",
    "vtsm_vectors:",
    "    b vtsm_fault",
    "    b vtsm_fault",
    "    b vtsm_fault",
    "    b vtsm_fault",
    "    b vtsm_fault",
    "    b vtsm_fault",
    "    b vtsm_fault",
    "    b vtsm_fault",
    "vtsm_fault:",
    "    ldr r0, =0xe7c00000",
    "    movw r1, #434",
    "    str r1, [r0, #0x10]", // BAUDDIV
    "    mov r1, #1",
    "    str r1, [r0, #0x8]", // CTRL: TX enable
    "    adr r2, 23f",
    "20: ldrb r1, [r2], #1",
    "    cmp r1, #0",
    "    beq 22f",
    "21: ldr r3, [r0, #0x4]", // STATE bit 0: TX full
    "    tst r3, #1",
    "    bne 21b",
    "    str r1, [r0]",
    "    b 20b",
    "22: mov r0, #0x18",
    "    ldr r1, =0x20023",
    "    hlt #0xf000",
    "    b 22b",
    "23: .asciz \"VTSM-FAULT unexpected exception\\n\"",
    ".balign 4",
);

#[no_mangle]
extern "C" fn armv8r_main() -> ! {
    // SAFETY: the CPU's own UART registers: baud divisor, then TX enable
    // (with TX disabled a written byte would stay in the buffer forever).
    unsafe {
        UART_BAUDDIV.write_volatile(BAUDDIV);
        UART_CTRL.write_volatile(1);
    }
    crate::run()
}

pub fn ticks() -> u64 {
    let (lo, hi): (u32, u32);
    // SAFETY: reads the 64-bit physical count of the generic timer, which Hyp
    // mode may always read; `isb` keeps the read after earlier instructions.
    unsafe {
        core::arch::asm!("isb", "mrrc p15, 0, {0}, {1}, c14", out(reg) lo, out(reg) hi, options(nomem, nostack));
    }
    (u64::from(hi) << 32) | u64::from(lo)
}

/// Exactly `2 * n` instructions: `subs` and `bne` per iteration.
pub fn calibration_loop(n: u32) {
    // SAFETY: a register-only countdown loop; touches no memory.
    unsafe {
        core::arch::asm!("1:", "subs {0}, {0}, #1", "bne 1b", inout(reg) n => _, options(nomem, nostack));
    }
}

pub fn print(bytes: &[u8]) {
    for &b in bytes {
        // SAFETY: the CMSDK UART registers; STATE bit 0 is "TX buffer full".
        unsafe {
            while UART_STATE.read_volatile() & 1 != 0 {}
            UART_DATA.write_volatile(u32::from(b));
        }
    }
}

pub fn exit(ok: bool) -> ! {
    let reason = if ok {
        ADP_STOPPED_APPLICATION_EXIT
    } else {
        ADP_STOPPED_RUN_TIME_ERROR_UNKNOWN
    };
    // SAFETY: the A32 semihosting trap (`hlt #0xf000`, QEMU with
    // -semihosting); SYS_EXIT (0x18) with the reason in r1 does not return.
    unsafe {
        core::arch::asm!("hlt #0xf000", in("r0") 0x18u32, in("r1") reason, options(nostack));
    }
    // Not reached under QEMU; without a semihosting host, wait here.
    loop {
        // SAFETY: waits for an event; touches no memory.
        unsafe { core::arch::asm!("wfe", options(nomem, nostack)) };
    }
}

pub fn stack_bounds() -> (usize, usize) {
    extern "C" {
        static __stack_bottom: u8;
        static __stack_top: u8;
    }
    // Linker symbols: only their addresses are taken.
    (
        core::ptr::addr_of!(__stack_bottom) as usize,
        core::ptr::addr_of!(__stack_top) as usize,
    )
}

pub fn stack_pointer() -> usize {
    let sp: usize;
    // SAFETY: reads the stack pointer register.
    unsafe { core::arch::asm!("mov {0}, sp", out(reg) sp, options(nomem, nostack)) };
    sp
}
