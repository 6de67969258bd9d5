//! What a run reports: the [`Outcome`] (pose, failure code, [`Quality`], work
//! [`Stats`], failure log) and the counters behind it.

use crate::config::MAX_ITER;
use crate::failure::{FailureCode, FailureLog};
use crate::geom::Pose;

/// Number of template variants counted in [`PipelineStats::matches`]:
/// size (ℓ, ℓ/2) × filter (gray, Sobel, Laplacian), index `size * 3 + filter`.
pub const MATCH_VARIANTS: usize = 6;

/// Work counters of the per-attempt pipeline.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PipelineStats {
    /// Template renders (left and right count separately).
    pub renders: u32,
    /// Pixels written by the rasterizer.
    pub render_pixels: u64,
    /// Template matches run, per variant.
    pub matches: [u32; MATCH_VARIANTS],
    /// Matches accepted, per variant.
    pub accepted: [u32; MATCH_VARIANTS],
    /// NCC positions scored.
    pub ncc_positions: u64,
    /// NCC multiply-accumulates.
    pub ncc_macs: u64,
    /// Samples rejected because the vertex projects out of view.
    pub out_of_view: u32,
    /// Samples rejected because the vertex is occluded.
    pub occluded: u32,
    /// Successful triangulations.
    pub triangulations: u32,
    /// Attempts that measured their revisit vertex
    /// ([`Options::revisit`](crate::reloc::Options::revisit)).
    pub revisited: u32,
    /// Of those, the attempts that gave a correspondence.
    pub revisit_pairs: u32,
    /// Attempts whose vertex was drawn near an agreeing vertex
    /// ([`Options::near`](crate::reloc::Options::near)).
    pub near_drawn: u32,
    /// Of those, the attempts that gave a correspondence.
    pub near_pairs: u32,
}

impl PipelineStats {
    /// Add the counters of `other` (another attempt's work) to these.
    pub fn add(&mut self, other: &PipelineStats) {
        self.renders = self.renders.saturating_add(other.renders);
        self.render_pixels = self.render_pixels.saturating_add(other.render_pixels);
        for (a, b) in self.matches.iter_mut().zip(other.matches) {
            *a = a.saturating_add(b);
        }
        for (a, b) in self.accepted.iter_mut().zip(other.accepted) {
            *a = a.saturating_add(b);
        }
        self.ncc_positions = self.ncc_positions.saturating_add(other.ncc_positions);
        self.ncc_macs = self.ncc_macs.saturating_add(other.ncc_macs);
        self.out_of_view = self.out_of_view.saturating_add(other.out_of_view);
        self.occluded = self.occluded.saturating_add(other.occluded);
        self.triangulations = self.triangulations.saturating_add(other.triangulations);
        self.revisited = self.revisited.saturating_add(other.revisited);
        self.revisit_pairs = self.revisit_pairs.saturating_add(other.revisit_pairs);
        self.near_drawn = self.near_drawn.saturating_add(other.near_drawn);
        self.near_pairs = self.near_pairs.saturating_add(other.near_pairs);
    }
}

/// Work counters of one run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Work units done (attempts + solves + RANSAC chunks).
    pub work_units: u32,
    /// Rounds started (successful and failed iterations, seeds included).
    pub rounds: u32,
    /// Correspondence attempts.
    pub attempts: u32,
    /// Correspondences produced by attempts.
    pub correspondences: u32,
    /// Correspondences carried over by Reuse.
    pub reused: u32,
    /// GetTransform calls.
    pub solves: u32,
    /// Extra work units spent in chunked GetTransform (RANSAC chunks).
    pub ransac_chunks: u32,
    /// RANSAC hypotheses evaluated, summed.
    pub ransac_iterations: u32,
    /// Successful iterations (pose updates).
    pub successes: u16,
    /// Stall events.
    pub stalls: u16,
    /// Reseed events.
    pub reseeds: u16,
    /// Seeds evaluated in multi-seed mode.
    pub seeds_tried: u16,
    /// First rounds solved a second time with the first-fix gate
    /// ([`Options::first_fix_sigma_scale`](super::Options::first_fix_sigma_scale)).
    pub widened_solves: u16,
    /// Rounds whose viewpoints were re-centred by [`Focus`](super::Focus).
    pub focused_rounds: u16,
    /// Final rounds run on gradient-domain matches only
    /// ([`Options::final_gradient_only`](super::Options::final_gradient_only); 0 or 1).
    pub gradient_rounds: u16,
    /// Final refinement counters (all zero when it did not run).
    pub refine: crate::pose::RefineStats,
    /// Pose updates not made because the stated uncertainty met the
    /// caller's [`Accuracy`](super::Accuracy) first (`n_iter` minus the
    /// updates made; 0 without one).
    pub rounds_saved: u16,
    /// Refinements run to check the caller's [`Accuracy`](super::Accuracy)
    /// after a pose update (0 without one).
    pub accuracy_checks: u16,
    /// Work units spent on [`Verify::repeat_solve`](super::Verify::repeat_solve) (its solve start and
    /// RANSAC chunks); 0 when it did not run.
    pub verify_units: u32,
    /// Pipeline counters.
    pub pipeline: PipelineStats,
}

/// One successful iteration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IterationRecord {
    /// Round index at which it happened.
    pub round: u32,
    /// Inliers of the new estimate.
    pub inliers: u16,
    /// Correspondences given to GetTransform.
    pub pairs: u16,
    /// RMS residual of the inliers, metres.
    pub rms_m: f32,
    /// t̃ used for the viewpoints of this iteration, metres.
    pub t_m: f32,
    /// r̃ used for the viewpoints of this iteration, radians.
    pub r_rad: f32,
    /// Translation change of the estimate, metres.
    pub update_m: f32,
}

/// Quality of the returned pose.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Quality {
    /// Inliers of the returned pose (0 if no iteration succeeded).
    pub inliers: u16,
    /// RMS residual of those inliers, metres.
    pub rms_m: f32,
    /// Inliers over pairs given to GetTransform.
    pub inlier_ratio: f32,
    /// Successful iterations, in order (multi-seed winner first when used).
    pub history: heapless::Vec<IterationRecord, MAX_ITER>,
    /// Covariance of `pose` from the final refinement (see
    /// [`crate::pose::Covariance`] for the frame); `None` if it did not run.
    pub covariance: Option<crate::pose::Covariance>,
    /// RMS reprojection residual of the inliers under `pose`, pixels per
    /// observation (0 if the final refinement did not run).
    pub reproj_rms_px: f32,
    /// RMS spread of the inliers' camera points across their principal
    /// direction (√λ₂ of their scatter about the centroid), metres.
    pub spread_m: f32,
    /// Translation and rotation (radians) between the final pose and the
    /// repeated solve of [`Verify::repeat_solve`](super::Verify::repeat_solve); `None` if it did not run.
    pub verify_diff: Option<(f32, f32)>,
}

/// The result of a relocalization.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// Best `world_from_left` (the prior if no iteration succeeded).
    pub pose: Pose,
    /// `None` on success; otherwise why it stopped (the pose is then not trusted,
    /// except as the anytime estimate with `RelocBudgetExhausted`).
    pub failure: Option<FailureCode>,
    /// Quality of `pose`.
    pub quality: Quality,
    /// Work counters.
    pub stats: Stats,
    /// Rejections and failures by cause.
    pub log: FailureLog,
}
