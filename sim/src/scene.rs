//! Scenes: the paper's capture grid over a simulated depot, with ground truth.
//!
//! A [`Scene`] is a terrain generated for a [`Profile`] (image size, terrain cell size,
//! supersampling, map resolution). For a time of day it gives [`Lighting`]; for a
//! [`Capture`] of the grid of paper Fig. 4 (design §8: 15 stops on each of two 1.5 m
//! circles centred on the tubes, two orientations per stop looking at each tube,
//! baselines 0.40 m and 0.20 m, 77° HFOV, cameras 1 m above the ground) it gives the
//! rectified rig (`core::geom::StereoRig`), the truth pose `world_from_left` and the
//! rendered left/right 8-bit images. [`mapping_trajectory`] gives the mapping viewpoints
//! of the step-size study (§V-C: wave and forward paths, sub-sampled).
//!
//! Everything is a pure function of (terrain kind, seed, profile, hours, capture,
//! noise seed): the same inputs give byte-identical images.

use crate::mapping::{build_map, MappingOptions, MeshData};
use crate::render::{render, LightModel, Lighting, RenderOptions, Sun};
use crate::terrain::{DepotChange, Terrain, TerrainKind, TUBE_XY_M};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion};
use vtsm_core::geom::{Camera, Pose, StereoRig, Vec3};
use vtsm_core::rng::Rng;

pub mod export;
pub mod physical;

/// Horizontal field of view of every camera, degrees.
pub const HFOV_DEG: f32 = 77.0;
/// The two stereo baselines of the dataset, metres.
pub const BASELINES_M: [f32; 2] = [0.40, 0.20];
/// Height of the cameras above the ground, metres.
pub const CAMERA_HEIGHT_M: f32 = 1.0;
/// Radius of the capture circles around each tube, metres.
pub const CIRCLE_RADIUS_M: f32 = 1.5;
/// Stops per circle.
pub const STOPS_PER_CIRCLE: u32 = 15;
/// Smallest downward pitch of a capture camera, degrees (keeps the horizon near the top).
pub const MIN_PITCH_DEG: f32 = 22.0;
/// Capture times of the dataset: am, noon, pm (local solar hours).
pub const TIMES_H: [(&str, f32); 3] = [("am", 9.5), ("noon", 12.5), ("pm", 15.5)];

/// Image and map resolution profile.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Profile {
    /// The paper's 5472 × 3648 images, 5 mm terrain cells.
    Paper,
    /// 1368 × 912 images, 5 mm terrain cells.
    Demo,
    /// 480 × 320 images, 10 mm terrain cells, coarse map: for unit tests.
    Test,
}

impl Profile {
    /// Parse `paper`, `demo` or `test`.
    pub fn parse(s: &str) -> Option<Self> {
        match s.to_ascii_lowercase().as_str() {
            "paper" => Some(Self::Paper),
            "demo" => Some(Self::Demo),
            "test" => Some(Self::Test),
            _ => None,
        }
    }

    /// Name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Paper => "paper",
            Self::Demo => "demo",
            Self::Test => "test",
        }
    }

    /// Image size (width, height), pixels.
    pub fn image_size(self) -> (u32, u32) {
        match self {
            Self::Paper => (5472, 3648),
            Self::Demo => (1368, 912),
            Self::Test => (480, 320),
        }
    }

    /// Terrain cell size, metres.
    pub fn terrain_cell_m(self) -> f32 {
        match self {
            Self::Paper | Self::Demo => 0.005,
            Self::Test => 0.01,
        }
    }

    /// Supersampling factor per axis. At the paper profile a pixel is under a millimetre
    /// on the near ground, far finer than the terrain cells, so one ray per pixel suffices.
    pub fn supersample(self) -> u32 {
        match self {
            Self::Paper => 1,
            Self::Demo | Self::Test => 2,
        }
    }

    /// Map-making options for this profile (mesh ≈ 360k triangles at 2 cm; test ≈ 90k).
    pub fn mapping(self, seed: u64) -> MappingOptions {
        let base = MappingOptions {
            seed,
            ..MappingOptions::default()
        };
        match self {
            Self::Paper | Self::Demo => base,
            Self::Test => MappingOptions {
                vertex_m: 0.04,
                texel_m: 0.01,
                ..base
            },
        }
    }
}

