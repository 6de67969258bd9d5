//! Relocalization speed and work at the test profile (640×480, ℓ = 64,
//! N_corr = 40, N_iter = 5) on a synthetic textured heightfield: wall time per
//! relocalization, attempts, renders, matches, NCC multiply-accumulates,
//! RANSAC hypotheses, and the pose error, from priors perturbed 10–20 cm / ≤ 1.5°.
//!
//! ```text
//! cargo run --release -p vtsm-core --example bench_reloc -- [RUNS]
//! ```
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::UnitQuaternion;
use std::time::Instant;
use vtsm_core::geom::{Pose, Vec3};
use vtsm_core::image::GrayView;
use vtsm_core::map::MapView;
use vtsm_core::ncc::Run;
use vtsm_core::reloc::workspace::TEST_WORKSPACE;
use vtsm_core::reloc::{Setup, Workspace};
use vtsm_core::rng::Rng;

#[path = "../testkit/testkit.rs"]
mod testkit;
use testkit::{build_map, camera_pose, render_full, rig, test_params};

fn main() {
    let runs: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(10);
    let bytes = build_map(1);
    let map = MapView::new_checked(&bytes).unwrap();
    let rig = rig();
    let truth = camera_pose(0.6, 0.2);
    let left = render_full(&map, &rig.cam(), &truth, 0.85, 20.0);
    let right = render_full(&map, &rig.cam(), &rig.world_from_right(&truth), 0.85, 20.0);
    let p = test_params();
    let (mut b, mut w, mut r) = (
        vec![0u8; TEST_WORKSPACE.bytes],
        vec![0u32; TEST_WORKSPACE.words],
        vec![Run::default(); TEST_WORKSPACE.runs],
    );
    let lv = GrayView::new(&left, 640, 480, 640).unwrap();
    let rv = GrayView::new(&right, 640, 480, 640).unwrap();
    let mut rng = Rng::new(2024);
    let mut times = Vec::new();
    println!("run  t_prior_m  r_prior_deg  err_m    err_deg  ok  attempts renders  ncc_macs      ransac_it  ms");
    for k in 0..runs {
        let t = rng.uniform(0.10, 0.20);
        let rdeg = rng.uniform(0.0, 1.5);
        let axis = rng.unit_vector3();
        let az = rng.uniform(0.0, core::f32::consts::TAU);
        let d = Vec3::new(libm::cosf(az), libm::sinf(az), 0.0) * t;
        let prior = Pose::new(
            truth.rotation() * UnitQuaternion::from_scaled_axis(axis * rdeg.to_radians()),
            truth.translation() + d,
        );
        let setup = Setup::new(&map, lv, rv, &rig, &p, &prior, k);
        let options = setup.options().with_min_inliers(15).unwrap();
        let setup = setup.with_options(options).unwrap();
        let ws = Workspace::new(TEST_WORKSPACE, &mut b, &mut w, &mut r).unwrap();
        let mut reloc = setup.build(ws).unwrap();
        let t0 = Instant::now();
        let out = reloc.run_to_completion(0);
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        times.push(ms);
        let (et, er) = out.pose.error_to(&truth);
        let s = out.stats;
        println!(
            "{k:>3}  {t:>9.3}  {rdeg:>11.2}  {et:>7.4}  {:>7.3}  {:>2}  {:>8} {:>7}  {:>12}  {:>9}  {ms:.1}",
            er.to_degrees(),
            if out.failure.is_none() { "y" } else { "n" },
            s.attempts,
            s.pipeline.renders,
            s.pipeline.ncc_macs,
            s.ransac_iterations,
        );
    }
    times.sort_by(f64::total_cmp);
    let mean = times.iter().sum::<f64>() / times.len() as f64;
    println!(
        "ms per relocalization: mean {mean:.1}, median {:.1}, max {:.1} over {} runs",
        times[times.len() / 2],
        times[times.len() - 1],
        times.len()
    );
}
