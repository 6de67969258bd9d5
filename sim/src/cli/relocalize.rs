//! `vtsm relocalize`: one stereo pair against a mesh or map product, from a prior.
//!
//! This module loads and validates every input ([`load_inputs`]), hands them to
//! the engine ([`run_engine`]) and writes `result.json` ([`outcome_result`]).
//! Any bad input gives a one-line error naming the file, exit code 2, and no
//! output; a clean relocalization failure gives exit code 1 and a result with
//! `"status": "failed"`. With `--pairs` it relocalizes a batch against one map
//! ([`super::batch`]).
//!
//! Poses in and out (prior, result) are f64 in the mesh's own frame; the map's
//! origin ([`MapView::origin`]) is subtracted on the way into the core and added
//! on the way out ([`crate::frame`]). A prior's stated `uncertainty` travels
//! with it to the runner, which builds the engine with it as (t̃₀, r̃₀); the
//! result echoes the pair used as `prior_uncertainty`.

use crate::error::{Error, Result, EXIT_RELOC_FAILED};
use crate::io::calib::{self, CalibFile};
use crate::io::image::{self as img, Gray8};
use crate::io::json::{self, Calib, ResultFile, Verified};
use crate::io::{self, mesh};
use crate::rectify::{Interp, Rectifier};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use vtsm_core::config::PriorUncertainty;
use vtsm_core::geom::{Pose, StereoRig};
use vtsm_core::map::MapView;
use vtsm_core::FailureCode;
use vtsm_hal::runner::VerifyChecks;

/// Arguments of `vtsm relocalize`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Textured depot mesh (OBJ with MTL texture, or PLY); the map product is
    /// built in memory. Give this or --map.
    #[arg(
        long,
        value_name = "M.obj",
        conflicts_with = "map",
        required_unless_present = "map"
    )]
    pub mesh: Option<PathBuf>,
    /// Mask mesh K (the triangles of --mesh to sample points from).
    #[arg(long, value_name = "K.obj", requires = "mesh")]
    pub mask: Option<PathBuf>,
    /// Map product written by `vtsm map build`. Give this or --mesh.
    #[arg(long, value_name = "D.vmap")]
    pub map: Option<PathBuf>,
    /// Stereo calibration: a rectified pair {"width","height","fx","fy","cx","cy","baseline_m"},
    /// the OpenCV form {"image_size","left","right","R","T"} of a physical pair,
    /// the ROS form {"ros_camera_info":{"left":"l.yaml","right":"r.yaml"}} naming
    /// two camera_info files, the Kalibr form {"kalibr_camchain":"camchain.yaml"},
    /// or the FileStorage form {"opencv_storage":["intrinsics.yml","extrinsics.yml"]}
    /// (a cv::FileStorage YAML or XML file may also be given here itself) (the physical
    /// forms are rectified here; poses then refer to the physical left camera).
    #[arg(long, value_name = "calib.json")]
    pub calib: PathBuf,
    /// Left image (PNG, JPEG, TIFF or PGM; 8 or 16 bit; colour is converted to gray).
    #[arg(long, value_name = "L.png", required_unless_present = "pairs")]
    pub left: Option<PathBuf>,
    /// Right image, same size as the left one and as the calibration.
    #[arg(long, value_name = "R.png", required_unless_present = "pairs")]
    pub right: Option<PathBuf>,
    /// Prior pose JSON file: `world_from_left` with translation `t` (x, y, z) and quaternion `q` (w, x, y, z),
    /// optionally `uncertainty` {"t_m", "r_deg"} (half-widths the truth lies within; default 0.20 m, 1.5°).
    #[arg(long, value_name = "prior.json", required_unless_present = "pairs")]
    pub prior: Option<PathBuf>,
    /// Batch: a JSON-lines file (or a directory of `*.json` pair files) naming
    /// left, right, prior (and optionally calib, out, truth, seed) per pair; the
    /// map is loaded once and one JSON line per pair is written to --out or stdout.
    #[arg(long, value_name = "pairs.jsonl", conflicts_with_all = ["left", "right", "prior"])]
    pub pairs: Option<PathBuf>,
    /// Seed of the relocalizer's random draws (same inputs + seed = same result).
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub seed: u64,
    /// `--verify [repeat,map]`: the engine's upset checks.
    #[command(flatten)]
    pub verify: super::VerifyArg,
    /// Where to write result.json; without it the result is printed to stdout.
    #[arg(long, value_name = "result.json")]
    pub out: Option<PathBuf>,
    /// Overwrite --out if it exists.
    #[arg(long)]
    pub force: bool,
    /// Tile edge (metres) of the map product built from --mesh.
    #[arg(long, value_name = "S", default_value_t = super::map_build::DEFAULT_TILE_SIZE_M)]
    pub tile_size_m: f32,
    /// Origin X,Y,Z (metres, mesh frame) of the map built from --mesh
    /// (default: the exact centre of the mesh's bounding box).
    #[arg(
        long,
        value_name = "X,Y,Z",
        requires = "mesh",
        allow_hyphen_values = true
    )]
    pub origin: Option<String>,
    /// Kernel of the host rectification when calib.json is the OpenCV stereo
    /// form: linear, cubic or lanczos4 (`cv2.remap`'s INTER_* of those names).
    #[arg(long, value_name = "KERNEL", default_value = "lanczos4")]
    pub interp: String,
}

