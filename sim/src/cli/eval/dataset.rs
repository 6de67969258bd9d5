//! `vtsm eval --suite dataset --data DIR`: every stereo pair of a data set on
//! disk, real photographs or renders from another tool, evaluated as the
//! simulated suites are (the same table, `trials.csv`, `summary.json`,
//! figures, tail statistics, covariance check and integrity table, the
//! local-feature baseline beside VTSM with `--baseline features`, shards and
//! their merge).
//!
//! The layout (`fsw-docs/interfaces/files.md`, "Data sets"):
//!
//! ```text
//! DIR/
//!   map/            one map: a product `*.vmap`, or a mesh `*.obj`/`*.ply`
//!                   (either possibly `.xz`-compressed) with its MTL and
//!                   texture; optional `mask.obj`/`mask.ply` (sampling mask)
//!   calib.json      optional: the calibration of every pair without its own
//!   views/<name>/   one stereo pair per directory, in name order:
//!     left.png, right.png   (or .jpg .jpeg .tif .tiff .pgm .ppm .pnm)
//!     calib.json            any form `vtsm relocalize` reads (or calib.yaml,
//!                           calib.yml, calib.xml: a cv::FileStorage file)
//!     prior.json            the prior; its `uncertainty`, when stated, is
//!                           what the engine runs with
//!     truth.json            optional: the true pose (`prior.json` form)
//! ```
//!
//! Every pair is a group (a row of the table) and `--trials N` runs it N
//! times, trial `k` with the seed [`trial_seed`]`(--seed, k)` in every group.
//! The map is loaded (or built from the mesh) and checked once; every
//! calibration, prior, truth and image size is checked before any trial
//! runs, so a bad file stops the run at once with its name. A pair without a
//! truth has no errors (NaN): its successes are counted, not judged.
//!
//! The campaign is recorded with the data set's name and a SHA-256 of every
//! file it read, so the parts of a sharded campaign (run where the data set
//! lives at another path) merge only when they evaluated the same files.

use super::config::{Method, SuiteConfig};
use super::group::{with_baseline_groups, Group};
use super::protocol::trial_seed;
use super::run::{accuracy_json, run_campaign, verify_json, SuiteRun};
use super::trial::{self, ErrorFrame};
use crate::error::{Error, Result};
use crate::eval::columns::{GroupColumns, TrialColumns};
use crate::eval::{self, RunMeta, TrialOutcome};
use crate::frame::UserPose;
use crate::io::json;
use crate::job::{self, Calibration, MapSpec};
use crate::locate;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use std::time::Instant;
use vtsm_core::config::PriorUncertainty;
use vtsm_core::geom::Pose;
use vtsm_core::map::MapView;

/// Image file extensions a pair's `left` and `right` may have.
pub const IMAGE_EXTENSIONS: [&str; 7] = ["png", "jpg", "jpeg", "tif", "tiff", "pgm", "ppm"];

/// Calibration file names looked for in a pair's directory, then in the
/// data set's.
pub const CALIB_NAMES: [&str; 4] = ["calib.json", "calib.yaml", "calib.yml", "calib.xml"];

/// Tile edge, metres, of a map product built from a data set's mesh (as
/// `vtsm map build` and `vtsm relocalize --mesh`).
pub const TILE_M: f32 = 0.5;

/// The files of one stereo pair of a data set.
#[derive(Clone, Debug, PartialEq)]
pub struct PairFiles {
    /// The pair's directory name under `views/`: the group's label.
    pub name: String,
    /// Left image.
    pub left: PathBuf,
    /// Right image.
    pub right: PathBuf,
    /// Calibration (the pair's own, or the data set's).
    pub calib: PathBuf,
    /// Prior pose.
    pub prior: PathBuf,
    /// True pose, when the data set has it.
    pub truth: Option<PathBuf>,
}

/// A data set's files, found in its layout.
#[derive(Clone, Debug, PartialEq)]
pub struct DataSet {
    /// The directory.
    pub dir: PathBuf,
    /// Its name (the directory's last component).
    pub name: String,
    /// Where the map comes from.
    pub map: MapSpec,
    /// The map's files (product or mesh, mask, MTL, texture...): everything
    /// under `map/`.
    pub map_files: Vec<PathBuf>,
    /// The pairs, in name order.
    pub pairs: Vec<PairFiles>,
}

