//! One relocalization on the desktop, on the flight path: simulated devices
//! (camera, clock, map store, prior, telemetry) serve the request to the HAL
//! runner, which acquires the inputs, builds the engine with the core's one
//! constructor ([`vtsm_core::reloc::Setup`]) over a heap workspace, and
//! drives it. Used by `vtsm demo`, `vtsm relocalize`, `vtsm eval`, `vtsm
//! bench`, `vtsm budget` and the end-to-end tests, so every path runs exactly
//! the same code: a [`Request`] built by [`Request::new`], run by [`run`] (or
//! [`relocalize`], which also turns a runner failure into an error) with one
//! [`RunOptions`] (device faults, drive limits, pair path, step hook, stage
//! observer).
//!
//! Copies and checks: the devices borrow the request's images and map (no
//! copy to set them up). A map given as a [`MapIn::Checked`] view is handed
//! to the runner as is (no read, copy or check there); raw bytes are checked
//! by the runner once. On [`PairPath::Ram`] the camera copies the pair once
//! into the runner's buffers; on [`PairPath::Store`] it is never copied
//! ([`DeviceRun::pair_copies`] counts them).

use crate::devices::{
    DecodedFrame, FaultConfig, FaultInjector, FixedCamera, FixedPrior, ManualClock, MemMapStore,
    RecordingSink,
};
use crate::error::{Error, Result};
use crate::workers::{RecordingPool, SampleRecord, ThreadPool};
use std::time::{Duration, Instant};
use vtsm_core::config::{Params, PriorUncertainty};
use vtsm_core::failure::FailureLog;
use vtsm_core::geom::Camera;
use vtsm_core::geom::{Pose, StereoRig};
use vtsm_core::image::Rect;
use vtsm_core::map::MapView;
use vtsm_core::ncc::Run;
use vtsm_core::raster::{self, Target};
use vtsm_core::reloc::{MatchPolicy, Outcome, Workspace, WorkspaceSizes};
use vtsm_core::FailureCode;
use vtsm_hal::runner::{
    Between, DriveLimits, InStore, Job, RamPair, RelocReport, Runner, RunnerConfig, StageEvent,
    StepStatus, VerifyChecks,
};
use vtsm_hal::AttemptPool;
use vtsm_hal::{Covariance, FramedTelemetry, PriorEstimate};

/// The parameters used for an image width: the paper's, with ℓ and the
/// search window scaled to the image ([`Params::for_image_width`]).
pub fn params_for_width(width: u32) -> Params {
    Params::for_image_width(width)
}

/// The map product a [`Request`] runs against.
#[derive(Clone, Copy, Debug)]
#[allow(
    clippy::large_enum_variant,
    reason = "a Copy value built once per request; boxing the view would allocate for nothing"
)]
pub enum MapIn<'a> {
    /// Encoded bytes: the runner checks them (in place or after reading
    /// them from the simulated storage), as on the flight path.
    Bytes(&'a [u8]),
    /// A view the caller checked once when it loaded or built the product
    /// ([`MapView::new_checked`]): handed to the runner as is, never read,
    /// copied or checked again (the host path).
    Checked(MapView<'a>),
}

impl<'a> MapIn<'a> {
    /// The encoded product.
    pub fn bytes(&self) -> &'a [u8] {
        match self {
            MapIn::Bytes(b) => b,
            MapIn::Checked(v) => v.bytes(),
        }
    }
}

impl<'a> From<&'a [u8]> for MapIn<'a> {
    fn from(b: &'a [u8]) -> Self {
        MapIn::Bytes(b)
    }
}

impl<'a> From<&'a Vec<u8>> for MapIn<'a> {
    fn from(b: &'a Vec<u8>) -> Self {
        MapIn::Bytes(b)
    }
}

impl<'a> From<MapView<'a>> for MapIn<'a> {
    fn from(v: MapView<'a>) -> Self {
        MapIn::Checked(v)
    }
}

