//! The flight path end to end: the HAL runner acquires a simulated stereo pair,
//! prior and map product through the devices, builds the engine with the core's
//! one constructor and drives it. Device faults must end in their failure codes
//! with bounded work, and the outcome must not depend on the step granularity.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use vtsm_core::geom::{Pose, Vec3};
use vtsm_core::reloc::Outcome;
use vtsm_core::FailureCode;
use vtsm_hal::runner::{DriveLimits, VerifyChecks};
use vtsm_hal::telemetry::{parse_outcome, FrameKind};
use vtsm_sim::devices::FaultConfig;
use vtsm_sim::locate::{self, DeviceFaults, DeviceRun, Request, RunOptions};
use vtsm_tests::scene::{scene, RELOC_SEED};
use vtsm_tests::testkit;

fn request(map: &[u8]) -> Request<'_> {
    scene()
        .request(map, RELOC_SEED)
        .with_params(vtsm_core::config::Params {
            // Short failing runs are not under test here: only how they end.
            attempts_per_iter: 300,
            ..testkit::test_params()
        })
}

fn run(faults: DeviceFaults, limits: DriveLimits) -> DeviceRun {
    locate::run(
        &request(&scene().map),
        RunOptions::default().faults(faults).limits(limits),
    )
    .unwrap()
}

fn all(timeout_pct: u8, truncate_pct: u8, corrupt_pct: u8) -> FaultConfig {
    FaultConfig {
        timeout_pct,
        truncate_pct,
        corrupt_pct,
    }
}

fn bits(o: &Outcome) -> (Vec<u32>, u16, u32, u32) {
    let pose = o
        .pose
        .t()
        .into_iter()
        .chain(o.pose.q())
        .map(f32::to_bits)
        .collect();
    (
        pose,
        o.quality.inliers,
        o.stats.attempts,
        o.stats.work_units,
    )
}

/// Verifies: VTSM-HAL-024
#[test]
fn runner_relocalizes_and_step_granularity_does_not_change_the_outcome() {
    let limits = |units| DriveLimits {
        units_per_step: units,
        ..DriveLimits::UNLIMITED
    };
    let whole = run(DeviceFaults::default(), limits(u32::MAX));
    let (o, rep) = whole.result.as_ref().unwrap();
    let (et, _) = o.pose.error_to(&scene().truth);
    println!(
        "runner: {:?} err {et:.4} m, {} steps",
        o.failure, rep.drive.steps
    );
    assert_eq!(o.failure, None);
    assert!(et < 0.05, "error {et} m");
    assert_eq!(rep.capture.attempts, 1);
    assert!(rep.drive.done);
    // The outcome went down as telemetry, bit for bit.
    let sent = whole
        .telemetry
        .iter()
        .find(|f| f.kind == FrameKind::Outcome as u8)
        .and_then(|f| parse_outcome(&f.payload))
        .unwrap();
    assert_eq!(sent.attempts, o.stats.attempts);
    assert_eq!(sent.t.map(f32::to_bits), o.pose.t().map(f32::to_bits));
    for units in [1, 7] {
        let stepped = run(DeviceFaults::default(), limits(units));
        let (s, srep) = stepped.result.as_ref().unwrap();
        assert_eq!(bits(s), bits(o), "{units} units per step");
        assert_eq!(s.stats, o.stats);
        assert_eq!(s.quality, o.quality);
        assert!(srep.drive.steps >= o.stats.work_units / units);
    }
}

