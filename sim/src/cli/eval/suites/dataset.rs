//! `dataset`: the stereo pairs of a data set on disk, one group per pair.
//! Its trials are run by [`crate::cli::eval::dataset`], which finds the
//! pairs; this definition draws and tabulates them.

use super::SuiteDef;
use crate::cli::eval::config::SuiteConfig;
use crate::cli::eval::depot::Depot;
use crate::cli::eval::figures;
use crate::cli::eval::group::Group;
use crate::cli::eval::maps::MapEntry;
use crate::cli::eval::plot::{Figure, Style};
use crate::error::{Error, Result};
use crate::eval::TrialOutcome;

/// A data set's pairs.
pub struct Dataset;

impl SuiteDef for Dataset {
    fn name(&self) -> &'static str {
        "dataset"
    }

    /// A data set's light is its own.
    fn default_hours(&self) -> Vec<f32> {
        Vec::new()
    }

    fn takes_baseline(&self) -> bool {
        true
    }

    fn check(&self, cfg: &SuiteConfig) -> Result<()> {
        match cfg.data {
            Some(_) => Ok(()),
            None => Err(Error::msg("--suite dataset needs --data DIR")),
        }
    }

    /// The simulated depot has no part in a data set's run: its groups come
    /// from the data set's pairs (`cli::eval::dataset`).
    fn groups(&self, _cfg: &SuiteConfig, _depot: &Depot, _maps: &[MapEntry]) -> Vec<Group> {
        Vec::new()
    }

    fn mapping_views(&self) -> &'static str {
        "none (a data set's map has no recorded mapping views)"
    }

    /// The final error against the prior's error, per pair.
    fn figures(
        &self,
        cfg: &SuiteConfig,
        groups: &[(String, Style)],
        outcomes: &[TrialOutcome],
    ) -> Vec<Figure> {
        vec![figures::scatter(
            "final_vs_prior_error",
            &format!("{}: final error vs the prior's error", cfg.suite.name()),
            "prior translation error (mm)",
            groups,
            outcomes,
            |o| o.init_t_mm,
        )]
    }
}
