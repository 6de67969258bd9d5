//! GetTransform for the engine: [`crate::pose::ransac`] behind [`super::Solver`],
//! and the final estimate ([`crate::pose::refine`]) when it is given the rig.

use super::{Correspondence, Solution, Solver};
use crate::config::Params;
use crate::failure::FailureCode;
use crate::geom::{Pose, StereoRig};
use crate::pose::{RefineConfig, Refined};
use crate::rng::Rng;

/// GetTransform with [`crate::pose::ransac`] (Umeyama + RANSAC), resumable
/// in chunks through [`crate::pose::Ransac`].
#[derive(Clone, Debug)]
pub struct RansacSolver {
    /// RANSAC settings.
    pub cfg: crate::pose::RansacConfig,
    /// Whether the engine runs RANSAC in chunks (one work unit each).
    pub chunked: bool,
    /// Rig and settings of the final refinement (`None`: no refinement and no
    /// covariance).
    pub refine: Option<(StereoRig, RefineConfig)>,
    /// Factor on the σ term of the gate of the next solves ([`Solver::set_sigma_scale`]).
    sigma_scale: f32,
    state: Option<crate::pose::Ransac>,
}

fn to_solution(e: crate::pose::Estimate) -> Solution {
    Solution {
        pose: e.pose,
        inliers: e.inliers,
        rms_m: e.rms_m,
        iterations: e.iterations,
        candidates: e.candidates,
    }
}

impl RansacSolver {
    /// Settings from validated params.
    pub fn from_params(p: &Params) -> Self {
        Self {
            cfg: crate::pose::RansacConfig::from_params(p),
            chunked: true,
            refine: None,
            sigma_scale: 1.0,
            state: None,
        }
    }

    /// Refine the final pose on the reprojection error in `rig` with `cfg`
    /// ([`crate::pose::refine`]).
    #[must_use]
    pub fn with_refinement(mut self, rig: &StereoRig, cfg: RefineConfig) -> Self {
        self.refine = Some((*rig, cfg));
        self
    }

    /// The RANSAC settings of the next solve: `cfg` with its σ term scaled.
    fn gated(&self) -> crate::pose::RansacConfig {
        crate::pose::RansacConfig {
            sigma_gate: self.cfg.sigma_gate * self.sigma_scale,
            ..self.cfg
        }
    }
}

impl Solver for RansacSolver {
    fn solve(
        &mut self,
        pairs: &[Correspondence],
        rng: &mut Rng,
        inlier_mask: &mut [bool],
    ) -> Result<Solution, FailureCode> {
        crate::pose::ransac(pairs, &self.gated(), rng, inlier_mask).map(to_solution)
    }

    fn start(&mut self, pairs: &[Correspondence], rng: Rng) -> Result<bool, FailureCode> {
        self.state = None;
        if !self.chunked {
            return Ok(true);
        }
        self.state = Some(crate::pose::Ransac::new(pairs, &self.gated(), rng)?);
        Ok(false)
    }

    fn run_chunk(
        &mut self,
        pairs: &[Correspondence],
        max_iterations: u16,
    ) -> Result<bool, FailureCode> {
        match self.state.as_mut() {
            Some(r) => r.run_chunk(pairs, max_iterations),
            None => Ok(true),
        }
    }

    fn finish(
        &mut self,
        pairs: &[Correspondence],
        inlier_mask: &mut [bool],
    ) -> Result<Solution, FailureCode> {
        match self.state.take() {
            Some(mut r) => r.finish(pairs, inlier_mask).map(to_solution),
            None => Err(FailureCode::PoseRansacNoConsensus),
        }
    }

    fn refine(
        &mut self,
        pairs: &[Correspondence],
        inlier_mask: &[bool],
        pose: &Pose,
    ) -> Option<Result<Refined, FailureCode>> {
        let (rig, cfg) = self.refine.as_ref()?;
        Some(crate::pose::refine(pairs, inlier_mask, rig, pose, cfg))
    }