/// Everything one relocalization needs. Built by [`Request::new`] and its
/// `with_*` methods.
#[derive(Clone, Copy)]
pub struct Request<'a> {
    /// The map product.
    pub map: MapIn<'a>,
    /// Left image, row-major, `rig.cam.width × rig.cam.height`.
    pub left: &'a [u8],
    /// Right image, same size.
    pub right: &'a [u8],
    /// Calibrated rig.
    pub rig: StereoRig,
    /// Prior `world_from_left`.
    pub prior: Pose,
    /// The prior's stated uncertainty (`prior.json`'s `uncertainty`): served
    /// with the prior, so the runner builds the engine with it as t̃₀, r̃₀.
    /// `None`: `params.t0_m`, `params.r0_deg` are the prior's uncertainty.
    pub uncertainty: Option<PriorUncertainty>,
    /// Relocalization parameters (validated by the core).
    pub params: Params,
    /// Seed of the relocalization's random streams.
    pub seed: u64,
    /// The engine's upset checks ([`Job::verify`](vtsm_hal::runner::Job::verify)).
    pub verify: VerifyChecks,
    /// The accuracy the caller needs ([`Job::accuracy`](vtsm_hal::runner::Job::accuracy)):
    /// the rounds end once the stated uncertainty meets it.
    pub accuracy: Option<vtsm_core::reloc::Accuracy>,
    /// Correspondences of the last round ([`Job::final_pairs`](vtsm_hal::runner::Job::final_pairs); 0: N_corr).
    pub final_pairs: u16,
    /// The search mechanisms, Revisit and Near ([`Job::search`](vtsm_hal::runner::Job::search)).
    pub search: vtsm_core::reloc::Search,
    /// Threads the attempts run on ([`crate::workers`]); 1: the runner's
    /// own pipeline in the caller's thread. Same outcome for every number.
    pub threads: usize,
}

impl<'a> Request<'a> {
    /// The request of `map`, the pair `left`/`right` seen by `rig` and the
    /// prior `prior`, with the parameters for the rig's image width
    /// ([`params_for_width`]), seed 0, no upset check, no stated prior
    /// uncertainty and one thread.
    pub fn new(
        map: impl Into<MapIn<'a>>,
        left: &'a [u8],
        right: &'a [u8],
        rig: StereoRig,
        prior: Pose,
    ) -> Self {
        Self {
            map: map.into(),
            left,
            right,
            rig,
            prior,
            uncertainty: None,
            params: params_for_width(rig.cam().width()),
            seed: 0,
            verify: VerifyChecks::OFF,
            accuracy: None,
            final_pairs: 0,
            search: vtsm_core::reloc::Search::DEFAULT,
            threads: 1,
        }
    }

    /// The same request with its attempts on `threads` threads (at least
    /// 1); the outcome is the same for every number.
    pub fn with_threads(self, threads: usize) -> Self {
        Self {
            threads: threads.max(1),
            ..self
        }
    }

    /// The same request with these parameters.
    pub fn with_params(self, params: Params) -> Self {
        Self { params, ..self }
    }

    /// The same request with this seed.
    pub fn with_seed(self, seed: u64) -> Self {
        Self { seed, ..self }
    }

    /// The same request with these upset checks.
    pub fn with_verify(self, verify: VerifyChecks) -> Self {
        Self { verify, ..self }
    }

    /// The same request ending its rounds once the stated uncertainty meets
    /// `accuracy` (`None`: every pose update).
    pub fn with_accuracy(self, accuracy: Option<vtsm_core::reloc::Accuracy>) -> Self {
        Self { accuracy, ..self }
    }

    /// The same request with `final_pairs` correspondences in its last
    /// round (0: N_corr).
    pub fn with_final_pairs(self, final_pairs: u16) -> Self {
        Self {
            final_pairs,
            ..self
        }
    }

    /// The same request with the search mechanisms `search`.
    pub fn with_search(self, search: vtsm_core::reloc::Search) -> Self {
        Self { search, ..self }
    }

