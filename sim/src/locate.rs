//! One relocalization on the desktop, on the flight path: simulated devices
//! (camera, clock, map store, prior, telemetry) serve the request to the HAL
//! runner, which acquires the inputs, builds the engine with the core's one
//! constructor ([`vtsm_core::reloc::Setup`]) over a heap workspace, and drives it. Used by `vtsm demo`,
//! `vtsm relocalize`, `vtsm eval` and the end-to-end tests, so every path runs
//! exactly the same code. [`relocalize_by_stage`] is the same run with the
//! engine stepped one stage at a time and each stage reported (`vtsm bench`).

use crate::devices::{
    DecodedFrame, FaultConfig, FaultInjector, FixedCamera, FixedPrior, ManualClock, MemMapStore,
    RecordingSink,
};
use crate::error::{Error, Result};
use std::time::{Duration, Instant};
use vtsm_core::config::{Params, PriorUncertainty};
use vtsm_core::failure::FailureLog;
use vtsm_core::geom::Camera;
use vtsm_core::geom::{Pose, StereoRig};
use vtsm_core::image::Rect;
use vtsm_core::map::MapView;
use vtsm_core::ncc::Run;
use vtsm_core::raster::{self, Target};
use vtsm_core::reloc::{Engine, MatchPolicy, Outcome, Workspace, WorkspaceSizes};
use vtsm_core::FailureCode;
use vtsm_hal::runner::{
    Between, DriveLimits, InStore, Job, RamPair, RelocReport, Runner, RunnerConfig, StageEvent,
    VerifyChecks,
};
use vtsm_hal::{Covariance, FramedTelemetry, PriorEstimate};

/// The parameters used for an image width: the paper's, with ℓ and the
/// search window scaled to the image ([`Params::for_image_width`]).
pub fn params_for_width(width: u32) -> Params {
    Params::for_image_width(width)
}

/// Everything one relocalization needs.
#[derive(Clone, Copy)]
pub struct Request<'a> {
    /// Encoded map product (checked here).
    pub map: &'a [u8],
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
}

/// Run one relocalization to completion on fault-free simulated devices.
///
/// # Errors
/// As [`relocalize_on_devices`].
pub fn relocalize(req: &Request<'_>) -> Result<Report> {
    relocalize_on_devices(req, &DeviceFaults::default(), &DriveLimits::UNLIMITED)
}

/// Run one relocalization through the HAL runner, on simulated devices that
/// serve `req`'s map, pair and prior with `faults`, under `limits`: the path a
/// flight computer runs, with the engine built by the core's one constructor.
///
/// # Errors
/// Bad map product, image sizes that disagree with the rig, parameters the
/// core rejects, or device faults that outlast their retries — each with its
/// failure code. A relocalization that fails cleanly is not an error: it is
/// an [`Outcome`] with a failure code.
pub fn relocalize_on_devices(
    req: &Request<'_>,
    faults: &DeviceFaults,
    limits: &DriveLimits,
) -> Result<Report> {
    let run = run_job(req, faults, limits, PairPath::Ram, None, None)?;
    into_report(req, run)
}

/// [`relocalize`] with the engine stepped one stage at a time through
/// [`Runner::run`]'s observer: `observe` gets [`StageEvent::Start`] once
/// the engine is built and [`StageEvent::Ran`] after each stage, and may read
/// a clock at each event. The outcome is bit-identical to [`relocalize`]'s
/// (the simulated clock does not move between steps).
///
/// # Errors
/// As [`relocalize_on_devices`].
pub fn relocalize_by_stage(
    req: &Request<'_>,
    observe: &mut dyn FnMut(StageEvent),
) -> Result<Report> {
    let run = run_job(
        req,
        &DeviceFaults::default(),
        &DriveLimits::UNLIMITED,
        PairPath::Ram,
        None,
        Some(observe),
    )?;
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
}

impl DeviceRun {
    /// The record of a runner call that began at `start`: its result, the
    /// runner's log and telemetry, and the simulated clock.
    fn of(
        result: std::result::Result<(Outcome, RelocReport), FailureCode>,
        runner: &SimRunner,
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
        }
    }
}

/// How the simulated devices serve a run: where the pair goes (RAM or the
/// camera's frame memory) and how the map is stored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PairPath {
    /// The pair is captured into RAM buffers ([`RamPair`]); the map is read
    /// into a RAM buffer.
    #[default]
    Ram,
    /// The pair stays in the camera's memory and the engine reads each
    /// search window from it ([`InStore`]), with `window_faults` drawn once
    /// per window read (seeded from the devices' seed); with `map_in_place`
    /// the map store is memory-mapped ([`MemMapStore::memory_mapped`]) and
    /// the product is checked and used in place, without a RAM copy.
    Store {
        /// Faults of the window reads.
        window_faults: FaultConfig,
        /// Whether the map store is memory-mapped.
        map_in_place: bool,
    },
}

