//! Integer zero-mean normalized cross-correlation (the `Match` step, paper §III-D).
//!
//! Finds an 8-bit template (optionally masked: 255 keep / 0 drop, any non-zero
//! value keeps) inside a caller-bounded search window of an 8-bit image and
//! returns the top-left offset of the best match, its zero-mean NCC score (the
//! quantity OpenCV calls `TM_CCOEFF_NORMED`), a sub-pixel refinement and the
//! best score outside the main peak's neighbourhood (the runner-up).
//!
//! Every sum is exact integer arithmetic: window sums and sums of squares come
//! from u32 integral images (wrapping arithmetic, exact because every true window
//! sum is below 2³²), the numerator and variances are i64, candidates are
//! compared by `sign(num)·num²/var_f` through an exact 192-bit cross
//! multiplication (no square root), and the final score is one correctly rounded
//! IEEE f64 division and square root of exact integers, so it is bit-identical on
//! every target. The bit budget is in `fsw-docs/budgets/numeric.md`.
//!
//! Template variants: [`sub_template_rect`] gives the centred ℓ/2 crop; [`Filter`]
//! selects the gray, Sobel or Laplacian domain, each mapped back to 8 bits so the
//! one correlation kernel serves all three.
//!
//! Search: [`Search::Exhaustive`] scores every position (the oracle);
//! [`Search::CoarseToFine`] scores every position of a 2×-box pyramid's coarsest
//! level, keeps several separated peaks, refines each at each finer level and
//! picks the winner at full resolution; [`SearchConfig`] holds the numbers
//! (candidates, radii, coarsest template size), with a default per [`Filter`]
//! ([`SearchConfig::for_filter`]).
//!
//! Bounds: template sides in `MIN_TEMPLATE_PX..=MAX_TEMPLATE_PX`, window sides up
//! to `MAX_SEARCH_PX`, at most [`MAX_LEVELS`] pyramid levels; all memory is the
//! caller's [`Scratch`], sized by [`ScratchSizes`]. No allocation, no panic, no NaN.

use core::cmp::Ordering;

use crate::config::{MAX_SEARCH_PX, MAX_TEMPLATE_PX, MIN_TEMPLATE_PX};
use crate::failure::FailureCode;
use crate::image::{GrayView, Rect};

/// Largest number of pyramid levels (level 0 = full resolution).
pub const MAX_LEVELS: usize = 4;
/// A coarser level is added only while the template's shorter side stays at least
/// this (the smallest [`SearchConfig::min_coarse_px`] allowed; scratch is sized for it).
pub const MIN_COARSE_PX: usize = 16;
/// Largest number of coarse candidates any [`SearchConfig`] may keep.
pub const MAX_CANDIDATES: usize = 64;
/// Largest refinement radius any [`SearchConfig`] may use (scratch is sized for it).
pub const MAX_REFINE_RADIUS_PX: usize = 3;
/// A window whose shorter side exceeds this many template sides is "wide"
/// ([`SearchConfig::wide_min_coarse_px`]).
pub const WIDE_WINDOW_RATIO: usize = 4;
/// Re-centring steps allowed when a refined peak lies on its region's border.
pub const MAX_CLIMB_STEPS: usize = 4;
/// Fewest kept template pixels a (masked) template may have at any level.
pub const MIN_MASK_PX: u32 = 16;

// Layout: `filter` (image domains, downsample), `pyramid` (level counts, scratch
// sizes, template and window levels), `integral` (window sums), `kernel` (Σ t·f),
// `search` (scoring positions, candidate lists, coarse-to-fine), `subpixel`.
mod filter;
mod integral;
mod kernel;
mod pyramid;
mod search;
mod subpixel;
#[cfg(test)]
mod test_util;

pub use filter::filter_region;
pub use pyramid::{peak_radius_px, pyramid_levels, pyramid_levels_min, search_levels};

use integral::Tables;
use pyramid::{Tpl, Win};
use search::{Strip, TopK};

/// Image domain in which template and window are correlated (paper §III-D).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Filter {
    /// Raw gray levels.
    Gray,
    /// Sobel magnitude `(|gx| + |gy|) / 8` (exactly 0..=255, no saturation needed).
    Sobel,
    /// 4-neighbour Laplacian `floor(lap / 8) + 128` (exactly 0..=255).
    Laplacian,
}

/// Search strategy.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Search {
    /// Score every position at full resolution (the test oracle).
    Exhaustive,
    /// Pyramid search with several coarse candidates, verified at full resolution.
    #[default]
    CoarseToFine,
}

/// Tuning of the coarse-to-fine search (ignored by [`Search::Exhaustive`]).
///
/// A checked type: [`SearchConfig::for_filter`] gives a default, and each
/// `with_*` method changes fields only to values in range, returning
/// [`FailureCode::ConfigParamOutOfRange`] otherwise (`candidates` and
/// `final_candidates` in `1..=MAX_CANDIDATES`, the radii in
/// `0..=MAX_REFINE_RADIUS_PX`, the coarsest sides at least [`MIN_COARSE_PX`]).
/// Fields are read through accessors of the same names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SearchConfig {
    /// Separated peaks kept at the coarsest level and refined at each finer level.
    candidates: usize,
    /// Candidates carried into the full-resolution verification (best first)
    /// for templates whose shorter side is at least `verify_all_below_px`.
    final_candidates: usize,
    /// Templates whose shorter side is below this verify every candidate at full
    /// resolution (the verification costs `(2r + 1)²·ℓ²` MACs per candidate).
    verify_all_below_px: usize,
    /// Refinement radius (pixels of the finer level) around each up-scaled
    /// candidate at the intermediate levels.
    refine_radius_px: usize,
    /// Refinement radius at full resolution.
    final_refine_radius_px: usize,
    /// Smallest refinement radius at the level just below the coarsest (the full
    /// resolution itself in a two-level search; the larger of this and the
    /// level's own radius above is used there). A coarse position suppressed by the non-maximum suppression lies
    /// within `nms_radius_px` coarse pixels of a kept candidate, i.e. up to
    /// `2·nms_radius_px + 1` pixels of the finer level from its up-scaled
    /// position; this radius at `2·nms_radius_px + 1` reaches those positions.
    first_refine_radius_px: usize,
    /// Non-maximum-suppression radius between coarse candidates (coarse pixels, Chebyshev).
    nms_radius_px: usize,
    /// Coarsest template side (see [`pyramid_levels_min`]) when the window's
    /// shorter side is at most [`WIDE_WINDOW_RATIO`] template sides (every search
    /// of the relocalization pipeline, whose windows are capped near 3.2 ℓ).
    min_coarse_px: usize,
    /// Coarsest template side for wider windows, where the coarsest level's
    /// exhaustive scan would otherwise dominate the cost.
    wide_min_coarse_px: usize,
}

impl SearchConfig {
    /// The default search for `filter`, chosen by the simulated-depot study
    /// (`fsw-docs/eval/matching.md`).
    pub const fn for_filter(filter: Filter) -> Self {
        Self {
            // Gray agrees at 16 (matching.md); the derivative domains need 32.
            candidates: match filter {
                Filter::Gray => 16,
                Filter::Sobel | Filter::Laplacian => 32,
            },
            final_candidates: 8,
            verify_all_below_px: 128,
            refine_radius_px: 2,
            final_refine_radius_px: 2,
            // Gray keeps candidates 2 coarse px apart (it agrees, matching.md
            // §1c, and the wide-window benchmarks keep their cost); the derivative
            // domains keep them 1 coarse px apart, which removes most of their
            // misses at equal cost. Widening the first refinement to ±3 px would
            // close the remaining gap but costs 15–50 % of relocalization time.
            first_refine_radius_px: 0,
            nms_radius_px: match filter {
                Filter::Gray => 2,
                Filter::Sobel | Filter::Laplacian => 1,
            },
            min_coarse_px: 32,
            wide_min_coarse_px: MIN_COARSE_PX,
        }
    }

