//! The depth format of every render: camera-frame Z in metres as a `u32` in
//! units of 2⁻¹⁶ m, [`DEPTH_NONE`] where nothing was drawn.
//!
//! Input: Z in metres (any `f32`); output: a depth value saturating at
//! [`DEPTH_MAX`], and back. See `fsw-docs/budgets/numeric.md`.

/// Depth value of a pixel where no surface was drawn.
pub const DEPTH_NONE: u32 = u32::MAX;

/// Fractional bits of the depth format: depth = round(Z · 2^16), Z in metres.
pub const DEPTH_FRAC_BITS: u32 = 16;

/// Largest depth value a surface can have (one below [`DEPTH_NONE`]), ≈ 65 535.99 m.
pub const DEPTH_MAX: u32 = u32::MAX - 1;

pub(super) const DEPTH_SCALE: f32 = (1u32 << DEPTH_FRAC_BITS) as f32;

/// Convert camera Z in metres to the depth format (rounded, saturating at [`DEPTH_MAX`]).
#[inline]
#[allow(
    clippy::cast_possible_truncation,
    reason = "float-to-int `as` saturates; the result is capped at DEPTH_MAX"
)]
pub fn depth_from_m(z_m: f32) -> u32 {
    // `as` saturates: NaN and negatives give 0, values beyond u32 give u32::MAX.
    ((z_m * DEPTH_SCALE + 0.5) as u32).min(DEPTH_MAX)
}

/// Convert a depth value to metres; `None` for [`DEPTH_NONE`].
#[inline]
pub fn depth_to_m(depth: u32) -> Option<f32> {
    (depth != DEPTH_NONE).then(|| depth as f32 / DEPTH_SCALE)
}
