//! # vtsm-ffi
//!
//! The C interface of VTSM: a `no_std` static library (`libvtsm_ffi.a`) and
//! its header `include/vtsm.h`, generated from this crate by cbindgen, for
//! flight software written in C or C++ (F Prime components, cFS apps, vendor
//! RTOS tasks). `fsw-docs/interfaces/c-api.md` is the integrator's guide.
//!
//! | item | what |
//! |---|---|
//! | [`vtsm_params_for_profile`], [`VtsmParams`] | the core's parameters as a plain struct, filled from a named [`VtsmProfile`] or set by hand |
//! | [`vtsm_storage_size`], [`VTSM_STORAGE_ALIGN`], `VTSM_STORAGE_BYTES_*` | the engine storage the caller provides |
//! | [`vtsm_engine_create`], [`VtsmConfig`] | check every input and set the engine up in the caller's storage |
//! | [`vtsm_engine_run`], [`VtsmLimits`], [`VtsmOutcome`] | one relocalization through the HAL runner, under a step, work and tick budget |
//! | [`vtsm_engine_release`] | give the storage back (the handle is refused from then on) |
//! | [`VtsmIo`] | C callbacks mirroring the HAL traits: read a window of a frame, read map bytes, write telemetry, read the clock |
//! | [`VtsmFailure`], [`vtsm_failure_name`] | the failure codes, generated from `vtsm_core::FailureCode::ALL` |
//!
//! ## Guarantees
//!
//! * Nothing is allocated: the caller owns the storage, the map product, the
//!   outcome and every buffer; the library keeps no pointer between calls
//!   except those the caller put in the [`VtsmConfig`] (map bytes, map
//!   buffer, callback context), which must stay valid until the last
//!   [`vtsm_engine_run`] on that storage.
//! * Every pointer and length crossing the boundary is checked (null,
//!   alignment, size, overlap) and a bad one returns a numbered code
//!   ([`VtsmFailure`]); no input makes the library panic. The bare-metal
//!   build links with the panic-freedom check (feature `panic-check`).
//! * Every relocalization goes through [`vtsm_hal::runner::Runner::run`], the
//!   one entry of every Rust path, so the outcome is bit-identical to the
//!   Rust flight path's on the same inputs, on the host and on the targets.
//! * This is the only crate of the workspace with `unsafe`; each block says
//!   why it is sound in a `// SAFETY:` comment.
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_op_in_unsafe_fn)]
#![deny(clippy::undocumented_unsafe_blocks)]
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::panic))]
#![cfg_attr(test, allow(clippy::indexing_slicing))]

// The host static library takes std's panic handler; bare-metal builds have
// the one below.
#[cfg(all(not(test), not(target_os = "none")))]
extern crate std;

mod codes;

pub use codes::VtsmFailure;

use core::ffi::{c_char, c_void};
use core::mem::{align_of, size_of};
use vtsm_core::config::Params;
use vtsm_core::frame::Eye;
use vtsm_core::geom::{Camera, Pose, StereoRig, Vec3};
use vtsm_core::image::Rect;
use vtsm_core::map::MapView;
use vtsm_core::nalgebra::{Quaternion, UnitQuaternion};
use vtsm_core::ncc::Run;
use vtsm_core::reloc::{Accuracy, MatchPolicy, Near, Outcome, Search, Workspace, WorkspaceSizes};
use vtsm_core::FailureCode;
use vtsm_hal::prior::{Covariance, PriorEstimate};
use vtsm_hal::runner::{
    DriveLimits, InStore, Job, MapSlot, RelocReport, Runner, RunnerConfig, Session, StepStatus,
    VerifyChecks,
};
use vtsm_hal::{
    Clock, ErrorKind, ErrorType, FrameInfo, FrameStore, MapStore, PosePrior, PriorUncertainty,
    Telemetry,
};

/// Alignment, in bytes, the engine storage must have.
pub const VTSM_STORAGE_ALIGN: usize = 16;

/// Bytes at the start of the engine storage that hold the engine's state
/// (the checked job, the callbacks, and between [`vtsm_engine_start`] and
/// [`vtsm_engine_outcome`] the relocalization under way); the workspace
/// follows. Fixed, so the storage sizes are the same on every target.
pub const VTSM_STORAGE_HEADER_BYTES: usize = 20480;

/// Engine storage for the `VTSM_PROFILE_PAPER` parameters (5472-pixel-wide
/// images): what [`vtsm_storage_size`] returns for them.
pub const VTSM_STORAGE_BYTES_PAPER: usize = 5_436_384;

/// Engine storage for the `VTSM_PROFILE_DEMO` parameters (1368-pixel-wide images).
pub const VTSM_STORAGE_BYTES_DEMO: usize = 606_224;

/// Engine storage for the `VTSM_PROFILE_TEST` parameters (480-pixel-wide
/// images; the CI flight-path scene).
pub const VTSM_STORAGE_BYTES_TEST: usize = 179_296;

/// `VtsmFailure::VTSM_OK` as the raw value the functions return.
const VTSM_OK: u16 = VtsmFailure::VTSM_OK as u16;

/// Default retries of one device operation (window read, map chunk read).
const DEVICE_ATTEMPTS: u8 = 3;
/// Default whole-product reads of the map when its check fails.
const PRODUCT_ATTEMPTS: u8 = 2;
/// Bytes per map read callback.
const MAP_CHUNK: u32 = 1 << 16;
/// Marks storage set up by [`vtsm_engine_create`] ("VTSMFFI1").
const MAGIC: u64 = 0x5654_534d_4646_4931;

/// A named parameter profile ([`vtsm_params_for_profile`]).
#[repr(u32)]
#[allow(non_camel_case_types)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VtsmProfile {
    /// The paper's parameters at 5472 × 3648 (ℓ = 256).
    VTSM_PROFILE_PAPER = 1,
    /// The paper's parameters scaled to 1368 × 912 images.
    VTSM_PROFILE_DEMO = 2,
    /// The paper's parameters scaled to 480 × 320 images (the CI scene).
    VTSM_PROFILE_TEST = 3,
}

/// Image width of a profile: its parameters are `Params::for_image_width(width)`.
fn profile_width(profile: u32) -> Option<u32> {
    match profile {
        1 => Some(5472),
        2 => Some(1368),
        3 => Some(480),
        _ => None,
    }
}

/// Which camera of the rectified pair a window is read from.
#[repr(u8)]
#[allow(non_camel_case_types)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VtsmEye {
    /// The left (reference) camera.
    VTSM_EYE_LEFT = 0,
    /// The right camera.
    VTSM_EYE_RIGHT = 1,
}

/// What a callback returns: `VTSM_IO_OK` or the kind of fault, as the HAL's
/// `ErrorKind` (timeouts, short transfers and detected corruption are retried
/// by the runner a bounded number of times; the others are not). Any other
/// value counts as `VTSM_IO_OTHER`.
#[repr(i32)]
#[allow(non_camel_case_types)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VtsmIoStatus {
    /// The operation succeeded.
    VTSM_IO_OK = 0,
    /// The device did not answer within the time it was given.
    VTSM_IO_TIMEOUT = 1,
    /// The device delivered less data than asked for.
    VTSM_IO_TRUNCATED = 2,
    /// The device detected that the data is damaged (link CRC, ECC).
    VTSM_IO_CORRUPTED = 3,
    /// The device is not available.
    VTSM_IO_UNAVAILABLE = 4,
    /// Any other fault.
    VTSM_IO_OTHER = 5,
}

fn io_result(status: i32) -> Result<(), ErrorKind> {
    match status {
        0 => Ok(()),
        1 => Err(ErrorKind::Timeout),
        2 => Err(ErrorKind::Truncated),
        3 => Err(ErrorKind::Corrupted),
        4 => Err(ErrorKind::Unavailable),
        _ => Err(ErrorKind::Other),
    }
}

