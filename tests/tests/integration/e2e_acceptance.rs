//! Acceptance of the relocalization engine on the simulator (test profile):
//! from priors perturbed by 10–20 cm and up to 1.5°, with the map made under
//! the same lighting as the images, the engine converges within 5 cm and
//! reports success; with a prior 1 m off, or with images of another place, it
//! returns a failure code rather than a confident wrong pose; and the same
//! inputs and seed give a bit-identical outcome.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::sync::OnceLock;
use vtsm_core::geom::{Pose, StereoRig, Vec3};
use vtsm_core::reloc::Outcome;
use vtsm_sim::locate::{self, Request, RunOptions};
use vtsm_sim::scene::{perturbed_prior, Capture, Profile, Scene, StereoPair};
use vtsm_sim::terrain::TerrainKind;

const TERRAIN: TerrainKind = TerrainKind::Flagstone;
const SCENE_SEED: u64 = 1;
const HOURS: f32 = 9.5;
/// Success threshold of the paper's evaluation.
const OK_M: f32 = 0.05;

struct Depot {
    scene: Scene,
    light: vtsm_sim::render::Lighting,
    map: Vec<u8>,
}

fn depot() -> &'static Depot {
    static D: OnceLock<Depot> = OnceLock::new();
    D.get_or_init(|| {
        let scene = Scene::new(TERRAIN, SCENE_SEED, Profile::Test);
        let light = scene.lighting(HOURS);
        let m = scene.map(&light);
        let map = m.encode_map(0.5).unwrap();
        Depot { scene, light, map }
    })
}

fn capture(stop: u32, look_at: u32) -> (StereoRig, Pose, StereoPair) {
    let d = depot();
    d.scene
        .capture(&d.light, &Capture::from_index(stop, look_at, 0.40))
}

fn relocalize(rig: StereoRig, pair: &StereoPair, prior: Pose, seed: u64) -> Outcome {
    relocalize_with(
        rig,
        pair,
        prior,
        seed,
        locate::params_for_width(rig.cam().width()),
    )
}

/// The paper's parameters with tighter Reseed and attempt caps, for the cases
/// that are expected to fail: the property under test (a failure code, never a
/// confident wrong pose) does not depend on how long it searches first.
fn relocalize_bounded(rig: StereoRig, pair: &StereoPair, prior: Pose, seed: u64) -> Outcome {
    let params = vtsm_core::config::Params {
        max_reseed: 3,
        attempts_per_iter: 600,
        ..locate::params_for_width(rig.cam().width())
    };
    relocalize_with(rig, pair, prior, seed, params)
}

fn relocalize_with(
    rig: StereoRig,
    pair: &StereoPair,
    prior: Pose,
    seed: u64,
    params: vtsm_core::config::Params,
) -> Outcome {
    let req = Request::new(&depot().map, &pair.left, &pair.right, rig, prior)
        .with_params(params)
        .with_seed(seed);
    locate::relocalize(&req, RunOptions::default())
        .unwrap()
        .outcome
}

/// A failure code, or a success that is right: never a confident wrong pose.
fn assert_not_confidently_wrong(o: &Outcome, truth: &Pose, what: &str) {
    eprintln!(
        "{what}: failure {:?}, {:.3} m from the truth, {} inliers, {} attempts",
        o.failure,
        o.pose.error_to(truth).0,
        o.quality.inliers,
        o.stats.attempts
    );
    if o.failure.is_none() {
        let (t, r) = o.pose.error_to(truth);
        assert!(
            t < OK_M,
            "{what}: claimed success {t:.3} m / {:.2}° from the truth ({} inliers)",
            r.to_degrees(),
            o.quality.inliers
        );
    }
}