    /// The same request with the prior's stated uncertainty.
    pub fn with_uncertainty(self, uncertainty: Option<PriorUncertainty>) -> Self {
        Self {
            uncertainty,
            ..self
        }
    }
}

/// Seeded faults of the simulated devices one relocalization runs on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DeviceFaults {
    /// Faults of the stereo camera (one draw per capture).
    pub camera: FaultConfig,
    /// Faults of the map store (one draw per chunk read).
    pub store: FaultConfig,
    /// Seed of both fault streams.
    pub seed: u64,
    /// Simulated time: ticks the runner's clock advances at each read (0:
    /// time moves only while a camera capture times out). With 1, the
    /// runner's elapsed ticks count its clock reads (one per engine step).
    pub clock_ticks_per_read: u64,
}

/// Workspace sizes the engine built for `params` with the default policy
/// needs (what `vtsm_core::reloc::Setup::sizes` gives for them).
pub fn workspace_sizes(params: &Params) -> WorkspaceSizes {
    WorkspaceSizes::for_params(params, MatchPolicy::for_params(params).search)
}

/// Retry and size settings of the desktop runner for a `width × height` rig,
/// without upset checks.
pub fn runner_config(width: u32, height: u32) -> RunnerConfig {
    RunnerConfig {
        attempts: 3,
        product_attempts: 2,
        chunk_len: 1 << 16,
        capture_timeout_ticks: 1_000,
        image_size: (width, height),
    }
}

/// What one relocalization produced.
pub struct Report {
    /// The engine's outcome.
    pub outcome: Outcome,
    /// Wall time of the run through the runner: device reads of the in-memory
    /// map and pair, engine construction and the engine (not file loading or
    /// workspace allocation).
    pub elapsed: Duration,
    /// Template side used.
    pub template_px: u16,
    /// Search-window cap used.
    pub search_px: u16,
    /// Workspace bytes allocated for the core.
    pub workspace_bytes: usize,
    /// Device, capture, map-read and drive work of the runner.
    pub run: RelocReport,
    /// Device faults and runner events (the engine's own are in `outcome.log`).
    pub device_log: FailureLog,
    /// Telemetry frames decoded from the downlink.
    pub telemetry: Vec<DecodedFrame>,
    /// Whole copies of the stereo pair made ([`DeviceRun::pair_copies`]).
    pub pair_copies: u32,
    /// Attempts the threads worked ([`DeviceRun::attempts_worked`]).
    pub attempts_worked: Option<u32>,
}

/// Run one relocalization to completion with `opts`
/// ([`RunOptions::default`]: fault-free devices, no limit, pair in RAM): the
/// one [`run`], with a runner failure returned as an error.
///
/// # Errors
/// Bad map product, image sizes that disagree with the rig, parameters the
/// core rejects, or device faults that outlast their retries — each with its
/// failure code. A relocalization that fails cleanly is not an error: it is
/// an [`Outcome`] with a failure code.
pub fn relocalize(req: &Request<'_>, opts: RunOptions<'_>) -> Result<Report> {
    let run = run(req, opts)?;
    into_report(req, run)
}

fn into_report(req: &Request<'_>, run: DeviceRun) -> Result<Report> {
    let (outcome, report) = run.result?;
    Ok(Report {
        outcome,
        elapsed: run.elapsed,
        template_px: req.params.template_px,
        search_px: req.params.search_px,
        workspace_bytes: run.workspace_bytes,
        run: report,
        device_log: run.log,
        telemetry: run.telemetry,
        pair_copies: run.pair_copies,
        attempts_worked: run.attempts_worked,
    })
}

