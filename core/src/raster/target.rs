//! The render target and its pixel sink: the caller's three window buffers,
//! the per-pixel and per-run depth test that writes them, and [`RenderStats`].
//!
//! Input: fragments (pixel index, depth, 16.16 texture coordinates, mask flag)
//! or linear runs of them; output: intensity, depth and mask depth written
//! where a fragment is nearer than what is stored (strict less: ties keep the
//! first surface). A run touches at most its `n` pixels; out-of-range indices
//! are skipped, never written.

use super::depth::{DEPTH_MAX, DEPTH_NONE};
use super::texture::{sample_bilinear, sample_inner};

/// Render target for one window: three row-major buffers of at least `w·h`
/// elements, stride = window width. Elements past `w·h` are never touched.
#[derive(Debug)]
pub struct Target<'b> {
    /// Intensity, 0 where nothing was drawn.
    pub intensity: &'b mut [u8],
    /// Depth of the visible surface, [`DEPTH_NONE`] where nothing was drawn.
    pub depth: &'b mut [u32],
    /// Depth where the visible surface belongs to M̂, else [`DEPTH_NONE`].
    pub mask_depth: &'b mut [u32],
}

/// Work done by one [`render_window`](super::render_window) call.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RenderStats {
    /// Non-empty tiles tested against the frustum.
    pub tiles_tested: u32,
    /// Tiles whose box intersects the frustum.
    pub tiles_visible: u32,
    /// Triangles of visible tiles examined.
    pub triangles_tested: u32,
    /// Clipped triangles (one polygon each) whose spans were filled.
    pub triangles_drawn: u32,
    /// Drawn triangles whose depth and texture coordinates were interpolated
    /// linearly in the image (small depth range), the others perspective-correct.
    pub triangles_linear: u32,
    /// Non-empty row spans filled.
    pub spans: u32,
    /// Depth-test passes (pixel writes; a pixel overwritten by a nearer surface counts twice).
    pub pixels_written: u32,
}

/// One pixel that a triangle covers, handed to the pixel sink.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Frag {
    /// Index into the window buffers (`y · w + x`).
    pub idx: usize,
    /// Depth in the depth format (see [`DEPTH_FRAC_BITS`]).
    pub depth: u32,
    /// Texture coordinates in texture pixels, 16.16 fixed point.
    pub u_q16: i64,
    pub v_q16: i64,
    /// The triangle belongs to M̂.
    pub mask: bool,
}

/// Receives every covered pixel of a render.
pub(crate) trait PixelSink {
    fn put(&mut self, f: Frag);

    /// A run of `n ≥ 1` covered pixels at consecutive indices from `idx`, with
    /// depth and texture coordinates stepped linearly: pixel `k` has
    /// `(acc + k·step) >> RUN_SHIFT` (depth, u, v). Same effect as [`Self::put`]
    /// on each pixel in order.
    #[inline]
    fn put_run(&mut self, idx: usize, n: usize, acc: [i64; 3], step: [i64; 3], mask: bool) {
        put_each(self, idx, n, (acc, step), mask);
    }
}

/// [`PixelSink::put_run`] as one [`PixelSink::put`] per pixel, in order.
#[inline]
fn put_each<S: PixelSink + ?Sized>(
    sink: &mut S,
    idx: usize,
    n: usize,
    (acc, step): ([i64; 3], [i64; 3]),
    mask: bool,
) {
    let mut acc = acc;
    for k in 0..n {
        sink.put(run_frag(idx.wrapping_add(k), acc, mask));
        acc = [
            acc[0].wrapping_add(step[0]),
            acc[1].wrapping_add(step[1]),
            acc[2].wrapping_add(step[2]),
        ];
    }
}

/// The fragment of a linear run at accumulator `acc` (values scaled by `2^RUN_SHIFT`).
#[inline(always)]
#[allow(
    clippy::cast_possible_truncation,
    reason = "clamped to 0..=DEPTH_MAX (< 2^32) before the cast"
)]
pub(super) fn run_frag(idx: usize, acc: [i64; 3], mask: bool) -> Frag {
    Frag {
        idx,
        depth: (acc[0] >> RUN_SHIFT).clamp(0, i64::from(DEPTH_MAX)) as u32,
        u_q16: acc[1] >> RUN_SHIFT,
        v_q16: acc[2] >> RUN_SHIFT,
        mask,
    }
}

impl<F: FnMut(Frag)> PixelSink for F {
    #[inline]
    fn put(&mut self, f: Frag) {
        self(f)
    }
}

/// The render target's pixel sink: depth test, mask depth, textured intensity.
pub(super) struct ZBuffer<'t, 'b> {
    pub(super) intensity: &'b mut [u8],
    pub(super) depth: &'b mut [u32],
    pub(super) mask_depth: &'b mut [u32],
    pub(super) tex: &'t [u8],
    pub(super) tw: usize,
    pub(super) th: usize,
    pub(super) written: u32,
}

impl PixelSink for ZBuffer<'_, '_> {
    #[inline(always)]
    fn put(&mut self, f: Frag) {
        let d = f.depth;
        if let Some(slot) = self.depth.get_mut(f.idx) {
            if d < *slot {
                *slot = d;
                if let Some(m) = self.mask_depth.get_mut(f.idx) {
                    *m = if f.mask { d } else { DEPTH_NONE };
                }
                if let Some(p) = self.intensity.get_mut(f.idx) {
                    *p = sample_bilinear(self.tex, self.tw, self.th, f.u_q16, f.v_q16);
                }
                self.written = self.written.saturating_add(1);
            }
        }
    }