/// The C framework's devices, as callbacks that mirror the HAL traits; each
/// gets `ctx` as its first argument. Called only from inside
/// [`vtsm_engine_run`], on the caller's thread.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct VtsmIo {
    /// Passed to every callback; may be null.
    pub ctx: *mut c_void,
    /// Reads the rectangle `x, y, w, h` (pixels, top-left origin) of the latched
    /// `eye` frame (`VtsmEye`) into `out`, row-major with stride `w`; `out_len`
    /// is at least `w * h`. Mirrors the HAL's `FrameStore::read_window`: return
    /// `VTSM_IO_OK` only when all of the `w * h` bytes are written; never write
    /// past `out_len`; keep no pointer to `out`.
    /// Required.
    pub read_window: Option<
        unsafe extern "C" fn(
            ctx: *mut c_void,
            eye: u8,
            x: i32,
            y: i32,
            w: u32,
            h: u32,
            out: *mut u8,
            out_len: usize,
        ) -> i32,
    >,
    /// Latches a new stereo pair in the camera's frame memory (HAL
    /// `FrameStore::capture_in_place`): after `VTSM_IO_OK`, window reads serve
    /// that pair until the next latch.
    /// Optional (null: the pair is already latched).
    pub latch: Option<unsafe extern "C" fn(ctx: *mut c_void) -> i32>,
    /// Reads `len` bytes of the stored map product starting at byte `offset`
    /// into `buf` (HAL `MapStore::read_range`); used only when the map product is
    /// not given in memory ([`VtsmConfig::map`] null).
    /// Required when [`VtsmConfig::map`] is null.
    pub read_map: Option<
        unsafe extern "C" fn(ctx: *mut c_void, offset: u32, buf: *mut u8, len: usize) -> i32,
    >,
    /// Sends one telemetry frame of `kind` (the HAL's `FrameKind`) carrying
    /// `len` bytes at `payload` (HAL `Telemetry::send`); keep no pointer to it.
    /// Optional (null: frames are discarded).
    pub write_telemetry: Option<
        unsafe extern "C" fn(ctx: *mut c_void, kind: u8, payload: *const u8, len: usize) -> i32,
    >,
    /// Reads the monotonic clock in ticks of [`VtsmIo::tick_hz`] (HAL `Clock`).
    /// Optional (null: time stands still at 0; the outcome does not depend on
    /// it, only the tick budget and the reported ticks do).
    pub now_ticks: Option<unsafe extern "C" fn(ctx: *mut c_void) -> u64>,
    /// Ticks per second of `now_ticks` (ignored without it).
    pub tick_hz: u32,
}

/// Relocalization parameters (the core's `Params`; ranges in
/// `fsw-docs/requirements/config.md`). Booleans are `0` or `1`; any other
/// value is `CONFIG_PARAM_OUT_OF_RANGE`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VtsmParams {
    /// N_corr, 3..=256.
    pub n_corr: u16,
    /// N_iter, 1..=16.
    pub n_iter: u8,
    /// Also match the ℓ/2 sub-template (0 or 1).
    pub sub_template: u8,
    /// t̃₀, metres, (0, 2]: the prior's translation uncertainty.
    pub t0_m: f32,
    /// r̃₀, degrees, (0, 20]: the prior's rotation uncertainty.
    pub r0_deg: f32,
    /// γ, [0, 1].
    pub gamma: f32,
    /// ε, pixels, (0, 64].
    pub epsilon_px: f32,
    /// ℓ, pixels, even, 16..=256.
    pub template_px: u16,
    /// Largest search-window side, pixels, `template_px..=1024`.
    pub search_px: u16,
    /// RANSAC iteration cap, 1..=4096.
    pub ransac_iter: u16,
    /// Pose seeds for large priors (0 = off), 0..=256.
    pub seeds: u16,
    /// RANSAC inlier threshold, metres, (0, 1].
    pub inlier_m: f32,
    /// Convergence threshold, metres, [0, 0.1].
    pub convergence_m: f32,
    /// Reuse fraction, [0, 1].
    pub reuse_fraction: f32,
    /// Attempts per iteration, `n_corr..=100000`.
    pub attempts_per_iter: u32,
    /// Minimum NCC score to accept a match, (0, 1).
    pub min_score: f32,
    /// Consecutive Stall cap, 1..=64.
    pub max_stall: u8,
    /// Consecutive Reseed cap, 1..=64.
    pub max_reseed: u8,
    /// Final refinement iterations, 0..=32.
    pub refine_iter: u8,
    /// Mechanism Stall (0 or 1).
    pub stall: u8,
    /// Mechanism Reseed (0 or 1).
    pub reseed: u8,
    /// Mechanism Anneal (0 or 1).
    pub anneal: u8,
    /// Mechanism Distribute (0 or 1).
    pub distribute: u8,
    /// Mechanism Reuse (0 or 1).
    pub reuse: u8,
}

/// The accuracy of a configuration: none when both bounds are 0, else both
/// in range ([`Accuracy::validate`]).
fn accuracy_of(sigma_t_m: f32, sigma_r_deg: f32) -> Result<Option<Accuracy>, FailureCode> {
    if sigma_t_m == 0.0 && sigma_r_deg == 0.0 {
        return Ok(None);
    }
    let a = Accuracy {
        sigma_t_m,
        sigma_r_deg,
    };
    if a.validate() {
        Ok(Some(a))
    } else {
        Err(FailureCode::ConfigParamOutOfRange)
    }
}

fn flag(v: u8) -> Result<bool, FailureCode> {
    match v {
        0 => Ok(false),
        1 => Ok(true),
        _ => Err(FailureCode::ConfigParamOutOfRange),
    }
}

impl VtsmParams {
    /// The plain form of `p`.
    pub fn from_params(p: &Params) -> Self {
        let m = p.mechanisms;
        Self {
            n_corr: p.n_corr,
            n_iter: p.n_iter,
            sub_template: u8::from(p.sub_template),
            t0_m: p.t0_m,
            r0_deg: p.r0_deg,
            gamma: p.gamma,
            epsilon_px: p.epsilon_px,
            template_px: p.template_px,
            search_px: p.search_px,
            ransac_iter: p.ransac_iter,
            seeds: p.seeds,
            inlier_m: p.inlier_m,
            convergence_m: p.convergence_m,
            reuse_fraction: p.reuse_fraction,
            attempts_per_iter: p.attempts_per_iter,
            min_score: p.min_score,
            max_stall: p.max_stall,
            max_reseed: p.max_reseed,
            refine_iter: p.refine_iter,
            stall: u8::from(m.stall),
            reseed: u8::from(m.reseed),
            anneal: u8::from(m.anneal),
            distribute: u8::from(m.distribute),
            reuse: u8::from(m.reuse),
        }
    }

    /// The checked core parameters.
    ///
    /// # Errors
    /// `ConfigParamOutOfRange` for a field outside its range.
    pub fn to_params(&self) -> Result<Params, FailureCode> {
        let mut p = Params::paper();
        p.n_corr = self.n_corr;
        p.n_iter = self.n_iter;
        p.sub_template = flag(self.sub_template)?;
        p.t0_m = self.t0_m;
        p.r0_deg = self.r0_deg;
        p.gamma = self.gamma;
        p.epsilon_px = self.epsilon_px;
        p.template_px = self.template_px;
        p.search_px = self.search_px;
        p.ransac_iter = self.ransac_iter;
        p.seeds = self.seeds;
        p.inlier_m = self.inlier_m;
        p.convergence_m = self.convergence_m;
        p.reuse_fraction = self.reuse_fraction;
        p.attempts_per_iter = self.attempts_per_iter;
        p.min_score = self.min_score;
        p.max_stall = self.max_stall;
        p.max_reseed = self.max_reseed;
        p.refine_iter = self.refine_iter;
        p.mechanisms.stall = flag(self.stall)?;
        p.mechanisms.reseed = flag(self.reseed)?;
        p.mechanisms.anneal = flag(self.anneal)?;
        p.mechanisms.distribute = flag(self.distribute)?;
        p.mechanisms.reuse = flag(self.reuse)?;
        p.validate()
            .map_err(|_| FailureCode::ConfigParamOutOfRange)?;
        Ok(p)
    }
}

/// A rectified stereo rig: the left camera's pinhole intrinsics and the
/// baseline (the right camera is the left one moved `baseline_m` along its x axis).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VtsmRig {
    /// Focal length along x, pixels.
    pub fx: f32,
    /// Focal length along y, pixels.
    pub fy: f32,
    /// Principal point x, pixels (pixel centres at integers).
    pub cx: f32,
    /// Principal point y, pixels.
    pub cy: f32,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Baseline, metres.
    pub baseline_m: f32,
}

