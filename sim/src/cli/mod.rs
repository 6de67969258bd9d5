//! The `vtsm` subcommands, one module each. Each `run` returns the process exit
//! code: 0 ok, 1 relocalization failed cleanly, 2 bad input.

use crate::effects::CameraEffects;
use crate::error::{Error, EXIT_BAD_INPUT};
use crate::terrain::DepotChange;
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

/// `--accuracy T_MM,R_DEG` of `vtsm relocalize`, `demo` and `eval`: the
/// accuracy the caller needs ([`vtsm_core::reloc::Accuracy`]).
#[derive(Debug, Clone, Copy, Default, clap::Args)]
pub struct AccuracyArg {
    /// End the rounds as soon as the refined estimate states a 1-σ
    /// uncertainty of at most T_MM millimetres and R_DEG degrees in every
    /// axis (e.g. `5,0.1`), instead of always making N_iter pose updates;
    /// `result.json` (`eval`: `trials.csv`) counts the updates saved
    /// (`rounds_saved`).
    #[arg(long = "accuracy", value_name = "T_MM,R_DEG", value_parser = parse_accuracy)]
    pub accuracy: Option<vtsm_core::reloc::Accuracy>,
}

/// `--final-pairs N` of `vtsm relocalize`, `demo` and `eval`: the
/// correspondences of the last round
/// ([`Options::final_pairs`](vtsm_core::reloc::Options::final_pairs)).
#[derive(Debug, Clone, Copy, Default, clap::Args)]
pub struct FinalPairsArg {
    /// Collect N correspondences in the last round instead of N_corr
    /// (N_corr..=256; 0, the default: N_corr): the final estimate is refined
    /// on more pairs, more exact where the matches are good, for more
    /// attempts in that round (`fsw-docs/eval/final-pairs.md`).
    #[arg(long = "final-pairs", value_name = "N", default_value_t = 0,
          value_parser = clap::value_parser!(u16).range(0..=vtsm_core::config::MAX_CORR as i64))]
    pub final_pairs: u16,
}

/// `--revisit on|off` and `--near on|off` of `vtsm relocalize`, `demo` and
/// `eval`: the search mechanisms ([`Search`](vtsm_core::reloc::Search)),
/// Revisit on and Near off by default.
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct SearchArgs {
    /// Measure the last update's inliers again first in the next round
    /// (`on`, the default), or draw every attempt's vertex (`off`)
    /// (`fsw-docs/eval/revisit.md`).
    #[arg(long = "revisit", value_enum, ignore_case = true,
          default_value_t = SearchArgs::default().revisit)]
    pub revisit: OnOff,
    /// In the rounds after a pose update but the last, draw each attempt's
    /// vertex near one that agreed with the update (`on`: fewer attempts
    /// under a large lighting change, a less exact pose), or anywhere in the
    /// map (`off`, the default) (`fsw-docs/eval/near.md`).
    #[arg(long = "near", value_enum, ignore_case = true,
          default_value_t = SearchArgs::default().near)]
    pub near: OnOff,
}

impl Default for SearchArgs {
    /// The flags of the engine's default, [`Search::DEFAULT`](vtsm_core::reloc::Search::DEFAULT).
    fn default() -> Self {
        let s = vtsm_core::reloc::Search::DEFAULT;
        Self {
            revisit: OnOff::of(s.revisit),
            near: OnOff::of(s.near.share_256 > 0),
        }
    }
}

impl SearchArgs {
    /// The engine's search mechanisms these flags ask for.
    pub fn search(&self) -> vtsm_core::reloc::Search {
        use vtsm_core::reloc::{Near, Search};
        Search {
            revisit: self.revisit == OnOff::On,
            near: if self.near == OnOff::On {
                Near::ON
            } else {
                Near::OFF
            },
        }
    }
}

