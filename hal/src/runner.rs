//! Bounded runner: gathers the inputs of one relocalization from the devices
//! and drives the core with the clock.
//!
//! Inputs: the five devices, caller-owned buffers (two images, the map
//! product) and a [`RunnerConfig`]. Outputs: checked [`Inputs`] views into
//! those buffers, a [`FailureLog`] of every device fault, and telemetry frames.
//!
//! Bounds: every device call is retried at most [`RunnerConfig::attempts`]
//! times (≤ [`MAX_DEVICE_ATTEMPTS`]) and only for transient kinds
//! ([`ErrorKind::is_transient`]); the map product is read in
//! `chunk_len`-byte pieces (≤ `buf.len() / chunk_len + 1` pieces) and
//! re-read whole at most `product_attempts` times when its check fails;
//! [`Runner::drive`] calls the engine at most `max_steps` times.
//!
//! [`Runner::run`] is the one entry of a relocalization, on the flight path
//! and every host path: a [`Job`] (rig, parameters, seed, limits, upset
//! checks) and a source of the stereo pair ([`RamPair`]: captured into RAM;
//! [`InStore`]: left in the camera's frame memory, read window by window).
//! It acquires the map product (checked once with `MapView::new_checked`, in
//! place when the store is memory-mapped, not at all when the store hands
//! over a view its owner checked), the prior and the pair through
//! the devices, builds the engine with the core's one constructor
//! ([`Setup`]) over the caller's workspace, and drives it with `now` from the
//! clock under a step, work and tick budget ([`DriveLimits`]), ending with
//! the anytime result when the budget runs out. An optional observer gets
//! each engine [`Stage`] as it runs, so a host can time the stages with its
//! own clock; the outcome is the same. The outcome and the failure log go
//! out as telemetry frames.

use crate::camera::{FrameInfo, StereoCamera};
use crate::clock::Clock;
use crate::error::{failure_code, Device, Error, ErrorKind};
use crate::frames::{FrameStore, StoreFrames, WindowReport};
use crate::pool::AttemptPool;
use crate::prior::{PosePrior, PriorEstimate, PriorUncertainty};
use crate::store::MapStore;
use crate::telemetry::{
    failure_counters_payload, failure_event_payload, FrameKind, Telemetry, MAX_PAYLOAD,
};
use crate::telemetry::{outcome_payload, OutcomeSummary};
use vtsm_core::config::Params;
use vtsm_core::failure::{FailureLog, Retry};
use vtsm_core::frame::{FrameSource, StereoPair};
use vtsm_core::geom::StereoRig;
use vtsm_core::image::GrayView;
use vtsm_core::map::{CheckedMap, MapView};
use vtsm_core::reloc::{Accuracy, Commit, Engine, Outcome, Setup, Stage, StepResult, Workspace};
use vtsm_core::FailureCode;

/// Cap on attempts of one device operation.
pub const MAX_DEVICE_ATTEMPTS: u8 = 16;
/// Cap on whole-product reads of the map.
pub const MAX_PRODUCT_ATTEMPTS: u8 = 8;

/// The engine's upset checks ([`vtsm_core::reloc::Verify`]) a run asks for;
/// their tolerances are the core's defaults for the parameters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VerifyChecks {
    /// Repeat the final solve from a second random stream and compare
    /// ([`vtsm_core::reloc::Verify::repeat_solve`], else `RELOC_VERIFY_DISAGREE`).
    pub repeat_solve: bool,
    /// Re-check the map product before a success is returned
    /// ([`vtsm_core::reloc::Verify::recheck_map`], else `RELOC_MAP_CHANGED`).
    pub recheck_map: bool,
}

impl VerifyChecks {
    /// No upset check (the engine's default).
    pub const OFF: VerifyChecks = VerifyChecks {
        repeat_solve: false,
        recheck_map: false,
    };
    /// Both upset checks.
    pub const ALL: VerifyChecks = VerifyChecks {
        repeat_solve: true,
        recheck_map: true,
    };

    /// Whether any check is asked for.
    pub const fn any(self) -> bool {
        self.repeat_solve || self.recheck_map
    }
}

/// Retry, size and check settings of the runner. Checked by [`RunnerConfig::validate`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RunnerConfig {
    /// Attempts per device operation (capture, one chunk read), 1..=MAX_DEVICE_ATTEMPTS.
    pub attempts: u8,
    /// Whole-product reads when the map check fails, 1..=MAX_PRODUCT_ATTEMPTS.
    pub product_attempts: u8,
    /// Bytes per `read_range` call, ≥ 1.
    pub chunk_len: u32,
    /// Capture timeout handed to the camera, ticks.
    pub capture_timeout_ticks: u64,
    /// Expected image size (width, height) from the calibration.
    pub image_size: (u32, u32),
}

impl RunnerConfig {
    /// `Err(ConfigParamOutOfRange)` if a field is outside its documented range.
    pub fn validate(&self) -> Result<(), FailureCode> {
        let ok = (1..=MAX_DEVICE_ATTEMPTS).contains(&self.attempts)
            && (1..=MAX_PRODUCT_ATTEMPTS).contains(&self.product_attempts)
            && self.chunk_len >= 1
            && self.image_size.0 >= 1
            && self.image_size.1 >= 1;
        if ok {
            Ok(())
        } else {
            Err(FailureCode::ConfigParamOutOfRange)
        }
    }
}

/// Work done by a capture.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CaptureReport {
    /// `capture` calls made.
    pub attempts: u8,
    /// Of those, failed with [`ErrorKind::Timeout`].
    pub timeouts: u8,
    /// Of those, failed with [`ErrorKind::Truncated`].
    pub truncated: u8,
    /// Of those, failed with any other kind.
    pub faults: u8,
}

/// Work done reading the map product.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReadReport {
    /// Product length in bytes.
    pub len: u32,
    /// Whole-product passes started.
    pub product_attempts: u8,
    /// `read_range` calls made.
    pub reads: u32,
    /// Of those, failed.
    pub failed_reads: u32,
    /// The product was used in place, without a `read_range` call or a
    /// copy: checked once in memory-mapped storage ([`MapStore::mapped`]),
    /// or already checked by the store's owner ([`MapStore::checked`]).
    pub in_place: bool,
    /// Full checks of the product ([`MapView::new_checked`]: parse and every
    /// CRC) this run made: one per whole-product pass that reached its
    /// check, so 1 for a product accepted on the first pass, 0 for a view
    /// the store handed over already checked. The view that passed is the
    /// one the engine uses; it is never checked again (the engine's own
    /// [`VerifyChecks::recheck_map`] is an upset check, not counted here).
    pub checks: u8,
}