/// Priors 10–20 cm and ≤ 1.5° off, same lighting: success within 5 cm.
///
/// Verifies: VTSM-RELOC-020
#[test]
fn converges_from_perturbed_priors() {
    // (stop, look_at, prior/engine seed): both circles, both tubes.
    let cases = [(3, 0, 1), (9, 0, 2), (18, 1, 3), (26, 1, 4)];
    for (stop, look_at, seed) in cases {
        let (rig, truth, pair) = capture(stop, look_at);
        let prior = perturbed_prior(&truth, seed);
        let (t0, r0) = prior.error_to(&truth);
        assert!(
            (0.0999..=0.2001).contains(&t0) && r0.to_degrees() <= 1.5001,
            "setup: prior {t0} m {}°",
            r0.to_degrees()
        );
        let o = relocalize(rig, &pair, prior, seed);
        let (t, r) = o.pose.error_to(&truth);
        assert_eq!(
            o.failure, None,
            "stop {stop} look {look_at} seed {seed}: failed, {t:.3} m from truth, stats {:?}",
            o.stats
        );
        assert!(
            t < OK_M,
            "stop {stop} look {look_at} seed {seed}: {t:.4} m, {:.3}° (prior {t0:.3} m)",
            r.to_degrees()
        );
        assert!(t < t0, "no improvement over the prior");
    }
}

/// A prior 1 m off: a failure code, not a confident wrong pose.
///
/// Verifies: VTSM-RELOC-015
#[test]
fn prior_one_metre_off_does_not_give_a_confident_wrong_pose() {
    let (rig, truth, pair) = capture(3, 0);
    // One direction only: a failing run goes through every Stall and Reseed
    // before it gives up, the slowest case of all.
    let prior = Pose::new(
        truth.rotation(),
        truth.translation() + Vec3::new(0.6, 0.8, 0.0),
    );
    assert!((prior.error_to(&truth).0 - 1.0).abs() < 1e-3);
    let o = relocalize_bounded(rig, &pair, prior, 5);
    assert_not_confidently_wrong(&o, &truth, "prior 1 m off");
}

/// Images of a place far from the prior (another stop of the other circle,
/// looking at the other tube): a failure code, or the images' own pose.
///
/// Verifies: VTSM-RELOC-015
#[test]
fn images_of_another_stop_do_not_give_a_confident_wrong_pose() {
    let (_, believed, _) = capture(3, 0);
    let (rig, actual, pair) = capture(22, 1);
    assert!(believed.error_to(&actual).0 > 1.0, "stops not far apart");
    let prior = perturbed_prior(&believed, 7);
    let o = relocalize_bounded(rig, &pair, prior, 7);
    assert_not_confidently_wrong(&o, &actual, "images of another stop");
}

/// Images of another depot (another terrain seed) against this map: failure.
///
/// Verifies: VTSM-RELOC-015
#[test]
fn images_of_another_terrain_do_not_give_a_confident_wrong_pose() {
    let other = Scene::new(TERRAIN, SCENE_SEED + 100, Profile::Test);
    let (rig, truth, pair) =
        other.capture(&other.lighting(HOURS), &Capture::from_index(3, 0, 0.40));
    let prior = perturbed_prior(&truth, 8);
    let o = relocalize_bounded(rig, &pair, prior, 8);
    // The other depot's pose is no pose in this map: success would be wrong.
    assert!(
        o.failure.is_some(),
        "claimed success on another depot: {:?}, {} inliers",
        o.pose.t(),
        o.quality.inliers
    );
}

/// Same inputs and seed: the whole outcome is bit-identical.
///
/// Verifies: VTSM-RELOC-014
#[test]
fn same_inputs_and_seed_give_a_bit_identical_outcome() {
    let (rig, truth, pair) = capture(9, 0);
    let prior = perturbed_prior(&truth, 2);
    let a = relocalize(rig, &pair, prior, 2);
    let b = relocalize(rig, &pair, prior, 2);
    let bits = |p: &Pose| (p.t().map(f32::to_bits), p.q().map(f32::to_bits));
    assert_eq!(bits(&a.pose), bits(&b.pose));
    assert_eq!(a.failure, b.failure);
    assert_eq!(a.stats, b.stats);
    // Debug prints every f32 in its shortest round-trip form: equal text, equal bits.
    assert_eq!(format!("{a:?}"), format!("{b:?}"));
    // A different seed draws different templates (the check above can fail).
    let c = relocalize(rig, &pair, prior, 12345);
    assert_ne!(format!("{a:?}"), format!("{c:?}"));
}
