extern crate std;
use super::super::solver::RansacSolver;
use super::super::workspace::WorkspaceSizes;
use super::super::workspace::{Workspace, TEST_WORKSPACE};
use super::super::{Outcome, Relocalizer, Setup, Stage, StepResult};
use super::window::{epipolar_band, search_rect};
use super::*;
use crate::frame::Eye;
use crate::image::GrayView;
use crate::ncc;
use crate::ncc::Run;
use crate::rng::Rng;
use nalgebra::UnitQuaternion;
use std::vec;
use std::vec::Vec;

use crate::testkit::{build_map, build_map_scored, camera_pose, render_full, rig, test_params};

fn relocalize(map: &MapView, left: &[u8], right: &[u8], prior: &Pose, seed: u64) -> Outcome {
    relocalize_with(map, left, right, prior, seed, &test_params())
}

fn relocalize_with(
    map: &MapView,
    left: &[u8],
    right: &[u8],
    prior: &Pose,
    seed: u64,
    p: &Params,
) -> Outcome {
    relocalize_stepped(map, left, right, prior, seed, p, 0)
}

/// `chunk` = 0: run to completion; otherwise `step_n(chunk)` until done.
fn relocalize_stepped(
    map: &MapView,
    left: &[u8],
    right: &[u8],
    prior: &Pose,
    seed: u64,
    p: &Params,
    chunk: u32,
) -> Outcome {
    let lv = GrayView::new(left, 640, 480, 640).unwrap();
    let rv = GrayView::new(right, 640, 480, 640).unwrap();
    let mut setup = Setup::new(map, lv, rv, &rig(), p, prior, seed);
    setup.options.min_inliers = 15;
    let (mut bytes, mut words, mut runs) = workspace_buffers(&setup.sizes());
    let ws = Workspace::new(setup.sizes(), &mut bytes, &mut words, &mut runs).unwrap();
    let mut r = setup.build(ws).unwrap();
    if chunk == 0 {
        return r.run_to_completion(0);
    }
    let mut now = 0;
    loop {
        now += 1;
        if let StepResult::Done(o) = r.step_n(now, chunk) {
            return o.clone();
        }
    }
}

/// Step by stage until done; the outcome and the stage of every step.
fn relocalize_by_stage(
    map: &MapView,
    left: &[u8],
    right: &[u8],
    prior: &Pose,
    seed: u64,
) -> (Outcome, Vec<Stage>) {
    let lv = GrayView::new(left, 640, 480, 640).unwrap();
    let rv = GrayView::new(right, 640, 480, 640).unwrap();
    let mut setup = Setup::new(map, lv, rv, &rig(), &test_params(), prior, seed);
    setup.options.min_inliers = 15;
    let (mut bytes, mut words, mut runs) = workspace_buffers(&setup.sizes());
    let ws = Workspace::new(setup.sizes(), &mut bytes, &mut words, &mut runs).unwrap();
    let mut r = setup.build(ws).unwrap();
    let mut stages = Vec::new();
    loop {
        let (stage, status) = r.step_stage(0);
        stages.extend(stage);
        if let StepResult::Done(o) = status {
            return (o.clone(), stages);
        }
    }
}

fn scene() -> (Vec<u8>, Pose) {
    (build_map(1), camera_pose(0.6, 0.2))
}

/// The engine's pipeline over the map `bytes` and a pair rendered from
/// `truth` (gain 0.85, offset 20), handed to `f` with the checked map.
fn with_pipeline_at(bytes: &[u8], truth: &Pose, f: impl FnOnce(&MapView, &mut Pipeline<'_, '_>)) {
    let map = MapView::new_checked(bytes).unwrap();
    let rig = rig();
    let left = render_full(&map, &rig.cam, truth, 0.85, 20.0);
    let right = render_full(&map, &rig.cam, &rig.world_from_right(truth), 0.85, 20.0);
    let p = test_params();
    let (mut b, mut w, mut r) = workspace_buffers(&TEST_WORKSPACE);
    let ws = Workspace::new(TEST_WORKSPACE, &mut b, &mut w, &mut r).unwrap();
    let lv = GrayView::new(&left, 640, 480, 640).unwrap();
    let rv = GrayView::new(&right, 640, 480, 640).unwrap();
    let mut engine = Setup::new(&map, lv, rv, &rig, &p, truth, 0)
        .build(ws)
        .unwrap();
    f(&map, engine.attempt_mut());
}

fn workspace_buffers(s: &WorkspaceSizes) -> (Vec<u8>, Vec<u32>, Vec<Run>) {
    (
        vec![0u8; s.bytes],
        vec![0u32; s.words],
        vec![Run::default(); s.runs],
    )
}

