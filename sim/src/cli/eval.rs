//! `vtsm eval`: the evaluation suites of the paper (§V) on the simulated depot.
//!
//! Each suite is a list of groups (rows of the table). Every terrain's
//! [`Scene`], every map product and every lighting are built once and shared
//! read-only by all trials, which run in parallel through
//! [`crate::eval::run_parallel`]. A trial is one capture of the paper's grid
//! (stops spread over the 30), its live lighting, a perturbed prior with a
//! per-trial seed and one [`locate::relocalize`]. Trial `k` uses the same
//! capture and the same seed in every group, so groups are paired comparisons,
//! and everything is a function of `--seed`.
//!
//! Suites:
//! - `paper`: flagstone, cfa6, cfa2 × time difference 0/3/6 h (map at 9.5 h),
//!   0.40 m baseline, priors 10–20 cm / ≤ 1.5°.
//! - `baseline`: the same with the 0.20 m baseline.
//! - `uncertainty50`: priors 25–50 cm / ≤ 1.5°, from a single start that is
//!   told the priors' real uncertainty ([`UNCERTAINTY_50`], served with the
//!   prior as a `prior.json` `uncertainty` is, so the engine runs with it as
//!   t̃₀, r̃₀), from a single start told nothing (the default t̃₀ 0.20 m,
//!   `K=0 untold`), and with the multi-seed mode (`Params.seeds = K` seeds
//!   spread over the same 0.50 m, t̃₀ 0.20 m; left out with `--seeds-k 0`);
//!   first, a reference group with the paper's 10–20 cm priors on the same
//!   captures (`ref 10-20cm`), so that the cost of the wider prior is
//!   measured in the same run.
//! - `stepsize`: maps restricted to what sub-sampled wave and forward mapping
//!   paths see (see [`restrict_to_views`]); reports range to the nearest view.
//! - `wrongplace`: inputs that must not give a confident answer, per terrain:
//!   the correct pair with small parameters (N_corr 27, N_iter 1, reseed cap
//!   3; priors 10–20 cm), the same with a "right" image that is the left one
//!   shifted by [`SHIFT_PX`] pixels (prior at the truth), frames taken at
//!   another stop of the grid with the prior of this one, and frames of the
//!   next terrain's depot at this stop (two or more terrains).
//!
//! Every suite ends with an integrity table: successes, and successes whose
//! true error exceeds [`WRONG_T_MM`] or [`WRONG_R_DEG`] ("confident wrong";
//! on `wrongplace` frames of another depot, every success).
//!
//! `--origin X,Y,Z` offsets the whole scene (mesh, priors, truths) by that
//! vector: maps are built from the offset mesh through the file readers' path
//! (f64 vertices, f32 local vertices about the map origin; [`offset_mesh`]),
//! with the map origin at X,Y,Z, as `vtsm map build --origin X,Y,Z` would;
//! priors go into the map's local frame and estimates come back in f64, and
//! errors are measured in the offset frame. The local frame is then the
//! simulator's (`f64(v) + X − X = v` wherever the sum is exact), so the results
//! do not depend on the offset.
//!
//! `--physical` renders every live pair (and the `wrongplace` frames) in the
//! physical form of `vtsm scene export --physical`
//! ([`crate::scene::physical::capture_physical`]: same truth and sensor-noise
//! seeds), rectifies it with [`Rectifier::rectify_input`] as `vtsm relocalize`
//! does for an OpenCV calibration, and turns the estimate back to the physical
//! left camera ([`Rectifier::to_physical`]) before measuring its error.
//!
//! Two diagnostics change the simulated depot, not the engine: `--light-model`
//! takes cast shadows or attached shading out of the mapping-time and the live
//! lighting alike ([`LightModel`]), and `--mask all` puts every map triangle in
//! the sampling mask M̂ (the paper keeps only rocks on Flagstone and CFA6).
//! `--wind S` changes the live depot after mapping (`Terrain::with_wind`: sand
//! ripples, dust, moved pebbles), the maps staying those of the mapped one: what
//! the rock-only masks of the paper guard against. Their defaults (`full`,
//! `paper`, 0) are the suites as the paper ran them.
//!
//! "Mapping views" for the distance/angle columns of `paper`, `baseline` and
//! `uncertainty50` are the 60 viewpoints of the wave mapping path
//! ([`mapping_trajectory`] with step 1); for `stepsize` they are the
//! sub-sampled path the map was restricted to.

use crate::cli::demo::MAP_HOURS;
use crate::error::{Error, Result};
use crate::eval::{self, GroupSummary, RunMeta, Series, TrialOutcome};
use crate::io::calib::model::OpenCvCalib;
use crate::io::image::Gray8;
use crate::io::mesh::MeshData;
use crate::locate::{self, Request};
use crate::rectify::{Interp, Rectifier};
use crate::render::{LightModel, Lighting};
use crate::scene::physical::capture_physical;
use crate::scene::{
    mapping_trajectory, perturbed_prior, Capture, Profile, Scene, StereoPair, Trajectory,
    STOPS_PER_CIRCLE,
};
use crate::terrain::TerrainKind;
use nalgebra::UnitQuaternion;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;
use vtsm_core::config::PriorUncertainty;
use vtsm_core::geom::{Camera, Pose, StereoRig, Vec3};
use vtsm_core::rng::Rng;
use vtsm_hal::runner::VerifyChecks;

/// Stereo baseline of the paper's main results, metres.
pub const MAIN_BASELINE_M: f32 = 0.40;
/// Stereo baseline of the `baseline` suite, metres.
pub const SHORT_BASELINE_M: f32 = 0.20;
/// Prior translation range of `paper`, `baseline` and `stepsize`, metres.
pub const PRIOR_M: (f32, f32) = (0.10, 0.20);
/// Prior translation range of `uncertainty50`, metres.
pub const PRIOR_50_M: (f32, f32) = (0.25, 0.50);
/// The uncertainty the `uncertainty50` priors state in the single-start
/// group: the half-widths they are drawn within (0.50 m, 1.5°).
pub const UNCERTAINTY_50: PriorUncertainty = PriorUncertainty {
    t_m: PRIOR_50_M.1,
    r_deg: PRIOR_MAX_DEG,
};
/// A success whose true translation error exceeds this is confident wrong, mm:
/// the smallest displacement of the evaluation priors, so such an answer is
/// no better than the prior it started from.
pub const WRONG_T_MM: f64 = 100.0;
/// A success whose true rotation error exceeds this is confident wrong,
/// degrees: the largest rotation of the evaluation priors.
pub const WRONG_R_DEG: f64 = 1.5;
/// Shift of the "right" image of the `wrongplace` suite, pixels (test
/// profile; scaled with the image width).
pub const SHIFT_PX: u32 = 4;

/// Fork of a scene's seed that seeds its `--wind`.
pub const WIND_SEED: u64 = 0x5749_4E44_4556;

/// Largest prior rotation, degrees (all suites).
pub const PRIOR_MAX_DEG: f32 = 1.5;
/// A map triangle counts as seen by a mapping view when its centroid is within
/// this range of the view (and in its field of view, facing it).
pub const MAP_VIEW_RANGE_M: f32 = 3.0;
/// Map tile size used for every map product, metres (as `vtsm demo`).
pub const TILE_M: f32 = 0.5;

/// Arguments of `vtsm eval`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Suite: paper, baseline, uncertainty50, stepsize or wrongplace.
    #[arg(long)]
    pub suite: String,
    /// Trials per group.
    #[arg(long, default_value_t = 2)]
    pub trials: usize,
    /// Base seed (scenes, captures, priors and relocalizations derive from it).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Image profile: test (480×320), demo (1368×912) or paper (5472×3648).
    #[arg(long, default_value = "test")]
    pub profile: String,
    /// Output directory (default: the first free `vtsm-eval/<suite>-N`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Overwrite existing outputs in `--out`.
    #[arg(long)]
    pub force: bool,
    /// Comma-separated terrains (default: flagstone,cfa6,cfa2).
    #[arg(long)]
    pub terrains: Option<String>,
    /// Comma-separated time differences in hours (default: 0,3,6; `uncertainty50`: 0).
    #[arg(long)]
    pub hours: Option<String>,
    /// Comma-separated mapping step sizes for `stepsize` (default: 1,3,6,12).
    #[arg(long)]
    pub steps: Option<String>,
    /// Pose seeds K of the multi-seed mode in `uncertainty50` (0: no multi-seed group).
    #[arg(long, default_value_t = 16)]
    pub seeds_k: u16,
    /// Also run a baseline relocalizer on the same trials and report it next to
    /// VTSM: `features` (FAST + BRIEF + stereo + RANSAC; `paper` and `baseline`
    /// suites).
    #[arg(long)]
    pub baseline: Option<String>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Offset X,Y,Z (metres) of the whole scene: mesh, priors and truths, e.g.
    /// UTM coordinates; the results are the same.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub origin: Option<String>,
    /// `--verify [repeat,map]`: the engine's upset checks.
    #[command(flatten)]
    pub verify: super::VerifyArg,
    /// Live pairs in the physical form of `vtsm scene export --physical`
    /// (distorted, slightly rotated cameras, OpenCV calibration), rectified on
    /// the host as `vtsm relocalize` does; errors are those of the physical
    /// left camera.
    #[arg(long)]
    pub physical: bool,
    /// Kernel of the host rectification of `--physical` pairs: linear, cubic
    /// or lanczos4 (`cv2.remap`'s INTER_* of those names).
    #[arg(
        long,
        value_name = "KERNEL",
        default_value = "lanczos4",
        requires = "physical"
    )]
    pub interp: String,
    /// Parts of the sunlight the simulated depot has, at mapping and live time
    /// alike: full, no-cast-shadows, no-attached-shading or flat (neither; a
    /// diagnostic of how each part moves the error after a change of the time
    /// of day).
    #[arg(long, value_name = "MODEL", default_value = "full")]
    pub light_model: String,
    /// Sampling mask M̂ of the maps: `paper` (rocks only on flagstone and cfa6,
    /// everything on cfa2, as the paper) or `all` (every triangle).
    #[arg(long, value_name = "MASK", default_value = "paper")]
    pub mask: String,
    /// Wind between mapping and relocalization, strength 0..=1 (0: none): sand
    /// ripples, dust streaks and moved pebbles in the live depot
    /// (`Terrain::with_wind`); the maps stay those of the mapping-time depot.
    #[arg(long, value_name = "S", default_value_t = 0.0)]
    pub wind: f32,
}

/// A relocalizer evaluated on the suite's trials.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// The paper's method (the core's engine).
    Vtsm,
    /// The local-feature baseline ([`crate::features`]).
    Features,
}

impl Method {
    /// Parse a `--baseline` name (only baselines, not `vtsm`).
    pub fn parse_baseline(s: &str) -> Option<Self> {
        match s.to_ascii_lowercase().as_str() {
            "features" => Some(Self::Features),
            _ => None,
        }
    }

