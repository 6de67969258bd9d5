//! The two pieces of work the engine drives, behind traits so each side is
//! testable alone: [`Attempt`] (one correspondence from a virtual viewpoint,
//! stage by stage) and [`Solver`] (GetTransform on the collected pairs), with
//! what they are handed and what they return.

use super::PipelineStats;
use crate::config::MAX_POSE_CANDIDATES;
use crate::failure::FailureCode;
use crate::geom::Pose;
use crate::pose::{Candidate, Correspondence};
use crate::rng::Rng;

/// Result of one GetTransform.
#[derive(Clone, Debug, PartialEq)]
pub struct Solution {
    /// Maximum-inlier `world_from_left`.
    pub pose: Pose,
    /// Inliers of `pose`.
    pub inliers: u16,
    /// RMS residual of the inliers, metres.
    pub rms_m: f32,
    /// RANSAC hypotheses evaluated.
    pub iterations: u16,
    /// Best distinct hypotheses, most inliers first.
    pub candidates: heapless::Vec<Candidate, MAX_POSE_CANDIDATES>,
}

/// What one correspondence attempt is given by the engine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AttemptContext {
    /// The randomized virtual viewpoint `world_from_left`.
    pub world_from_viewpoint: Pose,
    /// Current translation search bound t̃, metres (sizes the search window).
    pub t_m: f32,
    /// Current rotation search bound r̃, radians (sizes the search window).
    pub r_rad: f32,
    /// Accept only gradient-domain matches (Sobel, Laplacian): set in the
    /// final round under [`Options::final_gradient_only`](super::Options::final_gradient_only).
    pub gradient_only: bool,
    /// Revisit (VTSM-RELOC-046): the mask vertex SamplePoint tries first, an
    /// inlier of the last pose update that Reuse did not keep; `None` draws
    /// as always.
    pub revisit: Option<u32>,
    /// Near (VTSM-RELOC-047): a mask vertex that agreed with the last pose
    /// update; SamplePoint draws its vertex within `near_radius_m` of it
    /// (bounded draws, then anywhere as always). `None` draws as always.
    pub near: Option<u32>,
    /// How far from `near` the drawn vertex may lie, metres.
    pub near_radius_m: f32,
    /// Global attempt index (for logging).
    pub index: u32,
    /// Round index (iterations, Stall / Reseed rounds and seeds all count).
    pub round: u32,
}

/// The kind of work one [`Relocalizer::step_stage`](super::Relocalizer::step_stage) call did: what a caller
/// that timestamps each call attributes its time to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Stage {
    /// SamplePoint and Synthesize: vertex draws, the left template's render,
    /// the occlusion check and the left template mask.
    Render,
    /// Search windows and Match: every NCC search of the attempt, each
    /// including the filtering and pyramid of its template and window, and
    /// the right template's render and mask at the first accepted left match.
    Match,
    /// Valid and Stereo: the row check and the triangulation.
    Stereo,
    /// A whole correspondence attempt, from an [`Attempt`] without a staged
    /// form (the default [`Attempt::begin`]).
    Attempt,
    /// GetTransform: the start of a solve or one RANSAC chunk; the unit that
    /// ends a solve also concludes it (Anneal, Distribute, Reuse, and after
    /// the last iteration the final refinement and the integrity gates).
    Pose,
    /// The repeated final solve of [`Verify::repeat_solve`](super::Verify::repeat_solve).
    Verify,
    /// No work: the budget ran out and the anytime result was formed.
    Stop,
}

impl Stage {
    /// Every stage, in pipeline order.
    pub const ALL: [Stage; 7] = [
        Stage::Render,
        Stage::Match,
        Stage::Stereo,
        Stage::Attempt,
        Stage::Pose,
        Stage::Verify,
        Stage::Stop,
    ];

    /// Short lowercase name for reports.
    pub const fn name(self) -> &'static str {
        match self {
            Stage::Render => "render",
            Stage::Match => "match",
            Stage::Stereo => "stereo",
            Stage::Attempt => "attempt",
            Stage::Pose => "pose",
            Stage::Verify => "verify",
            Stage::Stop => "stop",
        }
    }
}

/// Stages of one attempt at most in the staged form ([`Attempt::begin`]
/// and [`Attempt::resume`]): Render, Match, Stereo.
pub const MAX_ATTEMPT_STAGES: usize = 3;

/// What one stage of a staged attempt did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StageStep {
    /// The stage that ran.
    pub stage: Stage,
    /// `Some` when the attempt ended with this stage: its correspondence, or
    /// the code of the step that rejected it. `None`: call [`Attempt::resume`].
    pub ended: Option<Result<Correspondence, FailureCode>>,
}

/// Per-attempt work: SamplePoint → Synthesize → Match → Valid → Stereo.
///
/// # Contract
/// Must do a bounded amount of work, draw randomness only from `rng`, and
/// return either one correspondence or the code of the step that rejected the
/// sample. It may add to `stats` (renders, matches, rejections by cause).
///
/// The staged form ([`Attempt::begin`], then [`Attempt::resume`] until the
/// attempt ends) is how the engine runs every attempt. It must do the same
/// work as [`Attempt::attempt`] and give the same result, bit for bit, and
/// end an attempt within [`MAX_ATTEMPT_STAGES`] stages. The default runs the
/// whole attempt in `begin`.
///
/// Its result and its `stats` must depend only on `ctx` and `rng`, never on
/// the attempts before it: then attempts handed out as tickets
/// ([`super::Relocalizer::ticket`]) can run on several instances (workers)
/// and the outcome is the one of a single instance.
pub trait Attempt {
    /// Try to produce one correspondence from `ctx.world_from_viewpoint`.
    ///
    /// # Errors
    /// The code of the rejecting step (out of view, flat template, low score, ...).
    fn attempt(
        &mut self,
        ctx: &AttemptContext,
        rng: &mut Rng,
        stats: &mut PipelineStats,
    ) -> Result<Correspondence, FailureCode>;