/// The context of a first-round attempt from `viewpoint` with a small
/// uncertainty (5 cm, 0.01 rad).
fn attempt_at(viewpoint: Pose) -> AttemptContext {
    AttemptContext {
        world_from_viewpoint: viewpoint,
        t_m: 0.05,
        r_rad: 0.01,
        gradient_only: false,
        revisit: None,
        near: None,
        near_radius_m: 0.25,
        index: 0,
        round: 0,
    }
}

/// Verifies: VTSM-RELOC-019
#[test]
fn attempts_from_the_true_pose_give_consistent_correspondences() {
    let (bytes, truth) = scene();
    with_pipeline_at(&bytes, &truth, |_, pipe| {
        true_pose_attempts(pipe, &truth);
    });
}

fn true_pose_attempts(pipe: &mut Pipeline<'_, '_>, truth: &Pose) {
    let truth = *truth;
    let mut stats = PipelineStats::default();
    let ctx = attempt_at(truth);
    let cam_from_world = truth.inverse();
    let (mut ok, mut occluded, mut other) = (0u32, 0u32, 0u32);
    let n = 60u32;
    for i in 0..n {
        let mut rng = Rng::new(9).fork(u64::from(i));
        match pipe.attempt(&ctx, &mut rng, &mut stats) {
            Ok(c) => {
                ok += 1;
                // Independent reference: the vertex seen from the true pose.
                let expect = cam_from_world.transform_point(&c.world);
                let err = (c.cam - expect).norm();
                assert!(
                    err < 0.03 + 3.0 * c.sigma_m,
                    "pair {i}: {err} m (sigma {})",
                    c.sigma_m
                );
            }
            Err(FailureCode::RelocSampleOccluded) => occluded += 1,
            Err(_) => other += 1,
        }
    }
    std::println!("ok {ok} occluded {occluded} other {other} {stats:?}");
    assert!(ok >= n * 3 / 4, "only {ok} of {n}");
    assert_eq!(stats.occluded, occluded);
    assert_eq!(stats.triangulations, ok);
    assert!(stats.renders <= 2 * n);
    assert_eq!(stats.accepted.iter().sum::<u32>(), ok);
    assert!(stats.matches.iter().sum::<u32>() <= 2 * 6 * n);

    // Looking at the sky: every draw is out of view and the attempt says so.
    let up = Pose::new(
        UnitQuaternion::from_axis_angle(&Vec3::x_axis(), core::f32::consts::PI) * truth.rotation(),
        truth.translation(),
    );
    let before = stats.out_of_view;
    let sky = AttemptContext {
        world_from_viewpoint: Pose::new(up.rotation(), Vec3::new(-50.0, 0.0, 30.0)),
        ..ctx
    };
    let got = pipe.attempt(&sky, &mut Rng::new(1), &mut stats).err();
    assert_eq!(got, Some(FailureCode::RelocSampleOutOfView));
    assert_eq!(stats.out_of_view - before, MAX_SAMPLE_TRIES);
}

/// On a scored map (version 3) SamplePoint draws only vertices with a
/// score, about in proportion to it, and reports which one it drew.
/// Verifies: VTSM-MAP-011
#[test]
fn sample_point_draws_in_proportion_to_the_map_scores() {
    // Even vertices 3, vertices divisible by 4 another 3: those draw twice
    // as often as the other even ones; odd vertices never.
    let score = |v: usize| -> u8 {
        match (v % 2, v % 4) {
            (0, 0) => 6,
            (0, _) => 3,
            _ => 0,
        }
    };
    let bytes = build_map_scored(1, |_| true, Some(&score));
    let truth = camera_pose(0.6, 0.2);
    with_pipeline_at(&bytes, &truth, |map, pipe| {
        scored_draws(map, pipe, &truth, &score);
    });
}

fn scored_draws(
    map: &MapView,
    pipe: &mut Pipeline<'_, '_>,
    truth: &Pose,
    score: &dyn Fn(usize) -> u8,
) {
    let truth = *truth;
    assert!(map.scored());
    assert_eq!(pipe.last_sample(), None);
    let mut stats = PipelineStats::default();
    let ctx = attempt_at(truth);
    let (mut fours, mut twos) = (0u32, 0u32);
    for i in 0..300u32 {
        let mut rng = Rng::new(5).fork(u64::from(i));
        let got = pipe.attempt(&ctx, &mut rng, &mut stats);
        let Some(k) = pipe.last_sample() else {
            assert_eq!(got.err(), Some(FailureCode::RelocSampleOutOfView));
            continue;
        };
        let v = map.mask_vertex(k).unwrap() as usize;
        assert_eq!(v % 2, 0, "vertex {v} has no score and was drawn");
        assert_eq!(map.mask_score(k), Some(score(v)));
        if v % 4 == 0 {
            fours += 1;
        } else {
            twos += 1;
        }
    }
    // Expected 2:1 (equal numbers of each kind in view, 6 against 3).
    assert!(fours + twos >= 200, "{} of 300 draws in view", fours + twos);
    assert!(
        fours > twos + twos / 2 && fours < 3 * twos,
        "{fours} draws of score 6 against {twos} of score 3"
    );
}