/// Everything a run on the simulated devices left behind, also when the
/// runner ended with a failure code.
pub struct DeviceRun {
    /// The runner's result: the outcome and its work, or the code it stopped with.
    pub result: std::result::Result<(Outcome, RelocReport), FailureCode>,
    /// Device faults and runner events.
    pub log: FailureLog,
    /// Telemetry frames decoded from the downlink.
    pub telemetry: Vec<DecodedFrame>,
    /// Wall time of the runner call.
    pub elapsed: Duration,
    /// Workspace bytes allocated for the core.
    pub workspace_bytes: usize,
    /// The simulated clock at the end of the run, ticks from 0 (camera
    /// timeouts and, with [`DeviceFaults::clock_ticks_per_read`], every clock read).
    pub ticks: u64,
    /// Whole copies of the stereo pair made: the camera's captures into the
    /// runner's RAM buffers (1 on [`PairPath::Ram`], 0 on
    /// [`PairPath::Store`]); setting the camera up copies nothing.
    pub pair_copies: u32,
    /// With threads ([`Request::threads`] > 1): the attempts the threads
    /// worked, those taken back (`outcome.stats.attempts`) and those dropped
    /// as stale; `None` on one thread.
    pub attempts_worked: Option<u32>,
}

impl DeviceRun {
    /// The record of a runner call that began at `start`: its result, the
    /// runner's log and telemetry, and the simulated clock.
    fn of(
        result: std::result::Result<(Outcome, RelocReport), FailureCode>,
        runner: &SimRunner<'_>,
        start: Instant,
        workspace_bytes: usize,
        probe: &ManualClock,
    ) -> Self {
        // The runner call's time, before the log and telemetry are copied out.
        let elapsed = start.elapsed();
        Self {
            result,
            log: runner.log.clone(),
            telemetry: runner.telemetry.writer().frames().frames,
            elapsed,
            workspace_bytes,
            ticks: probe.ticks(),
            pair_copies: runner.camera.pair_copies,
            attempts_worked: None,
        }
    }
}

/// How the simulated devices serve a run: where the pair goes (RAM or the
/// camera's frame memory) and how the map is stored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PairPath {
    /// The pair is captured into RAM buffers ([`RamPair`]); a map given as
    /// bytes is read into a RAM buffer.
    #[default]
    Ram,
    /// The pair stays in the camera's memory and the engine reads each
    /// search window from it ([`InStore`]), with `window_faults` drawn once
    /// per window read (seeded from the devices' seed); with `map_in_place`
    /// the map store of a map given as bytes is memory-mapped ([`MemMapStore::memory_mapped`]) and
    /// the product is checked and used in place, without a RAM copy.
    Store {
        /// Faults of the window reads.
        window_faults: FaultConfig,
        /// Whether the map store is memory-mapped.
        map_in_place: bool,
    },
}

/// How one run is set up besides its [`Request`]: device faults, drive
/// limits, the pair path, a hook before every step and a stage observer.
pub struct RunOptions<'h> {
    /// Seeded faults of the simulated devices.
    pub faults: DeviceFaults,
    /// Step, work and tick budget of the drive.
    pub limits: DriveLimits,
    /// Where the pair goes and how a map given as bytes is stored.
    pub path: PairPath,
    /// Called before every step call ([`PairPath::Ram`]; upset injection,
    /// a ground abort).
    pub between: Option<Between<'h>>,
    /// Stepping one stage at a time, each stage reported
    /// ([`Runner::run`]'s observer); the outcome is bit-identical.
    pub observe: Option<&'h mut dyn FnMut(StageEvent)>,
    /// Every attempt reported in attempt order: the map point drawn and its
    /// result ([`crate::workers::RecordingPool`], [`PairPath::Ram`] only;
    /// without `between` and `observe`, which it takes the place of). The
    /// outcome is bit-identical.
    pub samples: Option<&'h mut dyn FnMut(SampleRecord)>,
}

impl Default for RunOptions<'_> {
    /// Fault-free devices, no limit, the pair in RAM, no hook, no observer.
    fn default() -> Self {
        Self {
            faults: DeviceFaults::default(),
            limits: DriveLimits::UNLIMITED,
            path: PairPath::Ram,
            between: None,
            observe: None,
            samples: None,
        }
    }
}

impl<'h> RunOptions<'h> {
    /// The same options with these device faults.
    pub fn faults(self, faults: DeviceFaults) -> Self {
        Self { faults, ..self }
    }

    /// The same options with these drive limits.
    pub fn limits(self, limits: DriveLimits) -> Self {
        Self { limits, ..self }
    }