/// The pose prior from the navigation filter with its uncertainty.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VtsmPrior {
    /// Translation of `world_from_left`, metres, in the map's local frame.
    pub t: [f32; 3],
    /// Rotation of `world_from_left`, unit quaternion `[w, x, y, z]`; used
    /// bit for bit (not renormalized).
    pub q: [f32; 4],
    /// Covariance of `(t, rotation vector)`, 6 × 6 row-major, symmetric
    /// with a non-negative diagonal (checked).
    pub covariance: [f32; 36],
    /// Stated half-width of the translation region the truth lies in,
    /// metres, (0, 2]; `0` with `r_deg == 0`: not stated, the parameters'
    /// t̃₀, r̃₀ are used.
    pub t_m: f32,
    /// Stated rotation half-width, degrees, (0, 20]; see `t_m`.
    pub r_deg: f32,
}

/// Everything [`vtsm_engine_create`] sets an engine up with.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct VtsmConfig {
    /// The map product in memory (memory-mapped flash, RAM), checked in place
    /// at create and used in place; null: read through
    /// [`VtsmIo::read_map`] into `map_buffer` at each run.
    pub map: *const u8,
    /// Bytes at `map` (the product's length); with `map` null, the stored
    /// product's length.
    pub map_len: usize,
    /// RAM for the map product when `map` is null, at least `map_len` bytes,
    /// not inside the storage; unused (may be null) otherwise.
    pub map_buffer: *mut u8,
    /// Bytes at `map_buffer`.
    pub map_buffer_len: usize,
    /// The calibrated rig.
    pub rig: VtsmRig,
    /// The parameters ([`vtsm_params_for_profile`] or by hand).
    pub params: VtsmParams,
    /// The prior pose and its uncertainty.
    pub prior: VtsmPrior,
    /// Seed of the relocalization's random streams.
    pub seed: u64,
    /// Repeat the final solve from a second random stream and compare (0 or 1).
    pub verify_repeat_solve: u8,
    /// Re-check the map product before a success is returned (0 or 1).
    pub verify_recheck_map: u8,
    /// The accuracy the caller needs, 1-σ translation in metres (0, 1]:
    /// the rounds end once the refined estimate states at most this and
    /// [`VtsmConfig::accuracy_sigma_r_deg`] in every axis
    /// (`VtsmStats::rounds_saved`). Both 0: every pose update runs.
    pub accuracy_sigma_t_m: f32,
    /// The accuracy the caller needs, 1-σ rotation in degrees (0, 10]; both 0:
    /// none.
    pub accuracy_sigma_r_deg: f32,
    /// Correspondences of the last round, N_corr..=256 (0: N_corr like every
    /// round): the final estimate is refined on more pairs, more exact where
    /// the light agrees, for more attempts in that round
    /// (`Options::final_pairs`; fewer than N_corr is refused with
    /// `VTSM_CONFIG_PARAM_OUT_OF_RANGE`).
    pub final_pairs: u16,
    /// Revisit (VTSM-RELOC-046; `Options::revisit`): 0 on, the engine's
    /// default; 1 off (every attempt draws its vertex anywhere in the map).
    pub revisit_off: u8,
    /// Near (VTSM-RELOC-047; `Near`): 0 off, the engine's default; 1 on
    /// (`Near::ON`: fewer attempts under a large lighting change, a less
    /// exact pose). A zeroed configuration runs `Search::DEFAULT`. (Not
    /// `near`: a Windows header defines that name as an empty macro.)
    pub near_on: u8,
    /// The devices.
    pub io: VtsmIo,
}

/// How [`vtsm_engine_run`] may spend time (the HAL's `DriveLimits`). When
/// a budget runs out the best pose so far is returned with
/// `RELOC_BUDGET_EXHAUSTED`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VtsmLimits {
    /// Engine work units per step (≥ 1; one unit is one attempt or one
    /// RANSAC chunk); the outcome does not depend on it.
    pub units_per_step: u32,
    /// Steps at most.
    pub max_steps: u32,
    /// Clock ticks at most ([`VtsmIo::now_ticks`]).
    pub budget_ticks: u64,
}

/// Work counters of a relocalization (a subset of the core's `Stats`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VtsmStats {
    /// Work units done (attempts + solves + RANSAC chunks).
    pub work_units: u32,
    /// Rounds started.
    pub rounds: u32,
    /// Correspondence attempts.
    pub attempts: u32,
    /// Correspondences produced by attempts.
    pub correspondences: u32,
    /// Correspondences carried over by Reuse.
    pub reused: u32,
    /// GetTransform calls.
    pub solves: u32,
    /// RANSAC hypotheses evaluated, summed.
    pub ransac_iterations: u32,
    /// Templates rendered.
    pub renders: u32,
    /// Attempts that measured a Revisit vertex (VTSM-RELOC-046; 0 with
    /// [`VtsmConfig::revisit_off`]).
    pub revisited: u32,
    /// Attempts whose vertex Near drew near an agreeing one (VTSM-RELOC-047;
    /// 0 unless [`VtsmConfig::near_on`]).
    pub near_drawn: u32,
    /// NCC multiply-accumulates.
    pub ncc_macs: u64,
    /// Successful iterations (pose updates).
    pub successes: u16,
    /// Stall events.
    pub stalls: u16,
    /// Reseed events.
    pub reseeds: u16,
    /// Seeds evaluated in multi-seed mode.
    pub seeds_tried: u16,
    /// Pose updates not made because the caller's accuracy was met first.
    pub rounds_saved: u16,
    /// Engine step calls made by the runner.
    pub steps: u32,
    /// Clock ticks from the first engine step to the last.
    pub elapsed_ticks: u64,
}

/// The result of one relocalization.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VtsmOutcome {
    /// `VTSM_OK` (0) on success, else why it stopped ([`VtsmFailure`]); the
    /// pose is then not trusted, except as the anytime estimate with
    /// `RELOC_BUDGET_EXHAUSTED`.
    pub failure: u16,
    /// Inliers of the returned pose.
    pub inliers: u16,
    /// Whether `covariance` holds the final refinement's covariance (0 or 1).
    pub has_covariance: u8,
    /// Translation of the estimated `world_from_left`, metres.
    pub t: [f32; 3],
    /// Rotation of the estimated `world_from_left`, `[w, x, y, z]`.
    pub q: [f32; 4],
    /// Covariance of the pose, 6 × 6 row-major (translation in metres, then
    /// rotation in radians; the core's `pose::Covariance`); zero without it.
    pub covariance: [f32; 36],
    /// RMS residual of the inliers, metres.
    pub rms_m: f32,
    /// Inliers over pairs given to the final solve.
    pub inlier_ratio: f32,
    /// RMS reprojection residual of the inliers, pixels.
    pub reproj_rms_px: f32,
    /// Work counters.
    pub stats: VtsmStats,
}

impl VtsmOutcome {
    /// An outcome that only carries `code` (nothing ran).
    pub const fn failed(code: u16) -> Self {
        Self {
            failure: code,
            inliers: 0,
            has_covariance: 0,
            t: [0.0; 3],
            q: [1.0, 0.0, 0.0, 0.0],
            covariance: [0.0; 36],
            rms_m: 0.0,
            inlier_ratio: 0.0,
            reproj_rms_px: 0.0,
            stats: VtsmStats {
                work_units: 0,
                rounds: 0,
                attempts: 0,
                correspondences: 0,
                reused: 0,
                solves: 0,
                ransac_iterations: 0,
                renders: 0,
                revisited: 0,
                near_drawn: 0,
                ncc_macs: 0,
                successes: 0,
                stalls: 0,
                reseeds: 0,
                seeds_tried: 0,
                rounds_saved: 0,
                steps: 0,
                elapsed_ticks: 0,
            },
        }
    }

