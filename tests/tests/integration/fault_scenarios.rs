//! Fault scenarios on the flight path: each runs one relocalization through
//! the HAL runner on simulated devices (`locate::run`) with one fault, and
//! asserts the exact failure code, that the failure log counts it (the
//! runner's log and its downlinked counters frame for acquisition faults, the
//! outcome's log and the downlinked outcome for engine ends), and that the run
//! stayed within a stated work budget: engine attempts, renders and work
//! units, runner steps, and ticks of the simulated clock, which advances one
//! tick per clock read and a capture timeout per timed-out capture.
//!
//! A map product upset in memory after its check at load is injected between
//! two engine steps through the runner's step hook (`RunOptions::between`,
//! the core's `upset-injection` feature).
//!
//! Every bound is a named constant with the reason for it. The whole binary
//! runs in seconds in the test profile.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::sync::OnceLock;
use vtsm_core::geom::{Pose, Vec3};
use vtsm_core::map::{self, MapView};
use vtsm_core::reloc::{Engine, Options, Outcome};
use vtsm_core::FailureCode;
use vtsm_hal::runner::{DriveLimits, RelocReport, VerifyChecks};
use vtsm_hal::telemetry::{parse_outcome, FrameKind};
use vtsm_sim::devices::FaultConfig;
use vtsm_sim::locate::{self, runner_config, DeviceFaults, DeviceRun, Request, RunOptions};
use vtsm_tests::scene::{render_pair, request, scene};
use vtsm_tests::testkit;
use vtsm_tests::upsets::map_regions;

/// The prior of every scenario unless it is the fault: 12 cm and no rotation
/// off the truth, inside the paper's 20 cm uncertainty.
fn prior() -> Pose {
    scene().prior
}

fn clean_request() -> Request<'static> {
    let s = scene();
    request(&s.map, &s.left, &s.right, prior())
}

/// Device faults with the clock advancing one tick per read, so the runner's
/// elapsed ticks count its steps.
fn faults(camera: FaultConfig, store: FaultConfig) -> DeviceFaults {
    DeviceFaults {
        camera,
        store,
        seed: 3,
        clock_ticks_per_read: 1,
    }
}

fn every(timeout_pct: u8, truncate_pct: u8, corrupt_pct: u8) -> FaultConfig {
    FaultConfig {
        timeout_pct,
        truncate_pct,
        corrupt_pct,
    }
}

fn run(req: &Request<'_>, f: &DeviceFaults) -> DeviceRun {
    locate::run(req, RunOptions::default().faults(*f)).unwrap()
}

/// The work one run did.
#[derive(Debug, Default)]
struct Work {
    attempts: u32,
    renders: u32,
    work_units: u32,
    steps: u32,
    ticks: u64,
}

fn work(r: &DeviceRun) -> Work {
    let (o, rep): (Option<&Outcome>, Option<&RelocReport>) = match &r.result {
        Ok((o, rep)) => (Some(o), Some(rep)),
        Err(_) => (None, None),
    };
    Work {
        attempts: o.map_or(0, |o| o.stats.attempts),
        renders: o.map_or(0, |o| o.stats.pipeline.renders),
        work_units: o.map_or(0, |o| o.stats.work_units),
        steps: rep.map_or(0, |r| r.drive.steps),
        ticks: r.ticks,
    }
}

/// The (code, count) pairs of the downlinked failure-counters frame.
fn downlinked_counters(r: &DeviceRun) -> Vec<(u16, u16)> {
    let f = r
        .telemetry
        .iter()
        .find(|f| f.kind == FrameKind::FailureCounters as u8)
        .expect("a failure-counters frame");
    f.payload
        .chunks_exact(4)
        .map(|c| {
            (
                u16::from_le_bytes([c[0], c[1]]),
                u16::from_le_bytes([c[2], c[3]]),
            )
        })
        .collect()
}

/// The runner stopped before the engine with `code`: the runner's log counts
/// it `times`, the downlinked counters say the same, and no outcome was sent.
fn assert_refused(r: &DeviceRun, code: FailureCode, times: u16) {
    assert_eq!(r.result.as_ref().err(), Some(&code));
    assert_eq!(r.log.count(code), times, "{code:?} in the runner's log");
    assert!(downlinked_counters(r).contains(&(code.code(), times)));
    assert!(r
        .telemetry
        .iter()
        .all(|f| f.kind != FrameKind::Outcome as u8));
}

