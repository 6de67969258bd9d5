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
use crate::frame::{self, Eye, FrameSource, StereoPair, Window};
use crate::geom::{Camera, Pose, StereoRig, Vec3};
use crate::image::{GrayView, Rect};
use crate::map::MapView;
use crate::ncc::{self, Search};
use crate::raster::{self, Target};
use crate::stereo;

/// Vertex draws per attempt before the attempt is rejected as out of view.
pub const MAX_SAMPLE_TRIES: u32 = 16;
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
    world: Vec3,
    cam: Vec3,
    left: [f32; 2],
    right: [f32; 2],
}

fn round_i32(v: f32) -> i32 {
    libm::floorf(v + 0.5) as i32
}

/// Search rectangle of side ℓ + 2r centred on `px`, capped at `cap` and clipped to the image.
fn search_rect(px: [f32; 2], l: usize, r: i32, cap: usize, w: usize, h: usize) -> Rect {
    // Saturating and `max`/`min` (a `clamp` with bounds the wrong way round
    // panics): `px` is checked in view by SamplePoint, sizes are validated
    // params, but the arithmetic stays total.
    let to_i32 = |v: usize| i32::try_from(v).unwrap_or(i32::MAX);
    let half_max = to_i32(cap.saturating_sub(l) / 2);
    let r = r.max(0).min(half_max);
    let side = to_i32(l).saturating_add(r.saturating_mul(2));
    let x0 = round_i32(px[0]).saturating_sub(side / 2);
    let y0 = round_i32(px[1]).saturating_sub(side / 2);
    let (w, h) = (to_i32(w), to_i32(h));
    let cx0 = x0.max(0).min(w);
    let cy0 = y0.max(0).min(h);
    let cx1 = x0.saturating_add(side).max(0).min(w);
    let cy1 = y0.saturating_add(side).max(0).min(h);
    Rect::new(
        cx0,
        cy0,
        cx1.saturating_sub(cx0).max(0) as u32,
        cy1.saturating_sub(cy0).max(0) as u32,
    )
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
        }
    }

    /// SamplePoint: a random mask vertex whose left and right projections lie
    /// ℓ/2 inside both images.
    fn sample(
        &self,
        cam_from_world: &Pose,
        rng: &mut crate::rng::Rng,
        stats: &mut PipelineStats,
    ) -> Result<Sample, FailureCode> {
        let n = self.map.mask_vertex_count();
        let margin = (self.template_px / 2) as f32;
        for _ in 0..MAX_SAMPLE_TRIES {
            let k = rng.below(n);
            let Some(world) = self.map.mask_vertex(k).and_then(|i| self.map.vertex(i)) else {
                continue;
            };
            let cam = cam_from_world.transform_point(&world);
            match self.rig.project_stereo(&cam) {
                Some((l, r))
                    if self.rig.cam.contains(l[0], l[1], margin)
                        && self.rig.cam.contains(r[0], r[1], margin) =>
                {
                    return Ok(Sample {
                        world,
                        cam,
                        left: l,
                        right: r,
                    });
                }
                _ => stats.out_of_view = stats.out_of_view.saturating_add(1),
            }
        }
        Err(FailureCode::RelocSampleOutOfView)
    }
}

/// `rect` of `eye` copied into `buf` with its filter ring, `None` for an
/// empty rectangle.
///
/// # Errors
/// [`FailureCode::RelocFrameReadFailed`] when the source cannot serve it.
fn read_window<'b, F: FrameSource>(
    frames: &mut F,
    eye: Eye,
    rect: Rect,
    buf: &'b mut [u8],
) -> Result<Option<Window<'b>>, FailureCode> {
    if rect.w == 0 || rect.h == 0 {
        return Ok(None);
    }
    frame::read_with_halo(frames, eye, rect, buf)
        .map(Some)
        .map_err(|_| FailureCode::RelocFrameReadFailed)
}

/// Window of side ℓ whose centre pixel holds `px`.
fn template_rect(px: [f32; 2], l: usize) -> Rect {
    let h = i32::try_from(l / 2).unwrap_or(i32::MAX);
    Rect::new(
        round_i32(px[0]).saturating_sub(h),
        round_i32(px[1]).saturating_sub(h),
        l as u32,
        l as u32,
    )
}

