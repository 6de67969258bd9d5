//! `baseline`: the `paper` suite with the 0.20 m stereo baseline.

use super::{prior_group, terrain_hours, PriorSpec, SuiteDef};
use crate::cli::eval::config::SuiteConfig;
use crate::cli::eval::depot::Depot;
use crate::cli::eval::figures;
use crate::cli::eval::group::Group;
use crate::cli::eval::maps::MapEntry;
use crate::cli::eval::plot::{Figure, Style};
use crate::cli::eval::protocol::SHORT_BASELINE_M;
use crate::eval::TrialOutcome;

/// The paper's terrains and time differences at the short baseline.
pub struct Baseline;

impl SuiteDef for Baseline {
    fn name(&self) -> &'static str {
        "baseline"
    }

    fn takes_baseline(&self) -> bool {
        true
    }

    fn groups(&self, cfg: &SuiteConfig, depot: &Depot, _maps: &[MapEntry]) -> Vec<Group> {
        let spec = PriorSpec {
            baseline_m: SHORT_BASELINE_M,
            ..PriorSpec::PAPER
        };
        terrain_hours(cfg, depot)
            .into_iter()
            .map(|(t, hi, base, h)| {
                let label = format!("{base} b={SHORT_BASELINE_M:.2}m");
                prior_group(depot, (t, hi, h), label, spec)
            })
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