/// The engine ended with `code`: the outcome's log counts it and the
/// downlinked outcome carries it.
fn assert_outcome(r: &DeviceRun, code: FailureCode) -> &Outcome {
    let (o, _) = r.result.as_ref().expect("an outcome");
    assert_eq!(o.failure, Some(code));
    assert!(o.log.count(code) >= 1, "{code:?} in the outcome's log");
    let sent = r
        .telemetry
        .iter()
        .find(|f| f.kind == FrameKind::Outcome as u8)
        .and_then(|f| parse_outcome(&f.payload))
        .expect("a downlinked outcome");
    assert_eq!(sent.failure, code.code());
    assert_eq!(sent.attempts, o.stats.attempts);
    o
}

// ---- work budgets ------------------------------------------------------------

/// Capture attempts of the desktop runner (`runner_config`).
fn capture_attempts() -> u16 {
    u16::from(runner_config(640, 480).attempts)
}

/// Ticks of a run that never reaches the engine: a handful of clock reads
/// (start, prior, capture) at one tick each, plus one capture timeout
/// (1 000 ticks) per timed-out capture attempt (3).
const ACQUISITION_TICKS: u64 = 3 * 1_000 + 16;

/// Runner steps of a run the engine refuses before any work (preflight): the
/// first step returns the finished outcome.
const PREFLIGHT_STEPS: u32 = 1;

/// Ticks of a preflight refusal: the acquisition reads, the step and the
/// final read, one tick each.
const PREFLIGHT_TICKS: u64 = 16;

/// Attempts after which a frame without any correspondence stops
/// (`Options::no_evidence_attempts` of the test profile: max(4·N_corr, 200)).
fn no_evidence_attempts() -> u32 {
    Options::for_params(&testkit::test_params()).no_evidence_attempts()
}

/// Renders of one attempt at most: the left template, and the right one once
/// a left match is accepted.
const RENDERS_PER_ATTEMPT: u32 = 2;

/// Runner steps of a run of `attempts` units at `DriveLimits::UNLIMITED`'s 64
/// units per step, plus the step that returns the outcome.
fn steps_for(units: u32) -> u32 {
    units.div_ceil(DriveLimits::UNLIMITED.units_per_step) + 1
}

// ---- device faults -------------------------------------------------------------

/// A camera that always times out: every capture attempt is logged as a
/// timeout, then the runner gives up; no engine work, and the clock shows the
/// three timeouts.
///
/// Verifies: VTSM-HAL-025
#[test]
fn camera_timeout() {
    let r = run(
        &clean_request(),
        &faults(every(100, 0, 0), FaultConfig::NONE),
    );
    let w = work(&r);
    println!("camera timeout: {:?} {w:?}", r.result.as_ref().err());
    assert_refused(&r, FailureCode::HalCameraRetriesExhausted, 1);
    assert_eq!(
        r.log.count(FailureCode::HalCameraTimeout),
        capture_attempts()
    );
    assert!(
        w.ticks >= 3 * 1_000 && w.ticks <= ACQUISITION_TICKS,
        "{w:?}"
    );
    assert_eq!((w.attempts, w.renders), (0, 0));
}

/// A camera that delivers short frames: each is logged and discarded, no
/// engine work; time does not pass beyond the runner's reads.
///
/// Verifies: VTSM-HAL-025
#[test]
fn truncated_frame() {
    let r = run(
        &clean_request(),
        &faults(every(0, 100, 0), FaultConfig::NONE),
    );
    let w = work(&r);
    println!("truncated frame: {:?} {w:?}", r.result.as_ref().err());
    assert_refused(&r, FailureCode::HalCameraRetriesExhausted, 1);
    assert_eq!(
        r.log.count(FailureCode::HalCameraFrameTruncated),
        capture_attempts()
    );
    assert!(w.ticks <= ACQUISITION_TICKS - 3 * 1_000, "{w:?}");
    assert_eq!((w.attempts, w.renders), (0, 0));
}