    #[inline(always)]
    #[allow(
        clippy::cast_possible_truncation,
        reason = "clamped to 0..=DEPTH_MAX (< 2^32) before the cast"
    )]
    fn put_run(&mut self, idx: usize, n: usize, acc: [i64; 3], step: [i64; 3], mask: bool) {
        let end = idx.wrapping_add(n);
        // One bounds check per run: the three buffers have the same length (w·h).
        let (Some(ds), Some(ms), Some(is), true) = (
            self.depth.get_mut(idx..end),
            self.mask_depth.get_mut(idx..end),
            self.intensity.get_mut(idx..end),
            n >= 1,
        ) else {
            // Not reached for runs inside the window; the per-pixel path skips
            // out-of-range pixels the same way.
            put_each(self, idx, n, (acc, step), mask);
            return;
        };
        let (tex, tw, th) = (self.tex, self.tw, self.th);
        // Values are linear along the run, so their extremes are at its ends: when
        // both ends lie inside the depth range and at least one texel from the
        // texture's right and bottom edges, every pixel does, and the clamps of
        // `run_frag` and `sample_bilinear` are the identity (same pixels, less work).
        // Accumulators stay within ±2^58 (see `fill_polygon`), so no i64 overflow.
        let last = n.saturating_sub(1) as i64;
        let lo_hi = |a: i64, s: i64| {
            let b = a.wrapping_add(s.wrapping_mul(last));
            (a.min(b) >> RUN_SHIFT, a.max(b) >> RUN_SHIFT)
        };
        let (d0, d1) = lo_hi(acc[0], step[0]);
        let (u0, u1) = lo_hi(acc[1], step[1]);
        let (v0, v1) = lo_hi(acc[2], step[2]);
        let inner = d0 >= 0
            && d1 <= i64::from(DEPTH_MAX)
            && u0 >= 0
            && v0 >= 0
            && u1 < (tw as i64).saturating_sub(1) << 16
            && v1 < (th as i64).saturating_sub(1) << 16;
        let not_mask = if mask { 0 } else { DEPTH_NONE };
        if inner {
            let written = if mask {
                run_inner::<true>(ds, ms, is, tex, tw, acc, step)
            } else {
                run_inner::<false>(ds, ms, is, tex, tw, acc, step)
            };
            self.written = self.written.saturating_add(written);
            return;
        }
        let mut acc = acc;
        let mut written = 0u32;
        for ((slot, m), p) in ds.iter_mut().zip(ms.iter_mut()).zip(is.iter_mut()) {
            let d = (acc[0] >> RUN_SHIFT).clamp(0, i64::from(DEPTH_MAX)) as u32;
            if d < *slot {
                *slot = d;
                *m = d | not_mask;
                *p = sample_bilinear(tex, tw, th, acc[1] >> RUN_SHIFT, acc[2] >> RUN_SHIFT);
                written = written.wrapping_add(1);
            }
            acc = [
                acc[0].wrapping_add(step[0]),
                acc[1].wrapping_add(step[1]),
                acc[2].wrapping_add(step[2]),
            ];
        }
        self.written = self.written.saturating_add(written);
    }
}

/// The depth-test loop of a run whose depths lie in `0..=DEPTH_MAX` and whose
/// texture coordinates lie inside the texture by one texel (see `put_run`); a
/// function of its own so its state stays in registers. Returns the pixels written.
#[inline(never)]
#[allow(
    clippy::cast_possible_truncation,
    reason = "an inner run's depth is within 0..=DEPTH_MAX (checked by put_run before it calls this)"
)]
pub(super) fn run_inner<const MASK: bool>(
    ds: &mut [u32],
    ms: &mut [u32],
    is: &mut [u8],
    tex: &[u8],
    tw: usize,
    acc: [i64; 3],
    step: [i64; 3],
) -> u32 {
    let [mut z, mut u, mut v] = acc;
    let [sz, su, sv] = step;
    // The caller guarantees tw ≤ MAX_TEXTURE_DIM (map validation); the min tells the compiler.
    let tw = tw.min(crate::config::MAX_TEXTURE_DIM);
    let mut written = 0u32;
    for ((slot, m), p) in ds.iter_mut().zip(ms.iter_mut()).zip(is.iter_mut()) {
        let d = (z >> RUN_SHIFT) as u32;
        if d < *slot {
            *slot = d;
            *m = if MASK { d } else { DEPTH_NONE };
            *p = sample_inner(tex, tw, u, v);
            // At most MAX_RENDER_PX per run.
            written = written.wrapping_add(1);
        }
        // The caller bounds the accumulators (|acc| < 2^58): no i64 overflow.
        z = z.wrapping_add(sz);
        u = u.wrapping_add(su);
        v = v.wrapping_add(sv);
    }
    written
}

/// Fractional bits of the run accumulators handed to [`PixelSink::put_run`].
pub(super) const RUN_SHIFT: u32 = 16;

// `run_inner` hands the 16.16 texture accumulators to `sample_inner` as 32.32.
const _: () = assert!(RUN_SHIFT == 16);
