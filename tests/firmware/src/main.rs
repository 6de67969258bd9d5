//! Bare-metal image: runs the determinism workload and prints its digest over
//! semihosting, then exits QEMU. See `src/workload.rs`.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};

mod workload_mod {
    use vtsm_core::nalgebra;
    include!("workload.rs");
}

#[entry]
fn main() -> ! {
    let digest = workload_mod::workload();
    hprintln!("VTSM-DIGEST {:016x}", digest);
    let s = workload_mod::relocalization();
    hprintln!(
        "relocalization: success {} (code 0x{:04x}), error {} um -> {} um, {} attempts",
        s.success,
        s.failure,
        s.initial_error_um,
        s.final_error_um,
        s.attempts
    );
    debug::exit(debug::EXIT_SUCCESS);
    loop {}
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    debug::exit(debug::EXIT_FAILURE);
    loop {}
}