fn time_or_zero<K: Clock>(clock: &mut K, log: &mut FailureLog) -> u64 {
    match clock.now_ticks() {
        Ok(t) => t,
        Err(_) => {
            log.record(FailureCode::HalClockFault, 0, 0);
            0
        }
    }
}

/// Capture one stereo pair with bounded retries on transient faults.
///
/// Each failed attempt is recorded in `log` with its device failure code. A
/// non-transient fault ends the capture with that code; running out of
/// attempts ends it with [`FailureCode::HalCameraRetriesExhausted`]. A frame
/// whose [`FrameInfo`] disagrees with `cfg.image_size` or the buffers is
/// rejected with [`FailureCode::HalFrameInfoInvalid`] (not retried: the camera
/// broke its contract).
pub fn capture_pair<C: StereoCamera>(
    cam: &mut C,
    left: &mut [u8],
    right: &mut [u8],
    cfg: &RunnerConfig,
    now_ticks: u64,
    log: &mut FailureLog,
) -> Result<(FrameInfo, CaptureReport), FailureCode> {
    capture_retried(cfg, now_ticks, log, |timeout| -> Result<_, C::Error> {
        let info = cam.capture(left, right, timeout)?;
        Ok(match info.views(cfg.image_size, left, right) {
            Ok(_) => Ok(info),
            Err(code) => Err((code, info.sequence)),
        })
    })
}

/// Capture one stereo pair into a [`FrameStore`]'s own memory, with the
/// retries, logging and frame-info check of [`capture_pair`] (the codes are
/// the camera's: the store is the camera's frame memory).
pub fn capture_to_store<F: FrameStore>(
    store: &mut F,
    cfg: &RunnerConfig,
    now_ticks: u64,
    log: &mut FailureLog,
) -> Result<(FrameInfo, CaptureReport), FailureCode> {
    capture_retried(cfg, now_ticks, log, |timeout| -> Result<_, F::Error> {
        let info = store.capture_in_place(timeout)?;
        let ok = (info.width, info.height) == cfg.image_size && info.image_len().is_some();
        Ok(if ok {
            Ok(info)
        } else {
            Err((FailureCode::HalFrameInfoInvalid, info.sequence))
        })
    })
}

/// The retry loop of [`capture_pair`] and [`capture_to_store`]: at most
/// `cfg.attempts` calls of `capture(timeout)`, each of which gives the frame,
/// a frame whose info broke the camera's contract (the code to log and the
/// frame's sequence number: rejected with [`FailureCode::HalFrameInfoInvalid`],
/// not retried), or a device error (logged with its code, counted, retried
/// only when transient).
fn capture_retried<E: Error>(
    cfg: &RunnerConfig,
    now_ticks: u64,
    log: &mut FailureLog,
    mut capture: impl FnMut(u64) -> Result<Result<FrameInfo, (FailureCode, u32)>, E>,
) -> Result<(FrameInfo, CaptureReport), FailureCode> {
    cfg.validate()?;
    let mut rep = CaptureReport::default();
    for attempt in 0..cfg.attempts {
        rep.attempts = attempt + 1;
        match capture(cfg.capture_timeout_ticks) {
            Ok(Ok(info)) => return Ok((info, rep)),
            Ok(Err((code, sequence))) => {
                log.record(code, now_ticks, sequence);
                return Err(FailureCode::HalFrameInfoInvalid);
            }
            Err(e) => {
                let kind = e.kind();
                let code = failure_code(Device::Camera, kind);
                log.record(code, now_ticks, u32::from(attempt));
                match kind {
                    // Saturating: with a run-time attempt count (the C
                    // interface) the compiler cannot bound these by it.
                    ErrorKind::Timeout => rep.timeouts = rep.timeouts.saturating_add(1),
                    ErrorKind::Truncated => rep.truncated = rep.truncated.saturating_add(1),
                    _ => rep.faults = rep.faults.saturating_add(1),
                }
                if !kind.is_transient() {
                    return Err(code);
                }
            }
        }
    }
    log.record(
        FailureCode::HalCameraRetriesExhausted,
        now_ticks,
        u32::from(rep.attempts),
    );
    Err(FailureCode::HalCameraRetriesExhausted)
}

/// Read the whole map product into the front of `buf` once, chunk by chunk,
/// with bounded retries per chunk. Returns the product length.
///
/// Fails with [`FailureCode::HalMapTooLarge`] if the product is empty or
/// longer than `buf` (nothing is read), with the device's code for a
/// non-transient fault, and with [`FailureCode::HalStorageRetriesExhausted`]
/// when a chunk fails `cfg.attempts` times.
pub fn read_map_once<S: MapStore>(
    store: &mut S,
    buf: &mut [u8],
    cfg: &RunnerConfig,
    now_ticks: u64,
    log: &mut FailureLog,
    rep: &mut ReadReport,
) -> Result<usize, FailureCode> {
    cfg.validate()?;
    let len32 = match store.len() {
        Ok(l) => l,
        Err(e) => {
            let code = failure_code(Device::MapStore, e.kind());
            log.record(code, now_ticks, 0);
            return Err(code);
        }
    };
    rep.len = len32;
    let len = usize::try_from(len32).map_err(|_| FailureCode::HalMapTooLarge)?;
    let product = match buf.get_mut(..len) {
        Some(p) if len > 0 => p,
        _ => {
            log.record(FailureCode::HalMapTooLarge, now_ticks, len32);
            return Err(FailureCode::HalMapTooLarge);
        }
    };
    let chunk = usize::try_from(cfg.chunk_len).unwrap_or(usize::MAX);
    let mut offset: u32 = 0;
    // `max(1)`: a zero chunk length would make `chunks_mut` panic.
    for piece in product.chunks_mut(chunk.max(1)) {
        let mut done = false;
        for _ in 0..cfg.attempts {
            rep.reads = rep.reads.saturating_add(1);
            match store.read_range(offset, piece) {
                Ok(()) => {
                    done = true;
                    break;
                }
                Err(e) => {
                    rep.failed_reads = rep.failed_reads.saturating_add(1);
                    let code = failure_code(Device::MapStore, e.kind());
                    log.record(code, now_ticks, offset);
                    if !e.kind().is_transient() {
                        return Err(code);
                    }
                }
            }
        }
        if !done {
            log.record(FailureCode::HalStorageRetriesExhausted, now_ticks, offset);
            return Err(FailureCode::HalStorageRetriesExhausted);
        }
        // piece.len() <= len <= u32::MAX, so this cannot wrap past the product.
        offset = offset.saturating_add(u32::try_from(piece.len()).unwrap_or(u32::MAX));
    }
    Ok(len)
}