    /// The same options with this pair path.
    pub fn path(self, path: PairPath) -> Self {
        Self { path, ..self }
    }

    /// The same options with `between` called before every step.
    pub fn between(self, between: Between<'h>) -> Self {
        Self {
            between: Some(between),
            ..self
        }
    }

    /// The same options with each attempt reported to `samples`.
    pub fn samples(self, samples: &'h mut dyn FnMut(SampleRecord)) -> Self {
        Self {
            samples: Some(samples),
            ..self
        }
    }

    /// The same options with each engine stage reported to `observe`.
    pub fn observe(self, observe: &'h mut dyn FnMut(StageEvent)) -> Self {
        Self {
            observe: Some(observe),
            ..self
        }
    }
}

/// The one run of `req` on the simulated devices: set them up with
/// `opts.faults`, serve the pair by `opts.path`, and make the one runner call
/// ([`Runner::run`]) with the job of `req` and `opts.limits`, the hook
/// `opts.between` (RAM path) and the stage observer `opts.observe`; the
/// runner's log and telemetry are kept whatever the result.
///
/// # Errors
/// Only what stops the devices from being set up (image sizes that disagree
/// with the rig, parameters that cannot size a workspace, invalid fault
/// settings); everything after that is in [`DeviceRun::result`].
pub fn run(req: &Request<'_>, opts: RunOptions<'_>) -> Result<DeviceRun> {
    let RunOptions {
        faults,
        limits,
        path,
        between,
        observe,
        samples,
    } = opts;
    let (n, mut storage) = checked_storage(req)?;
    let sizes = storage.sizes;
    let ws = storage.workspace()?;
    let (mut runner, probe) = devices_for(req, &faults)?;
    let job = Job {
        rig: req.rig,
        params: req.params,
        seed: req.seed,
        limits,
        verify: req.verify,
        accuracy: req.accuracy,
        final_pairs: req.final_pairs,
        search: req.search,
    };
    // RAM for the map only when it must be read from storage (bytes, not
    // memory-mapped); a checked view is used where it is.
    let read_into_ram = matches!(req.map, MapIn::Bytes(_))
        && !matches!(
            path,
            PairPath::Store {
                map_in_place: true,
                ..
            }
        );
    let mut map = vec![
        0u8;
        if read_into_ram {
            req.map.bytes().len()
        } else {
            0
        }
    ];
    let start;
    let (result, attempts_worked) = match path {
        PairPath::Ram => {
            let (mut left, mut right) = (vec![0u8; n], vec![0u8; n]);
            let pair = RamPair {
                left: &mut left,
                right: &mut right,
                between,
            };
            start = Instant::now();
            if samples.is_some() || (req.threads > 1 && pair.between.is_none() && observe.is_none())
            {
                run_pooled(&mut runner, &job, &mut map, pair, ws, req.threads, samples)
            } else {
                (runner.run(&job, &mut map, pair, ws, observe), None)
            }
        }
        PairPath::Store {
            window_faults,
            map_in_place,
        } => {
            runner.camera.window_faults = FaultInjector::new(window_faults, faults.seed ^ 0xf4a3e)?;
            if map_in_place {
                runner.store = runner.store.memory_mapped();
            }
            start = Instant::now();
            (runner.run(&job, &mut map, InStore, ws, observe), None)
        }
    };
    Ok(DeviceRun {
        attempts_worked,
        ..DeviceRun::of(result, &runner, start, sizes.total_bytes(), &probe)
    })
}