/// The runner builds the engine with the upset checks of its configuration
/// (`RunnerConfig::verify`): with both on, the clean run repeats its final
/// solve in work units of its own (the two solves agreeing), re-checks the
/// map, and returns the pose of the run without them after the same search.
///
/// Verifies: VTSM-HAL-024, VTSM-RELOC-032
#[test]
fn runner_config_turns_the_upset_checks_on() {
    let plain = run(DeviceFaults::default(), DriveLimits::UNLIMITED);
    let req = request(&scene().map).with_verify(VerifyChecks::ALL);
    let checked = locate::run(&req, RunOptions::default()).unwrap();
    let (p, _) = plain.result.as_ref().unwrap();
    let (c, _) = checked.result.as_ref().unwrap();
    println!(
        "upset checks: {} of {} work units, solves {:?} apart",
        c.stats.verify_units, c.stats.work_units, c.quality.verify_diff
    );
    assert_eq!((p.stats.verify_units, p.quality.verify_diff), (0, None));
    assert_eq!(c.failure, None);
    assert!(c.stats.verify_units >= 1);
    assert_eq!(
        c.stats.work_units,
        p.stats.work_units + c.stats.verify_units
    );
    assert_eq!(c.stats.attempts, p.stats.attempts);
    assert_eq!(c.pose.t().map(f32::to_bits), p.pose.t().map(f32::to_bits));
    assert_eq!(c.pose.q().map(f32::to_bits), p.pose.q().map(f32::to_bits));
    let (dt, dr) = c.quality.verify_diff.unwrap();
    assert!(dt < 0.01 && dr < 0.2f32.to_radians(), "{dt} m {dr} rad");
}

/// Verifies: VTSM-HAL-024
#[test]
fn camera_timeouts_and_truncated_frames_end_in_their_codes_with_bounded_work() {
    for (faults, per_attempt) in [
        (all(100, 0, 0), FailureCode::HalCameraTimeout),
        (all(0, 100, 0), FailureCode::HalCameraFrameTruncated),
    ] {
        let r = run(
            DeviceFaults {
                camera: faults,
                ..DeviceFaults::default()
            },
            DriveLimits::UNLIMITED,
        );
        assert_eq!(r.result.err(), Some(FailureCode::HalCameraRetriesExhausted));
        // One logged fault per capture attempt, then the cap; nothing else ran.
        let attempts = u16::from(vtsm_sim::locate::runner_config(640, 480).attempts);
        assert_eq!(r.log.count(per_attempt), attempts);
        assert_eq!(r.log.count(FailureCode::HalCameraRetriesExhausted), 1);
        assert!(r
            .telemetry
            .iter()
            .all(|f| f.kind != FrameKind::Outcome as u8));
        assert!(r
            .telemetry
            .iter()
            .any(|f| f.kind == FrameKind::FailureCounters as u8));
    }
}

/// Verifies: VTSM-HAL-024
#[test]
fn corrupted_map_reads_end_in_the_map_check_code_after_bounded_rereads() {
    let r = run(
        DeviceFaults {
            store: all(0, 0, 100),
            seed: 3,
            ..DeviceFaults::default()
        },
        DriveLimits::UNLIMITED,
    );
    let code = r.result.err().unwrap();
    println!("corrupted map: {code:?}");
    assert_eq!(
        code.code() >> 8,
        FailureCode::MapCrcMismatch.code() >> 8,
        "a map-product code"
    );
    let passes = u16::from(vtsm_sim::locate::runner_config(640, 480).product_attempts);
    assert!(r.log.count(code) >= 1 && r.log.count(code) <= passes);
    // A product that is only timing out is retried per chunk, then given up.
    let r = run(
        DeviceFaults {
            store: all(100, 0, 0),
            ..DeviceFaults::default()
        },
        DriveLimits::UNLIMITED,
    );
    assert_eq!(
        r.result.err(),
        Some(FailureCode::HalStorageRetriesExhausted)
    );
}

/// Verifies: VTSM-HAL-024
#[test]
fn a_spent_step_budget_returns_the_anytime_result() {
    let r = run(
        DeviceFaults::default(),
        DriveLimits {
            units_per_step: 5,
            max_steps: 20,
            budget_ticks: u64::MAX,
        },
    );
    let (o, rep) = r.result.unwrap();
    assert_eq!(o.failure, Some(FailureCode::RelocBudgetExhausted));
    assert_eq!(rep.drive.steps, 20);
    assert!(!rep.drive.done);
    assert!(o.stats.work_units <= 100, "{} units", o.stats.work_units);
}

