//! AArch64 start-up (QEMU `virt`, `-cpu cortex-a53`, entered at EL1 with the
//! MMU off): a hand-written `_start` below, the PL011 UART at 0x0900_0000 for
//! output and semihosting `SYS_EXIT` to exit.
//!
//! Instruction counting: the PMU cycle counter `PMCCNTR_EL0`. QEMU derives it
//! from virtual time at 1 GHz, and under `-icount shift=0` virtual time
//! advances 1 ns per executed instruction, so one tick is one instruction
//! (the calibration loop checks it).
//!
//! With the MMU off every access is Device memory, where unaligned accesses
//! fault; the target (`aarch64-unknown-none`) compiles with `+strict-align`.

pub const NAME: &str = "aarch64-unknown-none (Cortex-A53, virt)";

const UART_DR: *mut u32 = 0x0900_0000 as *mut u32;
const UART_FR: *const u32 = 0x0900_0018 as *const u32;

// Boot: park all but core 0, enable FP/SIMD at EL1 (CPACR_EL1.FPEN = 0b11:
// the compiler uses FP/SIMD registers anywhere, so before any Rust code), set
// the stack, zero .bss, start the PMU cycle counter, call `aarch64_main`.
core::arch::global_asm!(
    ".section .text.boot, \"ax\"",
    ".global _start",
    "_start:",
    "    mrs x0, mpidr_el1",
    "    and x0, x0, #0xff",
    "    cbnz x0, 9f",
    "    mov x0, #(3 << 20)",
    "    msr cpacr_el1, x0",
    "    isb",
    "    ldr x0, =__stack_top",
    "    mov sp, x0",
    "    ldr x0, =__bss_start",
    "    ldr x1, =__bss_end",
    "1:  cmp x0, x1",
    "    b.hs 2f",
    "    str xzr, [x0], #8",
    "    b 1b",
    // PMCR_EL0: E (enable) | C (reset cycle counter) | LC (64-bit overflow).
    "2:  mov x0, #((1 << 0) | (1 << 2) | (1 << 6))",
    "    msr pmcr_el0, x0",
    // PMCNTENSET_EL0 bit 31: cycle counter on. PMCCFILTR_EL0 = 0: count at EL1.
    "    mov x0, #(1 << 31)",
    "    msr pmcntenset_el0, x0",
    "    msr pmccfiltr_el0, xzr",
    "    isb",
    "    bl aarch64_main",
    "9:  wfe",
    "    b 9b",
);

#[no_mangle]
extern "C" fn aarch64_main() -> ! {
    crate::run()
}

pub fn ticks() -> u64 {
    let v: u64;
    // SAFETY: reads the PMU cycle counter, enabled for EL1 by `_start`.
    unsafe { core::arch::asm!("isb", "mrs {0}, pmccntr_el0", out(reg) v, options(nomem, nostack)) };
    v
}

/// Exactly `2 * n` instructions: `subs` and `b.ne` per iteration.
pub fn calibration_loop(n: u32) {
    // SAFETY: a register-only countdown loop; touches no memory.
    unsafe {
        core::arch::asm!("1:", "subs {0}, {0}, #1", "b.ne 1b", inout(reg) u64::from(n) => _, options(nomem, nostack));
    }
}

pub fn print(bytes: &[u8]) {
    for &b in bytes {
        // SAFETY: the virt board's PL011 registers; FR bit 5 is "TX FIFO full".
        unsafe {
            while UART_FR.read_volatile() & (1 << 5) != 0 {}
            UART_DR.write_volatile(u32::from(b));
        }
    }
}

pub fn exit(ok: bool) -> ! {
    // Semihosting SYS_EXIT (0x18): x1 points to {reason, subcode};
    // ADP_Stopped_ApplicationExit (0x20026) with subcode = exit status.
    let block: [u64; 2] = [0x2_0026, if ok { 0 } else { 1 }];
    // SAFETY: the semihosting trap (`hlt #0xf000`, QEMU with -semihosting);
    // it reads `block` and does not return.
    unsafe {
        core::arch::asm!("hlt #0xf000", in("x0") 0x18u64, in("x1") block.as_ptr(), options(nostack));
    }
    loop {}
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
