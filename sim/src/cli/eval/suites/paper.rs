//! `paper`: flagstone, cfa6, cfa2 × time difference 0/3/6 h (map at 9.5 h),
//! 0.40 m baseline, priors 10–20 cm / ≤ 1.5°.

use super::{prior_group, terrain_hours, PriorSpec, SuiteDef};
use crate::cli::eval::config::SuiteConfig;
use crate::cli::eval::depot::Depot;
use crate::cli::eval::figures;
use crate::cli::eval::group::Group;
use crate::cli::eval::maps::MapEntry;
use crate::cli::eval::plot::{Figure, Style};
use crate::eval::TrialOutcome;

/// The paper's main results.
pub struct Paper;

impl SuiteDef for Paper {
    fn name(&self) -> &'static str {
        "paper"
    }

    fn takes_baseline(&self) -> bool {
        true
    }

    fn groups(&self, cfg: &SuiteConfig, depot: &Depot, _maps: &[MapEntry]) -> Vec<Group> {
        terrain_hours(cfg, depot)
            .into_iter()
            .map(|(t, hi, base, h)| prior_group(depot, (t, hi, h), base, PriorSpec::PAPER))
            .collect()
    }

    fn figures(
        &self,
        cfg: &SuiteConfig,
        groups: &[(String, Style)],
        outcomes: &[TrialOutcome],
    ) -> Vec<Figure> {
        figures::view_scatters(cfg, groups, outcomes)
    }
}