/// A relocalization of `left`/`right` from `prior` through the runner.
/// The prior's stated uncertainty reaches the engine through the runner: the
/// first iteration's viewpoints are drawn within it (or within Focus's
/// half-width once its pairs agreed, VTSM-RELOC-040), the report says what the
/// engine ran with, and a stated value out of range stops the run at the
/// prior check with `HAL_PRIOR_INVALID`.
///
/// Verifies: VTSM-HAL-026
#[test]
fn runner_builds_the_engine_with_the_priors_stated_uncertainty() {
    use vtsm_core::config::PriorUncertainty;
    let s = scene();
    let base = request(&s.map);
    let stated = PriorUncertainty {
        t_m: 0.3,
        r_deg: 2.0,
    };
    for (uncertainty, used) in [(None, base.params.uncertainty()), (Some(stated), stated)] {
        let req = base.with_uncertainty(uncertainty);
        let r = locate::run(&req, RunOptions::default()).unwrap();
        let (o, rep) = r.result.as_ref().unwrap();
        assert_eq!(o.failure, None, "{uncertainty:?}");
        assert_eq!(rep.prior_uncertainty, used);
        // The first fix's round drew its viewpoints within the stated
        // uncertainty, or, once Focus re-centred it (a stated t̃₀ above the
        // default only), within the focused half-width.
        let focus = vtsm_core::reloc::Focus::for_params(&base.params);
        let t_first = if o.stats.focused_rounds > 0 {
            assert!(used.t_m > focus.t_m, "{uncertainty:?}");
            focus.t_m
        } else {
            used.t_m
        };
        let first = o.quality.history.first().unwrap();
        assert_eq!(
            (first.t_m, first.r_rad),
            (t_first, used.r_deg.to_radians()),
            "{uncertainty:?}"
        );
        assert_eq!(o.stats.seeds_tried, 0);
    }
    let bad = base.with_uncertainty(Some(PriorUncertainty {
        t_m: vtsm_core::config::MAX_T0_M * 2.0,
        r_deg: 1.5,
    }));
    let r = locate::run(&bad, RunOptions::default()).unwrap();
    assert_eq!(r.result.err(), Some(FailureCode::HalPriorInvalid));
    assert_eq!(r.log.count(FailureCode::HalPriorInvalid), 1);
}

fn run_frames(left: &[u8], right: &[u8], prior: Pose) -> DeviceRun {
    let s = scene();
    let req = Request::new(&s.map, left, right, testkit::rig(), prior)
        .with_params(request(&s.map).params)
        .with_seed(RELOC_SEED);
    locate::run(&req, RunOptions::default()).unwrap()
}

/// Hopeless frames end fast with their own codes, as failed relocalizations:
/// the preflight refuses black, saturated and identical frames and a prior
/// facing away from the map before any render; noise ends in
/// `RELOC_NO_EVIDENCE` after the stated cap.
///
/// Verifies: VTSM-RELOC-021
#[test]
fn hopeless_frames_end_fast_with_their_own_codes() {
    let s = scene();
    let n = s.left.len();
    let prior = request(&s.map).prior;
    let (black, white) = (vec![0u8; n], vec![255u8; n]);
    for (l, r, code) in [
        (&black, &s.right, FailureCode::RelocFrameNoTexture),
        (&s.left, &white, FailureCode::RelocFrameNoTexture),
        (&s.left, &s.left, FailureCode::RelocStereoIdentical),
    ] {
        let r = run_frames(l, r, prior);
        let (o, _) = r.result.unwrap();
        assert_eq!(o.failure, Some(code));
        assert_eq!((o.stats.attempts, o.stats.work_units), (0, 0));
        assert_eq!(o.log.count(code), 1);
    }
    let away = Pose::new(
        vtsm_core::nalgebra::UnitQuaternion::from_axis_angle(
            &Vec3::x_axis(),
            core::f32::consts::PI,
        ) * prior.rotation(),
        prior.translation(),
    );
    let (o, _) = run_frames(&s.left, &s.right, away).result.unwrap();
    assert_eq!(o.failure, Some(FailureCode::RelocNoVisibleMaskVertex));
    assert_eq!(o.stats.attempts, 0);

    let mut rng = vtsm_core::rng::Rng::new(11);
    let mut noise = || -> Vec<u8> { (0..n).map(|_| rng.below(256) as u8).collect() };
    let (nl, nr) = (noise(), noise());
    let r = run_frames(&nl, &nr, prior);
    let (o, _) = r.result.unwrap();
    let cap = vtsm_core::reloc::Options::for_params(&request(&s.map).params).no_evidence_attempts();
    println!(
        "noise: {:?} after {} attempts (cap {cap})",
        o.failure, o.stats.attempts
    );
    assert_eq!(o.failure, Some(FailureCode::RelocNoEvidence));
    assert_eq!(o.stats.attempts, cap);
    assert_eq!(o.stats.correspondences, 0);
}