/// The regular files of `dir`, sorted by name.
fn files_in(dir: &Path) -> Result<Vec<PathBuf>> {
    let entries = std::fs::read_dir(dir)
        .map_err(|e| Error::file(dir, format!("cannot read: {}", crate::io::io_reason(&e))))?;
    let mut out: Vec<PathBuf> = entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_file())
        .collect();
    out.sort();
    Ok(out)
}

/// The file name of `p` in lower case.
fn lower_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().to_lowercase())
        .unwrap_or_default()
}

/// Whether `name` is a mesh file name (`.obj`, `.ply`, either `.xz`).
fn is_mesh(name: &str) -> bool {
    let inner = name.strip_suffix(".xz").unwrap_or(name);
    inner.ends_with(".obj") || inner.ends_with(".ply")
}

/// The map of `map/`: one product, or one mesh besides the mask.
fn find_map(dir: &Path, files: &[PathBuf]) -> Result<MapSpec> {
    let named = |pred: &dyn Fn(&str) -> bool| -> Vec<&PathBuf> {
        files.iter().filter(|p| pred(&lower_name(p))).collect()
    };
    let products = named(&|n| n.ends_with(".vmap"));
    let masks = named(&|n| is_mesh(n) && n.starts_with("mask."));
    let meshes = named(&|n| is_mesh(n) && !n.starts_with("mask."));
    let one = |list: &[&PathBuf], what: &str| -> Result<Option<PathBuf>> {
        match list {
            [] => Ok(None),
            [p] => Ok(Some((*p).clone())),
            _ => Err(Error::file(
                dir,
                format!(
                    "holds {} {what} files ({}); a data set has one",
                    list.len(),
                    list.iter()
                        .map(|p| lower_name(p))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )),
        }
    };
    let (product, mesh, mask) = (
        one(&products, "map product")?,
        one(&meshes, "mesh")?,
        one(&masks, "mask")?,
    );
    match (product, mesh) {
        (Some(_), Some(_)) => Err(Error::file(
            dir,
            "holds both a map product and a mesh; a data set has one map",
        )),
        (None, None) => Err(Error::file(
            dir,
            "holds no map (a *.vmap product, or a mesh *.obj / *.ply, possibly .xz)",
        )),
        (Some(_), None) if mask.is_some() => Err(Error::file(
            dir,
            "holds a mask beside a map product; the product carries its own mask",
        )),
        (map, mesh) => Ok(MapSpec {
            map,
            mesh,
            mask,
            origin: None,
            tile_size_m: TILE_M,
            scores: false,
            sun: None,
        }),
    }
}

/// The one file of `dir` named `stem.<ext>` for an extension in `exts`.
fn find_named(dir: &Path, files: &[PathBuf], stem: &str, exts: &[&str]) -> Result<Option<PathBuf>> {
    let found: Vec<&PathBuf> = files
        .iter()
        .filter(|p| {
            let n = lower_name(p);
            exts.iter().any(|e| n == format!("{stem}.{e}"))
        })
        .collect();
    match found.as_slice() {
        [] => Ok(None),
        [p] => Ok(Some((*p).clone())),
        _ => Err(Error::file(
            dir,
            format!("holds {} files named {stem}.*; a pair has one", found.len()),
        )),
    }
}

/// The calibration file among `files` (one of [`CALIB_NAMES`]).
fn find_calib(dir: &Path, files: &[PathBuf]) -> Result<Option<PathBuf>> {
    let exts: Vec<&str> = CALIB_NAMES
        .iter()
        .filter_map(|n| n.strip_prefix("calib."))
        .collect();
    find_named(dir, files, "calib", &exts)
}

impl DataSet {
    /// Find the files of the data set in `dir` (the layout of the module
    /// documentation), without reading them.
    ///
    /// # Errors
    /// A missing or ambiguous part of the layout, as a one-line error naming
    /// the directory or file.
    pub fn find(dir: &Path) -> Result<Self> {
        if !dir.is_dir() {
            return Err(Error::file(dir, "is not a data set directory"));
        }
        let map_dir = dir.join("map");
        let map_files = files_in(&map_dir)?;
        let map = find_map(&map_dir, &map_files)?;
        let shared_calib = find_calib(dir, &files_in(dir)?)?;
        let views = dir.join("views");
        let entries = std::fs::read_dir(&views).map_err(|e| {
            Error::file(&views, format!("cannot read: {}", crate::io::io_reason(&e)))
        })?;
        let mut view_dirs: Vec<PathBuf> = entries
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.is_dir())
            .collect();
        view_dirs.sort();
        if view_dirs.is_empty() {
            return Err(Error::file(&views, "holds no pair directory"));
        }
        let pairs = view_dirs
            .iter()
            .map(|v| Self::pair(v, shared_calib.as_deref()))
            .collect::<Result<Vec<_>>>()?;
        let name = dir
            .canonicalize()
            .ok()
            .and_then(|d| d.file_name().map(|n| n.to_string_lossy().into_owned()))
            .unwrap_or_else(|| dir.display().to_string());
        Ok(Self {
            dir: dir.to_path_buf(),
            name,
            map,
            map_files,
            pairs,
        })
    }

    /// The files of the pair in `dir`.
    fn pair(dir: &Path, shared_calib: Option<&Path>) -> Result<PairFiles> {
        let files = files_in(dir)?;
        let need = |stem: &str, exts: &[&str]| -> Result<PathBuf> {
            find_named(dir, &files, stem, exts)?.ok_or_else(|| {
                Error::file(
                    dir,
                    format!("has no {stem} file ({stem}.{})", exts.join(", .")),
                )
            })
        };
        let calib = match find_calib(dir, &files)? {
            Some(c) => c,
            None => shared_calib.map(Path::to_path_buf).ok_or_else(|| {
                Error::file(
                    dir,
                    "has no calibration (calib.json here or in the data set's directory)",
                )
            })?,
        };
        Ok(PairFiles {
            name: dir
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            left: need("left", &IMAGE_EXTENSIONS)?,
            right: need("right", &IMAGE_EXTENSIONS)?,
            calib,
            prior: need("prior", &["json"])?,
            truth: find_named(dir, &files, "truth", &["json"])?,
        })
    }

    /// Every file the data set is read from, in a fixed order: the map's,
    /// then each pair's.
    pub fn files(&self) -> Vec<&Path> {
        let mut out: Vec<&Path> = self.map_files.iter().map(PathBuf::as_path).collect();
        for p in &self.pairs {
            out.extend([p.left.as_path(), &p.right, &p.calib, &p.prior]);
            out.extend(p.truth.as_deref());
        }
        out
    }

    /// SHA-256 (hex) of every file of [`DataSet::files`]: each one's path
    /// relative to the data set, its length and its bytes.
    ///
    /// # Errors
    /// A file that cannot be read.
    pub fn fingerprint(&self) -> Result<String> {
        let mut h = Sha256::new();
        for f in self.files() {
            let rel = f.strip_prefix(&self.dir).unwrap_or(f);
            let bytes = crate::io::read_file(f)?;
            h.update(rel.to_string_lossy().as_bytes());
            h.update([0]);
            h.update((bytes.len() as u64).to_le_bytes());
            h.update(&bytes);
        }
        Ok(h.finalize().iter().map(|b| format!("{b:02x}")).collect())
    }
}