/// Storage that damages every chunk it reads, silently: each whole-product
/// pass fails its check, the runner re-reads the product `product_attempts`
/// times and gives up with the map check's code.
///
/// Verifies: VTSM-HAL-025, VTSM-MAP-003
#[test]
fn corrupted_map_read() {
    let r = run(
        &clean_request(),
        &faults(FaultConfig::NONE, every(0, 0, 100)),
    );
    let w = work(&r);
    let code = *r.result.as_ref().unwrap_err();
    println!("corrupted map read: {code:?} {w:?}");
    let passes = u16::from(runner_config(640, 480).product_attempts);
    // Seed 3 damages a section body on both passes: a CRC mismatch.
    assert_eq!(code, FailureCode::MapCrcMismatch);
    assert_refused(&r, code, passes);
    assert!(w.ticks <= ACQUISITION_TICKS - 3 * 1_000, "{w:?}");
}

/// Storage that delivers every chunk short: each chunk read is retried
/// `attempts` times and then the read is given up.
///
/// Verifies: VTSM-HAL-025
#[test]
fn truncated_map_read() {
    let r = run(
        &clean_request(),
        &faults(FaultConfig::NONE, every(0, 100, 0)),
    );
    let w = work(&r);
    println!("truncated map read: {:?} {w:?}", r.result.as_ref().err());
    assert_refused(&r, FailureCode::HalStorageRetriesExhausted, 1);
    assert_eq!(r.log.count(FailureCode::HalStorageRead), capture_attempts());
    assert!(w.ticks <= ACQUISITION_TICKS - 3 * 1_000, "{w:?}");
}

/// A product that was stored short (a transfer cut off before the end): it
/// reads without a device fault and fails its check as truncated, on every
/// re-read.
///
/// Verifies: VTSM-HAL-025, VTSM-MAP-002
#[test]
fn truncated_map_product() {
    let s = scene();
    let short = &s.map[..s.map.len() / 2];
    let r = run(
        &request(short, &s.left, &s.right, prior()),
        &faults(FaultConfig::NONE, FaultConfig::NONE),
    );
    let w = work(&r);
    println!("truncated map product: {:?} {w:?}", r.result.as_ref().err());
    let passes = u16::from(runner_config(640, 480).product_attempts);
    assert_refused(&r, FailureCode::MapTruncated, passes);
    assert!(w.ticks <= ACQUISITION_TICKS - 3 * 1_000, "{w:?}");
}

// ---- hopeless frames -------------------------------------------------------------

/// Run `left`/`right` from `prior` on fault-free devices.
fn run_frames(left: &[u8], right: &[u8], prior: Pose) -> DeviceRun {
    let s = scene();
    run(
        &request(&s.map, left, right, prior),
        &faults(FaultConfig::NONE, FaultConfig::NONE),
    )
}

/// The preflight refused the inputs: the code, no engine work, one step.
fn assert_preflight_refusal(r: &DeviceRun, code: FailureCode) {
    let o = assert_outcome(r, code);
    assert_eq!(o.log.count(code), 1);
    let w = work(r);
    println!("{code:?}: {w:?}");
    assert_eq!((w.attempts, w.renders, w.work_units), (0, 0, 0));
    assert_eq!(w.steps, PREFLIGHT_STEPS);
    assert!(w.ticks <= PREFLIGHT_TICKS, "{w:?}");
}

/// An all-black left image (lens cap, no exposure).
///
/// Verifies: VTSM-HAL-025, VTSM-RELOC-021
#[test]
fn all_black_frame() {
    let s = scene();
    let black = vec![0u8; s.left.len()];
    let r = run_frames(&black, &s.right, prior());
    assert_preflight_refusal(&r, FailureCode::RelocFrameNoTexture);
}

/// A saturated right image (sun in the lens, exposure runaway).
///
/// Verifies: VTSM-HAL-025, VTSM-RELOC-021
#[test]
fn saturated_frame() {
    let s = scene();
    let white = vec![255u8; s.right.len()];
    let r = run_frames(&s.left, &white, prior());
    assert_preflight_refusal(&r, FailureCode::RelocFrameNoTexture);
}

/// The same sensor delivered twice (left = right).
///
/// Verifies: VTSM-HAL-025, VTSM-RELOC-021
#[test]
fn left_equals_right() {
    let s = scene();
    let r = run_frames(&s.left, &s.left, prior());
    assert_preflight_refusal(&r, FailureCode::RelocStereoIdentical);
}

