//! RISC-V 64 start-up (QEMU `virt`, `-bios none`, M-mode): riscv-rt (which
//! also enables the FPU), the NS16550 UART at 0x1000_0000 for output and the
//! SiFive test device at 0x10_0000 to exit.
//!
//! Instruction counting: `minstret`. Under `-icount shift=0` QEMU derives it
//! from the instruction counter, one per executed instruction (the calibration
//! loop checks it).

pub const NAME: &str = "riscv64gc-unknown-none-elf (RV64GC, virt)";

const UART_THR: *mut u8 = 0x1000_0000 as *mut u8;
const UART_LSR: *const u8 = 0x1000_0005 as *const u8;
const SIFIVE_TEST: *mut u32 = 0x0010_0000 as *mut u32;

pub fn ticks() -> u64 {
    let v: u64;
    // SAFETY: reads a counter CSR; M-mode may always read it.
    unsafe { core::arch::asm!("csrr {0}, minstret", out(reg) v, options(nomem, nostack)) };
    v
}

/// Exactly `2 * n` instructions: `addi` and `bnez` per iteration.
pub fn calibration_loop(n: u32) {
    // SAFETY: a register-only countdown loop; touches no memory.
    unsafe {
        core::arch::asm!("1:", "addi {0}, {0}, -1", "bnez {0}, 1b", inout(reg) u64::from(n) => _, options(nomem, nostack));
    }
}

pub fn print(bytes: &[u8]) {
    for &b in bytes {
        // SAFETY: the virt board's UART registers; LSR bit 5 is "THR empty".
        unsafe {
            while UART_LSR.read_volatile() & 0x20 == 0 {}
            UART_THR.write_volatile(b);
        }
    }
}

pub fn exit(ok: bool) -> ! {
    // SiFive test device: 0x5555 = pass; (code << 16) | 0x3333 = fail with code.
    let v = if ok { 0x5555 } else { (1 << 16) | 0x3333 };
    // SAFETY: the virt board's test device register.
    unsafe { SIFIVE_TEST.write_volatile(v) };
    loop {}
}

/// riscv-rt's link.x: the stack runs from `_stack_start` (top of RAM) down to
/// `__eheap` (end of .bss plus a zero-size heap).
pub fn stack_bounds() -> (usize, usize) {
    extern "C" {
        static __eheap: u8;
        static _stack_start: u8;
    }
    // Linker symbols: only their addresses are taken.
    (
        core::ptr::addr_of!(__eheap) as usize,
        core::ptr::addr_of!(_stack_start) as usize,
    )
}

pub fn stack_pointer() -> usize {
    let sp: usize;
    // SAFETY: reads the stack pointer register.
    unsafe { core::arch::asm!("mv {0}, sp", out(reg) sp, options(nomem, nostack)) };
    sp
}

#[riscv_rt::entry]
fn main() -> ! {
    crate::run()
}
