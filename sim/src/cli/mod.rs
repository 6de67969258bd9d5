//! The `vtsm` subcommands, one module each. Each `run` returns the process exit
//! code: 0 ok, 1 relocalization failed cleanly, 2 bad input.

use crate::error::{Error, EXIT_BAD_INPUT};
use vtsm_hal::runner::VerifyChecks;

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

/// `--verify [repeat,map]` of `vtsm relocalize`, `demo` and `eval`: the
/// engine's upset checks, set in the runner's `RunnerConfig::verify`.
#[derive(Debug, Clone, Copy, Default, clap::Args)]
pub struct VerifyArg {
    /// Upset checks before a result is trusted: `repeat` solves the final
    /// correspondences again from a second random stream and compares, `map`
    /// re-checks the map product (CRCs) before a success; `--verify` alone is
    /// both. `result.json` (`eval`: `trials.csv`) says which ran.
    #[arg(
        long = "verify",
        value_name = "repeat,map",
        num_args = 0..=1,
        default_missing_value = "repeat,map",
        value_parser = parse_verify
    )]
    pub verify: Option<VerifyChecks>,
}

impl VerifyArg {
    /// The checks asked for; none without `--verify`.
    pub fn checks(self) -> VerifyChecks {
        self.verify.unwrap_or(VerifyChecks::OFF)
    }
}

/// Parse the value of `--verify`: a comma-separated list of `repeat` (repeat
/// the final solve from a second random stream and compare) and `map`
/// (re-check the map product before a success is returned).
///
/// # Errors
/// An empty list or an unknown word, with what is accepted.
pub fn parse_verify(s: &str) -> std::result::Result<VerifyChecks, String> {
    let mut v = VerifyChecks::OFF;
    for word in s.split(',').map(str::trim) {
        match word {
            "repeat" => v.repeat_solve = true,
            "map" => v.recheck_map = true,
            _ => {
                return Err(format!(
                    "unknown check `{word}` (a comma-separated list of `repeat` and `map`)"
                ))
            }
        }
    }
    Ok(v)
}