/// Parse a time of day: `am`, `noon`, `pm` or decimal hours (0–24).
pub fn parse_hours(s: &str) -> Option<f32> {
    if let Some((_, h)) = TIMES_H.iter().find(|(n, _)| *n == s.to_ascii_lowercase()) {
        return Some(*h);
    }
    s.parse::<f32>()
        .ok()
        .filter(|h| h.is_finite() && (0.0..=24.0).contains(h))
}

/// One capture configuration of the grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Capture {
    /// Circle (0 or 1), i.e. the tube it is centred on.
    pub circle: u32,
    /// Stop on the circle, 0..15.
    pub stop: u32,
    /// Tube looked at (0 or 1).
    pub look_at: u32,
    /// Stereo baseline, metres.
    pub baseline_m: f32,
}

impl Capture {
    /// Stop `k` of the 30 (circle = k / 15), looking at `look_at`, with `baseline_m`.
    pub fn from_index(k: u32, look_at: u32, baseline_m: f32) -> Self {
        Self {
            circle: (k / STOPS_PER_CIRCLE).min(1),
            stop: k % STOPS_PER_CIRCLE,
            look_at: look_at.min(1),
            baseline_m,
        }
    }
}

/// The full grid: 2 baselines × 2 circles × 15 stops × 2 orientations = 120 captures.
pub fn capture_grid() -> Vec<Capture> {
    let mut v = Vec::with_capacity(120);
    for baseline_m in BASELINES_M {
        for k in 0..2 * STOPS_PER_CIRCLE {
            for look_at in 0..2 {
                v.push(Capture::from_index(k, look_at, baseline_m));
            }
        }
    }
    v
}

/// `world_from_cam` of a camera at `eye` looking along horizontal heading towards
/// `target`, pitched down by `pitch_rad` (no roll).
pub fn look_pose(eye: [f32; 3], target: [f32; 3], pitch_rad: f32) -> Pose {
    let (hx, hy) = (target[0] - eye[0], target[1] - eye[1]);
    let n = (hx * hx + hy * hy).sqrt().max(1e-6);
    let (hx, hy) = (hx / n, hy / n);
    let fwd = Vec3::new(hx * pitch_rad.cos(), hy * pitch_rad.cos(), -pitch_rad.sin());
    let right = fwd.cross(&Vec3::z()).normalize();
    let down = fwd.cross(&right);
    let m = Matrix3::from_columns(&[right, down, fwd]);
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m));
    Pose::new(q, Vec3::new(eye[0], eye[1], eye[2]))
}

/// Truth `world_from_left` of a capture over `terrain`: the rig centre stands on the
/// circle `CAMERA_HEIGHT_M` above the ground; the optical axis points at the tube
/// (pitch at least [`MIN_PITCH_DEG`]); the left camera sits half a baseline to the left.
pub fn capture_pose(terrain: &Terrain, c: &Capture) -> Pose {
    let centre = TUBE_XY_M[c.circle.min(1) as usize];
    // Stagger the two circles so their stops do not mirror each other.
    let theta =
        std::f32::consts::TAU * (c.stop as f32 + 0.5 * c.circle as f32) / STOPS_PER_CIRCLE as f32;
    let (x, y) = (
        centre[0] + CIRCLE_RADIUS_M * theta.cos(),
        centre[1] + CIRCLE_RADIUS_M * theta.sin(),
    );
    let eye = [x, y, terrain.height(x, y) + CAMERA_HEIGHT_M];
    let tube = terrain.tube_centre(c.look_at.min(1) as usize);
    let dist = ((tube[0] - x).powi(2) + (tube[1] - y).powi(2)).sqrt();
    let pitch = (eye[2] - tube[2])
        .atan2(dist)
        .max(MIN_PITCH_DEG.to_radians());
    let mid = look_pose(eye, tube, pitch);
    mid.compose(&Pose::new(
        UnitQuaternion::identity(),
        Vec3::new(-0.5 * c.baseline_m, 0.0, 0.0),
    ))
}

/// Mapping imaging trajectories of the step-size study (paper §V-C).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Trajectory {
    /// The rover weaves between the two tubes, imaging both.
    Wave,
    /// The rover drives along the depot, looking ahead only.
    Forward,
}

