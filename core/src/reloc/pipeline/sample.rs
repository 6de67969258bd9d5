//! SamplePoint and Synthesize (§III-C): a random mask vertex in view of both
//! images, and its ℓ×ℓ virtual template rendered with depth and masked.

use super::{
    round_i32, Pipeline, Sample, Templates, MAX_NEAR_TRIES, MAX_SAMPLE_TRIES, OCCLUSION_ABS_M,
    OCCLUSION_REL,
};
use crate::failure::FailureCode;
use crate::frame::FrameSource;
use crate::geom::{Camera, Pose};
use crate::image::Rect;
use crate::map::MapView;
use crate::raster::{self, Target};
use crate::reloc::{AttemptContext, PipelineStats};

impl<F: FrameSource> Pipeline<'_, '_, F> {
    /// SamplePoint: a random mask vertex whose left and right projections lie
    /// ℓ/2 inside both images, drawn uniformly from M̂, or in proportion to
    /// the map's scores when the product carries them (version 3). One
    /// random number per draw either way, so the draw count per attempt is
    /// the same bound, [`MAX_SAMPLE_TRIES`].
    ///
    /// With `revisit` (the context's [`AttemptContext::revisit`](crate::reloc::AttemptContext::revisit)) that mask
    /// vertex is tried first, without a random number; out of view, the
    /// draws follow as without it.
    ///
    /// With a Near vertex ([`AttemptContext::near`], never beside a revisit
    /// vertex) up to [`MAX_NEAR_TRIES`] Near draws come first, each four
    /// random numbers; the first that gives a mask vertex near it and in
    /// view is taken (counted in `near_drawn`), and if none does the draws
    /// anywhere follow as without it.
    pub(super) fn sample(
        &self,
        cam_from_world: &Pose,
        ctx: &AttemptContext,
        rng: &mut crate::rng::Rng,
        stats: &mut PipelineStats,
    ) -> Result<Sample, FailureCode> {
        if let Some(k) = ctx.revisit {
            match self.sample_vertex(cam_from_world, k) {
                Some(s) => {
                    stats.revisited = stats.revisited.saturating_add(1);
                    return Ok(Sample { revisit: true, ..s });
                }
                None => stats.out_of_view = stats.out_of_view.saturating_add(1),
            }
        }
        let anchor = ctx
            .near
            .and_then(|a| self.map.mask_vertex(a))
            .and_then(|i| self.map.vertex(i));
        if let Some(anchor) = anchor {
            for _ in 0..MAX_NEAR_TRIES {
                let Some(k) = self.draw_near(anchor, ctx.near_radius_m, rng) else {
                    continue;
                };
                if let Some(s) = self.sample_vertex(cam_from_world, k) {
                    stats.near_drawn = stats.near_drawn.saturating_add(1);
                    return Ok(Sample { near: true, ..s });
                }
            }
        }
        for _ in 0..MAX_SAMPLE_TRIES {
            let Some(k) = self.draw_mask_index(rng) else {
                continue;
            };
            match self.sample_vertex(cam_from_world, k) {
                Some(s) => return Ok(s),
                None => stats.out_of_view = stats.out_of_view.saturating_add(1),
            }
        }
        Err(FailureCode::RelocSampleOutOfView)
    }

    /// One draw of a mask index: uniform over M̂, or in proportion to the
    /// map's scores (version 3); one random number either way.
    fn draw_mask_index(&self, rng: &mut crate::rng::Rng) -> Option<u32> {
        if self.map.scored() {
            self.map.draw_mask_index(rng.below(self.map.score_total()))
        } else {
            Some(rng.below(self.map.mask_vertex_count()))
        }
    }

    /// One Near draw (VTSM-RELOC-047): a point uniform in the x-y square of
    /// half-side `radius_m` about `anchor`, a triangle uniform in the map
    /// tile holding it, one of its corners uniform; that corner's mask index
    /// when it is a mask vertex within `radius_m` of `anchor`. Four random
    /// numbers, a binary search of the mask.
    fn draw_near(
        &self,
        anchor: crate::geom::Vec3,
        radius_m: f32,
        rng: &mut crate::rng::Rng,
    ) -> Option<u32> {
        // All four numbers are drawn before any check, so every Near draw
        // moves the stream by the same count.
        let x = anchor.x + rng.uniform(-radius_m, radius_m);
        let y = anchor.y + rng.uniform(-radius_m, radius_m);
        let pick = rng.next_u32();
        let corner = rng.below(3);
        let tile = self.map.tile(self.map.tile_at(x, y)?)?;
        if tile.triangle_count == 0 {
            return None;
        }
        let t = tile.first_triangle.checked_add(
            (u64::from(pick).wrapping_mul(u64::from(tile.triangle_count)) >> 32) as u32,
        )?;
        let v = *self.map.triangle(t)?.v.get(corner as usize)?;
        let w = self.map.vertex(v)?;
        if (w - anchor).norm_squared() > radius_m * radius_m {
            return None;
        }
        self.map.mask_index_of(v)
    }

    /// Mask vertex `k` as a sample when it exists and its left and right
    /// projections lie ℓ/2 inside both images.
    fn sample_vertex(&self, cam_from_world: &Pose, k: u32) -> Option<Sample> {
        let margin = (self.template_px / 2) as f32;
        let world = self.map.mask_vertex(k).and_then(|i| self.map.vertex(i))?;
        let cam = cam_from_world.transform_point(&world);
        let (l, r) = self.rig.project_stereo(&cam)?;
        let inside =
            self.rig.cam.contains(l[0], l[1], margin) && self.rig.cam.contains(r[0], r[1], margin);
        inside.then_some(Sample {
            mask_index: k,
            revisit: false,
            near: false,
            world,
            cam,
            left: l,
            right: r,
        })
    }

    /// Synthesize (§III-C): render the ℓ×ℓ left template centred on the
    /// vertex's left projection, reject a vertex hidden in the virtual view,
    /// and form the left template mask. The right template is rendered by
    /// [`Pipeline::match_pair`] when a left match is accepted: an attempt
    /// rejected on the left (or hidden) never needs it.
    pub(super) fn synthesize(
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

/// Render the ℓ×ℓ template `rect` of the virtual camera at `pose` into the
/// intensity, depth and mask-depth buffers, counting the render and its
/// pixels (`PipelineStats::renders`, `render_pixels`).
pub(super) fn render_template(
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
pub(super) fn template_mask(
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