    /// Staged form, first stage of a new attempt from `ctx` (any attempt
    /// under way is abandoned). Every random draw of the attempt is made
    /// here. The default is the whole [`Attempt::attempt`] as one
    /// [`Stage::Attempt`].
    fn begin(
        &mut self,
        ctx: &AttemptContext,
        rng: &mut Rng,
        stats: &mut PipelineStats,
    ) -> StageStep {
        StageStep {
            stage: Stage::Attempt,
            ended: Some(self.attempt(ctx, rng, stats)),
        }
    }

    /// Staged form, next stage of the attempt under way (the last
    /// [`StageStep`] had `ended: None`). With no attempt under way (never the
    /// case for the default [`Attempt::begin`], which always ends it) the
    /// attempt ends at once with [`FailureCode::RelocSampleOutOfView`]: no
    /// vertex was sampled.
    fn resume(&mut self, stats: &mut PipelineStats) -> StageStep {
        let _ = stats;
        StageStep {
            stage: Stage::Attempt,
            ended: Some(Err(FailureCode::RelocSampleOutOfView)),
        }
    }

    /// Re-check the inputs the attempts read that can be checked again (the
    /// map product's CRCs), for [`Verify::recheck_map`](super::Verify::recheck_map). The default has
    /// nothing to check.
    ///
    /// # Errors
    /// [`FailureCode::RelocMapChanged`] when a check that passed at load fails now.
    fn recheck(&mut self) -> Result<(), FailureCode> {
        Ok(())
    }
}

/// GetTransform: robust rigid transform `world_from_left` from pairs.
///
/// # Contract
/// Bounded work; randomness only from `rng`; `inlier_mask[i]` set for each
/// inlier pair `i` of the returned solution (`inlier_mask.len() >= pairs.len()`).
pub trait Solver {
    /// Estimate the transform.
    ///
    /// # Errors
    /// Pose-stage codes (too few points, degenerate, no consensus, non-finite).
    fn solve(
        &mut self,
        pairs: &[Correspondence],
        rng: &mut Rng,
        inlier_mask: &mut [bool],
    ) -> Result<Solution, FailureCode>;

    /// Chunked form, first unit: prepare a solve of `pairs` drawing from `rng`.
    /// `Ok(true)` means the solver has no chunked form and the engine calls
    /// [`Solver::solve`] in the same unit (the default).
    ///
    /// # Errors
    /// As [`Solver::solve`].
    fn start(&mut self, pairs: &[Correspondence], rng: Rng) -> Result<bool, FailureCode> {
        let _ = (pairs, rng);
        Ok(true)
    }

    /// Chunked form: evaluate at most `max_iterations` hypotheses; `Ok(true)` once done.
    ///
    /// # Errors
    /// As [`Solver::solve`].
    fn run_chunk(
        &mut self,
        pairs: &[Correspondence],
        max_iterations: u16,
    ) -> Result<bool, FailureCode> {
        let _ = (pairs, max_iterations);
        Ok(true)
    }

    /// Chunked form, last unit: the solution of the solve begun by [`Solver::start`].
    ///
    /// # Errors
    /// As [`Solver::solve`]; the default (no chunked form) reports no consensus.
    fn finish(
        &mut self,
        pairs: &[Correspondence],
        inlier_mask: &mut [bool],
    ) -> Result<Solution, FailureCode> {
        let _ = (pairs, inlier_mask);
        Err(FailureCode::PoseRansacNoConsensus)
    }

    /// The final estimate: refine `pose` (the last solution) on the pairs
    /// flagged in `inlier_mask` and give its covariance. `None` (the default)
    /// means the solver has no refinement; the engine then keeps `pose`.
    ///
    /// # Contract
    /// Bounded work, no randomness; the returned pose is either `pose` or one
    /// that passed the solver's own safeguard.
    fn refine(
        &mut self,
        pairs: &[Correspondence],
        inlier_mask: &[bool],
        pose: &Pose,
    ) -> Option<Result<crate::pose::Refined, FailureCode>> {
        let _ = (pairs, inlier_mask, pose);
        None
    }

    /// Scale the per-pair depth-uncertainty term of the inlier gate of the
    /// solves that follow by `scale` (≥ 1; 1 is the solver's own gate) until
    /// it is set again. The engine widens it for a second solve of a first
    /// round's pairs ([`Options::first_fix_sigma_scale`](super::Options::first_fix_sigma_scale)) and sets it back to
    /// 1 when a round starts. The default ignores it.
    fn set_sigma_scale(&mut self, scale: f32) {
        let _ = scale;
    }
}

/// RANSAC hypotheses evaluated per work unit by a chunked [`Solver`].
pub const RANSAC_CHUNK: u16 = 64;
