//! Match (§III-D): the policy's template variants tried in order against the
//! real left and right search windows, the right template rendered and the
//! right window read only once a left match is accepted, the right search
//! confined to the epipolar band where Valid can accept it.

use super::sample::{render_template, template_mask};
use super::window::{epipolar_band, read_window};
use super::{Pipeline, Sample, Templates, Windows};
use crate::failure::FailureCode;
use crate::frame::{Eye, FrameSource, Window};
use crate::geom::Camera;
use crate::image::{GrayView, Rect};
use crate::map::MapView;
use crate::ncc::{self, Scratch, Search};
use crate::reloc::policy::{MatchPolicy, Variant};
use crate::reloc::PipelineStats;

/// A template and its mask, as the searches read them.
#[derive(Clone, Copy)]
struct TemplateViews<'t> {
    image: GrayView<'t>,
    mask: GrayView<'t>,
}

/// The right template's buffers before its render: intensity, depth,
/// mask depth and mask.
type RightBuffers<'b> = (&'b mut [u8], &'b mut [u32], &'b mut [u32], &'b mut [u8]);

/// The ℓ×ℓ view of a template buffer.
fn view(b: &[u8], l: usize) -> Result<GrayView<'_>, FailureCode> {
    GrayView::new(b, l, l, l)
}

/// The views a variant searches with: the whole template, or its centred
/// ℓ/2 sub-template when `half`.
fn crop(t: TemplateViews<'_>, half: bool) -> Option<TemplateViews<'_>> {
    if half {
        Some(TemplateViews {
            image: ncc::sub_template(&t.image)?,
            mask: ncc::sub_template(&t.mask)?,
        })
    } else {
        Some(t)
    }
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

/// The value of `r`, or `None` with its code kept in `last` (a variant that
/// is rejected leaves its code for the attempt, unless a later one is accepted).
fn kept_or_last<T>(r: Result<T, FailureCode>, last: &mut FailureCode) -> Option<T> {
    match r {
        Ok(v) => Some(v),
        Err(e) => {
            *last = e;
            None
        }
    }
}

/// One search of variant `v`: counted in `stats.matches` whether or not
/// there is a window, scored over `search` by `mode`, accepted under `policy`.
fn search_accepted(
    v: Variant,
    policy: &MatchPolicy,
    t: TemplateViews<'_>,
    img: Option<&Window<'_>>,
    (search, mode): (Rect, Search),
    scratch: &mut Scratch<'_>,
    stats: &mut PipelineStats,
) -> Result<ncc::Match, FailureCode> {
    if let Some(c) = stats.matches.get_mut(v.index()) {
        *c = c.saturating_add(1);
    }
    let img = img.ok_or(FailureCode::NccWindowOutsideImage)?;
    let (m, ms) =
        ncc::match_in_window(t.image, Some(t.mask), img, search, v.filter, mode, scratch)?;
    stats.ncc_positions = stats.ncc_positions.saturating_add(ms.positions_scored);
    stats.ncc_macs = stats.ncc_macs.saturating_add(ms.macs);
    accept(&m, policy)?;
    Ok(m)
}

/// The vertex's pixel inside the left and the right template of variant
/// `half` (projection − template origin − sub-template origin).
fn vertex_in_templates(s: &Sample, t: &Templates, l: usize, half: bool) -> ([f32; 2], [f32; 2]) {
    let (ox, oy) = if half {
        let r = ncc::sub_template_rect(l, l);
        (r.x as f32, r.y as f32)
    } else {
        (0.0, 0.0)
    };
    (
        [
            s.left[0] - t.left.x as f32 - ox,
            s.left[1] - t.left.y as f32 - oy,
        ],
        [
            s.right[0] - t.right.x as f32 - ox,
            s.right[1] - t.right.y as f32 - oy,
        ],
    )
}

/// Render the right template of `t` into `bufs` and form its mask; the
/// rendered buffers become the views the right searches read.
fn render_right<'b>(
    map: &MapView<'_>,
    cam: &Camera,
    t: &Templates,
    l: usize,
    (inten, depth, mdepth, mask): RightBuffers<'b>,
    stats: &mut PipelineStats,
) -> Result<TemplateViews<'b>, FailureCode> {
    render_template(
        map,
        cam,
        &t.vp_right,
        t.right,
        (&mut *inten, &mut *depth, &mut *mdepth),
        (&mut stats.renders, &mut stats.render_pixels),
    )?;
    template_mask(depth, mdepth, mask, l)?;
    let (inten, mask): (&'b [u8], &'b [u8]) = (inten, mask);
    Ok(TemplateViews {
        image: view(inten, l)?,
        mask: view(mask, l)?,
    })
}