/// Revisit: an attempt whose context names a mask vertex in view measures
/// that vertex, without a random number, and counts it; a vertex out of
/// view or not in the mask falls back to the draws, counted out of view.
/// Verifies: VTSM-RELOC-046
#[test]
fn sample_point_measures_the_revisit_vertex_first() {
    let (bytes, truth) = scene();
    with_pipeline_at(&bytes, &truth, |map, pipe| {
        let mut stats = PipelineStats::default();
        let drawn = |pipe: &mut Pipeline<'_, '_>, ctx: &AttemptContext, stats: &mut _| {
            let mut rng = Rng::new(3);
            let got = pipe.attempt(ctx, &mut rng, stats);
            (
                pipe.last_sample(),
                got.ok().map(|c| c.mask_index),
                rng.next_u32(),
            )
        };
        let plain = attempt_at(truth);
        let (k0, _, after_draw) = drawn(pipe, &plain, &mut stats);
        let plain_out_of_view = stats.out_of_view;
        let k0 = k0.expect("a vertex in view");
        assert_eq!(stats.revisited, 0);
        // A vertex in view other than the one the stream draws.
        let other = (0..map.mask_vertex_count())
            .find(|&k| {
                k != k0 && {
                    let mut s = PipelineStats::default();
                    let ctx = AttemptContext {
                        revisit: Some(k),
                        ..plain
                    };
                    drawn(pipe, &ctx, &mut s).0 == Some(k)
                }
            })
            .expect("another vertex in view");
        let ctx = AttemptContext {
            revisit: Some(other),
            ..plain
        };
        let (k, pair, after_revisit) = drawn(pipe, &ctx, &mut stats);
        assert_eq!(k, Some(other));
        assert_eq!(stats.revisited, 1);
        match pair {
            Some(m) => {
                assert_eq!(m, other, "the pair names the vertex it measures");
                assert_eq!(stats.revisit_pairs, 1);
            }
            None => assert_eq!(stats.revisit_pairs, 0),
        }
        // No random number spent on the revisit vertex: the stream is where
        // a plain attempt's draw of one vertex leaves it, less that draw.
        assert_ne!(after_revisit, after_draw);
        // Not in the mask: the draws as without it, one more out of view.
        let before = stats.out_of_view;
        let ctx = AttemptContext {
            revisit: Some(u32::MAX - 1),
            ..plain
        };
        let (k, _, _) = drawn(pipe, &ctx, &mut stats);
        assert_eq!(k, Some(k0));
        assert_eq!(stats.out_of_view, before + plain_out_of_view + 1);
        assert_eq!(stats.revisited, 1);
    });
}

/// The right template is rendered only once a left match is accepted:
/// every attempt that triangulates rendered both templates, an occluded
/// one only the left, and on real images of pure noise (where no left
/// search is accepted) every attempt that reached Synthesize rendered
/// the left template alone.
/// Verifies: VTSM-RELOC-039
#[test]
fn the_right_template_is_rendered_only_after_a_left_match() {
    let (bytes, truth) = scene();
    let map = MapView::new_checked(&bytes).unwrap();
    let rig = rig();
    let p = test_params();
    let ctx = attempt_at(truth);
    let mut noise = Rng::new(17);
    let mut noise_image = || -> Vec<u8> {
        (0..640 * 480)
            .map(|_| (noise.next_u32() >> 24) as u8)
            .collect()
    };
    let textured = (
        render_full(&map, &rig.cam, &truth, 0.85, 20.0),
        render_full(&map, &rig.cam, &rig.world_from_right(&truth), 0.85, 20.0),
    );
    let noisy = (noise_image(), noise_image());
    for (images, real) in [(&textured, true), (&noisy, false)] {
        let (mut b, mut w, mut r) = workspace_buffers(&TEST_WORKSPACE);
        let ws = Workspace::new(TEST_WORKSPACE, &mut b, &mut w, &mut r).unwrap();
        let lv = GrayView::new(&images.0, 640, 480, 640).unwrap();
        let rv = GrayView::new(&images.1, 640, 480, 640).unwrap();
        let mut engine = Setup::new(&map, lv, rv, &rig, &p, &truth, 0)
            .build(ws)
            .unwrap();
        let pipe = engine.attempt_mut();
        let mut stats = PipelineStats::default();
        let (mut ok, mut synthesized) = (0u32, 0u32);
        for i in 0..40u32 {
            let before = stats;
            let mut rng = Rng::new(9).fork(u64::from(i));
            let got = pipe.attempt(&ctx, &mut rng, &mut stats);
            let renders = stats.renders - before.renders;
            let searches = stats.matches.iter().sum::<u32>() - before.matches.iter().sum::<u32>();
            match got {
                Ok(_) => {
                    ok += 1;
                    assert_eq!(renders, 2, "attempt {i}");
                }
                Err(FailureCode::RelocSampleOutOfView) => assert_eq!(renders, 0),
                Err(FailureCode::RelocSampleOccluded) => assert_eq!(renders, 1),
                Err(code) => {
                    assert!((1..=2).contains(&renders), "attempt {i}: {code:?}");
                    if !real {
                        assert_eq!(renders, 1, "attempt {i}: {code:?}");
                    }
                    // A left search per variant at least, so at least as
                    // many searches as renders beyond the left one.
                    assert!(searches >= renders, "attempt {i}");
                }
            }
            if renders > 0 {
                synthesized += 1;
            }
        }
        if real {
            assert!(ok >= 30, "only {ok} of 40");
        } else {
            assert_eq!(ok, 0);
            assert_eq!(stats.renders, synthesized);
            assert!(synthesized >= 30, "{stats:?}");
        }
    }
}