/// The attempts of one relocalization on 1, 2, 3 or 5 threads
/// (`Request::with_threads`, `Session::step_pooled`): the outcome — pose,
/// code, quality, every counter, the failure log — and the downlinked
/// telemetry are bit-identical to one thread's, at any step granularity and
/// when a step limit ends the run with the anytime result.
///
/// Verifies: VTSM-HAL-029, VTSM-RELOC-043
#[test]
fn threads_do_not_change_the_outcome() {
    let scene = scene();
    let threaded = |threads: usize, limits: DriveLimits| {
        locate::run(
            &request(&scene.map).with_threads(threads),
            RunOptions::default().limits(limits),
        )
        .unwrap()
    };
    let same = |a: &DeviceRun, b: &DeviceRun, what: &str| {
        let (oa, ra) = a.result.as_ref().unwrap();
        let (ob, rb) = b.result.as_ref().unwrap();
        assert_eq!(bits(oa), bits(ob), "{what}");
        assert_eq!(oa.failure, ob.failure, "{what}");
        assert_eq!(oa.stats, ob.stats, "{what}");
        assert_eq!(oa.quality, ob.quality, "{what}");
        assert_eq!(
            oa.log.counters().collect::<Vec<_>>(),
            ob.log.counters().collect::<Vec<_>>(),
            "{what}"
        );
        assert_eq!(ra.drive.steps, rb.drive.steps, "{what}");
        let frames = |r: &DeviceRun| {
            r.telemetry
                .iter()
                .map(|f| (f.kind, f.payload.clone()))
                .collect::<Vec<_>>()
        };
        assert_eq!(frames(a), frames(b), "{what}");
    };
    for limits in [
        DriveLimits::UNLIMITED,
        DriveLimits {
            units_per_step: 1,
            ..DriveLimits::UNLIMITED
        },
        // Ends early with the anytime result, in the middle of a round.
        DriveLimits {
            units_per_step: 3,
            max_steps: 17,
            budget_ticks: u64::MAX,
        },
    ] {
        let one = threaded(1, limits);
        let (o, _) = one.result.as_ref().unwrap();
        if limits.max_steps < u32::MAX {
            assert_eq!(o.failure, Some(FailureCode::RelocBudgetExhausted));
        } else {
            assert_eq!(o.failure, None);
            assert!(o.stats.rounds > 1 && o.stats.attempts > 100);
        }
        assert_eq!(one.attempts_worked, None);
        for threads in [2, 3, 5] {
            let what = format!("{threads} threads, {limits:?}");
            let many = threaded(threads, limits);
            same(&one, &many, &what);
            // Every attempt taken back was worked by a thread; the rest
            // were dropped as stale.
            let worked = many.attempts_worked.unwrap();
            assert!(worked >= o.stats.attempts, "{what}: {worked} worked");
        }
    }
}