    /// Name used in the `method` column and in group labels.
    pub fn name(self) -> &'static str {
        match self {
            Self::Vtsm => "vtsm",
            Self::Features => "features",
        }
    }
}

/// The four suites.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Suite {
    /// Terrains × time differences, 0.40 m baseline.
    Paper,
    /// Terrains × time differences, 0.20 m baseline.
    Baseline,
    /// Priors 25–50 cm stating their uncertainty, single start and multi-seed.
    Uncertainty50,
    /// Maps restricted to sub-sampled mapping paths.
    Stepsize,
    /// Inputs that do not show the map from the prior.
    Wrongplace,
}

impl Suite {
    /// Parse a suite name.
    pub fn parse(s: &str) -> Option<Self> {
        match s.to_ascii_lowercase().as_str() {
            "paper" => Some(Self::Paper),
            "baseline" => Some(Self::Baseline),
            "uncertainty50" => Some(Self::Uncertainty50),
            "stepsize" => Some(Self::Stepsize),
            "wrongplace" => Some(Self::Wrongplace),
            _ => None,
        }
    }

    /// Command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Paper => "paper",
            Self::Baseline => "baseline",
            Self::Uncertainty50 => "uncertainty50",
            Self::Stepsize => "stepsize",
            Self::Wrongplace => "wrongplace",
        }
    }
}

/// Everything that defines a suite run.
#[derive(Clone, Debug)]
pub struct SuiteConfig {
    /// Suite.
    pub suite: Suite,
    /// Trials per group.
    pub trials: usize,
    /// Base seed.
    pub seed: u64,
    /// Image profile.
    pub profile: Profile,
    /// Terrains.
    pub terrains: Vec<TerrainKind>,
    /// Time differences between mapping and capture, hours.
    pub hours: Vec<f32>,
    /// Mapping step sizes (`stepsize` only).
    pub steps: Vec<usize>,
    /// Pose seeds K of the multi-seed mode (`uncertainty50` only).
    pub seeds_k: u16,
    /// Baseline run on the same trials next to VTSM (`paper` and `baseline` only).
    pub baseline: Option<Method>,
    /// Show a progress bar.
    pub progress: bool,
    /// Offset of the whole scene (`--origin`), `None` for the simulator's frame.
    pub origin: Option<[f64; 3]>,
    /// Upset checks of every VTSM trial (`--verify`).
    pub verify: VerifyChecks,
    /// Live pairs in the physical form, rectified on the host (`--physical`).
    pub physical: bool,
    /// Kernel of that rectification (`--interp`).
    pub interp: Interp,
    /// Parts of the sunlight the depot has (`--light-model`).
    pub light_model: LightModel,
    /// Every map triangle in the sampling mask (`--mask all`) instead of the
    /// paper's per-terrain masks.
    pub mask_all: bool,
    /// Wind strength between mapping and the live pairs (`--wind`, 0 = none).
    pub wind: f32,
}

impl SuiteConfig {
    /// The suite's defaults: all terrains, Δ 0/3/6 h (0 h for `uncertainty50`),
    /// steps 1/3/6/12, K = 16.
    pub fn new(suite: Suite, profile: Profile, trials: usize, seed: u64) -> Self {
        Self {
            suite,
            trials,
            seed,
            profile,
            terrains: TerrainKind::ALL.to_vec(),
            hours: if matches!(suite, Suite::Uncertainty50 | Suite::Wrongplace) {
                vec![0.0]
            } else {
                vec![0.0, 3.0, 6.0]
            },
            steps: vec![1, 3, 6, 12],
            seeds_k: 16,
            baseline: None,
            progress: false,
            origin: None,
            verify: VerifyChecks::OFF,
            physical: false,
            interp: Interp::default(),
            light_model: LightModel::Full,
            mask_all: false,
            wind: 0.0,
        }
    }
}

/// A finished suite run.
pub struct SuiteRun {
    /// Reproducibility record.
    pub meta: RunMeta,
    /// One outcome per trial, in group then trial order.
    pub outcomes: Vec<TrialOutcome>,
    /// One summary per group.
    pub groups: Vec<GroupSummary>,
    /// Extra Markdown (per-suite breakdowns) printed after the table.
    pub notes: String,
    /// SVG plots: (file name, SVG text).
    pub plots: Vec<(String, String)>,
    /// Wall time of building scenes, lightings and maps, seconds.
    pub setup_s: f64,
    /// Wall time of all trials, seconds.
    pub trials_s: f64,
}

/// One row of the table.
struct Group {
    label: String,
    terrain: usize,
    map: usize,
    light: usize,
    baseline_m: f32,
    prior_m: (f32, f32),
    seeds: u16,
    /// The uncertainty the priors state (`None`: the engine's t̃₀, r̃₀).
    uncertainty: Option<PriorUncertainty>,
    method: Method,
    extra: Vec<(&'static str, f64)>,
    /// What the relocalizer is given as frames.
    frames: Frames,
    /// Small parameters (N_corr 27, N_iter 1, reseed cap 3).
    small: bool,
}

/// The frames of a trial (`wrongplace` varies them).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Frames {
    /// The capture of the trial.
    Truth,
    /// The left image of the capture as both images, the right one shifted
    /// left by this many pixels; the prior is the truth.
    ShiftedRight(u32),
    /// The capture at the stop half the grid away, prior from this stop.
    OtherSpot,
    /// The capture at this stop in the depot of terrain index `.0`.
    OtherDepot(usize),
}

/// One map product and the mapping views its distances are measured to.
struct MapEntry {
    bytes: std::result::Result<Vec<u8>, String>,
    views: Vec<Pose>,
    /// The map's origin (user frame = the scene offset by `--origin`).
    origin: [f64; 3],
}

/// `mesh` (simulator frame) offset by `offset` and re-expressed as the file
/// readers do: f64 vertices in the offset frame, f32 vertices relative to
/// `origin` (`None`: the default origin, [`crate::frame::default_origin`]).
///
/// # Errors
/// An unusable origin, or a vertex out of f32 range about it.
pub fn offset_mesh(
    mesh: &MeshData,
    offset: [f64; 3],
    origin: Option<[f64; 3]>,
) -> Result<MeshData> {
    let user: Vec<[f64; 3]> = mesh
        .vertices
        .iter()
        .map(|v| [0, 1, 2].map(|k| f64::from(v[k]) + mesh.origin[k] + offset[k]))
        .collect();
    let origin = origin.unwrap_or_else(|| crate::frame::default_origin(&user));
    let vertices = crate::frame::local_vertices(&user, origin).map_err(Error::msg)?;
    Ok(MeshData {
        vertices,
        origin,
        ..mesh.clone()
    })
}

/// Encode a suite's map, offset by `--origin` when given; the bytes (or why
/// not) and the map's origin.
fn encode_entry(
    mesh: &MeshData,
    offset: Option<[f64; 3]>,
) -> (std::result::Result<Vec<u8>, String>, [f64; 3]) {
    let mesh = match offset {
        None => std::borrow::Cow::Borrowed(mesh),
        Some(o) => match offset_mesh(mesh, o, Some(o)) {
            Ok(m) => std::borrow::Cow::Owned(m),
            Err(e) => return (Err(e.to_string()), [0.0; 3]),
        },
    };
    (
        mesh.encode_map(TILE_M).map_err(|e| e.to_string()),
        mesh.origin,
    )
}

#[derive(Clone, Copy)]
struct Spec {
    group: usize,
    k: usize,
}

/// Capture `k` of `n`: stops spread evenly over the 30 (then cycling), the
/// looked-at tube alternating.
pub fn capture_for_trial(k: usize, n: usize, baseline_m: f32) -> Capture {
    let stops = (2 * STOPS_PER_CIRCLE) as usize;
    let stop = if n <= stops {
        k * stops / n.max(1)
    } else {
        k % stops
    };
    let look_at = (k + k / stops) % 2;
    Capture::from_index(stop as u32, look_at as u32, baseline_m)
}

/// Seed of trial `k` (the same in every group of a run).
pub fn trial_seed(base: u64, k: usize) -> u64 {
    Rng::new(base)
        .fork(0x4556_414C ^ ((k as u64) << 32))
        .next_u64()
}

/// A prior: truth displaced by `lo..hi` metres in a random direction and rotated
/// by up to [`PRIOR_MAX_DEG`] about a random axis. The paper's 10–20 cm range is
/// exactly [`perturbed_prior`].
pub fn prior_in_range(truth: &Pose, seed: u64, (lo, hi): (f32, f32)) -> Pose {
    if (lo, hi) == PRIOR_M {
        return perturbed_prior(truth, seed);
    }
    let mut rng = Rng::new(seed).fork(0x0050_5249_4F52_3530);
    let dt = rng.unit_vector3() * rng.uniform(lo, hi);
    let axis = rng.unit_vector3();
    let angle = rng.uniform(-PRIOR_MAX_DEG, PRIOR_MAX_DEG).to_radians();
    let dq = UnitQuaternion::from_scaled_axis(axis * angle);
    Pose::new(dq * truth.rotation(), truth.translation() + dt)
}

/// Distance (m) to the nearest of `views` (by camera centre) and the angle (°)
/// between its optical axis and that of `pose`. `None` without views.
pub fn nearest_view(pose: &Pose, views: &[Pose]) -> Option<(f64, f64)> {
    let c = pose.translation();
    let v = views.iter().min_by(|a, b| {
        (a.translation() - c)
            .norm()
            .total_cmp(&(b.translation() - c).norm())
    })?;
    let z = Vec3::z();
    let (a, b) = (pose.rotation() * z, v.rotation() * z);
    let angle = f64::from(a.dot(&b).clamp(-1.0, 1.0)).acos().to_degrees();
    Some((f64::from((v.translation() - c).norm()), angle))
}

/// Whether the triangle `(a, b, c)` is seen by a camera `cam` at `world_from_cam`:
/// centroid in front, within `range_m`, inside the image, and the triangle's
/// upward-oriented normal facing the camera. Occlusion is not tested.
pub fn seen_by(cam: &Camera, world_from_cam: &Pose, tri: [Vec3; 3], range_m: f32) -> bool {
    let centroid = (tri[0] + tri[1] + tri[2]) / 3.0;
    let eye = world_from_cam.translation();
    let to_eye = eye - centroid;
    if to_eye.norm() > range_m {
        return false;
    }
    let mut n = (tri[1] - tri[0]).cross(&(tri[2] - tri[0]));
    if n.z < 0.0 {
        n = -n;
    }
    if n.dot(&to_eye) <= 0.0 {
        return false;
    }
    let p = world_from_cam.inverse().transform_point(&centroid);
    if p.z <= 0.0 {
        return false;
    }
    cam.project(&p)
        .is_some_and(|[u, v]| cam.contains(u, v, 0.0))
}