/// [`Runner::run`] with the attempts handed out as tickets: on `threads`
/// threads ([`crate::workers::ThreadPool`]), or with `record`, on one
/// worker in this thread that reports each attempt
/// ([`crate::workers::RecordingPool`]). The same start, steps of the job's
/// limits ([`vtsm_hal::runner::Session::step_pooled`]) and finish, so the
/// outcome is the one of a single thread. Each worker's pipeline has its
/// own workspace of the engine's sizes, allocated here.
fn run_pooled(
    runner: &mut SimRunner<'_>,
    job: &Job,
    map: &mut [u8],
    pair: RamPair<'_, '_>,
    ws: Workspace<'_>,
    threads: usize,
    record: Option<&mut dyn FnMut(SampleRecord)>,
) -> (
    std::result::Result<(Outcome, RelocReport), FailureCode>,
    Option<u32>,
) {
    let sizes = ws.sizes();
    let threads = if record.is_some() { 1 } else { threads };
    let mut stores: Vec<HeapStorage> = (0..threads).map(|_| HeapStorage::new(sizes)).collect();
    let mut slot = None;
    let started = runner.start(job, map, &mut slot, pair, ws, None);
    let mut session = match started {
        Ok(s) => s,
        Err(code) => {
            drop(started);
            runner.send_failure_log();
            return (Err(code), None);
        }
    };
    let mut workers = Vec::with_capacity(threads);
    for s in &mut stores {
        // Sized as the engine's own workspace: `worker` cannot refuse it.
        let Ok(ws) = s.workspace() else {
            return (Err(FailureCode::ConfigCapacityTooSmall), None);
        };
        match session.engine().worker(ws) {
            Ok(w) => workers.push(w),
            Err(code) => return (Err(code), None),
        }
    }
    // Bounded: the session counts its step calls against
    // `job.limits.max_steps` and is done at the limit.
    let mut drive = |pool: &mut dyn AttemptPool| {
        for _ in 0..=job.limits.max_steps {
            if session.step_pooled(job.limits.units_per_step, pool) == StepStatus::Done {
                break;
            }
        }
        pool.cancel();
    };
    let worked = match record {
        // One store, so one worker: the recording pool works in this thread.
        Some(record) => {
            let Some(worker) = workers.pop() else {
                return (Err(FailureCode::ConfigCapacityTooSmall), None);
            };
            drive(&mut RecordingPool::new(worker, record));
            None
        }
        None => Some(std::thread::scope(|scope| {
            let mut pool = ThreadPool::start(scope, workers);
            drive(&mut pool);
            pool.worked()
        })),
    };
    (Ok(session.finish()), worked)
}

/// The engine's caller-owned storage on the host heap, of the sizes
/// [`workspace_sizes`] gives.
struct HeapStorage {
    sizes: WorkspaceSizes,
    bytes: Vec<u8>,
    words: Vec<u32>,
    runs: Vec<Run>,
}

impl HeapStorage {
    fn new(sizes: WorkspaceSizes) -> Self {
        Self {
            sizes,
            bytes: vec![0u8; sizes.bytes],
            words: vec![0u32; sizes.words],
            runs: vec![Run::default(); sizes.runs],
        }
    }

    fn workspace(&mut self) -> Result<Workspace<'_>> {
        Ok(Workspace::new(
            self.sizes,
            &mut self.bytes,
            &mut self.words,
            &mut self.runs,
        )?)
    }
}

/// Check `req`'s images against its rig and its parameters, then allocate
/// the engine's storage: the pixel count of one image and the storage. The
/// parameters are checked before allocating, so a bad one cannot size a
/// huge workspace.
fn checked_storage(req: &Request<'_>) -> Result<(usize, HeapStorage)> {
    let (w, h) = (req.rig.cam().width(), req.rig.cam().height());
    let n = (w as usize) * (h as usize);
    if req.left.len() != n || req.right.len() != n {
        return Err(Error::from(FailureCode::ImageSizeMismatch));
    }
    req.params.validate().map_err(FailureCode::from)?;
    let sizes = workspace_sizes(&req.params);
    Ok((n, HeapStorage::new(sizes)))
}

