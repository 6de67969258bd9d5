//! The scene the file-path tests share: the flagstone test-profile depot
//! mapped at 9:30, one capture of it with a perturbed prior, and the scratch
//! folder it is written to as `vtsm scene export` writes it.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use vtsm_core::geom::{Pose, StereoRig};
use vtsm_sim::io::mesh::MeshData;
use vtsm_sim::scene::export::SceneFiles;
use vtsm_sim::scene::{perturbed_prior, Capture, Profile, Scene, StereoPair};
use vtsm_sim::terrain::TerrainKind;

/// Hour of the day the map is baked at (and the pairs are taken at).
pub const MAP_HOURS: f32 = 9.5;

/// One capture of a scene: the rig, the true pose, the pair and a prior
/// perturbed from the truth by the capture's seed.
pub struct Shot {
    /// The rig.
    pub rig: StereoRig,
    /// The true `world_from_left`.
    pub truth: Pose,
    /// The rectified stereo pair.
    pub pair: StereoPair,
    /// The prior, 10–20 cm and about 1° from the truth.
    pub prior: Pose,
}

impl Shot {
    /// The capture of `scene` at `stop` (0.40 m from the grid's pose) under
    /// `MAP_HOURS` light, its prior perturbed with `prior_seed`.
    pub fn take(scene: &Scene, stop: u32, prior_seed: u64) -> Self {
        let light = scene.lighting(MAP_HOURS);
        let (rig, truth, pair) = scene.capture(&light, &Capture::from_index(stop, 0, 0.40));
        let prior = perturbed_prior(&truth, prior_seed);
        Self {
            rig,
            truth,
            pair,
            prior,
        }
    }

    /// What `write_scene` writes for this shot against `map`, with `meta`.
    pub fn files<'a>(&'a self, map: &'a MeshData, meta: serde_json::Value) -> SceneFiles<'a> {
        SceneFiles {
            map,
            rig: &self.rig,
            left: &self.pair.left,
            right: &self.pair.right,
            prior: &self.prior,
            truth: &self.truth,
            meta,
            sun: None,
        }
    }
}

/// The flagstone test-profile scene of `seed`, its map baked at `MAP_HOURS`.
pub fn flagstone(seed: u64) -> (Scene, MeshData) {
    let scene = Scene::new(TerrainKind::Flagstone, seed, Profile::Test);
    let map = scene.map(&scene.lighting(MAP_HOURS));
    (scene, map)
}

/// The flagstone scene of `seed` and its capture at `stop`, the prior
/// perturbed with `seed`.
pub fn flagstone_shot(seed: u64, stop: u32) -> (MeshData, Shot) {
    let (scene, map) = flagstone(seed);
    let shot = Shot::take(&scene, stop, seed);
    (map, shot)
}

/// An empty scratch folder `<name>-<pid>-<seed>` under the test target's
/// temporary directory (removed first if an earlier run left it).
pub fn scratch_dir(name: &str, seed: u64) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("{name}-{}-{seed}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Distance, mm, of a `result.json`'s estimate to `truth`.
pub fn error_mm(r: &vtsm_sim::io::json::ResultFile, truth: &Pose) -> f64 {
    let t = r.world_from_left.unwrap().t;
    let tt = truth.t();
    (0..3)
        .map(|k| (t[k] - f64::from(tt[k])).powi(2))
        .sum::<f64>()
        .sqrt()
        * 1e3
}

/// `vtsm relocalize` arguments for a scene exported to `dir` (mesh and mask,
/// `calib.json`, `left.png`, `right.png`, the prior file `prior`), with
/// `seed` and every other option at its command-line default: no output
/// file, the default origin and tile size. Tests set what they vary with
/// struct update.
pub fn exported_args(dir: &Path, prior: &str, seed: u64) -> vtsm_sim::cli::relocalize::Args {
    vtsm_sim::cli::relocalize::Args {
        mesh: Some(dir.join("map.obj")),
        mask: Some(dir.join("mask.obj")),
        map: None,
        calib: dir.join("calib.json"),
        left: Some(dir.join("left.png")),
        right: Some(dir.join("right.png")),
        prior: Some(dir.join(prior)),
        pairs: None,
        seed,
        out: None,
        force: false,
        tile_size_m: vtsm_sim::cli::map_build::DEFAULT_TILE_SIZE_M,
        interp: vtsm_sim::rectify::Interp::Lanczos4,
        origin: None,
        verify: Default::default(),
        accuracy: Default::default(),
        final_pairs: Default::default(),
        search: Default::default(),
        map_scores: Default::default(),
        map_sun: None,
        threads: Default::default(),
    }
}
