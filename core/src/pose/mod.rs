//! `GetTransform` (paper §III-E): the rigid transform between map points and
//! camera points, by a closed-form least-squares fit inside a bounded RANSAC.
//!
//! Inputs: [`Correspondence`]s `{ world, cam, sigma_m }` (at most
//! [`MAX_CORR`](crate::config::MAX_CORR)); for RANSAC a [`RansacConfig`] and the core [`Rng`](crate::rng::Rng).
//! Outputs: `world_from_cam` as a [`Pose`] (`world = R cam + t`), and for RANSAC
//! an [`Estimate`] with inlier count, RMS residual, work counters and up to
//! [`MAX_POSE_CANDIDATES`] distinct pose candidates for `Distribute`.
//!
//! * Fit ([`umeyama`]): Umeyama's rigid alignment without scale, solved in the
//!   closed form of Horn (1987): the rotation is the unit quaternion that is the
//!   dominant eigenvector of a symmetric 4×4 matrix built from the cross-covariance
//!   of the centred point sets. A unit quaternion is always a proper rotation
//!   (det = +1), so no reflection fix-up is needed. The 4×4 eigenproblem is solved
//!   by cyclic Jacobi rotations capped at [`JACOBI_MAX_SWEEPS`] sweeps of six
//!   rotations each. Points are centred on their centroids before the
//!   cross-covariance is accumulated (f32 precision).
//! * Degeneracy: for the scatter matrix `S` of each centred set, coincident points
//!   have a tiny trace (RMS spread below [`MIN_SPREAD_M`]) and collinear points a
//!   tiny second invariant `m₂ = λ₁λ₂ + λ₁λ₃ + λ₂λ₃` relative to `tr(S)²`
//!   (below [`MIN_PLANARITY`]); since `λ₁λ₂ ≤ m₂ ≤ 3λ₁λ₂` and `tr/3 ≤ λ₁ ≤ tr`,
//!   this bounds `λ₂/λ₁` in closed form, without an eigen-solve.
//! * RANSAC ([`ransac`](fn@ransac), resumable as [`Ransac`]): minimal samples of three
//!   distinct pairs drawn with exactly three PRNG draws; a rigid-distance check
//!   and the degeneracy test per sample; an inlier gate in metres, optionally
//!   widened per pair by its depth uncertainty; a hard cap
//!   `min(cfg.iterations, MAX_RANSAC_ITER)`; early exit once
//!   `N = log(1 − p) / log(1 − w³)` samples have been drawn; each new best
//!   hypothesis is refitted on its own inliers (local optimisation); a final
//!   refit on all inliers with recount (at most [`REFIT_ROUNDS`] rounds).
//!
//! Bounds per RANSAC iteration: 3 PRNG draws, one 3-point fit (≤ 16 Jacobi
//! sweeps), `n ≤ MAX_CORR` residuals, ≤ `MAX_POSE_CANDIDATES` candidate
//! comparisons; plus at most `n` local refits per search (each one fit and
//! `3n` residuals), since each needs a strictly larger inlier count. No allocation; f32 through nalgebra and libm, no FMA, so the same
//! seed gives the same bits on every target.
//!
//! Layout: the shared types are defined here; the fit is in `fit.rs` and the
//! search in `ransac.rs`, both re-exported from this module.

mod fit;
mod ransac;
mod refine;

pub use fit::{
    umeyama, umeyama_weighted, umeyama_with_stats, FitStats, JACOBI_MAX_SWEEPS, MIN_PLANARITY,
    MIN_SIGMA_M, MIN_SPREAD_M,
};
pub use ransac::{
    ransac, required_iterations, Ransac, RansacConfig, RansacStats, DEFAULT_CONFIDENCE,
    REFIT_ROUNDS, SIGMA_GATE,
};
pub use refine::{
    refine, Covariance, RefineConfig, RefineStats, Refined, DEFAULT_MAX_STEP_RAD, SHARED_R,
    SHARED_T,
};

