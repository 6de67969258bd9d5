//! One relocalization from start to end, as the crate docs' "Start here"
//! shows it, printing what a newcomer wants to see: the prior's error, the
//! pose's error, the stated uncertainty and the work the engine did.
//!
//! ```text
//! cargo run --release -p vtsm-core --example start_here -- [SEED]
//! ```
//!
//! The map is the crate's built-in test map (a textured heightfield 8 m
//! across); the stereo pair is rendered from it at a known pose, so the
//! error is measured against the truth. On a rover the map comes from
//! `vtsm map build` and the pair from the cameras (see `vtsm-hal`'s
//! `Runner::run`).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::{UnitQuaternion, Vector3};
use vtsm_core::geom::Pose;
use vtsm_core::image::GrayView;
use vtsm_core::map::MapView;
use vtsm_core::ncc::Run;
use vtsm_core::reloc::workspace::TEST_WORKSPACE;
use vtsm_core::reloc::{Setup, Workspace};
use vtsm_core::FailureCode;

#[path = "../testkit/testkit.rs"]
mod testkit;

fn main() -> Result<(), FailureCode> {
    let seed: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(7);

    // The map product, checked once; the view is what everything reads.
    let bytes = testkit::build_map(1);
    let map = MapView::new_checked(&bytes)?;

    // A rectified 640×480 pair seen from the true pose.
    let rig = testkit::rig();
    let truth = testkit::camera_pose(0.6, 0.2);
    let left = testkit::render_full(&map, &rig.cam(), &truth, 0.85, 20.0);
    let right = testkit::render_full(&map, &rig.cam(), &rig.world_from_right(&truth), 0.85, 20.0);
    let left = GrayView::new(&left, 640, 480, 640)?;
    let right = GrayView::new(&right, 640, 480, 640)?;

    // The prior: 15 cm and 1° off the truth.
    let prior = Pose::new(
        truth.rotation() * UnitQuaternion::from_scaled_axis(Vector3::z() * 1f32.to_radians()),
        truth.translation() + Vector3::new(0.12, -0.09, 0.0),
    );

    // Caller-owned workspace for the test profile.
    let (mut ws_bytes, mut words, mut runs) = (
        vec![0u8; TEST_WORKSPACE.bytes],
        vec![0u32; TEST_WORKSPACE.words],
        vec![Run::default(); TEST_WORKSPACE.runs],
    );
    let ws = Workspace::new(TEST_WORKSPACE, &mut ws_bytes, &mut words, &mut runs)?;

    let params = testkit::test_params();
    let mut engine = Setup::new(&map, left, right, &rig, &params, &prior, seed).build(ws)?;
    let out = engine.run_to_completion(0);

    let (prior_m, prior_rad) = prior.error_to(&truth);
    let (err_m, err_rad) = out.pose.error_to(&truth);
    println!("seed {seed}");
    println!(
        "prior error   {:7.1} mm {:6.3}°",
        prior_m * 1e3,
        prior_rad.to_degrees()
    );
    println!(
        "pose error    {:7.2} mm {:6.3}°",
        err_m * 1e3,
        err_rad.to_degrees()
    );
    println!("failure       {}", out.failure.map_or("none", |c| c.name()));
    println!(
        "inliers       {} of the last round's correspondences",
        out.quality.inliers
    );
    println!(
        "work          {} rounds, {} attempts, {} renders, {} template matches",
        out.stats.rounds,
        out.stats.attempts,
        out.stats.pipeline.renders,
        out.stats.pipeline.matches.iter().sum::<u32>()
    );
    Ok(())
}
