//! Bilinear texture sampling of the map's 8-bit texture at 16.16 (checked) or
//! 32.32 (inner-run) fixed-point texel coordinates.
//!
//! Input: texture bytes (stride = width ≤ `MAX_TEXTURE_DIM`) and a texel
//! position; output: one rounded 8-bit intensity. Edge texels are clamped (the
//! checked form) or the point is required one texel inside (the inner form).
//! 32-bit arithmetic throughout; no loop.

/// Bilinear sample of a texture (stride = width) at texture pixel `(u, v)`,
/// clamped to the edge texels; 8-bit weights, rounded. 32-bit arithmetic: the map
/// validates `1 ≤ tw, th ≤ MAX_TEXTURE_DIM = 2^14`, so clamped coordinates are
/// below 2^30 in 16.16, texel indices below 2^28, and every weighted sum below
/// 255·256·256 + 2^15 < 2^24 (the wrapping operations never wrap).
const _: () = assert!(crate::config::MAX_TEXTURE_DIM <= 1 << 14);

#[inline(always)]
#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "coordinates clamped to the texture (≤ MAX_TEXTURE_DIM = 2^14, asserted above) before the casts; x0 + 1, y0 + 1 < 2^15; the rounded lerp is ≤ 255"
)]
pub(super) fn sample_bilinear(tex: &[u8], tw: usize, th: usize, u_q16: i64, v_q16: i64) -> u8 {
    // max/min rather than clamp: no bounds-order check per pixel.
    let u = u_q16.max(0).min((tw as i64).saturating_sub(1) << 16) as u32;
    let v = v_q16.max(0).min((th as i64).saturating_sub(1) << 16) as u32;
    let (x0, y0) = ((u >> 16) as usize, (v >> 16) as usize);
    let fx = (u >> 8) & 0xFF;
    let fy = (v >> 8) & 0xFF;
    let dx = usize::from(x0 + 1 < tw);
    let dy = if y0 + 1 < th { tw } else { 0 };
    let i = y0.wrapping_mul(tw).wrapping_add(x0);
    let px = |k: usize| u32::from(tex.get(k).copied().unwrap_or(0));
    let top = lerp8(px(i), px(i.wrapping_add(dx)), fx);
    let j = i.wrapping_add(dy);
    let bot = lerp8(px(j), px(j.wrapping_add(dx)), fx);
    (lerp8(top, bot, fy).wrapping_add(1 << 15) >> 16) as u8
}

/// [`sample_bilinear`] for a point at least one texel inside the right and bottom
/// edges, given as 32.32 fixed-point texel coordinates `u`, `v` with
/// `0 ≤ u < (tw − 1)·2^32`, `0 ≤ v < (th − 1)·2^32` and `tw ≤ MAX_TEXTURE_DIM`:
/// same result, without the clamps and with one bounds check for the four texels.
#[inline(always)]
#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "texel indices < 2^28 (texture ≤ 2^14 × 2^14, asserted above); the rounded lerp is ≤ 255"
)]
pub(super) fn sample_inner(tex: &[u8], tw: usize, u: i64, v: i64) -> u8 {
    // The masks are the identity under the preconditions; they let the compiler
    // prove that the index arithmetic below cannot overflow.
    const MAX: usize = crate::config::MAX_TEXTURE_DIM - 1;
    let (x0, y0) = ((u >> 32) as usize & MAX, (v >> 32) as usize & MAX);
    let fx = ((u >> 24) & 0xFF) as u32;
    let fy = ((v >> 24) & 0xFF) as u32;
    let i = y0 * tw + x0;
    let Some((top, bottom)) = tex.get(i..i + tw + 2).and_then(|q| q.split_at_checked(tw)) else {
        return 0;
    };
    let (&[a, b, ..], &[c, d]) = (top, bottom) else {
        return 0;
    };
    let top = lerp8(u32::from(a), u32::from(b), fx);
    let bot = lerp8(u32::from(c), u32::from(d), fx);
    (lerp8(top, bot, fy).wrapping_add(1 << 15) >> 16) as u8
}

/// a·(256 − f) + b·f for f ≤ 256, computed as 256·a + (b − a)·f with wrapping
/// 32-bit operations: the exact result is below 2^24, so the wrapped
/// intermediate (b − a may be negative) gives it exactly.
#[inline(always)]
pub(super) fn lerp8(a: u32, b: u32, f: u32) -> u32 {
    (a << 8).wrapping_add(b.wrapping_sub(a).wrapping_mul(f))
}