/// The right search band holds exactly the template positions whose vertex
/// pixel is within ε + 1 px of the left row and at a disparity within the
/// range ± 1 px, clipped to the right window; no position, no band.
/// Verifies: VTSM-RELOC-034
#[test]
fn epipolar_band_holds_the_positions_valid_can_accept() {
    let within = Rect::new(100, 50, 300, 300);
    let (pl, o, eps) = ([250.4_f32, 180.6_f32], [31.5_f32, 32.25_f32], 2.0);
    let band = epipolar_band(pl, o, (64, 64), (40.0, 60.0), eps, within).unwrap();
    // Top-left rows: floor(180.6 − 32.25 − 3) ..= ceil(180.6 − 32.25 + 3).
    assert_eq!((band.y, band.h), (145, 152 - 145 + 64));
    // Top-left columns: floor(250.4 − 60 − 31.5 − 1) ..= ceil(250.4 − 40 − 31.5 + 1).
    assert_eq!((band.x, band.w), (157, 180 - 157 + 64));
    // Every position in the band satisfies the row and disparity bounds.
    for ty in band.y..=band.y + band.h as i32 - 64 {
        for tx in band.x..=band.x + band.w as i32 - 64 {
            let pr = [tx as f32 + o[0], ty as f32 + o[1]];
            assert!((pr[1] - pl[1]).abs() <= eps + 1.0 + 1.0);
            let d = pl[0] - pr[0];
            assert!((40.0 - 2.0..=60.0 + 2.0).contains(&d), "{d}");
        }
    }
    // Clipped to the right window.
    let tight = Rect::new(170, 0, 80, 400);
    let clipped = epipolar_band(pl, o, (64, 64), (40.0, 60.0), eps, tight).unwrap();
    assert_eq!((clipped.x, clipped.w), (170, 157 + 87 - 170));
    // A window left of every plausible position, a window too narrow for
    // the template, and a non-finite range give no band.
    let left_of = Rect::new(0, 0, 150, 400);
    assert_eq!(
        epipolar_band(pl, o, (64, 64), (40.0, 60.0), eps, left_of),
        None
    );
    let narrow = Rect::new(200, 0, 60, 400);
    assert_eq!(
        epipolar_band(pl, o, (64, 64), (40.0, 60.0), eps, narrow),
        None
    );
    let nan = epipolar_band(pl, o, (64, 64), (f32::NAN, 60.0), eps, within);
    assert_eq!(nan, None);
}