    /// The plain form of an engine outcome and the runner's report.
    pub fn from_outcome(o: &Outcome, report: &RelocReport) -> Self {
        let (has_cov, cov) = match o.quality.covariance {
            Some(c) => (1, c.m),
            None => (0, [0.0; 36]),
        };
        let s = &o.stats;
        Self {
            failure: o.failure.map_or(0, FailureCode::code),
            inliers: o.quality.inliers,
            has_covariance: has_cov,
            t: o.pose.t(),
            q: o.pose.q(),
            covariance: cov,
            rms_m: o.quality.rms_m,
            inlier_ratio: o.quality.inlier_ratio,
            reproj_rms_px: o.quality.reproj_rms_px,
            stats: VtsmStats {
                work_units: s.work_units,
                rounds: s.rounds,
                attempts: s.attempts,
                correspondences: s.correspondences,
                reused: s.reused,
                solves: s.solves,
                ransac_iterations: s.ransac_iterations,
                renders: s.pipeline.renders,
                revisited: s.pipeline.revisited,
                near_drawn: s.pipeline.near_drawn,
                ncc_macs: s.pipeline.ncc_macs,
                successes: s.successes,
                stalls: s.stalls,
                reseeds: s.reseeds,
                seeds_tried: s.seeds_tried,
                rounds_saved: s.rounds_saved,
                steps: report.drive.steps,
                elapsed_ticks: report.drive.elapsed_ticks,
            },
        }
    }
}

/// An engine set up in caller storage by [`vtsm_engine_create`]; opaque
/// (a handle is the storage's address).
pub struct VtsmEngine {
    _opaque: [u8; 0],
}

// ---------------------------------------------------------------------------
// Storage layout

/// Where the workspace's three buffers lie in the storage.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Layout {
    ws: WorkspaceSizes,
    words_at: usize,
    runs_at: usize,
    total: usize,
}

const fn round16(n: usize) -> Option<usize> {
    match n.checked_add(15) {
        Some(v) => Some(v & !15),
        None => None,
    }
}

/// The workspace sizes of checked `params` (the engine's own choice of
/// search mode) and where they go in the storage.
fn layout(params: &Params) -> Option<Layout> {
    let ws = WorkspaceSizes::for_params(params, MatchPolicy::for_params(params).search);
    let words_at = VTSM_STORAGE_HEADER_BYTES.checked_add(round16(ws.bytes)?)?;
    let runs_at = words_at.checked_add(round16(ws.words.checked_mul(4)?)?)?;
    let total = runs_at.checked_add(ws.runs.checked_mul(size_of::<Run>())?)?;
    Some(Layout {
        ws,
        words_at,
        runs_at,
        total,
    })
}

/// The engine's state at the start of the storage; `repr(C)` so the magic
/// word is its first 8 bytes.
#[repr(C)]
struct Header {
    /// [`MAGIC`]; read through the raw storage pointer by [`vtsm_engine_run`].
    #[allow(dead_code)]
    magic: u64,
    storage_len: usize,
    layout: Layout,
    job: Job,
    prior: PriorEstimate,
    map: *const u8,
    map_len: usize,
    map_buffer: *mut u8,
    map_buffer_len: usize,
    io: VtsmIo,
    /// [`STATE_IDLE`] or [`STATE_RUNNING`]; written in place through the
    /// raw storage pointer.
    state: u32,
}

/// No relocalization under way: [`vtsm_engine_start`] may start one.
const STATE_IDLE: u32 = 0;
/// A relocalization started by [`vtsm_engine_start`] is under way: its
/// session is at [`LIVE_AT`]; [`vtsm_engine_step`] and
/// [`vtsm_engine_outcome`] may be called.
const STATE_RUNNING: u32 = 1;

/// The runner over the callbacks.
type CRunner = Runner<CFrames, CClock, CStore<'static>, CPrior, CTelemetry>;
/// A relocalization under way over the storage ([`Runner::start`]).
type CSession = Session<'static, 'static, CFrames, CClock, CTelemetry, InStore>;

/// What a relocalization under way keeps in the storage's header area
/// between calls: the runner, the checked map view and the session that
/// borrows both. The `'static` lifetimes stand for "until
/// [`vtsm_engine_outcome`]": every borrow is of the storage, the map bytes
/// or the map buffer, which the caller keeps valid and untouched until then.
#[repr(C)]
struct Live {
    runner: CRunner,
    slot: MapSlot<'static>,
    session: core::mem::MaybeUninit<CSession>,
}

/// Offset of the [`Live`] state in the storage's header area.
const LIVE_AT: usize = match round16(size_of::<Header>()) {
    Some(n) => n,
    None => VTSM_STORAGE_HEADER_BYTES,
};

const _: () = assert!(LIVE_AT + size_of::<Live>() <= VTSM_STORAGE_HEADER_BYTES);
const _: () = assert!(align_of::<Live>() <= VTSM_STORAGE_ALIGN);
const _: () = assert!(size_of::<Header>() <= VTSM_STORAGE_HEADER_BYTES);
const _: () = assert!(align_of::<Header>() <= VTSM_STORAGE_ALIGN);
const _: () = assert!(VTSM_STORAGE_HEADER_BYTES % VTSM_STORAGE_ALIGN == 0);
const _: () = assert!(align_of::<Run>() <= VTSM_STORAGE_ALIGN);

// ---------------------------------------------------------------------------
// Devices over the callbacks

/// The type of [`VtsmIo::read_window`].
type ReadWindowFn =
    unsafe extern "C" fn(*mut c_void, u8, i32, i32, u32, u32, *mut u8, usize) -> i32;

/// The camera's frame memory, read through [`VtsmIo::read_window`].
struct CFrames {
    io: VtsmIo,
    read_window: ReadWindowFn,
    width: u32,
    height: u32,
    sequence: u32,
}

impl ErrorType for CFrames {
    type Error = ErrorKind;
}

impl FrameStore for CFrames {
    fn capture_in_place(&mut self, _timeout_ticks: u64) -> Result<FrameInfo, ErrorKind> {
        if let Some(latch) = self.io.latch {
            // SAFETY: `latch` is a C function pointer the caller supplied in
            // the config with `ctx`, documented to take exactly that context.
            io_result(unsafe { latch(self.io.ctx) })?;
        }
        self.sequence = self.sequence.wrapping_add(1);
        let timestamp_ticks = now(&self.io);
        Ok(FrameInfo {
            width: self.width,
            height: self.height,
            stride: self.width,
            sequence: self.sequence,
            timestamp_ticks,
            exposure_us: 0,
        })
    }

    fn read_window(&mut self, eye: Eye, rect: Rect, out: &mut [u8]) -> Result<(), ErrorKind> {
        let need = (rect.w as usize)
            .checked_mul(rect.h as usize)
            .ok_or(ErrorKind::Other)?;
        if out.len() < need {
            return Err(ErrorKind::Other);
        }
        let eye = match eye {
            Eye::Left => VtsmEye::VTSM_EYE_LEFT as u8,
            Eye::Right => VtsmEye::VTSM_EYE_RIGHT as u8,
        };
        // SAFETY: `read_window` is the caller's callback; `out` is a live
        // exclusive buffer of `out.len()` bytes for the duration of the call,
        // and the contract forbids writing past `out_len` or keeping it.
        let status = unsafe {
            (self.read_window)(
                self.io.ctx,
                eye,
                rect.x,
                rect.y,
                rect.w,
                rect.h,
                out.as_mut_ptr(),
                out.len(),
            )
        };
        io_result(status)
    }
}

fn now(io: &VtsmIo) -> u64 {
    match io.now_ticks {
        // SAFETY: the caller's clock callback with its own context.
        Some(f) => unsafe { f(io.ctx) },
        None => 0,
    }
}

/// The clock callback (or a clock standing at 0).
struct CClock(VtsmIo);

impl ErrorType for CClock {
    type Error = core::convert::Infallible;
}

impl Clock for CClock {
    fn tick_hz(&self) -> u32 {
        self.0.tick_hz.max(1)
    }
    fn now_ticks(&mut self) -> Result<u64, core::convert::Infallible> {
        Ok(now(&self.0))
    }
}

/// The map product: in memory (checked and used in place) or behind the
/// read callback.
struct CStore<'m> {
    mapped: Option<&'m [u8]>,
    len: u32,
    io: VtsmIo,
}

impl ErrorType for CStore<'_> {
    type Error = ErrorKind;
}