    /// The configuration with `candidates` coarse peaks and `final_candidates`
    /// verified at full resolution.
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] unless both are in `1..=MAX_CANDIDATES`.
    pub const fn with_candidates(
        self,
        candidates: usize,
        final_candidates: usize,
    ) -> Result<Self, FailureCode> {
        if candidates == 0
            || candidates > MAX_CANDIDATES
            || final_candidates == 0
            || final_candidates > MAX_CANDIDATES
        {
            return Err(FailureCode::ConfigParamOutOfRange);
        }
        Ok(Self {
            candidates,
            final_candidates,
            ..self
        })
    }

    /// The configuration with the refinement radii: `refine` at the
    /// intermediate levels, `last` at full resolution, `first` at least at the
    /// level just below the coarsest.
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] unless each is at most
    /// [`MAX_REFINE_RADIUS_PX`].
    pub const fn with_refine_radii_px(
        self,
        refine: usize,
        last: usize,
        first: usize,
    ) -> Result<Self, FailureCode> {
        if refine > MAX_REFINE_RADIUS_PX
            || last > MAX_REFINE_RADIUS_PX
            || first > MAX_REFINE_RADIUS_PX
        {
            return Err(FailureCode::ConfigParamOutOfRange);
        }
        Ok(Self {
            refine_radius_px: refine,
            final_refine_radius_px: last,
            first_refine_radius_px: first,
            ..self
        })
    }

    /// The configuration with coarsest template sides `min_coarse_px` (windows
    /// up to [`WIDE_WINDOW_RATIO`] template sides) and `wide_min_coarse_px`
    /// (wider windows).
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] unless both are at least [`MIN_COARSE_PX`].
    pub const fn with_coarse_px(
        self,
        min_coarse_px: usize,
        wide_min_coarse_px: usize,
    ) -> Result<Self, FailureCode> {
        if min_coarse_px < MIN_COARSE_PX || wide_min_coarse_px < MIN_COARSE_PX {
            return Err(FailureCode::ConfigParamOutOfRange);
        }
        Ok(Self {
            min_coarse_px,
            wide_min_coarse_px,
            ..self
        })
    }

    /// The configuration with non-maximum-suppression radius `nms_radius_px`
    /// and full verification below templates of side `verify_all_below_px`
    /// (any values).
    pub const fn with_nms_and_verify_px(
        self,
        nms_radius_px: usize,
        verify_all_below_px: usize,
    ) -> Self {
        Self {
            nms_radius_px,
            verify_all_below_px,
            ..self
        }
    }

    /// Separated peaks kept at the coarsest level and refined at each finer level.
    pub const fn candidates(&self) -> usize {
        self.candidates
    }

    /// Candidates carried into the full-resolution verification (best first) for
    /// templates whose shorter side is at least [`Self::verify_all_below_px`].
    pub const fn final_candidates(&self) -> usize {
        self.final_candidates
    }

    /// Templates whose shorter side is below this verify every candidate at full
    /// resolution.
    pub const fn verify_all_below_px(&self) -> usize {
        self.verify_all_below_px
    }

    /// Refinement radius (pixels of the finer level) around each up-scaled candidate at
    /// the intermediate levels.
    pub const fn refine_radius_px(&self) -> usize {
        self.refine_radius_px
    }

    /// Refinement radius at full resolution.
    pub const fn final_refine_radius_px(&self) -> usize {
        self.final_refine_radius_px
    }

    /// Smallest refinement radius at the level just below the coarsest.
    pub const fn first_refine_radius_px(&self) -> usize {
        self.first_refine_radius_px
    }

    /// Non-maximum-suppression radius between coarse candidates (coarse pixels,
    /// Chebyshev).
    pub const fn nms_radius_px(&self) -> usize {
        self.nms_radius_px
    }

    /// Coarsest template side for windows at most [`WIDE_WINDOW_RATIO`] template sides
    /// wide.
    pub const fn min_coarse_px(&self) -> usize {
        self.min_coarse_px
    }

    /// Coarsest template side for wider windows.
    pub const fn wide_min_coarse_px(&self) -> usize {
        self.wide_min_coarse_px
    }
}

/// Exact integer terms of one zero-mean NCC score.
///
/// `num = N·Σft − Σf·Σt`, `var_f = N·Σf² − (Σf)²`, `var_t = N·Σt² − (Σt)²`,
/// score `= num / √(var_f·var_t)`; all sums over the kept template pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Score {
    num: i64,
    var_f: i64,
    var_t: i64,
}

impl Score {
    /// Numerator, |num| < 2⁴⁸.
    pub const fn num(&self) -> i64 {
        self.num
    }

    /// Window variance term, 0 ≤ var_f < 2⁴⁸.
    pub const fn var_f(&self) -> i64 {
        self.var_f
    }

    /// Template variance term, 0 ≤ var_t < 2⁴⁸.
    pub const fn var_t(&self) -> i64 {
        self.var_t
    }

    /// The score as f64: exact integers, one correctly rounded product conversion,
    /// square root and division, so the value is the same on every IEEE target.
    /// Exactly ±1 when `num² = var_f·var_t`; 0 when either variance is zero.
    #[allow(
        clippy::arithmetic_side_effects,
        reason = "variances and |num| are below 2^48 (numeric.md): their u128 products are exact"
    )]
    pub fn to_f64(&self) -> f64 {
        if self.var_f <= 0 || self.var_t <= 0 {
            return 0.0;
        }
        let prod = (self.var_f as u128) * (self.var_t as u128);
        let n2 = u128::from(self.num.unsigned_abs()) * u128::from(self.num.unsigned_abs());
        if n2 >= prod {
            // Cauchy–Schwarz gives n2 <= prod; equality is a perfect (anti)correlation.
            return if self.num < 0 { -1.0 } else { 1.0 };
        }
        let r = self.num as f64 / libm::sqrt(prod as f64);
        r.clamp(-1.0, 1.0)
    }

    /// The score as f32 (the f64 value rounded once).
    #[allow(
        clippy::cast_possible_truncation,
        reason = "the f64 score in [−1, 1] rounded once to f32"
    )]
    pub fn to_f32(&self) -> f32 {
        self.to_f64() as f32
    }
}

/// `a·b` as a 192-bit number `(high 128 bits, low 64 bits)`, exact.
#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "64×64-bit partial products in u128 and a carry below 2^64 (see the comment): exact by construction"
)]
fn mul_wide(a: u128, b: u64) -> (u128, u64) {
    let p0 = (a as u64 as u128) * u128::from(b);
    let p1 = (a >> 64) * u128::from(b);
    // p1 <= (2^64-1)^2 and the carry < 2^64, so the sum cannot overflow.
    (p1 + (p0 >> 64), p0 as u64)
}

