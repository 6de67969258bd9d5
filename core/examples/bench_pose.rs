//! Measures the pose stage: time per Umeyama fit and per RANSAC run, work
//! counters, state sizes, and the accuracy of the plain, local-refit and
//! 1/σ²-weighted variants on simulated stereo correspondences.
//!
//! `cargo run --release -p vtsm-core --example bench_pose [trials]`
//!
//! `bench_pose instr` instead runs a fixed workload through four
//! `#[inline(never)]` functions for instruction counting:
//! `valgrind --tool=callgrind target/release/examples/bench_pose instr`, then
//! `callgrind_annotate --inclusive=yes` and divide by the call counts printed.
//!
//! The simulated scene uses the paper profile (5472 px, 77° HFOV, 0.40 m
//! baseline): map points 2–12 m ahead, left/right peaks perturbed by Gaussian
//! pixel noise, triangulated by `stereo::triangulate`, map points perturbed by
//! 2 mm, and a fraction of correspondences replaced by gross outliers.

// A host-side measuring tool: a broken setup should stop it loudly.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use std::hint::black_box;
use std::time::Instant;
use vtsm_core::config::MAX_CORR;
use vtsm_core::geom::{Camera, Pose, StereoRig, Vec3};
use vtsm_core::pose::{self, Correspondence, Ransac, RansacConfig};
use vtsm_core::rng::Rng;
use vtsm_core::stereo;

#[path = "../testkit/testkit.rs"]
mod testkit;
use testkit::random_pose;