/// Read the map product and check it with `verify`; re-read the whole product
/// (at most `cfg.product_attempts` passes) while the check fails with a code
/// whose retry hint is not [`Retry::Never`] — undetected storage corruption
/// shows up here as a CRC mismatch.
pub fn read_map_verified<S: MapStore, V: FnMut(&[u8]) -> Result<(), FailureCode>>(
    store: &mut S,
    buf: &mut [u8],
    cfg: &RunnerConfig,
    now_ticks: u64,
    log: &mut FailureLog,
    mut verify: V,
) -> Result<(usize, ReadReport), FailureCode> {
    let mut rep = ReadReport::default();
    let len = read_passes(store, buf, cfg, now_ticks, log, &mut rep, |b, _, _| {
        verify(b).map(|()| b.len())
    })?;
    Ok((len, rep))
}

/// [`read_map_verified`] with the product's own check
/// ([`MapView::new_checked`]) as the check, and the view that passed it
/// handed to `then` with the log and the read report: the retry loop's check
/// is the one check of the product, and its view is what is used afterwards
/// (`then` runs inside the loop's pass, so the view's borrow of `buf` ends
/// before a retry could write to it). Returns what `then` returns.
///
/// # Errors
/// As [`read_map_verified`].
pub fn read_map_checked<S: MapStore, R>(
    store: &mut S,
    buf: &mut [u8],
    cfg: &RunnerConfig,
    now_ticks: u64,
    log: &mut FailureLog,
    then: impl FnOnce(MapView<'_>, &mut FailureLog, ReadReport) -> R,
) -> Result<R, FailureCode> {
    let mut rep = ReadReport::default();
    let mut then = Some(then);
    let r = read_passes(store, buf, cfg, now_ticks, log, &mut rep, |b, log, rep| {
        let view = MapView::new_checked(b)?;
        Ok(then.take().map(|f| f(view, log, *rep)))
    })?;
    // `then` is taken by the first passing check, after which the loop
    // returns: a second pass cannot reach it.
    r.ok_or(FailureCode::HalStorageRetriesExhausted)
}

/// The whole-product passes of [`read_map_verified`] and
/// [`read_map_checked`]: read the product into `buf`, count and run `check`
/// on it, and re-read while the check fails with a retryable code.
fn read_passes<S: MapStore, R>(
    store: &mut S,
    buf: &mut [u8],
    cfg: &RunnerConfig,
    now_ticks: u64,
    log: &mut FailureLog,
    rep: &mut ReadReport,
    mut check: impl FnMut(&[u8], &mut FailureLog, &ReadReport) -> Result<R, FailureCode>,
) -> Result<R, FailureCode> {
    cfg.validate()?;
    let mut last = FailureCode::HalStorageRetriesExhausted;
    for pass in 0..cfg.product_attempts {
        rep.product_attempts = pass + 1;
        let len = read_map_once(store, buf, cfg, now_ticks, log, rep)?;
        let product = buf.get(..len).ok_or(FailureCode::HalMapTooLarge)?;
        rep.checks = rep.checks.saturating_add(1);
        match check(product, log, rep) {
            Ok(r) => return Ok(r),
            Err(code) => {
                log.record(code, now_ticks, u32::from(pass));
                last = code;
                if code.retry() == Retry::Never {
                    return Err(code);
                }
            }
        }
    }
    Err(last)
}

/// Caller-owned memory the runner fills.
#[derive(Debug)]
pub struct Buffers<'b> {
    /// Left image, at least one full frame.
    pub left: &'b mut [u8],
    /// Right image, at least one full frame.
    pub right: &'b mut [u8],
    /// Map product, at least its stored length.
    pub map: &'b mut [u8],
}

/// The checked inputs of one relocalization, borrowing the [`Buffers`].
#[derive(Clone, Copy, Debug)]
pub struct Inputs<'b> {
    /// Left image.
    pub left: GrayView<'b>,
    /// Right image.
    pub right: GrayView<'b>,
    /// Frame metadata of the pair.
    pub frame: FrameInfo,
    /// The verified map product bytes.
    pub map: &'b [u8],
    /// The checked pose prior.
    pub prior: PriorEstimate,
    /// Clock time when acquisition started.
    pub start_ticks: u64,
    /// Capture work.
    pub capture: CaptureReport,
    /// Map read work.
    pub map_read: ReadReport,
}

/// Status a step closure returns to [`Runner::drive`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StepStatus {
    /// More work remains.
    Continue,
    /// The engine has an outcome.
    Done,
}

/// How [`Runner::drive`] ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriveReport {
    /// Steps called.
    pub steps: u32,
    /// Ticks from the first to the last clock read.
    pub elapsed_ticks: u64,
    /// Cycle-counter difference over the run, if the clock has one.
    pub cycles: Option<u64>,
    /// Whether the engine reported [`StepStatus::Done`].
    pub done: bool,
}

/// How [`Runner::run`] may spend time: engine work units per step
/// call, step calls, and clock ticks from the first step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriveLimits {
    /// Engine work units per step call (≥ 1; one unit is one attempt or one
    /// RANSAC chunk). The outcome does not depend on it.
    pub units_per_step: u32,
    /// Step calls at most.
    pub max_steps: u32,
    /// Ticks at most, measured with the runner's clock.
    pub budget_ticks: u64,
}

impl DriveLimits {
    /// No limit beyond the engine's own structural bound.
    pub const UNLIMITED: DriveLimits = DriveLimits {
        units_per_step: 64,
        max_steps: u32::MAX,
        budget_ticks: u64::MAX,
    };
}

/// What [`Runner::run`] tells its observer, in order: one
/// `Start`, then one `Ran` per engine step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StageEvent {
    /// The inputs are acquired and checked and the engine is built; its
    /// first step comes next.
    Start,
    /// The engine ran one stage ([`vtsm_core::reloc::Relocalizer::step_stage`]).
    Ran(Stage),
}

/// What one [`Runner::run`] did besides the engine's outcome.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RelocReport {
    /// Frame metadata of the pair used.
    pub frame: FrameInfo,
    /// Capture work.
    pub capture: CaptureReport,
    /// Map read work.
    pub map_read: ReadReport,
    /// Engine driving.
    pub drive: DriveReport,
    /// The prior uncertainty (t̃₀, r̃₀) the engine ran with: the prior's
    /// stated one ([`PriorEstimate::uncertainty`]) or, without it, the
    /// caller's parameters'.
    pub prior_uncertainty: PriorUncertainty,
    /// Window reads from the frame store ([`InStore`];
    /// zero when the pair was captured into RAM).
    pub windows: WindowReport,
}