/// Viewpoints of a mapping trajectory, `world_from_left` of the 0.40 m pair, keeping every
/// `step`-th of 60 base viewpoints spaced about 0.32 m (step 6 ≈ 1.9 m, as in the paper).
pub fn mapping_trajectory(terrain: &Terrain, kind: Trajectory, step: usize) -> Vec<Pose> {
    let n = 60usize;
    let step = step.max(1);
    let mut poses = Vec::new();
    for k in (0..n).step_by(step) {
        let s = k as f32 / (n - 1) as f32;
        let (x, y, target) = match kind {
            Trajectory::Forward => {
                let y = -5.0 + 9.5 * s;
                (-0.8, y, [-0.8, y + 2.0, 0.0])
            }
            Trajectory::Wave => {
                let y = -4.5 + 9.0 * s;
                let x = 1.2 * (std::f32::consts::PI * y / 3.0).sin();
                let tube = if y < 0.0 { TUBE_XY_M[0] } else { TUBE_XY_M[1] };
                let t = if ((tube[0] - x).powi(2) + (tube[1] - y).powi(2)).sqrt() < 0.6 {
                    [x, y + 2.0]
                } else {
                    tube
                };
                (x, y, [t[0], t[1], 0.0])
            }
        };
        let eye = [x, y, terrain.height(x, y) + CAMERA_HEIGHT_M];
        let mid = look_pose(eye, target, 30f32.to_radians());
        poses.push(mid.compose(&Pose::new(
            UnitQuaternion::identity(),
            Vec3::new(-0.20, 0.0, 0.0),
        )));
    }
    poses
}

/// A rendered stereo pair.
#[derive(Clone, Debug, PartialEq)]
pub struct StereoPair {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Left image, row-major, stride = width.
    pub left: Vec<u8>,
    /// Right image, row-major, stride = width.
    pub right: Vec<u8>,
}

/// A simulated depot at one profile.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The terrain.
    pub terrain: Terrain,
    /// Profile.
    pub profile: Profile,
    /// Seed (terrain, map noise, sensor noise are forked from it).
    pub seed: u64,
    /// The map is made from imagery this many times coarser than the
    /// profile's: its vertex spacing and texel size are multiplied by it
    /// ([`MappingOptions::coarsened`]); 1 is the profile's map.
    pub map_coarse: u32,
}

impl Scene {
    /// Generate the depot of `kind` from `seed` at `profile`.
    pub fn new(kind: TerrainKind, seed: u64, profile: Profile) -> Self {
        Self {
            terrain: Terrain::generate(kind, seed, profile.terrain_cell_m()),
            profile,
            seed,
            map_coarse: 1,
        }
    }

    /// The map coarsening factors `--map-coarse` accepts.
    pub const MAP_COARSE: [u32; 4] = [1, 2, 4, 8];

    /// `k` if it is one of [`Self::MAP_COARSE`].
    ///
    /// # Errors
    /// Any other value, with what is accepted (bad input: exit 2).
    pub fn check_map_coarse(k: u32) -> crate::error::Result<u32> {
        if Self::MAP_COARSE.contains(&k) {
            Ok(k)
        } else {
            Err(crate::error::Error::msg(
                "--map-coarse must be 1, 2, 4 or 8",
            ))
        }
    }

    /// The same scene with its map made `k` times coarser (`k` ≥ 1: vertex
    /// spacing and texel size × `k`), as a map from a lander's descent
    /// camera or an older rover's would be; the live pairs are unchanged.
    pub fn with_map_coarse(self, k: u32) -> Self {
        Self {
            map_coarse: k.max(1),
            ..self
        }
    }

    /// The same depot as it is at capture time: after wind of `wind`
    /// ([`Terrain::with_wind`]) and then `change` ([`Terrain::with_change`]),
    /// both drawn from `seed`. The map is still made from `self`, so a change
    /// is what the map does not know. No wind and [`DepotChange::NONE`] give
    /// an identical scene.
    pub fn live(&self, wind: f32, change: &DepotChange, seed: u64) -> Scene {
        let mut terrain = if wind > 0.0 {
            self.terrain.with_wind(seed, wind)
        } else {
            self.terrain.clone()
        };
        if !change.is_none() {
            terrain = terrain.with_change(seed, change);
        }
        Scene {
            terrain,
            profile: self.profile,
            seed: self.seed,
            map_coarse: self.map_coarse,
        }
    }