/// Accept a match under `policy`.
fn accept(m: &ncc::Match, policy: &MatchPolicy) -> Result<(), FailureCode> {
    if m.score < policy.min_score {
        Err(FailureCode::NccLowScore)
    } else if m.runner_up > policy.max_runner_up_ratio * m.score {
        Err(FailureCode::NccAmbiguous)
    } else {
        Ok(())
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

/// Integer bounds `[floor(lo), ceil(hi)]` as i32 (saturating; non-finite
/// bounds give an empty range).
fn int_range(lo: f32, hi: f32) -> (i32, i32) {
    if lo.is_finite() && hi.is_finite() {
        (libm::floorf(lo) as i32, libm::ceilf(hi) as i32)
    } else {
        (1, 0)
    }
}

/// The right-image search window for a vertex found at `pl` in the left image
/// (§III-D Valid, by construction): template top-left positions whose vertex
/// pixel (at `o` inside the template) lies within ε (+1 px for the sub-pixel
/// step) of the left row and at a disparity in `disparity` (±1 px), as the
/// window those positions need, inside `within`. `None` when no position is
/// left.
fn epipolar_band(
    pl: [f32; 2],
    o: [f32; 2],
    (tw, th): (usize, usize),
    disparity: (f32, f32),
    epsilon_px: f32,
    within: Rect,
) -> Option<Rect> {
    let slack = epsilon_px + 1.0;
    let (y0, y1) = int_range(pl[1] - o[1] - slack, pl[1] - o[1] + slack);
    let (x0, x1) = int_range(
        pl[0] - disparity.1 - o[0] - 1.0,
        pl[0] - disparity.0 - o[0] + 1.0,
    );
    if x1 < x0 || y1 < y0 {
        return None;
    }
    // Positions a..=b of a template of side t need b − a + t pixels.
    let extent = |a: i32, b: i32, t: usize| {
        let t = i64::try_from(t).ok()?;
        u32::try_from(i64::from(b).saturating_sub(i64::from(a)).saturating_add(t)).ok()
    };
    let band = Rect::new(x0, y0, extent(x0, x1, tw)?, extent(y0, y1, th)?);
    band.intersect(&within)
        .filter(|r| r.w as usize >= tw && r.h as usize >= th)
}

/// Render the ℓ×ℓ template `rect` of the virtual camera at `pose` into the
/// intensity, depth and mask-depth buffers, counting the render and its
/// pixels (`PipelineStats::renders`, `render_pixels`).
fn render_template(
    map: &MapView<'_>,
    cam: &Camera,
    pose: &Pose,
    rect: Rect,
    (intensity, depth, mask_depth): (&mut [u8], &mut [u32], &mut [u32]),
    (renders, pixels): (&mut u32, &mut u64),
) -> Result<(), FailureCode> {
    let mut target = Target {
        intensity,
        depth,
        mask_depth,
    };
    let rs = raster::render_window(map, cam, pose, rect, &mut target)?;
    *renders = renders.saturating_add(1);
    *pixels = pixels.saturating_add(u64::from(rs.pixels_written));
    Ok(())
}

/// Form the §III-C mask of a rendered ℓ×ℓ template from its depth and
/// mask-depth buffers.
fn template_mask(
    depth: &[u32],
    mask_depth: &[u32],
    mask: &mut [u8],
    l: usize,
) -> Result<(), FailureCode> {
    let n = l.saturating_mul(l);
    let (Some(d), Some(m)) = (depth.get(..n), mask_depth.get(..n)) else {
        return Err(FailureCode::ConfigCapacityTooSmall);
    };
    raster::template_mask(d, m, l, l, mask);
    Ok(())
}

impl<F: FrameSource> Pipeline<'_, '_, F> {
    /// Synthesize (§III-C): render the ℓ×ℓ left template centred on the
    /// vertex's left projection, reject a vertex hidden in the virtual view,
    /// and form the left template mask. The right template is rendered by
    /// [`Pipeline::match_pair`] when a left match is accepted: an attempt
    /// rejected on the left (or hidden) never needs it.
    fn synthesize(
        &mut self,
        vp_left: &Pose,
        s: &Sample,
        stats: &mut PipelineStats,
    ) -> Result<Templates, FailureCode> {
        let l = self.template_px;
        let t = Templates {
            left: template_rect(s.left, l),
            right: template_rect(s.right, l),
            vp_right: self.rig.world_from_right(vp_left),
        };
        let ws = &mut self.ws;
        render_template(
            self.map,
            &self.rig.cam,
            vp_left,
            t.left,
            (&mut *ws.inten_l, &mut *ws.depth_l, &mut *ws.mdepth_l),
            (&mut stats.renders, &mut stats.render_pixels),
        )?;
        // Occlusion: the surface drawn at the vertex's pixel must be the vertex's own.
        // ℓ ≤ MAX_TEMPLATE_PX (validated params): the centre index fits.
        let centre = (l / 2).wrapping_mul(l).wrapping_add(l / 2);
        let drawn = ws.depth_l.get(centre).copied().and_then(raster::depth_to_m);
        let tol = OCCLUSION_ABS_M + OCCLUSION_REL * s.cam.z;
        if drawn.is_none_or(|z| z < s.cam.z - tol) {
            stats.occluded = stats.occluded.saturating_add(1);
            return Err(FailureCode::RelocSampleOccluded);
        }
        template_mask(ws.depth_l, ws.mdepth_l, ws.mask_l, l)?;
        Ok(t)
    }

    /// Search windows (§III-D): the projected (t̃, r̃) uncertainty around each
    /// predicted pixel plus the policy margin, capped at `search_px`, clipped
    /// to the image.
    fn search_windows(&self, ctx: &AttemptContext, s: &Sample) -> Windows {
        let (l, cam) = (self.template_px, self.rig.cam);
        let f = cam.fx.max(cam.fy);
        let r_px = f * (2.0 * ctx.t_m / s.cam.z.max(0.1) + 2.0 * ctx.r_rad);
        let r_px = if r_px.is_finite() {
            (libm::ceilf(r_px) as i32).saturating_add(i32::from(self.policy.margin_px))
        } else {
            0
        };
        let (w, h) = (cam.width as usize, cam.height as usize);
        // Depth of the vertex in the real camera: within 2·(t̃ + D·r̃) of its
        // depth in the viewpoint (D its distance), as the window radius above
        // doubles the projected uncertainty; disparity f·B/Z over that range,
        // widened by the policy margin. A range reaching the camera leaves the
        // largest disparity open (the image width).
        let fb = cam.fx * self.rig.baseline_m;
        let dz = 2.0 * (ctx.t_m + s.cam.norm() * ctx.r_rad);
        let m = f32::from(self.policy.margin_px);
        let near = s.cam.z - dz;
        let d_hi = if near > 0.0 {
            (fb / near + m).min(cam.width as f32)
        } else {
            cam.width as f32
        };
        let d_lo = (fb / (s.cam.z + dz) - m).max(self.policy.min_disparity_px);
        Windows {
            left: search_rect(s.left, l, r_px, self.search_px, w, h),
            right: search_rect(s.right, l, r_px, self.search_px, w, h),
            disparity: (d_lo, d_hi),
        }
    }

    /// Match (§III-D): try the policy's variants in order; the first whose
    /// left and right searches are both accepted gives the vertex's pixel in
    /// each real image. Otherwise the last rejection's code.
    fn match_pair(
        &mut self,
        s: &Sample,
        t: Templates,
        win: Windows,
        stats: &mut PipelineStats,
    ) -> Result<([f32; 2], [f32; 2], u8), FailureCode> {
        let l = self.template_px;
        let ws = &mut self.ws;
        fn view(b: &[u8], l: usize) -> Result<GrayView<'_>, FailureCode> {
            GrayView::new(b, l, l, l)
        }
        let (tl, tml) = (view(ws.inten_l, l)?, view(ws.mask_l, l)?);
        // The right template is rendered at the first accepted left match.
        let mut right_tpl = Some((
            &mut *ws.inten_r,
            &mut *ws.depth_r,
            &mut *ws.mdepth_r,
            &mut *ws.mask_r,
        ));
        let mut right: Option<(GrayView<'_>, GrayView<'_>)> = None;
        // The left window is read once per attempt, the right one at the
        // first accepted left match (an attempt rejected on the left reads
        // nothing more); an empty window reads nothing and matches nothing,
        // as a search outside the image does.
        let left_win = read_window(&mut self.frames, Eye::Left, win.left, ws.frame_l)?;
        let mut right_buf = Some(&mut *ws.frame_r);
        let mut right_win: Option<Window<'_>> = None;
        let mut last = FailureCode::NccLowScore;
        let gradient_only = self.gradient_only;
        for v in self.policy.variants.iter().flatten() {
            if gradient_only && !super::policy::is_gradient_variant(v.index() as u8) {
                continue;
            }
            fn crop(t: GrayView<'_>, half: bool) -> Option<GrayView<'_>> {
                if half {
                    ncc::sub_template(&t)
                } else {
                    Some(t)
                }
            }
            let (Some(tl), Some(tml)) = (crop(tl, v.half), crop(tml, v.half)) else {
                continue;
            };
            let (ox, oy) = if v.half {
                let r = ncc::sub_template_rect(l, l);
                (r.x as f32, r.y as f32)
            } else {
                (0.0, 0.0)
            };
            let idx = v.index();
            let policy = &self.policy;
            let mut one = |t,
                           m,
                           img: Option<&Window<'_>>,
                           search,
                           mode|
             -> Result<ncc::Match, FailureCode> {
                if let Some(c) = stats.matches.get_mut(idx) {
                    *c = c.saturating_add(1);
                }
                let img = img.ok_or(FailureCode::NccWindowOutsideImage)?;
                let (m, ms) =
                    ncc::match_in_window(t, Some(m), img, search, v.filter, mode, &mut ws.scratch)?;
                stats.ncc_positions = stats.ncc_positions.saturating_add(ms.positions_scored);
                stats.ncc_macs = stats.ncc_macs.saturating_add(ms.macs);
                accept(&m, policy)?;
                Ok(m)
            };
            let ml = match one(tl, tml, left_win.as_ref(), win.left, policy.search) {
                Ok(m) => m,
                Err(e) => {
                    last = e;
                    continue;
                }
            };
            // The vertex sits at (projection − template origin) inside the template.
            let (ol, or) = (
                [
                    s.left[0] - t.left.x as f32 - ox,
                    s.left[1] - t.left.y as f32 - oy,
                ],
                [
                    s.right[0] - t.right.x as f32 - ox,
                    s.right[1] - t.right.y as f32 - oy,
                ],
            );
            let pl = [ml.sub_x + ol[0], ml.sub_y + ol[1]];
            if let Some((inten, depth, mdepth, mask)) = right_tpl.take() {
                render_template(
                    self.map,
                    &self.rig.cam,
                    &t.vp_right,
                    t.right,
                    (&mut *inten, &mut *depth, &mut *mdepth),
                    (&mut stats.renders, &mut stats.render_pixels),
                )?;
                template_mask(depth, mdepth, mask, l)?;
                right = Some((view(inten, l)?, view(mask, l)?));
            }
            let Some((Some(tr), Some(tmr))) =
                right.map(|(t, m)| (crop(t, v.half), crop(m, v.half)))
            else {
                continue;
            };
            // The right match is sought only where Valid can accept it: the
            // epipolar band of the left match over the plausible disparities.
            let (tw, th) = (tr.width(), tr.height());
            let (band, mode) = if policy.epipolar_band {
                let Some(band) =
                    epipolar_band(pl, or, (tw, th), win.disparity, self.epsilon_px, win.right)
                else {
                    last = FailureCode::StereoEpipolarViolation;
                    continue;
                };
                // Score every position of the band when there are no more of
                // them than the coarse-to-fine search would score at full
                // resolution alone (its candidates × (2r + 1)²).
                let cfg = ncc::SearchConfig::for_filter(v.filter);
                let side = cfg
                    .final_refine_radius_px
                    .saturating_mul(2)
                    .saturating_add(1);
                let c2f_full_res = cfg.candidates.saturating_mul(side).saturating_mul(side);
                let positions = (band.w as usize)
                    .saturating_sub(tw)
                    .saturating_add(1)
                    .saturating_mul((band.h as usize).saturating_sub(th).saturating_add(1));
                if positions <= c2f_full_res {
                    (band, Search::Exhaustive)
                } else {
                    (band, policy.search)
                }
            } else {
                (win.right, policy.search)
            };
            if let Some(buf) = right_buf.take() {
                right_win = read_window(&mut self.frames, Eye::Right, win.right, buf)?;
            }
            let mr = match one(tr, tmr, right_win.as_ref(), band, mode) {
                Ok(m) => m,
                Err(e) => {
                    last = e;
                    continue;
                }
            };
            if let Some(c) = stats.accepted.get_mut(idx) {
                *c = c.saturating_add(1);
            }
            let pr = [mr.sub_x + or[0], mr.sub_y + or[1]];
            // Variant indices are < MATCH_VARIANTS ≤ u8::MAX.
            let variant = u8::try_from(idx).unwrap_or(crate::pose::VARIANT_UNKNOWN);
            return Ok((pl, pr, variant));
        }
        Err(last)
    }

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
        Ok(Correspondence {
            world: s.world,
            cam: p.p_cam,
            sigma_m: p.sigma_z_m,
            variant,
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
        let rendered = self
            .sample(&vp_left.inverse(), rng, stats)
            .and_then(|sample| Ok((sample, self.synthesize(&vp_left, &sample, stats)?)));
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

#[cfg(test)]
mod tests {
    extern crate std;
    use super::super::solver::RansacSolver;
    use super::super::workspace::WorkspaceSizes;
    use super::super::workspace::{Workspace, TEST_WORKSPACE};
    use super::super::{Outcome, Relocalizer, Setup, Stage, StepResult};
    use super::*;
    use crate::ncc::Run;
    use crate::rng::Rng;
    use nalgebra::UnitQuaternion;
    use std::vec;
    use std::vec::Vec;

    use crate::testkit::{build_map, camera_pose, render_full, rig, test_params};

    fn relocalize(map: &MapView, left: &[u8], right: &[u8], prior: &Pose, seed: u64) -> Outcome {
        relocalize_with(map, left, right, prior, seed, &test_params())
    }

    fn relocalize_with(
        map: &MapView,
        left: &[u8],
        right: &[u8],
        prior: &Pose,
        seed: u64,
        p: &Params,
    ) -> Outcome {
        relocalize_stepped(map, left, right, prior, seed, p, 0)
    }

    /// `chunk` = 0: run to completion; otherwise `step_n(chunk)` until done.
    fn relocalize_stepped(
        map: &MapView,
        left: &[u8],
        right: &[u8],
        prior: &Pose,
        seed: u64,
        p: &Params,
        chunk: u32,
    ) -> Outcome {
        let lv = GrayView::new(left, 640, 480, 640).unwrap();
        let rv = GrayView::new(right, 640, 480, 640).unwrap();
        let mut setup = Setup::new(map, lv, rv, &rig(), p, prior, seed);
        setup.options.min_inliers = 15;
        let (mut bytes, mut words, mut runs) = workspace_buffers(&setup.sizes());
        let ws = Workspace::new(setup.sizes(), &mut bytes, &mut words, &mut runs).unwrap();
        let mut r = setup.build(ws).unwrap();
        if chunk == 0 {
            return r.run_to_completion(0);
        }
        let mut now = 0;
        loop {
            now += 1;
            if let StepResult::Done(o) = r.step_n(now, chunk) {
                return o.clone();
            }
        }
    }

    /// Step by stage until done; the outcome and the stage of every step.
    fn relocalize_by_stage(
        map: &MapView,
        left: &[u8],
        right: &[u8],
        prior: &Pose,
        seed: u64,
    ) -> (Outcome, Vec<Stage>) {
        let lv = GrayView::new(left, 640, 480, 640).unwrap();
        let rv = GrayView::new(right, 640, 480, 640).unwrap();
        let mut setup = Setup::new(map, lv, rv, &rig(), &test_params(), prior, seed);
        setup.options.min_inliers = 15;
        let (mut bytes, mut words, mut runs) = workspace_buffers(&setup.sizes());
        let ws = Workspace::new(setup.sizes(), &mut bytes, &mut words, &mut runs).unwrap();
        let mut r = setup.build(ws).unwrap();
        let mut stages = Vec::new();
        loop {
            let (stage, status) = r.step_stage(0);
            stages.extend(stage);
            if let StepResult::Done(o) = status {
                return (o.clone(), stages);
            }
        }
    }

    fn scene() -> (Vec<u8>, Pose) {
        (build_map(1), camera_pose(0.6, 0.2))
    }

    fn workspace_buffers(s: &WorkspaceSizes) -> (Vec<u8>, Vec<u32>, Vec<Run>) {
        (
            vec![0u8; s.bytes],
            vec![0u32; s.words],
            vec![Run::default(); s.runs],
        )
    }

    /// The context of a first-round attempt from `viewpoint` with a small
    /// uncertainty (5 cm, 0.01 rad).
    fn attempt_at(viewpoint: Pose) -> AttemptContext {
        AttemptContext {
            world_from_viewpoint: viewpoint,
            t_m: 0.05,
            r_rad: 0.01,
            gradient_only: false,
            index: 0,
            round: 0,
        }
    }

    /// Verifies: VTSM-RELOC-019
    #[test]
    fn attempts_from_the_true_pose_give_consistent_correspondences() {
        let (bytes, truth) = scene();
        let map = MapView::new_checked(&bytes).unwrap();
        let rig = rig();
        let left = render_full(&map, &rig.cam, &truth, 0.85, 20.0);
        let right = render_full(&map, &rig.cam, &rig.world_from_right(&truth), 0.85, 20.0);
        let p = test_params();
        let (mut b, mut w, mut r) = workspace_buffers(&TEST_WORKSPACE);
        let ws = Workspace::new(TEST_WORKSPACE, &mut b, &mut w, &mut r).unwrap();
        let lv = GrayView::new(&left, 640, 480, 640).unwrap();
        let rv = GrayView::new(&right, 640, 480, 640).unwrap();
        let setup = Setup::new(&map, lv, rv, &rig, &p, &truth, 0);
        let mut engine = setup.build(ws).unwrap();
        let pipe = engine.attempt_mut();
        let mut stats = PipelineStats::default();
        let ctx = attempt_at(truth);
        let cam_from_world = truth.inverse();
        let (mut ok, mut occluded, mut other) = (0u32, 0u32, 0u32);
        let n = 60u32;
        for i in 0..n {
            let mut rng = Rng::new(9).fork(u64::from(i));
            match pipe.attempt(&ctx, &mut rng, &mut stats) {
                Ok(c) => {
                    ok += 1;
                    // Independent reference: the vertex seen from the true pose.
                    let expect = cam_from_world.transform_point(&c.world);
                    let err = (c.cam - expect).norm();
                    assert!(
                        err < 0.03 + 3.0 * c.sigma_m,
                        "pair {i}: {err} m (sigma {})",
                        c.sigma_m
                    );
                }
                Err(FailureCode::RelocSampleOccluded) => occluded += 1,
                Err(_) => other += 1,
            }
        }
        std::println!("ok {ok} occluded {occluded} other {other} {stats:?}");
        assert!(ok >= n * 3 / 4, "only {ok} of {n}");
        assert_eq!(stats.occluded, occluded);
        assert_eq!(stats.triangulations, ok);
        assert!(stats.renders <= 2 * n);
        assert_eq!(stats.accepted.iter().sum::<u32>(), ok);
        assert!(stats.matches.iter().sum::<u32>() <= 2 * 6 * n);

        // Looking at the sky: every draw is out of view and the attempt says so.
        let up = Pose::new(
            UnitQuaternion::from_axis_angle(&Vec3::x_axis(), core::f32::consts::PI)
                * truth.rotation(),
            truth.translation(),
        );
        let before = stats.out_of_view;
        let sky = AttemptContext {
            world_from_viewpoint: Pose::new(up.rotation(), Vec3::new(-50.0, 0.0, 30.0)),
            ..ctx
        };
        let got = pipe.attempt(&sky, &mut Rng::new(1), &mut stats).err();
        assert_eq!(got, Some(FailureCode::RelocSampleOutOfView));
        assert_eq!(stats.out_of_view - before, MAX_SAMPLE_TRIES);
    }

    /// The right template is rendered only once a left match is accepted:
    /// every attempt that triangulates rendered both templates, an occluded
    /// one only the left, and on real images of pure noise (where no left
    /// search is accepted) every attempt that reached Synthesize rendered
    /// the left template alone.
    /// Verifies: VTSM-RELOC-039
    #[test]
    fn the_right_template_is_rendered_only_after_a_left_match() {
        let (bytes, truth) = scene();
        let map = MapView::new_checked(&bytes).unwrap();
        let rig = rig();
        let p = test_params();
        let ctx = attempt_at(truth);
        let mut noise = Rng::new(17);
        let mut noise_image = || -> Vec<u8> {
            (0..640 * 480)
                .map(|_| (noise.next_u32() >> 24) as u8)
                .collect()
        };
        let textured = (
            render_full(&map, &rig.cam, &truth, 0.85, 20.0),
            render_full(&map, &rig.cam, &rig.world_from_right(&truth), 0.85, 20.0),
        );
        let noisy = (noise_image(), noise_image());
        for (images, real) in [(&textured, true), (&noisy, false)] {
            let (mut b, mut w, mut r) = workspace_buffers(&TEST_WORKSPACE);
            let ws = Workspace::new(TEST_WORKSPACE, &mut b, &mut w, &mut r).unwrap();
            let lv = GrayView::new(&images.0, 640, 480, 640).unwrap();
            let rv = GrayView::new(&images.1, 640, 480, 640).unwrap();
            let mut engine = Setup::new(&map, lv, rv, &rig, &p, &truth, 0)
                .build(ws)
                .unwrap();
            let pipe = engine.attempt_mut();
            let mut stats = PipelineStats::default();
            let (mut ok, mut synthesized) = (0u32, 0u32);
            for i in 0..40u32 {
                let before = stats;
                let mut rng = Rng::new(9).fork(u64::from(i));
                let got = pipe.attempt(&ctx, &mut rng, &mut stats);
                let renders = stats.renders - before.renders;
                let searches =
                    stats.matches.iter().sum::<u32>() - before.matches.iter().sum::<u32>();
                match got {
                    Ok(_) => {
                        ok += 1;
                        assert_eq!(renders, 2, "attempt {i}");
                    }
                    Err(FailureCode::RelocSampleOutOfView) => assert_eq!(renders, 0),
                    Err(FailureCode::RelocSampleOccluded) => assert_eq!(renders, 1),
                    Err(code) => {
                        assert!((1..=2).contains(&renders), "attempt {i}: {code:?}");
                        if !real {
                            assert_eq!(renders, 1, "attempt {i}: {code:?}");
                        }
                        // A left search per variant at least, so at least as
                        // many searches as renders beyond the left one.
                        assert!(searches >= renders, "attempt {i}");
                    }
                }
                if renders > 0 {
                    synthesized += 1;
                }
            }
            if real {
                assert!(ok >= 30, "only {ok} of 40");
            } else {
                assert_eq!(ok, 0);
                assert_eq!(stats.renders, synthesized);
                assert!(synthesized >= 30, "{stats:?}");
            }
        }
    }

    /// The right search band holds exactly the template positions whose vertex
    /// pixel is within ε + 1 px of the left row and at a disparity within the
    /// range ± 1 px, clipped to the right window; no position, no band.
    /// Verifies: VTSM-RELOC-034
    #[test]
    fn epipolar_band_holds_the_positions_valid_can_accept() {
        let within = Rect::new(100, 50, 300, 300);
        let (pl, o, eps) = ([250.4_f32, 180.6_f32], [31.5_f32, 32.25_f32], 2.0);
        let band = epipolar_band(pl, o, (64, 64), (40.0, 60.0), eps, within).unwrap();
        // Top-left rows: floor(180.6 − 32.25 − 3) ..= ceil(180.6 − 32.25 + 3).
        assert_eq!((band.y, band.h), (145, 152 - 145 + 64));
        // Top-left columns: floor(250.4 − 60 − 31.5 − 1) ..= ceil(250.4 − 40 − 31.5 + 1).
        assert_eq!((band.x, band.w), (157, 180 - 157 + 64));
        // Every position in the band satisfies the row and disparity bounds.
        for ty in band.y..=band.y + band.h as i32 - 64 {
            for tx in band.x..=band.x + band.w as i32 - 64 {
                let pr = [tx as f32 + o[0], ty as f32 + o[1]];
                assert!((pr[1] - pl[1]).abs() <= eps + 1.0 + 1.0);
                let d = pl[0] - pr[0];
                assert!((40.0 - 2.0..=60.0 + 2.0).contains(&d), "{d}");
            }
        }
        // Clipped to the right window.
        let tight = Rect::new(170, 0, 80, 400);
        let clipped = epipolar_band(pl, o, (64, 64), (40.0, 60.0), eps, tight).unwrap();
        assert_eq!((clipped.x, clipped.w), (170, 157 + 87 - 170));
        // A window left of every plausible position, a window too narrow for
        // the template, and a non-finite range give no band.
        let left_of = Rect::new(0, 0, 150, 400);
        assert_eq!(
            epipolar_band(pl, o, (64, 64), (40.0, 60.0), eps, left_of),
            None
        );
        let narrow = Rect::new(200, 0, 60, 400);
        assert_eq!(
            epipolar_band(pl, o, (64, 64), (40.0, 60.0), eps, narrow),
            None
        );
        let nan = epipolar_band(pl, o, (64, 64), (f32::NAN, 60.0), eps, within);
        assert_eq!(nan, None);
    }

    /// Verifies: VTSM-RELOC-016
    #[test]
    fn setup_refuses_mismatched_images_small_workspaces_and_bad_inputs() {
        let (bytes, truth) = scene();
        let map = MapView::new_checked(&bytes).unwrap();
        let rig = rig();
        let p = test_params();
        let left = render_full(&map, &rig.cam, &truth, 0.85, 20.0);
        let right = render_full(&map, &rig.cam, &rig.world_from_right(&truth), 0.85, 20.0);
        let small = vec![0u8; 320 * 240];
        let lv = GrayView::new(&left, 640, 480, 640).unwrap();
        let rv = GrayView::new(&right, 640, 480, 640).unwrap();
        let sv = GrayView::new(&small, 320, 240, 320).unwrap();
        let good = Setup::new(&map, lv, rv, &rig, &p, &truth, 1);
        assert_eq!(good.sizes(), TEST_WORKSPACE);
        assert_eq!(good.validate(), Ok(()));
        let build = |s: &Setup, sizes: WorkspaceSizes| {
            let (mut b, mut w, mut r) = workspace_buffers(&sizes);
            let ws = Workspace::new(sizes, &mut b, &mut w, &mut r).unwrap();
            s.build(ws).err()
        };
        assert_eq!(build(&good, TEST_WORKSPACE), None);
        let mismatched = Setup {
            frames: StereoPair::new(lv, sv),
            ..good
        };
        assert_eq!(
            build(&mismatched, TEST_WORKSPACE),
            Some(FailureCode::ImageSizeMismatch)
        );
        let tiny = WorkspaceSizes::new(32, 256, ncc::Search::CoarseToFine);
        assert_eq!(
            build(&good, tiny),
            Some(FailureCode::ConfigCapacityTooSmall)
        );
        let wide = Setup {
            params: Params {
                search_px: 512,
                ..p
            },
            ..good
        };
        assert_eq!(
            build(&wide, TEST_WORKSPACE),
            Some(FailureCode::ConfigCapacityTooSmall)
        );
        let bad_params = Setup {
            params: Params { n_corr: 1, ..p },
            ..good
        };
        assert_eq!(
            build(&bad_params, TEST_WORKSPACE),
            Some(FailureCode::ConfigParamOutOfRange)
        );
        let mut bad_policy = good;
        bad_policy.policy.min_score = 2.0;
        assert_eq!(
            bad_policy.validate(),
            Err(FailureCode::ConfigParamOutOfRange)
        );
        let mut bad_options = good;
        bad_options.options.min_inliers = 0;
        assert_eq!(
            bad_options.validate(),
            Err(FailureCode::ConfigParamOutOfRange)
        );
        let nan_prior = Setup {
            prior: Pose::new(truth.rotation(), Vec3::new(f32::NAN, 0.0, 0.0)),
            ..good
        };
        assert_eq!(
            build(&nan_prior, TEST_WORKSPACE),
            Some(FailureCode::RelocPriorInvalid)
        );
    }

    proptest::proptest! {
        /// Verifies: VTSM-RELOC-019
        #[test]
        fn search_window_is_inside_the_image_and_under_the_cap(
            u in -100.0f32..800.0, v in -100.0f32..600.0, r in -10i32..600, l in 16usize..128,
        ) {
            let l = l & !1;
            let cap = 256usize.max(l);
            let s = search_rect([u, v], l, r, cap, 640, 480);
            proptest::prop_assert!(s.x >= 0 && s.y >= 0);
            proptest::prop_assert!(s.x as u32 + s.w <= 640 && s.y as u32 + s.h <= 480);
            proptest::prop_assert!(s.w as usize <= cap && s.h as usize <= cap);
            // Away from the border the window is centred on the prediction and holds the template.
            let inner = u > 300.0 && u < 340.0 && v > 220.0 && v < 260.0;
            if inner && r >= 0 {
                proptest::prop_assert!(s.w as usize >= l && s.h as usize >= l);
                let cx = s.x as f32 + s.w as f32 / 2.0;
                proptest::prop_assert!((cx - u).abs() <= 1.0);
            }
        }
    }

    fn perturb(truth: &Pose, rng: &mut Rng, t_m: f32, r_deg: f32) -> Pose {
        let axis = rng.unit_vector3();
        let az = rng.uniform(0.0, core::f32::consts::TAU);
        let d = Vec3::new(libm::cosf(az), libm::sinf(az), rng.uniform(-0.2, 0.2)).normalize() * t_m;
        let rot = truth.rotation() * UnitQuaternion::from_scaled_axis(axis * r_deg.to_radians());
        Pose::new(rot, truth.translation() + d)
    }

    /// Verifies: VTSM-RELOC-001
    #[test]
    fn converges_from_perturbed_priors_on_a_textured_scene() {
        let bytes = build_map(1);
        let map = MapView::new_checked(&bytes).unwrap();
        let rig = rig();
        let truth = camera_pose(0.6, 0.2);
        let left = render_full(&map, &rig.cam, &truth, 0.85, 20.0);
        let right = render_full(&map, &rig.cam, &rig.world_from_right(&truth), 0.85, 20.0);
        let mut rng = Rng::new(77);
        for (k, (t, r)) in [(0.10f32, 1.0f32), (0.15, 1.5), (0.20, 1.2)]
            .iter()
            .enumerate()
        {
            let prior = perturb(&truth, &mut rng, *t, *r);
            let out = relocalize(&map, &left, &right, &prior, 100 + k as u64);
            let (et, er) = out.pose.error_to(&truth);
            std::println!(
                "prior {t} m {r}°: err {et:.4} m {:.3}°, failure {:?}, inliers {}, iters {}, attempts {}",
                er.to_degrees(),
                out.failure,
                out.quality.inliers,
                out.stats.successes,
                out.stats.attempts
            );
            assert_eq!(out.failure, None);
            assert!(et < 0.05, "error {et} m");
            assert!(out.quality.inliers >= 15);
            // Work stays under the structural bound; RANSAC ran in chunks.
            let p = test_params();
            let max = Relocalizer::<Pipeline, RansacSolver>::max_work_units(&p);
            let s = out.stats;
            assert!(s.work_units <= max && s.ransac_chunks > 0);
            assert_eq!(s.work_units, s.attempts + s.solves + s.ransac_chunks);
            assert!(s.pipeline.renders <= 2 * s.attempts);
            assert!(s.ransac_iterations <= s.solves * u32::from(p.ransac_iter));
            if k == 0 {
                // Same seed, stepped 3 units at a time: bit-identical outcome.
                let p = test_params();
                let stepped = relocalize_stepped(&map, &left, &right, &prior, 100, &p, 3);
                assert_eq!(
                    stepped.pose.t().map(f32::to_bits),
                    out.pose.t().map(f32::to_bits)
                );
                assert_eq!(
                    stepped.pose.q().map(f32::to_bits),
                    out.pose.q().map(f32::to_bits)
                );
                assert_eq!(stepped.stats, out.stats);
                assert_eq!(stepped.quality, out.quality);
            }
        }
    }

    /// Verifies: VTSM-RELOC-035
    #[test]
    fn stepping_by_stage_reports_each_stage_and_changes_nothing() {
        let (bytes, truth) = scene();
        let map = MapView::new_checked(&bytes).unwrap();
        let rig = rig();
        let left = render_full(&map, &rig.cam, &truth, 0.85, 20.0);
        let right = render_full(&map, &rig.cam, &rig.world_from_right(&truth), 0.85, 20.0);
        let prior = perturb(&truth, &mut Rng::new(31), 0.15, 1.2);
        let whole = relocalize(&map, &left, &right, &prior, 41);
        let (staged, stages) = relocalize_by_stage(&map, &left, &right, &prior, 41);
        let bits = |o: &Outcome| {
            let (t, q) = (o.pose.t(), o.pose.q());
            (t.map(f32::to_bits), q.map(f32::to_bits))
        };
        assert_eq!(bits(&staged), bits(&whole));
        assert_eq!(staged.stats, whole.stats);
        assert_eq!(staged.quality, whole.quality);
        assert_eq!(staged.failure, whole.failure);
        assert_eq!(
            staged.log.counters().collect::<Vec<_>>(),
            whole.log.counters().collect::<Vec<_>>()
        );
        // Every attempt begins with Render; Match only after Render, Stereo
        // only after Match; the pose units are the solves and their chunks.
        let count = |k: Stage| stages.iter().filter(|&&s| s == k).count() as u32;
        let s = staged.stats;
        assert_eq!(count(Stage::Render), s.attempts);
        assert_eq!(count(Stage::Pose), s.solves + s.ransac_chunks);
        assert!(count(Stage::Stereo) >= s.pipeline.triangulations);
        assert!(s.pipeline.triangulations >= s.correspondences && s.correspondences > 0);
        assert!(count(Stage::Match) >= count(Stage::Stereo));
        for w in stages.windows(2) {
            match w[1] {
                Stage::Match => assert_eq!(w[0], Stage::Render),
                Stage::Stereo => assert_eq!(w[0], Stage::Match),
                _ => {}
            }
        }
        let kinds = [Stage::Render, Stage::Match, Stage::Stereo, Stage::Pose];
        assert!(stages.iter().all(|s| kinds.contains(s)), "{stages:?}");
        assert_eq!(staged.failure, None);
    }

    /// Verifies: VTSM-RELOC-015
    #[test]
    fn wrong_prior_or_wrong_place_gives_a_failure_code() {
        let bytes = build_map(1);
        let map = MapView::new_checked(&bytes).unwrap();
        let rig = rig();
        let truth = camera_pose(0.6, 0.2);
        // Images of a different place: another random scene.
        let other_bytes = build_map(2);
        let other = MapView::new_checked(&other_bytes).unwrap();
        let left = render_full(&other, &rig.cam, &truth, 1.0, 0.0);
        let right = render_full(&other, &rig.cam, &rig.world_from_right(&truth), 1.0, 0.0);
        // Fewer attempts per round keep the failing cases short; the rules are the same.
        let quick = Params {
            attempts_per_iter: 100,
            max_reseed: 1,
            ..test_params()
        };
        let out = relocalize_with(&map, &left, &right, &truth, 5, &quick);
        std::println!(
            "other place: {:?} inliers {}",
            out.failure,
            out.quality.inliers
        );
        assert!(out.failure.is_some());
        // A prior 1 m off: either a failure code or (if it still finds the truth) a correct pose.
        let left = render_full(&map, &rig.cam, &truth, 1.0, 0.0);
        let right = render_full(&map, &rig.cam, &rig.world_from_right(&truth), 1.0, 0.0);
        let prior = Pose::new(
            truth.rotation(),
            truth.translation() + Vec3::new(0.7, 0.7, 0.0).normalize(),
        );
        let out = relocalize_with(&map, &left, &right, &prior, 6, &quick);
        let (et, _) = out.pose.error_to(&truth);
        std::println!("1 m off: {:?} err {et}", out.failure);
        assert!(
            out.failure.is_some() || et < 0.05,
            "confident wrong pose, error {et} m"
        );
    }

    /// A source that serves `good` reads and then fails every read.
    struct FailAfter<'a> {
        pair: StereoPair<'a>,
        good: u32,
        reads: u32,
    }

    impl FrameSource for FailAfter<'_> {
        fn size(&self) -> (usize, usize) {
            self.pair.size()
        }
        fn read_window(&mut self, eye: Eye, r: Rect, out: &mut [u8]) -> Result<(), FailureCode> {
            self.reads += 1;
            if self.reads > self.good {
                return Err(FailureCode::HalFrameStoreRead);
            }
            self.pair.read_window(eye, r, out)
        }
    }

    /// A frame source that stops serving reads part-way through the run ends
    /// the relocalization at that attempt with `RELOC_FRAME_READ_FAILED`; one
    /// that serves every read gives the in-memory pair's outcome.
    ///
    /// Verifies: VTSM-RELOC-037
    #[test]
    fn a_frame_source_that_fails_ends_the_run_with_its_code() {
        let (bytes, truth) = scene();
        let map = MapView::new_checked(&bytes).unwrap();
        let rig = rig();
        let left = render_full(&map, &rig.cam, &truth, 0.85, 20.0);
        let right = render_full(&map, &rig.cam, &rig.world_from_right(&truth), 0.85, 20.0);
        let lv = GrayView::new(&left, 640, 480, 640).unwrap();
        let rv = GrayView::new(&right, 640, 480, 640).unwrap();
        let prior = perturb(&truth, &mut Rng::new(31), 0.15, 1.2);
        let run = |good: u32| {
            let src = FailAfter {
                pair: StereoPair::new(lv, rv),
                good,
                reads: 0,
            };
            let mut setup = Setup::with_frames(&map, src, &rig, &test_params(), &prior, 41);
            setup.options.min_inliers = 15;
            let (mut b, mut w, mut r) = workspace_buffers(&setup.sizes());
            let ws = Workspace::new(setup.sizes(), &mut b, &mut w, &mut r).unwrap();
            let mut engine = setup.build(ws).unwrap();
            let out = engine.run_to_completion(0);
            (out, engine.attempt_ref().frames().reads)
        };
        let (all, reads) = run(u32::MAX);
        let whole = relocalize(&map, &left, &right, &prior, 41);
        assert_eq!(
            all.pose.t().map(f32::to_bits),
            whole.pose.t().map(f32::to_bits)
        );
        assert_eq!(all.stats, whole.stats);
        assert_eq!(all.failure, None);
        // 2 × 64 preflight reads, then windows.
        assert!(reads > 128, "{reads}");
        let (cut, _) = run(128 + 40);
        assert_eq!(cut.failure, Some(FailureCode::RelocFrameReadFailed));
        assert!(cut.stats.attempts > 0 && cut.stats.attempts < all.stats.attempts);
        let (early, _) = run(3);
        assert_eq!(early.failure, Some(FailureCode::RelocFrameReadFailed));
        assert_eq!(early.stats.attempts, 0);
    }
}