/// The map as the views would have made it: keep only triangles [`seen_by`] at
/// least one view within [`MAP_VIEW_RANGE_M`]; vertices and texture are kept
/// whole (unreferenced vertices cost nothing to the core).
pub fn restrict_to_views(mesh: &MeshData, cam: &Camera, views: &[Pose]) -> MeshData {
    let mut out = MeshData {
        vertices: mesh.vertices.clone(),
        triangles: Vec::new(),
        uvs: Vec::new(),
        mask: Vec::new(),
        texture: mesh.texture.clone(),
        origin: mesh.origin,
    };
    let vert = |i: u32| {
        mesh.vertices
            .get(i as usize)
            .map_or(Vec3::zeros(), |p| Vec3::new(p[0], p[1], p[2]))
    };
    for ((t, uv), m) in mesh.triangles.iter().zip(&mesh.uvs).zip(&mesh.mask) {
        let tri = [vert(t[0]), vert(t[1]), vert(t[2])];
        if views.iter().any(|v| seen_by(cam, v, tri, MAP_VIEW_RANGE_M)) {
            out.triangles.push(*t);
            out.uvs.push(*uv);
            out.mask.push(*m);
        }
    }
    out
}

fn parse_list<T: std::str::FromStr>(s: &str, what: &str) -> Result<Vec<T>> {
    s.split(',')
        .map(|x| {
            x.trim()
                .parse::<T>()
                .map_err(|_| Error::msg(format!("bad {what} `{x}`")))
        })
        .collect()
}

fn hours_label(h: f32) -> String {
    format!("Δ{}h", h)
}

/// Build the config from command-line arguments.
///
/// # Errors
/// An unknown suite, profile or terrain, or a malformed list.
pub fn config_from_args(args: &Args) -> Result<SuiteConfig> {
    let suite = Suite::parse(&args.suite).ok_or_else(|| {
        Error::msg(format!(
            "unknown --suite `{}` (paper, baseline, uncertainty50, stepsize, wrongplace)",
            args.suite
        ))
    })?;
    let profile = Profile::parse(&args.profile).ok_or_else(|| {
        Error::msg(format!(
            "unknown --profile `{}` (test, demo, paper)",
            args.profile
        ))
    })?;
    if args.trials == 0 {
        return Err(Error::msg("--trials must be at least 1"));
    }
    let mut cfg = SuiteConfig::new(suite, profile, args.trials, args.seed);
    if let Some(t) = &args.terrains {
        cfg.terrains = t
            .split(',')
            .map(|n| {
                TerrainKind::parse(n.trim()).ok_or_else(|| {
                    Error::msg(format!("unknown terrain `{n}` (flagstone, cfa6, cfa2)"))
                })
            })
            .collect::<Result<_>>()?;
    }
    if let Some(h) = &args.hours {
        cfg.hours = parse_list(h, "hours")?;
        if cfg
            .hours
            .iter()
            .any(|h| !(h.is_finite() && (0.0..=8.0).contains(h)))
        {
            return Err(Error::msg("--hours must be between 0 and 8"));
        }
    }
    if let Some(s) = &args.steps {
        cfg.steps = parse_list(s, "step")?;
        if cfg.steps.iter().any(|&s| s == 0 || s > 60) {
            return Err(Error::msg("--steps must be 1..=60"));
        }
    }
    if usize::from(args.seeds_k) > vtsm_core::config::MAX_SEEDS {
        return Err(Error::msg(format!(
            "--seeds-k must be at most {}",
            vtsm_core::config::MAX_SEEDS
        )));
    }
    cfg.seeds_k = args.seeds_k;
    if let Some(b) = &args.baseline {
        let m = Method::parse_baseline(b)
            .ok_or_else(|| Error::msg(format!("unknown --baseline `{b}` (features)")))?;
        if !matches!(suite, Suite::Paper | Suite::Baseline) {
            return Err(Error::msg(
                "--baseline runs with the paper and baseline suites only",
            ));
        }
        cfg.baseline = Some(m);
    }
    cfg.progress = !args.quiet;
    cfg.origin = args
        .origin
        .as_deref()
        .map(crate::frame::parse_origin)
        .transpose()?;
    cfg.verify = args.verify.checks();
    cfg.physical = args.physical;
    cfg.interp = Interp::parse(&args.interp).map_err(Error::msg)?;
    cfg.light_model = LightModel::parse(&args.light_model).ok_or_else(|| {
        Error::msg(format!(
            "unknown --light-model `{}` (full, no-cast-shadows, no-attached-shading, flat)",
            args.light_model
        ))
    })?;
    cfg.mask_all = match args.mask.as_str() {
        "paper" => false,
        "all" => true,
        m => return Err(Error::msg(format!("unknown --mask `{m}` (paper, all)"))),
    };
    if !(0.0..=1.0).contains(&args.wind) {
        return Err(Error::msg("--wind must be a strength in 0..=1"));
    }
    cfg.wind = args.wind;
    Ok(cfg)
}

/// Run a suite: build the shared scenes, lightings and maps, run every trial,
/// summarize and draw the plots.
///
/// # Errors
/// Empty terrain/hour/step lists. Per-trial problems (a map that cannot be
/// encoded, a rejected request) are recorded as failed trials, not errors.
pub fn run_suite(cfg: &SuiteConfig, command: &str) -> Result<SuiteRun> {
    if cfg.terrains.is_empty() || cfg.hours.is_empty() || cfg.trials == 0 {
        return Err(Error::msg("a suite needs terrains, hours and trials"));
    }
    if cfg.suite == Suite::Stepsize && cfg.steps.is_empty() {
        return Err(Error::msg("the stepsize suite needs step sizes"));
    }
    let t_setup = Instant::now();
    let scenes: Vec<Scene> = cfg
        .terrains
        .par_iter()
        .map(|&k| Scene::new(k, cfg.seed, cfg.profile))
        .collect();
    let full_meshes: Vec<MeshData> = scenes
        .par_iter()
        .map(|s| {
            let mut mesh = s.map(&s.lighting_with(MAP_HOURS, cfg.light_model));
            if cfg.mask_all {
                mesh.mask.iter_mut().for_each(|m| *m = true);
            }
            mesh
        })
        .collect();
    let live_hours: Vec<f32> = if cfg.suite == Suite::Stepsize {
        vec![cfg.hours.first().copied().unwrap_or(0.0)]
    } else {
        cfg.hours.clone()
    };
    // Lightings: index = terrain * live_hours.len() + hour.
    // The live depots: the mapped ones after `--wind` (the same ones without it).
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
    let live_scenes: &[Scene] = if windy.is_empty() { &scenes } else { &windy };
    let light_keys: Vec<(usize, f32)> = (0..scenes.len())
        .flat_map(|t| live_hours.iter().map(move |&h| (t, h)))
        .collect();
    let lights: Vec<Lighting> = light_keys
        .par_iter()
        .map(|&(t, h)| live_scenes[t].lighting_with(MAP_HOURS + h, cfg.light_model))
        .collect();
    let light_of = |t: usize, hi: usize| t * live_hours.len() + hi;

    let maps: Vec<MapEntry>;
    let mut groups: Vec<Group> = Vec::new();
    let wave_views = |s: &Scene| mapping_trajectory(&s.terrain, Trajectory::Wave, 1);
    match cfg.suite {
        Suite::Paper | Suite::Baseline | Suite::Uncertainty50 | Suite::Wrongplace => {
            let full: Vec<MapEntry> = scenes
                .par_iter()
                .zip(&full_meshes)
                .map(|(s, m)| {
                    let (bytes, origin) = encode_entry(m, cfg.origin);
                    MapEntry {
                        bytes,
                        views: wave_views(s),
                        origin,
                    }
                })
                .collect();
            maps = full;
            for (t, kind) in cfg.terrains.iter().enumerate() {
                for (hi, &h) in live_hours.iter().enumerate() {
                    let base = format!("{} {}", kind.name(), hours_label(h));
                    if cfg.suite == Suite::Wrongplace {
                        let n = cfg.terrains.len();
                        let shift = SHIFT_PX * (scenes[t].camera().width() / 480).max(1);
                        let mut kinds = vec![
                            ("correct, small params".to_string(), Frames::Truth),
                            (
                                format!("right = left shifted {shift} px, small params"),
                                Frames::ShiftedRight(shift),
                            ),
                            ("another spot".to_string(), Frames::OtherSpot),
                            ("another spot, small params".to_string(), Frames::OtherSpot),
                        ];
                        if n > 1 {
                            let o = (t + 1) % n;
                            let other = cfg.terrains[o].name();
                            kinds.push((format!("{other} depot"), Frames::OtherDepot(o)));
                            kinds.push((
                                format!("{other} depot, small params"),
                                Frames::OtherDepot(o),
                            ));
                        }
                        for (name, frames) in kinds {
                            groups.push(Group {
                                small: name.ends_with("small params"),
                                label: format!("{base} {name}"),
                                terrain: t,
                                map: t,
                                light: light_of(t, hi),
                                baseline_m: MAIN_BASELINE_M,
                                prior_m: PRIOR_M,
                                seeds: 0,
                                uncertainty: None,
                                method: Method::Vtsm,
                                extra: vec![
                                    ("hours", f64::from(h)),
                                    (
                                        "wrong_place",
                                        f64::from(u8::from(matches!(
                                            frames,
                                            Frames::OtherDepot(_)
                                        ))),
                                    ),
                                ],
                                frames,
                            });
                        }
                        continue;
                    }
                    let default_u =
                        locate::params_for_width(scenes[t].camera().width()).uncertainty();
                    let mut push =
                        |label: String,
                         baseline_m,
                         prior_m,
                         seeds: u16,
                         uncertainty: Option<PriorUncertainty>| {
                            // t̃₀, r̃₀ the engine runs with (the stated uncertainty
                            // or the profile's), for the trials table.
                            let u = uncertainty.unwrap_or(default_u);
                            groups.push(Group {
                                label,
                                terrain: t,
                                map: t,
                                light: light_of(t, hi),
                                baseline_m,
                                prior_m,
                                seeds,
                                uncertainty,
                                method: Method::Vtsm,
                                extra: vec![
                                    ("hours", f64::from(h)),
                                    ("prior_max_m", f64::from(prior_m.1)),
                                    ("seeds_k", f64::from(seeds)),
                                    ("t0_m", f64::from(u.t_m)),
                                    ("r0_deg", f64::from(u.r_deg)),
                                ],
                                frames: Frames::Truth,
                                small: false,
                            });
                        };
                    match cfg.suite {
                        Suite::Paper => push(base, MAIN_BASELINE_M, PRIOR_M, 0, None),
                        Suite::Baseline => push(
                            format!("{base} b={SHORT_BASELINE_M:.2}m"),
                            SHORT_BASELINE_M,
                            PRIOR_M,
                            0,
                            None,
                        ),
                        _ => {
                            // The 10–20 cm reference on the same stops, so the
                            // cost of the wider prior is measured in the same run.
                            push(
                                format!("{base} ref 10-20cm"),
                                MAIN_BASELINE_M,
                                PRIOR_M,
                                0,
                                None,
                            );
                            push(
                                format!("{base} K=0 t0={:.2}m", UNCERTAINTY_50.t_m),
                                MAIN_BASELINE_M,
                                PRIOR_50_M,
                                0,
                                Some(UNCERTAINTY_50),
                            );
                            push(
                                format!("{base} K=0 untold"),
                                MAIN_BASELINE_M,
                                PRIOR_50_M,
                                0,
                                None,
                            );
                            if cfg.seeds_k > 0 {
                                push(
                                    format!("{base} K={}", cfg.seeds_k),
                                    MAIN_BASELINE_M,
                                    PRIOR_50_M,
                                    cfg.seeds_k,
                                    None,
                                );
                            }
                        }
                    }
                }
            }
        }
        Suite::Stepsize => {
            let mut keys = Vec::new();
            for t in 0..scenes.len() {
                for traj in [Trajectory::Wave, Trajectory::Forward] {
                    for &step in &cfg.steps {
                        keys.push((t, traj, step));
                    }
                }
            }
            maps = keys
                .par_iter()
                .map(|&(t, traj, step)| {
                    let s = &scenes[t];
                    let views = mapping_trajectory(&s.terrain, traj, step);
                    let mesh = restrict_to_views(&full_meshes[t], &s.camera(), &views);
                    let (bytes, origin) = encode_entry(&mesh, cfg.origin);
                    MapEntry {
                        bytes,
                        views,
                        origin,
                    }
                })
                .collect();
            for (m, &(t, traj, step)) in keys.iter().enumerate() {
                let name = match traj {
                    Trajectory::Wave => "wave",
                    Trajectory::Forward => "forward",
                };
                groups.push(Group {
                    label: format!(
                        "{} {} step {} ({} views)",
                        cfg.terrains[t].name(),
                        name,
                        step,
                        maps[m].views.len()
                    ),
                    terrain: t,
                    map: m,
                    light: light_of(t, 0),
                    baseline_m: MAIN_BASELINE_M,
                    prior_m: PRIOR_M,
                    seeds: 0,
                    uncertainty: None,
                    method: Method::Vtsm,
                    extra: vec![
                        ("hours", f64::from(live_hours[0])),
                        ("step", step as f64),
                        ("forward", f64::from(u8::from(traj == Trajectory::Forward))),
                    ],
                    frames: Frames::Truth,
                    small: false,
                });
            }
        }
    }
    if let Some(m) = cfg.baseline {
        groups = groups
            .into_iter()
            .flat_map(|g| {
                let b = Group {
                    label: format!("{} · {}", g.label, m.name()),
                    method: m,
                    extra: g.extra.clone(),
                    ..g
                };
                [g, b]
            })
            .collect();
    }
    let setup_s = t_setup.elapsed().as_secs_f64();

    let specs: Vec<Spec> = (0..groups.len())
        .flat_map(|g| (0..cfg.trials).map(move |k| Spec { group: g, k }))
        .collect();
    let t_trials = Instant::now();
    let outcomes = eval::run_parallel(
        &specs,
        |s| run_trial(cfg, &groups[s.group], live_scenes, &lights, &maps, s),
        cfg.progress,
    );
    let trials_s = t_trials.elapsed().as_secs_f64();
    let summary = eval::summarize(&outcomes);
    let params = locate::params_for_width(scenes[0].camera().width());
    let meta = RunMeta {
        suite: cfg.suite.name().to_string(),
        git_revision: eval::git_revision(),
        profile: cfg.profile.name().to_string(),
        seed: cfg.seed,
        trials: cfg.trials,
        physical: cfg.physical,
        params: serde_json::json!({
            "relocalization": format!("{params:?}"),
            "terrains": cfg.terrains.iter().map(|k| k.name()).collect::<Vec<_>>(),
            "hours": live_hours,
            "map_hours": MAP_HOURS,
            "steps": if cfg.suite == Suite::Stepsize { cfg.steps.clone() } else { Vec::new() },
            "seeds_k": cfg.seeds_k,
            "stated_uncertainty": if cfg.suite == Suite::Uncertainty50 {
                serde_json::json!({
                    "groups": "K=0",
                    "t_m": UNCERTAINTY_50.t_m,
                    "r_deg": UNCERTAINTY_50.r_deg,
                })
            } else {
                serde_json::Value::Null
            },
            "prior_m": if cfg.suite == Suite::Uncertainty50 { PRIOR_50_M } else { PRIOR_M },
            "prior_max_deg": PRIOR_MAX_DEG,
            "map_view_range_m": MAP_VIEW_RANGE_M,
            "tile_m": TILE_M,
            "light_model": cfg.light_model.name(),
            "mask": if cfg.mask_all { "all" } else { "paper" },
            "wind": cfg.wind,
            "rectify_interp": if cfg.physical { Some(cfg.interp.name()) } else { None },
            "baseline": cfg.baseline.map(Method::name),
            "origin": cfg.origin,
            "verify": {
                "repeat_solve": cfg.verify.repeat_solve,
                "recheck_map": cfg.verify.recheck_map,
            },
            "features": cfg.baseline.map(|_| {
                format!("{:?}", crate::features::FeatureParams::for_width(scenes[0].camera().width()))
            }),
            "mapping_views": if cfg.suite == Suite::Stepsize {
                "sub-sampled mapping path of the group"
            } else {
                "wave mapping path, step 1 (60 views)"
            },
        }),
        command: command.to_string(),
    };
    let (mut notes, plots) = breakdowns(cfg, &outcomes);
    if let Some(m) = cfg.baseline {
        notes = side_by_side(&summary, m) + &notes;
    }
    Ok(SuiteRun {
        meta,
        outcomes,
        groups: summary,
        notes,
        plots,
        setup_s,
        trials_s,
    })
}