impl MapStore for CStore<'_> {
    fn len(&mut self) -> Result<u32, ErrorKind> {
        Ok(self.len)
    }
    fn read_range(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), ErrorKind> {
        let end = (offset as usize)
            .checked_add(buf.len())
            .ok_or(ErrorKind::Other)?;
        if end > self.len as usize {
            return Err(ErrorKind::Other);
        }
        if let Some(bytes) = self.mapped {
            let src = bytes.get(offset as usize..end).ok_or(ErrorKind::Other)?;
            buf.copy_from_slice(src);
            return Ok(());
        }
        let read = self.io.read_map.ok_or(ErrorKind::Unavailable)?;
        // SAFETY: the caller's callback; `buf` is a live exclusive buffer of
        // `buf.len()` bytes for the call, which must not write past it.
        io_result(unsafe { read(self.io.ctx, offset, buf.as_mut_ptr(), buf.len()) })
    }
    fn mapped(&self) -> Option<&[u8]> {
        self.mapped
    }
}

/// The prior checked at create.
struct CPrior(PriorEstimate);

impl ErrorType for CPrior {
    type Error = core::convert::Infallible;
}

impl PosePrior for CPrior {
    fn latest(&mut self) -> Result<PriorEstimate, core::convert::Infallible> {
        Ok(self.0)
    }
}

/// The telemetry callback (or a sink).
struct CTelemetry(VtsmIo);

impl ErrorType for CTelemetry {
    type Error = ErrorKind;
}

impl Telemetry for CTelemetry {
    fn send(&mut self, kind: u8, payload: &[u8]) -> Result<(), ErrorKind> {
        match self.0.write_telemetry {
            // SAFETY: the caller's callback; `payload` is live for the call
            // and the contract forbids keeping it.
            Some(f) => io_result(unsafe { f(self.0.ctx, kind, payload.as_ptr(), payload.len()) }),
            None => Ok(()),
        }
    }
}

// ---------------------------------------------------------------------------
// Checks

/// Null and alignment check of a pointer to one `T`.
fn check_ptr<T>(p: *const T) -> Result<(), FailureCode> {
    if p.is_null() {
        Err(FailureCode::FfiNullPointer)
    } else if !(p as usize).is_multiple_of(align_of::<T>()) {
        Err(FailureCode::FfiMisaligned)
    } else {
        Ok(())
    }
}

/// Whether the byte ranges `[a, a + an)` and `[b, b + bn)` overlap.
fn overlaps(a: usize, an: usize, b: usize, bn: usize) -> bool {
    an > 0 && bn > 0 && a < b.saturating_add(bn) && b < a.saturating_add(an)
}

fn rig_of(r: &VtsmRig) -> Result<StereoRig, FailureCode> {
    let cam = Camera::new(r.fx, r.fy, r.cx, r.cy, r.width, r.height)?;
    StereoRig::new(cam, r.baseline_m)
}

fn prior_of(p: &VtsmPrior) -> Result<PriorEstimate, FailureCode> {
    let [w, x, y, z] = p.q;
    let norm2 = w * w + x * x + y * y + z * z;
    if !(norm2.is_finite() && (norm2 - 1.0).abs() <= 1e-3) {
        return Err(FailureCode::RelocPriorInvalid);
    }
    // The caller's unit quaternion bit for bit: renormalizing could move its
    // last bit and with it the engine's draws.
    let q = UnitQuaternion::new_unchecked(Quaternion::new(w, x, y, z));
    let pose = Pose::new(q, Vec3::new(p.t[0], p.t[1], p.t[2]));
    let mut full = [[0.0f32; 6]; 6];
    for (row, src) in full.iter_mut().zip(p.covariance.chunks_exact(6)) {
        row.copy_from_slice(src);
    }
    let uncertainty = if p.t_m == 0.0 && p.r_deg == 0.0 {
        None
    } else {
        Some(PriorUncertainty {
            t_m: p.t_m,
            r_deg: p.r_deg,
        })
    };
    let est = PriorEstimate {
        world_from_left: pose,
        covariance: Covariance::Full(full),
        uncertainty,
        timestamp_ticks: 0,
    };
    est.check()?;
    Ok(est)
}

// ---------------------------------------------------------------------------
// The C functions

/// The name of a failure code (`"CONFIG_PARAM_OUT_OF_RANGE"`, ...; `"OK"`
/// for 0, `"UNKNOWN"` for a value that is not a code): a static
/// NUL-terminated string, never null.
#[no_mangle]
pub extern "C" fn vtsm_failure_name(code: u16) -> *const c_char {
    codes::c_name(code).as_ptr()
}

/// Fill `out` with the parameters of `profile` (a [`VtsmProfile`] value).
///
/// Returns `VTSM_OK`, `FFI_NULL_POINTER` / `FFI_MISALIGNED` for a bad
/// `out`, or `CONFIG_PARAM_OUT_OF_RANGE` for an unknown profile (`out`
/// untouched).
///
/// # Safety
/// `out` is null or points at writable memory for one `VtsmParams`.
#[no_mangle]
pub unsafe extern "C" fn vtsm_params_for_profile(profile: u32, out: *mut VtsmParams) -> u16 {
    if let Err(c) = check_ptr(out) {
        return c.code();
    }
    let Some(width) = profile_width(profile) else {
        return FailureCode::ConfigParamOutOfRange.code();
    };
    let p = VtsmParams::from_params(&Params::for_image_width(width));
    // SAFETY: `out` is non-null and aligned (checked), and the caller
    // guarantees it is writable for one `VtsmParams`.
    unsafe { out.write(p) };
    VTSM_OK
}

/// Bytes of engine storage (aligned to [`VTSM_STORAGE_ALIGN`]) an engine
/// with `params` needs; 0 when `params` is null, misaligned or out of range.
/// Pure: the same answer for the same parameters on every target (the
/// `VTSM_STORAGE_BYTES_*` constants are its values for the profiles).
///
/// # Safety
/// `params` is null or points at a readable `VtsmParams`.
#[no_mangle]
pub unsafe extern "C" fn vtsm_storage_size(params: *const VtsmParams) -> usize {
    if check_ptr(params).is_err() {
        return 0;
    }
    // SAFETY: non-null and aligned (checked); readable by the caller's
    // guarantee; `VtsmParams` is plain data valid for any bits.
    let p = unsafe { params.read() };
    match p.to_params().ok().and_then(|p| layout(&p)) {
        Some(l) => l.total,
        None => 0,
    }
}

/// Check every input and set an engine up in the caller's `storage`
/// (`storage_len` bytes, aligned to [`VTSM_STORAGE_ALIGN`], at least
/// [`vtsm_storage_size`] of the parameters); `*engine_out` is then the
/// handle, which points into `storage`.
///
/// Checked here: the pointers (null, alignment), the storage's size, the
/// parameters, the rig, the prior, that the map and its buffer do not
/// overlap the storage, and the map product itself when it is in memory
/// (parsed and CRC-checked in place). Nothing is copied: the map bytes, the
/// map buffer and the callback context must stay valid, and the storage
/// untouched, until the last [`vtsm_engine_run`] on this handle.
///
/// Returns `VTSM_OK` or the first failure found (`FFI_NULL_POINTER`,
/// `FFI_MISALIGNED`, `CONFIG_CAPACITY_TOO_SMALL`, `CONFIG_PARAM_OUT_OF_RANGE`,
/// `STEREO_RIG_INVALID`, `RELOC_PRIOR_INVALID`, `HAL_PRIOR_INVALID`,
/// `HAL_MAP_TOO_LARGE`, the `MAP_*` codes); on failure `*engine_out` is
/// null (when `engine_out` itself is valid) and the storage holds no engine.
///
/// # Safety
/// Each pointer is null or valid for what it describes: `storage` for
/// `storage_len` writable bytes, `config` for one readable `VtsmConfig`,
/// `engine_out` for one writable pointer, and inside the config `map` for
/// `map_len` readable bytes, `map_buffer` for `map_buffer_len` writable
/// bytes; the callbacks are C functions with the documented signatures.
#[no_mangle]
pub unsafe extern "C" fn vtsm_engine_create(
    storage: *mut c_void,
    storage_len: usize,
    config: *const VtsmConfig,
    engine_out: *mut *mut VtsmEngine,
) -> u16 {
    if let Err(c) = check_ptr(engine_out) {
        return c.code();
    }
    // SAFETY: `engine_out` is non-null and aligned (checked) and writable
    // by the caller's guarantee.
    unsafe { engine_out.write(core::ptr::null_mut()) };
    // SAFETY: forwarded from this function's own contract.
    match unsafe { create(storage.cast::<u8>(), storage_len, config) } {
        Ok(()) => {
            // SAFETY: as above; the handle is the storage's address.
            unsafe { engine_out.write(storage.cast::<VtsmEngine>()) };
            VTSM_OK
        }
        Err(c) => c.code(),
    }
}