    /// The profile's camera (77° HFOV, principal point at the centre).
    pub fn camera(&self) -> Camera {
        let (w, h) = self.profile.image_size();
        let f = (w as f32 * 0.5) / (HFOV_DEG.to_radians() * 0.5).tan();
        match Camera::new(f, f, (w as f32 - 1.0) * 0.5, (h as f32 - 1.0) * 0.5, w, h) {
            Ok(cam) => cam,
            // The three profiles are fixed data, each checked by
            // `every_profile_has_a_valid_rig`.
            Err(e) => unreachable!("profile {:?} camera refused: {e:?}", self.profile),
        }
    }

    /// The rectified rig with `baseline_m` (the paper's 0.20 or 0.40 m, or any
    /// positive finite value).
    pub fn rig(&self, baseline_m: f32) -> StereoRig {
        match StereoRig::new(self.camera(), baseline_m) {
            Ok(rig) => rig,
            Err(e) => unreachable!("baseline {baseline_m} m refused: {e:?}"),
        }
    }

    /// Lighting at local solar time `hours` (computes the shadow map).
    pub fn lighting(&self, hours: f32) -> Lighting {
        self.lighting_with(hours, LightModel::Full)
    }

    /// [`Scene::lighting`] with only the parts of the sunlight that `model` keeps.
    pub fn lighting_with(&self, hours: f32, model: LightModel) -> Lighting {
        Lighting::with_model(&self.terrain, Sun::depot(hours), model)
    }

    /// Render options of the profile with sensor noise seeded by `noise_seed`.
    pub fn render_options(&self, noise_seed: u64) -> RenderOptions {
        RenderOptions {
            supersample: self.profile.supersample(),
            noise_seed,
            ..RenderOptions::default()
        }
    }

    /// Render the stereo pair of `rig` at `world_from_left` with `opts` (the right
    /// image gets a different noise stream).
    pub fn render_pair(
        &self,
        light: &Lighting,
        rig: &StereoRig,
        world_from_left: &Pose,
        opts: &RenderOptions,
    ) -> StereoPair {
        let left = render(&self.terrain, light, &rig.cam(), world_from_left, opts);
        let ropts = RenderOptions {
            noise_seed: Rng::new(opts.noise_seed).fork(0x0052_4947_4854).next_u64(),
            ..*opts
        };
        let right = render(
            &self.terrain,
            light,
            &rig.cam(),
            &rig.world_from_right(world_from_left),
            &ropts,
        );
        StereoPair {
            width: rig.cam().width(),
            height: rig.cam().height(),
            left,
            right,
        }
    }

    /// Capture: rig, truth `world_from_left` and the rendered pair, with sensor noise
    /// seeded from the scene seed and the capture.
    pub fn capture(&self, light: &Lighting, c: &Capture) -> (StereoRig, Pose, StereoPair) {
        let rig = self.rig(c.baseline_m);
        let pose = capture_pose(&self.terrain, c);
        let noise_seed = Rng::new(self.seed)
            .fork(
                u64::from(c.circle * 100 + c.stop * 2 + c.look_at)
                    ^ (u64::from(c.baseline_m.to_bits()) << 20),
            )
            .next_u64();
        let pair = self.render_pair(light, &rig, &pose, &self.render_options(noise_seed));
        (rig, pose, pair)
    }

    /// The map product made under `light` (the mapping-time lighting).
    pub fn map(&self, light: &Lighting) -> MeshData {
        build_map(
            &self.terrain,
            light,
            &self
                .profile
                .mapping(self.seed ^ 0x4D41_5000)
                .coarsened(self.map_coarse),
        )
    }
}

/// A prior pose as in the paper's evaluation (design §8): truth perturbed by a translation
/// of 10–20 cm in a random direction and a rotation of up to 1.5° about a random axis.
pub fn perturbed_prior(truth: &Pose, seed: u64) -> Pose {
    let mut rng = Rng::new(seed).fork(0x50_5249_4F52);
    let dt = rng.unit_vector3() * rng.uniform(0.10, 0.20);
    let axis = rng.unit_vector3();
    let angle = rng.uniform(-1.5, 1.5).to_radians();
    let dq = UnitQuaternion::from_scaled_axis(axis * angle);
    Pose::new(dq * truth.rotation(), truth.translation() + dt)
}

#[cfg(test)]
mod tests;
