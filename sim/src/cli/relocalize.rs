//! `vtsm relocalize`: one stereo pair against a mesh or map product, from a prior.
//!
//! A thin wrapper over the host job ([`crate::job`]): the arguments become a
//! [`job::Spec`] and one [`job::Pair`] (a batch of one), the job loads and
//! checks every input once and runs the pair, and this module writes
//! `result.json`. Any bad input gives a one-line error naming the file, exit
//! code 2, and no output; a clean relocalization failure gives exit code 1
//! and a result with `"status": "failed"`. With `--pairs` it relocalizes a
//! batch against one map ([`super::batch`], the same job).

use crate::error::{Error, Result, EXIT_RELOC_FAILED};
use crate::io::{self, json};
use crate::job::{self, Pair, PairDone, Spec};
use crate::rectify::Interp;
use std::path::{Path, PathBuf};

pub use crate::job::{outcome_from_core, outcome_result, verified, Calibration, Inputs, Outcome};

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
    /// `--accuracy T_MM,R_DEG`: end the rounds once the stated uncertainty
    /// meets it.
    #[command(flatten)]
    pub accuracy: super::AccuracyArg,
    /// `--final-pairs N`: correspondences of the last round.
    #[command(flatten)]
    pub final_pairs: super::FinalPairsArg,
    /// `--revisit on|off`, `--near on|off`: the search mechanisms.
    #[command(flatten)]
    pub search: super::SearchArgs,
    /// `--map-scores on|off`: score the product built from `--mesh`
    /// (a product given with `--map` carries its own scores or none).
    #[command(flatten)]
    pub map_scores: super::MapScoresArg,
    /// The sun the map was made under, `AZIMUTH,ELEVATION` in degrees in the
    /// map's frame (azimuth clockwise from `+y`, elevation above the `xy`
    /// plane). A pair whose prior states its capture-time `sun` is then
    /// matched against the map relit to that sun; without it, or without a
    /// `sun` in the prior, the map is matched as made.
    #[arg(long, value_name = "AZ,EL", value_parser = parse_sun)]
    pub map_sun: Option<crate::relight::SunAngles>,
    /// `--threads N`: the threads each pair's attempts run on (same result).
    #[command(flatten)]
    pub threads: super::ThreadsArg,
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
        allow_hyphen_values = true,
        value_parser = crate::frame::origin_arg
    )]
    pub origin: Option<[f64; 3]>,
    /// Kernel of the host rectification when calib.json is the OpenCV stereo
    /// form: linear, cubic or lanczos4 (`cv2.remap`'s INTER_* of those names).
    #[arg(long, value_name = "KERNEL", value_enum, default_value_t = Interp::Lanczos4)]
    pub interp: Interp,
}

/// Argument combinations the parser lets through: clap does not enforce
/// `--mask`'s `requires = "mesh"` when `--map` (which conflicts with `--mesh`)
/// is given, and a map product already carries its mask.
///
/// # Errors
/// `--mask` or `--map-scores on` without `--mesh`.
pub fn check_args(args: &Args) -> Result<()> {
    if let (Some(k), None) = (&args.mask, &args.mesh) {
        return Err(Error::file(
            k,
            "--mask needs --mesh (a map product from --map already holds its mask)",
        ));
    }
    if args.map_scores.on() && args.mesh.is_none() {
        return Err(Error::msg(
            "--map-scores on needs --mesh (a map product from --map carries its own scores or none)",
        ));
    }
    Ok(())
}

/// `--map-sun AZ,EL`.
fn parse_sun(s: &str) -> std::result::Result<crate::relight::SunAngles, String> {
    crate::relight::SunAngles::parse(s)
}