/// Pure noise in both images: textured, so the preflight passes it; no
/// template ever matches and the engine stops after the no-evidence cap.
///
/// Verifies: VTSM-HAL-025, VTSM-RELOC-021
#[test]
fn pure_noise_frames() {
    let s = scene();
    let n = s.left.len();
    let mut rng = vtsm_core::rng::Rng::new(11);
    let mut noise = || -> Vec<u8> { (0..n).map(|_| rng.below(256) as u8).collect() };
    let (l, r) = (noise(), noise());
    let run = run_frames(&l, &r, prior());
    let o = assert_outcome(&run, FailureCode::RelocNoEvidence);
    let w = work(&run);
    println!("noise: {w:?}");
    let cap = no_evidence_attempts();
    assert_eq!(o.log.count(FailureCode::RelocNoEvidence), 1);
    assert_eq!(o.stats.correspondences, 0);
    assert_eq!(w.attempts, cap);
    assert_eq!(w.work_units, cap);
    assert!(w.renders <= RENDERS_PER_ATTEMPT * cap, "{w:?}");
    assert!(w.steps <= steps_for(cap), "{w:?}");
    assert!(
        w.ticks <= PREFLIGHT_TICKS + u64::from(steps_for(cap)),
        "{w:?}"
    );
}

/// Rounds of a run that never updates the pose: the first and one per Reseed
/// (Stall needs a success first), each ending at the attempt cap or after one
/// solve of at most ⌈ransac_iter / 64⌉ chunks.
/// A frame from a different place: the pair is rendered 3.9 m further along
/// the depot and 2.2 m to the side, the prior is where the rover should be.
///
/// Templates of the prior's place now and then match something in the other
/// place's texture, so correspondences trickle in (no `RELOC_NO_EVIDENCE`),
/// but they never agree on a pose: the first round ends without a consensus
/// and the run stops with `RELOC_NO_CONSENSUS` (VTSM-RELOC-036), within one
/// round of the test profile's defaults. (Before that rule it went through
/// every Reseed round: 1 868 attempts, 3 542 renders, 1 884 work units.)
///
/// Verifies: VTSM-HAL-025, VTSM-RELOC-036
#[test]
fn frame_from_a_different_place() {
    let s = scene();
    let view = MapView::new_checked(&s.map).unwrap();
    let elsewhere = testkit::camera_pose(4.5, -2.0);
    let (l, r) = render_pair(&view, &elsewhere);
    let req = request(&s.map, &l, &r, prior());
    let run = run(&req, &faults(FaultConfig::NONE, FaultConfig::NONE));
    let w = work(&run);
    let o = assert_outcome(&run, FailureCode::RelocNoConsensus);
    println!(
        "different place: {:?} {w:?}; {} correspondences, {} solves, inliers {}",
        o.failure, o.stats.correspondences, o.stats.solves, o.quality.inliers
    );
    assert_eq!(o.stats.successes, 0, "no pose update from another place");
    let p = req.params;
    let rounds = u32::from(vtsm_core::reloc::Options::for_params(&p).first_fix_rounds());
    assert_eq!(o.stats.rounds, rounds);
    let max_attempts = rounds * p.attempts_per_iter;
    let max_units = max_attempts + rounds * (1 + u32::from(p.ransac_iter.div_ceil(64)));
    assert!(w.attempts <= max_attempts, "{w:?}");
    assert!(w.work_units <= max_units, "{w:?}");
    assert!(w.renders <= RENDERS_PER_ATTEMPT * w.attempts, "{w:?}");
    assert!(w.steps <= steps_for(max_units), "{w:?}");
    assert!(
        w.ticks <= PREFLIGHT_TICKS + u64::from(steps_for(max_units)),
        "{w:?}"
    );
}

// ---- bad priors -------------------------------------------------------------------

/// A prior with a NaN position: the runner's prior check refuses it before
/// any capture.
///
/// Verifies: VTSM-HAL-025
#[test]
fn nan_prior() {
    let s = scene();
    let nan = Pose::new(s.truth.rotation(), Vec3::new(f32::NAN, 0.2, 1.2));
    let r = run_frames(&s.left, &s.right, nan);
    let w = work(&r);
    println!("NaN prior: {:?} {w:?}", r.result.as_ref().err());
    assert_refused(&r, FailureCode::HalPriorInvalid, 1);
    assert!(w.ticks <= ACQUISITION_TICKS - 3 * 1_000, "{w:?}");
}

