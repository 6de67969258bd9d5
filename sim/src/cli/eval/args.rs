//! The command line of `vtsm eval` and the [`SuiteConfig`] it makes.

use super::config::{Method, Suite, SuiteConfig};
use crate::error::{Error, Result};
use crate::rectify::Interp;
use crate::render::LightModel;
use crate::scene::Profile;
use crate::terrain::TerrainKind;
use std::path::PathBuf;

/// `--profile`: the image profile.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum ProfileArg {
    /// 480×320 images.
    #[default]
    Test,
    /// 1368×912 images.
    Demo,
    /// 5472×3648 images.
    Paper,
}

impl From<ProfileArg> for Profile {
    fn from(p: ProfileArg) -> Self {
        match p {
            ProfileArg::Test => Self::Test,
            ProfileArg::Demo => Self::Demo,
            ProfileArg::Paper => Self::Paper,
        }
    }
}

/// A `--terrains` entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
#[value(rename_all = "lower")]
pub enum TerrainArg {
    /// Broken slabs separated by cracks.
    Flagstone,
    /// Rocks on sand, k = 6 %.
    Cfa6,
    /// Pebbles on dust and sand, k = 2 %.
    Cfa2,
}

impl From<TerrainArg> for TerrainKind {
    fn from(t: TerrainArg) -> Self {
        match t {
            TerrainArg::Flagstone => Self::Flagstone,
            TerrainArg::Cfa6 => Self::Cfa6,
            TerrainArg::Cfa2 => Self::Cfa2,
        }
    }
}

/// `--baseline`: a relocalizer run next to VTSM.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BaselineArg {
    /// FAST + BRIEF + stereo + RANSAC ([`crate::features`]).
    Features,
}

impl From<BaselineArg> for Method {
    fn from(b: BaselineArg) -> Self {
        match b {
            BaselineArg::Features => Self::Features,
        }
    }
}

/// `--light-model`: the parts of the sunlight the depot has.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum LightModelArg {
    /// Cast shadows and attached shading.
    #[default]
    Full,
    /// No cast shadows.
    NoCastShadows,
    /// No attached shading.
    NoAttachedShading,
    /// Neither.
    Flat,
}

impl From<LightModelArg> for LightModel {
    fn from(m: LightModelArg) -> Self {
        match m {
            LightModelArg::Full => Self::Full,
            LightModelArg::NoCastShadows => Self::NoCastShadows,
            LightModelArg::NoAttachedShading => Self::NoAttachedShading,
            LightModelArg::Flat => Self::Flat,
        }
    }
}

/// `--mask`: the sampling mask M̂ of the maps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum MaskArg {
    /// Rocks only on flagstone and cfa6, everything on cfa2 (the paper).
    #[default]
    Paper,
    /// Every triangle.
    All,
}

/// `vtsm eval` subcommands.
#[derive(Debug, Clone, clap::Subcommand)]
pub enum EvalCommand {
    /// Join the parts of a campaign run with `--shard K/N` into the outputs
    /// of a single run (table, trials.csv, summary.json, figures).
    Merge(MergeArgs),
}

/// Arguments of `vtsm eval merge`.
#[derive(Debug, Clone, clap::Args)]
pub struct MergeArgs {
    /// Output directory (refused if it exists and is not empty, unless
    /// `--force`).
    #[arg(long)]
    pub out: PathBuf,
    /// Replace existing outputs in `--out`.
    #[arg(long)]
    pub force: bool,
    /// The parts' result directories, every shard of one campaign once.
    #[arg(required = true, value_name = "PART")]
    pub parts: Vec<PathBuf>,
}