/// A pair's inputs besides its images, read and checked before any trial.
#[derive(Clone, Debug)]
pub struct PairInputs {
    /// The calibration.
    pub calib: Calibration,
    /// The uncertainty the prior states (`None`: the engine's default).
    pub uncertainty: Option<PriorUncertainty>,
    /// The truth in the user frame and in the map's local frame, if given.
    pub truth: Option<(UserPose, Pose)>,
}

/// Read and check the calibration, prior, truth and image sizes of `p`
/// against the checked map `map`.
///
/// # Errors
/// The first bad file, named, with its failure code where it has one.
pub fn check_pair(
    p: &PairFiles,
    map: &MapView<'_>,
    interp: crate::rectify::Interp,
) -> Result<PairInputs> {
    let calib = job::read_calibration(&p.calib, interp)?;
    let prior = json::read_prior(&p.prior)?;
    prior.world_from_left.to_local(map.origin()).map_err(|c| {
        Error::file(
            &p.prior,
            format!("pose rejected in the map's local frame: {}", c.name()),
        )
        .with_code(c)
    })?;
    let truth = match &p.truth {
        None => None,
        Some(path) => {
            let user = json::read_user_pose(path)?;
            let local = crate::frame::to_local(&user, map.origin()).map_err(|c| {
                Error::file(
                    path,
                    format!("pose rejected in the map's local frame: {}", c.name()),
                )
                .with_code(c)
            })?;
            Some((user, local))
        }
    };
    let (w, h) = calib.image_size;
    for img in [&p.left, &p.right] {
        let (iw, ih) = image::image_dimensions(img)
            .map_err(|e| Error::file(img, format!("not a readable image: {e}")))?;
        if (iw, ih) != (w, h) {
            return Err(Error::file(
                img,
                format!(
                    "is {iw}×{ih}; its calibration {} is for {w}×{h}",
                    p.calib.display()
                ),
            ));
        }
    }
    Ok(PairInputs {
        calib,
        uncertainty: prior.uncertainty.map(|u| u.core()),
        truth,
    })
}