impl Args {
    /// The job these arguments describe (everything but the pairs).
    ///
    /// # Errors
    /// As [`check_args`].
    pub fn spec(&self) -> Result<Spec> {
        check_args(self)?;
        Ok(Spec {
            calib: self.calib.clone(),
            interp: self.interp,
            map: job::MapSpec {
                map: self.map.clone(),
                mesh: self.mesh.clone(),
                mask: self.mask.clone(),
                origin: self.origin,
                tile_size_m: self.tile_size_m,
                scores: self.map_scores.on(),
                sun: self.map_sun,
            },
            verify: self.verify.checks(),
            accuracy: self.accuracy.accuracy,
            final_pairs: self.final_pairs.final_pairs,
            search: self.search.search(),
            threads: self.threads.threads(),
            force: self.force,
        })
    }

    /// The one pair these arguments name (`--left`, `--right`, `--prior`,
    /// `--seed`, and `--out` as its `result.json`).
    ///
    /// # Errors
    /// A required path is missing (clap requires it unless `--pairs` is given).
    pub fn pair(&self) -> Result<Pair> {
        let required = |p: &Option<PathBuf>, name: &str| {
            p.clone()
                .ok_or_else(|| Error::msg(format!("--{name} is required (or give --pairs)")))
        };
        Ok(Pair {
            left: required(&self.left, "left")?,
            right: required(&self.right, "right")?,
            prior: required(&self.prior, "prior")?,
            seed: self.seed,
            out: self.out.clone(),
            ..Pair::default()
        })
    }
}

/// Relocalize the one pair `args` names as a batch of one ([`job::run`]),
/// writing `args.out` when given.
///
/// # Errors
/// The first bad input, as a one-line error naming its file.
pub fn relocalize_one(args: &Args) -> Result<PairDone> {
    let spec = args.spec()?;
    let pair = args.pair()?;
    let summary = job::run(&spec, &[Ok(pair)], |_, _| {})?;
    summary
        .pairs
        .into_iter()
        .next()
        .map_or_else(|| Err(Error::msg("no pair")), |(r, _)| r)
}

/// The inputs of the one pair `args` names, loaded and checked as the job
/// loads them, handed to `f` with the job's checked map (for a caller that
/// looks at the inputs before running them with [`job::run_engine`]).
///
/// # Errors
/// The first bad input, or `f`'s error.
pub fn with_inputs<R>(
    args: &Args,
    f: impl FnOnce(vtsm_core::map::MapView<'_>, &Inputs) -> Result<R>,
) -> Result<R> {
    let spec = args.spec()?;
    let pair = args.pair()?;
    let calib = job::read_calibration(&spec.calib, spec.interp)?;
    let bytes = job::load_map(&spec.map)?;
    let map = job::check_map(&bytes, &spec.map)?;
    let inputs = Inputs {
        accuracy: spec.accuracy,
        final_pairs: spec.final_pairs,
        search: spec.search,
        threads: spec.threads,
        map_sun: spec.map.sun,
        ..job::load_inputs(&map, &calib, &pair, spec.verify)?
    };
    f(map, &inputs)
}

/// `vtsm relocalize --pairs` with these arguments ([`super::batch::run_batch`]).
///
/// # Errors
/// Bad input of the batch itself.
pub fn run_batch(args: &Args, pairs: &Path, progress: bool) -> Result<super::batch::Summary> {
    super::batch::run_batch(
        &args.spec()?,
        args.seed,
        pairs,
        args.out.as_deref(),
        progress,
    )
}

/// Run the command; returns the exit code.
///
/// # Errors
/// Bad input (exit code 2 at the command line).
pub fn run(args: &Args) -> Result<u8> {
    let spec = args.spec()?;
    if let Some(pairs) = &args.pairs {
        return super::batch::run(&spec, args.seed, pairs, args.out.as_deref());
    }
    if let Some(out) = &args.out {
        io::check_output(out, args.force)?;
    }
    let done = relocalize_one(args)?;
    if args.out.is_none() {
        print!("{}", json::result_text(&done.result));
    }
    Ok(if done.outcome.failure.is_none() {
        0
    } else {
        EXIT_RELOC_FAILED
    })
}