/// A prior 100 m away from the depot: no mask vertex is in view from it.
///
/// Verifies: VTSM-HAL-025, VTSM-RELOC-021
#[test]
fn prior_100_m_away() {
    let s = scene();
    let p = prior();
    let far = Pose::new(p.rotation(), p.translation() + Vec3::new(100.0, 0.0, 0.0));
    let r = run_frames(&s.left, &s.right, far);
    assert_preflight_refusal(&r, FailureCode::RelocNoVisibleMaskVertex);
}

/// A prior facing the sky (turned half a turn about the camera's x axis).
///
/// Verifies: VTSM-HAL-025, VTSM-RELOC-021
#[test]
fn prior_facing_the_sky() {
    let s = scene();
    let p = prior();
    let sky = Pose::new(
        p.rotation()
            * vtsm_core::nalgebra::UnitQuaternion::from_axis_angle(
                &Vec3::x_axis(),
                core::f32::consts::PI,
            ),
        p.translation(),
    );
    let r = run_frames(&s.left, &s.right, sky);
    assert_preflight_refusal(&r, FailureCode::RelocNoVisibleMaskVertex);
}

// ---- bad maps ------------------------------------------------------------------------

/// A map whose sampling mask M̂ is empty: it passes its checks (a valid
/// product), and the engine's constructor refuses it before any work.
///
/// Verifies: VTSM-HAL-025
#[test]
fn empty_mask() {
    static MAP: OnceLock<Vec<u8>> = OnceLock::new();
    let map = MAP.get_or_init(|| testkit::build_map_with_mask(1, |_| false));
    assert_eq!(MapView::new_checked(map).unwrap().mask_vertex_count(), 0);
    let s = scene();
    let r = run(
        &request(map, &s.left, &s.right, prior()),
        &faults(FaultConfig::NONE, FaultConfig::NONE),
    );
    let w = work(&r);
    println!("empty mask: {:?} {w:?}", r.result.as_ref().err());
    assert_refused(&r, FailureCode::RelocNoVisibleMaskVertex, 1);
    assert!(w.ticks <= ACQUISITION_TICKS - 3 * 1_000, "{w:?}");
}

/// A map of degenerate triangles: the map builder refuses it
/// (`MAP_NO_SURFACE`), and a hand-made product carrying one (every triangle
/// collapsed onto its first vertex, CRCs resealed) is refused by the
/// runner's map check on every re-read.
///
/// Verifies: VTSM-HAL-025, VTSM-MAP-008
#[test]
fn map_of_degenerate_triangles() {
    // The builder: three collinear vertices make a triangle without area.
    let tex = [128u8; 16];
    let src = map::MapSource {
        vertices: &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
        triangles: &[[0, 1, 2]],
        uvs: &[[[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]]],
        mask: &[true],
        texture: vtsm_core::image::GrayView::new(&tex, 4, 4, 4).unwrap(),
        tile_size_m: 1.0,
        origin: [0.0; 3],
        vertex_scores: None,
    };
    assert_eq!(
        map::encoded_len(&src).err(),
        Some(FailureCode::MapNoSurface)
    );
    let mut out = vec![0u8; 4096];
    assert_eq!(
        map::encode(&src, &mut out).err(),
        Some(FailureCode::MapNoSurface)
    );

    // A hand-made product.
    let s = scene();
    let mut bytes = s.map.clone();
    let view = MapView::new_checked(&s.map).unwrap();
    let n = view.triangle_count() as usize;
    let tri_off = triangles_offset(&bytes);
    for i in 0..n {
        let at = tri_off + i * map::TRIANGLE_BYTES;
        let first: [u8; 4] = bytes[at..at + 4].try_into().unwrap();
        bytes[at + 4..at + 8].copy_from_slice(&first);
        bytes[at + 8..at + 12].copy_from_slice(&first);
    }
    map::reseal(&mut bytes).unwrap();
    assert_eq!(
        MapView::new_checked(&bytes).err(),
        Some(FailureCode::MapNoSurface)
    );
    let r = run(
        &request(&bytes, &s.left, &s.right, prior()),
        &faults(FaultConfig::NONE, FaultConfig::NONE),
    );
    let w = work(&r);
    println!("degenerate map: {:?} {w:?}", r.result.as_ref().err());
    let passes = u16::from(runner_config(640, 480).product_attempts);
    assert_refused(&r, FailureCode::MapNoSurface, passes);
    assert!(w.ticks <= ACQUISITION_TICKS - 3 * 1_000, "{w:?}");
}