/// The simulated runner of `req` (camera, clock, map store, prior,
/// telemetry, with `faults`) and a probe of its clock.
fn devices_for<'a>(
    req: &Request<'a>,
    faults: &DeviceFaults,
) -> Result<(SimRunner<'a>, ManualClock)> {
    let (w, h) = (req.rig.cam().width(), req.rig.cam().height());
    let clock = ManualClock::new(1_000);
    // The camera and the store borrow the request's memory: nothing copied.
    let camera = FixedCamera::new(req.left, req.right, w, h)?
        .with_clock(clock.clone())
        .with_faults(FaultInjector::new(faults.camera, faults.seed)?);
    let store = match req.map {
        MapIn::Bytes(b) => MemMapStore::new(b),
        MapIn::Checked(v) => MemMapStore::from_checked(v),
    }
    .with_faults(FaultInjector::new(faults.store, faults.seed ^ 0x5107e)?);
    let u = req.uncertainty.unwrap_or(req.params.uncertainty());
    let t0 = u.t_m * u.t_m;
    let r0 = u.r_deg.to_radians() * u.r_deg.to_radians();
    let prior = FixedPrior {
        estimate: Some(PriorEstimate {
            world_from_left: req.prior,
            covariance: Covariance::Diagonal([t0, t0, t0, r0, r0, r0]),
            uncertainty: req.uncertainty,
            timestamp_ticks: 0,
        }),
    };
    let telemetry = FramedTelemetry::new(RecordingSink::new());
    let probe = clock.clone();
    let clock = clock.with_ticks_per_read(faults.clock_ticks_per_read);
    let cfg = runner_config(w, h);
    Ok((
        Runner::new(camera, clock, store, prior, telemetry, cfg),
        probe,
    ))
}

/// The runner over the simulated devices, borrowing a request's memory.
type SimRunner<'a> = Runner<
    FixedCamera<'a>,
    ManualClock,
    MemMapStore<'a>,
    FixedPrior,
    FramedTelemetry<RecordingSink>,
>;

/// An ℓ×ℓ synthetic template with its depth and §III-C mask, row-major.
pub struct Template {
    /// The window of the full virtual image that was rendered.
    pub rect: Rect,
    /// Rendered intensity.
    pub intensity: Vec<u8>,
    /// Depth, fixed point (`raster::depth_to_m`), `raster::DEPTH_NONE` where empty.
    pub depth: Vec<u32>,
    /// Template mask: 255 keep, 0 drop.
    pub mask: Vec<u8>,
}