fn run_trial(
    cfg: &SuiteConfig,
    g: &Group,
    scenes: &[Scene],
    lights: &[Lighting],
    maps: &[MapEntry],
    s: &Spec,
) -> TrialOutcome {
    let seed = trial_seed(cfg.seed, s.k);
    let capture = capture_for_trial(s.k, cfg.trials, g.baseline_m);
    let (scene, light, map) = (&scenes[g.terrain], &lights[g.light], &maps[g.map]);
    let (rig, here, mut pair, calib) = shoot(cfg.physical, scene, light, &capture);
    let mut prior = prior_in_range(&here, seed, g.prior_m);
    // `truth`: where the frames were taken (the errors are measured to it).
    let truth = match g.frames {
        Frames::Truth => here,
        Frames::ShiftedRight(d) => {
            pair.right = shifted_left(&pair.left, pair.width as usize, d as usize);
            prior = here;
            here
        }
        Frames::OtherSpot => {
            let stops = 2 * STOPS_PER_CIRCLE;
            let k = capture.circle * STOPS_PER_CIRCLE + capture.stop;
            let other = Capture {
                circle: ((k + stops / 2) % stops) / STOPS_PER_CIRCLE,
                stop: ((k + stops / 2) % stops) % STOPS_PER_CIRCLE,
                ..capture
            };
            let (_, there, p, _) = shoot(cfg.physical, scene, light, &other);
            pair = p;
            there
        }
        Frames::OtherDepot(o) => {
            let hours = live_hour_index(g.light, scenes.len(), lights.len());
            let (_, there, p, _) = shoot(
                cfg.physical,
                &scenes[o],
                &lights[o * hours.1 + hours.0],
                &capture,
            );
            pair = p;
            there
        }
    };
    // With --origin: truth and prior in the offset (user) frame, the prior given
    // to the relocalizer in the map's local frame, errors measured in f64.
    let truth_user = cfg
        .origin
        .map(|o| crate::frame::offset(&crate::frame::to_user(&truth, [0.0; 3]), o));
    let error = |est: &Pose| -> (f64, f64) {
        match &truth_user {
            None => {
                let (t, r) = est.error_to(&truth);
                (f64::from(t), f64::from(r))
            }
            Some(tu) => crate::frame::error_to(&crate::frame::to_user(est, map.origin), tu),
        }
    };
    let (prior, prior_rejected) = match cfg.origin {
        None => (prior, None),
        Some(o) => {
            // Translation through the offset frame in f64; the rotation is the
            // same in every frame, so it is kept as is (no renormalisation).
            let user = crate::io::json::PoseJson::from_local(&prior, o);
            let t = [0, 1, 2].map(|k| (user.t[k] - map.origin[k]) as f32);
            if t.iter().all(|c| c.is_finite()) {
                (
                    Pose::new(prior.rotation(), Vec3::new(t[0], t[1], t[2])),
                    None,
                )
            } else {
                (prior, Some(vtsm_core::FailureCode::MapOriginOutOfRange))
            }
        }
    };
    let (t0, r0) = error(&prior);
    let mut extra: BTreeMap<String, f64> = g
        .extra
        .iter()
        .map(|(k, v)| ((*k).to_string(), *v))
        .collect();
    extra.insert(
        "stop".into(),
        f64::from(capture.circle * STOPS_PER_CIRCLE + capture.stop),
    );
    extra.insert("look_at".into(), f64::from(capture.look_at));
    if let Some((d, a)) = nearest_view(&truth, &map.views) {
        extra.insert("view_dist_m".into(), d);
        extra.insert("view_angle_deg".into(), a);
    }
    let mut o = TrialOutcome {
        group: g.label.clone(),
        method: g.method.name().to_string(),
        trial: s.k,
        seed,
        success: false,
        failure: None,
        init_t_mm: t0 * 1e3,
        init_r_deg: r0.to_degrees(),
        final_t_mm: t0 * 1e3,
        final_r_deg: r0.to_degrees(),
        inliers: 0,
        iterations: 0,
        time_s: 0.0,
        extra,
    };
    let bytes = match &map.bytes {
        Ok(b) => b,
        Err(e) => {
            o.failure = Some(format!("map: {e}"));
            return o;
        }
    };
    if let Some(c) = prior_rejected {
        o.failure = Some(format!("prior in the map's frame: {}", c.name()));
        return o;
    }
    // A physical pair goes through `vtsm relocalize`'s path for an OpenCV
    // calibration: rectified on the host, the prior turned to the rectified
    // left camera, the estimate turned back to the physical one.
    let rectifier = match calib
        .as_ref()
        .map(|c| Rectifier::new(c).map(|r| r.with_interp(cfg.interp)))
        .transpose()
    {
        Ok(r) => r,
        Err(e) => {
            o.failure = Some(format!("rectification: {e}"));
            return o;
        }
    };
    let (rig, left, right, prior) = match &rectifier {
        Some(r) => {
            let gray = |pixels| Gray8 {
                width: pair.width,
                height: pair.height,
                pixels,
            };
            let (l, rr, p) = r.rectify_input(&gray(pair.left), &gray(pair.right), &prior);
            (r.rig, l.pixels, rr.pixels, p)
        }
        None => (rig, pair.left, pair.right, prior),
    };
    let as_physical = |est: &Pose| rectifier.as_ref().map_or(*est, |r| r.to_physical(est));
    let mut params = locate::params_for_width(rig.cam().width());
    params.seeds = g.seeds;
    if g.small {
        params.n_corr = 27;
        params.n_iter = 1;
        params.max_reseed = 3;
    }
    let req = Request {
        map: bytes,
        left: &left,
        right: &right,
        rig,
        prior,
        uncertainty: g.uncertainty,
        params,
        seed,
        verify: cfg.verify,
    };
    if g.method == Method::Features {
        let fp = crate::features::FeatureParams::for_width(rig.cam().width());
        match crate::features::relocalize_features(&req, &fp) {
            Ok(r) => {
                let (t1, r1) = error(&as_physical(&r.pose));
                o.success = r.failure.is_none();
                o.failure = r.failure;
                o.final_t_mm = t1 * 1e3;
                o.final_r_deg = r1.to_degrees();
                o.inliers = r.inliers;
                o.iterations = r.iterations;
                o.time_s = r.elapsed.as_secs_f64();
                for (k, v) in [
                    ("map_keypoints", r.map_keypoints),
                    ("live_keypoints", r.live_keypoints),
                    ("matches", r.matches),
                    ("stereo_points", r.stereo_points),
                ] {
                    o.extra.insert(k.into(), v as f64);
                }
            }
            Err(e) => o.failure = Some(format!("error: {e}")),
        }
        return o;
    }
    match locate::relocalize(&req) {
        Ok(r) => {
            let out = &r.outcome;
            let est = as_physical(&out.pose);
            let (t1, r1) = error(&est);
            o.success = out.failure.is_none();
            o.failure = out.failure.map(|c| c.name().to_string());
            o.final_t_mm = t1 * 1e3;
            o.final_r_deg = r1.to_degrees();
            o.inliers = u32::from(out.quality.inliers);
            o.iterations = u32::from(out.stats.successes);
            o.time_s = r.elapsed.as_secs_f64();
            // The engine's work counters, so a slow trial can be told apart
            // from a loaded machine.
            for (k, v) in [
                ("attempts", out.stats.attempts),
                ("stalls", u32::from(out.stats.stalls)),
                ("reseeds", u32::from(out.stats.reseeds)),
                ("focused_rounds", u32::from(out.stats.focused_rounds)),
                ("gradient_rounds", u32::from(out.stats.gradient_rounds)),
                ("refine_accepted", u32::from(out.stats.refine.accepted)),
            ] {
                o.extra.insert(k.into(), f64::from(v));
            }
            // What the integrity gates saw (the core's camera), to show their margins.
            let (dt, dr) = vtsm_core::reloc::integrity::distance_to(&prior, &out.pose);
            for (k, v) in [
                ("spread_m", out.quality.spread_m),
                ("reproj_px", out.quality.reproj_rms_px),
                ("prior_dt_m", dt),
                ("prior_dr_deg", dr.to_degrees()),
            ] {
                o.extra.insert(k.into(), f64::from(v));
            }
            if let Some(c) = &out.quality.covariance {
                // Its world-frame blocks hold for the physical camera too: the
                // same centre, a rotation differing by a fixed right factor.
                for (k, v) in covariance_check(&est, &truth, c) {
                    o.extra.insert(k.into(), v);
                }
            }
            // Which upset checks ran (1) or not (0), only when asked for.
            if cfg.verify.any() {
                let v = crate::cli::relocalize::verified(out, cfg.verify);
                for (k, ran) in [
                    ("verify_repeat_solve", v.repeat_solve),
                    ("verify_recheck_map", v.recheck_map),
                ] {
                    o.extra.insert(k.into(), f64::from(u8::from(ran)));
                }
            }
        }
        Err(e) => o.failure = Some(format!("error: {e}")),
    }
    o
}