/// `sign(num_a)·num_a²·var_f_b` against `sign(num_b)·num_b²·var_f_a` in f64
/// where the two differ by far more than the rounding error, `None` where they
/// are too close to tell (the caller then compares exactly). Every operand is an
/// integer below 2⁵³ and so exact in f64 (signed conversions, one instruction
/// each on x86-64); each product is rounded twice (relative error < 2.3·10⁻¹⁶),
/// so a difference above 10⁻¹² of the products' magnitudes decides the exact
/// comparison, signs included: the result is the exact order whenever it is
/// `Some` (two zero numerators are left to the integers, which call them equal).
/// Only where f64 is hardware (the 64-bit host and application targets);
/// elsewhere every comparison is the integer one.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
#[inline]
#[allow(
    clippy::cast_precision_loss,
    clippy::arithmetic_side_effects,
    reason = "|num|, var_f < 2^48 are exact in f64; the rounding of the products is bounded above (f64 arithmetic)"
)]
pub(crate) fn cmp_keys_f64(a: &Score, b: &Score) -> Option<Ordering> {
    let (na, nb) = (a.num as f64, b.num as f64);
    let la = na * na.abs() * (b.var_f as f64).abs();
    let lb = nb * nb.abs() * (a.var_f as f64).abs();
    const GAP: f64 = 1e-12;
    let g = GAP * (la.abs() + lb.abs());
    if la - lb > g {
        Some(Ordering::Greater)
    } else if lb - la > g {
        Some(Ordering::Less)
    } else {
        None
    }
}

/// The integer comparison decides every pair on this target.
#[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
#[inline]
pub(crate) fn cmp_keys_f64(_: &Score, _: &Score) -> Option<Ordering> {
    None
}

/// Exact order of two scores of the same template (same `var_t`), by
/// `sign(num)·num²/var_f`, with no division and no square root.
#[inline]
pub fn cmp_scores(a: &Score, b: &Score) -> Ordering {
    if let Some(o) = cmp_keys_f64(a, b) {
        return o;
    }
    cmp_scores_exact(a, b)
}

/// Order key of a score of a given template: `sign(num)·num²/var_f` in f64
/// (three roundings: relative error below 3.4·10⁻¹⁶), NaN when `var_f ≤ 0`.
/// [`key_beats`] orders two scores of one template by their keys where these
/// are clearly apart and by [`cmp_scores_exact`] otherwise. Only where f64 is
/// hardware; elsewhere every key is NaN, so every comparison is the integer one.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
#[inline]
#[allow(
    clippy::cast_precision_loss,
    clippy::arithmetic_side_effects,
    reason = "|num|, var_f < 2^48 are exact in f64; the rounding is bounded above (f64 arithmetic)"
)]
pub(crate) fn order_key(s: &Score) -> f64 {
    if s.var_f <= 0 {
        return f64::NAN;
    }
    let n = s.num as f64;
    n * n.abs() / s.var_f as f64
}

/// Order key where f64 is software: NaN, so every comparison is the integer one.
#[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
#[inline]
pub(crate) fn order_key(_: &Score) -> f64 {
    f64::NAN
}

/// Whether `a` (order key `ka`) is strictly better than `b` (key `kb`), two
/// scores of one template: the keys decide when they differ by more than 10⁻¹²
/// of their magnitudes (far above their rounding error, so the order is the
/// exact one), [`cmp_scores_exact`] otherwise (and for NaN keys, for which both
/// comparisons are false). Always `cmp_scores(a, b) == Greater`.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
#[inline]
#[allow(
    clippy::arithmetic_side_effects,
    reason = "f64 arithmetic on finite keys or NaN (every comparison with NaN is false)"
)]
pub(crate) fn key_beats(ka: f64, a: &Score, kb: f64, b: &Score) -> bool {
    const GAP: f64 = 1e-12;
    let g = GAP * (ka.abs() + kb.abs());
    if ka - kb > g {
        return true;
    }
    if kb - ka > g {
        return false;
    }
    cmp_scores_exact(a, b) == Ordering::Greater
}

/// [`key_beats`] where f64 is software: the integer comparison alone.
#[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
#[inline]
pub(crate) fn key_beats(_: f64, a: &Score, _: f64, b: &Score) -> bool {
    cmp_scores_exact(a, b) == Ordering::Greater
}

/// [`cmp_scores`] by the integer products alone (the reference its f64 shortcut
/// is tested against).
#[allow(
    clippy::arithmetic_side_effects,
    reason = "|num| < 2^48, so num² < 2^96 fits u128; the 192-bit product is mul_wide's"
)]
pub(crate) fn cmp_scores_exact(a: &Score, b: &Score) -> Ordering {
    let (sa, sb) = (a.num.signum(), b.num.signum());
    if sa != sb {
        return sa.cmp(&sb);
    }
    if sa == 0 {
        return Ordering::Equal;
    }
    let na = u128::from(a.num.unsigned_abs());
    let nb = u128::from(b.num.unsigned_abs());
    let la = mul_wide(na * na, b.var_f.unsigned_abs());
    let lb = mul_wide(nb * nb, a.var_f.unsigned_abs());
    if sa > 0 {
        la.cmp(&lb)
    } else {
        lb.cmp(&la)
    }
}

/// Result of one template search.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Match {
    /// Column of the best match's top-left corner, image coordinates.
    pub x: i32,
    /// Row of the best match's top-left corner, image coordinates.
    pub y: i32,
    /// Zero-mean NCC of the best match (`exact.to_f32()`).
    pub score: f32,
    /// Sub-pixel top-left column (3-point parabola on the exact scores).
    pub sub_x: f32,
    /// Sub-pixel top-left row.
    pub sub_y: f32,
    /// Best score among candidates farther than [`peak_radius_px`] from the winner
    /// (Chebyshev distance); −1 when there is none.
    pub runner_up: f32,
    /// Exact integer terms of the best score.
    pub exact: Score,
}

/// Work done by one search.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MatchStats {
    /// Positions whose correlation was computed (all levels).
    pub positions_scored: u64,
    /// Positions skipped because the window had zero variance there.
    pub flat_positions: u64,
    /// Multiply-accumulates of the correlation kernel (all levels).
    pub macs: u64,
    /// Pyramid levels used (1 = full resolution only).
    pub levels: u8,
    /// Coarse candidates that were refined.
    pub candidates: u8,
}

/// One rectangle of kept pixels of a masked template: columns `x0..x1` of the
/// `rows` rows from `row` (consecutive rows with the same single run of kept
/// pixels share one rectangle, so a fully kept template is one rectangle and
/// its window sums cost four table reads per position).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Run {
    /// First template row.
    pub row: u16,
    /// First kept column.
    pub x0: u16,
    /// One past the last kept column.
    pub x1: u16,
    /// Number of rows, ≥ 1.
    pub rows: u16,
}

/// Caller-provided working memory; size it with [`ScratchSizes`].
#[derive(Debug)]
pub struct Scratch<'a> {
    /// Window pixels, every pyramid level.
    pub window: &'a mut [u8],
    /// Template pixels and masks, every pyramid level.
    pub template: &'a mut [u8],
    /// Integral images of window sums and sums of squares.
    pub integral: &'a mut [u32],
    /// Runs of kept pixels of masked templates.
    pub runs: &'a mut [Run],
}

/// Element counts each [`Scratch`] buffer needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ScratchSizes {
    /// `Scratch::window` length (bytes).
    pub window: usize,
    /// `Scratch::template` length (bytes).
    pub template: usize,
    /// `Scratch::integral` length (u32 elements).
    pub integral: usize,
    /// `Scratch::runs` length (runs).
    pub runs: usize,
}

