//! `stepsize`: maps restricted to what sub-sampled wave and forward mapping
//! paths see (see [`restrict_to_views`]); reports range to the nearest view.

use super::SuiteDef;
use crate::cli::eval::config::SuiteConfig;
use crate::cli::eval::depot::Depot;
use crate::cli::eval::figures;
use crate::cli::eval::group::Group;
use crate::cli::eval::maps::{MapEntry, Scoring};
use crate::cli::eval::plot::{Figure, Style};
use crate::cli::eval::tables::{range_table, view_dist_m};
use crate::cli::eval::views::restrict_to_views;
use crate::error::{Error, Result};
use crate::eval::columns::GroupColumns;
use crate::eval::TrialOutcome;
use crate::scene::{mapping_trajectory, Trajectory};
use rayon::prelude::*;

/// Maps of sub-sampled mapping paths.
pub struct Stepsize;

/// `(terrain index, path, step)` of every map, terrain-major.
fn keys(cfg: &SuiteConfig, depot: &Depot) -> Vec<(usize, Trajectory, usize)> {
    let mut keys = Vec::new();
    for t in 0..depot.scenes.len() {
        for traj in [Trajectory::Wave, Trajectory::Forward] {
            for &step in &cfg.steps {
                keys.push((t, traj, step));
            }
        }
    }
    keys
}

impl SuiteDef for Stepsize {
    fn name(&self) -> &'static str {
        "stepsize"
    }

    fn check(&self, cfg: &SuiteConfig) -> Result<()> {
        if cfg.steps.is_empty() {
            return Err(Error::msg("the stepsize suite needs step sizes"));
        }
        Ok(())
    }

    /// Only the first time difference.
    fn live_hours(&self, cfg: &SuiteConfig) -> Vec<f32> {
        vec![cfg.hours.first().copied().unwrap_or(0.0)]
    }

    fn maps(&self, cfg: &SuiteConfig, depot: &Depot) -> Vec<MapEntry> {
        keys(cfg, depot)
            .par_iter()
            .map(|&(t, traj, step)| {
                let s = &depot.scenes[t];
                let views = mapping_trajectory(&s.terrain, traj, step);
                let mesh = restrict_to_views(&depot.meshes[t], &s.camera(), &views);
                MapEntry::encode(&mesh, cfg.origin, views, Scoring::of(cfg)).with_source(
                    &mesh,
                    &crate::render::Sun::depot(crate::cli::demo::MAP_HOURS),
                    cfg.relight,
                )
            })
            .collect()
    }

    fn groups(&self, cfg: &SuiteConfig, depot: &Depot, maps: &[MapEntry]) -> Vec<Group> {
        keys(cfg, depot)
            .into_iter()
            .enumerate()
            .map(|(m, (t, traj, step))| {
                let name = match traj {
                    Trajectory::Wave => "wave",
                    Trajectory::Forward => "forward",
                };
                let label = format!(
                    "{} {} step {} ({} views)",
                    cfg.terrains[t].name(),
                    name,
                    step,
                    maps[m].views.len()
                );
                let columns = GroupColumns::Step {
                    hours: depot.live_hours[0],
                    step,
                    forward: traj == Trajectory::Forward,
                };
                Group::new(label, t, depot.light_of(t, 0), columns).on_map(m)
            })
            .collect()
    }

    fn steps(&self, cfg: &SuiteConfig) -> Vec<usize> {
        cfg.steps.clone()
    }

    fn mapping_views(&self) -> &'static str {
        "sub-sampled mapping path of the group"
    }

    fn figures(
        &self,
        _cfg: &SuiteConfig,
        groups: &[(String, Style)],
        outcomes: &[TrialOutcome],
    ) -> Vec<Figure> {
        vec![figures::scatter(
            "final_vs_range",
            "stepsize: final error vs range to nearest mapping view",
            "range to nearest mapping view (m)",
            groups,
            outcomes,
            view_dist_m,
        )]
    }

    fn notes(&self, outcomes: &[TrialOutcome]) -> String {
        range_table(outcomes)
    }
}