/// A worker's pipeline (`Engine::worker`) needs a workspace as large as the
/// engine's own: a smaller one is refused with `CONFIG_CAPACITY_TOO_SMALL`.
///
/// Verifies: VTSM-RELOC-043
#[test]
fn a_worker_refuses_a_workspace_smaller_than_the_engines() {
    let (bytes, truth) = scene();
    let map = MapView::new_checked(&bytes).unwrap();
    let rig = rig();
    let p = test_params();
    let left = render_full(&map, &rig.cam, &truth, 0.85, 20.0);
    let right = render_full(&map, &rig.cam, &rig.world_from_right(&truth), 0.85, 20.0);
    let lv = GrayView::new(&left, 640, 480, 640).unwrap();
    let rv = GrayView::new(&right, 640, 480, 640).unwrap();
    let (mut b, mut w, mut r) = workspace_buffers(&TEST_WORKSPACE);
    let ws = Workspace::new(TEST_WORKSPACE, &mut b, &mut w, &mut r).unwrap();
    let engine = Setup::new(&map, lv, rv, &rig, &p, &truth, 1)
        .build(ws)
        .unwrap();
    let tiny = WorkspaceSizes::new(32, 256, ncc::Search::CoarseToFine);
    let (mut tb, mut tw, mut tr) = workspace_buffers(&tiny);
    let small = Workspace::new(tiny, &mut tb, &mut tw, &mut tr).unwrap();
    assert_eq!(
        engine.worker(small).err(),
        Some(FailureCode::ConfigCapacityTooSmall)
    );
    let (mut sb, mut sw, mut sr) = workspace_buffers(&TEST_WORKSPACE);
    let same = Workspace::new(TEST_WORKSPACE, &mut sb, &mut sw, &mut sr).unwrap();
    assert!(engine.worker(same).is_ok());
}

/// Verifies: VTSM-RELOC-016
#[test]
fn setup_refuses_mismatched_images_small_workspaces_and_bad_inputs() {
    let (bytes, truth) = scene();
    let map = MapView::new_checked(&bytes).unwrap();
    let rig = rig();
    let p = test_params();
    let left = render_full(&map, &rig.cam, &truth, 0.85, 20.0);
    let right = render_full(&map, &rig.cam, &rig.world_from_right(&truth), 0.85, 20.0);
    let small = vec![0u8; 320 * 240];
    let lv = GrayView::new(&left, 640, 480, 640).unwrap();
    let rv = GrayView::new(&right, 640, 480, 640).unwrap();
    let sv = GrayView::new(&small, 320, 240, 320).unwrap();
    let good = Setup::new(&map, lv, rv, &rig, &p, &truth, 1);
    assert_eq!(good.sizes(), TEST_WORKSPACE);
    assert_eq!(good.validate(), Ok(()));
    let build = |s: &Setup, sizes: WorkspaceSizes| {
        let (mut b, mut w, mut r) = workspace_buffers(&sizes);
        let ws = Workspace::new(sizes, &mut b, &mut w, &mut r).unwrap();
        s.build(ws).err()
    };
    assert_eq!(build(&good, TEST_WORKSPACE), None);
    let mismatched = Setup {
        frames: StereoPair::new(lv, sv),
        ..good
    };
    assert_eq!(
        build(&mismatched, TEST_WORKSPACE),
        Some(FailureCode::ImageSizeMismatch)
    );
    let tiny = WorkspaceSizes::new(32, 256, ncc::Search::CoarseToFine);
    assert_eq!(
        build(&good, tiny),
        Some(FailureCode::ConfigCapacityTooSmall)
    );
    let wide = Setup {
        params: Params {
            search_px: 512,
            ..p
        },
        ..good
    };
    assert_eq!(
        build(&wide, TEST_WORKSPACE),
        Some(FailureCode::ConfigCapacityTooSmall)
    );
    let bad_params = Setup {
        params: Params { n_corr: 1, ..p },
        ..good
    };
    assert_eq!(
        build(&bad_params, TEST_WORKSPACE),
        Some(FailureCode::ConfigParamOutOfRange)
    );
    let mut bad_policy = good;
    bad_policy.policy.min_score = 2.0;
    assert_eq!(
        bad_policy.validate(),
        Err(FailureCode::ConfigParamOutOfRange)
    );
    let mut bad_options = good;
    bad_options.options.min_inliers = 0;
    assert_eq!(
        bad_options.validate(),
        Err(FailureCode::ConfigParamOutOfRange)
    );
    // The builders refuse the same values before a build.
    let bad = Err(FailureCode::ConfigParamOutOfRange);
    let policy = MatchPolicy {
        min_score: 2.0,
        ..good.policy
    };
    assert_eq!(good.with_policy(policy).map(|_| ()), bad);
    let too_many = good.options.with_min_inliers(p.n_corr + 1).unwrap();
    assert_eq!(good.with_options(too_many).map(|_| ()), bad);
    let ok = good.options.with_min_inliers(p.n_corr).unwrap();
    assert_eq!(
        good.with_options(ok).unwrap().options().min_inliers(),
        p.n_corr
    );
    let checked = good.with_upset_checks(true, true).options().verify();
    assert!(checked.repeat_solve && checked.recheck_map);
    let nan_prior = Setup {
        prior: Pose::new(truth.rotation(), Vec3::new(f32::NAN, 0.0, 0.0)),
        ..good
    };
    assert_eq!(
        build(&nan_prior, TEST_WORKSPACE),
        Some(FailureCode::RelocPriorInvalid)
    );
}