    fn set_sigma_scale(&mut self, scale: f32) {
        self.sigma_scale = if scale.is_finite() && scale >= 1.0 {
            scale
        } else {
            1.0
        };
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::geom::Vec3;
    use nalgebra::UnitQuaternion;
    use std::vec::Vec;

    /// Verifies: VTSM-RELOC-018
    #[test]
    fn ransac_solver_recovers_known_pose_despite_outliers() {
        let truth = Pose::new(
            UnitQuaternion::from_euler_angles(0.1, -0.2, 1.0),
            Vec3::new(2.0, -1.0, 0.5),
        );
        let mut rng = Rng::new(4);
        let pairs: Vec<Correspondence> = (0..60)
            .map(|i| {
                let cam = Vec3::new(
                    rng.uniform(-2.0, 2.0),
                    rng.uniform(-1.0, 1.0),
                    rng.uniform(1.0, 6.0),
                );
                let mut world = truth.transform_point(&cam);
                if i % 4 == 0 {
                    world += Vec3::new(rng.uniform(0.5, 2.0), rng.uniform(-2.0, 2.0), 0.3);
                }
                Correspondence {
                    world,
                    cam,
                    sigma_m: 0.005,
                    variant: crate::pose::VARIANT_UNKNOWN,
                    mask_index: crate::pose::MASK_INDEX_UNKNOWN,
                }
            })
            .collect();
        let p = Params::paper();
        let mut s = RansacSolver::from_params(&p);
        let mut mask = [false; 64];
        let sol = s.solve(&pairs, &mut Rng::new(1), &mut mask).unwrap();
        let (et, er) = sol.pose.error_to(&truth);
        assert!(et < 1e-3 && er < 1e-3, "{et} {er}");
        assert_eq!(sol.inliers, 45);
        for (i, m) in mask.iter().take(60).enumerate() {
            assert_eq!(*m, i % 4 != 0, "pair {i}");
        }
        assert!(sol.iterations >= 1 && sol.iterations <= p.ransac_iter);
        // The chunked form gives the same solution bit for bit.
        assert!(!s.start(&pairs, Rng::new(1)).unwrap());
        let mut chunks = 0;
        while !s.run_chunk(&pairs, 7).unwrap() {
            chunks += 1;
            assert!(chunks <= 1 + usize::from(p.ransac_iter) / 7);
        }
        let mut mask2 = [false; 64];
        let chunked = s.finish(&pairs, &mut mask2).unwrap();
        assert_eq!(chunked, sol);
        assert_eq!(mask2, mask);
        assert_eq!(
            s.solve(&pairs[..2], &mut Rng::new(1), &mut mask).err(),
            Some(FailureCode::PoseTooFewPoints)
        );
    }

    /// Verifies: VTSM-RELOC-038
    #[test]
    fn sigma_scale_widens_only_the_depth_term_of_the_gate() {
        // One pair in four displaced 10 cm along its camera ray, σ = 1 cm:
        // outside the 5 cm gate with 3σ (√(5² + 3²) ≈ 5.8 cm), inside it
        // with 4 × 3σ (13 cm).
        let truth = Pose::new(UnitQuaternion::identity(), Vec3::new(0.0, 0.0, 0.0));
        let mut rng = Rng::new(9);
        let pairs: Vec<Correspondence> = (0..40)
            .map(|i| {
                let cam = Vec3::new(
                    rng.uniform(-2.0, 2.0),
                    rng.uniform(-1.0, 1.0),
                    rng.uniform(2.0, 6.0),
                );
                let shift = if i % 4 == 0 { 0.1 } else { 0.0 };
                Correspondence {
                    world: truth.transform_point(&(cam + cam.normalize() * shift)),
                    cam,
                    sigma_m: 0.01,
                    variant: crate::pose::VARIANT_UNKNOWN,
                    mask_index: crate::pose::MASK_INDEX_UNKNOWN,
                }
            })
            .collect();
        let p = Params::paper();
        let mut s = RansacSolver::from_params(&p);
        s.chunked = false;
        let mut mask = [false; 64];
        let narrow = s.solve(&pairs, &mut Rng::new(1), &mut mask).unwrap();
        s.set_sigma_scale(4.0);
        let wide = s.solve(&pairs, &mut Rng::new(1), &mut mask).unwrap();
        assert_eq!(narrow.inliers, 30);
        assert_eq!(wide.inliers, 40);
        // Back to 1 (and anything below 1 or not finite means 1): the same
        // solution as before, bit for bit.
        for back in [1.0, 0.25, f32::NAN] {
            s.set_sigma_scale(back);
            assert_eq!(
                s.solve(&pairs, &mut Rng::new(1), &mut mask).unwrap(),
                narrow
            );
        }
    }

    /// Observes a fixed scene under `truth`: each attempt triangulates one map
    /// point from both images with 0.3 px noise per coordinate; one in ten is
    /// a gross mismatch.
    struct StereoScene {
        rig: StereoRig,
        truth: Pose,
    }

    impl super::super::Attempt for StereoScene {
        fn attempt(
            &mut self,
            _ctx: &super::super::AttemptContext,
            rng: &mut Rng,
            _stats: &mut super::super::PipelineStats,
        ) -> Result<Correspondence, FailureCode> {
            let p = Vec3::new(
                rng.uniform(-4.0, 4.0),
                rng.uniform(-0.5, 1.5),
                rng.uniform(2.0, 15.0),
            );
            let (l, r) = self
                .rig
                .project_stereo(&p)
                .ok_or(FailureCode::RelocSampleOutOfView)?;
            let mut noisy = |x: [f32; 2]| [x[0] + 0.3 * rng.normal(), x[1] + 0.3 * rng.normal()];
            let (l, r) = (noisy(l), noisy(r));
            let pt = crate::stereo::triangulate(&self.rig, l, r, 8.0, 0.42, 0.5)?;
            let mut world = self.truth.transform_point(&p);
            if rng.below(10) == 0 {
                world += Vec3::new(rng.uniform(0.3, 1.0), rng.uniform(-1.0, 1.0), 0.2);
            }
            Ok(Correspondence {
                world,
                cam: pt.p_cam,
                sigma_m: pt.sigma_z_m,
                variant: crate::pose::VARIANT_UNKNOWN,
                mask_index: crate::pose::MASK_INDEX_UNKNOWN,
            })
        }
    }

    /// Verifies: VTSM-RELOC-022
    #[test]
    fn engine_refines_the_final_pose_and_reports_its_covariance() {
        let rig = StereoRig::new(
            crate::geom::Camera::from_hfov(1368, 912, 77.0).unwrap(),
            0.4,
        )
        .unwrap();
        let (mut err_off, mut err_on) = (0.0f64, 0.0f64);
        for seed in 0..20u64 {
            let truth = Pose::new(
                UnitQuaternion::from_euler_angles(0.05 * seed as f32, -0.2, 1.0),
                Vec3::new(2.0, -1.0, 0.5),
            );
            let run = |refine_iter: u8| {
                let p = Params {
                    n_corr: 60,
                    n_iter: 2,
                    refine_iter,
                    ..Params::paper()
                };
                let solver = RansacSolver::from_params(&p)
                    .with_refinement(&rig, RefineConfig::from_params(&p));
                let o = super::super::Options::for_params(&p);
                let scene = StereoScene { rig, truth };
                let mut r =
                    super::super::Relocalizer::new(scene, solver, &p, &o, &truth, seed).unwrap();
                r.run_to_completion(0)
            };
            let off = run(0);
            let on = run(10);
            assert_eq!(off.failure, None);
            assert_eq!(on.failure, None);
            // Same search either way: the refinement only touches the final estimate.
            assert_eq!(on.stats.attempts, off.stats.attempts);
            assert_eq!(on.quality.inliers, off.quality.inliers);
            assert_eq!(off.stats.refine.iterations, 0);
            assert!(!off.stats.refine.accepted);
            assert!(on.stats.refine.iterations >= 1 && on.stats.refine.iterations <= 10);
            assert_eq!(
                usize::from(on.stats.refine.points),
                usize::from(on.quality.inliers)
            );
            // Covariance in both cases, positive on the diagonal.
            for o in [&off, &on] {
                let c = o.quality.covariance.unwrap();
                assert!((0..6).all(|i| c.get(i, i) > 0.0));
                assert!(o.quality.reproj_rms_px > 0.0);
            }
            if on.stats.refine.accepted {
                assert_ne!(on.pose, off.pose);
            } else {
                assert_eq!(on.pose, off.pose);
            }
            err_off += f64::from(off.pose.error_to(&truth).0);
            err_on += f64::from(on.pose.error_to(&truth).0);
        }
        std::println!(
            "mean final error over 20 runs: {:.2} mm RANSAC, {:.2} mm refined",
            err_off / 20.0 * 1e3,
            err_on / 20.0 * 1e3
        );
        assert!(err_on < 0.7 * err_off, "{err_on} vs {err_off}");
    }

    /// Verifies: VTSM-RELOC-042
    #[test]
    fn a_stated_accuracy_ends_the_rounds_once_the_covariance_meets_it() {
        let rig = StereoRig::new(
            crate::geom::Camera::from_hfov(1368, 912, 77.0).unwrap(),
            0.4,
        )
        .unwrap();
        let p = Params {
            n_corr: 60,
            n_iter: 4,
            refine_iter: 10,
            convergence_m: 0.0,
            ..Params::paper()
        };
        for seed in 0..8u64 {
            let truth = Pose::new(
                UnitQuaternion::from_euler_angles(0.05 * seed as f32, -0.2, 1.0),
                Vec3::new(2.0, -1.0, 0.5),
            );
            let run = |acc: Option<super::super::Accuracy>| {
                let solver = RansacSolver::from_params(&p)
                    .with_refinement(&rig, RefineConfig::from_params(&p));
                let o = super::super::Options::for_params(&p)
                    .with_accuracy(acc)
                    .unwrap();
                let scene = StereoScene { rig, truth };
                let mut r =
                    super::super::Relocalizer::new(scene, solver, &p, &o, &truth, seed).unwrap();
                r.run_to_completion(0)
            };
            let full = run(None);
            assert_eq!(full.failure, None);
            assert_eq!(full.stats.successes, 4);
            assert_eq!(
                (full.stats.rounds_saved, full.stats.accuracy_checks),
                (0, 0)
            );
            let c = full.quality.covariance.unwrap();
            // Loose: met after the first pose update.
            let loose = run(Some(super::super::Accuracy {
                sigma_t_m: 1.0,
                sigma_r_deg: 10.0,
            }));
            assert_eq!(loose.failure, None);
            assert_eq!(loose.stats.successes, 1);
            assert_eq!(loose.stats.rounds_saved, 3);
            assert_eq!(loose.stats.accuracy_checks, 1);
            assert!(loose.stats.attempts < full.stats.attempts);
            let lc = loose.quality.covariance.unwrap();
            assert!(lc.sigma_t_m().iter().all(|&s| s <= 1.0));
            // Unreachable: every update checked, nothing saved, the same run.
            let tight = run(Some(super::super::Accuracy {
                sigma_t_m: 1e-9,
                sigma_r_deg: 1e-9,
            }));
            assert_eq!(tight.stats.rounds_saved, 0);
            assert_eq!(tight.stats.accuracy_checks, 3);
            assert_eq!(tight.pose, full.pose);
            assert_eq!(tight.quality.covariance.unwrap(), c);
            assert_eq!(tight.stats.attempts, full.stats.attempts);
        }
        // Out of range is refused.
        let o = super::super::Options::for_params(&p);
        for (t, r) in [
            (0.0, 0.1),
            (0.005, 0.0),
            (2.0, 0.1),
            (0.005, 11.0),
            (f32::NAN, 0.1),
        ] {
            let a = super::super::Accuracy {
                sigma_t_m: t,
                sigma_r_deg: r,
            };
            assert_eq!(
                o.with_accuracy(Some(a)),
                Err(FailureCode::ConfigParamOutOfRange)
            );
        }
    }
}