/// Every input of one relocalization, loaded and checked.
#[derive(Clone, Debug)]
pub struct Inputs {
    /// Map product bytes, already accepted by `MapView::new_checked`.
    pub map: Vec<u8>,
    /// The calibration as read (for a physical pair: the rectified one).
    pub calib: Calib,
    /// The checked stereo rig.
    pub rig: StereoRig,
    /// Left image, calibration size.
    pub left: Gray8,
    /// Right image, calibration size.
    pub right: Gray8,
    /// Prior `world_from_left` in the map's local frame (user frame minus
    /// `origin`) of the camera the core sees (for a physical pair: the
    /// rectified left camera).
    pub prior: Pose,
    /// The prior's stated uncertainty (`None`: the engine's default t̃₀, r̃₀).
    pub uncertainty: Option<PriorUncertainty>,
    /// Seed.
    pub seed: u64,
    /// Upset checks asked for (`--verify`).
    pub verify: VerifyChecks,
    /// The rectifier of a physical pair (OpenCV form of `calib.json`); the
    /// images above are already rectified.
    pub physical: Option<Rectifier>,
    /// The map's origin in the user frame ([`MapView::origin`]).
    pub origin: [f64; 3],
}

impl Inputs {
    /// The checked view of the map product.
    ///
    /// # Errors
    /// Never for inputs from [`load_inputs`] (the bytes were checked there).
    pub fn map_view(&self) -> std::result::Result<MapView<'_>, FailureCode> {
        MapView::new_checked(&self.map)
    }
}

/// Argument combinations the parser lets through: clap does not enforce
/// `--mask`'s `requires = "mesh"` when `--map` (which conflicts with `--mesh`)
/// is given, and a map product already carries its mask.
///
/// # Errors
/// `--mask` without `--mesh`.
pub fn check_args(args: &Args) -> Result<()> {
    if let (Some(k), None) = (&args.mask, &args.mesh) {
        return Err(Error::file(
            k,
            "--mask needs --mesh (a map product from --map already holds its mask)",
        ));
    }
    Ok(())
}

/// The calibration of a pair, read from any form of `calib.json` (or a
/// `cv::FileStorage` file given itself) and checked once: the rectified
/// calibration the core sees, its rig, and for a physical pair the rectifier
/// and the physical image size.
#[derive(Clone, Debug)]
pub struct Calibration {
    /// The calibration as read (for a physical pair: the rectified one).
    pub calib: Calib,
    /// The checked stereo rig.
    pub rig: StereoRig,
    /// The rectifier of a physical pair, else `None`.
    pub physical: Option<Rectifier>,
    /// Size (width, height) of the images as captured.
    pub image_size: (u32, u32),
}