proptest::proptest! {
    /// Verifies: VTSM-RELOC-019
    #[test]
    fn search_window_is_inside_the_image_and_under_the_cap(
        u in -100.0f32..800.0, v in -100.0f32..600.0, r in -10i32..600, l in 16usize..128,
    ) {
        let l = l & !1;
        let cap = 256usize.max(l);
        let s = search_rect([u, v], l, r, cap, 640, 480);
        proptest::prop_assert!(s.x >= 0 && s.y >= 0);
        proptest::prop_assert!(s.x as u32 + s.w <= 640 && s.y as u32 + s.h <= 480);
        proptest::prop_assert!(s.w as usize <= cap && s.h as usize <= cap);
        // Away from the border the window is centred on the prediction and holds the template.
        let inner = u > 300.0 && u < 340.0 && v > 220.0 && v < 260.0;
        if inner && r >= 0 {
            proptest::prop_assert!(s.w as usize >= l && s.h as usize >= l);
            let cx = s.x as f32 + s.w as f32 / 2.0;
            proptest::prop_assert!((cx - u).abs() <= 1.0);
        }
    }
}

fn perturb(truth: &Pose, rng: &mut Rng, t_m: f32, r_deg: f32) -> Pose {
    let axis = rng.unit_vector3();
    let az = rng.uniform(0.0, core::f32::consts::TAU);
    let d = Vec3::new(libm::cosf(az), libm::sinf(az), rng.uniform(-0.2, 0.2)).normalize() * t_m;
    let rot = truth.rotation() * UnitQuaternion::from_scaled_axis(axis * r_deg.to_radians());
    Pose::new(rot, truth.translation() + d)
}

/// Verifies: VTSM-RELOC-001
#[test]
fn converges_from_perturbed_priors_on_a_textured_scene() {
    let bytes = build_map(1);
    let map = MapView::new_checked(&bytes).unwrap();
    let rig = rig();
    let truth = camera_pose(0.6, 0.2);
    let left = render_full(&map, &rig.cam, &truth, 0.85, 20.0);
    let right = render_full(&map, &rig.cam, &rig.world_from_right(&truth), 0.85, 20.0);
    let mut rng = Rng::new(77);
    for (k, (t, r)) in [(0.10f32, 1.0f32), (0.15, 1.5), (0.20, 1.2)]
        .iter()
        .enumerate()
    {
        let prior = perturb(&truth, &mut rng, *t, *r);
        let out = relocalize(&map, &left, &right, &prior, 100 + k as u64);
        let (et, er) = out.pose.error_to(&truth);
        std::println!(
            "prior {t} m {r}°: err {et:.4} m {:.3}°, failure {:?}, inliers {}, iters {}, attempts {}",
            er.to_degrees(),
            out.failure,
            out.quality.inliers,
            out.stats.successes,
            out.stats.attempts
        );
        assert_eq!(out.failure, None);
        assert!(et < 0.05, "error {et} m");
        assert!(out.quality.inliers >= 15);
        // Work stays under the structural bound; RANSAC ran in chunks.
        let p = test_params();
        let max = Relocalizer::<Pipeline, RansacSolver>::max_work_units(&p);
        let s = out.stats;
        assert!(s.work_units <= max && s.ransac_chunks > 0);
        assert_eq!(s.work_units, s.attempts + s.solves + s.ransac_chunks);
        assert!(s.pipeline.renders <= 2 * s.attempts);
        assert!(s.ransac_iterations <= s.solves * u32::from(p.ransac_iter));
        if k == 0 {
            // Same seed, stepped 3 units at a time: bit-identical outcome.
            let p = test_params();
            let stepped = relocalize_stepped(&map, &left, &right, &prior, 100, &p, 3);
            assert_eq!(
                stepped.pose.t().map(f32::to_bits),
                out.pose.t().map(f32::to_bits)
            );
            assert_eq!(
                stepped.pose.q().map(f32::to_bits),
                out.pose.q().map(f32::to_bits)
            );
            assert_eq!(stepped.stats, out.stats);
            assert_eq!(stepped.quality, out.quality);
        }
    }
}