/// [`vtsm_engine_create`] with `Result`s.
///
/// # Safety
/// That of [`vtsm_engine_create`].
unsafe fn create(
    storage: *mut u8,
    storage_len: usize,
    config: *const VtsmConfig,
) -> Result<(), FailureCode> {
    check_ptr(config)?;
    if storage.is_null() {
        return Err(FailureCode::FfiNullPointer);
    }
    if !(storage as usize).is_multiple_of(VTSM_STORAGE_ALIGN) {
        return Err(FailureCode::FfiMisaligned);
    }
    // SAFETY: non-null and aligned (checked), readable by the caller's
    // guarantee. Every field is plain data valid for any bits (integers,
    // floats, raw pointers, nullable function pointers).
    let cfg = unsafe { config.read() };
    if cfg.io.read_window.is_none() {
        return Err(FailureCode::FfiNullPointer);
    }
    let params = cfg.params.to_params()?;
    let layout = layout(&params).ok_or(FailureCode::ConfigCapacityTooSmall)?;
    if storage_len < layout.total {
        return Err(FailureCode::ConfigCapacityTooSmall);
    }
    let rig = rig_of(&cfg.rig)?;
    let prior = prior_of(&cfg.prior)?;
    let verify = VerifyChecks {
        repeat_solve: flag(cfg.verify_repeat_solve)?,
        recheck_map: flag(cfg.verify_recheck_map)?,
    };
    let accuracy = accuracy_of(cfg.accuracy_sigma_t_m, cfg.accuracy_sigma_r_deg)?;
    // `Options::final_pairs`' range, checked at creation as the others are.
    let max_pairs = vtsm_core::config::MAX_CORR as u16;
    if cfg.final_pairs != 0 && !(params.n_corr..=max_pairs).contains(&cfg.final_pairs) {
        return Err(FailureCode::ConfigParamOutOfRange);
    }
    let search = Search {
        revisit: !flag(cfg.revisit_off)?,
        near: if flag(cfg.near_on)? {
            Near::ON
        } else {
            Near::OFF
        },
    };
    if cfg.map_len == 0 || u32::try_from(cfg.map_len).is_err() {
        return Err(FailureCode::HalMapTooLarge);
    }
    let at = storage as usize;
    if cfg.map.is_null() {
        if cfg.io.read_map.is_none() || cfg.map_buffer.is_null() {
            return Err(FailureCode::FfiNullPointer);
        }
        if cfg.map_buffer_len < cfg.map_len {
            return Err(FailureCode::HalMapTooLarge);
        }
        if overlaps(
            cfg.map_buffer as usize,
            cfg.map_buffer_len,
            at,
            layout.total,
        ) {
            return Err(FailureCode::ConfigParamOutOfRange);
        }
    } else {
        if overlaps(cfg.map as usize, cfg.map_len, at, layout.total) {
            return Err(FailureCode::ConfigParamOutOfRange);
        }
        // SAFETY: `map` is non-null and readable for `map_len` bytes by the
        // caller's guarantee, and does not overlap the storage this call
        // writes (checked above); the slice lives only in this call.
        let bytes = unsafe { core::slice::from_raw_parts(cfg.map, cfg.map_len) };
        MapView::new_checked(bytes)?;
    }
    let header = Header {
        magic: MAGIC,
        storage_len,
        layout,
        job: Job {
            rig,
            params,
            seed: cfg.seed,
            limits: DriveLimits::UNLIMITED,
            verify,
            accuracy,
            final_pairs: cfg.final_pairs,
            search,
        },
        prior,
        map: cfg.map,
        map_len: cfg.map_len,
        map_buffer: cfg.map_buffer,
        map_buffer_len: cfg.map_buffer_len,
        io: cfg.io,
        state: STATE_IDLE,
    };
    // SAFETY: `storage` is valid for `storage_len >= layout.total` writable
    // bytes (caller's guarantee, size checked), so zeroing the layout stays
    // inside it; every buffer carved from it later holds integers, for which
    // zero bytes are valid values.
    unsafe { core::ptr::write_bytes(storage, 0, layout.total) };
    // SAFETY: the storage is aligned to 16 ≥ align_of::<Header>() and holds
    // at least VTSM_STORAGE_HEADER_BYTES ≥ size_of::<Header>() (const
    // asserts), writable by the caller's guarantee.
    unsafe { storage.cast::<Header>().write(header) };
    Ok(())
}

/// Run one relocalization with the engine set up in its storage by
/// [`vtsm_engine_create`]: [`vtsm_engine_start`] with `limits`,
/// [`vtsm_engine_step`] with `limits->units_per_step` (null `limits`: 64)
/// until `VTSM_STEP_DONE`, and [`vtsm_engine_outcome`] — the same path as a
/// caller that steps the engine itself, so the outcome is the same. May be
/// called again on the same handle (a fresh run with the same inputs).
///
/// Returns `VTSM_OK` when `*outcome` holds the engine's outcome (whose
/// `failure` says whether it succeeded), else the code that stopped the run
/// before the engine could (`FFI_NULL_POINTER`, `FFI_MISALIGNED`,
/// `FFI_BAD_HANDLE`, `FFI_ENGINE_STATE`, `CONFIG_PARAM_OUT_OF_RANGE` for a
/// zero `units_per_step`, a device or map code), which is then also in
/// `outcome->failure` when `outcome` is valid.
///
/// # Safety
/// As [`vtsm_engine_start`]; `outcome` is null or points at one writable
/// `VtsmOutcome`.
#[no_mangle]
pub unsafe extern "C" fn vtsm_engine_run(
    engine: *mut VtsmEngine,
    limits: *const VtsmLimits,
    outcome: *mut VtsmOutcome,
) -> u16 {
    if let Err(c) = check_ptr(outcome) {
        return c.code();
    }
    // SAFETY: forwarded from this function's contract.
    let (out, code) = match unsafe { run(engine.cast::<u8>(), limits) } {
        Ok(o) => (o, VTSM_OK),
        Err(c) => (VtsmOutcome::failed(c.code()), c.code()),
    };
    // SAFETY: `outcome` is non-null and aligned (checked), writable by the
    // caller's guarantee.
    unsafe { outcome.write(out) };
    code
}

/// [`vtsm_engine_run`] with `Result`s.
///
/// # Safety
/// That of [`vtsm_engine_run`].
unsafe fn run(storage: *mut u8, limits: *const VtsmLimits) -> Result<VtsmOutcome, FailureCode> {
    // SAFETY: forwarded from this function's contract.
    let limits = unsafe { start(storage, limits) }?;
    // Bounded: the session counts its steps against `max_steps` and is
    // done at the limit.
    for _ in 0..=limits.max_steps {
        // SAFETY: started above; forwarded from this function's contract.
        if unsafe { step(storage, limits.units_per_step) }? == StepStatus::Done {
            break;
        }
    }
    // SAFETY: as above.
    unsafe { finish(storage) }
}

/// What [`vtsm_engine_step`] says about the relocalization.
#[repr(u32)]
#[allow(non_camel_case_types)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VtsmStepStatus {
    /// More work remains: call [`vtsm_engine_step`] again (next period).
    VTSM_STEP_RUNNING = 1,
    /// The engine has its outcome, or the limits given to
    /// [`vtsm_engine_start`] are reached: call [`vtsm_engine_outcome`].
    VTSM_STEP_DONE = 2,
}

