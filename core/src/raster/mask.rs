//! The template mask of paper §III-C from a rendered window's depth and mask
//! depth buffers.
//!
//! Input: two `w × h` depth buffers (w, h ≤ `MAX_RENDER_PX`); output: 255 where
//! M̂ is the visible surface or lies in front of a silhouette jump nearby, 0
//! elsewhere, and the kept count. O(w·h·(2r+1)), one row buffer on the stack.

use super::depth::{DEPTH_FRAC_BITS, DEPTH_NONE};
use crate::config::{
    MAX_RENDER_PX, TEMPLATE_MASK_JUMP_M, TEMPLATE_MASK_JUMP_REL_DIV, TEMPLATE_MASK_RADIUS_PX,
};

/// Form the template mask of paper §III-C from a rendered window.
///
/// Rule: pixel p is kept (255) when M̂ is the visible surface there
/// (`mask_depth[p] != DEPTH_NONE`), or when some pixel q within
/// [`TEMPLATE_MASK_RADIUS_PX`] (Chebyshev) has `mask_depth[q]` set and p lies
/// behind it by a depth discontinuity: `depth[p] > mask_depth[q] + J(q)` with
/// `J(q) = TEMPLATE_MASK_JUMP_M + mask_depth[q] / TEMPLATE_MASK_JUMP_REL_DIV`
/// (empty pixels count as infinitely far). These are background pixels at rock
/// silhouettes. Everything else is 0. Returns the number of kept pixels.
///
/// Bounds: O(w·h·(2r+1)) with separable minimum filters; one row buffer of
/// [`MAX_RENDER_PX`] `u32` on the stack. Invalid sizes (`w`, `h` outside
/// `1..=MAX_RENDER_PX` or a slice shorter than `w·h`) write nothing and return 0.
#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "w, h ≤ MAX_RENDER_PX are checked first (w·h and h − 1 are exact); JUMP_Q16 is a constant below 2^32"
)]
pub fn template_mask(depth: &[u32], mask_depth: &[u32], w: usize, h: usize, out: &mut [u8]) -> u32 {
    // Sizes first: w·h is formed only for sizes within the cap (no overflow).
    if !((1..=MAX_RENDER_PX).contains(&w) && (1..=MAX_RENDER_PX).contains(&h)) {
        return 0;
    }
    let n = w * h;
    let (Some(depth), Some(mdepth), Some(out)) =
        (depth.get(..n), mask_depth.get(..n), out.get_mut(..n))
    else {
        return 0;
    };
    const JUMP_Q16: u32 = (TEMPLATE_MASK_JUMP_M * (1u32 << DEPTH_FRAC_BITS) as f32) as u32;
    let r = TEMPLATE_MASK_RADIUS_PX;
    // Separable minimum filter of mask_depth over the (2r+1)² neighbourhood, one
    // output row at a time: column minimum, then row minimum (straight slice loops).
    let mut colmin = [DEPTH_NONE; MAX_RENDER_PX];
    let mut nbmin = [DEPTH_NONE; MAX_RENDER_PX];
    let (Some(colmin), Some(nbmin)) = (colmin.get_mut(..w), nbmin.get_mut(..w)) else {
        return 0;
    };
    let mut kept = 0u32;
    for y in 0..h {
        // w, h ≤ MAX_RENDER_PX (checked above): no row offset below can wrap.
        let row_of = |y: usize| y.wrapping_mul(w)..y.wrapping_add(1).wrapping_mul(w);
        let (y0, y1) = (y.saturating_sub(r), y.saturating_add(r).min(h - 1));
        colmin.fill(DEPTH_NONE);
        for yy in y0..=y1 {
            if let Some(row) = mdepth.get(row_of(yy)) {
                for (c, m) in colmin.iter_mut().zip(row) {
                    *c = (*c).min(*m);
                }
            }
        }
        nbmin.copy_from_slice(colmin);
        for d in 1..=r.min(w.saturating_sub(1)) {
            let (Some(right), Some(left)) = (colmin.get(d..), colmin.get(..w.wrapping_sub(d)))
            else {
                break;
            };
            for (n, c) in nbmin.iter_mut().zip(right) {
                *n = (*n).min(*c);
            }
            if let Some(tail) = nbmin.get_mut(d..) {
                for (n, c) in tail.iter_mut().zip(left) {
                    *n = (*n).min(*c);
                }
            }
        }
        let (Some(drow), Some(mrow), Some(orow)) = (
            depth.get(row_of(y)),
            mdepth.get(row_of(y)),
            out.get_mut(row_of(y)),
        ) else {
            break;
        };
        for (((o, d), own), m) in orow.iter_mut().zip(drow).zip(mrow).zip(nbmin.iter()) {
            // J grows with depth, so the minimum of mask_depth + J is J applied to the minimum.
            let thr = m
                .saturating_add(JUMP_Q16)
                .saturating_add(m / TEMPLATE_MASK_JUMP_REL_DIV);
            let keep = *own != DEPTH_NONE || (*m != DEPTH_NONE && *d > thr);
            *o = if keep { 255 } else { 0 };
            kept = kept.saturating_add(u32::from(keep));
        }
    }
    kept
}
