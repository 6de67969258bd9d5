//! The `vtsm` subcommands, one module each. Each `run` returns the process exit
//! code: 0 ok, 1 relocalization failed cleanly, 2 bad input.

use crate::error::{Error, EXIT_BAD_INPUT};

pub mod batch;
pub mod bench;
pub mod budget;
pub mod demo;
pub mod eval;
pub mod map_build;
pub mod ncc;
pub mod relocalize;
pub mod scene_export;
pub mod scene_sheet;

/// Print a one-line error to stderr and return the bad-input exit code.
pub fn report(e: &Error) -> u8 {
    eprintln!("vtsm: error: {e}");
    EXIT_BAD_INPUT
}