/// One capture as the rig delivers it: the core's rig, the truth
/// `world_from_left`, the pair and, in the physical form
/// ([`capture_physical`], as `vtsm scene export --physical` writes it; same
/// truth and sensor-noise seeds as [`Scene::capture`]), the rig's OpenCV
/// calibration (the images are then distorted and unrectified).
fn shoot(
    physical: bool,
    scene: &Scene,
    light: &Lighting,
    c: &Capture,
) -> (StereoRig, Pose, StereoPair, Option<OpenCvCalib>) {
    if physical {
        let (calib, truth, pair) = capture_physical(scene, light, c);
        (scene.rig(c.baseline_m), truth, pair, Some(calib))
    } else {
        let (rig, truth, pair) = scene.capture(light, c);
        (rig, truth, pair, None)
    }
}

/// How the reported covariance covers the true error: squared Mahalanobis
/// distances of the world-frame position error `t_est − t_true` (3×3
/// translation block) and of the world-frame rotation vector `φ` with
/// `R_true = exp([φ]×) R_est` (rotation block), and the 1-σ radii
/// `√tr` of each block (mm, degrees).
pub fn covariance_check(
    est: &Pose,
    truth: &Pose,
    c: &vtsm_core::pose::Covariance,
) -> [(&'static str, f64); 4] {
    use nalgebra::{Matrix3, Vector3};
    let q64 = |p: &Pose| {
        let q = p.q();
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            f64::from(q[0]),
            f64::from(q[1]),
            f64::from(q[2]),
            f64::from(q[3]),
        ))
    };
    let t64 = |p: &Pose| {
        let t = p.t();
        Vector3::new(f64::from(t[0]), f64::from(t[1]), f64::from(t[2]))
    };
    let dt = t64(est) - t64(truth);
    let phi = (q64(truth) * q64(est).inverse()).scaled_axis();
    let block = |o: usize| Matrix3::from_fn(|i, j| f64::from(c.get(o + i, o + j)));
    let d2 = |e: Vector3<f64>, m: Matrix3<f64>| {
        m.try_inverse()
            .map_or(f64::NAN, |inv| (e.transpose() * inv * e)[(0, 0)])
    };
    [
        ("cov_d2_t", d2(dt, block(0))),
        ("cov_d2_r", d2(phi, block(3))),
        ("sigma_t_mm", block(0).trace().max(0.0).sqrt() * 1e3),
        ("sigma_r_deg", block(3).trace().max(0.0).sqrt().to_degrees()),
    ]
}

/// Which trials a plot series keeps.
type Keep = Box<dyn Fn(&TrialOutcome) -> bool>;

const COLORS: [&str; 6] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#17becf",
];

/// `img` (`width` wide) shifted left by `d` pixels, the last columns
/// repeating the edge: every pixel at disparity `d`.
fn shifted_left(img: &[u8], width: usize, d: usize) -> Vec<u8> {
    img.chunks(width.max(1))
        .flat_map(|row| (0..row.len()).map(move |x| row[(x + d).min(row.len() - 1)]))
        .collect()
}

/// (hour index, hours per terrain) of lighting index `light`, given that
/// lightings are laid out terrain-major over the same hours.
fn live_hour_index(light: usize, terrains: usize, lights: usize) -> (usize, usize) {
    let per = (lights / terrains.max(1)).max(1);
    (light % per, per)
}

fn extra(o: &TrialOutcome, k: &str) -> f64 {
    o.extra.get(k).copied().unwrap_or(f64::NAN)
}

/// Per-suite breakdown table and plots.
fn breakdowns(cfg: &SuiteConfig, outcomes: &[TrialOutcome]) -> (String, Vec<(String, String)>) {
    let mut plots = Vec::new();
    let mut notes = String::new();
    // The error distribution of every suite: one empirical CDF per group.
    let cdf = eval::error_cdf_series(outcomes);
    let cdf_series: Vec<Series> = cdf
        .iter()
        .enumerate()
        .map(|(i, (g, pts))| Series {
            name: g,
            color: COLORS[i % COLORS.len()],
            points: pts.clone(),
        })
        .collect();
    plots.push((
        "final_error_cdf.svg".to_string(),
        eval::svg_scatter(
            &format!(
                "{}: distribution of the final error (successful trials)",
                cfg.suite.name()
            ),
            "final translation error (mm)",
            "fraction of successes at or below",
            &cdf_series,
        ),
    ));
    match cfg.suite {
        Suite::Paper | Suite::Baseline => {
            for (file, key, xlabel) in [
                (
                    "final_vs_view_distance.svg",
                    "view_dist_m",
                    "distance to nearest mapping view (m)",
                ),
                (
                    "final_vs_view_angle.svg",
                    "view_angle_deg",
                    "angle to nearest mapping view (°)",
                ),
            ] {
                let mut series: Vec<Series> = cfg
                    .hours
                    .iter()
                    .zip(COLORS)
                    .map(|(&h, color)| Series {
                        name: "",
                        color,
                        points: outcomes
                            .iter()
                            .filter(|o| {
                                o.success && o.method == "vtsm" && extra(o, "hours") == f64::from(h)
                            })
                            .map(|o| (extra(o, key), o.final_t_mm))
                            .collect(),
                    })
                    .collect();
                let names: Vec<String> = cfg
                    .hours
                    .iter()
                    .map(|&h| format!("{} ok", hours_label(h)))
                    .collect();
                for (s, n) in series.iter_mut().zip(&names) {
                    s.name = n;
                }
                if let Some(m) = cfg.baseline {
                    series.push(Series {
                        name: m.name(),
                        color: "#7f7f7f",
                        points: outcomes
                            .iter()
                            .filter(|o| o.success && o.method == m.name())
                            .map(|o| (extra(o, key), o.final_t_mm))
                            .collect(),
                    });
                }
                let fail_pts: Vec<(f64, f64)> = outcomes
                    .iter()
                    .filter(|o| !o.success)
                    .map(|o| (extra(o, key), o.final_t_mm))
                    .collect();
                series.push(Series {
                    name: "failed",
                    color: "#d62728",
                    points: fail_pts,
                });
                plots.push((
                    file.to_string(),
                    eval::svg_scatter(
                        &format!("{}: final error vs nearest mapping view", cfg.suite.name()),
                        xlabel,
                        "final translation error (mm)",
                        &series,
                    ),
                ));
            }
        }
        Suite::Uncertainty50 => {
            // One series per kind of group (terrains together): the 50 cm
            // single start told 0.50 m, the one told nothing, the multi-seed
            // mode, and the 10–20 cm reference.
            let wide = f64::from(PRIOR_50_M.1);
            let told = f64::from(UNCERTAINTY_50.t_m);
            let k = f64::from(cfg.seeds_k);
            let mut kinds: Vec<(String, Keep)> = vec![
                (
                    format!("K=0 t0={told:.2}m ok"),
                    Box::new(move |o| {
                        extra(o, "prior_max_m") == wide
                            && extra(o, "seeds_k") == 0.0
                            && extra(o, "t0_m") == told
                    }),
                ),
                (
                    "K=0 untold ok".into(),
                    Box::new(move |o| {
                        extra(o, "prior_max_m") == wide
                            && extra(o, "seeds_k") == 0.0
                            && extra(o, "t0_m") != told
                    }),
                ),
            ];
            if cfg.seeds_k > 0 {
                kinds.push((
                    format!("K={} ok", cfg.seeds_k),
                    Box::new(move |o| extra(o, "seeds_k") == k),
                ));
            }
            kinds.push((
                "ref 10-20cm ok".into(),
                Box::new(move |o| extra(o, "prior_max_m") != wide),
            ));
            let mut series: Vec<Series> = kinds
                .iter()
                .zip(COLORS)
                .map(|((n, keep), color)| Series {
                    name: n,
                    color,
                    points: outcomes
                        .iter()
                        .filter(|o| o.success && keep(o))
                        .map(|o| (o.init_t_mm, o.final_t_mm))
                        .collect(),
                })
                .collect();
            let failed: Vec<(f64, f64)> = outcomes
                .iter()
                .filter(|o| !o.success)
                .map(|o| (o.init_t_mm, o.final_t_mm))
                .collect();
            series.push(Series {
                name: "failed",
                color: "#d62728",
                points: failed,
            });
            plots.push((
                "final_vs_initial.svg".into(),
                eval::svg_scatter(
                    "uncertainty50: final vs initial error",
                    "initial translation error (mm)",
                    "final translation error (mm)",
                    &series,
                ),
            ));
        }
        Suite::Stepsize => {
            let names = ["wave ok", "forward ok"];
            let mut series: Vec<Series> = [0.0, 1.0]
                .iter()
                .zip(names)
                .zip(COLORS)
                .map(|((&f, name), color)| Series {
                    name,
                    color,
                    points: outcomes
                        .iter()
                        .filter(|o| o.success && extra(o, "forward") == f)
                        .map(|o| (extra(o, "view_dist_m"), o.final_t_mm))
                        .collect(),
                })
                .collect();
            let failed: Vec<(f64, f64)> = outcomes
                .iter()
                .filter(|o| !o.success)
                .map(|o| (extra(o, "view_dist_m"), o.final_t_mm))
                .collect();
            series.push(Series {
                name: "failed",
                color: "#d62728",
                points: failed,
            });
            plots.push((
                "final_vs_range.svg".into(),
                eval::svg_scatter(
                    "stepsize: final error vs range to nearest mapping view",
                    "range to nearest mapping view (m)",
                    "final translation error (mm)",
                    &series,
                ),
            ));
            notes = range_table(outcomes);
        }
        Suite::Wrongplace => {}
    }
    notes.push_str(&integrity_table(outcomes));
    (notes, plots)
}

