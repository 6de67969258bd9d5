//! One module per suite behind [`SuiteDef`]: its groups (rows of the table),
//! the maps and lightings they need, the columns its trials write (through
//! each group's [`crate::eval::columns::GroupColumns`]), its figures and
//! notes. Every figure styles a group alike ([`super::figures::styles`]).
//! [`Suite::def`] is the registry, the one place a [`Suite`] is matched.

use super::config::{Suite, SuiteConfig};
use super::depot::{Depot, World};
use super::group::Group;
use super::maps::{MapEntry, Scoring};
use super::plot::{Figure, Style};
use super::protocol::PRIOR_M;
use crate::error::Result;
use crate::eval::TrialOutcome;
use crate::scene::{mapping_trajectory, Trajectory};
use rayon::prelude::*;
use vtsm_core::config::PriorUncertainty;

mod baseline;
mod dataset;
pub mod hard;
mod paper;
mod stepsize;
mod uncertainty50;
mod wrongplace;

/// What a suite runs and reports.
pub trait SuiteDef: Sync {
    /// Command-line name.
    fn name(&self) -> &'static str;

    /// Default time differences between mapping and capture, hours.
    fn default_hours(&self) -> Vec<f32> {
        vec![0.0, 3.0, 6.0]
    }

    /// Whether `--baseline` may run next to VTSM on this suite's trials.
    fn takes_baseline(&self) -> bool {
        false
    }

    /// Settings the suite cannot run without.
    ///
    /// # Errors
    /// What is missing.
    fn check(&self, _cfg: &SuiteConfig) -> Result<()> {
        Ok(())
    }

    /// The time differences the live pairs are rendered at, hours.
    fn live_hours(&self, cfg: &SuiteConfig) -> Vec<f32> {
        cfg.hours.clone()
    }

    /// Live depots besides the terrains × time differences (changed since
    /// mapping, or lit at another hour); groups reach them through
    /// [`Depot::world_light`]. None by default.
    fn worlds(&self, _cfg: &SuiteConfig) -> Vec<World> {
        Vec::new()
    }

    /// The map products: by default each terrain's whole map, with the 60
    /// views of the wave mapping path.
    fn maps(&self, cfg: &SuiteConfig, depot: &Depot) -> Vec<MapEntry> {
        full_maps(cfg, depot)
    }

    /// The groups, in table order.
    fn groups(&self, cfg: &SuiteConfig, depot: &Depot, maps: &[MapEntry]) -> Vec<Group>;

    /// The prior translation range recorded in the run's parameters, metres.
    fn prior_m(&self) -> (f32, f32) {
        PRIOR_M
    }

    /// The uncertainty some groups' priors state, recorded in the run's
    /// parameters.
    fn stated_uncertainty(&self) -> Option<PriorUncertainty> {
        None
    }

    /// The mapping step sizes recorded in the run's parameters.
    fn steps(&self, _cfg: &SuiteConfig) -> Vec<usize> {
        Vec::new()
    }

    /// What "nearest mapping view" is measured to.
    fn mapping_views(&self) -> &'static str {
        "wave mapping path, step 1 (60 views)"
    }

    /// The suite's figures besides the error CDF.
    fn figures(
        &self,
        _cfg: &SuiteConfig,
        _groups: &[(String, Style)],
        _outcomes: &[TrialOutcome],
    ) -> Vec<Figure> {
        Vec::new()
    }

    /// The suite's tables besides the summary, the tail and the integrity
    /// tables.
    fn notes(&self, _outcomes: &[TrialOutcome]) -> String {
        String::new()
    }
}

impl Suite {
    /// The suite's definition (the registry).
    pub fn def(self) -> &'static dyn SuiteDef {
        match self {
            Self::Paper => &paper::Paper,
            Self::Baseline => &baseline::Baseline,
            Self::Uncertainty50 => &uncertainty50::Uncertainty50,
            Self::Stepsize => &stepsize::Stepsize,
            Self::Wrongplace => &wrongplace::Wrongplace,
            Self::Dataset => &dataset::Dataset,
            Self::Hard => &hard::Hard,
        }
    }
}

/// Each terrain's whole map with the 60 views of the wave mapping path.
pub fn full_maps(cfg: &SuiteConfig, depot: &Depot) -> Vec<MapEntry> {
    depot
        .scenes
        .par_iter()
        .zip(&depot.meshes)
        .map(|(s, m)| {
            let views = mapping_trajectory(&s.terrain, Trajectory::Wave, 1);
            MapEntry::encode(m, cfg.origin, views, Scoring::of(cfg)).with_source(
                m,
                &crate::render::Sun::depot(crate::cli::demo::MAP_HOURS),
                cfg.relight,
            )
        })
        .collect()
}

/// `(terrain index, time difference index, group label prefix, hours)` of
/// every terrain × live time difference, terrain-major.
pub fn terrain_hours(cfg: &SuiteConfig, depot: &Depot) -> Vec<(usize, usize, String, f32)> {
    let mut out = Vec::new();
    for (t, kind) in cfg.terrains.iter().enumerate() {
        for (hi, &h) in depot.live_hours.iter().enumerate() {
            let base = format!("{} {}", kind.name(), super::protocol::hours_label(h));
            out.push((t, hi, base, h));
        }
    }
    out
}

/// The prior, baseline and start of a terrain × time difference group.
#[derive(Clone, Copy, Debug)]
pub struct PriorSpec {
    /// Stereo baseline of the live pairs, metres.
    pub baseline_m: f32,
    /// Prior translation range, metres.
    pub prior_m: (f32, f32),
    /// Pose seeds K of the multi-seed mode (0: single start).
    pub seeds: u16,
    /// The uncertainty the priors state (`None`: the engine's t̃₀, r̃₀).
    pub uncertainty: Option<PriorUncertainty>,
}

impl PriorSpec {
    /// The paper's: 0.40 m baseline, 10–20 cm priors, a single start told nothing.
    pub const PAPER: Self = Self {
        baseline_m: super::protocol::MAIN_BASELINE_M,
        prior_m: PRIOR_M,
        seeds: 0,
        uncertainty: None,
    };
}

/// The group `label` of terrain `t` at time difference index `hi` (`h` hours)
/// with prior `p`; its columns record t̃₀, r̃₀ the engine runs with (the
/// stated uncertainty or the profile's).
pub fn prior_group(
    depot: &Depot,
    (t, hi, h): (usize, usize, f32),
    label: String,
    p: PriorSpec,
) -> Group {
    let default_u = crate::locate::params_for_width(depot.scenes[t].camera().width()).uncertainty();
    let u = p.uncertainty.unwrap_or(default_u);
    let columns = crate::eval::columns::GroupColumns::Prior {
        hours: h,
        prior_max_m: p.prior_m.1,
        seeds_k: p.seeds,
        t0_m: u.t_m,
        r0_deg: u.r_deg,
    };
    Group::new(label, t, depot.light_of(t, hi), columns)
        .with_baseline(p.baseline_m)
        .with_prior(p.prior_m, p.seeds, p.uncertainty)
}
