//! Selects the linker script for the target being built:
//! - Cortex-M (`arm`): `memory-m7.x` (or `memory-flight.x`) copied to OUT_DIR as
//!   `memory.x`, on the search path for cortex-m-rt's `link.x`;
//! - RISC-V 64: `memory-riscv64.x` (regions) before riscv-rt's `link.x`;
//! - AArch64: `link-aarch64.x`, the whole layout (the start-up is in the crate);
//! - Armv8-R (`armv8r-none-eabihf`, also `target_arch = "arm"`): `link-armv8r.x`,
//!   the whole layout, and the `vtsm_armv8r` cfg that selects its start-up.
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").unwrap_or_default());
    let dir = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default());
    let arch = env::var("CARGO_CFG_TARGET_ARCH").unwrap_or_default();
    // Cortex-M and Cortex-R share `target_arch = "arm"`, and stable Rust
    // exposes no target feature that tells them apart: the triple does.
    let armv8r = env::var("TARGET").is_ok_and(|t| t.starts_with("armv8r-"));
    println!("cargo::rustc-check-cfg=cfg(vtsm_armv8r)");
    // A flight-profile bundle (tests/src/bin/flight_bundle.rs) turns the image
    // into the flight run; its map and pair need the larger memory layouts.
    println!("cargo::rustc-check-cfg=cfg(vtsm_flight)");
    println!("cargo:rerun-if-env-changed=VTSM_FLIGHT_BUNDLE");
    let flight = env::var_os("VTSM_FLIGHT_BUNDLE").map(PathBuf::from);
    if let Some(dir) = &flight {
        let dir = fs::canonicalize(dir).unwrap_or_else(|_| dir.clone());
        println!("cargo:rustc-cfg=vtsm_flight");
        println!("cargo:rustc-env=VTSM_FLIGHT_DIR={}", dir.display());
        for f in ["scene.rs", "map.vmap", "left.gray", "right.gray"] {
            println!("cargo:rerun-if-changed={}", dir.join(f).display());
        }
    }
    match arch.as_str() {
        "arm" if armv8r => {
            println!("cargo:rustc-cfg=vtsm_armv8r");
            println!(
                "cargo:rustc-link-arg-bins=-T{}",
                dir.join("link-armv8r.x").display()
            );
        }
        "arm" => {
            let memory = if flight.is_some() {
                "memory-flight.x"
            } else {
                "memory-m7.x"
            };
            if let Err(e) = fs::copy(memory, out.join("memory.x")) {
                panic!("cannot copy {memory} to {}: {e}", out.display());
            }
            println!("cargo:rustc-link-search={}", out.display());
            println!("cargo:rustc-link-arg-bins=-Tlink.x");
        }
        "riscv64" => {
            let memory = if flight.is_some() {
                "memory-riscv64-flight.x"
            } else {
                "memory-riscv64.x"
            };
            println!("cargo:rustc-link-arg-bins=-T{}", dir.join(memory).display());
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
    println!("cargo:rerun-if-changed=memory-m7.x");
    println!("cargo:rerun-if-changed=memory-flight.x");
    println!("cargo:rerun-if-changed=memory-riscv64-flight.x");
    println!("cargo:rerun-if-changed=memory-riscv64.x");
    println!("cargo:rerun-if-changed=link-aarch64.x");
    println!("cargo:rerun-if-changed=link-armv8r.x");
}