/// Start one relocalization with the engine set up in its storage by
/// [`vtsm_engine_create`], through the HAL runner: latch the pair (when a
/// latch callback is given), check the map product (in place, or read
/// through the callback into the map buffer) and build the engine over the
/// storage's workspace, to be driven by [`vtsm_engine_step`] under `limits`
/// (null: unlimited; its `units_per_step` is used only by
/// [`vtsm_engine_run`]) and ended by [`vtsm_engine_outcome`].
///
/// Returns `VTSM_OK` when the relocalization is under way, else the code
/// that stopped it (`FFI_NULL_POINTER`, `FFI_MISALIGNED`, `FFI_BAD_HANDLE`,
/// `FFI_ENGINE_STATE` when one is already under way on this handle,
/// `CONFIG_PARAM_OUT_OF_RANGE` for a zero `units_per_step`, a device or map
/// code); a device or map failure also sends the failure log through the
/// telemetry callback.
///
/// # Safety
/// `engine` is null or a handle from [`vtsm_engine_create`] whose storage,
/// map bytes, map buffer and callback context are still valid and were not
/// modified by the caller since, and stay so until [`vtsm_engine_outcome`];
/// `limits` is null or points at one readable `VtsmLimits`. Not reentrant
/// on one handle: one call at a time per storage.
#[no_mangle]
pub unsafe extern "C" fn vtsm_engine_start(
    engine: *mut VtsmEngine,
    limits: *const VtsmLimits,
) -> u16 {
    // SAFETY: forwarded from this function's contract.
    match unsafe { start(engine.cast::<u8>(), limits) } {
        Ok(_) => VTSM_OK,
        Err(c) => c.code(),
    }
}

/// Do one bounded piece of the relocalization started by
/// [`vtsm_engine_start`]: at most `max_units` (≥ 1) units of engine work
/// (one unit is one attempt or one RANSAC chunk), with the time from the
/// `now_ticks` callback — what a rate group's `schedIn` or an app's wakeup
/// calls once per period. `*status` is then `VTSM_STEP_RUNNING` or
/// `VTSM_STEP_DONE`. How the work is cut into steps does not change the
/// outcome.
///
/// Returns `VTSM_OK`, or `FFI_NULL_POINTER`, `FFI_MISALIGNED`,
/// `FFI_BAD_HANDLE`, `FFI_ENGINE_STATE` (no relocalization under way: not
/// started, or its outcome already taken), `CONFIG_PARAM_OUT_OF_RANGE` (zero
/// `max_units`); nothing is done then and `*status` is not written.
///
/// # Safety
/// As [`vtsm_engine_start`]; `status` is null or points at one writable
/// `VtsmStepStatus`.
#[no_mangle]
pub unsafe extern "C" fn vtsm_engine_step(
    engine: *mut VtsmEngine,
    max_units: u32,
    status: *mut VtsmStepStatus,
) -> u16 {
    if let Err(c) = check_ptr(status) {
        return c.code();
    }
    // SAFETY: forwarded from this function's contract.
    match unsafe { step(engine.cast::<u8>(), max_units) } {
        Ok(s) => {
            let s = match s {
                StepStatus::Continue => VtsmStepStatus::VTSM_STEP_RUNNING,
                StepStatus::Done => VtsmStepStatus::VTSM_STEP_DONE,
            };
            // SAFETY: non-null and aligned (checked), writable by the
            // caller's guarantee.
            unsafe { status.write(s) };
            VTSM_OK
        }
        Err(c) => c.code(),
    }
}

/// End the relocalization started by [`vtsm_engine_start`] and write its
/// outcome: the engine's own once [`vtsm_engine_step`] said
/// `VTSM_STEP_DONE` for it, else its anytime result
/// (`RELOC_BUDGET_EXHAUSTED`: the caller stopped early). The outcome and the
/// failure log go out through the telemetry callback; the storage, the map
/// bytes, the map buffer and the callback context are the caller's again
/// (until the next [`vtsm_engine_start`]).
///
/// Returns `VTSM_OK` when `*outcome` holds the outcome, else
/// `FFI_NULL_POINTER`, `FFI_MISALIGNED`, `FFI_BAD_HANDLE` or
/// `FFI_ENGINE_STATE` (no relocalization under way), which is then also in
/// `outcome->failure` when `outcome` is valid.
///
/// # Safety
/// As [`vtsm_engine_start`]; `outcome` is null or points at one writable
/// `VtsmOutcome`.
#[no_mangle]
pub unsafe extern "C" fn vtsm_engine_outcome(
    engine: *mut VtsmEngine,
    outcome: *mut VtsmOutcome,
) -> u16 {
    if let Err(c) = check_ptr(outcome) {
        return c.code();
    }
    // SAFETY: forwarded from this function's contract.
    let (out, code) = match unsafe { finish(engine.cast::<u8>()) } {
        Ok(o) => (o, VTSM_OK),
        Err(c) => (VtsmOutcome::failed(c.code()), c.code()),
    };
    // SAFETY: `outcome` is non-null and aligned (checked), writable by the
    // caller's guarantee.
    unsafe { outcome.write(out) };
    code
}

/// Release the engine set up in `engine`'s storage: its state is cleared,
/// so the handle (and any copy of it) is refused from now on with
/// `FFI_BAD_HANDLE`, and the storage, the map bytes, the map buffer and the
/// callback context are the caller's again (a relocalization under way is
/// abandoned without its outcome). Null, misaligned or already released
/// handles are ignored.
///
/// # Safety
/// `engine` is null, or a handle from [`vtsm_engine_create`] whose storage is
/// still valid, or the address of storage of at least
/// `VTSM_STORAGE_HEADER_BYTES` writable bytes; no other call on it is in
/// progress.
#[no_mangle]
pub unsafe extern "C" fn vtsm_engine_release(engine: *mut VtsmEngine) {
    let storage = engine.cast::<u64>();
    if storage.is_null() || !(storage as usize).is_multiple_of(VTSM_STORAGE_ALIGN) {
        return;
    }
    // SAFETY: a handle is the start of a storage of at least
    // VTSM_STORAGE_HEADER_BYTES aligned writable bytes (caller's guarantee);
    // clearing the magic word writes 8 of them.
    unsafe { storage.write(0) };
}

/// The header of the engine in `storage`, checked: non-null, aligned, the
/// magic and the layout.
///
/// # Safety
/// `storage` is null or a handle from [`vtsm_engine_create`] (the start of a
/// storage of at least `VTSM_STORAGE_HEADER_BYTES` aligned bytes) that the
/// caller has not modified since.
unsafe fn open(storage: *mut u8) -> Result<Header, FailureCode> {
    if storage.is_null() {
        return Err(FailureCode::FfiNullPointer);
    }
    if !(storage as usize).is_multiple_of(VTSM_STORAGE_ALIGN) {
        return Err(FailureCode::FfiMisaligned);
    }
    // SAFETY: a handle is the start of a storage of at least
    // VTSM_STORAGE_HEADER_BYTES aligned bytes, so its first 8 bytes are
    // readable; a `u64` is valid for any bits.
    let magic = unsafe { storage.cast::<u64>().read() };
    if magic != MAGIC {
        return Err(FailureCode::FfiBadHandle);
    }
    // SAFETY: the magic says `vtsm_engine_create` wrote a `Header` here, and
    // the caller guarantees the storage was not modified since. A copy is
    // taken so no reference into the storage outlives this line.
    let h = unsafe { storage.cast::<Header>().read() };
    let l = h.layout;
    if h.storage_len < l.total || l.runs_at < l.words_at || l.words_at < VTSM_STORAGE_HEADER_BYTES {
        return Err(FailureCode::FfiBadHandle);
    }
    if h.state != STATE_IDLE && h.state != STATE_RUNNING {
        return Err(FailureCode::FfiBadHandle);
    }
    Ok(h)
}

/// Write the engine's state in its header.
///
/// # Safety
/// `storage` passed [`open`].
unsafe fn set_state(storage: *mut u8, state: u32) {
    // SAFETY: `open` found a `Header` at the start of the aligned storage,
    // which the caller lets this call write.
    unsafe { core::ptr::addr_of_mut!((*storage.cast::<Header>()).state).write(state) };
}

/// The [`Live`] state in the storage's header area.
///
/// # Safety
/// `storage` passed [`open`].
unsafe fn live(storage: *mut u8) -> *mut Live {
    // SAFETY: LIVE_AT + size_of::<Live>() <= VTSM_STORAGE_HEADER_BYTES
    // (const assert), inside the storage; LIVE_AT is a multiple of 16 ≥
    // align_of::<Live>().
    unsafe { storage.add(LIVE_AT).cast::<Live>() }
}