/// Arguments of `vtsm eval`.
#[derive(Debug, Clone, clap::Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct Args {
    /// `merge`: join the parts of a sharded campaign.
    #[command(subcommand)]
    pub command: Option<EvalCommand>,
    /// Suite (not with `--replot`, which reads it).
    #[arg(
        long,
        value_enum,
        ignore_case = true,
        required_unless_present = "replot"
    )]
    pub suite: Option<Suite>,
    /// Trials per group.
    #[arg(long, default_value_t = 2)]
    pub trials: usize,
    /// Base seed (scenes, captures, priors and relocalizations derive from it).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Image profile: test (480×320), demo (1368×912) or paper (5472×3648).
    #[arg(long, value_enum, ignore_case = true, default_value_t = ProfileArg::Test)]
    pub profile: ProfileArg,
    /// Output directory (default: the first free `vtsm-eval/<suite>-N`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Overwrite existing outputs in `--out`.
    #[arg(long)]
    pub force: bool,
    /// Comma-separated terrains (default: flagstone,cfa6,cfa2).
    #[arg(long, value_enum, ignore_case = true, value_delimiter = ',')]
    pub terrains: Option<Vec<TerrainArg>>,
    /// Comma-separated time differences in hours (default: 0,3,6; `uncertainty50`: 0).
    #[arg(long, value_delimiter = ',')]
    pub hours: Option<Vec<f32>>,
    /// Comma-separated mapping step sizes for `stepsize` (default: 1,3,6,12).
    #[arg(long, value_delimiter = ',')]
    pub steps: Option<Vec<usize>>,
    /// Pose seeds K of the multi-seed mode in `uncertainty50` (0: no multi-seed group).
    #[arg(long, default_value_t = 16)]
    pub seeds_k: u16,
    /// Also run a baseline relocalizer on the same trials and report it next to
    /// VTSM (`paper`, `baseline`, `hard` and `dataset` suites).
    #[arg(long, value_enum, ignore_case = true)]
    pub baseline: Option<BaselineArg>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Offset X,Y,Z (metres) of the whole scene: mesh, priors and truths, e.g.
    /// UTM coordinates; the results are the same.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub origin: Option<String>,
    /// `--verify [repeat,map]`: the engine's upset checks.
    #[command(flatten)]
    pub verify: super::super::VerifyArg,
    /// `--accuracy T_MM,R_DEG`: every VTSM trial ends its rounds once the
    /// stated uncertainty meets it.
    #[command(flatten)]
    pub accuracy: super::super::AccuracyArg,
    /// `--final-pairs N`: correspondences of every VTSM trial's last round.
    #[command(flatten)]
    pub final_pairs: super::super::FinalPairsArg,
    /// `--revisit on|off`, `--near on|off`: the search mechanisms of every
    /// VTSM trial.
    #[command(flatten)]
    pub search: super::super::SearchArgs,
    /// `--map-scores on|off`: maps built with sampling scores.
    #[command(flatten)]
    pub map_scores: super::super::MapScoresArg,
    /// Count each VTSM trial's attempts and correct matches per decile of
    /// the map's sampling scores (columns `score_d<k>_attempts`,
    /// `score_d<k>_correct`; the notes' decile table).
    #[arg(long)]
    pub score_deciles: bool,
    /// Relight each group's map from the mapping sun to its live pairs' sun
    /// before matching ([`crate::relight`]; `on`), or match the map as made
    /// (`off`, the default).
    #[arg(long, value_enum, ignore_case = true, default_value_t = super::super::OnOff::Off)]
    pub relight: super::super::OnOff,
    /// Count each VTSM trial's matches, accepted matches and correct
    /// matches per template variant (columns `variant_<k>_matches`,
    /// `_accepted`, `_correct`; the notes' variant table).
    #[arg(long)]
    pub variant_counts: bool,
    /// Live pairs in the physical form of `vtsm scene export --physical`
    /// (distorted, slightly rotated cameras, OpenCV calibration), rectified on
    /// the host as `vtsm relocalize` does; errors are those of the physical
    /// left camera.
    #[arg(long)]
    pub physical: bool,
    /// Kernel of the host rectification of `--physical` pairs (`cv2.remap`'s
    /// INTER_* of those names).
    #[arg(
        long,
        value_name = "KERNEL",
        value_enum,
        default_value_t = Interp::Lanczos4,
        requires = "physical"
    )]
    pub interp: Interp,
    /// Parts of the sunlight the simulated depot has, at mapping and live time
    /// alike (`flat`: neither cast shadows nor attached shading; a diagnostic
    /// of how each part moves the error after a change of the time of day).
    #[arg(long, value_name = "MODEL", value_enum, default_value_t = LightModelArg::Full)]
    pub light_model: LightModelArg,
    /// Sampling mask M̂ of the maps: `paper` (rocks only on flagstone and cfa6,
    /// everything on cfa2, as the paper) or `all` (every triangle).
    #[arg(long, value_name = "MASK", value_enum, default_value_t = MaskArg::Paper)]
    pub mask: MaskArg,
    /// Wind between mapping and relocalization, strength 0..=1 (0: none): sand
    /// ripples, dust streaks and moved pebbles in the live depot
    /// (`Terrain::with_wind`); the maps stay those of the mapping-time depot.
    #[arg(long, value_name = "S", default_value_t = 0.0)]
    pub wind: f32,
    /// Maps from imagery K times coarser (1, 2, 4 or 8): vertex spacing and
    /// texel size × K, each texel the mean over its footprint, as a map from
    /// a lander's descent camera or an older rover's (`Scene::with_map_coarse`);
    /// the live pairs are unchanged.
    #[arg(long, value_name = "K", default_value_t = 1)]
    pub map_coarse: u32,
    /// `--change SPEC` and `--camera SPEC`: the live depot changed since
    /// mapping and a camera that is not ideal, in every group (the `hard`
    /// suite sets its own).
    #[command(flatten)]
    pub conditions: super::super::ConditionsArg,
    /// Run nothing: draw the figures of the run recorded in DIR again from its
    /// `trials.csv` (suite and terrains from its `summary.json`), into DIR
    /// (`--force` to replace them).
    #[arg(long, value_name = "DIR", conflicts_with = "suite")]
    pub replot: Option<PathBuf>,
    /// Run only shard K of N of the campaign's trials (campaign index `i`,
    /// `group × trials + k`, runs in shard `i mod N`; K from 0 to N − 1, as a Slurm array task id) and write a part
    /// (the outputs of those trials and a `part.json`) for `vtsm eval merge`.
    /// Each finished trial is recorded in `part.d/`; rerun into the same
    /// `--out`, a killed shard runs only the trials not recorded.
    #[arg(long, value_name = "K/N", value_parser = super::shard::Shard::parse)]
    pub shard: Option<super::shard::Shard>,
    /// The data set of `--suite dataset`: a directory in the layout of
    /// `fsw-docs/interfaces/files.md` (a map, and one directory per stereo
    /// pair under `views/`).
    #[arg(long, value_name = "DIR")]
    pub data: Option<PathBuf>,
    /// `--suite dataset`: also write a result panel per pair (as `vtsm
    /// demo`'s `panel.png`, from the pair's first trial) into `--out`'s
    /// `panels/`.
    #[arg(long)]
    pub panels: bool,
}