/// Read and check a calibration in every form `vtsm relocalize` accepts,
/// with `interp` the kernel of the host rectification of a physical pair.
/// The one reader of `--calib` and of a batch pair's `calib`.
///
/// # Errors
/// The file is unreadable or malformed, cannot be rectified, or its rig is
/// rejected by the core (with its code).
pub fn read_calibration(path: &Path, interp: &str) -> Result<Calibration> {
    let (calib, physical) = match calib::read_calib_any(path)? {
        CalibFile::Rectified(c) => (c, None),
        CalibFile::OpenCv(c) => {
            let interp = Interp::parse(interp).map_err(Error::msg)?;
            let r = Rectifier::new(&c)
                .map_err(|why| Error::file(path, why))?
                .with_interp(interp);
            (r.calib(), Some((r, c.size())))
        }
    };
    let rig = calib
        .rig()
        .map_err(|c| Error::file(path, format!("rejected: {}", c.description())).with_code(c))?;
    let image_size = physical
        .as_ref()
        .map_or((calib.width, calib.height), |p| p.1);
    Ok(Calibration {
        calib,
        rig,
        physical: physical.map(|p| p.0),
        image_size,
    })
}

/// Load and validate every input named by `args`.
///
/// # Errors
/// The first bad input, as a one-line error naming its file.
pub fn load_inputs(args: &Args) -> Result<Inputs> {
    check_args(args)?;
    // The small file first: a bad calibration is reported before a map
    // product is read or built from a mesh.
    let calib = read_calibration(&args.calib, &args.interp)?;
    let map = load_map(args)?;
    load_inputs_with_map(args, &calib, map)
}

/// A required single-pair path (clap requires it unless `--pairs` is given).
fn required<'a>(p: &'a Option<PathBuf>, name: &str) -> Result<&'a PathBuf> {
    p.as_ref()
        .ok_or_else(|| Error::msg(format!("--{name} is required (or give --pairs)")))
}

/// Load and validate the images and prior named by `args`, for the
/// calibration `calib` already read by [`read_calibration`], against a map
/// product already loaded by [`load_map`].
///
/// # Errors
/// The first bad input, as a one-line error naming its file.
pub fn load_inputs_with_map(args: &Args, calib: &Calibration, map: Vec<u8>) -> Result<Inputs> {
    let (left_path, right_path, prior_path) = (
        required(&args.left, "left")?,
        required(&args.right, "right")?,
        required(&args.prior, "prior")?,
    );
    let origin = MapView::new_checked(&map).map_err(Error::from)?.origin();
    let prior_file = json::read_prior(prior_path)?;
    let uncertainty = prior_file.uncertainty.map(|u| u.core());
    let prior = prior_file.world_from_left.to_local(origin).map_err(|c| {
        Error::file(
            prior_path,
            format!("pose rejected in the map's local frame: {}", c.name()),
        )
        .with_code(c)
    })?;
    let (w, h) = calib.image_size;
    let left = img::read_gray_sized(left_path, w, h)?;
    let right = img::read_gray_sized(right_path, w, h)?;
    let physical = calib.physical.clone();
    // A physical pair: the core sees the rectified left camera (a rotation
    // of the physical one about its centre, so the origin shift commutes).
    let (left, right, prior) = match &physical {
        Some(r) => r.rectify_input(&left, &right, &prior),
        None => (left, right, prior),
    };
    Ok(Inputs {
        map,
        calib: calib.calib,
        rig: calib.rig,
        left,
        right,
        prior,
        uncertainty,
        seed: args.seed,
        verify: args.verify.checks(),
        physical,
        origin,
    })
}

/// Relocalize the one pair `args` names (its images, prior, seed, and
/// `out` when given) with the calibration `calib` against the loaded map
/// product: load its inputs, run the engine, write `args.out`. The same
/// code for a single pair and for every pair of a batch.
///
/// # Errors
/// The first bad input, as a one-line error naming its file.
pub fn relocalize_pair(
    args: &Args,
    calib: &Calibration,
    map: Vec<u8>,
) -> Result<(Outcome, ResultFile)> {
    let inputs = load_inputs_with_map(args, calib, map)?;
    let outcome = run_engine(&inputs)?;
    let result = outcome_result(&outcome);
    if let Some(out) = &args.out {
        json::write_result(out, &result, args.force)?;
    }
    Ok((outcome, result))
}

