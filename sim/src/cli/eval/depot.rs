//! The simulated depots of a run, built once and shared read-only by every
//! trial: one scene per terrain, its mapped mesh, the live scenes (after
//! `--wind`, and after each [`World`]'s change) and their lightings.

use super::config::SuiteConfig;
use super::protocol::WIND_SEED;
use crate::cli::demo::MAP_HOURS;
use crate::io::mesh::MeshData;
use crate::render::Lighting;
use crate::scene::Scene;
use crate::terrain::DepotChange;
use rayon::prelude::*;

/// A live depot a suite asks for besides its terrains × time differences:
/// terrain `terrain` after `change` (instead of `--change`, on top of
/// `--wind`), lit at local solar time `hours`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct World {
    /// Terrain index (into `--terrains`).
    pub terrain: usize,
    /// Local solar time of the live pairs, hours.
    pub hours: f32,
    /// How the depot changed since mapping.
    pub change: DepotChange,
}

/// The depots of a run.
pub struct Depot {
    /// One mapped scene per terrain, in `--terrains` order.
    pub scenes: Vec<Scene>,
    /// The mapped mesh of each scene (under the mapping lighting).
    pub meshes: Vec<MeshData>,
    /// The live scenes: one per terrain (the mapped one after `--wind` and
    /// `--change`), then one per distinct changed depot of the worlds, each
    /// with its terrain index; `None` where nothing changed (the mapped
    /// scene is the live one, not a copy of it).
    live: Vec<(usize, Option<Scene>)>,
    /// The time differences the live pairs are rendered at, hours.
    pub live_hours: Vec<f32>,
    /// Live lightings: terrain-major over `live_hours` ([`Depot::light_of`]),
    /// then one per world ([`Depot::world_light`]).
    pub lights: Vec<Lighting>,
    /// The live scene (index into `live`) each lighting belongs to.
    light_scene: Vec<usize>,
}

impl Depot {
    /// Build the scenes, meshes, live scenes and lightings of `cfg` for the
    /// time differences `live_hours` and the extra `worlds`.
    pub fn build(cfg: &SuiteConfig, live_hours: Vec<f32>, worlds: &[World]) -> Self {
        let scenes: Vec<Scene> = cfg
            .terrains
            .par_iter()
            .map(|&k| Scene::new(k, cfg.seed, cfg.profile).with_map_coarse(cfg.map_coarse))
            .collect();
        let meshes = mapped_meshes(cfg, &scenes);
        // Distinct (terrain, change) pairs, the run's own (`--change`) first.
        let mut kinds: Vec<(usize, DepotChange)> =
            (0..scenes.len()).map(|t| (t, cfg.change)).collect();
        for w in worlds {
            if !kinds.contains(&(w.terrain, w.change)) {
                kinds.push((w.terrain, w.change));
            }
        }
        let live: Vec<(usize, Option<Scene>)> = kinds
            .par_iter()
            .map(|&(t, change)| {
                let s = &scenes[t];
                let changed = cfg.wind > 0.0 || !change.is_none();
                (
                    t,
                    changed.then(|| s.live(cfg.wind, &change, s.seed ^ WIND_SEED)),
                )
            })
            .collect();
        let mut keys: Vec<(usize, f32)> = (0..scenes.len())
            .flat_map(|t| live_hours.iter().map(move |&h| (t, MAP_HOURS + h)))
            .collect();
        keys.extend(worlds.iter().map(|w| {
            let s = kinds
                .iter()
                .position(|k| *k == (w.terrain, w.change))
                .unwrap_or(w.terrain);
            (s, w.hours)
        }));
        let mut depot = Self {
            scenes,
            meshes,
            live,
            live_hours,
            lights: Vec::new(),
            light_scene: keys.iter().map(|k| k.0).collect(),
        };
        let lights: Vec<Lighting> = keys
            .par_iter()
            .map(|&(s, h)| depot.live_scene(s).lighting_with(h, cfg.light_model))
            .collect();
        depot.lights = lights;
        depot
    }

    /// Live scene `s` (index into `live`).
    fn live_scene(&self, s: usize) -> &Scene {
        match self.live.get(s) {
            Some((_, Some(changed))) => changed,
            Some((t, None)) => &self.scenes[*t],
            None => &self.scenes[0],
        }
    }

    /// The live scene lighting `light` belongs to.
    pub fn live_of(&self, light: usize) -> &Scene {
        self.live_scene(self.light_scene.get(light).copied().unwrap_or(0))
    }

    /// Index into [`Depot::lights`] of terrain `t` at time difference index `hi`.
    pub fn light_of(&self, t: usize, hi: usize) -> usize {
        t * self.live_hours.len() + hi
    }

    /// Index into [`Depot::lights`] of world `w` (in the order given to
    /// [`Depot::build`]).
    pub fn world_light(&self, w: usize) -> usize {
        self.scenes.len() * self.live_hours.len() + w
    }
}

/// Every scene's mesh under the mapping lighting, with every triangle in the
/// mask under `--mask all`.
fn mapped_meshes(cfg: &SuiteConfig, scenes: &[Scene]) -> Vec<MeshData> {
    scenes
        .par_iter()
        .map(|s| mapped_mesh(cfg, s, MAP_HOURS))
        .collect()
}

/// The mesh of `scene` mapped at local solar time `hours`, with every
/// triangle in the mask under `--mask all`.
pub fn mapped_mesh(cfg: &SuiteConfig, scene: &Scene, hours: f32) -> MeshData {
    let mut mesh = scene.map(&scene.lighting_with(hours, cfg.light_model));
    if cfg.mask_all {
        mesh.mask.iter_mut().for_each(|m| *m = true);
    }
    mesh
}