impl Args {
    /// The defaults of the command line for `suite`: one trial, seed 1, test
    /// profile, no progress bar.
    pub fn new(suite: Suite) -> Self {
        Self {
            suite: Some(suite),
            trials: 1,
            seed: 1,
            profile: ProfileArg::Test,
            out: None,
            force: false,
            terrains: None,
            hours: None,
            steps: None,
            seeds_k: 16,
            baseline: None,
            quiet: true,
            origin: None,
            verify: super::super::VerifyArg::default(),
            accuracy: super::super::AccuracyArg::default(),
            final_pairs: super::super::FinalPairsArg::default(),
            search: super::super::SearchArgs::default(),
            map_scores: super::super::MapScoresArg::default(),
            score_deciles: false,
            relight: super::super::OnOff::Off,
            variant_counts: false,
            physical: false,
            interp: Interp::Lanczos4,
            light_model: LightModelArg::Full,
            mask: MaskArg::Paper,
            wind: 0.0,
            map_coarse: 1,
            conditions: super::super::ConditionsArg::default(),
            replot: None,
            shard: None,
            data: None,
            panels: false,
            command: None,
        }
    }
}

/// Build the config from command-line arguments.
///
/// # Errors
/// No suite, out-of-range numbers, an unusable origin, or a baseline with a
/// suite that has none.
pub fn config_from_args(args: &Args) -> Result<SuiteConfig> {
    let suite = args
        .suite
        .ok_or_else(|| Error::msg("--suite is required to run a suite"))?;
    if args.trials == 0 {
        return Err(Error::msg("--trials must be at least 1"));
    }
    let mut cfg = SuiteConfig::new(suite, args.profile.into(), args.trials, args.seed);
    if let Some(t) = &args.terrains {
        cfg.terrains = t.iter().map(|&t| t.into()).collect();
    }
    if let Some(h) = &args.hours {
        if h.iter()
            .any(|h| !(h.is_finite() && (0.0..=8.0).contains(h)))
        {
            return Err(Error::msg("--hours must be between 0 and 8"));
        }
        cfg.hours = h.clone();
    }
    if let Some(s) = &args.steps {
        if s.iter().any(|&s| s == 0 || s > 60) {
            return Err(Error::msg("--steps must be 1..=60"));
        }
        cfg.steps = s.clone();
    }
    if usize::from(args.seeds_k) > vtsm_core::config::MAX_SEEDS {
        return Err(Error::msg(format!(
            "--seeds-k must be at most {}",
            vtsm_core::config::MAX_SEEDS
        )));
    }
    cfg.seeds_k = args.seeds_k;
    if let Some(b) = args.baseline {
        if !suite.def().takes_baseline() {
            return Err(Error::msg(
                "--baseline runs with the paper, baseline, hard and dataset suites only",
            ));
        }
        cfg.baseline = Some(b.into());
    }
    cfg.progress = !args.quiet;
    cfg.origin = args
        .origin
        .as_deref()
        .map(crate::frame::parse_origin)
        .transpose()?;
    cfg.verify = args.verify.checks();
    cfg.accuracy = args.accuracy.accuracy;
    cfg.final_pairs = args.final_pairs.final_pairs;
    cfg.search = args.search.search();
    cfg.map_scores = args.map_scores.on();
    cfg.score_deciles = args.score_deciles;
    cfg.relight = args.relight == super::super::OnOff::On;
    cfg.variant_counts = args.variant_counts;
    cfg.physical = args.physical;
    cfg.interp = args.interp;
    cfg.light_model = args.light_model.into();
    cfg.mask_all = args.mask == MaskArg::All;
    if !(0.0..=1.0).contains(&args.wind) {
        return Err(Error::msg("--wind must be a strength in 0..=1"));
    }
    cfg.wind = args.wind;
    cfg.map_coarse = crate::scene::Scene::check_map_coarse(args.map_coarse)?;
    cfg.change = args.conditions.change;
    cfg.camera = args.conditions.camera;
    cfg.shard = args.shard;
    dataset_args(args, &mut cfg)?;
    Ok(cfg)
}