/// What every trial of a data set's campaign reads.
struct Shared<'a> {
    cfg: &'a SuiteConfig,
    set: &'a DataSet,
    inputs: &'a [PairInputs],
    groups: &'a [Group],
    map: MapView<'a>,
}

/// The pair index of group `g` (set by [`groups`]).
fn pair_of(g: &Group) -> usize {
    match g.columns {
        GroupColumns::Dataset { pair, .. } => pair as usize,
        _ => 0,
    }
}

/// One group per pair, its columns recording the uncertainty the engine
/// runs with (the prior's stated one, or the default for the pair's width).
fn groups(set: &DataSet, inputs: &[PairInputs]) -> Vec<Group> {
    set.pairs
        .iter()
        .zip(inputs)
        .enumerate()
        .map(|(i, (p, inp))| {
            let default_u = locate::params_for_width(inp.calib.rig.cam().width()).uncertainty();
            let u = inp.uncertainty.unwrap_or(default_u);
            let columns = GroupColumns::Dataset {
                pair: u32::try_from(i).unwrap_or(u32::MAX),
                t0_m: u.t_m,
                r0_deg: u.r_deg,
            };
            Group::new(p.name.clone(), 0, 0, columns).with_prior((0.0, 0.0), 0, inp.uncertainty)
        })
        .collect()
}

/// Run trial `k` of group `gi`.
fn run_trial(sh: &Shared<'_>, gi: usize, k: usize) -> TrialOutcome {
    let (cfg, g) = (sh.cfg, &sh.groups[gi]);
    let p = pair_of(g);
    let (files, inp) = (&sh.set.pairs[p], &sh.inputs[p]);
    let seed = trial_seed(cfg.seed, k);
    let mut o = TrialOutcome {
        group: g.label.clone(),
        method: g.method.name().to_string(),
        trial: k,
        seed,
        success: false,
        failure: None,
        init_t_mm: f64::NAN,
        init_r_deg: f64::NAN,
        final_t_mm: f64::NAN,
        final_r_deg: f64::NAN,
        inliers: 0,
        iterations: 0,
        time_s: 0.0,
        columns: TrialColumns {
            group: Some(g.columns),
            ..TrialColumns::default()
        },
    };
    let pair = job::Pair {
        left: files.left.clone(),
        right: files.right.clone(),
        prior: files.prior.clone(),
        calib: None,
        truth: None,
        out: None,
        seed,
    };
    let loaded = match job::load_inputs(&sh.map, &inp.calib, &pair, cfg.verify) {
        Ok(l) => l,
        Err(e) => {
            o.failure = Some(format!("input: {e}"));
            return o;
        }
    };
    let inputs = trial::Inputs {
        rig: loaded.rig,
        left: loaded.left.pixels,
        right: loaded.right.pixels,
        prior: loaded.prior,
        rectifier: loaded.physical,
    };
    let frame = ErrorFrame::user(inp.truth, loaded.origin);
    let (t0, r0) = frame.error(&inputs.as_physical(&inputs.prior));
    (o.init_t_mm, o.init_r_deg) = (t0 * 1e3, r0.to_degrees());
    (o.final_t_mm, o.final_r_deg) = (o.init_t_mm, o.init_r_deg);
    let req = trial::request(cfg, g, sh.map, &inputs, seed);
    match g.method {
        Method::Features => trial::run_features(&mut o, &req, &inputs, &frame),
        Method::Vtsm => {
            let ran = trial::run_vtsm(&mut o, cfg, &req, &inputs, &frame, None);
            if let (Some(dir), Some((pose, template_px)), 0) = (&cfg.panels, ran, k) {
                if let Err(e) = write_panel(dir, sh, files, inp, &inputs, (pose, template_px)) {
                    eprintln!("vtsm: warning: no panel for {}: {e}", files.name);
                }
            }
        }
    }
    o
}