/// Codes of the integrity gates on the final estimate. They act only in the
/// last work unit, after the search, so a trial that ended in one of them is
/// exactly a trial that reported success before the gates existed.
pub const GATE_CODES: [&str; 3] = [
    "RELOC_POSE_OUTSIDE_PRIOR",
    "RELOC_INLIERS_DEGENERATE",
    "RELOC_RESIDUAL_HIGH",
];

/// Whether the trial would have reported success without the integrity gates.
pub fn success_without_gates(o: &TrialOutcome) -> bool {
    o.success
        || o.failure
            .as_deref()
            .is_some_and(|f| GATE_CODES.contains(&f))
}

/// Whether a trial whose success is `success` is a confident wrong answer: a
/// success whose true error exceeds [`WRONG_T_MM`] or [`WRONG_R_DEG`], or any
/// success on frames of another depot (extra `wrong_place` = 1).
pub fn confident_wrong(o: &TrialOutcome, success: bool) -> bool {
    success
        && (o.final_t_mm.is_nan()
            || o.final_t_mm > WRONG_T_MM
            || o.final_r_deg.is_nan()
            || o.final_r_deg > WRONG_R_DEG
            || extra(o, "wrong_place") == 1.0)
}

/// Per group: trials; successes and confident wrong answers without the
/// integrity gates (gate codes counted as successes) and with them; the
/// successes beyond 50 mm (the paper's accuracy threshold) for reference;
/// the failure codes.
pub fn integrity_table(outcomes: &[TrialOutcome]) -> String {
    let mut s = format!(
        "\nIntegrity: confident wrong = success with true error > {WRONG_T_MM} mm or > {WRONG_R_DEG}° (any success on another depot's frames); \"without gates\" counts the integrity-gate codes as successes (the acceptance before the gates, same trials):\n\n| group | trials | successes without gates | confident wrong without gates | successes | confident wrong | successes > 50 mm | failure codes |\n|---|---:|---:|---:|---:|---:|---:|---|\n"
    );
    let mut order: Vec<&str> = Vec::new();
    for o in outcomes {
        if !order.contains(&o.group.as_str()) {
            order.push(&o.group);
        }
    }
    let mut total = [0usize; 6];
    for g in order {
        let rows: Vec<&TrialOutcome> = outcomes.iter().filter(|o| o.group == g).collect();
        let before = rows.iter().filter(|o| success_without_gates(o)).count();
        let wrong_before = rows
            .iter()
            .filter(|o| confident_wrong(o, success_without_gates(o)))
            .count();
        let ok = rows.iter().filter(|o| o.success).count();
        let wrong = rows
            .iter()
            .filter(|o| confident_wrong(o, o.success))
            .count();
        let over = rows
            .iter()
            .filter(|o| o.success && o.final_t_mm > 50.0)
            .count();
        let mut codes: BTreeMap<&str, usize> = BTreeMap::new();
        for o in &rows {
            if let Some(f) = &o.failure {
                *codes.entry(f.as_str()).or_default() += 1;
            }
        }
        let codes: Vec<String> = codes.iter().map(|(c, n)| format!("{c} ×{n}")).collect();
        let _ = writeln!(
            s,
            "| {g} | {} | {before} | {wrong_before} | {ok} | {wrong} | {over} | {} |",
            rows.len(),
            codes.join(", ")
        );
        for (t, v) in total
            .iter_mut()
            .zip([rows.len(), before, wrong_before, ok, wrong, over])
        {
            *t += v;
        }
    }
    let [tt, tb, twb, ts, tw, t50] = total;
    let _ = writeln!(
        s,
        "| **all** | {tt} | {tb} | {twb} | {ts} | {tw} | {t50} | |"
    );
    s
}

/// VTSM and a baseline next to each other, one row per VTSM group (the
/// baseline's group is the next one, labelled `"<group> · <method>"`).
pub fn side_by_side(groups: &[GroupSummary], m: Method) -> String {
    let mut s = format!(
        "\nVTSM and the {0} baseline on the same trials:\n\n| group | VTSM success | VTSM final error (mm, median) | {0} success | {0} final error (mm, median) | {0} final error (mm, mean) |\n|---|---:|---:|---:|---:|---:|\n",
        m.name()
    );
    let num = |v: f64| {
        if v.is_finite() {
            format!("{v:.1}")
        } else {
            "—".to_string()
        }
    };
    for g in groups {
        let label = format!("{} · {}", g.group, m.name());
        let Some(b) = groups.iter().find(|b| b.group == label) else {
            continue;
        };
        let _ = writeln!(
            s,
            "| {} | {:.0} % | {} | {:.0} % | {} | {} |",
            g.group,
            g.success_pct,
            num(g.final_t_mm_median),
            b.success_pct,
            num(b.final_t_mm_median),
            num(b.final_t_mm_mean)
        );
    }
    s
}

/// Range bins (m) of the stepsize breakdown.
pub const RANGE_BINS_M: [f64; 6] = [0.0, 0.5, 1.0, 1.5, 2.0, 3.0];

/// Success and median final error by range to the nearest mapping view (Fig. 7d).
pub fn range_table(outcomes: &[TrialOutcome]) -> String {
    let mut s = String::from(
        "\nBy range to the nearest mapping view:\n\n| range (m) | trials | success | final error (mm, median of successes) |\n|---|---:|---:|---:|\n",
    );
    for (i, &lo) in RANGE_BINS_M.iter().enumerate() {
        let hi = RANGE_BINS_M.get(i + 1).copied().unwrap_or(f64::INFINITY);
        let rows: Vec<&TrialOutcome> = outcomes
            .iter()
            .filter(|o| {
                let d = extra(o, "view_dist_m");
                d >= lo && d < hi
            })
            .collect();
        if rows.is_empty() {
            continue;
        }
        let mut ok: Vec<f64> = rows
            .iter()
            .filter(|o| o.success)
            .map(|o| o.final_t_mm)
            .collect();
        ok.sort_by(f64::total_cmp);
        let med = match ok.len() {
            0 => "—".to_string(),
            m if m % 2 == 1 => format!("{:.1}", ok[m / 2]),
            m => format!("{:.1}", 0.5 * (ok[m / 2 - 1] + ok[m / 2])),
        };
        let range = if hi.is_finite() {
            format!("{lo:.1}–{hi:.1}")
        } else {
            format!("≥ {lo:.1}")
        };
        let _ = writeln!(
            s,
            "| {range} | {} | {:.0} % | {med} |",
            rows.len(),
            100.0 * ok.len() as f64 / rows.len() as f64
        );
    }
    s
}

/// Write `table.md` (with the breakdown appended), `trials.csv`, `summary.json`
/// and the plots into `dir`.
///
/// # Errors
/// As [`eval::write_outputs`].
pub fn write_run(dir: &Path, run: &SuiteRun, force: bool) -> Result<()> {
    eval::write_outputs(dir, &run.meta, &run.groups, &run.outcomes, force)?;
    if !run.notes.is_empty() {
        let table = eval::markdown_table(&run.meta, &run.groups) + &run.notes;
        eval::write_new(&dir.join("table.md"), &table, true)?;
    }
    for (name, svg) in &run.plots {
        eval::write_new(&dir.join(name), svg, force)?;
    }
    Ok(())
}

fn default_out(suite: Suite) -> PathBuf {
    (1..)
        .map(|k| PathBuf::from(format!("vtsm-eval/{}-{k}", suite.name())))
        .find(|p| !p.exists())
        .unwrap_or_else(|| PathBuf::from("vtsm-eval/run"))
}