/// The centred ℓ/2 sub-template of a `w × h` template (paper §III-D):
/// `w/2 × h/2` pixels starting at `((w − w/2)/2, (h − h/2)/2)`.
#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "w/2 ≤ w and template sides ≤ MAX_TEMPLATE_PX fit i32 and u32"
)]
pub const fn sub_template_rect(w: usize, h: usize) -> Rect {
    let (sw, sh) = (w / 2, h / 2);
    Rect::new(
        ((w - sw) / 2) as i32,
        ((h - sh) / 2) as i32,
        sw as u32,
        sh as u32,
    )
}

/// The centred ℓ/2 sub-template view of `template` (same crop for its mask).
pub fn sub_template<'a>(template: &GrayView<'a>) -> Option<GrayView<'a>> {
    template.sub(sub_template_rect(template.width(), template.height()))
}
/// Find `template` (optionally masked) inside `search` of `image`.
///
/// `search` is the region in which the whole template must lie; it is clipped to
/// the image. The template and the window are filtered with `filter` first
/// (window pixels use their true image neighbours). (x, y) is the top-left offset
/// in image coordinates, as OpenCV `matchTemplate` + `minMaxLoc` report it; ties
/// go to the first position in raster order.
///
/// # Errors
/// [`FailureCode::NccTemplateSizeInvalid`] (template side outside
/// `MIN_TEMPLATE_PX..=MAX_TEMPLATE_PX`, or mask size differs),
/// [`FailureCode::NccWindowOutsideImage`], [`FailureCode::NccWindowTooLarge`],
/// [`FailureCode::NccTemplateLargerThanWindow`], [`FailureCode::NccScratchTooSmall`],
/// [`FailureCode::NccMaskEmpty`], [`FailureCode::NccTemplateFlat`],
/// [`FailureCode::NccWindowFlat`] (every position has zero variance).
pub fn match_template(
    template: GrayView,
    mask: Option<GrayView>,
    image: GrayView,
    search: Rect,
    filter: Filter,
    mode: Search,
    scratch: &mut Scratch,
) -> Result<(Match, MatchStats), FailureCode> {
    match_template_with(
        template,
        mask,
        image,
        search,
        filter,
        mode,
        &SearchConfig::for_filter(filter),
        scratch,
    )
}

/// [`match_template`] with an explicit coarse-to-fine configuration (ignored
/// by [`Search::Exhaustive`]).
///
/// # Errors
/// As [`match_template`].
#[allow(clippy::too_many_arguments)]
pub fn match_template_with(
    template: GrayView,
    mask: Option<GrayView>,
    image: GrayView,
    search: Rect,
    filter: Filter,
    mode: Search,
    cfg: &SearchConfig,
    scratch: &mut Scratch,
) -> Result<(Match, MatchStats), FailureCode> {
    match_at(
        template,
        mask,
        image,
        (0, 0),
        search,
        filter,
        mode,
        cfg,
        scratch,
    )
}

/// [`match_template`] inside a window copied out of a larger frame
/// ([`crate::frame::read_with_halo`]): `search` and the returned positions
/// are in frame coordinates, `window.origin` is where the copy's pixel (0, 0)
/// lies in the frame. When the copy holds `search` and the one-pixel ring the
/// filters read (clipped to the frame), the result is bit-identical to
/// [`match_template`] over the whole frame.
///
/// # Errors
/// As [`match_template`].
pub fn match_in_window(
    template: GrayView,
    mask: Option<GrayView>,
    window: &crate::frame::Window,
    search: Rect,
    filter: Filter,
    mode: Search,
    scratch: &mut Scratch,
) -> Result<(Match, MatchStats), FailureCode> {
    match_at(
        template,
        mask,
        window.view,
        window.origin,
        window.local(search),
        filter,
        mode,
        &SearchConfig::for_filter(filter),
        scratch,
    )
}

/// The search of [`match_template_with`] over `image` whose pixel (0, 0) is
/// pixel `origin` of the frame the caller works in; `search` is in `image`'s
/// coordinates and the result in the frame's, so the sub-pixel position is
/// rounded once, from frame coordinates, wherever the image was cut from.
#[allow(clippy::too_many_lines, clippy::too_many_arguments)]
#[allow(
    clippy::cast_possible_truncation,
    reason = "levels ≤ MAX_LEVELS fits u8; positions lie in a window of ≤ MAX_IMAGE_DIM pixels (fit i32); sub-pixel coordinates are pixel positions, rounded once to f32"
)]
fn match_at(
    template: GrayView,
    mask: Option<GrayView>,
    image: GrayView,
    origin: (i32, i32),
    search: Rect,
    filter: Filter,
    mode: Search,
    cfg: &SearchConfig,
    scratch: &mut Scratch,
) -> Result<(Match, MatchStats), FailureCode> {
    let cfg = *cfg;
    let (tw, th) = (template.width(), template.height());
    let side_ok = |s: usize| (MIN_TEMPLATE_PX..=MAX_TEMPLATE_PX).contains(&s);
    if !side_ok(tw) || !side_ok(th) {
        return Err(FailureCode::NccTemplateSizeInvalid);
    }
    if let Some(m) = &mask {
        if m.width() != tw || m.height() != th {
            return Err(FailureCode::NccTemplateSizeInvalid);
        }
    }
    let wr = image
        .rect()
        .intersect(&search)
        .ok_or(FailureCode::NccWindowOutsideImage)?;
    let (ww, wh) = (wr.w as usize, wr.h as usize);
    if ww > MAX_SEARCH_PX || wh > MAX_SEARCH_PX {
        return Err(FailureCode::NccWindowTooLarge);
    }
    if tw > ww || th > wh {
        return Err(FailureCode::NccTemplateLargerThanWindow);
    }
    if !ScratchSizes::minimum(tw, th, ww, wh, mode, &cfg).fits(scratch) {
        return Err(FailureCode::NccScratchTooSmall);
    }
    let want = match mode {
        Search::Exhaustive => 1,
        Search::CoarseToFine => search_levels(tw, th, ww, wh, &cfg),
    };
    let Scratch {
        window,
        template: tbuf,
        integral,
        runs,
    } = scratch;
    let mut tpls: [Option<Tpl>; MAX_LEVELS] = [None; MAX_LEVELS];
    let levels = pyramid::build_template_levels(
        &template,
        mask.as_ref(),
        filter,
        want,
        tbuf,
        runs,
        &mut tpls,
    )?;
    let mut wins: [Option<Win>; MAX_LEVELS] = [None; MAX_LEVELS];
    pyramid::build_window_levels(&image, wr, filter, levels, window, &mut wins)?;

    let mut stats = MatchStats {
        levels: levels as u8,
        ..MatchStats::default()
    };
    let radius0 = peak_radius_px(tw, th);
    let mut tables = Tables::new(integral);
    let mut strip = Strip::new();
    let top = search::coarse_to_fine(
        &tpls,
        &wins,
        levels,
        (tw, th, ww, wh),
        &cfg,
        &mut tables,
        &mut strip,
        &mut stats,
    )?;

    let cands = top.as_slice();
    let Some(win) = cands.first().copied() else {
        return Err(FailureCode::NccWindowFlat);
    };
    let probe = TopK::new(1, radius0);
    let runner_up = cands
        .iter()
        .skip(1)
        .find(|c| !probe.near(c, &win))
        .map_or(-1.0, |c| c.s.to_f32());
    let (dx, dy) = subpixel::offsets(&tpls, &wins, &win, &mut tables, &mut strip, &mut stats)?;

    // The winner lies inside the window rectangle, itself inside the image
    // (≤ MAX_IMAGE_DIM), so these sums fit; wrapping keeps them total.
    let x = origin.0.wrapping_add(wr.x).wrapping_add(win.x as i32);
    let y = origin.1.wrapping_add(wr.y).wrapping_add(win.y as i32);
    Ok((
        Match {
            x,
            y,
            score: win.s.to_f32(),
            sub_x: (f64::from(x) + dx) as f32,
            sub_y: (f64::from(y) + dy) as f32,
            runner_up,
            exact: win.s,
        },
        stats,
    ))
}

