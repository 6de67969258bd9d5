//! The real per-attempt pipeline: SamplePoint → Synthesize → Match → Valid →
//! Stereo (paper §III-C, §III-D), implementing [`super::Attempt`].
//!
//! Inputs: the map, the real left/right images (a [`FrameSource`], read one
//! search window at a time into the workspace), the rig, a [`MatchPolicy`] and a
//! [`Workspace`] of caller-provided buffers sized by [`WorkspaceSizes`](super::WorkspaceSizes),
//! all checked once by [`super::Setup::build`], the only constructor. Output:
//! one [`Correspondence`] (map vertex in world, triangulated point in the left
//! camera) or the code of the rejecting step.
//!
//! Bounds per attempt: at most [`MAX_SAMPLE_TRIES`] vertex draws, two renders of
//! ℓ×ℓ (the left template in Synthesize, the right one only once a left match
//! is accepted), at most two template searches per policy variant (≤ [`MATCH_VARIANTS`](super::MATCH_VARIANTS)),
//! each in a window of at most `params.search_px`² pixels, and one triangulation.
//!
//! Staged form ([`Attempt::begin`] / [`Attempt::resume`]): an attempt runs as
//! [`Stage::Render`] (SamplePoint, Synthesize, search windows), [`Stage::Match`]
//! (with the right template's render) and [`Stage::Stereo`], ending early at the stage that rejects it; what one
//! stage hands to the next is kept in the pipeline (a few dozen bytes).
//! [`Attempt::attempt`] is the same stages run back to back.

use super::policy::MatchPolicy;
use super::workspace::Workspace;
use super::{
    Attempt, AttemptContext, Correspondence, PipelineStats, Stage, StageStep, MAX_ATTEMPT_STAGES,
};
use crate::config::Params;
use crate::failure::FailureCode;
use crate::frame::{FrameSource, StereoPair};
use crate::geom::{Pose, StereoRig, Vec3};
use crate::image::Rect;
use crate::map::MapView;
use crate::stereo;

mod matching;
mod sample;
#[cfg(test)]
mod tests;
mod window;

/// Vertex draws per attempt before the attempt is rejected as out of view.
pub const MAX_SAMPLE_TRIES: u32 = 16;
/// Vertex draws per attempt looking for one near its Near vertex
/// ([`AttemptContext::near`]) before it draws anywhere.
pub const MAX_NEAR_TRIES: u32 = 16;
/// Occlusion tolerance: a vertex is hidden when the rendered depth at its pixel
/// is nearer by more than this plus [`OCCLUSION_REL`] of its depth, metres.
pub const OCCLUSION_ABS_M: f32 = 0.03;
/// Relative part of the occlusion tolerance.
pub const OCCLUSION_REL: f32 = 0.02;

/// The real [`Attempt`]: renders, matches and triangulates one map vertex.
///
/// `F` is where the real pair's pixels come from: each Match stage copies its
/// left search window (and, once a left match is accepted, the right one)
/// into the workspace and matches there; the in-memory pair by default.
pub struct Pipeline<'a, 'w, F = StereoPair<'a>> {
    map: &'a MapView<'a>,
    frames: F,
    rig: StereoRig,
    template_px: usize,
    search_px: usize,
    epsilon_px: f32,
    policy: MatchPolicy,
    ws: Workspace<'w>,
    /// What the next stage of a staged attempt starts from.
    pending: Pending,
    /// The attempt under way accepts only gradient-domain variants
    /// ([`AttemptContext::gradient_only`]).
    gradient_only: bool,
    /// Index into M̂ of the vertex the latest SamplePoint drew.
    last_sample: Option<u32>,
}

/// Where a staged attempt stands between two of its stages.
#[derive(Clone, Copy)]
enum Pending {
    /// No attempt under way.
    None,
    /// Rendered, with its search windows: Match is next.
    Match(Sample, Templates, Windows),
    /// Matched in both images: Valid + Stereo is next.
    Stereo(Sample, ([f32; 2], [f32; 2]), u8),
}