/// `n` stereo correspondences under `truth`, a fraction `outliers` of them gross.
fn stereo_pairs(
    rng: &mut Rng,
    rig: &StereoRig,
    truth: &Pose,
    n: usize,
    outliers: f32,
    sigma_px: f32,
) -> Vec<Correspondence> {
    let mut v = Vec::with_capacity(n);
    while v.len() < n {
        let p = Vec3::new(
            rng.uniform(-4.0, 4.0),
            rng.uniform(-0.5, 1.5),
            rng.uniform(2.0, 12.0),
        );
        let Some((l, r)) = rig.project_stereo(&p) else {
            continue;
        };
        let l = [
            l[0] + sigma_px * rng.normal(),
            l[1] + sigma_px * rng.normal(),
        ];
        let r = [
            r[0] + sigma_px * rng.normal(),
            r[1] + sigma_px * rng.normal(),
        ];
        let sigma_d = sigma_px * std::f32::consts::SQRT_2;
        let Ok(q) = stereo::triangulate(rig, l, r, 8.0, sigma_d, 1.0) else {
            continue;
        };
        let mut world =
            truth.transform_point(&p) + Vec3::new(rng.normal(), rng.normal(), rng.normal()) * 0.002;
        if rng.next_f32() < outliers {
            world = truth.transform_point(&Vec3::new(
                rng.uniform(-4.0, 4.0),
                rng.uniform(-0.5, 1.5),
                rng.uniform(2.0, 12.0),
            ));
        }
        v.push(Correspondence {
            world,
            cam: q.p_cam,
            sigma_m: q.sigma_z_m,
            variant: vtsm_core::pose::VARIANT_UNKNOWN,
            mask_index: vtsm_core::pose::MASK_INDEX_UNKNOWN,
        });
    }
    v
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

#[inline(never)]
fn instr_umeyama_3(pairs: &[Correspondence]) -> Option<Pose> {
    black_box(0); // keeps the linker from merging identical wrappers
    pose::umeyama(pairs).ok()
}

#[inline(never)]
fn instr_umeyama_100(pairs: &[Correspondence]) -> Option<Pose> {
    black_box(1); // keeps the linker from merging identical wrappers
    pose::umeyama(pairs).ok()
}

#[inline(never)]
fn instr_ransac_40(pairs: &[Correspondence], cfg: &RansacConfig, seed: u64) -> u16 {
    black_box(2); // keeps the linker from merging identical wrappers
    let mut mask = [false; MAX_CORR];
    pose::ransac(pairs, cfg, &mut Rng::new(seed), &mut mask).map_or(0, |e| e.iterations)
}

#[inline(never)]
fn instr_ransac_60(pairs: &[Correspondence], cfg: &RansacConfig, seed: u64) -> u16 {
    black_box(3); // keeps the linker from merging identical wrappers
    let mut mask = [false; MAX_CORR];
    pose::ransac(pairs, cfg, &mut Rng::new(seed), &mut mask).map_or(0, |e| e.iterations)
}

/// Fixed workload for instruction counting (see the module docs).
fn instr(rig: &StereoRig) {
    let mut rng = Rng::new(5);
    let cfg = RansacConfig {
        iterations: 1000,
        inlier_m: 0.05,
        confidence: 0.999,
        sigma_gate: vtsm_core::pose::SIGMA_GATE,
    };
    let calls = 100u64;
    let mut it = [0u64; 2];
    for k in 0..calls {
        let truth = random_pose(&mut rng);
        let p100 = stereo_pairs(&mut rng, rig, &truth, 100, 0.0, 0.3);
        black_box(instr_umeyama_3(black_box(&p100[..3])));
        black_box(instr_umeyama_100(black_box(&p100)));
        let p40 = stereo_pairs(&mut rng, rig, &truth, 100, 0.4, 0.3);
        it[0] += u64::from(instr_ransac_40(black_box(&p40), &cfg, k));
        let p60 = stereo_pairs(&mut rng, rig, &truth, 100, 0.6, 0.3);
        it[1] += u64::from(instr_ransac_60(black_box(&p60), &cfg, k));
    }
    println!(
        "instr: {calls} calls each; RANSAC samples drawn: 40 % outliers {}, 60 % outliers {}",
        it[0], it[1]
    );
}

fn main() {
    if std::env::args().nth(1).as_deref() == Some("instr") {
        let rig = StereoRig::new(Camera::from_hfov(5472, 3648, 77.0).unwrap(), 0.40).unwrap();
        instr(&rig);
        return;
    }
    let trials: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(2000);
    let rig = StereoRig::new(Camera::from_hfov(5472, 3648, 77.0).unwrap(), 0.40).unwrap();
    println!(
        "sizes: Correspondence {} B, Ransac state {} B, Estimate {} B, pairs buffer (MAX_CORR={MAX_CORR}) {} B",
        std::mem::size_of::<Correspondence>(),
        std::mem::size_of::<Ransac>(),
        std::mem::size_of::<pose::Estimate>(),
        MAX_CORR * std::mem::size_of::<Correspondence>(),
    );

    // ---- timing: Umeyama -------------------------------------------------
    let mut rng = Rng::new(1);
    for n in [3usize, 30, 100, 256] {
        let truth = random_pose(&mut rng);
        let pairs = stereo_pairs(&mut rng, &rig, &truth, n, 0.0, 0.3);
        let reps = 20_000 / n.max(10) * 10;
        let mut times = Vec::new();
        for _ in 0..15 {
            let t0 = Instant::now();
            for _ in 0..reps {
                black_box(pose::umeyama(black_box(&pairs)).ok());
            }
            times.push(t0.elapsed().as_secs_f64() * 1e9 / reps as f64);
        }
        let (_, st) = pose::umeyama_with_stats(&pairs).unwrap();
        println!(
            "umeyama n={n:3}: {:8.0} ns median of 15 x {reps} ({} Jacobi sweeps)",
            median(times),
            st.jacobi_sweeps
        );
    }

    // ---- timing and work: RANSAC ------------------------------------------
    for (n, out) in [(100usize, 0.4f32), (100, 0.6), (256, 0.6)] {
        let cfg = RansacConfig {
            iterations: 1000,
            inlier_m: 0.05,
            confidence: 0.999,
            sigma_gate: vtsm_core::pose::SIGMA_GATE,
        };
        let sets: Vec<_> = (0..200)
            .map(|_| {
                let truth = random_pose(&mut rng);
                stereo_pairs(&mut rng, &rig, &truth, n, out, 0.3)
            })
            .collect();
        let mut mask = [false; MAX_CORR];
        let (mut it, mut res, mut sweeps, mut max_it) = (0u64, 0u64, 0u64, 0u16);
        let t0 = Instant::now();
        for (k, pairs) in sets.iter().enumerate() {
            let mut r = Rng::new(k as u64);
            if let Ok(e) = pose::ransac(pairs, &cfg, &mut r, &mut mask) {
                it += u64::from(e.iterations);
                res += u64::from(e.stats.residuals_evaluated);
                sweeps += u64::from(e.stats.jacobi_sweeps);
                max_it = max_it.max(e.iterations);
            }
        }
        let us = t0.elapsed().as_secs_f64() * 1e6 / sets.len() as f64;
        let m = sets.len() as f64;
        println!(
            "ransac n={n} outliers={:.0}%: {us:7.1} us/run, iterations mean {:.1} max {max_it}, residuals mean {:.0}, Jacobi sweeps mean {:.0}",
            out * 100.0,
            it as f64 / m,
            res as f64 / m,
            sweeps as f64 / m
        );
    }

    // ---- accuracy: plain vs local refit vs weighted final refit ---------------
    // (name, local refit, weighted final refit)
    let variants = [
        ("plain RANSAC + refit", false, false),
        ("local refit (default)", true, false),
        ("local refit + 1/sigma^2 final refit", true, true),
    ];
    for sigma_px in [0.3f32, 1.0] {
        for (name, lo, weighted) in variants {
            let mut rng = Rng::new(77);
            let (mut et, mut er, mut ok) = (Vec::new(), Vec::new(), 0usize);
            for k in 0..trials {
                let truth = random_pose(&mut rng);
                let pairs = stereo_pairs(&mut rng, &rig, &truth, 100, 0.3, sigma_px);
                let cfg = RansacConfig {
                    iterations: 1000,
                    inlier_m: 0.05,
                    confidence: 0.999,
                    sigma_gate: vtsm_core::pose::SIGMA_GATE,
                };
                let mut mask = [false; MAX_CORR];
                let mut s = Ransac::new(&pairs, &cfg, Rng::new(k as u64))
                    .unwrap()
                    .with_local_refit(lo)
                    .with_weighted_refit(weighted);
                s.run_chunk(&pairs, u16::MAX).unwrap();
                if let Ok(e) = s.finish(&pairs, &mut mask) {
                    let (t, r) = e.pose.error_to(&truth);
                    et.push(f64::from(t) * 1e3);
                    er.push(f64::from(r).to_degrees());
                    ok += 1;
                }
            }
            let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
            println!(
                "accuracy sigma_px={sigma_px} 30% outliers, {name:38}: {ok}/{trials} ok, translation median {:.2} mm rms {:.2} mm, rotation median {:.4} deg rms {:.4} deg",
                median(et.clone()),
                rms(&et),
                median(er.clone()),
                rms(&er)
            );
        }
    }
}