/// The devices and the failure log of one relocalization run.
#[derive(Debug)]
pub struct Runner<C, K, S, P, T> {
    /// Stereo camera.
    pub camera: C,
    /// System clock.
    pub clock: K,
    /// Map storage.
    pub store: S,
    /// Pose prior source.
    pub prior: P,
    /// Telemetry downlink.
    pub telemetry: T,
    /// Retry and size settings.
    pub cfg: RunnerConfig,
    /// Every fault seen so far.
    pub log: FailureLog,
    /// Telemetry frames that could not be sent (saturating).
    pub telemetry_dropped: u32,
}

/// [`Runner::drive`] over the runner's clock and log, borrowed apart from
/// the devices (the engine of a frame-store run borrows the camera).
fn drive_steps<K: Clock, F: FnMut(u64) -> Result<StepStatus, FailureCode>>(
    clock: &mut K,
    log: &mut FailureLog,
    max_steps: u32,
    budget_ticks: u64,
    mut step: F,
) -> (DriveReport, Result<(), FailureCode>) {
    let start = time_or_zero(clock, log);
    let c0 = clock.cycles();
    let mut rep = DriveReport {
        steps: 0,
        elapsed_ticks: 0,
        cycles: None,
        done: false,
    };
    let mut result = Err(FailureCode::RelocBudgetExhausted);
    let mut now = start;
    for _ in 0..max_steps {
        if now.saturating_sub(start) >= budget_ticks {
            break;
        }
        rep.steps += 1;
        let status = step(now);
        now = time_or_zero(clock, log).max(now);
        match status {
            Ok(StepStatus::Continue) => {}
            Ok(StepStatus::Done) => {
                rep.done = true;
                result = Ok(());
                break;
            }
            Err(code) => {
                log.record(code, now, rep.steps);
                result = Err(code);
                break;
            }
        }
    }
    rep.elapsed_ticks = now.saturating_sub(start);
    rep.cycles = match (c0, clock.cycles()) {
        (Some(a), Some(b)) => Some(b.wrapping_sub(a)),
        _ => None,
    };
    if !rep.done && result == Err(FailureCode::RelocBudgetExhausted) {
        log.record(FailureCode::RelocBudgetExhausted, now, rep.steps);
    }
    (rep, result)
}

/// The latest prior from `prior`, checked ([`PriorEstimate::check`]); a
/// device error or an invalid prior is recorded at `now` and returned.
fn read_prior<P: PosePrior>(
    prior: &mut P,
    log: &mut FailureLog,
    now: u64,
) -> Result<PriorEstimate, FailureCode> {
    let p = match prior.latest() {
        Ok(p) => p,
        Err(e) => {
            let code = failure_code(Device::PosePrior, e.kind());
            log.record(code, now, 0);
            return Err(code);
        }
    };
    if let Err(code) = p.check() {
        log.record(code, now, 0);
        return Err(code);
    }
    Ok(p)
}

/// Check the map product in place in memory-mapped storage: `bytes` (the
/// store's [`MapStore::mapped`] view) parsed and CRC-checked once; a failure
/// is recorded at `now` and returned (re-reading mapped memory gives the
/// same bytes, so there is no retry).
fn map_in_place<'m>(
    bytes: &'m [u8],
    log: &mut FailureLog,
    now: u64,
    rep: &mut ReadReport,
) -> Result<MapView<'m>, FailureCode> {
    rep.in_place = true;
    rep.product_attempts = 1;
    rep.len = u32::try_from(bytes.len()).map_err(|_| FailureCode::HalMapTooLarge)?;
    if bytes.is_empty() {
        log.record(FailureCode::HalMapTooLarge, now, 0);
        return Err(FailureCode::HalMapTooLarge);
    }
    rep.checks = 1;
    MapView::new_checked(bytes).inspect_err(|&c| log.record(c, now, 0))
}

impl<C, K, S, P, T> Runner<C, K, S, P, T>
where
    K: Clock,
    S: MapStore,
    P: PosePrior,
    T: Telemetry,
{
    /// A runner over these devices. `cfg` is checked by every operation.
    pub fn new(camera: C, clock: K, store: S, prior: P, telemetry: T, cfg: RunnerConfig) -> Self {
        Self {
            camera,
            clock,
            store,
            prior,
            telemetry,
            cfg,
            log: FailureLog::new(),
            telemetry_dropped: 0,
        }
    }

    /// Read the clock; a clock fault is logged and reads as 0.
    pub fn now(&mut self) -> u64 {
        time_or_zero(&mut self.clock, &mut self.log)
    }

    /// Call `step(now)` until it returns [`StepStatus::Done`], at most
    /// `max_steps` times and while fewer than `budget_ticks` have elapsed.
    ///
    /// Running out of steps or ticks records and returns
    /// [`FailureCode::RelocBudgetExhausted`] together with the report; an
    /// error from `step` is returned as is. INTEGRATION POINT: `step` is
    /// `|now| relocalizer.step(now)` mapped to [`StepStatus`].
    pub fn drive<F: FnMut(u64) -> Result<StepStatus, FailureCode>>(
        &mut self,
        max_steps: u32,
        budget_ticks: u64,
        step: F,
    ) -> (DriveReport, Result<(), FailureCode>) {
        drive_steps(
            &mut self.clock,
            &mut self.log,
            max_steps,
            budget_ticks,
            step,
        )
    }

    /// The map product (read into `map` and checked with `verify_map`) and
    /// the checked pose prior: the first two steps of every acquisition.
    /// Returns the product bytes, the read report, the prior and the clock
    /// time when acquisition started.
    fn acquire_map_and_prior<'b, V: FnMut(&[u8]) -> Result<(), FailureCode>>(
        &mut self,
        map: &'b mut [u8],
        verify_map: V,
    ) -> Result<(&'b [u8], ReadReport, PriorEstimate, u64), FailureCode> {
        self.cfg.validate()?;
        let start = self.now();
        let (len, map_read) = read_map_verified(
            &mut self.store,
            map,
            &self.cfg,
            start,
            &mut self.log,
            verify_map,
        )?;
        let prior = read_prior(&mut self.prior, &mut self.log, start)?;
        let map: &'b [u8] = map;
        let map = map.get(..len).ok_or(FailureCode::HalMapTooLarge)?;
        Ok((map, map_read, prior, start))
    }

    /// Send one frame; a failure is counted and logged, never retried.
    pub fn send(&mut self, kind: u8, payload: &[u8]) {
        send_frame(
            &mut self.telemetry,
            &mut self.telemetry_dropped,
            &mut self.clock,
            &mut self.log,
            kind,
            payload,
        );
    }

    /// Downlink the failure log: one counters frame, then the recent events
    /// oldest first (at most the ring length of frames).
    pub fn send_failure_log(&mut self) {
        send_log(
            &mut self.telemetry,
            &mut self.telemetry_dropped,
            &mut self.clock,
            &mut self.log,
        );
    }
}

