//! The host job of `vtsm relocalize`: typed inputs between the command line
//! and the runner.
//!
//! A [`Spec`] (calibration file and rectification kernel, map source, seed,
//! upset checks) and a list of [`Pair`]s go through [`run`]: the calibration
//! is read once by the one reader of every form ([`read_calibration`]), the
//! map product is loaded once ([`load_map`]: a file, or built from a mesh in
//! any form the mesh loader reads) and checked once ([`check_map`]); every
//! pair then loads its images and prior ([`load_inputs`]) and runs against
//! that checked view ([`run_engine`], through [`crate::locate`] and the HAL
//! runner, which uses the view as is). A single pair is a batch of one: both
//! `vtsm relocalize` forms are this code, and `cli::relocalize` and
//! `cli::batch` only turn arguments into a job and results into output.
//!
//! Outputs are serde types: `result.json` ([`ResultFile`], its `stats` the
//! core's counters as [`WorkStats`]) and the batch lines ([`PairResult`]).
//! Poses in and out are f64 in the mesh's own frame; the map's origin
//! ([`MapView::origin`]) is subtracted on the way into the core and added on
//! the way out ([`crate::frame`]).

use crate::error::{Error, Result};
use crate::io::calib::{self, CalibFile};
use crate::io::image::{self as img, Gray8};
use crate::io::json::{self, Calib, ResultFile, Verified, WorkStats};
use crate::io::{self, mesh};
use crate::locate::{self, Request, RunOptions};
use crate::rectify::{Interp, Rectifier};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;
use vtsm_core::config::PriorUncertainty;
use vtsm_core::geom::{Pose, StereoRig};
use vtsm_core::map::MapView;
use vtsm_core::FailureCode;
use vtsm_hal::runner::VerifyChecks;

/// Where the map product of a job comes from.
#[derive(Clone, Debug, PartialEq)]
pub struct MapSpec {
    /// A map product written by `vtsm map build`.
    pub map: Option<PathBuf>,
    /// A textured mesh (OBJ or PLY) to build the product from in memory.
    pub mesh: Option<PathBuf>,
    /// The mask mesh of `mesh`.
    pub mask: Option<PathBuf>,
    /// Origin (mesh frame, metres) of the product built from `mesh`
    /// (`None`: the centre of the mesh's bounding box).
    pub origin: Option<[f64; 3]>,
    /// Tile edge, metres, of the product built from `mesh`.
    pub tile_size_m: f32,
    /// Score the product built from `mesh` for SamplePoint
    /// ([`crate::mapscore`], version 3; `--map-scores on`).
    pub scores: bool,
    /// The sun the map was made under (`--map-sun`): with a prior that
    /// states the capture-time sun, each pair's map is relit to it
    /// ([`crate::relight`]).
    pub sun: Option<crate::relight::SunAngles>,
}

/// One relocalization job besides its pairs.
#[derive(Clone, Debug, PartialEq)]
pub struct Spec {
    /// The calibration of every pair that does not name its own.
    pub calib: PathBuf,
    /// Kernel of the host rectification of a physical pair.
    pub interp: Interp,
    /// The map product.
    pub map: MapSpec,
    /// Upset checks asked for.
    pub verify: VerifyChecks,
    /// The accuracy the caller needs (`--accuracy`): the rounds end once the
    /// stated uncertainty meets it.
    pub accuracy: Option<vtsm_core::reloc::Accuracy>,
    /// Correspondences of each pair's last round (`--final-pairs`; 0: N_corr).
    pub final_pairs: u16,
    /// The search mechanisms (`--revisit`, on by default; `--near`, off).
    pub search: vtsm_core::reloc::Search,
    /// Threads each pair's attempts run on (`--threads`; pairs run one
    /// after another). Same outcome for every number.
    pub threads: usize,
    /// Overwrite existing output files.
    pub force: bool,
}