// ---- upsets after load ------------------------------------------------------------

/// The scene's map product with one bit of its texture flipped, seen through
/// the layout of the product checked at load: what the engine reads once the
/// memory holding the map has been upset after that check.
fn changed_map() -> &'static MapView<'static> {
    static BYTES: OnceLock<Vec<u8>> = OnceLock::new();
    static VIEW: OnceLock<MapView<'static>> = OnceLock::new();
    VIEW.get_or_init(|| {
        let s = scene();
        let bytes = BYTES.get_or_init(|| {
            let (_, start, end) = map_regions(&s.map)
                .into_iter()
                .find(|r| r.0 == "texture")
                .unwrap();
            let mut b = s.map.clone();
            b[(start + end) / 2] ^= 0x80;
            b
        });
        let view = MapView::new_checked(&s.map).unwrap();
        assert!(
            MapView::new_checked(bytes).is_err(),
            "the flip breaks a CRC"
        );
        view.with_changed_bytes(bytes).unwrap()
    })
}

/// Run `req` on fault-free devices with the map upset before the second
/// engine step (after the load check and some engine work); the hook's calls.
fn run_with_map_upset(req: &Request<'_>) -> (DeviceRun, u32) {
    let mut calls = 0u32;
    let mut upset = |engine: &mut Engine<'_, '_>, _now: u64| {
        calls += 1;
        if calls == 2 {
            engine.upset_map(changed_map());
        }
    };
    let opts = RunOptions::default()
        .faults(faults(FaultConfig::NONE, FaultConfig::NONE))
        .between(&mut upset);
    let r = locate::run(req, opts).unwrap();
    (r, calls)
}

/// The map product changes in memory after the runner checked it at load
/// (one texture bit, between two engine steps). With the runner's map
/// re-check on (`RunnerConfig::verify`), the run ends in `RELOC_MAP_CHANGED`
/// instead of a success, with the work of the same run without the check:
/// the re-check is part of the last unit. Without it the change goes
/// unnoticed and the same pose is reported as a success; on an unchanged map
/// the re-check passes.
///
/// Verifies: VTSM-HAL-025, VTSM-RELOC-033
#[test]
fn map_changed_after_load() {
    let recheck = clean_request().with_verify(VerifyChecks {
        repeat_solve: false,
        recheck_map: true,
    });
    let (checked, calls) = run_with_map_upset(&recheck);
    let w = work(&checked);
    println!("map changed after load: {w:?}, {calls} steps");
    // The hook runs before every step and flips the bit at its second call:
    // after the first step and before the second, so at least two steps ran.
    assert!(calls >= 2, "the upset fell between two steps of the run");
    let o = assert_outcome(&checked, FailureCode::RelocMapChanged);
    assert_eq!(o.log.count(FailureCode::RelocMapChanged), 1);
    // The runner had accepted the product on its first read.
    let (_, rep) = checked.result.as_ref().unwrap();
    assert_eq!(rep.map_read.product_attempts, 1);
    assert_eq!(checked.log.count(FailureCode::MapCrcMismatch), 0);

    let (unchecked, _) = run_with_map_upset(&clean_request());
    let (u, _) = unchecked.result.as_ref().unwrap();
    assert_eq!(u.failure, None, "without the re-check nothing notices");
    assert_eq!(u.pose.t().map(f32::to_bits), o.pose.t().map(f32::to_bits));
    let wu = work(&unchecked);
    assert_eq!((w.attempts, w.work_units), (wu.attempts, wu.work_units));
    assert_eq!(w.steps, wu.steps);

    let clean = run(&recheck, &faults(FaultConfig::NONE, FaultConfig::NONE));
    let (c, _) = clean.result.as_ref().unwrap();
    assert_eq!(c.failure, None, "the re-check passes an unchanged map");
}

/// Offset of the triangle section: the third (offset, length, CRC) entry of
/// the header's section table at byte 76.
fn triangles_offset(bytes: &[u8]) -> usize {
    let e = 76 + 12 * 2;
    u32::from_le_bytes(bytes[e..e + 4].try_into().unwrap()) as usize
}