/// Load the map product named by `args`: read and check `--map`, or build it
/// from `--mesh` (and `--mask`, `--origin`, `--tile-size-m`).
///
/// # Errors
/// The first bad input, as a one-line error naming its file.
pub fn load_map(args: &Args) -> Result<Vec<u8>> {
    check_args(args)?;
    let origin = args
        .origin
        .as_deref()
        .map(crate::frame::parse_origin)
        .transpose()?;
    let map = match (&args.map, &args.mesh) {
        (Some(path), None) => {
            let bytes = io::read_file(path)?;
            MapView::new_checked(&bytes).map_err(|c| {
                Error::file(
                    path,
                    format!(
                        "not a valid map product: {} ({})",
                        c.name(),
                        c.description()
                    ),
                )
                .with_code(c)
            })?;
            bytes
        }
        (None, Some(path)) => {
            let mut m = mesh::load_mesh_at(path, origin)?;
            if let Some(k) = &args.mask {
                let geo = mesh::load_geometry(k)?;
                m.apply_mask(&geo, k)?;
            }
            m.encode_map(args.tile_size_m).map_err(|mut e| {
                if e.file.is_none() {
                    e.file = Some(path.clone());
                }
                e
            })?
        }
        _ => return Err(Error::msg("give exactly one of --mesh and --map")),
    };
    Ok(map)
}

/// What the engine reports for one relocalization.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// The failure code when the relocalization failed cleanly, `None` on success.
    pub failure: Option<FailureCode>,
    /// Final estimate (the last estimate on failure), if any, in the map's
    /// local frame.
    pub pose: Option<Pose>,
    /// The map's origin: `pose` plus this is the estimate in the user frame.
    pub origin: [f64; 3],
    /// RANSAC inliers of the final estimate.
    pub inliers: u32,
    /// Successful iterations.
    pub iterations: u32,
    /// Work counters by name.
    pub stats: BTreeMap<String, u64>,
    /// Pose covariance from the final refinement (`vtsm_core::pose::Covariance`).
    pub covariance: Option<vtsm_core::pose::Covariance>,
    /// The upset checks that ran.
    pub verified: Verified,
    /// The prior uncertainty (t̃₀, r̃₀) the engine ran with, when known.
    pub prior_uncertainty: Option<PriorUncertainty>,
}

/// The relocalization engine call: the same [`crate::locate::relocalize`] as
/// `vtsm demo` and `vtsm eval`, with the paper's parameters and ℓ scaled to the
/// image width, and the prior's stated uncertainty served with the prior (one
/// start: it replaces t̃₀, r̃₀). For a physical pair the outcome's pose is
/// converted back from the rectified left camera to the physical one.
///
/// # Errors
/// Inputs the core rejects (map, image sizes, parameters), with their codes.
pub fn run_engine(inputs: &Inputs) -> Result<Outcome> {
    let req = crate::locate::Request::new(
        inputs.map.as_slice(),
        &inputs.left.pixels,
        &inputs.right.pixels,
        inputs.rig,
        inputs.prior,
    )
    .with_uncertainty(inputs.uncertainty)
    .with_seed(inputs.seed)
    .with_verify(inputs.verify);
    let report = crate::locate::relocalize(&req, crate::locate::RunOptions::default())?;
    let mut outcome = Outcome {
        origin: inputs.origin,
        prior_uncertainty: Some(report.run.prior_uncertainty),
        ..outcome_from_core(&report.outcome, inputs.verify)
    };
    // The core solved for the rectified left camera; report the physical one.
    if let (Some(r), Some(p)) = (&inputs.physical, outcome.pose.as_mut()) {
        *p = r.to_physical(p);
    }
    Ok(outcome)
}