/// Exact score of `template` (optionally masked, after `filter`) placed with its
/// top-left corner at `(x, y)` of `image`: a search over that single position.
///
/// # Errors
/// As [`match_template`]; [`FailureCode::NccWindowFlat`] when the window has zero variance.
#[allow(
    clippy::cast_possible_truncation,
    reason = "template sides ≤ MAX_TEMPLATE_PX fit u32"
)]
pub fn score_at(
    template: GrayView,
    mask: Option<GrayView>,
    image: GrayView,
    x: i32,
    y: i32,
    filter: Filter,
    scratch: &mut Scratch,
) -> Result<Score, FailureCode> {
    let r = Rect::new(x, y, template.width() as u32, template.height() as u32);
    if !image.rect().contains(&r) {
        return Err(FailureCode::NccWindowOutsideImage);
    }
    match_template(
        template,
        mask,
        image,
        r,
        filter,
        Search::Exhaustive,
        scratch,
    )
    .map(|(m, _)| m.exact)
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::test_util::*;

    /// The f64 shortcuts of `cmp_scores` and `key_beats` never change an
    /// order: they agree with the integer comparison on random scores over the
    /// whole range, on exact ties, and on pairs one unit apart at the top of the
    /// range (where the shortcuts must defer to the integers).
    #[test]
    fn cmp_scores_shortcut_equals_exact_comparison() {
        let mut rng = crate::rng::Rng::new(77);
        let top = (1i64 << 48) - 1;
        let draw = |rng: &mut crate::rng::Rng| {
            let bits = 1 + rng.below(48);
            let v = i64::from(rng.below(u32::MAX)) << 16 | i64::from(rng.below(1 << 16));
            v & ((1i64 << bits) - 1)
        };
        for case in 0..200_000u32 {
            let num_a = draw(&mut rng) * if rng.below(2) == 0 { 1 } else { -1 };
            let var_a = draw(&mut rng).max(1);
            let (num_b, var_b) = match case % 4 {
                0 => (num_a, var_a),
                1 => (
                    num_a * 2 / 2 + if rng.below(2) == 0 { 1 } else { -1 },
                    var_a,
                ),
                2 => (num_a, (var_a + 1).min(top)),
                _ => (
                    draw(&mut rng) * if rng.below(2) == 0 { 1 } else { -1 },
                    draw(&mut rng).max(1),
                ),
            };
            let a = Score {
                num: num_a,
                var_f: var_a,
                var_t: 5,
            };
            let b = Score {
                num: num_b.clamp(-top, top),
                var_f: var_b,
                var_t: 5,
            };
            assert_eq!(cmp_scores(&a, &b), cmp_scores_exact(&a, &b), "{a:?} {b:?}");
            assert_eq!(cmp_scores(&b, &a), cmp_scores_exact(&b, &a), "{b:?} {a:?}");
            for (p, q) in [(&a, &b), (&b, &a)] {
                assert_eq!(
                    key_beats(order_key(p), p, order_key(q), q),
                    cmp_scores_exact(p, q) == Ordering::Greater,
                    "{p:?} {q:?}"
                );
            }
        }
        let a = Score {
            num: top,
            var_f: top,
            var_t: 1,
        };
        let b = Score {
            num: top - 1,
            var_f: top - 2,
            var_t: 1,
        };
        assert_eq!(cmp_scores(&a, &b), cmp_scores_exact(&a, &b));
        assert_eq!(
            key_beats(order_key(&a), &a, order_key(&b), &b),
            cmp_scores_exact(&a, &b) == Ordering::Greater
        );
    }
    use super::*;
    use crate::rng::Rng;
    use proptest::prelude::*;
    use std::vec;
    use std::vec::Vec;

    /// Verifies: VTSM-NCC-001
    #[test]
    fn scores_equal_f64_reference_on_random_images() {
        let mut rng = Rng::new(11);
        let mut worst = 0.0f64;
        for case in 0..200 {
            let tw = 16 + rng.below(25) as usize;
            let th = 16 + rng.below(25) as usize;
            let (iw, ih) = (
                tw + 1 + rng.below(30) as usize,
                th + 1 + rng.below(30) as usize,
            );
            let img = random_px(iw * ih, &mut rng);
            let t = random_px(tw * th, &mut rng);
            let (x, y) = (
                rng.below((iw - tw + 1) as u32) as usize,
                rng.below((ih - th + 1) as u32) as usize,
            );
            let s = score_one(&t, tw, th, None, &img, iw, ih, x, y, Filter::Gray).unwrap();
            let r = ref_score(&t, tw, th, None, &img, iw, x, y).unwrap();
            worst = worst.max((s.to_f64() - r).abs());
            assert!(
                (s.to_f64() - r).abs() < 1e-9,
                "case {case}: {} vs {r}",
                s.to_f64()
            );
            assert_eq!(s.to_f32(), s.to_f64() as f32);
        }
        std::println!("max |exact - f64 reference| = {worst:e}");
    }

    /// Verifies: VTSM-NCC-002
    #[test]
    fn identical_patch_scores_one_and_negated_patch_minus_one() {
        let mut rng = Rng::new(14);
        for _ in 0..50 {
            let (tw, th) = (16 + rng.below(30) as usize, 16 + rng.below(30) as usize);
            let (iw, ih) = (tw + 10, th + 10);
            let img = random_px(iw * ih, &mut rng);
            let (x, y) = (rng.below(11) as usize, rng.below(11) as usize);
            let t = crop(&img, iw, x, y, tw, th);
            let neg: Vec<u8> = t.iter().map(|v| 255 - v).collect();
            let s = score_one(&t, tw, th, None, &img, iw, ih, x, y, Filter::Gray).unwrap();
            assert_eq!(s.to_f64(), 1.0);
            assert_eq!(s.to_f32(), 1.0);
            let s = score_one(&neg, tw, th, None, &img, iw, ih, x, y, Filter::Gray).unwrap();
            assert_eq!(s.to_f64(), -1.0);
        }
    }

    /// Verifies: VTSM-NCC-003
    #[test]
    fn score_is_invariant_to_gain_and_offset() {
        let mut rng = Rng::new(15);
        for _ in 0..50 {
            let (tw, th) = (16 + rng.below(30) as usize, 16 + rng.below(30) as usize);
            let (iw, ih) = (tw + 7, th + 5);
            let img = random_px(iw * ih, &mut rng);
            let t: Vec<u8> = (0..tw * th).map(|_| rng.below(60) as u8).collect();
            let gain = 1 + rng.below(3);
            let off = rng.below(70);
            let t2: Vec<u8> = t
                .iter()
                .map(|&v| (u32::from(v) * gain + off) as u8)
                .collect();
            let (x, y) = (rng.below(8) as usize, rng.below(6) as usize);
            let a = score_one(&t, tw, th, None, &img, iw, ih, x, y, Filter::Gray).unwrap();
            let b = score_one(&t2, tw, th, None, &img, iw, ih, x, y, Filter::Gray).unwrap();
            assert!((a.to_f64() - b.to_f64()).abs() < 1e-12);
            // The same holds on the image side, and the exact order sees the scores as equal
            // when only the window changes by gain and offset.
            let img2: Vec<u8> = img.iter().map(|&v| (u32::from(v) / 2 + 40) as u8).collect();
            let c = score_one(&t, tw, th, None, &img2, iw, ih, x, y, Filter::Gray).unwrap();
            let r = ref_score(&t, tw, th, None, &img2, iw, x, y).unwrap();
            assert!((c.to_f64() - r).abs() < 1e-9);
        }
    }

    /// Verifies: VTSM-NCC-004
    #[test]
    fn exhaustive_argmax_equals_reference_argmax() {
        let mut rng = Rng::new(16);
        for case in 0..40 {
            let (tw, th) = (16 + rng.below(8) as usize, 16 + rng.below(8) as usize);
            let (iw, ih) = (
                tw + 20 + rng.below(20) as usize,
                th + 20 + rng.below(20) as usize,
            );
            let img = if case % 2 == 0 {
                random_px(iw * ih, &mut rng)
            } else {
                textured(iw, ih, &mut rng)
            };
            let t = random_px(tw * th, &mut rng);
            let mut best = (f64::MIN, 0, 0);
            for y in 0..=ih - th {
                for x in 0..=iw - tw {
                    let r = ref_score(&t, tw, th, None, &img, iw, x, y).unwrap();
                    if r > best.0 {
                        best = (r, x, y);
                    }
                }
            }
            let mut b = Bufs::new(tw, th, iw, ih, Search::Exhaustive);
            let (m, st) = match_template(
                view(&t, tw, th),
                None,
                view(&img, iw, ih),
                Rect::new(0, 0, iw as u32, ih as u32),
                Filter::Gray,
                Search::Exhaustive,
                &mut b.scratch(),
            )
            .unwrap();
            assert_eq!((m.x, m.y), (best.1 as i32, best.2 as i32), "case {case}");
            assert!((m.exact.to_f64() - best.0).abs() < 1e-9);
            // Work counters: every position once, N MACs each, plus the sub-pixel probe.
            let positions = ((iw - tw + 1) * (ih - th + 1)) as u64;
            assert!(st.positions_scored >= positions && st.positions_scored <= positions + 9);
            assert_eq!(st.macs, st.positions_scored * (tw * th) as u64);
        }
    }

    /// Verifies: VTSM-NCC-005
    #[test]
    fn masked_score_equals_reference_restricted_to_mask() {
        let mut rng = Rng::new(17);
        for case in 0..60 {
            let (tw, th) = (16 + rng.below(20) as usize, 16 + rng.below(20) as usize);
            let (iw, ih) = (tw + 12, th + 9);
            let img = random_px(iw * ih, &mut rng);
            let t = random_px(tw * th, &mut rng);
            // Blobby masks (runs) and speckled ones (many short runs).
            let mask: Vec<u8> = (0..tw * th)
                .map(|i| {
                    let keep = if case % 2 == 0 {
                        let (x, y) = (
                            (i % tw) as i64 - tw as i64 / 2,
                            (i / tw) as i64 - th as i64 / 2,
                        );
                        x * x + y * y < (tw * th / 5) as i64
                    } else {
                        rng.below(3) != 0
                    };
                    if keep {
                        255
                    } else {
                        0
                    }
                })
                .collect();
            let mut best = (f64::MIN, 0, 0);
            for y in 0..=ih - th {
                for x in 0..=iw - tw {
                    let r = ref_score(&t, tw, th, Some(&mask), &img, iw, x, y).unwrap();
                    let s = score_one(&t, tw, th, Some(&mask), &img, iw, ih, x, y, Filter::Gray)
                        .unwrap();
                    assert!((s.to_f64() - r).abs() < 1e-9, "case {case} at ({x},{y})");
                    if r > best.0 {
                        best = (r, x, y);
                    }
                }
            }
            // Dropped pixels really do not count: change them and nothing moves.
            let t_changed: Vec<u8> = t
                .iter()
                .zip(&mask)
                .map(|(&v, &m)| if m == 0 { 255 - v } else { v })
                .collect();
            let mut b = Bufs::new(tw, th, iw, ih, Search::Exhaustive);
            for tt in [&t, &t_changed] {
                let (m, _) = match_template(
                    view(tt, tw, th),
                    Some(view(&mask, tw, th)),
                    view(&img, iw, ih),
                    Rect::new(0, 0, iw as u32, ih as u32),
                    Filter::Gray,
                    Search::Exhaustive,
                    &mut b.scratch(),
                )
                .unwrap();
                assert_eq!((m.x, m.y), (best.1 as i32, best.2 as i32), "case {case}");
            }
        }
    }

    /// Verifies: VTSM-NCC-007
    #[test]
    fn bit_budget_holds_at_the_extremes() {
        let l = MAX_TEMPLATE_PX;
        // All-255 template: flat, rejected (not NaN).
        let all = vec![255u8; l * l];
        assert_eq!(
            score_one(&all, l, l, None, &all, l, l, 0, 0, Filter::Gray),
            Err(FailureCode::NccTemplateFlat)
        );
        // 255 everywhere but one pixel: Σft = 255²·(N−1) ≈ 4.26e9, next to the u32 limit.
        let mut t = all.clone();
        t[l * l / 2 + 17] = 0;
        let s = score_one(&t, l, l, None, &t, l, l, 0, 0, Filter::Gray).unwrap();
        assert_eq!(s.to_f64(), 1.0);
        let n = (l * l) as i64;
        assert_eq!(
            s.var_t,
            n * 255 * 255 * (n - 1) - (255 * (n - 1)) * (255 * (n - 1))
        );
        // A window of all 255 but a different dark pixel: exact against the reference.
        let mut w = all.clone();
        w[3] = 0;
        let s = score_one(&t, l, l, None, &w, l, l, 0, 0, Filter::Gray).unwrap();
        let r = ref_score(&t, l, l, None, &w, l, 0, 0).unwrap();
        assert!((s.to_f64() - r).abs() < 1e-9, "{} vs {r}", s.to_f64());
        // Largest variances: a 0/255 checkerboard against itself and its negative, masked full.
        let cb: Vec<u8> = (0..l * l)
            .map(|i| if (i / l + i % l) % 2 == 0 { 255 } else { 0 })
            .collect();
        let neg: Vec<u8> = cb.iter().map(|v| 255 - v).collect();
        let full = vec![255u8; l * l];
        let s = score_one(&cb, l, l, Some(&full), &cb, l, l, 0, 0, Filter::Gray).unwrap();
        assert_eq!(s.to_f64(), 1.0);
        // var_t = N·Σt² − (Σt)² = 255²·N²/4 = 255²·2³⁰, the largest value any 256² template reaches.
        assert_eq!(s.var_t, 255 * 255 * (1 << 30));
        assert_eq!(s.var_f, s.var_t);
        let s = score_one(&neg, l, l, None, &cb, l, l, 0, 0, Filter::Gray).unwrap();
        assert_eq!(s.to_f64(), -1.0);
        assert_eq!(s.num, -255 * 255 * (1 << 30));
    }

    /// Verifies: VTSM-NCC-007
    #[test]
    fn exact_order_agrees_with_wide_reference() {
        let mut rng = Rng::new(18);
        let big = |rng: &mut Rng| (rng.next_u64() >> 16) as i64; // < 2^48
        for _ in 0..20_000 {
            let vt = 1 + big(&mut rng);
            let a = Score {
                num: big(&mut rng) - (1 << 47),
                var_f: 1 + big(&mut rng),
                var_t: vt,
            };
            let b = Score {
                num: big(&mut rng) - (1 << 47),
                var_f: 1 + big(&mut rng),
                var_t: vt,
            };
            // Reference: compare sign·num²/var_f with 256-bit-free big-float-free logic:
            // split each side into (hi, lo) limbs computed with u128 via a different route.
            let key = |s: &Score, other: &Score| -> (u128, u128) {
                let n = s.num.unsigned_abs() as u128;
                let v = other.var_f as u128;
                // n²·v = n·(n·v); n·v < 2^96 so split it into 48-bit halves.
                let nv = n * v;
                let (h, l) = (nv >> 48, nv & ((1 << 48) - 1));
                let (ph, pl) = (n * h, n * l); // value = ph·2^48 + pl
                let lo = pl & ((1 << 48) - 1);
                let hi = ph + (pl >> 48);
                (hi, lo)
            };
            let (ka, kb) = (key(&a, &b), key(&b, &a));
            let want = match (a.num.signum(), b.num.signum()) {
                (x, y) if x != y => x.cmp(&y),
                (0, _) => Ordering::Equal,
                (1, _) => ka.cmp(&kb),
                _ => kb.cmp(&ka),
            };
            assert_eq!(cmp_scores(&a, &b), want);
            if (a.to_f64() - b.to_f64()).abs() > 1e-12 {
                assert_eq!(
                    cmp_scores(&a, &b),
                    a.to_f64().partial_cmp(&b.to_f64()).unwrap()
                );
            }
        }
    }

    /// Verifies: VTSM-NCC-008
    #[test]
    fn each_bad_input_has_its_own_failure_code() {
        let mut rng = Rng::new(19);
        let img = random_px(64 * 64, &mut rng);
        let t = random_px(20 * 20, &mut rng);
        let all = Rect::new(0, 0, 64, 64);
        let run = |t: &[u8],
                   tw: usize,
                   mask: Option<&[u8]>,
                   img: &[u8],
                   iw: usize,
                   ih: usize,
                   r: Rect,
                   b: &mut Bufs| {
            match_template(
                view(t, tw, tw),
                mask.map(|m| view(m, tw, tw)),
                view(img, iw, ih),
                r,
                Filter::Gray,
                Search::CoarseToFine,
                &mut b.scratch(),
            )
            .map(|(m, _)| m)
        };
        let mut b = Bufs::new(20, 20, 64, 64, Search::CoarseToFine);
        let flat = vec![9u8; 400];
        assert_eq!(
            run(&flat, 20, None, &img, 64, 64, all, &mut b),
            Err(FailureCode::NccTemplateFlat)
        );
        let flat_img = vec![200u8; 64 * 64];
        assert_eq!(
            run(&t, 20, None, &flat_img, 64, 64, all, &mut b),
            Err(FailureCode::NccWindowFlat)
        );
        assert_eq!(
            run(&t, 20, None, &img, 64, 64, Rect::new(70, 0, 30, 30), &mut b),
            Err(FailureCode::NccWindowOutsideImage)
        );
        assert_eq!(
            run(&t, 20, None, &img, 64, 64, Rect::new(0, 0, 0, 30), &mut b),
            Err(FailureCode::NccWindowOutsideImage)
        );
        assert_eq!(
            run(
                &t,
                20,
                None,
                &img,
                64,
                64,
                Rect::new(50, 50, 30, 30),
                &mut b
            ),
            Err(FailureCode::NccTemplateLargerThanWindow)
        );
        let mut small = Bufs::new(20, 20, 40, 40, Search::CoarseToFine);
        assert_eq!(
            run(&t, 20, None, &img, 64, 64, all, &mut small),
            Err(FailureCode::NccScratchTooSmall)
        );
        let mut ex_small = Bufs::new(20, 20, 64, 64, Search::CoarseToFine);
        ex_small.i.truncate(10);
        assert_eq!(
            run(&t, 20, None, &img, 64, 64, all, &mut ex_small),
            Err(FailureCode::NccScratchTooSmall)
        );
        let mut mask = vec![0u8; 400];
        mask[..10].fill(255);
        assert_eq!(
            run(&t, 20, Some(&mask), &img, 64, 64, all, &mut b),
            Err(FailureCode::NccMaskEmpty)
        );
        let tiny = random_px(8 * 8, &mut rng);
        assert_eq!(
            run(&tiny, 8, None, &img, 64, 64, all, &mut b),
            Err(FailureCode::NccTemplateSizeInvalid)
        );
        let wide = random_px(1100 * 20, &mut rng);
        let mut bw = Bufs::new(20, 20, 1100, 20, Search::CoarseToFine);
        assert_eq!(
            run(
                &t,
                20,
                None,
                &wide,
                1100,
                20,
                Rect::new(0, 0, 1100, 20),
                &mut bw
            ),
            Err(FailureCode::NccWindowTooLarge)
        );
        for c in [
            FailureCode::NccTemplateFlat,
            FailureCode::NccWindowFlat,
            FailureCode::NccWindowTooLarge,
            FailureCode::NccTemplateSizeInvalid,
        ] {
            assert_eq!(c.group(), 0x05);
        }
        // A search rectangle partly outside the image is clipped, not rejected.
        let m = run(
            &t,
            20,
            None,
            &img,
            64,
            64,
            Rect::new(-10, -10, 50, 50),
            &mut b,
        )
        .unwrap();
        assert!(m.x >= 0 && m.y >= 0 && m.x <= 20 && m.y <= 20);
    }

    /// Verifies: VTSM-NCC-009
    #[test]
    fn runner_up_reports_a_second_copy_and_ties_go_to_raster_order() {
        let mut rng = Rng::new(20);
        let (iw, ih, l) = (120usize, 90usize, 24usize);
        for mode in [Search::Exhaustive, Search::CoarseToFine] {
            let mut img = textured(iw, ih, &mut rng);
            let t = textured(l, l, &mut rng);
            for (x, y) in [(70usize, 50usize), (10, 12)] {
                for r in 0..l {
                    img[(y + r) * iw + x..(y + r) * iw + x + l]
                        .copy_from_slice(&t[r * l..r * l + l]);
                }
            }
            let mut b = Bufs::new(l, l, iw, ih, mode);
            let (m, _) = match_template(
                view(&t, l, l),
                None,
                view(&img, iw, ih),
                Rect::new(0, 0, iw as u32, ih as u32),
                Filter::Gray,
                mode,
                &mut b.scratch(),
            )
            .unwrap();
            assert_eq!((m.x, m.y, m.score), (10, 12, 1.0), "{mode:?}");
            assert_eq!(m.runner_up, 1.0, "{mode:?}");
        }
        // A single copy in noise: the runner-up is far below the peak.
        let img = random_px(iw * ih, &mut rng);
        let t = crop(&img, iw, 40, 30, l, l);
        let mut b = Bufs::new(l, l, iw, ih, Search::Exhaustive);
        let (m, _) = match_template(
            view(&t, l, l),
            None,
            view(&img, iw, ih),
            Rect::new(0, 0, iw as u32, ih as u32),
            Filter::Gray,
            Search::Exhaustive,
            &mut b.scratch(),
        )
        .unwrap();
        assert_eq!((m.x, m.y), (40, 30));
        assert!(m.runner_up < 0.5 && m.runner_up > -1.0, "{}", m.runner_up);
    }

    /// Verifies: VTSM-NCC-010
    #[test]
    fn sub_template_is_the_centred_half_crop_and_matches_in_place() {
        assert_eq!(sub_template_rect(256, 256), Rect::new(64, 64, 128, 128));
        assert_eq!(sub_template_rect(128, 96), Rect::new(32, 24, 64, 48));
        assert_eq!(sub_template_rect(33, 17), Rect::new(8, 4, 16, 8));
        let mut rng = Rng::new(21);
        let (iw, ih) = (160usize, 140usize);
        let img = textured(iw, ih, &mut rng);
        let t = crop(&img, iw, 50, 40, 64, 64);
        let tv = view(&t, 64, 64);
        let sub = sub_template(&tv).unwrap();
        assert_eq!((sub.width(), sub.height()), (32, 32));
        assert_eq!(sub.get(0, 0), Some(img[(40 + 16) * iw + 50 + 16]));
        let mut b = Bufs::new(32, 32, iw, ih, Search::CoarseToFine);
        let (m, _) = match_template(
            sub,
            None,
            view(&img, iw, ih),
            Rect::new(0, 0, iw as u32, ih as u32),
            Filter::Sobel,
            Search::CoarseToFine,
            &mut b.scratch(),
        )
        .unwrap();
        assert_eq!((m.x, m.y), (66, 56));
    }

    /// Verifies: VTSM-NCC-012
    #[test]
    fn search_config_refuses_out_of_range_values() {
        let d = SearchConfig::for_filter(Filter::Gray);
        let bad = FailureCode::ConfigParamOutOfRange;
        assert_eq!(d.with_candidates(0, 8), Err(bad));
        assert_eq!(d.with_candidates(8, 0), Err(bad));
        assert_eq!(d.with_candidates(MAX_CANDIDATES + 1, 8), Err(bad));
        assert_eq!(d.with_candidates(8, 999), Err(bad));
        let c = d.with_candidates(1, MAX_CANDIDATES).unwrap();
        assert_eq!((c.candidates(), c.final_candidates()), (1, MAX_CANDIDATES));
        let over = MAX_REFINE_RADIUS_PX + 1;
        assert_eq!(d.with_refine_radii_px(over, 0, 0), Err(bad));
        assert_eq!(d.with_refine_radii_px(0, over, 0), Err(bad));
        assert_eq!(d.with_refine_radii_px(0, 0, over), Err(bad));
        let r = MAX_REFINE_RADIUS_PX;
        let c = d.with_refine_radii_px(r, r, r).unwrap();
        assert_eq!(
            (
                c.refine_radius_px(),
                c.final_refine_radius_px(),
                c.first_refine_radius_px()
            ),
            (r, r, r)
        );
        assert_eq!(d.with_coarse_px(MIN_COARSE_PX - 1, 32), Err(bad));
        assert_eq!(d.with_coarse_px(32, 0), Err(bad));
        let c = d.with_coarse_px(MIN_COARSE_PX, 64).unwrap();
        assert_eq!(
            (c.min_coarse_px(), c.wide_min_coarse_px()),
            (MIN_COARSE_PX, 64)
        );
        let c = d.with_nms_and_verify_px(0, 0);
        assert_eq!((c.nms_radius_px(), c.verify_all_below_px()), (0, 0));
        assert_eq!(search_levels(64, 64, 204, 204, &d), 2);
        assert_eq!(search_levels(128, 128, 800, 800, &d), 4);
        assert_eq!(search_levels(256, 256, 800, 800, &d), 4);
        for f in [Filter::Gray, Filter::Sobel, Filter::Laplacian] {
            let c = SearchConfig::for_filter(f);
            let checked = c
                .with_candidates(c.candidates(), c.final_candidates())
                .and_then(|c| {
                    c.with_refine_radii_px(
                        c.refine_radius_px(),
                        c.final_refine_radius_px(),
                        c.first_refine_radius_px(),
                    )
                })
                .and_then(|c| c.with_coarse_px(c.min_coarse_px(), c.wide_min_coarse_px()));
            assert_eq!(checked, Ok(c), "{f:?} default is in range");
        }
        assert_eq!(pyramid_levels_min(64, 64, 32), 2);
        assert_eq!(pyramid_levels_min(32, 32, 32), 2);
        assert_eq!(pyramid_levels_min(31, 64, 32), 1);
        assert_eq!(pyramid_levels_min(256, 256, 32), 4);
        assert_eq!(pyramid_levels_min(128, 128, 32), 3);
        assert_eq!(pyramid_levels_min(64, 64, 0), pyramid_levels(64, 64));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]
        /// Verifies: VTSM-NCC-008
        #[test]
        fn never_panics_and_scores_stay_in_range(
            tw in 12usize..40, th in 12usize..40, iw in 1usize..90, ih in 1usize..90,
            sx in -20i32..100, sy in -20i32..100, sw in 0u32..120, sh in 0u32..120,
            seed in any::<u64>(), levels in 0u32..256, flat in any::<bool>(),
            masked in any::<bool>(), filt in 0u8..3, exhaustive in any::<bool>(), short in any::<bool>(),
            min_coarse in MIN_COARSE_PX..80,
        ) {
            let mut rng = Rng::new(seed);
            let img: Vec<u8> = if flat { vec![levels as u8; iw * ih] } else { random_px(iw * ih, &mut rng) };
            let t: Vec<u8> = (0..tw * th).map(|_| rng.below(levels + 1) as u8).collect();
            let mask: Vec<u8> = (0..tw * th).map(|_| if rng.below(4) == 0 { 0 } else { 255 }).collect();
            let mode = if exhaustive { Search::Exhaustive } else { Search::CoarseToFine };
            let filter = [Filter::Gray, Filter::Sobel, Filter::Laplacian][usize::from(filt)];
            let cfg = SearchConfig::for_filter(filter)
                .with_coarse_px(min_coarse, (min_coarse / 2).max(MIN_COARSE_PX))
                .unwrap();
            let mut b = Bufs::with_config(tw, th, sw as usize, sh as usize, mode, &cfg);
            if short { b.i.truncate(b.i.len() / 2); }
            let r = match_template_with(
                view(&t, tw, th), masked.then(|| view(&mask, tw, th)), view(&img, iw, ih),
                Rect::new(sx, sy, sw, sh), filter, mode, &cfg, &mut b.scratch(),
            );
            match r {
                Ok((m, st)) => {
                    prop_assert!(m.score.is_finite() && (-1.0..=1.0).contains(&m.score));
                    prop_assert!(m.runner_up.is_finite() && (-1.0..=1.0).contains(&m.runner_up));
                    prop_assert!((m.sub_x - m.x as f32).abs() <= 0.5 && (m.sub_y - m.y as f32).abs() <= 0.5);
                    prop_assert!(m.x >= sx.max(0) && m.y >= sy.max(0));
                    prop_assert!(m.x as usize + tw <= iw && m.y as usize + th <= ih);
                    prop_assert!(st.positions_scored > 0 && usize::from(st.levels) <= MAX_LEVELS);
                }
                Err(e) => prop_assert_eq!(e.group(), 0x05),
            }
        }
    }
}