/// Verifies: VTSM-RELOC-035
#[test]
fn stepping_by_stage_reports_each_stage_and_changes_nothing() {
    let (bytes, truth) = scene();
    let map = MapView::new_checked(&bytes).unwrap();
    let rig = rig();
    let left = render_full(&map, &rig.cam, &truth, 0.85, 20.0);
    let right = render_full(&map, &rig.cam, &rig.world_from_right(&truth), 0.85, 20.0);
    let prior = perturb(&truth, &mut Rng::new(31), 0.15, 1.2);
    let whole = relocalize(&map, &left, &right, &prior, 41);
    let (staged, stages) = relocalize_by_stage(&map, &left, &right, &prior, 41);
    let bits = |o: &Outcome| {
        let (t, q) = (o.pose.t(), o.pose.q());
        (t.map(f32::to_bits), q.map(f32::to_bits))
    };
    assert_eq!(bits(&staged), bits(&whole));
    assert_eq!(staged.stats, whole.stats);
    assert_eq!(staged.quality, whole.quality);
    assert_eq!(staged.failure, whole.failure);
    assert_eq!(
        staged.log.counters().collect::<Vec<_>>(),
        whole.log.counters().collect::<Vec<_>>()
    );
    // Every attempt begins with Render; Match only after Render, Stereo
    // only after Match; the pose units are the solves and their chunks.
    let count = |k: Stage| stages.iter().filter(|&&s| s == k).count() as u32;
    let s = staged.stats;
    assert_eq!(count(Stage::Render), s.attempts);
    assert_eq!(count(Stage::Pose), s.solves + s.ransac_chunks);
    assert!(count(Stage::Stereo) >= s.pipeline.triangulations);
    assert!(s.pipeline.triangulations >= s.correspondences && s.correspondences > 0);
    assert!(count(Stage::Match) >= count(Stage::Stereo));
    for w in stages.windows(2) {
        match w[1] {
            Stage::Match => assert_eq!(w[0], Stage::Render),
            Stage::Stereo => assert_eq!(w[0], Stage::Match),
            _ => {}
        }
    }
    let kinds = [Stage::Render, Stage::Match, Stage::Stereo, Stage::Pose];
    assert!(stages.iter().all(|s| kinds.contains(s)), "{stages:?}");
    assert_eq!(staged.failure, None);
}

/// Verifies: VTSM-RELOC-015
#[test]
fn wrong_prior_or_wrong_place_gives_a_failure_code() {
    let bytes = build_map(1);
    let map = MapView::new_checked(&bytes).unwrap();
    let rig = rig();
    let truth = camera_pose(0.6, 0.2);
    // Images of a different place: another random scene.
    let other_bytes = build_map(2);
    let other = MapView::new_checked(&other_bytes).unwrap();
    let left = render_full(&other, &rig.cam, &truth, 1.0, 0.0);
    let right = render_full(&other, &rig.cam, &rig.world_from_right(&truth), 1.0, 0.0);
    // Fewer attempts per round keep the failing cases short; the rules are the same.
    let quick = Params {
        attempts_per_iter: 100,
        max_reseed: 1,
        ..test_params()
    };
    let out = relocalize_with(&map, &left, &right, &truth, 5, &quick);
    std::println!(
        "other place: {:?} inliers {}",
        out.failure,
        out.quality.inliers
    );
    assert!(out.failure.is_some());
    // A prior 1 m off: either a failure code or (if it still finds the truth) a correct pose.
    let left = render_full(&map, &rig.cam, &truth, 1.0, 0.0);
    let right = render_full(&map, &rig.cam, &rig.world_from_right(&truth), 1.0, 0.0);
    let prior = Pose::new(
        truth.rotation(),
        truth.translation() + Vec3::new(0.7, 0.7, 0.0).normalize(),
    );
    let out = relocalize_with(&map, &left, &right, &prior, 6, &quick);
    let (et, _) = out.pose.error_to(&truth);
    std::println!("1 m off: {:?} err {et}", out.failure);
    assert!(
        out.failure.is_some() || et < 0.05,
        "confident wrong pose, error {et} m"
    );
}

/// A source that serves `good` reads and then fails every read.
struct FailAfter<'a> {
    pair: StereoPair<'a>,
    good: u32,
    reads: u32,
}

impl FrameSource for FailAfter<'_> {
    fn size(&self) -> (usize, usize) {
        self.pair.size()
    }
    fn read_window(&mut self, eye: Eye, r: Rect, out: &mut [u8]) -> Result<(), FailureCode> {
        self.reads += 1;
        if self.reads > self.good {
            return Err(FailureCode::HalFrameStoreRead);
        }
        self.pair.read_window(eye, r, out)
    }
}