impl<C, K, S, P, T> Runner<C, K, S, P, T>
where
    C: StereoCamera,
    K: Clock,
    S: MapStore,
    P: PosePrior,
    T: Telemetry,
{
    /// Gather everything one relocalization needs: the map product (checked
    /// with `verify_map`), a stereo pair and the pose prior.
    ///
    /// Order: map first (slowest, and useless to capture without it), then the
    /// prior, then the images, so the pair is as close as possible in time to
    /// the prior it is matched against.
    pub fn acquire<'b, V: FnMut(&[u8]) -> Result<(), FailureCode>>(
        &mut self,
        bufs: Buffers<'b>,
        verify_map: V,
    ) -> Result<Inputs<'b>, FailureCode> {
        let (map, map_read, prior, start) = self.acquire_map_and_prior(bufs.map, verify_map)?;
        let now = self.now();
        let (frame, capture) = capture_pair(
            &mut self.camera,
            bufs.left,
            bufs.right,
            &self.cfg,
            now,
            &mut self.log,
        )?;
        let left: &'b [u8] = bufs.left;
        let right: &'b [u8] = bufs.right;
        let (left, right) = frame.views(self.cfg.image_size, left, right)?;
        Ok(Inputs {
            left,
            right,
            frame,
            map,
            prior,
            start_ticks: start,
            capture,
            map_read,
        })
    }
}

/// One relocalization job: what the engine is built and driven with besides
/// the map product, the prior and the stereo pair, which the devices serve.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Job {
    /// Calibrated rig.
    pub rig: StereoRig,
    /// Relocalization parameters; t̃₀, r̃₀ are replaced by the prior's stated
    /// uncertainty when it has one ([`PriorEstimate::uncertainty`]).
    pub params: Params,
    /// Seed of the relocalization's random streams.
    pub seed: u64,
    /// Step, work and tick budget of the drive.
    pub limits: DriveLimits,
    /// The engine's upset checks.
    pub verify: VerifyChecks,
    /// The accuracy the caller needs: the rounds end as soon as the stated
    /// uncertainty meets it (`None`: every pose update of `params.n_iter`).
    pub accuracy: Option<Accuracy>,
    /// Correspondences of the last round
    /// ([`Options::final_pairs`](vtsm_core::reloc::Options::final_pairs); 0:
    /// N_corr like every round).
    pub final_pairs: u16,
    /// The search mechanisms, Revisit and Near
    /// ([`Search`](vtsm_core::reloc::Search); `Search::DEFAULT` is the
    /// engine's default).
    pub search: vtsm_core::reloc::Search,
}

/// What a [`PairSource`] hands the runner after the capture: the engine's
/// frame source, the frame metadata, the capture work and the caller's hook.
#[derive(Debug)]
pub struct Captured<F, H> {
    /// Where the engine reads its windows and preflight rows from.
    pub frames: F,
    /// Frame metadata of the pair.
    pub frame: FrameInfo,
    /// Capture work.
    pub capture: CaptureReport,
    /// The caller's work before every engine step ([`PairSource::before_step`]).
    pub hook: H,
}

/// Where the stereo pair of a job comes from: captured into RAM
/// ([`RamPair`], camera `C: StereoCamera`) or left in the camera's frame
/// memory ([`InStore`], `C: FrameStore`). [`Runner::start`] has checked the
/// map and the prior; the source captures the pair and gives the engine's
/// frame source, which [`Runner::start`] builds the engine over with
/// [`Setup`]. Sealed: these two are the pair paths the runner knows how to
/// drive.
pub trait PairSource<C>: sealed::Sealed {
    /// The engine's frame source, borrowing the camera for `'c`.
    type Frames<'c>: FrameSource
    where
        Self: 'c,
        C: 'c;
    /// The caller's work before every engine step.
    type Hook<'c>
    where
        Self: 'c,
        C: 'c;

    /// Capture the pair at clock time `now` (faults logged in `log`).
    ///
    /// # Errors
    /// The capture's code, or a frame that disagrees with `cfg.image_size`.
    fn capture<'c>(
        self,
        camera: &'c mut C,
        cfg: &RunnerConfig,
        now: u64,
        log: &mut FailureLog,
    ) -> Result<Captured<Self::Frames<'c>, Self::Hook<'c>>, FailureCode>
    where
        Self: 'c;

    /// Run the hook before an engine step at `now`.
    fn before_step<'c, 'w>(
        hook: &mut Self::Hook<'c>,
        engine: &mut Engine<'c, 'w, Self::Frames<'c>>,
        now: u64,
    ) where
        Self: 'c;

    /// The window reads of `frames` once the engine is done; their failures
    /// go into `log`.
    fn windows<'c>(frames: &Self::Frames<'c>, log: &mut FailureLog) -> WindowReport
    where
        Self: 'c;
}

mod sealed {
    /// Seals [`super::PairSource`] to the runner's own pair paths.
    pub trait Sealed {}
    impl Sealed for super::RamPair<'_, '_> {}
    impl Sealed for super::InStore {}
}

/// A caller's work before every engine step of a pair in RAM: a watchdog, a
/// ground abort through [`vtsm_core::reloc::Relocalizer::stop`], or a
/// simulator's upset injection (core feature `upset-injection`).
pub type Between<'h> = &'h mut dyn for<'m, 'w> FnMut(&mut Engine<'m, 'w>, u64);

/// A stereo pair captured into caller-owned RAM ([`capture_pair`]).
pub struct RamPair<'b, 'h> {
    /// Left image, at least one full frame.
    pub left: &'b mut [u8],
    /// Right image, at least one full frame.
    pub right: &'b mut [u8],
    /// Called before every step call, when given.
    pub between: Option<Between<'h>>,
}

impl core::fmt::Debug for RamPair<'_, '_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("RamPair")
            .field("left", &self.left.len())
            .field("right", &self.right.len())
            .field("between", &self.between.is_some())
            .finish()
    }
}

impl<'b, 'h> RamPair<'b, 'h> {
    /// A pair captured into `left` and `right`, without a hook.
    pub fn new(left: &'b mut [u8], right: &'b mut [u8]) -> Self {
        Self {
            left,
            right,
            between: None,
        }
    }
}

impl<'b, 'h, C: StereoCamera> PairSource<C> for RamPair<'b, 'h> {
    type Frames<'c>
        = StereoPair<'c>
    where
        Self: 'c,
        C: 'c;
    type Hook<'c>
        = Option<Between<'h>>
    where
        Self: 'c,
        C: 'c;