/// [`vtsm_engine_start`] with `Result`s; gives the limits.
///
/// # Safety
/// That of [`vtsm_engine_start`].
unsafe fn start(storage: *mut u8, limits: *const VtsmLimits) -> Result<DriveLimits, FailureCode> {
    // SAFETY: forwarded from this function's contract.
    let h = unsafe { open(storage) }?;
    if h.state != STATE_IDLE {
        return Err(FailureCode::FfiEngineState);
    }
    let limits = if limits.is_null() {
        DriveLimits::UNLIMITED
    } else {
        check_ptr(limits)?;
        // SAFETY: non-null and aligned (checked), readable by the caller's
        // guarantee; plain integers.
        let l = unsafe { limits.read() };
        if l.units_per_step == 0 {
            return Err(FailureCode::ConfigParamOutOfRange);
        }
        DriveLimits {
            units_per_step: l.units_per_step,
            max_steps: l.max_steps,
            budget_ticks: l.budget_ticks,
        }
    };
    let l = h.layout;
    let read_window = h.io.read_window.ok_or(FailureCode::FfiBadHandle)?;
    // SAFETY: the three buffers lie inside the storage after the header
    // area (`VTSM_STORAGE_HEADER_BYTES <= words_at - bytes <= ...`, `total
    // <= storage_len`, checked by `open`), do not overlap one another or the
    // header area (the layout rounds each up to 16 bytes), are aligned for
    // their types (16-byte offsets in 16-byte-aligned storage; `Run` needs
    // ≤ 16), hold integers (valid values for any bits), and the session has
    // exclusive use of them until `vtsm_engine_outcome` by the caller's
    // guarantee.
    let (bytes, words, runs) = unsafe {
        (
            core::slice::from_raw_parts_mut(storage.add(VTSM_STORAGE_HEADER_BYTES), l.ws.bytes),
            core::slice::from_raw_parts_mut(storage.add(l.words_at).cast::<u32>(), l.ws.words),
            core::slice::from_raw_parts_mut(storage.add(l.runs_at).cast::<Run>(), l.ws.runs),
        )
    };
    let ws = Workspace::new(l.ws, bytes, words, runs)?;
    let mapped: Option<&'static [u8]> = if h.map.is_null() {
        None
    } else {
        // SAFETY: checked at create to be readable for `map_len` bytes and
        // outside the storage; the caller keeps it valid and unchanged until
        // `vtsm_engine_outcome`.
        Some(unsafe { core::slice::from_raw_parts(h.map, h.map_len) })
    };
    let map_ram: &'static mut [u8] = if h.map_buffer.is_null() || mapped.is_some() {
        &mut []
    } else {
        // SAFETY: checked at create to be non-null, at least `map_len`
        // bytes and outside the storage; writable and exclusively the
        // session's until `vtsm_engine_outcome` by the caller's guarantee.
        unsafe { core::slice::from_raw_parts_mut(h.map_buffer, h.map_buffer_len) }
    };
    let mut job = h.job;
    job.limits = limits;
    let cfg = RunnerConfig {
        attempts: DEVICE_ATTEMPTS,
        product_attempts: PRODUCT_ATTEMPTS,
        chunk_len: MAP_CHUNK,
        capture_timeout_ticks: u64::MAX,
        image_size: (job.rig.cam().width(), job.rig.cam().height()),
    };
    let runner = Runner::new(
        CFrames {
            io: h.io,
            read_window,
            width: job.rig.cam().width(),
            height: job.rig.cam().height(),
            sequence: 0,
        },
        CClock(h.io),
        CStore {
            mapped,
            len: u32::try_from(h.map_len).map_err(|_| FailureCode::HalMapTooLarge)?,
            io: h.io,
        },
        CPrior(h.prior),
        CTelemetry(h.io),
        cfg,
    );
    // SAFETY: `storage` passed `open`.
    let live = unsafe { live(storage) };
    // SAFETY: `live` is inside the storage's header area, aligned, and not
    // in use (state idle: no session borrows it); the writes put valid
    // values in place without reading the old bytes.
    unsafe {
        core::ptr::addr_of_mut!((*live).runner).write(runner);
        core::ptr::addr_of_mut!((*live).slot).write(None);
    }
    // SAFETY: both fields were just written and stay in place, untouched
    // by anything but the session, until `vtsm_engine_outcome` reads the
    // session out (the caller keeps the storage valid and unmodified).
    let (runner, slot) = unsafe {
        (
            &mut *core::ptr::addr_of_mut!((*live).runner),
            &mut *core::ptr::addr_of_mut!((*live).slot),
        )
    };
    match runner.start(&job, map_ram, slot, InStore, ws, None) {
        Ok(session) => {
            // SAFETY: the session's field of `live`, not borrowed by it.
            unsafe {
                core::ptr::addr_of_mut!((*live).session).write(core::mem::MaybeUninit::new(session))
            };
            // SAFETY: `storage` passed `open`.
            unsafe { set_state(storage, STATE_RUNNING) };
            Ok(limits)
        }
        Err(code) => {
            // SAFETY: the failed start holds no borrow of the runner any more.
            unsafe { (*core::ptr::addr_of_mut!((*live).runner)).send_failure_log() };
            Err(code)
        }
    }
}

/// The session of the relocalization under way in `storage`.
///
/// # Safety
/// That of [`vtsm_engine_step`].
unsafe fn session(storage: *mut u8) -> Result<*mut CSession, FailureCode> {
    // SAFETY: forwarded from this function's contract.
    let h = unsafe { open(storage) }?;
    if h.state != STATE_RUNNING {
        return Err(FailureCode::FfiEngineState);
    }
    // SAFETY: `storage` passed `open`; state running: `start` wrote the
    // session.
    Ok(unsafe { core::ptr::addr_of_mut!((*live(storage)).session) }.cast::<CSession>())
}

/// [`vtsm_engine_step`] with `Result`s.
///
/// # Safety
/// That of [`vtsm_engine_step`].
unsafe fn step(storage: *mut u8, max_units: u32) -> Result<StepStatus, FailureCode> {
    // SAFETY: forwarded from this function's contract.
    let s = unsafe { session(storage) }?;
    if max_units == 0 {
        return Err(FailureCode::ConfigParamOutOfRange);
    }
    // SAFETY: the session `start` wrote, initialised and in place; this call
    // has exclusive use of the storage (not reentrant).
    Ok(unsafe { &mut *s }.step(max_units))
}

/// [`vtsm_engine_outcome`] with `Result`s.
///
/// # Safety
/// That of [`vtsm_engine_outcome`].
unsafe fn finish(storage: *mut u8) -> Result<VtsmOutcome, FailureCode> {
    // SAFETY: forwarded from this function's contract.
    let s = unsafe { session(storage) }?;
    // SAFETY: the session `start` wrote, read out once: the state goes to
    // idle before it is used, so no later call reads it again.
    let s = unsafe { s.read() };
    // SAFETY: `storage` passed `open`.
    unsafe { set_state(storage, STATE_IDLE) };
    let (o, report) = s.finish();
    Ok(VtsmOutcome::from_outcome(&o, &report))
}

// ---------------------------------------------------------------------------
// Bare-metal panic handler

#[cfg(all(
    target_os = "none",
    feature = "panic-handler",
    not(feature = "panic-check")
))]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    extern "C" {
        /// Supplied by the C program: record the fault and reset or halt.
        fn vtsm_panic();
    }
    // SAFETY: a C function without arguments that the program supplies.
    unsafe { vtsm_panic() };
    loop {
        core::hint::spin_loop();
    }
}

/// The panic-freedom check: the C image links only when the linker removed
/// every call to this handler, i.e. no panic path remains in what it uses;
/// otherwise the link fails with `undefined reference to
/// vtsm_panic_path_remains`.
#[cfg(all(target_os = "none", feature = "panic-check"))]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    extern "C" {
        fn vtsm_panic_path_remains() -> !;
    }
    // SAFETY: never defined: a call left in the image fails the link.
    unsafe { vtsm_panic_path_remains() }
}

#[cfg(test)]
mod tests;
