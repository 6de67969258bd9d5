//! Records how the `vtsm` binary was built, for the reports of `vtsm bench`
//! and `vtsm eval`: target triple, cargo profile, enabled target features,
//! compiler, and the git revision of the sources (`+dirty` when tracked files
//! differ from it), so a report names the build that made it, not the
//! checkout it was run in.

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
    git_revision();
    for k in [
        "RUSTFLAGS",
        "CARGO_ENCODED_RUSTFLAGS",
        "CARGO_BUILD_RUSTFLAGS",
    ] {
        println!("cargo:rerun-if-env-changed={k}");
    }
}

/// `VTSM_GIT_REV`: the short HEAD commit of the workspace, with `+dirty` when
/// a tracked file differs from it; nothing when git or the repository is
/// missing (the binary then falls back to the checkout it runs in). Reruns
/// when HEAD, the index or any source directory of the workspace changes, so
/// the flag follows edits.
fn git_revision() {
    let Some(root) = std::env::var_os("CARGO_MANIFEST_DIR")
        .map(std::path::PathBuf::from)
        .and_then(|d| d.parent().map(std::path::Path::to_path_buf))
    else {
        return;
    };
    let git = |args: &[&str]| {
        std::process::Command::new("git")
            .arg("-C")
            .arg(&root)
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .and_then(|o| String::from_utf8(o.stdout).ok())
            .map(|s| s.trim().to_string())
    };
    let Some(git_dir) = git(&["rev-parse", "--absolute-git-dir"]) else {
        return;
    };
    for p in ["HEAD", "index"] {
        println!("cargo:rerun-if-changed={git_dir}/{p}");
    }
    if let Some(head_ref) = git(&["symbolic-ref", "-q", "HEAD"]) {
        println!("cargo:rerun-if-changed={git_dir}/{head_ref}");
    }
    for d in ["core/src", "hal/src", "sim/src", "Cargo.toml", "Cargo.lock"] {
        println!("cargo:rerun-if-changed={}", root.join(d).display());
    }
    let Some(rev) = git(&["rev-parse", "--short=12", "HEAD"]).filter(|r| !r.is_empty()) else {
        return;
    };
    let dirty =
        git(&["status", "--porcelain", "--untracked-files=no"]).is_some_and(|s| !s.is_empty());
    let suffix = if dirty { "+dirty" } else { "" };
    println!("cargo:rustc-env=VTSM_GIT_REV={rev}{suffix}");
}