    fn capture<'c>(
        self,
        camera: &'c mut C,
        cfg: &RunnerConfig,
        now: u64,
        log: &mut FailureLog,
    ) -> Result<Captured<StereoPair<'c>, Option<Between<'h>>>, FailureCode>
    where
        Self: 'c,
    {
        let (frame, capture) = capture_pair(camera, self.left, self.right, cfg, now, log)?;
        let left: &'c [u8] = self.left;
        let right: &'c [u8] = self.right;
        let (left, right) = frame.views(cfg.image_size, left, right)?;
        Ok(Captured {
            frames: StereoPair::new(left, right),
            frame,
            capture,
            hook: self.between,
        })
    }

    fn before_step<'c, 'w>(
        hook: &mut Option<Between<'h>>,
        engine: &mut Engine<'c, 'w, StereoPair<'c>>,
        now: u64,
    ) where
        Self: 'c,
    {
        if let Some(b) = hook.as_mut() {
            b(engine, now);
        }
    }

    fn windows<'c>(_: &StereoPair<'c>, _: &mut FailureLog) -> WindowReport
    where
        Self: 'c,
    {
        WindowReport::default()
    }
}

/// The pair left in the camera's frame memory ([`capture_to_store`]): the
/// engine reads each search window (and the preflight's rows) from the store
/// when it needs it, each read retried on transient faults at most
/// [`RunnerConfig::attempts`] times, so RAM holds the workspace and no frame.
/// A read that still fails ends the relocalization with
/// [`FailureCode::RelocFrameReadFailed`] in the outcome; every failed read is
/// in the runner's log with [`FailureCode::HalFrameStoreRead`]. With the same
/// pixels the outcome is bit-identical to a [`RamPair`]'s.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct InStore;

impl<C: FrameStore> PairSource<C> for InStore {
    type Frames<'c>
        = StoreFrames<&'c mut C>
    where
        Self: 'c,
        C: 'c;
    type Hook<'c>
        = ()
    where
        Self: 'c,
        C: 'c;

    fn capture<'c>(
        self,
        camera: &'c mut C,
        cfg: &RunnerConfig,
        now: u64,
        log: &mut FailureLog,
    ) -> Result<Captured<StoreFrames<&'c mut C>, ()>, FailureCode>
    where
        Self: 'c,
    {
        let (frame, capture) = capture_to_store(camera, cfg, now, log)?;
        Ok(Captured {
            frames: StoreFrames::new(camera, &frame, cfg.attempts, now),
            frame,
            capture,
            hook: (),
        })
    }

    fn before_step<'c, 'w>(_: &mut (), _: &mut Engine<'c, 'w, StoreFrames<&'c mut C>>, _: u64)
    where
        Self: 'c,
    {
    }

    fn windows<'c>(frames: &StoreFrames<&'c mut C>, log: &mut FailureLog) -> WindowReport
    where
        Self: 'c,
    {
        log.absorb(&frames.log);
        frames.report
    }
}

/// Build the engine of `setup` with the upset checks and the accuracy of
/// `job` over `ws`; a rejected setup is logged at `start`.
fn build<'a, 'w, F: FrameSource>(
    setup: Setup<'a, F>,
    job: &Job,
    ws: Workspace<'w>,
    log: &mut FailureLog,
    start: u64,
) -> Result<Engine<'a, 'w, F>, FailureCode> {
    let setup = setup.with_upset_checks(job.verify.repeat_solve, job.verify.recheck_map);
    let options = setup
        .options()
        .with_accuracy(job.accuracy)
        .and_then(|o| o.with_final_pairs(job.final_pairs))
        .and_then(|o| o.with_search(job.search));
    options
        .and_then(|o| setup.with_options(o))
        .and_then(|s| s.build(ws))
        .inspect_err(|&c| log.record(c, start, 0))
}

/// Read the map product into `buf` and check it, as [`read_map_checked`],
/// and give the view that passed over `buf`'s bytes without a second check
/// ([`CheckedMap`]).
fn read_map_view<'m, S: MapStore>(
    store: &mut S,
    buf: &'m mut [u8],
    cfg: &RunnerConfig,
    now_ticks: u64,
    log: &mut FailureLog,
    rep: &mut ReadReport,
) -> Result<MapView<'m>, FailureCode> {
    let checked: CheckedMap = read_passes(store, buf, cfg, now_ticks, log, rep, |b, _, _| {
        MapView::new_checked(b).map(|v| v.detach())
    })?;
    let len = usize::try_from(rep.len).map_err(|_| FailureCode::HalMapTooLarge)?;
    let bytes: &'m [u8] = buf;
    bytes
        .get(..len)
        .and_then(|b| checked.attach(b))
        .ok_or(FailureCode::HalMapTooLarge)
}

/// Where [`Runner::start`] keeps the checked map view the engine borrows:
/// the caller's, declared before the [`Session`] (`let mut slot = None;`).
pub type MapSlot<'m> = Option<MapView<'m>>;

/// Send one frame over `telemetry`; a failure is counted in `dropped` and
/// logged at the clock's time, never retried.
fn send_frame<K: Clock, T: Telemetry>(
    telemetry: &mut T,
    dropped: &mut u32,
    clock: &mut K,
    log: &mut FailureLog,
    kind: u8,
    payload: &[u8],
) {
    if payload.len() > MAX_PAYLOAD {
        // The frame format cannot carry it: dropped before the device sees it.
        *dropped = dropped.saturating_add(1);
        let now = time_or_zero(clock, log);
        log.record(
            FailureCode::HalTelemetryPayloadTooLong,
            now,
            u32::from(kind),
        );
        return;
    }
    if telemetry.send(kind, payload).is_err() {
        *dropped = dropped.saturating_add(1);
        let now = time_or_zero(clock, log);
        log.record(FailureCode::HalTelemetryWrite, now, u32::from(kind));
    }
}

/// Downlink `log`: one counters frame, then the recent events oldest first
/// (at most the ring length of frames).
fn send_log<K: Clock, T: Telemetry>(
    telemetry: &mut T,
    dropped: &mut u32,
    clock: &mut K,
    log: &mut FailureLog,
) {
    let mut payload = [0u8; MAX_PAYLOAD];
    let n = failure_counters_payload(log, &mut payload);
    let snapshot = log.clone();
    send_frame(
        telemetry,
        dropped,
        clock,
        log,
        FrameKind::FailureCounters as u8,
        payload.get(..n).unwrap_or(&[]),
    );
    for e in snapshot.recent() {
        send_frame(
            telemetry,
            dropped,
            clock,
            log,
            FrameKind::FailureEvent as u8,
            &failure_event_payload(&e),
        );
    }
}