/// A frame source that stops serving reads part-way through the run ends
/// the relocalization at that attempt with `RELOC_FRAME_READ_FAILED`; one
/// that serves every read gives the in-memory pair's outcome.
///
/// Verifies: VTSM-RELOC-037
#[test]
fn a_frame_source_that_fails_ends_the_run_with_its_code() {
    let (bytes, truth) = scene();
    let map = MapView::new_checked(&bytes).unwrap();
    let rig = rig();
    let left = render_full(&map, &rig.cam, &truth, 0.85, 20.0);
    let right = render_full(&map, &rig.cam, &rig.world_from_right(&truth), 0.85, 20.0);
    let lv = GrayView::new(&left, 640, 480, 640).unwrap();
    let rv = GrayView::new(&right, 640, 480, 640).unwrap();
    let prior = perturb(&truth, &mut Rng::new(31), 0.15, 1.2);
    let run = |good: u32| {
        let src = FailAfter {
            pair: StereoPair::new(lv, rv),
            good,
            reads: 0,
        };
        let mut setup = Setup::with_frames(&map, src, &rig, &test_params(), &prior, 41);
        setup.options.min_inliers = 15;
        let (mut b, mut w, mut r) = workspace_buffers(&setup.sizes());
        let ws = Workspace::new(setup.sizes(), &mut b, &mut w, &mut r).unwrap();
        let mut engine = setup.build(ws).unwrap();
        let out = engine.run_to_completion(0);
        (out, engine.attempt_ref().frames().reads)
    };
    let (all, reads) = run(u32::MAX);
    let whole = relocalize(&map, &left, &right, &prior, 41);
    assert_eq!(
        all.pose.t().map(f32::to_bits),
        whole.pose.t().map(f32::to_bits)
    );
    assert_eq!(all.stats, whole.stats);
    assert_eq!(all.failure, None);
    // 2 × 64 preflight reads, then windows.
    assert!(reads > 128, "{reads}");
    let (cut, _) = run(128 + 40);
    assert_eq!(cut.failure, Some(FailureCode::RelocFrameReadFailed));
    assert!(cut.stats.attempts > 0 && cut.stats.attempts < all.stats.attempts);
    let (early, _) = run(3);
    assert_eq!(early.failure, Some(FailureCode::RelocFrameReadFailed));
    assert_eq!(early.stats.attempts, 0);
}

/// Near: with a Near vertex in view, SamplePoint takes a mask vertex within
/// the radius of it (counted in `near_drawn`, and in `near_pairs` when it
/// gives a pair); a radius too small for any other vertex, or a Near vertex
/// not in the mask, falls back to the draws anywhere, uncounted.
/// Verifies: VTSM-RELOC-047
#[test]
fn sample_point_draws_near_the_near_vertex() {
    let (bytes, truth) = scene();
    with_pipeline_at(&bytes, &truth, |map, pipe| {
        let plain = attempt_at(truth);
        let world = |k: u32| map.vertex(map.mask_vertex(k).unwrap()).unwrap();
        let mut rng = Rng::new(3);
        let mut s = PipelineStats::default();
        let _ = pipe.attempt(&plain, &mut rng, &mut s);
        let anchor = pipe.last_sample().expect("a vertex in view");
        let (mut near, mut pairs, mut far) = (0u32, 0u32, 0u32);
        let mut stats = PipelineStats::default();
        for seed in 0..40u64 {
            for (radius, want_near) in [(0.2f32, true), (1.0e-4, false)] {
                let ctx = AttemptContext {
                    near: Some(anchor),
                    near_radius_m: radius,
                    ..plain
                };
                let before = stats;
                let mut rng = Rng::new(100 + seed);
                let got = pipe.attempt(&ctx, &mut rng, &mut stats);
                let Some(k) = pipe.last_sample() else {
                    continue;
                };
                let d = (world(k) - world(anchor)).norm();
                if stats.near_drawn > before.near_drawn {
                    assert!(
                        d <= radius + 1e-6,
                        "vertex {k} at {d} m from the Near vertex"
                    );
                    // A radius of 0.1 mm holds the Near vertex alone.
                    assert!(want_near || k == anchor, "radius {radius}: vertex {k}");
                    near += u32::from(want_near);
                    if got.is_ok() {
                        pairs += 1;
                        assert_eq!(stats.near_pairs, before.near_pairs + 1);
                    }
                } else {
                    far += u32::from(d > 0.2);
                }
            }
        }
        // The test map's 0.5 m tiles are wide against 0.2 m: some attempts
        // find no vertex near within their draws.
        assert!(near >= 10, "near draws {near} of 40");
        assert!(pairs > 0 && far > 0, "pairs {pairs}, far {far}");
        assert_eq!(stats.near_pairs, pairs);
        // A Near vertex not in the mask: draws as without it.
        let ctx = AttemptContext {
            near: Some(u32::MAX - 1),
            ..plain
        };
        let mut a = Rng::new(9);
        let mut b = Rng::new(9);
        let mut s = PipelineStats::default();
        let _ = pipe.attempt(&ctx, &mut a, &mut s);
        let k = pipe.last_sample();
        let _ = pipe.attempt(&plain, &mut b, &mut PipelineStats::default());
        assert_eq!(k, pipe.last_sample());
        assert_eq!(s.near_drawn, 0);
    });
}
