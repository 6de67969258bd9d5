//! Helpers of the tests that run the `vtsm` binary.
#![allow(dead_code, clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A fresh, empty directory `<test>_<name>` under the target's temporary directory.
pub fn dir(test: &str, name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("{test}_{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Run the `vtsm` binary with `args`.
pub fn vtsm(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vtsm"))
        .args(args)
        .output()
        .unwrap()
}

/// A path as `&str` (the tests' paths are UTF-8).
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}