/// Where and how the right match is sought for a left match whose vertex
/// pixel is `pl` (`or` inside a right template of `size`): the whole right
/// window, or with [`MatchPolicy::epipolar_band`] only the band where Valid
/// can accept it, scored exhaustively when it holds no more positions than
/// the coarse-to-fine search would score at full resolution alone (its
/// candidates × (2r + 1)²).
///
/// # Errors
/// [`FailureCode::StereoEpipolarViolation`] when the band holds no position.
fn right_search(
    policy: &MatchPolicy,
    v: Variant,
    (pl, or): ([f32; 2], [f32; 2]),
    (tw, th): (usize, usize),
    win: &Windows,
    epsilon_px: f32,
) -> Result<(Rect, Search), FailureCode> {
    if !policy.epipolar_band {
        return Ok((win.right, policy.search));
    }
    let band = epipolar_band(pl, or, (tw, th), win.disparity, epsilon_px, win.right)
        .ok_or(FailureCode::StereoEpipolarViolation)?;
    let cfg = ncc::SearchConfig::for_filter(v.filter);
    let side = cfg
        .final_refine_radius_px()
        .saturating_mul(2)
        .saturating_add(1);
    let c2f_full_res = cfg.candidates().saturating_mul(side).saturating_mul(side);
    let positions = (band.w as usize)
        .saturating_sub(tw)
        .saturating_add(1)
        .saturating_mul((band.h as usize).saturating_sub(th).saturating_add(1));
    if positions <= c2f_full_res {
        Ok((band, Search::Exhaustive))
    } else {
        Ok((band, policy.search))
    }
}

impl<F: FrameSource> Pipeline<'_, '_, F> {
    /// Match (§III-D): try the policy's variants in order; the first whose
    /// left and right searches are both accepted gives the vertex's pixel in
    /// each real image. Otherwise the last rejection's code.
    pub(super) fn match_pair(
        &mut self,
        s: &Sample,
        t: Templates,
        win: Windows,
        stats: &mut PipelineStats,
    ) -> Result<([f32; 2], [f32; 2], u8), FailureCode> {
        let l = self.template_px;
        let ws = &mut self.ws;
        let left = TemplateViews {
            image: view(ws.inten_l, l)?,
            mask: view(ws.mask_l, l)?,
        };
        // The right template is rendered at the first accepted left match.
        let mut right_tpl: Option<RightBuffers<'_>> = Some((
            &mut *ws.inten_r,
            &mut *ws.depth_r,
            &mut *ws.mdepth_r,
            &mut *ws.mask_r,
        ));
        let mut right: Option<TemplateViews<'_>> = None;
        // The left window is read once per attempt, the right one at the
        // first accepted left match (an attempt rejected on the left reads
        // nothing more); an empty window reads nothing and matches nothing,
        // as a search outside the image does.
        let left_win = read_window(&mut self.frames, Eye::Left, win.left, ws.frame_l)?;
        let mut right_buf = Some(&mut *ws.frame_r);
        let mut right_win: Option<Window<'_>> = None;
        let mut last = FailureCode::NccLowScore;
        let policy = &self.policy;
        for &v in policy.variants.iter().flatten() {
            if self.gradient_only && !crate::reloc::policy::is_gradient_variant(v.index() as u8) {
                continue;
            }
            let Some(tl) = crop(left, v.half) else {
                continue;
            };
            let found_left = search_accepted(
                v,
                policy,
                tl,
                left_win.as_ref(),
                (win.left, policy.search),
                &mut ws.scratch,
                stats,
            );
            let Some(ml) = kept_or_last(found_left, &mut last) else {
                continue;
            };
            let (ol, or) = vertex_in_templates(s, &t, l, v.half);
            let pl = [ml.sub_x + ol[0], ml.sub_y + ol[1]];
            if let Some(bufs) = right_tpl.take() {
                right = Some(render_right(self.map, &self.rig.cam, &t, l, bufs, stats)?);
            }
            let Some(tr) = right.and_then(|r| crop(r, v.half)) else {
                continue;
            };
            let size = (tr.image.width(), tr.image.height());
            let band = right_search(policy, v, (pl, or), size, &win, self.epsilon_px);
            let Some(band) = kept_or_last(band, &mut last) else {
                continue;
            };
            if let Some(buf) = right_buf.take() {
                right_win = read_window(&mut self.frames, Eye::Right, win.right, buf)?;
            }
            let found_right = search_accepted(
                v,
                policy,
                tr,
                right_win.as_ref(),
                band,
                &mut ws.scratch,
                stats,
            );
            let Some(mr) = kept_or_last(found_right, &mut last) else {
                continue;
            };
            let idx = v.index();
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
}
