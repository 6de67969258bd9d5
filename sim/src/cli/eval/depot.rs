//! The simulated depots of a run, built once and shared read-only by every
//! trial: one scene per terrain, its mapped mesh, the live scenes (after
//! `--wind`) and one live lighting per terrain and time difference.

use super::config::SuiteConfig;
use super::protocol::WIND_SEED;
use crate::cli::demo::MAP_HOURS;
use crate::io::mesh::MeshData;
use crate::render::Lighting;
use crate::scene::Scene;
use rayon::prelude::*;

/// The depots of a run.
pub struct Depot {
    /// One mapped scene per terrain, in `--terrains` order.
    pub scenes: Vec<Scene>,
    /// The mapped mesh of each scene (under the mapping lighting).
    pub meshes: Vec<MeshData>,
    /// The live scenes: the mapped ones after `--wind` (empty without wind,
    /// the mapped ones are then live).
    windy: Vec<Scene>,
    /// The time differences the live pairs are rendered at, hours.
    pub live_hours: Vec<f32>,
    /// Live lightings, terrain-major: index [`Depot::light_of`].
    pub lights: Vec<Lighting>,
}

impl Depot {
    /// Build the scenes, meshes, live scenes and lightings of `cfg` for the
    /// time differences `live_hours`.
    pub fn build(cfg: &SuiteConfig, live_hours: Vec<f32>) -> Self {
        let scenes: Vec<Scene> = cfg
            .terrains
            .par_iter()
            .map(|&k| Scene::new(k, cfg.seed, cfg.profile).with_map_coarse(cfg.map_coarse))
            .collect();
        let meshes = mapped_meshes(cfg, &scenes);
        let windy: Vec<Scene> = if cfg.wind > 0.0 {
            scenes
                .par_iter()
                .map(|s| Scene {
                    terrain: s.terrain.with_wind(s.seed ^ WIND_SEED, cfg.wind),
                    ..*s
                })
                .collect()
        } else {
            Vec::new()
        };
        let live: &[Scene] = if windy.is_empty() { &scenes } else { &windy };
        let keys: Vec<(usize, f32)> = (0..scenes.len())
            .flat_map(|t| live_hours.iter().map(move |&h| (t, h)))
            .collect();
        let lights: Vec<Lighting> = keys
            .par_iter()
            .map(|&(t, h)| live[t].lighting_with(MAP_HOURS + h, cfg.light_model))
            .collect();
        Self {
            scenes,
            meshes,
            windy,
            live_hours,
            lights,
        }
    }

    /// The scenes the live pairs are taken in.
    pub fn live(&self) -> &[Scene] {
        if self.windy.is_empty() {
            &self.scenes
        } else {
            &self.windy
        }
    }

    /// Index into [`Depot::lights`] of terrain `t` at time difference index `hi`.
    pub fn light_of(&self, t: usize, hi: usize) -> usize {
        t * self.live_hours.len() + hi
    }
}

/// Every scene's mesh under the mapping lighting, with every triangle in the
/// mask under `--mask all`.
fn mapped_meshes(cfg: &SuiteConfig, scenes: &[Scene]) -> Vec<MeshData> {
    scenes
        .par_iter()
        .map(|s| {
            let mut mesh = s.map(&s.lighting_with(MAP_HOURS, cfg.light_model));
            if cfg.mask_all {
                mesh.mask.iter_mut().for_each(|m| *m = true);
            }
            mesh
        })
        .collect()
}