/// One relocalization under way: the engine built by [`Runner::start`] over
/// the checked map, the captured pair and the caller's workspace, with the
/// runner's clock, log and telemetry borrowed until [`Session::finish`].
///
/// [`Session::step`] does a bounded piece of work per call (a rate group's
/// or a wakeup's budget), so the relocalization can be spread over periods;
/// [`Runner::run`] is [`Runner::start`], [`Session::step`] until
/// [`StepStatus::Done`], and [`Session::finish`]. The outcome does not depend
/// on how the work is cut into steps.
pub struct Session<'r, 'w, C, K, T, Src>
where
    Src: PairSource<C> + 'r,
    C: 'r,
{
    engine: Engine<'r, 'w, Src::Frames<'r>>,
    hook: Src::Hook<'r>,
    clock: &'r mut K,
    log: &'r mut FailureLog,
    telemetry: &'r mut T,
    telemetry_dropped: &'r mut u32,
    observe: Option<&'r mut dyn FnMut(StageEvent)>,
    max_steps: u32,
    budget_ticks: u64,
    report: RelocReport,
    /// Clock time of the first step.
    t0: u64,
    /// Cycle counter at the first step.
    c0: Option<u64>,
    /// Clock time of the next step.
    now: u64,
    /// The drive has ended (engine done or limits reached).
    ended: bool,
}

impl<C, K, T, Src> core::fmt::Debug for Session<'_, '_, C, K, T, Src>
where
    Src: PairSource<C>,
{
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Session")
            .field("drive", &self.report.drive)
            .field("now", &self.now)
            .field("ended", &self.ended)
            .finish()
    }
}

impl<'r, 'w, C, K, T, Src> Session<'r, 'w, C, K, T, Src>
where
    Src: PairSource<C> + 'r,
    C: 'r,
    K: Clock,
    T: Telemetry,
{
    /// One step call: the hook, then up to `max_units` (≥ 1) units of engine
    /// work at the clock time of the previous step — one [`Stage`] reported
    /// to the observer instead when [`Runner::start`] got one — then the
    /// clock is read. Returns [`StepStatus::Done`] once the engine has its
    /// outcome or the job's step or tick limit ([`DriveLimits`]) is reached
    /// (the limit is then logged as [`FailureCode::RelocBudgetExhausted`]),
    /// and from then on without doing any work; else
    /// [`StepStatus::Continue`].
    pub fn step(&mut self, max_units: u32) -> StepStatus {
        // Lent to the step's work and given back after it.
        let mut observe = self.observe.take();
        let status = self.step_with(|engine, now| match observe.as_mut() {
            None => matches!(engine.step_n(now, max_units.max(1)), StepResult::Done(_)),
            Some(observe) => {
                let (stage, r) = engine.step_stage(now);
                let done = matches!(r, StepResult::Done(_));
                if let Some(s) = stage {
                    observe(StageEvent::Ran(s));
                }
                done
            }
        });
        self.observe = observe;
        status
    }

    /// One step call as [`Session::step`], with the attempts run by `pool`'s
    /// workers ([`crate::pool`]): up to `max_units` (≥ 1) units, each either
    /// an attempt taken back from the pool in attempt order (the pool kept
    /// full of the next tickets) or a unit of other work done here. The
    /// outcome is bit-identical to [`Session::step`]'s (without an
    /// observer, which this does not call). Tickets may still be in flight
    /// when it returns; the next call takes them back. Once it returns
    /// [`StepStatus::Done`], cancel what is left in the pool.
    pub fn step_pooled<P: AttemptPool + ?Sized>(
        &mut self,
        max_units: u32,
        pool: &mut P,
    ) -> StepStatus {
        self.step_with(|engine, now| {
            for _ in 0..max_units.max(1) {
                if engine.outcome().is_some() {
                    break;
                }
                if !engine.collecting() {
                    pool.cancel();
                    let _ = engine.step(now);
                    continue;
                }
                let mut next = engine.stats().attempts.saturating_add(pool.in_flight());
                while pool.in_flight() < pool.capacity().max(1) {
                    let Some(t) = engine.ticket(next) else {
                        break;
                    };
                    pool.submit(t);
                    next = next.saturating_add(1);
                }
                match pool.next() {
                    Some(w) => {
                        if engine.commit(&w, now) != (Commit::Taken { keep: true }) {
                            pool.cancel();
                        }
                    }
                    // No ticket could be handed out (the work budget):
                    // the engine's own unit ends the run.
                    None => {
                        let _ = engine.step(now);
                    }
                }
            }
            engine.outcome().is_some()
        })
    }

    /// The step call around `work` (engine work at the step's time; true
    /// once the engine has its outcome): the limits, the hook, the step
    /// count and the clock read.
    fn step_with<W>(&mut self, work: W) -> StepStatus
    where
        W: FnOnce(&mut Engine<'r, 'w, Src::Frames<'r>>, u64) -> bool,
    {
        if self.ended {
            return StepStatus::Done;
        }
        if self.limit_reached() {
            self.end();
            return StepStatus::Done;
        }
        self.report.drive.steps = self.report.drive.steps.saturating_add(1);
        let now = self.now;
        Src::before_step(&mut self.hook, &mut self.engine, now);
        let done = work(&mut self.engine, now);
        self.now = time_or_zero(self.clock, self.log).max(now);
        if done {
            self.report.drive.done = true;
            self.end();
            return StepStatus::Done;
        }
        if self.limit_reached() {
            self.end();
            return StepStatus::Done;
        }
        StepStatus::Continue
    }

    /// Whether the job's step or tick limit is reached.
    fn limit_reached(&self) -> bool {
        self.report.drive.steps >= self.max_steps
            || self.now.saturating_sub(self.t0) >= self.budget_ticks
    }

    /// Close the drive report; without an outcome, log the limit.
    fn end(&mut self) {
        let drive = &mut self.report.drive;
        drive.elapsed_ticks = self.now.saturating_sub(self.t0);
        drive.cycles = match (self.c0, self.clock.cycles()) {
            (Some(a), Some(b)) => Some(b.wrapping_sub(a)),
            _ => None,
        };
        if !drive.done {
            self.log
                .record(FailureCode::RelocBudgetExhausted, self.now, drive.steps);
        }
        self.ended = true;
    }

    /// The engine, to build worker pipelines for an [`AttemptPool`]
    /// ([`vtsm_core::reloc::Engine::worker`]) and read its counters.
    pub fn engine(&self) -> &Engine<'r, 'w, Src::Frames<'r>> {
        &self.engine
    }

    /// The drive so far (steps called, and once ended the elapsed ticks and
    /// cycles).
    pub fn drive(&self) -> DriveReport {
        self.report.drive
    }

    /// End the relocalization: the engine's outcome — its anytime result
    /// ([`FailureCode::RelocBudgetExhausted`]) when [`Session::step`] has not
    /// returned [`StepStatus::Done`] for the engine's own outcome — and the
    /// report; the outcome and the failure log are sent as telemetry.
    pub fn finish(mut self) -> (Outcome, RelocReport) {
        if !self.ended {
            self.end();
        }
        let now = time_or_zero(self.clock, self.log);
        let outcome = self.engine.stop(now).clone();
        self.report.windows = Src::windows(self.engine.attempt_ref().frames(), self.log);
        let summary = outcome_payload(&OutcomeSummary::of(&outcome));
        send_frame(
            self.telemetry,
            self.telemetry_dropped,
            self.clock,
            self.log,
            FrameKind::Outcome as u8,
            &summary,
        );
        send_log(self.telemetry, self.telemetry_dropped, self.clock, self.log);
        (outcome, self.report)
    }
}