/// `--data` and `--panels`, which belong to `--suite dataset` alone, and the
/// simulator's settings, which do not apply to it.
fn dataset_args(args: &Args, cfg: &mut SuiteConfig) -> Result<()> {
    if cfg.suite != Suite::Dataset {
        if args.data.is_some() || args.panels {
            return Err(Error::msg("--data and --panels go with --suite dataset"));
        }
        return Ok(());
    }
    let data = args
        .data
        .clone()
        .ok_or_else(|| Error::msg("--suite dataset needs --data DIR"))?;
    let simulated = [
        ("--terrains", args.terrains.is_some()),
        ("--hours", args.hours.is_some()),
        ("--steps", args.steps.is_some()),
        ("--origin", args.origin.is_some()),
        ("--physical", args.physical),
        ("--light-model", args.light_model != LightModelArg::Full),
        ("--mask", args.mask != MaskArg::Paper),
        ("--wind", args.wind != 0.0),
        ("--map-coarse", args.map_coarse != 1),
        ("--change", !args.conditions.change.is_none()),
        ("--camera", !args.conditions.camera.is_none()),
    ];
    if let Some((flag, _)) = simulated.iter().find(|f| f.1) {
        return Err(Error::msg(format!(
            "{flag} sets up the simulated depot; a data set brings its own pairs"
        )));
    }
    // `--panels` is set by the command once `--out` is resolved.
    cfg.data = Some(data);
    Ok(())
}
