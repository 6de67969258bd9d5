// The flight-profile relocalization: built only with `VTSM_FLIGHT_BUNDLE=DIR`
// (a bundle written by `cargo run -p vtsm-tests --bin flight_bundle`). The
// map product and the stereo pair are linked into the image as read-only data
// (the map store's flash and the camera's frame memory). Neither is copied
// whole: `Runner::run` with `InStore` checks the map product in place in
// the memory-mapped flash (`MapStore::mapped`) and has the engine read each
// search window from the camera's memory (`FrameStore`) into its workspace.
// The engine's storage is a static, so the static RAM figure of the image
// plus the stack high-water mark is the run's whole RAM.

use crate::workload_mod::devices::{CountingTelemetry, FixedPrior, FlashStore, FrameCamera, TickClock};
use crate::workload_mod::{fold_outcome, Digest};
use core::ptr::addr_of_mut;
use vtsm_core::config::Params;
use vtsm_core::geom::{Camera, Pose, StereoRig, Vec3};
use vtsm_core::ncc::Search;
use vtsm_core::reloc::{MatchPolicy, Storage, WorkspaceSizes};
use vtsm_hal::runner::{DriveLimits, InStore, Job, Runner, RunnerConfig, VerifyChecks};

pub mod scene {
    include!(concat!(env!("VTSM_FLIGHT_DIR"), "/scene.rs"));
}
use scene::{HEIGHT, MAP_LEN, WIDTH};

const N: usize = WIDTH * HEIGHT;
/// The flight profile: the core's parameters for this image width.
const PARAMS: Params = Params::for_image_width(WIDTH as u32);
const WS: WorkspaceSizes = WorkspaceSizes::for_params(&PARAMS, Search::CoarseToFine);

#[cfg_attr(target_arch = "arm", link_section = ".flight_flash")]
static MAP_FLASH: [u8; MAP_LEN] = *include_bytes!(concat!(env!("VTSM_FLIGHT_DIR"), "/map.vmap"));
static LEFT_FRAME: [u8; N] = *include_bytes!(concat!(env!("VTSM_FLIGHT_DIR"), "/left.gray"));
static RIGHT_FRAME: [u8; N] = *include_bytes!(concat!(env!("VTSM_FLIGHT_DIR"), "/right.gray"));

static mut STORAGE: Storage<{ WS.bytes }, { WS.words }, { WS.runs }> = Storage::new();

/// What the flight run reports.
pub struct FlightSummary {
    pub digest: u64,
    pub failure: u16,
    pub initial_error_um: u32,
    pub final_error_um: u32,
    pub attempts: u32,
    pub steps: u32,
    pub engine_ticks: u64,
    pub workspace_bytes: usize,
}

fn pose(p: ([f32; 3], [f32; 4])) -> Pose {
    let (t, q) = p;
    // The bundle holds the unit quaternion's own bits: no renormalization,
    // which could move the last bit and with it the engine's draws.
    let q = nalgebra::UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]));
    Pose::new(q, Vec3::new(t[0], t[1], t[2]))
}

/// Run the bundled relocalization through the runner. Called once.
pub fn run(clock: &dyn Fn() -> u64) -> FlightSummary {
    let fail = |code: u16| FlightSummary { digest: 0, failure: code, initial_error_um: 0, final_error_um: u32::MAX, attempts: 0, steps: 0, engine_ticks: 0, workspace_bytes: 0 };
    if WorkspaceSizes::for_params(&PARAMS, MatchPolicy::for_params(&PARAMS).search) != WS {
        return fail(1);
    }
    let (fx, fy, cx, cy) = scene::CAMERA;
    let Ok(cam) = Camera::new(fx, fy, cx, cy, WIDTH as u32, HEIGHT as u32) else { return fail(2) };
    let Ok(rig) = StereoRig::new(cam, scene::BASELINE_M) else { return fail(3) };
    let (prior, truth) = (pose(scene::PRIOR), pose(scene::TRUTH));
    let mut runner = Runner::new(
        FrameCamera { left: &LEFT_FRAME, right: &RIGHT_FRAME, width: WIDTH as u32, height: HEIGHT as u32, sequence: 0, clock },
        TickClock(clock),
        FlashStore(&MAP_FLASH),
        FixedPrior(prior),
        CountingTelemetry::default(),
        RunnerConfig { attempts: 3, product_attempts: 2, chunk_len: 1 << 16, capture_timeout_ticks: u64::MAX, image_size: (WIDTH as u32, HEIGHT as u32) },
    );
    // SAFETY: `run` is called once, from the single thread of the image, and
    // this static is not touched anywhere else: the reference is unique.
    let storage = unsafe { &mut *addr_of_mut!(STORAGE) };
    let Ok(ws) = storage.workspace(WS) else { return fail(4) };
    let limits = DriveLimits { units_per_step: 16, max_steps: u32::MAX, budget_ticks: u64::MAX };
    let job = Job { rig, params: PARAMS, seed: scene::SEED, limits, verify: VerifyChecks::OFF, accuracy: None, final_pairs: 0, search: vtsm_core::reloc::Search::DEFAULT };
    let (out, report) = match runner.run(&job, &mut [], InStore, ws, None) {
        Ok(r) => r,
        Err(e) => return fail(e.code()),
    };
    let mut d = Digest::new();
    fold_outcome(&mut d, &out);
    let (e0, _) = prior.error_to(&truth);
    let (e1, _) = out.pose.error_to(&truth);
    FlightSummary {
        digest: d.0,
        failure: out.failure.map_or(0, |c| c.code()),
        initial_error_um: (e0 * 1e6) as u32,
        final_error_um: (e1 * 1e6) as u32,
        attempts: out.stats.attempts,
        steps: report.drive.steps,
        engine_ticks: report.drive.elapsed_ticks,
        workspace_bytes: WS.total_bytes(),
    }
}