/// `--map-scores on|off` of `vtsm map build`, `demo` and `eval`: whether
/// the map product carries sampling scores ([`crate::mapscore`]; version 3)
/// that SamplePoint draws in proportion to.
#[derive(Debug, Clone, Copy, Default, clap::Args)]
pub struct MapScoresArg {
    /// Score every mask vertex for how likely its template is to match and
    /// ship the scores in the map (`on`), or draw mask vertices uniformly
    /// as a version-2 product does (`off`).
    #[arg(long = "map-scores", value_enum, ignore_case = true, default_value_t = OnOff::Off)]
    pub map_scores: OnOff,
}

impl MapScoresArg {
    /// Whether scores are asked for.
    pub fn on(self) -> bool {
        self.map_scores == OnOff::On
    }
}

/// A switch on the command line.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum OnOff {
    /// On.
    On,
    /// Off.
    #[default]
    Off,
}

impl OnOff {
    /// `On` for `true`, `Off` for `false`.
    pub const fn of(on: bool) -> Self {
        if on {
            Self::On
        } else {
            Self::Off
        }
    }
}

/// `--threads N` of `vtsm relocalize` and `demo`: the threads one
/// relocalization's attempts run on ([`crate::workers`]).
#[derive(Debug, Clone, Copy, Default, clap::Args)]
pub struct ThreadsArg {
    /// Run the attempts of a relocalization on N threads (default: every
    /// core, or `RAYON_NUM_THREADS`). The result is the same, bit for bit,
    /// for every N; only the time changes.
    #[arg(long = "threads", value_name = "N", value_parser = clap::value_parser!(u16).range(1..=256))]
    pub threads: Option<u16>,
}

impl ThreadsArg {
    /// The threads asked for, else [`crate::workers::default_threads`].
    pub fn threads(self) -> usize {
        self.threads
            .map_or_else(crate::workers::default_threads, usize::from)
    }
}

/// `--change SPEC` and `--camera SPEC` of `vtsm scene export`, `demo` and
/// `eval`: how the live depot and the live camera differ from the mapped
/// depot and the ideal camera.
#[derive(Debug, Clone, Copy, Default, clap::Args)]
pub struct ConditionsArg {
    /// The depot changed since mapping: `none`, or a comma-separated list of
    /// `tracks=N` (rover passes, each two wheel tracks with tread, 0–8),
    /// `rocks=F` (fraction of the rocks moved 5–30 cm or taken away, 0–1) and
    /// `dust=F` (dust cover lowering albedo contrast, 0–0.9). Seeded by
    /// `--seed`; the map is made from the unchanged depot.
    #[arg(long, value_name = "SPEC", default_value = "none", value_parser = DepotChange::parse)]
    pub change: DepotChange,
    /// A camera that is not ideal: `none`, or a comma-separated list of
    /// `gain=G` (0.1–10), `mismatch=M` (right/left gain − 1, ±0.5),
    /// `noise=DN` (read noise, 0–50, with shot noise), `defocus=PX` (Gaussian
    /// σ, 0–10), `motion=PX` (blur length, 0–30), `motion-deg=D`,
    /// `vignetting=F` (0–0.9), `jpeg=Q` (1–100) and `compand` (12→8-bit
    /// square root). Noise seeded by `--seed`.
    #[arg(long, value_name = "SPEC", default_value = "none", value_parser = CameraEffects::parse)]
    pub camera: CameraEffects,
}

/// Parse the value of `--accuracy`: `T_MM,R_DEG`, 1-σ translation in
/// millimetres (0, 1000] and rotation in degrees (0, 10].
///
/// # Errors
/// Anything else, with what is accepted.
pub fn parse_accuracy(s: &str) -> std::result::Result<vtsm_core::reloc::Accuracy, String> {
    let bad = || {
        format!("`{s}` is not T_MM,R_DEG (1-σ millimetres in (0, 1000], degrees in (0, 10]), e.g. 5,0.1")
    };
    let (t, r) = s.split_once(',').ok_or_else(bad)?;
    let t: f32 = t.trim().parse().map_err(|_| bad())?;
    let r: f32 = r.trim().parse().map_err(|_| bad())?;
    let a = vtsm_core::reloc::Accuracy {
        sigma_t_m: t / 1000.0,
        sigma_r_deg: r,
    };
    if a.validate() {
        Ok(a)
    } else {
        Err(bad())
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
