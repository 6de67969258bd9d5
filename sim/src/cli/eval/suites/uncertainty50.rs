//! `uncertainty50`: priors 25–50 cm / ≤ 1.5°, from a single start that is
//! told the priors' real uncertainty ([`UNCERTAINTY_50`], served with the
//! prior as a `prior.json` `uncertainty` is, so the engine runs with it as
//! t̃₀, r̃₀), from a single start told nothing (the default t̃₀ 0.20 m,
//! `K=0 untold`), and with the multi-seed mode (`Params.seeds = K` seeds
//! spread over the same 0.50 m, t̃₀ 0.20 m; left out with `--seeds-k 0`);
//! first, a reference group with the paper's 10–20 cm priors on the same
//! captures (`ref 10-20cm`), so that the cost of the wider prior is measured
//! in the same run.

use super::{prior_group, terrain_hours, PriorSpec, SuiteDef};
use crate::cli::eval::config::SuiteConfig;
use crate::cli::eval::depot::Depot;
use crate::cli::eval::figures;
use crate::cli::eval::group::Group;
use crate::cli::eval::maps::MapEntry;
use crate::cli::eval::plot::{Figure, Style};
use crate::cli::eval::protocol::{PRIOR_50_M, UNCERTAINTY_50};
use crate::eval::TrialOutcome;
use vtsm_core::config::PriorUncertainty;

/// Wide priors, told or not, single start or multi-seed.
pub struct Uncertainty50;

/// The kinds of group, in table order.
fn kinds(cfg: &SuiteConfig) -> Vec<(String, PriorSpec)> {
    let wide = PriorSpec {
        prior_m: PRIOR_50_M,
        ..PriorSpec::PAPER
    };
    let mut kinds = vec![
        // The 10–20 cm reference on the same stops, so the cost of the wider
        // prior is measured in the same run.
        ("ref 10-20cm".to_string(), PriorSpec::PAPER),
        (
            format!("K=0 t0={:.2}m", UNCERTAINTY_50.t_m),
            PriorSpec {
                uncertainty: Some(UNCERTAINTY_50),
                ..wide
            },
        ),
        ("K=0 untold".to_string(), wide),
    ];
    if cfg.seeds_k > 0 {
        kinds.push((
            format!("K={}", cfg.seeds_k),
            PriorSpec {
                seeds: cfg.seeds_k,
                ..wide
            },
        ));
    }
    kinds
}

impl SuiteDef for Uncertainty50 {
    fn name(&self) -> &'static str {
        "uncertainty50"
    }

    fn default_hours(&self) -> Vec<f32> {
        vec![0.0]
    }

    fn groups(&self, cfg: &SuiteConfig, depot: &Depot, _maps: &[MapEntry]) -> Vec<Group> {
        let kinds = kinds(cfg);
        terrain_hours(cfg, depot)
            .into_iter()
            .flat_map(|(t, hi, base, h)| {
                kinds.iter().map(move |(name, spec)| {
                    prior_group(depot, (t, hi, h), format!("{base} {name}"), *spec)
                })
            })
            .collect()
    }

    fn prior_m(&self) -> (f32, f32) {
        PRIOR_50_M
    }

    fn stated_uncertainty(&self) -> Option<PriorUncertainty> {
        Some(UNCERTAINTY_50)
    }

    fn figures(
        &self,
        _cfg: &SuiteConfig,
        groups: &[(String, Style)],
        outcomes: &[TrialOutcome],
    ) -> Vec<Figure> {
        vec![figures::scatter(
            "final_vs_initial",
            "uncertainty50: final vs initial error",
            "initial translation error (mm)",
            groups,
            outcomes,
            |o| o.init_t_mm,
        )]
    }
}
