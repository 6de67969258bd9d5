//! Selects the linker script for the target being built:
//! - Cortex-M (`arm`): `memory.x` on the search path for cortex-m-rt's `link.x`;
//! - RISC-V 64: `memory-riscv64.x` (regions) before riscv-rt's `link.x`;
//! - AArch64: `link-aarch64.x`, the whole layout (the start-up is in the crate).
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").unwrap_or_default());
    let dir = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default());
    let arch = env::var("CARGO_CFG_TARGET_ARCH").unwrap_or_default();
    match arch.as_str() {
        "arm" => {
            let _ = fs::copy("memory.x", out.join("memory.x"));
            println!("cargo:rustc-link-search={}", out.display());
            println!("cargo:rustc-link-arg-bins=-Tlink.x");
        }
        "riscv64" => {
            println!(
                "cargo:rustc-link-arg-bins=-T{}",
                dir.join("memory-riscv64.x").display()
            );
            println!("cargo:rustc-link-arg-bins=-Tlink.x");
        }
        "aarch64" => {
            println!(
                "cargo:rustc-link-arg-bins=-T{}",
                dir.join("link-aarch64.x").display()
            );
        }
        _ => {}
    }
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=memory-riscv64.x");
    println!("cargo:rerun-if-changed=link-aarch64.x");
}