/// Which of the upset checks `asked` ran in `o`: the repeated solve when it
/// did work; the map re-check when the run reached it (it is the last step
/// before a success: the run then succeeded or ended with `RELOC_MAP_CHANGED`).
pub fn verified(o: &vtsm_core::reloc::Outcome, asked: VerifyChecks) -> Verified {
    Verified {
        repeat_solve: asked.repeat_solve && o.stats.verify_units > 0,
        recheck_map: asked.recheck_map
            && matches!(o.failure, None | Some(FailureCode::RelocMapChanged)),
    }
}

/// The command-line view of a core outcome (pose, inliers, iterations,
/// every work counter by name, and which of the upset checks `asked` ran),
/// for a map at origin 0.
pub fn outcome_from_core(o: &vtsm_core::reloc::Outcome, asked: VerifyChecks) -> Outcome {
    let s = &o.stats;
    let p = &s.pipeline;
    let mut stats = BTreeMap::new();
    for (k, v) in [
        ("work_units", u64::from(s.work_units)),
        ("rounds", u64::from(s.rounds)),
        ("attempts", u64::from(s.attempts)),
        ("correspondences", u64::from(s.correspondences)),
        ("reused", u64::from(s.reused)),
        ("solves", u64::from(s.solves)),
        ("ransac_iterations", u64::from(s.ransac_iterations)),
        ("stalls", u64::from(s.stalls)),
        ("reseeds", u64::from(s.reseeds)),
        ("seeds_tried", u64::from(s.seeds_tried)),
        ("widened_solves", u64::from(s.widened_solves)),
        ("focused_rounds", u64::from(s.focused_rounds)),
        ("gradient_rounds", u64::from(s.gradient_rounds)),
        ("renders", u64::from(p.renders)),
        ("render_pixels", p.render_pixels),
        ("ncc_matches", p.matches.iter().map(|&m| u64::from(m)).sum()),
        (
            "ncc_accepted",
            p.accepted.iter().map(|&m| u64::from(m)).sum(),
        ),
        ("ncc_positions", p.ncc_positions),
        ("ncc_macs", p.ncc_macs),
        ("samples_out_of_view", u64::from(p.out_of_view)),
        ("samples_occluded", u64::from(p.occluded)),
        ("triangulations", u64::from(p.triangulations)),
        ("refine_iterations", u64::from(s.refine.iterations)),
        ("refine_accepted", u64::from(s.refine.accepted)),
        ("verify_units", u64::from(s.verify_units)),
    ] {
        stats.insert(k.to_string(), v);
    }
    Outcome {
        failure: o.failure,
        pose: Some(o.pose),
        origin: [0.0; 3],
        inliers: u32::from(o.quality.inliers),
        iterations: u32::from(s.successes),
        stats,
        covariance: o.quality.covariance,
        verified: verified(o, asked),
        prior_uncertainty: None,
    }
}

/// The `result.json` content of an outcome (pose in the user frame).
pub fn outcome_result(o: &Outcome) -> ResultFile {
    ResultFile {
        status: if o.failure.is_none() { "ok" } else { "failed" }.to_string(),
        failure: o.failure.map(|c| c.name().to_string()),
        world_from_left: o
            .pose
            .as_ref()
            .map(|p| json::PoseJson::from_local(p, o.origin)),
        inliers: o.inliers,
        iterations: o.iterations,
        stats: o.stats.clone(),
        covariance: o
            .covariance
            .map(|c| c.m.iter().map(|&v| f64::from(v)).collect()),
        verified: o.verified,
        prior_uncertainty: o
            .prior_uncertainty
            .as_ref()
            .map(json::UncertaintyJson::from_core),
    }
}

/// Run the command; returns the exit code.
pub fn run(args: &Args) -> Result<u8> {
    check_args(args)?;
    if let Some(pairs) = &args.pairs {
        return super::batch::run(args, pairs);
    }
    if let Some(out) = &args.out {
        io::check_output(out, args.force)?;
    }
    let calib = read_calibration(&args.calib, &args.interp)?;
    let map = load_map(args)?;
    let (outcome, result) = relocalize_pair(args, &calib, map)?;
    if args.out.is_none() {
        print!("{}", json::result_text(&result));
    }
    Ok(if outcome.failure.is_none() {
        0
    } else {
        EXIT_RELOC_FAILED
    })
}