/// A sampled vertex and its projections.
#[derive(Clone, Copy)]
struct Sample {
    /// Index into M̂.
    mask_index: u32,
    /// The context's revisit vertex (counted in `revisit_pairs` when it
    /// gives a pair).
    revisit: bool,
    /// Drawn near the context's Near vertex (counted in `near_pairs`).
    near: bool,
    world: Vec3,
    cam: Vec3,
    left: [f32; 2],
    right: [f32; 2],
}

fn round_i32(v: f32) -> i32 {
    libm::floorf(v + 0.5) as i32
}

impl<'a, 'w, F: FrameSource> Pipeline<'a, 'w, F> {
    /// The frame source the pipeline reads its windows from (a device
    /// adapter's read counters and fault log, after the run).
    pub fn frames(&self) -> &F {
        &self.frames
    }

    /// The workspace, for upset injection.
    #[cfg(feature = "upset-injection")]
    pub(super) fn workspace(&self) -> &Workspace<'w> {
        &self.ws
    }

    /// The workspace, for upset injection.
    #[cfg(feature = "upset-injection")]
    pub(super) fn workspace_mut(&mut self) -> &mut Workspace<'w> {
        &mut self.ws
    }

    /// Read the map through `map` from now on, for upset injection.
    #[cfg(feature = "upset-injection")]
    pub(super) fn set_map(&mut self, map: &'a MapView<'a>) {
        self.map = map;
    }

    /// A pipeline over `map` and the real stereo pair, from inputs that
    /// [`super::Setup::build`] has checked (params, policy, image sizes, workspace, mask).
    pub(super) fn from_checked(
        map: &'a MapView<'a>,
        frames: F,
        rig: &StereoRig,
        params: &Params,
        policy: &MatchPolicy,
        ws: Workspace<'w>,
    ) -> Self {
        Self {
            map,
            frames,
            rig: *rig,
            template_px: usize::from(params.template_px),
            search_px: usize::from(params.search_px),
            epsilon_px: params.epsilon_px,
            policy: *policy,
            ws,
            pending: Pending::None,
            gradient_only: false,
            last_sample: None,
        }
    }

    /// Index into the mask M̂ ([`MapView::mask_vertex`]) of the vertex the
    /// latest attempt's SamplePoint drew, `None` before any draw or when it
    /// found no vertex in view: what a ground tool attributes an attempt's
    /// result to (the correct-match rate per map score).
    pub fn last_sample(&self) -> Option<u32> {
        self.last_sample
    }
}

impl<'a, F: FrameSource + Clone> Pipeline<'a, '_, F> {
    /// A second pipeline over the same map, frames, rig, parameters and
    /// policy, with its own workspace `ws`: a worker that runs attempts handed
    /// out as tickets ([`super::work_ticket`]) with the same results as this
    /// one. No attempt is under way in it.
    ///
    /// # Errors
    /// [`FailureCode::ConfigCapacityTooSmall`] if `ws` was carved for smaller
    /// sizes than this pipeline's workspace.
    pub fn twin<'v>(&self, ws: Workspace<'v>) -> Result<Pipeline<'a, 'v, F>, FailureCode> {
        if !ws.sizes().covers(&self.ws.sizes()) {
            return Err(FailureCode::ConfigCapacityTooSmall);
        }
        Ok(Pipeline {
            map: self.map,
            frames: self.frames.clone(),
            rig: self.rig,
            template_px: self.template_px,
            search_px: self.search_px,
            epsilon_px: self.epsilon_px,
            policy: self.policy,
            ws,
            pending: Pending::None,
            gradient_only: false,
            last_sample: None,
        })
    }
}

/// Template origins of one attempt: the ℓ×ℓ windows of the virtual left and
/// right images (the left one rendered by Synthesize, the right one at the
/// attempt's first accepted left match), and the virtual right camera's pose.
#[derive(Clone, Copy)]
struct Templates {
    left: Rect,
    right: Rect,
    vp_right: Pose,
}

/// Search windows of one attempt in the real left and right images, and the
/// disparity range the right match may take once the left one is known.
#[derive(Clone, Copy)]
struct Windows {
    left: Rect,
    right: Rect,
    /// Smallest and largest plausible disparity of the vertex, pixels.
    disparity: (f32, f32),
}