/// The result panel of a pair's first VTSM trial, `panels/<pair>.png`: as
/// `vtsm demo`'s, in the core's (rectified) left camera; the points are
/// placed at the truth, or at the final pose when the pair has none.
fn write_panel(
    dir: &Path,
    sh: &Shared<'_>,
    files: &PairFiles,
    inp: &PairInputs,
    inputs: &trial::Inputs,
    (fin, template_px): (Pose, u16),
) -> Result<()> {
    let truth = inp.truth.map_or(fin, |(_, local)| {
        inputs
            .rectifier
            .as_ref()
            .map_or(local, |r| r.to_rectified(&local))
    });
    let canvas = crate::panel::result_panel(
        &sh.map,
        &inputs.rig.cam(),
        &inputs.left,
        &inputs.prior,
        &fin,
        &truth,
        template_px,
        sh.cfg.seed,
    );
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::file(dir, format!("cannot create directory: {e}")))?;
    canvas.save_png(&dir.join(format!("{}.png", files.name)), true)
}

/// The reproducibility record of a data set's campaign.
fn run_meta(
    cfg: &SuiteConfig,
    set: &DataSet,
    inputs: &[PairInputs],
    fingerprint: String,
    command: &str,
) -> RunMeta {
    let mut widths: Vec<u32> = inputs.iter().map(|i| i.calib.rig.cam().width()).collect();
    widths.sort_unstable();
    widths.dedup();
    let per_width = |f: &dyn Fn(u32) -> String| -> serde_json::Value {
        widths
            .iter()
            .map(|&w| (w.to_string(), serde_json::Value::String(f(w))))
            .collect::<serde_json::Map<_, _>>()
            .into()
    };
    let map_name = set
        .map
        .map
        .as_ref()
        .or(set.map.mesh.as_ref())
        .map(|p| lower_name(p));
    RunMeta {
        suite: cfg.suite.name().to_string(),
        git_revision: eval::git_revision(),
        profile: DATA_PROFILE.to_string(),
        seed: cfg.seed,
        trials: cfg.trials,
        physical: inputs.iter().any(|i| i.calib.physical.is_some()),
        params: serde_json::json!({
            "data": set.name,
            "data_sha256": fingerprint,
            "pairs": set.pairs.iter().map(|p| p.name.clone()).collect::<Vec<_>>(),
            "map": map_name,
            "mask": set.map.mask.as_ref().map(|p| lower_name(p)),
            "tile_m": TILE_M,
            "relocalization": per_width(&|w| format!("{:?}", locate::params_for_width(w))),
            "rectify_interp": cfg.interp.name(),
            "baseline": cfg.baseline.map(Method::name),
            "verify": verify_json(cfg),
            "accuracy": accuracy_json(cfg),
            "final_pairs": cfg.final_pairs,
            "revisit": cfg.search.revisit,
            "near": cfg.search.near.share_256 > 0,
            "map_scores": cfg.map_scores,
            "features": cfg.baseline.map(|_| {
                per_width(&|w| format!("{:?}", crate::features::FeatureParams::for_width(w)))
            }),
        }),
        command: command.to_string(),
    }
}

/// The `profile` a data set's campaign records: its images are its own.
pub const DATA_PROFILE: &str = "data";

/// Run the campaign of `cfg` (`--suite dataset --data DIR`): find and check
/// the data set, load and check its map once, run every pair's trials (the
/// campaign indices of `cfg.shard`, those in `journal` read back).
///
/// # Errors
/// No `--data`, a data set that does not follow the layout, or any bad file
/// of it (named, with its code); a journal of another campaign.
pub fn run(
    cfg: &SuiteConfig,
    command: &str,
    journal: Option<&super::shard::Journal>,
) -> Result<SuiteRun> {
    let dir = cfg
        .data
        .as_deref()
        .ok_or_else(|| Error::msg("--suite dataset needs --data DIR"))?;
    if cfg.trials == 0 {
        return Err(Error::msg("--trials must be at least 1"));
    }
    let t_setup = Instant::now();
    let mut set = DataSet::find(dir)?;
    set.map.scores = cfg.map_scores;
    let fingerprint = set.fingerprint()?;
    let bytes = job::load_map(&set.map)?;
    let map = job::check_map(&bytes, &set.map)?;
    let inputs = set
        .pairs
        .iter()
        .map(|p| check_pair(p, &map, cfg.interp))
        .collect::<Result<Vec<_>>>()?;
    let groups = with_baseline_groups(groups(&set, &inputs), cfg.baseline);
    let setup_s = t_setup.elapsed().as_secs_f64();
    let meta = run_meta(cfg, &set, &inputs, fingerprint, command);
    let sh = Shared {
        cfg,
        set: &set,
        inputs: &inputs,
        groups: &groups,
        map,
    };
    run_campaign(cfg, meta, groups.len(), journal, setup_s, |g, k| {
        run_trial(&sh, g, k)
    })
}