/// One stereo pair of a job, its paths resolved.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Pair {
    /// Left image.
    pub left: PathBuf,
    /// Right image.
    pub right: PathBuf,
    /// Prior pose file (`prior.json` form, user frame).
    pub prior: PathBuf,
    /// Calibration of this pair (`None`: the job's).
    pub calib: Option<PathBuf>,
    /// Truth pose file: the error to it is reported.
    pub truth: Option<PathBuf>,
    /// Where to write this pair's `result.json`.
    pub out: Option<PathBuf>,
    /// Seed of the relocalization's random streams.
    pub seed: u64,
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
pub fn read_calibration(path: &Path, interp: Interp) -> Result<Calibration> {
    let (calib, physical) = match calib::read_calib_any(path)? {
        CalibFile::Rectified(c) => (c, None),
        CalibFile::OpenCv(c) => {
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

/// Load the map product of `spec`, unchecked: read the `map` file, or build
/// the product from `mesh` (and `mask`, `origin`, `tile_size_m`). The one
/// check is [`check_map`]'s.
///
/// # Errors
/// The first bad input, as a one-line error naming its file.
pub fn load_map(spec: &MapSpec) -> Result<Vec<u8>> {
    match (&spec.map, &spec.mesh) {
        (Some(path), None) => io::read_file(path),
        (None, Some(path)) => {
            let mut m = mesh::load_mesh_at(path, spec.origin)?;
            if let Some(k) = &spec.mask {
                let geo = mesh::load_geometry(k)?;
                m.apply_mask(&geo, k)?;
            }
            crate::mapscore::encode(&m, spec.tile_size_m, spec.scores).map_err(|mut e| {
                if e.file.is_none() {
                    e.file = Some(path.clone());
                }
                e
            })
        }
        _ => Err(Error::msg("give exactly one of --mesh and --map")),
    }
}

/// The job's one check of the map product loaded by [`load_map`]
/// ([`MapView::new_checked`]): the view every pair runs against, handed to
/// the runner as is.
///
/// # Errors
/// The product is rejected: a one-line error naming the map (or mesh) file,
/// with the failure code.
pub fn check_map<'m>(bytes: &'m [u8], spec: &MapSpec) -> Result<MapView<'m>> {
    MapView::new_checked(bytes).map_err(|c| {
        let why = format!(
            "not a valid map product: {} ({})",
            c.name(),
            c.description()
        );
        match spec.map.as_ref().or(spec.mesh.as_ref()) {
            Some(path) => Error::file(path, why),
            None => Error::msg(why),
        }
        .with_code(c)
    })
}

/// Every per-pair input of one relocalization, loaded and checked.
#[derive(Clone, Debug)]
pub struct Inputs {
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
    /// Upset checks asked for.
    pub verify: VerifyChecks,
    /// The accuracy the caller needs (`None` from [`load_inputs`]; a job
    /// sets its [`Spec::accuracy`]).
    pub accuracy: Option<vtsm_core::reloc::Accuracy>,
    /// Correspondences of the last round (0 from [`load_inputs`]; a job
    /// sets its [`Spec::final_pairs`]).
    pub final_pairs: u16,
    /// The search mechanisms (the default from [`load_inputs`]; a job sets
    /// its [`Spec::search`]).
    pub search: vtsm_core::reloc::Search,
    /// Threads the attempts run on (1 from [`load_inputs`]; a job sets its
    /// [`Spec::threads`]).
    pub threads: usize,
    /// The rectifier of a physical pair; the images above are already rectified.
    pub physical: Option<Rectifier>,
    /// The map's origin in the user frame ([`MapView::origin`]).
    pub origin: [f64; 3],
    /// The capture-time sun the prior states (`None` from a prior without
    /// one).
    pub sun: Option<crate::relight::SunAngles>,
    /// The sun the map was made under (`None` from [`load_inputs`]; a job
    /// sets its [`MapSpec::sun`]). With [`Inputs::sun`] the map is relit.
    pub map_sun: Option<crate::relight::SunAngles>,
}

/// Load and check the images and prior of `pair` with the calibration
/// `calib`, for the checked map `map` (its origin).
///
/// # Errors
/// The first bad input, as a one-line error naming its file.
pub fn load_inputs(
    map: &MapView<'_>,
    calib: &Calibration,
    pair: &Pair,
    verify: VerifyChecks,
) -> Result<Inputs> {
    let origin = map.origin();
    let prior_file = json::read_prior(&pair.prior)?;
    let uncertainty = prior_file.uncertainty.map(|u| u.core());
    let prior = prior_file.world_from_left.to_local(origin).map_err(|c| {
        Error::file(
            &pair.prior,
            format!("pose rejected in the map's local frame: {}", c.name()),
        )
        .with_code(c)
    })?;
    let (w, h) = calib.image_size;
    let left = img::read_gray_sized(&pair.left, w, h)?;
    let right = img::read_gray_sized(&pair.right, w, h)?;
    let physical = calib.physical.clone();
    // A physical pair: the core sees the rectified left camera (a rotation
    // of the physical one about its centre, so the origin shift commutes).
    let (left, right, prior) = match &physical {
        Some(r) => r.rectify_input(&left, &right, &prior),
        None => (left, right, prior),
    };
    Ok(Inputs {
        calib: calib.calib,
        rig: calib.rig,
        left,
        right,
        prior,
        uncertainty,
        seed: pair.seed,
        verify,
        accuracy: None,
        final_pairs: 0,
        search: vtsm_core::reloc::Search::DEFAULT,
        threads: 1,
        physical,
        origin,
        sun: prior_file.sun,
        map_sun: None,
    })
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
    /// The engine's work counters.
    pub stats: WorkStats,
    /// Pose covariance from the final refinement (`vtsm_core::pose::Covariance`).
    pub covariance: Option<vtsm_core::pose::Covariance>,
    /// The upset checks that ran.
    pub verified: Verified,
    /// The prior uncertainty (t̃₀, r̃₀) the engine ran with, when known.
    pub prior_uncertainty: Option<PriorUncertainty>,
}

/// One relocalization through the runner, and what it cost.
#[derive(Clone, Debug, PartialEq)]
pub struct Ran {
    /// The outcome.
    pub outcome: Outcome,
    /// Checks of the map product the runner made (0: it used the job's view).
    pub runner_map_checks: u8,
    /// Whole copies of the stereo pair made (the capture into RAM).
    pub pair_copies: u32,
}

/// The relocalization engine call: the same [`crate::locate::relocalize`] as
/// `vtsm demo` and `vtsm eval`, against the job's checked map, with the
/// paper's parameters and ℓ scaled to the image width, and the prior's
/// stated uncertainty served with the prior (one start: it replaces t̃₀,
/// r̃₀). For a physical pair the outcome's pose is converted back from the
/// rectified left camera to the physical one.
///
/// # Errors
/// Inputs the core rejects (image sizes, parameters), with their codes.
pub fn run_engine(map: MapView<'_>, inputs: &Inputs) -> Result<Ran> {
    let relit;
    let map = match (inputs.map_sun, inputs.sun) {
        (Some(from), Some(to)) => {
            relit = crate::relight::relit_product(
                &map,
                from,
                to,
                &crate::relight::RelightOptions::default(),
            )?
            .0;
            MapView::new_checked(&relit).map_err(|c| {
                Error::msg(format!("the relit map was refused: {}", c.name())).with_code(c)
            })?
        }
        _ => map,
    };
    let req = Request::new(
        map,
        &inputs.left.pixels,
        &inputs.right.pixels,
        inputs.rig,
        inputs.prior,
    )
    .with_uncertainty(inputs.uncertainty)
    .with_seed(inputs.seed)
    .with_verify(inputs.verify)
    .with_accuracy(inputs.accuracy)
    .with_final_pairs(inputs.final_pairs)
    .with_search(inputs.search)
    .with_threads(inputs.threads);
    let report = locate::relocalize(&req, RunOptions::default())?;
    let mut outcome = Outcome {
        origin: inputs.origin,
        prior_uncertainty: Some(report.run.prior_uncertainty),
        ..outcome_from_core(&report.outcome, inputs.verify)
    };
    // The core solved for the rectified left camera; report the physical one.
    if let (Some(r), Some(p)) = (&inputs.physical, outcome.pose.as_mut()) {
        *p = r.to_physical(p);
    }
    Ok(Ran {
        outcome,
        runner_map_checks: report.run.map_read.checks,
        pair_copies: report.pair_copies,
    })
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

/// The host view of a core outcome (pose, inliers, iterations, the work
/// counters, and which of the upset checks `asked` ran), for a map at origin 0.
pub fn outcome_from_core(o: &vtsm_core::reloc::Outcome, asked: VerifyChecks) -> Outcome {
    Outcome {
        failure: o.failure,
        pose: Some(o.pose),
        origin: [0.0; 3],
        inliers: u32::from(o.quality.inliers),
        iterations: u32::from(o.stats.successes),
        stats: WorkStats::from(&o.stats),
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
        stats: o.stats,
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

/// What one pair of a job gave.
#[derive(Clone, Debug, PartialEq)]
pub struct PairDone {
    /// The outcome.
    pub outcome: Outcome,
    /// Its `result.json` (written to the pair's `out` when given).
    pub result: ResultFile,
    /// Error to the pair's truth (translation m, rotation rad), when given.
    pub error: Option<(f64, f64)>,
    /// Checks of the map product the runner made for this pair.
    pub runner_map_checks: u8,
    /// Whole copies of the stereo pair made.
    pub pair_copies: u32,
}

/// Relocalize one pair against the job's checked map, with its own
/// calibration when it names one, else `calib` (the job's, read once): load
/// its inputs, run the engine, write its `out`.
///
/// # Errors
/// The first bad input, as a one-line error naming its file.
pub fn run_pair(
    map: MapView<'_>,
    calib: &Calibration,
    spec: &Spec,
    pair: &Pair,
) -> Result<PairDone> {
    if let Some(out) = &pair.out {
        io::check_output(out, spec.force)?;
    }
    let truth = pair
        .truth
        .as_deref()
        .map(json::read_user_pose)
        .transpose()?;
    let own;
    let calib = match &pair.calib {
        Some(c) => {
            own = read_calibration(c, spec.interp)?;
            &own
        }
        None => calib,
    };
    let inputs = Inputs {
        accuracy: spec.accuracy,
        final_pairs: spec.final_pairs,
        search: spec.search,
        threads: spec.threads,
        map_sun: spec.map.sun,
        ..load_inputs(&map, calib, pair, spec.verify)?
    };
    let ran = run_engine(map, &inputs)?;
    let result = outcome_result(&ran.outcome);
    if let Some(out) = &pair.out {
        json::write_result(out, &result, spec.force)?;
    }
    let user = ran
        .outcome
        .pose
        .as_ref()
        .map(|p| crate::frame::to_user(p, ran.outcome.origin));
    let error = truth
        .as_ref()
        .zip(user.as_ref())
        .map(|(t, u)| crate::frame::error_to(u, t));
    Ok(PairDone {
        outcome: ran.outcome,
        result,
        error,
        runner_map_checks: ran.runner_map_checks,
        pair_copies: ran.pair_copies,
    })
}

/// What a job did.
#[derive(Debug)]
pub struct Summary {
    /// One result per pair, in input order, with its wall time (loading its
    /// files and relocalizing), seconds.
    pub pairs: Vec<(Result<PairDone>, f64)>,
    /// Times the map product was loaded (read, or built from the mesh): 1.
    pub map_loads: usize,
    /// Checks of the map product over the whole job: the job's one check
    /// plus the runner's for every pair (0 each: the runner uses the view).
    pub map_checks: u32,
    /// Wall time of loading and checking the map, seconds.
    pub map_load_s: f64,
    /// Wall time of all pairs, seconds.
    pub pairs_s: f64,
}

/// Run a job: read the calibration, load and check the map once, then run
/// every pair of `pairs` in order against that view (a pair that could not
/// even be parsed is given as the reason), calling `each` with the index and
/// the result of each pair as it ends.
///
/// # Errors
/// Bad input of the job itself (calibration or map); per-pair problems are
/// in the returned results.
pub fn run(
    spec: &Spec,
    pairs: &[std::result::Result<Pair, String>],
    mut each: impl FnMut(usize, &Result<PairDone>),
) -> Result<Summary> {
    // The small file first: a bad calibration is reported before a map
    // product is read or built from a mesh.
    let calib = read_calibration(&spec.calib, spec.interp)?;
    let t_map = Instant::now();
    let bytes = load_map(&spec.map)?;
    let map = check_map(&bytes, &spec.map)?;
    let map_load_s = t_map.elapsed().as_secs_f64();
    let mut map_checks = 1u32;
    let t_pairs = Instant::now();
    let mut results = Vec::with_capacity(pairs.len());
    for (i, pair) in pairs.iter().enumerate() {
        let t0 = Instant::now();
        let r = match pair {
            Ok(p) => run_pair(map, &calib, spec, p),
            Err(why) => Err(Error::msg(why.clone())),
        };
        if let Ok(done) = &r {
            map_checks += u32::from(done.runner_map_checks);
        }
        each(i, &r);
        results.push((r, t0.elapsed().as_secs_f64()));
    }
    Ok(Summary {
        pairs: results,
        map_loads: 1,
        map_checks,
        map_load_s,
        pairs_s: t_pairs.elapsed().as_secs_f64(),
    })
}

/// One pair of a batch, as written in `pairs.jsonl`. Its prior file may
/// state the prior's own uncertainty (`prior.json` form).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PairSpec {
    /// Label echoed in the output line (default: the source `file:line`).
    #[serde(default)]
    pub id: Option<String>,
    /// Left image.
    pub left: PathBuf,
    /// Right image.
    pub right: PathBuf,
    /// Prior pose file (`prior.json` form, user frame).
    pub prior: PathBuf,
    /// Calibration of this pair (default: `--calib`).
    #[serde(default)]
    pub calib: Option<PathBuf>,
    /// Truth pose file: adds the final error to the output line.
    #[serde(default)]
    pub truth: Option<PathBuf>,
    /// Also write this pair's `result.json` here (refused if it exists, unless `--force`).
    #[serde(default)]
    pub out: Option<PathBuf>,
    /// Seed of this pair (default: `--seed`).
    #[serde(default)]
    pub seed: Option<u64>,
}

impl PairSpec {
    /// The job's [`Pair`] of this spec: paths relative to `base`, the seed
    /// `seed` unless the spec names its own.
    pub fn pair(&self, base: &Path, seed: u64) -> Pair {
        let resolve = |p: &Path| {
            if p.is_absolute() {
                p.to_path_buf()
            } else {
                base.join(p)
            }
        };
        Pair {
            left: resolve(&self.left),
            right: resolve(&self.right),
            prior: resolve(&self.prior),
            calib: self.calib.as_deref().map(resolve),
            truth: self.truth.as_deref().map(resolve),
            out: self.out.as_deref().map(resolve),
            seed: self.seed.unwrap_or(seed),
        }
    }
}

/// One output line of a batch.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PairResult {
    /// Position of the pair in the batch, from 0.
    pub index: usize,
    /// Where the pair was read: `file:line` or the pair file.
    pub source: String,
    /// The pair's `id`, when it had one.
    pub id: Option<String>,
    /// `"ok"`, `"failed"` (clean relocalization failure) or `"error"` (bad pair input).
    pub status: String,
    /// Failure code name, or `null` (success, or a bad input without a code).
    pub failure: Option<String>,
    /// One-line reason when not `"ok"`.
    pub message: Option<String>,
    /// Final estimate in the user frame (the last estimate when failed), or `null`.
    pub world_from_left: Option<json::PoseJson>,
    /// RANSAC inliers of the final estimate.
    pub inliers: u32,
    /// Successful iterations.
    pub iterations: u32,
    /// The prior uncertainty (t̃₀, r̃₀) the engine ran with (the prior's
    /// stated `uncertainty`, else the default); `null` for a bad pair.
    #[serde(default)]
    pub prior_uncertainty: Option<json::UncertaintyJson>,
    /// Translation error to `truth`, mm (when given).
    pub error_t_mm: Option<f64>,
    /// Rotation error to `truth`, degrees (when given).
    pub error_r_deg: Option<f64>,
    /// Wall time of the pair (loading its files and relocalizing), seconds.
    pub time_s: f64,
}

impl PairResult {
    /// The line of pair `index` read from `source` (with its `id`): its
    /// result, or the error that stopped it, and its wall time.
    pub fn of(
        index: usize,
        source: String,
        id: Option<String>,
        r: &Result<PairDone>,
        time_s: f64,
    ) -> Self {
        match r {
            Ok(d) => Self {
                index,
                source,
                id,
                status: d.result.status.clone(),
                failure: d.result.failure.clone(),
                message: d.outcome.failure.map(|c| c.description().to_string()),
                world_from_left: d.result.world_from_left,
                inliers: d.result.inliers,
                iterations: d.result.iterations,
                prior_uncertainty: d.result.prior_uncertainty,
                error_t_mm: d.error.map(|(t, _)| t * 1e3),
                error_r_deg: d.error.map(|(_, r)| r.to_degrees()),
                time_s,
            },
            Err(err) => Self {
                index,
                source,
                id,
                status: "error".to_string(),
                failure: err.code.map(|c| c.name().to_string()),
                message: Some(err.to_string()),
                world_from_left: None,
                inliers: 0,
                iterations: 0,
                prior_uncertainty: None,
                error_t_mm: None,
                error_r_deg: None,
                time_s,
            },
        }
    }
}