use crate::config::MAX_POSE_CANDIDATES;
use crate::geom::{Pose, Vec3};

/// One map-to-camera point correspondence.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Correspondence {
    /// Map point, world frame, metres.
    pub world: Vec3,
    /// The same point triangulated in the left camera frame, metres.
    pub cam: Vec3,
    /// One-sigma uncertainty of `cam` (the stereo depth sigma), metres, ≥ 0.
    pub sigma_m: f32,
    /// The template variant whose matches gave `cam`
    /// ([`Variant::index`](crate::reloc::Variant::index)), or
    /// [`VARIANT_UNKNOWN`]. The engine's final round keeps only
    /// gradient-domain pairs (VTSM-RELOC-041).
    pub variant: u8,
    /// The map's mask vertex the pair measures
    /// ([`MapView::mask_vertex`](crate::map::MapView::mask_vertex)), or
    /// [`MASK_INDEX_UNKNOWN`]. Revisit draws the next round's first attempts
    /// from the inliers' (VTSM-RELOC-046).
    pub mask_index: u32,
}

/// [`Correspondence::variant`] of a pair that no template match produced.
pub const VARIANT_UNKNOWN: u8 = u8::MAX;
/// [`Correspondence::mask_index`] of a pair that no map vertex produced.
pub const MASK_INDEX_UNKNOWN: u32 = u32::MAX;

impl Correspondence {
    fn is_finite(&self) -> bool {
        self.world
            .iter()
            .chain(self.cam.iter())
            .all(|c| c.is_finite())
            && self.sigma_m.is_finite()
            && self.sigma_m >= 0.0
    }
}

/// A pose hypothesis and its inlier count.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    /// `world_from_cam`.
    pub pose: Pose,
    /// Pairs within the inlier gate.
    pub inliers: u16,
}

/// RANSAC result.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    /// Maximum-inlier `world_from_cam`, refitted on its inliers.
    pub pose: Pose,
    /// Inliers of `pose`.
    pub inliers: u16,
    /// RMS residual of the inliers under `pose`, metres.
    pub rms_m: f32,
    /// Samples drawn (same as `stats.iterations`).
    pub iterations: u16,
    /// Distinct hypotheses, pairwise farther apart than the inlier gate in the
    /// sense of `|Δt| + θ·(mean camera-point range)`: first `pose`, then the
    /// others by inlier count, most first.
    pub candidates: heapless::Vec<Candidate, MAX_POSE_CANDIDATES>,
    /// Work counters.
    pub stats: RansacStats,
}

/// Test data shared by the fit and RANSAC tests.
#[cfg(test)]
mod test_pairs {
    extern crate std;
    use super::Correspondence;
    use crate::geom::{Pose, Vec3};
    use crate::rng::Rng;
    use std::vec::Vec;

    /// A rover-like scene: points 2–10 m ahead of the left camera.
    pub(super) fn random_cam_point(rng: &mut Rng) -> Vec3 {
        Vec3::new(
            rng.uniform(-3.0, 3.0),
            rng.uniform(-1.0, 1.5),
            rng.uniform(2.0, 10.0),
        )
    }

    pub(super) fn exact_pairs(rng: &mut Rng, pose: &Pose, n: usize) -> Vec<Correspondence> {
        (0..n)
            .map(|_| {
                let cam = random_cam_point(rng);
                Correspondence {
                    world: pose.transform_point(&cam),
                    cam,
                    sigma_m: 0.01,
                    variant: crate::pose::VARIANT_UNKNOWN,
                    mask_index: crate::pose::MASK_INDEX_UNKNOWN,
                }
            })
            .collect()
    }

    pub(super) fn add_noise(pairs: &mut [Correspondence], rng: &mut Rng, sigma: f32) {
        for p in pairs {
            p.world += Vec3::new(rng.normal(), rng.normal(), rng.normal()) * sigma;
        }
    }
}
