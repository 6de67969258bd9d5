//! What defines a suite run: the suite, the relocalizer and every setting.

use crate::rectify::Interp;
use crate::render::LightModel;
use crate::scene::Profile;
use crate::terrain::TerrainKind;
use vtsm_hal::runner::VerifyChecks;

/// A relocalizer evaluated on the suite's trials.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// The paper's method (the core's engine).
    Vtsm,
    /// The local-feature baseline ([`crate::features`]).
    Features,
}

impl Method {
    /// Name used in the `method` column and in group labels.
    pub fn name(self) -> &'static str {
        match self {
            Self::Vtsm => "vtsm",
            Self::Features => "features",
        }
    }
}

/// The suites; what each one runs is in its module of
/// [`super::suites`], found through [`Suite::def`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
#[value(rename_all = "lower")]
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
    /// The stereo pairs of a data set on disk (`--data DIR`), real or not.
    Dataset,
    /// The operating envelope: low sun, a changed depot, coarse maps, a
    /// camera that is not ideal, and their worst combinations.
    Hard,
}

impl Suite {
    /// Parse a suite name (any case).
    pub fn parse(s: &str) -> Option<Self> {
        <Self as clap::ValueEnum>::from_str(s, true).ok()
    }

    /// Command-line name.
    pub fn name(self) -> &'static str {
        self.def().name()
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
    /// The accuracy every VTSM trial is asked for (`--accuracy`).
    pub accuracy: Option<vtsm_core::reloc::Accuracy>,
    /// Correspondences of every VTSM trial's last round (`--final-pairs`; 0:
    /// N_corr).
    pub final_pairs: u16,
    /// The search mechanisms of every VTSM trial (`--revisit`, on by
    /// default; `--near`, off).
    pub search: vtsm_core::reloc::Search,
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
    /// The maps from imagery this many times coarser (`--map-coarse`, 1 =
    /// the profile's map; `Scene::with_map_coarse`).
    pub map_coarse: u32,
    /// How the live depot changed since mapping (`--change`).
    pub change: crate::terrain::DepotChange,
    /// The live camera's effects in every group (`--camera`).
    pub camera: crate::effects::CameraEffects,
    /// Maps carry sampling scores (`--map-scores on`): version-3 products,
    /// SamplePoint draws in proportion to them.
    pub map_scores: bool,
    /// Count every VTSM trial's attempts and correct matches per decile of
    /// the map's scores (`--score-deciles`; scores computed whether or not
    /// the map carries them).
    pub score_deciles: bool,
    /// Each group's map relit to its live pairs' sun (`--relight on`).
    pub relight: bool,
    /// Count matches per template variant (`--variant-counts`).
    pub variant_counts: bool,
    /// Run only this shard of the campaign's trials (`--shard K/N`).
    pub shard: Option<super::shard::Shard>,
    /// The data set directory (`dataset` only, `--data`).
    pub data: Option<std::path::PathBuf>,
    /// Where to write a result panel per pair (`dataset` only, `--panels`):
    /// the run's `panels/` directory.
    pub panels: Option<std::path::PathBuf>,
}

impl SuiteConfig {
    /// The suite's defaults: all terrains, Δ 0/3/6 h (0 h for `uncertainty50`
    /// and `wrongplace`), steps 1/3/6/12, K = 16.
    pub fn new(suite: Suite, profile: Profile, trials: usize, seed: u64) -> Self {
        Self {
            suite,
            trials,
            seed,
            profile,
            terrains: TerrainKind::ALL.to_vec(),
            hours: suite.def().default_hours(),
            steps: vec![1, 3, 6, 12],
            seeds_k: 16,
            baseline: None,
            progress: false,
            origin: None,
            verify: VerifyChecks::OFF,
            accuracy: None,
            final_pairs: 0,
            search: vtsm_core::reloc::Search::DEFAULT,
            physical: false,
            interp: Interp::default(),
            light_model: LightModel::Full,
            mask_all: false,
            wind: 0.0,
            map_coarse: 1,
            change: crate::terrain::DepotChange::NONE,
            camera: crate::effects::CameraEffects::NONE,
            map_scores: false,
            score_deciles: false,
            relight: false,
            variant_counts: false,
            shard: None,
            data: None,
            panels: None,
        }
    }
}
