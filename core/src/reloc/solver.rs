//! GetTransform for the engine: [`crate::pose::ransac`] behind [`super::Solver`].

use super::{Correspondence, Solution, Solver};
use crate::config::Params;
use crate::failure::FailureCode;
use crate::rng::Rng;

/// GetTransform with [`crate::pose::ransac`] (Umeyama + RANSAC).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RansacSolver {
    /// RANSAC settings.
    pub cfg: crate::pose::RansacConfig,
}

impl RansacSolver {
    /// Settings from validated params.
    pub fn from_params(p: &Params) -> Self {
        Self {
            cfg: crate::pose::RansacConfig::from_params(p),
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
        let e = crate::pose::ransac(pairs, &self.cfg, rng, inlier_mask)?;
        Ok(Solution {
            pose: e.pose,
            inliers: e.inliers,
            rms_m: e.rms_m,
            iterations: e.iterations,
            candidates: e.candidates,
        })
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::geom::{Pose, Vec3};
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
        assert_eq!(
            s.solve(&pairs[..2], &mut Rng::new(1), &mut mask).err(),
            Some(FailureCode::PoseTooFewPoints)
        );
    }
}