impl<C, K, S, P, T> Runner<C, K, S, P, T>
where
    K: Clock,
    S: MapStore,
    P: PosePrior,
    T: Telemetry,
{
    /// One relocalization, the one entry of every path (flight, host,
    /// tests): [`Runner::start`], [`Session::step`] with
    /// `job.limits.units_per_step` units until [`StepStatus::Done`], and
    /// [`Session::finish`]; a failed start sends the failure log.
    ///
    /// # Errors
    /// As [`Runner::start`]; each code is also in [`Runner::log`] and sent
    /// with the failure log.
    pub fn run<'p, Src: PairSource<C> + 'p>(
        &mut self,
        job: &Job,
        map: &mut [u8],
        pair: Src,
        ws: Workspace<'_>,
        observe: Option<&mut dyn FnMut(StageEvent)>,
    ) -> Result<(Outcome, RelocReport), FailureCode> {
        let mut slot = None;
        // Reborrowed for the session's lifetime.
        let observe = observe.map(|o| o as &mut dyn FnMut(StageEvent));
        let started = self.start(job, map, &mut slot, pair, ws, observe);
        let mut session = match started {
            Ok(s) => s,
            Err(code) => {
                // Ends the borrow of the runner before the log is sent.
                drop(started);
                self.send_failure_log();
                return Err(code);
            }
        };
        // Bounded: the session counts its step calls against
        // `job.limits.max_steps` and is done at the limit.
        for _ in 0..=job.limits.max_steps {
            if session.step(job.limits.units_per_step) == StepStatus::Done {
                break;
            }
        }
        Ok(session.finish())
    }

    /// Start a relocalization: check the map product at most once — not at
    /// all when the store hands over a view its owner already checked
    /// ([`MapStore::checked`], the host path), in place when the store is
    /// memory-mapped ([`MapStore::mapped`], the flight path; `map` is unused
    /// in both and may be empty), else read into `map` with bounded retries
    /// and checked by the retry loop —, the view that passed (kept in
    /// `slot`) being the one the engine uses ([`ReadReport::checks`] counts
    /// the checks); get the checked prior, then let `pair` ([`RamPair`] or
    /// [`InStore`]) capture the stereo pair, and build the engine with
    /// [`Setup`] (the job's rig, seed and upset checks; its parameters with
    /// t̃₀, r̃₀ replaced by the prior's stated uncertainty when it has one,
    /// [`Params::with_uncertainty`]) over `ws`. The [`Session`] drives it
    /// with `now` from the clock under `job.limits`. With `observe`, the
    /// engine is stepped one [`Stage`] at a time and `observe` gets
    /// [`StageEvent::Start`] here, once the engine is built, and
    /// [`StageEvent::Ran`] after each step, so a host can time the stages
    /// with its own clock; with a clock that does not move between steps the
    /// outcome is bit-identical.
    ///
    /// # Errors
    /// The failure code of acquisition (device faults after their retries, a
    /// map product that fails its check, an invalid prior, a frame that
    /// disagrees with the calibration) or of [`Setup::build`]; each is also
    /// in [`Runner::log`]. The failure log is not sent: the caller sends it
    /// ([`Runner::send_failure_log`]).
    pub fn start<'r, 'w, Src: PairSource<C> + 'r>(
        &'r mut self,
        job: &Job,
        map: &'r mut [u8],
        slot: &'r mut MapSlot<'r>,
        pair: Src,
        ws: Workspace<'w>,
        mut observe: Option<&'r mut dyn FnMut(StageEvent)>,
    ) -> Result<Session<'r, 'w, C, K, T, Src>, FailureCode> {
        self.cfg.validate()?;
        let start = self.now();
        let Self {
            camera,
            clock,
            store,
            prior,
            telemetry,
            cfg,
            log,
            telemetry_dropped,
        } = self;
        let cfg: &RunnerConfig = cfg;
        // A view the store's owner checked is used as is; memory-mapped
        // bytes are checked in place; anything else is read into `map` and
        // checked by the retry loop. One check at most, on every path.
        let mut map_read = ReadReport::default();
        let view = if store.checked().is_some() || store.mapped().is_some() {
            let store: &'r S = store;
            if let Some(view) = store.checked() {
                map_read.len = u32::try_from(view.bytes().len()).unwrap_or(u32::MAX);
                map_read.in_place = true;
                view
            } else {
                let bytes = store.mapped().unwrap_or(&[]);
                map_in_place(bytes, log, start, &mut map_read)?
            }
        } else {
            read_map_view(store, map, cfg, start, log, &mut map_read)?
        };
        let view: &'r MapView<'r> = slot.insert(view);
        let prior = read_prior(prior, log, start)?;
        let now = time_or_zero(clock, log);
        // The prior's stated half-widths size the search (one start, as the
        // caller's `seeds` says); `Setup::build` validates them again with
        // the rest of the parameters.
        let params = match prior.uncertainty {
            Some(u) => job.params.with_uncertainty(u),
            None => job.params,
        };
        let captured = pair.capture(camera, cfg, now, log)?;
        let setup = Setup::with_frames(
            view,
            captured.frames,
            &job.rig,
            &params,
            &prior.world_from_left,
            job.seed,
        );
        let engine = build(setup, job, ws, log, start)?;
        if let Some(o) = observe.as_mut() {
            o(StageEvent::Start);
        }
        let t0 = time_or_zero(clock, log);
        let c0 = clock.cycles();
        Ok(Session {
            engine,
            hook: captured.hook,
            clock,
            log,
            telemetry,
            telemetry_dropped,
            observe,
            max_steps: job.limits.max_steps,
            budget_ticks: job.limits.budget_ticks,
            report: RelocReport {
                frame: captured.frame,
                capture: captured.capture,
                map_read,
                drive: DriveReport {
                    steps: 0,
                    elapsed_ticks: 0,
                    cycles: None,
                    done: false,
                },
                prior_uncertainty: params.uncertainty(),
                windows: WindowReport::default(),
            },
            t0,
            c0,
            now: t0,
            ended: false,
        })
    }
}