/// Run the command; returns the exit code.
pub fn run(args: &Args) -> Result<u8> {
    let cfg = config_from_args(args)?;
    let out = args.out.clone().unwrap_or_else(|| default_out(cfg.suite));
    std::fs::create_dir_all(&out)
        .map_err(|e| Error::file(&out, format!("cannot create directory: {e}")))?;
    for name in ["table.md", "trials.csv", "summary.json"] {
        crate::io::check_output(&out.join(name), args.force)?;
    }
    let command = std::env::args().collect::<Vec<_>>().join(" ");
    let run = run_suite(&cfg, &command)?;
    print!("{}", eval::markdown_table(&run.meta, &run.groups));
    print!("{}", run.notes);
    println!(
        "setup (scenes, lightings, maps) {:.1} s; {} trials in {:.1} s wall on {} threads",
        run.setup_s,
        run.outcomes.len(),
        run.trials_s,
        rayon::current_num_threads()
    );
    write_run(&out, &run, args.force)?;
    println!("wrote {}", out.display());
    Ok(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small(suite: Suite) -> SuiteConfig {
        SuiteConfig {
            terrains: vec![TerrainKind::Flagstone],
            hours: vec![0.0],
            steps: vec![12],
            seeds_k: 4,
            ..SuiteConfig::new(suite, Profile::Test, 1, 7)
        }
    }

    fn median(mut v: Vec<f64>) -> f64 {
        v.sort_by(f64::total_cmp);
        match v.len() {
            0 => f64::NAN,
            n if n % 2 == 1 => v[n / 2],
            n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
        }
    }

    /// Check a run's outcomes, summaries and written files against each other.
    fn check_run(
        run: &SuiteRun,
        groups: usize,
        trials: usize,
        prior_mm: (f64, f64),
        plots: &[&str],
    ) {
        assert_eq!(run.groups.len(), groups);
        assert_eq!(run.outcomes.len(), groups * trials);
        for o in &run.outcomes {
            assert_eq!(o.success, o.failure.is_none(), "{o:?}");
            assert!(
                o.init_t_mm >= prior_mm.0 - 1e-3 && o.init_t_mm <= prior_mm.1 + 1e-3,
                "{o:?}"
            );
            assert!(o.init_r_deg <= f64::from(PRIOR_MAX_DEG) + 1e-3, "{o:?}");
            assert!(o.final_t_mm.is_finite() && o.final_t_mm >= 0.0);
            let d = o.extra["view_dist_m"];
            assert!(d.is_finite() && d >= 0.0, "{o:?}");
            if o.success {
                assert!(
                    o.iterations > 0 && o.inliers >= 3 && o.time_s > 0.0,
                    "{o:?}"
                );
            }
        }
        for g in &run.groups {
            let rows: Vec<&TrialOutcome> =
                run.outcomes.iter().filter(|o| o.group == g.group).collect();
            let ok: Vec<f64> = rows
                .iter()
                .filter(|o| o.success)
                .map(|o| o.final_t_mm)
                .collect();
            assert_eq!(g.trials, trials);
            assert_eq!(g.successes, ok.len());
            assert!((g.success_pct - 100.0 * ok.len() as f64 / trials as f64).abs() < 1e-9);
            let m = median(ok);
            assert!(m.is_nan() && g.final_t_mm_median.is_nan() || m == g.final_t_mm_median);
        }
        let dir = std::env::temp_dir().join(format!(
            "vtsm-eval-suite-{}-{}",
            run.meta.suite,
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        write_run(&dir, run, false).unwrap();
        // A second write without --force must refuse.
        assert!(write_run(&dir, run, false).is_err());
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap())
                .unwrap();
        assert_eq!(json["meta"]["suite"], run.meta.suite.as_str());
        assert_eq!(json["meta"]["profile"], "test");
        assert_eq!(json["meta"]["seed"], 7);
        assert!(!json["meta"]["git_revision"].as_str().unwrap().is_empty());
        assert!(json["meta"]["params"]["relocalization"]
            .as_str()
            .unwrap()
            .contains("template_px"));
        assert_eq!(json["trials"].as_array().unwrap().len(), run.outcomes.len());
        let csv = std::fs::read_to_string(dir.join("trials.csv")).unwrap();
        let mut lines = csv.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
        let (cs, cf, ce) = (col("success"), col("failure"), col("final_t_mm"));
        let rows: Vec<Vec<String>> = lines
            .map(|l| l.split(',').map(str::to_string).collect())
            .collect();
        assert_eq!(rows.len(), run.outcomes.len());
        for (r, o) in rows.iter().zip(&run.outcomes) {
            assert_eq!(r.len(), header.len());
            assert_eq!(r[cs] == "true", o.success);
            assert_eq!(r[cf].is_empty(), o.success);
            let e: f64 = r[ce].parse().unwrap();
            assert!((e - o.final_t_mm).abs() < 1e-3);
        }
        let table = std::fs::read_to_string(dir.join("table.md")).unwrap();
        for g in &run.groups {
            let row = format!("| {} | {} | {:.0} % |", g.group, g.trials, g.success_pct);
            assert!(table.contains(&row), "{row} not in\n{table}");
        }
        for p in plots {
            let svg = std::fs::read_to_string(dir.join(p)).unwrap();
            assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
            let dots = svg.matches("<circle").count();
            // One dot per trial plus one legend dot per series.
            assert!(dots >= run.outcomes.len(), "{p}: {dots} dots");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// Verifies: VTSM-CLI-019
    #[test]
    fn paper_and_baseline_suites_run_end_to_end_with_consistent_outputs() {
        let cfg = small(Suite::Paper);
        let run = run_suite(&cfg, "test").unwrap();
        check_run(
            &run,
            1,
            1,
            (100.0, 200.0),
            &["final_vs_view_distance.svg", "final_vs_view_angle.svg"],
        );
        // At Δ0 h on flagstone the paper's method converges.
        assert!(run.outcomes[0].success, "{:?}", run.outcomes[0]);
        assert!(run.outcomes[0].final_t_mm < run.outcomes[0].init_t_mm);
        let cfg = small(Suite::Baseline);
        let run = run_suite(&cfg, "test").unwrap();
        check_run(
            &run,
            1,
            1,
            (100.0, 200.0),
            &["final_vs_view_distance.svg", "final_vs_view_angle.svg"],
        );
        assert!(run.groups[0].group.contains("b=0.20m"));
    }

    /// Verifies: VTSM-CLI-022, VTSM-CLI-023
    #[test]
    fn feature_baseline_runs_on_the_same_trials_and_is_reported_side_by_side() {
        let cfg = SuiteConfig {
            baseline: Some(Method::Features),
            ..small(Suite::Paper)
        };
        let run = run_suite(&cfg, "test").unwrap();
        check_run(
            &run,
            2,
            1,
            (100.0, 200.0),
            &["final_vs_view_distance.svg", "final_vs_view_angle.svg"],
        );
        let (v, f) = (&run.outcomes[0], &run.outcomes[1]);
        assert_eq!((v.method.as_str(), f.method.as_str()), ("vtsm", "features"));
        assert_eq!(f.group, format!("{} · features", v.group));
        // Paired: same capture, seed and prior.
        assert_eq!(
            (v.seed, v.init_t_mm, v.extra["stop"]),
            (f.seed, f.init_t_mm, f.extra["stop"])
        );
        // A finite result or a clean, named failure.
        assert!(
            f.final_t_mm.is_finite() && f.final_r_deg.is_finite(),
            "{f:?}"
        );
        assert!(f.success || f.failure.as_deref().is_some_and(|c| !c.is_empty()));
        assert!(f.extra["live_keypoints"] > 0.0, "{f:?}");
        // The engine's work counters are recorded with each VTSM trial.
        assert!(v.extra["attempts"] >= 1.0, "{v:?}");
        assert!(v.extra.contains_key("stalls") && v.extra.contains_key("reseeds"));
        assert!(eval::csv(&run.outcomes)
            .lines()
            .next()
            .is_some_and(|h| h.contains(",attempts,")));
        assert!(run.notes.contains("VTSM and the features baseline"));
        assert!(run.notes.contains(&format!("| {} |", v.group)));
        // Deterministic.
        let again = run_suite(&cfg, "test").unwrap();
        assert_eq!(again.outcomes[1].final_t_mm, f.final_t_mm);
        assert_eq!(again.outcomes[1].failure, f.failure);
        // Only with the suites it is defined for, and only known names.
        let mut args = Args {
            suite: "uncertainty50".into(),
            trials: 1,
            seed: 1,
            profile: "test".into(),
            out: None,
            force: false,
            terrains: None,
            hours: None,
            steps: None,
            seeds_k: 4,
            baseline: Some("features".into()),
            quiet: true,
            origin: None,
            verify: crate::cli::VerifyArg::default(),
            physical: false,
            interp: "lanczos4".into(),
            light_model: "full".into(),
            mask: "paper".into(),
            wind: 0.0,
        };
        assert!(config_from_args(&args).is_err());
        args.suite = "baseline".into();
        let parsed = config_from_args(&args).unwrap();
        assert_eq!(parsed.baseline, Some(Method::Features));
        assert_eq!(
            (parsed.light_model, parsed.mask_all),
            (LightModel::Full, false)
        );
        args.light_model = "no-cast-shadows".into();
        args.mask = "all".into();
        let parsed = config_from_args(&args).unwrap();
        assert_eq!(
            (parsed.light_model, parsed.mask_all),
            (LightModel::NoCastShadows, true)
        );
        args.mask = "rocks".into();
        assert!(config_from_args(&args).is_err());
        args.mask = "paper".into();
        args.light_model = "overcast".into();
        assert!(config_from_args(&args).is_err());
        args.light_model = "full".into();
        args.wind = 1.5;
        assert!(config_from_args(&args).is_err());
        args.wind = 0.5;
        assert_eq!(config_from_args(&args).unwrap().wind, 0.5);
        args.baseline = Some("sift".into());
        assert!(config_from_args(&args).is_err());
    }

    /// `--wind` changes the live pairs and not the map or the priors (beyond the
    /// micrometres the ground under the rover moves); `--mask all` changes the
    /// map's mask and not the pairs or the priors.
    ///
    /// Verifies: VTSM-SIM-016
    #[test]
    fn wind_and_mask_change_only_what_they_name() {
        let base = SuiteConfig {
            terrains: vec![TerrainKind::Cfa6],
            ..small(Suite::Paper)
        };
        let plain = run_suite(&base, "test").unwrap();
        let windy = run_suite(
            &SuiteConfig {
                wind: 1.0,
                ..base.clone()
            },
            "test",
        )
        .unwrap();
        let masked = run_suite(
            &SuiteConfig {
                mask_all: true,
                ..base.clone()
            },
            "test",
        )
        .unwrap();
        for run in [&windy, &masked] {
            assert_eq!(run.outcomes.len(), plain.outcomes.len());
            for (a, b) in plain.outcomes.iter().zip(&run.outcomes) {
                // The rover stands on the live ground, which the wind moves by
                // millimetres, so the truth (and the prior drawn about it) may
                // move by a micrometre.
                assert_eq!(a.seed, b.seed);
                assert!((a.init_t_mm - b.init_t_mm).abs() < 1e-2, "{a:?} {b:?}");
            }
        }
        let finals = |r: &SuiteRun| {
            r.outcomes
                .iter()
                .map(|o| (o.final_t_mm, o.inliers))
                .collect::<Vec<_>>()
        };
        assert_ne!(finals(&plain), finals(&windy), "wind changed nothing");
        assert_ne!(finals(&plain), finals(&masked), "the mask changed nothing");
        assert_eq!(windy.meta.params["wind"], 1.0);
        assert_eq!(masked.meta.params["mask"], "all");
    }

    /// The paper suite with the whole scene offset to UTM-sized coordinates
    /// gives the same trials: same successes, seeds, inliers and iterations,
    /// errors within 1 µm / 10⁻⁴° (well inside 1 mm / 0.01°): the maps' origin
    /// is the offset, so the core's local inputs are the unshifted ones.
    ///
    /// Verifies: VTSM-CLI-037
    #[test]
    fn origin_offset_leaves_suite_results_unchanged() {
        let cfg = SuiteConfig {
            trials: 2,
            ..small(Suite::Paper)
        };
        let plain = run_suite(&cfg, "test").unwrap();
        let offset = [391_234.567_8, 3_784_321.987_6, 312.25];
        let moved = run_suite(
            &SuiteConfig {
                origin: Some(offset),
                ..cfg.clone()
            },
            "test",
        )
        .unwrap();
        assert_eq!(plain.outcomes.len(), moved.outcomes.len());
        assert!(
            plain.outcomes.iter().any(|o| o.success),
            "nothing to compare"
        );
        for (a, b) in plain.outcomes.iter().zip(&moved.outcomes) {
            assert_eq!(
                (a.seed, a.success, &a.failure),
                (b.seed, b.success, &b.failure)
            );
            assert!((a.init_t_mm - b.init_t_mm).abs() < 1e-3, "{a:?} {b:?}");
            // The core saw the same inputs: only the f64 error arithmetic differs.
            assert_eq!((a.inliers, a.iterations), (b.inliers, b.iterations));
            assert!((a.final_t_mm - b.final_t_mm).abs() < 1e-3, "{a:?} {b:?}");
            assert!((a.final_r_deg - b.final_r_deg).abs() < 1e-4, "{a:?} {b:?}");
            eprintln!(
                "trial {}: final {:.6} mm / {:.6}° vs {:.6} mm / {:.6}° (inliers {} vs {})",
                a.trial,
                a.final_t_mm,
                a.final_r_deg,
                b.final_t_mm,
                b.final_r_deg,
                a.inliers,
                b.inliers
            );
        }
        assert_eq!(moved.meta.params["origin"][0].as_f64(), Some(offset[0]));
        // The offset mesh at the offset's origin has the simulator's vertices
        // (all but coordinates within millimetres of 0 bit for bit); with the
        // default origin, the unshifted mesh's box centre plus the offset.
        let scene = Scene::new(TerrainKind::Flagstone, cfg.seed, cfg.profile);
        let map = scene.map(&scene.lighting(MAP_HOURS));
        let m = offset_mesh(&map, offset, Some(offset)).unwrap();
        let same = m
            .vertices
            .iter()
            .zip(&map.vertices)
            .filter(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits))
            .count();
        eprintln!("{same} of {} vertices bit for bit", map.vertices.len());
        assert!(same * 1000 >= map.vertices.len() * 999);
        for (a, b) in m.vertices.iter().zip(&map.vertices) {
            assert!(a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-8));
        }
        let c = offset_mesh(&map, [0.0; 3], None).unwrap().origin;
        let d = offset_mesh(&map, offset, None).unwrap();
        for ((o, s), c) in d.origin.iter().zip(offset).zip(c) {
            assert!((o - s - c).abs() < 1e-6, "{:?} vs {c}", d.origin);
        }
    }

    /// Verifies: VTSM-CLI-019, VTSM-CLI-021
    #[test]
    fn uncertainty_suite_pairs_k0_stating_the_uncertainty_and_k_seeds() {
        let run = run_suite(&small(Suite::Uncertainty50), "test").unwrap();
        check_run(&run, 4, 1, (100.0, 500.0), &["final_vs_initial.svg"]);
        // Groups in order: the 10–20 cm reference, K=0 told the uncertainty,
        // K=0 told nothing, K seeds.
        let [r, a, u, b] = [0, 1, 2, 3].map(|i| &run.outcomes[i]);
        assert!(r.group.contains("ref 10-20cm"), "{}", r.group);
        assert!((100.0..=200.0 + 1e-3).contains(&r.init_t_mm), "{r:?}");
        assert_eq!(r.extra["prior_max_m"], f64::from(PRIOR_M.1));
        // The reference relocalizes the same capture as the other groups.
        assert_eq!(r.seed, a.seed);
        // Paired: same capture and prior in the 50 cm groups, only what the
        // engine is told and K differ.
        for o in [u, b] {
            assert_eq!((a.seed, a.init_t_mm), (o.seed, o.init_t_mm));
            assert_eq!(o.extra["prior_max_m"], f64::from(PRIOR_50_M.1));
        }
        assert!(a.init_t_mm >= 250.0 - 1e-3, "{a:?}");
        assert_eq!((a.extra["seeds_k"], u.extra["seeds_k"]), (0.0, 0.0));
        assert_eq!(b.extra["seeds_k"], 4.0);
        // The single start is told the priors' real uncertainty, or nothing
        // (the default t̃₀); the multi-seed group keeps the default t̃₀ and
        // spreads its seeds instead.
        assert_eq!((a.extra["t0_m"], a.extra["r0_deg"]), (0.5, 1.5));
        for o in [r, u, b] {
            assert!((o.extra["t0_m"] - 0.2).abs() < 1e-6, "{:?}", o.extra);
        }
        assert!(a.group.contains("K=0 t0=0.50m"), "{}", a.group);
        assert!(u.group.contains("K=0 untold"), "{}", u.group);
        assert_eq!(run.meta.params["stated_uncertainty"]["t_m"], 0.5);
    }

    /// Verifies: VTSM-CLI-019, VTSM-CLI-020
    #[test]
    fn stepsize_suite_reports_range_breakdown() {
        let run = run_suite(&small(Suite::Stepsize), "test").unwrap();
        check_run(&run, 2, 1, (100.0, 200.0), &["final_vs_range.svg"]);
        assert!(run.notes.contains("By range"));
        let binned: usize = run
            .notes
            .lines()
            .filter(|l| l.starts_with("| ") && l.contains('–') || l.starts_with("| ≥"))
            .map(|l| {
                l.split('|')
                    .nth(2)
                    .unwrap()
                    .trim()
                    .parse::<usize>()
                    .unwrap()
            })
            .sum();
        assert_eq!(binned, run.outcomes.len());
    }

    /// Verifies: VTSM-CLI-020
    #[test]
    fn restricted_map_keeps_exactly_the_triangles_a_view_sees() {
        let scene_cam = Camera::new(100.0, 100.0, 49.5, 49.5, 100, 100).unwrap();
        // Camera at (0,0,1) looking straight down (cam z = -world z).
        let down = Pose::new(
            UnitQuaternion::from_axis_angle(&Vec3::x_axis(), std::f32::consts::PI),
            Vec3::new(0.0, 0.0, 1.0),
        );
        // Flat ground triangles centred at x = 0, 0.3, 0.8 (out of the ±0.5 FOV), 5 (out of range).
        let mut mesh = MeshData {
            vertices: Vec::new(),
            triangles: Vec::new(),
            uvs: Vec::new(),
            mask: Vec::new(),
            texture: crate::io::image::Gray8 {
                width: 1,
                height: 1,
                pixels: vec![0],
            },
            origin: [0.0; 3],
        };
        for (i, x) in [0.0f32, 0.3, 0.8, 5.0].iter().enumerate() {
            let n = mesh.vertices.len() as u32;
            mesh.vertices.extend([
                [x - 0.01, -0.01, 0.0],
                [x + 0.01, -0.01, 0.0],
                [*x, 0.01, 0.0],
            ]);
            mesh.triangles.push([n, n + 1, n + 2]);
            mesh.uvs.push([[0.0; 2]; 3]);
            mesh.mask.push(i % 2 == 0);
        }
        let kept = restrict_to_views(&mesh, &scene_cam, &[down]);
        // Reference: pinhole with f = 100 px over a 100 px image sees |x| < 0.5 at 1 m depth.
        assert_eq!(kept.triangles, vec![[0, 1, 2], [3, 4, 5]]);
        assert_eq!(kept.mask, vec![true, false]);
        assert_eq!(kept.vertices, mesh.vertices);
        // A camera below the ground sees nothing (the ground faces up).
        let under = Pose::new(UnitQuaternion::identity(), Vec3::new(0.0, 0.0, -1.0));
        assert!(restrict_to_views(&mesh, &scene_cam, &[under])
            .triangles
            .is_empty());
        // No views, no map.
        assert!(restrict_to_views(&mesh, &scene_cam, &[])
            .triangles
            .is_empty());
    }

    /// Verifies: VTSM-CLI-021
    #[test]
    fn priors_and_captures_follow_the_protocol() {
        let truth = Pose::new(
            UnitQuaternion::from_euler_angles(0.1, -0.4, 2.0),
            Vec3::new(1.0, -2.0, 0.7),
        );
        for k in 0..200u64 {
            for (range, lo, hi) in [(PRIOR_M, 0.10, 0.20), (PRIOR_50_M, 0.25, 0.50)] {
                let p = prior_in_range(&truth, trial_seed(3, k as usize), range);
                let dt = (p.translation() - truth.translation()).norm();
                assert!(dt >= lo - 1e-5 && dt <= hi + 1e-5, "{dt}");
                let ang = (p.rotation() * truth.rotation().inverse())
                    .angle()
                    .to_degrees();
                assert!(ang <= PRIOR_MAX_DEG + 1e-3, "{ang}");
            }
        }
        // Ten trials visit ten distinct stops, spread over both circles.
        let stops: Vec<u32> = (0..10)
            .map(|k| {
                let c = capture_for_trial(k, 10, 0.4);
                c.circle * STOPS_PER_CIRCLE + c.stop
            })
            .collect();
        assert_eq!(stops, vec![0, 3, 6, 9, 12, 15, 18, 21, 24, 27]);
        // Seeds differ per trial and repeat per base seed.
        assert_ne!(trial_seed(1, 0), trial_seed(1, 1));
        assert_eq!(trial_seed(1, 5), trial_seed(1, 5));
        assert_ne!(trial_seed(1, 5), trial_seed(2, 5));
        let near = nearest_view(
            &truth,
            &[
                Pose::new(
                    truth.rotation(),
                    truth.translation() + Vec3::new(3.0, 0.0, 0.0),
                ),
                Pose::new(
                    UnitQuaternion::from_euler_angles(0.0, 0.0, 0.5) * truth.rotation(),
                    truth.translation() + Vec3::new(0.0, 0.6, 0.8),
                ),
            ],
        )
        .unwrap();
        assert!((near.0 - 1.0).abs() < 1e-5);
        // A rotation of 0.5 rad about world z: the optical axis turns by at most 0.5 rad.
        assert!(near.1 > 0.0 && near.1 <= 0.5f64.to_degrees() + 1e-3);
    }
}