/// Render the ℓ×ℓ template of `map` seen from `world_from_cam`, centred on the
/// pixel nearest to `centre_px` (the way the engine's Synthesize step does), and
/// form its mask. `None` when nothing is drawn or ℓ is out of range.
pub fn render_template(
    map: &MapView<'_>,
    cam: &Camera,
    world_from_cam: &Pose,
    centre_px: [f32; 2],
    l: usize,
) -> Option<Template> {
    let h = (l / 2) as i32;
    let rect = Rect::new(
        (centre_px[0] + 0.5).floor() as i32 - h,
        (centre_px[1] + 0.5).floor() as i32 - h,
        l as u32,
        l as u32,
    );
    let (mut intensity, mut depth, mut mask_depth) =
        (vec![0u8; l * l], vec![0u32; l * l], vec![0u32; l * l]);
    let mut target = Target {
        intensity: &mut intensity,
        depth: &mut depth,
        mask_depth: &mut mask_depth,
    };
    raster::render_window(map, cam, world_from_cam, rect, &mut target).ok()?;
    let mut mask = vec![0u8; l * l];
    raster::template_mask(&depth, &mask_depth, l, l, &mut mask);
    Some(Template {
        rect,
        intensity,
        depth,
        mask,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::scene::{perturbed_prior, Capture, Profile, Scene};
    use crate::terrain::TerrainKind;
    use vtsm_core::reloc::Stage;

    /// Verifies: VTSM-RELOC-035
    #[test]
    fn stepping_by_stage_through_the_runner_gives_the_same_outcome() {
        let scene = Scene::new(TerrainKind::Flagstone, 3, Profile::Test);
        let light = scene.lighting(9.5);
        let map = scene.map(&light).encode_map(0.5).unwrap();
        let (rig, truth, pair) = scene.capture(&light, &Capture::from_index(5, 0, 0.40));
        let req = Request::new(
            &map,
            &pair.left,
            &pair.right,
            rig,
            perturbed_prior(&truth, 3),
        )
        .with_seed(3);
        let whole = relocalize(&req, RunOptions::default()).unwrap();
        let mut events = Vec::new();
        let mut observe = |e| events.push(e);
        let staged = relocalize(&req, RunOptions::default().observe(&mut observe)).unwrap();
        let (a, b) = (&whole.outcome, &staged.outcome);
        let bits = |o: &Outcome| {
            let (t, q) = (o.pose.t(), o.pose.q());
            (t.map(f32::to_bits), q.map(f32::to_bits))
        };
        assert_eq!(bits(a), bits(b));
        assert_eq!(
            (a.stats, &a.quality, a.failure),
            (b.stats, &b.quality, b.failure)
        );
        assert_eq!(
            a.log.counters().collect::<Vec<_>>(),
            b.log.counters().collect::<Vec<_>>()
        );
        // One Start, then one event per step the runner made.
        assert_eq!(events.first(), Some(&StageEvent::Start));
        assert_eq!(events.len() as u32, staged.run.drive.steps + 1);
        let renders = events
            .iter()
            .filter(|e| **e == StageEvent::Ran(Stage::Render))
            .count() as u32;
        assert_eq!(renders, b.stats.attempts);
        assert!(events.contains(&StageEvent::Ran(Stage::Pose)));
    }

    /// The map is checked once and the pair copied at most once on every
    /// host path, and the outcome does not depend on the path.
    #[test]
    fn map_checked_once_and_pair_copied_at_most_once_on_every_path() {
        let scene = Scene::new(TerrainKind::Flagstone, 3, Profile::Test);
        let light = scene.lighting(9.5);
        let map = scene.map(&light).encode_map(0.5).unwrap();
        let (rig, truth, pair) = scene.capture(&light, &Capture::from_index(5, 0, 0.40));
        let prior = perturbed_prior(&truth, 3);
        let view = MapView::new_checked(&map).unwrap(); // the host's one check
        let store = PairPath::Store {
            window_faults: FaultConfig::default(),
            map_in_place: true,
        };
        let store_read = PairPath::Store {
            window_faults: FaultConfig::default(),
            map_in_place: false,
        };
        let mut outcomes = Vec::new();
        // (map, path, checks in the runner, in place, pair copies)
        for (map_in, path, checks, in_place, copies) in [
            (MapIn::Checked(view), PairPath::Ram, 0, true, 1),
            (MapIn::Checked(view), store, 0, true, 0),
            (MapIn::Bytes(&map), PairPath::Ram, 1, false, 1),
            (MapIn::Bytes(&map), store, 1, true, 0),
            (MapIn::Bytes(&map), store_read, 1, false, 0),
        ] {
            let req = Request::new(map_in, &pair.left, &pair.right, rig, prior).with_seed(3);
            // The devices serve the request's own memory.
            let (runner, _) = devices_for(&req, &DeviceFaults::default()).unwrap();
            let (l, r) = runner.camera.pixels();
            assert!(
                std::ptr::eq(l, pair.left.as_slice()) && std::ptr::eq(r, pair.right.as_slice())
            );
            assert!(std::ptr::eq(runner.store.data(), map.as_slice()));
            let rep = relocalize(&req, RunOptions::default().path(path)).unwrap();
            let what = format!("{path:?} checked {}", matches!(map_in, MapIn::Checked(_)));
            assert_eq!(rep.run.map_read.checks, checks, "{what}");
            assert_eq!(rep.run.map_read.in_place, in_place, "{what}");
            assert_eq!(rep.pair_copies, copies, "{what}");
            outcomes.push(rep.outcome);
        }
        let bits = |o: &Outcome| {
            let (t, q) = (o.pose.t(), o.pose.q());
            (t.map(f32::to_bits), q.map(f32::to_bits), o.stats)
        };
        assert!(outcomes.iter().all(|o| bits(o) == bits(&outcomes[0])));
    }
}