/// [`relocalize_on_devices`], keeping the runner's log and telemetry whatever
/// the result.
///
/// # Errors
/// Only what stops the devices from being set up (image sizes that disagree
/// with the rig, parameters that cannot size a workspace, invalid fault
/// settings); everything after that is in [`DeviceRun::result`].
pub fn run_on_devices(
    req: &Request<'_>,
    faults: &DeviceFaults,
    limits: &DriveLimits,
) -> Result<DeviceRun> {
    run_job(req, faults, limits, PairPath::Ram, None, None)
}

/// [`run_on_devices`] with `between(engine, now)` called before every step
/// call (upset injection between steps).
///
/// # Errors
/// As [`run_on_devices`].
pub fn run_on_devices_with<F>(
    req: &Request<'_>,
    faults: &DeviceFaults,
    limits: &DriveLimits,
    mut between: F,
) -> Result<DeviceRun>
where
    F: for<'m, 'w> FnMut(&mut Engine<'m, 'w>, u64),
{
    run_job(req, faults, limits, PairPath::Ram, Some(&mut between), None)
}

/// [`run_on_devices`] on the frame-store path ([`PairPath::Store`]): no RAM
/// copy of the pair is made.
///
/// # Errors
/// As [`run_on_devices`].
pub fn run_from_store(
    req: &Request<'_>,
    faults: &DeviceFaults,
    window_faults: FaultConfig,
    map_in_place: bool,
    limits: &DriveLimits,
) -> Result<DeviceRun> {
    let path = PairPath::Store {
        window_faults,
        map_in_place,
    };
    run_job(req, faults, limits, path, None, None)
}

/// The one run of `req` on the simulated devices: set them up with
/// `faults`, serve the pair by `path`, and make the one runner call
/// ([`Runner::run`]) with the job of `req` and `limits`, the hook `between`
/// (RAM path) and the stage observer `observe`.
///
/// # Errors
/// As [`run_on_devices`].
pub fn run_job<'h>(
    req: &Request<'_>,
    faults: &DeviceFaults,
    limits: &DriveLimits,
    path: PairPath,
    between: Option<Between<'h>>,
    observe: Option<&mut dyn FnMut(StageEvent)>,
) -> Result<DeviceRun> {
    let (n, mut storage) = checked_storage(req)?;
    let sizes = storage.sizes;
    let ws = storage.workspace()?;
    let (mut runner, probe) = devices_for(req, faults)?;
    let job = Job {
        rig: req.rig,
        params: req.params,
        seed: req.seed,
        limits: *limits,
        verify: req.verify,
    };
    let mut map = Vec::new();
    let (mut left, mut right) = (Vec::new(), Vec::new());
    let start;
    let result = match path {
        PairPath::Ram => {
            map.resize(req.map.len(), 0);
            left.resize(n, 0);
            right.resize(n, 0);
            let pair = RamPair {
                left: &mut left,
                right: &mut right,
                between,
            };
            start = Instant::now();
            runner.run(&job, &mut map, pair, ws, observe)
        }
        PairPath::Store {
            window_faults,
            map_in_place,
        } => {
            runner.camera.window_faults = FaultInjector::new(window_faults, faults.seed ^ 0xf4a3e)?;
            if map_in_place {
                runner.store = runner.store.memory_mapped();
            } else {
                map.resize(req.map.len(), 0);
            }
            start = Instant::now();
            runner.run(&job, &mut map, InStore, ws, observe)
        }
    };
    Ok(DeviceRun::of(
        result,
        &runner,
        start,
        sizes.total_bytes(),
        &probe,
    ))
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
    Ok((
        n,
        HeapStorage {
            sizes,
            bytes: vec![0u8; sizes.bytes],
            words: vec![0u32; sizes.words],
            runs: vec![Run::default(); sizes.runs],
        },
    ))
}

/// The simulated runner of `req` (camera, clock, map store, prior,
/// telemetry, with `faults`) and a probe of its clock.
fn devices_for(req: &Request<'_>, faults: &DeviceFaults) -> Result<(SimRunner, ManualClock)> {
    let (w, h) = (req.rig.cam().width(), req.rig.cam().height());
    let clock = ManualClock::new(1_000);
    let camera = FixedCamera::new(req.left.to_vec(), req.right.to_vec(), w, h)?
        .with_clock(clock.clone())
        .with_faults(FaultInjector::new(faults.camera, faults.seed)?);
    let store = MemMapStore::new(req.map.to_vec())
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

/// The runner over the simulated devices.
type SimRunner =
    Runner<FixedCamera, ManualClock, MemMapStore, FixedPrior, FramedTelemetry<RecordingSink>>;

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
        let req = Request {
            map: &map,
            left: &pair.left,
            right: &pair.right,
            rig,
            prior: perturbed_prior(&truth, 3),
            params: params_for_width(rig.cam().width()),
            seed: 3,
            verify: VerifyChecks::OFF,
            uncertainty: None,
        };
        let whole = relocalize(&req).unwrap();
        let mut events = Vec::new();
        let staged = relocalize_by_stage(&req, &mut |e| events.push(e)).unwrap();
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
}