impl<F: FrameSource> Pipeline<'_, '_, F> {
    /// Valid + Stereo (§III-D): check the rows agree within ε and triangulate
    /// the pixel pair into the left camera frame.
    fn stereo(
        &self,
        s: &Sample,
        (pl, pr, variant): ([f32; 2], [f32; 2], u8),
        stats: &mut PipelineStats,
    ) -> Result<Correspondence, FailureCode> {
        let p = stereo::triangulate(
            &self.rig,
            pl,
            pr,
            self.epsilon_px,
            self.policy.sigma_d_px,
            self.policy.min_disparity_px,
        )?;
        stats.triangulations = stats.triangulations.saturating_add(1);
        if s.revisit {
            stats.revisit_pairs = stats.revisit_pairs.saturating_add(1);
        }
        if s.near {
            stats.near_pairs = stats.near_pairs.saturating_add(1);
        }
        Ok(Correspondence {
            world: s.world,
            cam: p.p_cam,
            sigma_m: p.sigma_z_m,
            variant,
            mask_index: s.mask_index,
        })
    }
}

impl<F: FrameSource> Attempt for Pipeline<'_, '_, F> {
    /// SamplePoint → Synthesize → search window → Match → Valid + Stereo:
    /// the stages of [`Attempt::begin`] and [`Attempt::resume`] back to back.
    fn attempt(
        &mut self,
        ctx: &AttemptContext,
        rng: &mut crate::rng::Rng,
        stats: &mut PipelineStats,
    ) -> Result<Correspondence, FailureCode> {
        let mut step = self.begin(ctx, rng, stats);
        for _ in 1..MAX_ATTEMPT_STAGES {
            if step.ended.is_some() {
                break;
            }
            step = self.resume(stats);
        }
        // Stereo, the last stage, always ends the attempt.
        step.ended.unwrap_or(Err(FailureCode::RelocSampleOutOfView))
    }

    /// [`Stage::Render`]: SamplePoint, Synthesize and the search windows.
    fn begin(
        &mut self,
        ctx: &AttemptContext,
        rng: &mut crate::rng::Rng,
        stats: &mut PipelineStats,
    ) -> StageStep {
        self.pending = Pending::None;
        self.gradient_only = ctx.gradient_only;
        let vp_left = ctx.world_from_viewpoint;
        let sampled = self.sample(&vp_left.inverse(), ctx, rng, stats);
        self.last_sample = sampled.as_ref().ok().map(|s| s.mask_index);
        let rendered =
            sampled.and_then(|sample| Ok((sample, self.synthesize(&vp_left, &sample, stats)?)));
        let ended = match rendered {
            Ok((sample, templates)) => {
                let windows = self.search_windows(ctx, &sample);
                self.pending = Pending::Match(sample, templates, windows);
                None
            }
            Err(code) => Some(Err(code)),
        };
        StageStep {
            stage: Stage::Render,
            ended,
        }
    }

    /// [`Stage::Match`], then [`Stage::Stereo`].
    fn resume(&mut self, stats: &mut PipelineStats) -> StageStep {
        let pending = core::mem::replace(&mut self.pending, Pending::None);
        match pending {
            Pending::Match(sample, templates, windows) => {
                let ended = match self.match_pair(&sample, templates, windows, stats) {
                    Ok((pl, pr, variant)) => {
                        self.pending = Pending::Stereo(sample, (pl, pr), variant);
                        None
                    }
                    Err(code) => Some(Err(code)),
                };
                StageStep {
                    stage: Stage::Match,
                    ended,
                }
            }
            Pending::Stereo(sample, pixels, variant) => StageStep {
                stage: Stage::Stereo,
                ended: Some(self.stereo(&sample, (pixels.0, pixels.1, variant), stats)),
            },
            // No attempt under way: nothing was sampled.
            Pending::None => StageStep {
                stage: Stage::Render,
                ended: Some(Err(FailureCode::RelocSampleOutOfView)),
            },
        }
    }

    /// Every check of [`MapView::new_checked`] again, on the same bytes: an
    /// upset of the map in memory since load shows as a failed CRC.
    fn recheck(&mut self) -> Result<(), FailureCode> {
        MapView::new_checked(self.map.bytes())
            .map(|_| ())
            .map_err(|_| FailureCode::RelocMapChanged)
    }
}
