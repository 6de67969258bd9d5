//! The search windows of an attempt (§III-D) in the real images, how they are
//! read from the frame source, and the epipolar band of a left match.

use super::{round_i32, Pipeline, Sample, Windows};
use crate::failure::FailureCode;
use crate::frame::{self, Eye, FrameSource, Window};
use crate::image::Rect;
use crate::reloc::AttemptContext;

impl<F: FrameSource> Pipeline<'_, '_, F> {
    /// Search windows (§III-D): the projected (t̃, r̃) uncertainty around each
    /// predicted pixel plus the policy margin, capped at `search_px`, clipped
    /// to the image.
    pub(super) fn search_windows(&self, ctx: &AttemptContext, s: &Sample) -> Windows {
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
}

/// Search rectangle of side ℓ + 2r centred on `px`, capped at `cap` and clipped to the image.
pub(super) fn search_rect(px: [f32; 2], l: usize, r: i32, cap: usize, w: usize, h: usize) -> Rect {
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

/// `rect` of `eye` copied into `buf` with its filter ring, `None` for an
/// empty rectangle.
///
/// # Errors
/// [`FailureCode::RelocFrameReadFailed`] when the source cannot serve it.
pub(super) fn read_window<'b, F: FrameSource>(
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
pub(super) fn epipolar_band(
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
