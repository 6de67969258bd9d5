//! Records how the `vtsm` binary was built, for the report of `vtsm bench`:
//! target triple, cargo profile, enabled target features and compiler.

fn main() {
    let var = |k: &str| std::env::var(k).unwrap_or_default();
    let rustc =
        std::process::Command::new(std::env::var_os("RUSTC").unwrap_or_else(|| "rustc".into()))
            .arg("--version")
            .output()
            .ok()
            .and_then(|o| String::from_utf8(o.stdout).ok())
            .map(|s| s.trim().to_string())
            .unwrap_or_default();
    println!("cargo:rustc-env=VTSM_BUILD_TARGET={}", var("TARGET"));
    println!("cargo:rustc-env=VTSM_BUILD_PROFILE={}", var("PROFILE"));
    println!("cargo:rustc-env=VTSM_BUILD_OPT_LEVEL={}", var("OPT_LEVEL"));
    println!(
        "cargo:rustc-env=VTSM_BUILD_TARGET_FEATURES={}",
        var("CARGO_CFG_TARGET_FEATURE")
    );
    println!("cargo:rustc-env=VTSM_BUILD_RUSTC={rustc}");
    println!("cargo:rerun-if-changed=build.rs");
    for k in [
        "RUSTFLAGS",
        "CARGO_ENCODED_RUSTFLAGS",
        "CARGO_BUILD_RUSTFLAGS",
    ] {
        println!("cargo:rerun-if-env-changed={k}");
    }
}
