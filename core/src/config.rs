//! Capacities and default parameters of the paper, and validated runtime [`Params`].
//!
//! Capacities (`SCREAMING_CASE`) size every buffer and bound every loop in the
//! core; [`Params`] holds the values a mission may tune at run time. A parameter
//! outside its range is an error ([`ParamError`]), never silently clamped.

// ---- capacities -----------------------------------------------------------

/// Largest image side (pixels) any view accepts. Paper profile: 5472×3648.
pub const MAX_IMAGE_DIM: usize = 8192;
/// Largest template side ℓ (pixels). Paper: 256.
pub const MAX_TEMPLATE_PX: usize = 256;
/// Smallest template side accepted.
pub const MIN_TEMPLATE_PX: usize = 16;
/// Largest search-window side (pixels). Paper: about 800.
pub const MAX_SEARCH_PX: usize = 1024;
/// Largest number of correspondences per iteration (N_corr cap).
pub const MAX_CORR: usize = 256;
/// Largest number of iterations (N_iter cap).
pub const MAX_ITER: usize = 16;
/// Largest RANSAC iteration cap.
pub const MAX_RANSAC_ITER: usize = 4096;
/// Pose candidates kept for Distribute.
pub const MAX_POSE_CANDIDATES: usize = 8;
/// Largest number of pose seeds for the multi-seed mode.
pub const MAX_SEEDS: usize = 256;
/// Largest cap on consecutive Stall or Reseed.
pub const MAX_CONSECUTIVE_CAP: usize = 64;
/// Largest cap on correspondence attempts in one iteration.
pub const MAX_ATTEMPTS_PER_ITER: usize = 100_000;
/// Largest cap on Levenberg–Marquardt iterations of the final pose refinement.
pub const MAX_REFINE_ITER: usize = 32;
/// Events kept in the failure log's ring.
pub const FAILURE_RING_LEN: usize = 32;

// ---- map product and rasterizer (core::map, core::raster) ----------------

/// Largest number of vertices in a map product. A depot map is ~10⁵–10⁶.
pub const MAX_MAP_VERTICES: usize = 1 << 22;
/// Largest number of triangles in a map product.
pub const MAX_MAP_TRIANGLES: usize = 1 << 22;
/// Largest number of tiles (cells of the x-y tiling grid) in a map product.
pub const MAX_MAP_TILES: usize = 1 << 16;
/// Largest magnitude of each coordinate of a map product's origin, metres.
/// 10⁸ m is beyond every Earth-fixed frame (UTM northings reach 10⁷ m, ECEF
/// 6.4·10⁶ m) and an f64 there still resolves 15 nm.
pub const MAX_MAP_ORIGIN_M: f64 = 1.0e8;
/// Largest texture side (pixels) in a map product.
pub const MAX_TEXTURE_DIM: usize = 16384;
/// Largest render window side (pixels): a template.
pub const MAX_RENDER_PX: usize = MAX_TEMPLATE_PX;
/// Guard band (pixels) around the render window: geometry is clipped in camera
/// space to the window grown by this much, so fixed-point edge setup stays in range.
pub const RASTER_GUARD_PX: i32 = 256;
/// Near clipping plane of the virtual camera, metres.
pub const RASTER_NEAR_M: f32 = 0.05;
/// Far limit of the virtual camera, metres (depth format range, see numeric.md).
pub const RASTER_FAR_M: f32 = 60_000.0;
/// Template mask: search radius (pixels, Chebyshev) for a nearer mask pixel.
pub const TEMPLATE_MASK_RADIUS_PX: usize = 3;
/// Template mask: a background pixel is kept when it is farther than a nearby
/// mask pixel by more than this absolute jump, metres...
pub const TEMPLATE_MASK_JUMP_M: f32 = 0.05;
/// ...plus the mask pixel's depth divided by this (50 → 2 %: the threshold grows with range).
pub const TEMPLATE_MASK_JUMP_REL_DIV: u32 = 50;

// ---- defaults (paper §III, §IV) ------------------------------------------

/// N_corr: correspondences per iteration.
pub const DEFAULT_N_CORR: u16 = 100;
/// N_iter: successful iterations.
pub const DEFAULT_N_ITER: u8 = 5;
/// t̃₀: initial translation search bound, metres.
pub const DEFAULT_T0_M: f32 = 0.20;
/// r̃₀: initial rotation search bound, degrees.
pub const DEFAULT_R0_DEG: f32 = 1.5;
/// Largest t̃₀ ([`Params::t0_m`], [`PriorUncertainty::t_m`]), metres. Beyond
/// a couple of metres a single start does not see the templates it renders
/// near the truth; larger priors need the multi-seed mode.
pub const MAX_T0_M: f32 = 2.0;
/// Largest r̃₀ ([`Params::r0_deg`], [`PriorUncertainty::r_deg`]), degrees.
pub const MAX_R0_DEG: f32 = 20.0;
/// γ: Anneal decay.
pub const DEFAULT_GAMMA: f32 = 0.5;
/// ε: epipolar row tolerance, pixels.
pub const DEFAULT_EPSILON_PX: f32 = 8.0;
/// ℓ: template side at paper scale.
pub const DEFAULT_TEMPLATE_PX: u16 = 256;
/// Consecutive Stall cap.
pub const DEFAULT_MAX_STALL: u8 = 3;
/// Consecutive Reseed cap.
pub const DEFAULT_MAX_RESEED: u8 = 10;
/// RANSAC iteration cap.
pub const DEFAULT_RANSAC_ITER: u16 = 1000;
/// RANSAC inlier threshold, metres.
pub const DEFAULT_INLIER_M: f32 = 0.05;
/// Convergence: stop when the pose update is below this, metres.
pub const DEFAULT_CONVERGENCE_M: f32 = 0.001;
/// Reuse: fraction of inliers carried into the next iteration.
pub const DEFAULT_REUSE_FRACTION: f32 = 0.5;
/// Correspondence attempts allowed per iteration before it fails.
pub const DEFAULT_ATTEMPTS_PER_ITER: u32 = 2000;
/// Minimum NCC score to accept a match.
pub const DEFAULT_MIN_SCORE: f32 = 0.5;
/// Levenberg–Marquardt iterations of the final pose refinement (0 = off).
pub const DEFAULT_REFINE_ITER: u8 = 10;

const _: () = assert!(MIN_TEMPLATE_PX <= MAX_TEMPLATE_PX);
const _: () = assert!(MAX_TEMPLATE_PX <= MAX_SEARCH_PX);
const _: () = assert!(DEFAULT_N_CORR as usize <= MAX_CORR);
const _: () = assert!(DEFAULT_N_ITER as usize <= MAX_ITER);
const _: () = assert!(DEFAULT_RANSAC_ITER as usize <= MAX_RANSAC_ITER);
const _: () = assert!(DEFAULT_REFINE_ITER as usize <= MAX_REFINE_ITER);
const _: () = assert!(DEFAULT_TEMPLATE_PX as usize <= MAX_TEMPLATE_PX);
const _: () = assert!(DEFAULT_T0_M > 0.0 && DEFAULT_T0_M <= MAX_T0_M);
const _: () = assert!(DEFAULT_R0_DEG > 0.0 && DEFAULT_R0_DEG <= MAX_R0_DEG);
// 28.4 edge setup runs in i64 on absolute coordinates (< 2^18, so edge terms < 2^41);
// a window-relative variant would fit i32: see fsw-docs/budgets/numeric.md.
const _: () = assert!((MAX_RENDER_PX as i64 + 2 * RASTER_GUARD_PX as i64 + 16) * 16 < (1 << 15));
const _: () = assert!(MAX_MAP_TILES <= MAX_MAP_TRIANGLES);
const _: () = assert!(((MAX_IMAGE_DIM as i64 + 2 * RASTER_GUARD_PX as i64 + 16) * 16) < (1 << 18));
const _: () = assert!(MAX_TEXTURE_DIM * MAX_TEXTURE_DIM <= u32::MAX as usize);
// 255² · 256² must fit a u32 for exact integer NCC sums (see fsw-docs/budgets/numeric.md).
const _: () = assert!((255u64 * 255 * (MAX_TEMPLATE_PX * MAX_TEMPLATE_PX) as u64) < (1u64 << 32));

// ---- template and search-window policy -----------------------------------

/// Template side ℓ for an image `width` pixels wide: the paper's 256 px at
/// 5472 px, scaled with the image so templates cover the same angle, rounded
/// to the nearest integer, clamped to `32..=MAX_TEMPLATE_PX` and made even.
///
/// Integer arithmetic: `round(256·w / 5472)` is never a tie (`8w/171` has an
/// odd denominator), so this equals the f64 formula for every width.
pub const fn template_px_for_width(width: u32) -> u16 {
    let w = width as u64;
    let l = (2 * 256 * w + 5472) / (2 * 5472);
    let l = if l < 32 {
        32
    } else if l > MAX_TEMPLATE_PX as u64 {
        MAX_TEMPLATE_PX as u64
    } else {
        l
    };
    (l & !1) as u16
}

/// Search-window cap for template side ℓ: the paper's ~800 px for ℓ = 256,
/// i.e. ⌊3.2 ℓ⌋, at least 2 ℓ, at most `MAX_SEARCH_PX`.
pub const fn search_px_for_template(template_px: u16) -> u16 {
    let l = template_px as usize;
    let s = l * 16 / 5;
    let s = if s < 2 * l { 2 * l } else { s };
    let s = if s > MAX_SEARCH_PX { MAX_SEARCH_PX } else { s };
    s as u16
}

/// The relocalization mechanisms of paper §III-E, each switchable.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Mechanisms {
    /// Stall: on failure after a success, collect new correspondences from the same pose.
    pub stall: bool,
    /// Reseed: on failure, perturb the pose randomly before collecting again.
    pub reseed: bool,
    /// Anneal: shrink t̃, r̃ by γ after each success.
    pub anneal: bool,
    /// Distribute: spread viewpoints over the best pose candidates by inlier count.
    pub distribute: bool,
    /// Reuse: carry a fraction of inliers into the next iteration.
    pub reuse: bool,
}

/// The uncertainty of a pose prior: half-widths of the region the true pose
/// lies in around it (the paper's t̃₀, r̃₀), as a navigation filter or the
/// operator states it with the prior. The engine takes them as
/// [`Params::t0_m`] and [`Params::r0_deg`] ([`Params::with_uncertainty`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PriorUncertainty {
    /// Translation half-width, metres, (0, [`MAX_T0_M`]].
    pub t_m: f32,
    /// Rotation half-width, degrees, (0, [`MAX_R0_DEG`]].
    pub r_deg: f32,
}

impl PriorUncertainty {
    /// The paper's prior uncertainty: 0.20 m, 1.5° ([`DEFAULT_T0_M`],
    /// [`DEFAULT_R0_DEG`]).
    pub const PAPER: Self = Self {
        t_m: DEFAULT_T0_M,
        r_deg: DEFAULT_R0_DEG,
    };

    /// Check both half-widths: finite, `t_m` in (0, [`MAX_T0_M`]], `r_deg` in
    /// (0, [`MAX_R0_DEG`]] (the ranges of [`Params::t0_m`], [`Params::r0_deg`]).
    ///
    /// # Errors
    /// [`ParamField::T0`] or [`ParamField::R0`] for the first one out of range.
    pub fn validate(&self) -> Result<(), ParamError> {
        if !in_range(self.t_m, 0.0, MAX_T0_M, true) {
            return Err(ParamError {
                field: ParamField::T0,
            });
        }
        if !in_range(self.r_deg, 0.0, MAX_R0_DEG, true) {
            return Err(ParamError {
                field: ParamField::R0,
            });
        }
        Ok(())
    }
}

/// Runtime parameters, validated against the capacities above.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Params {
    /// N_corr, 3..=MAX_CORR.
    pub n_corr: u16,
    /// N_iter, 1..=MAX_ITER.
    pub n_iter: u8,
    /// t̃₀ in metres, (0, [`MAX_T0_M`]]: the prior's translation uncertainty
    /// (half-width), which sizes the first viewpoint perturbations, the
    /// search windows and the prior integrity gate. Set from a stated prior
    /// uncertainty with [`Params::with_uncertainty`].
    pub t0_m: f32,
    /// r̃₀ in degrees, (0, [`MAX_R0_DEG`]]: the prior's rotation uncertainty.
    pub r0_deg: f32,
    /// γ, [0, 1].
    pub gamma: f32,
    /// ε in pixels, (0, 64].
    pub epsilon_px: f32,
    /// ℓ in pixels, even, MIN_TEMPLATE_PX..=MAX_TEMPLATE_PX.
    pub template_px: u16,
    /// Largest search-window side in pixels, `template_px..=MAX_SEARCH_PX`
    /// (the window is the projected uncertainty, capped at this). Sizes the
    /// workspace ([`crate::reloc::WorkspaceSizes::for_params`]); set together
    /// with ℓ by [`Params::with_template_px`].
    pub search_px: u16,
    /// Also match the ℓ/2 sub-template variant.
    pub sub_template: bool,
    /// Consecutive Stall cap, 1..=MAX_CONSECUTIVE_CAP.
    pub max_stall: u8,
    /// Consecutive Reseed cap, 1..=MAX_CONSECUTIVE_CAP.
    pub max_reseed: u8,
    /// RANSAC iteration cap, 1..=MAX_RANSAC_ITER.
    pub ransac_iter: u16,
    /// RANSAC inlier threshold in metres, (0, 1].
    pub inlier_m: f32,
    /// Convergence threshold in metres, [0, 0.1].
    pub convergence_m: f32,
    /// Reuse fraction, [0, 1].
    pub reuse_fraction: f32,
    /// Attempts per iteration, n_corr..=MAX_ATTEMPTS_PER_ITER.
    pub attempts_per_iter: u32,
    /// Minimum NCC score to accept a match, (0, 1).
    pub min_score: f32,
    /// Pose seeds for large priors (0 = off), 0..=MAX_SEEDS.
    pub seeds: u16,
    /// Levenberg–Marquardt iterations of the final pose refinement on the
    /// stereo reprojection error, 0..=MAX_REFINE_ITER (0 = keep the RANSAC
    /// pose; its covariance is reported either way).
    pub refine_iter: u8,
    /// Mechanism switches.
    pub mechanisms: Mechanisms,
}

impl Default for Params {
    fn default() -> Self {
        Self::paper()
    }
}

/// Which field of [`Params`] is out of range.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ParamField {
    /// `n_corr`
    NCorr,
    /// `n_iter`
    NIter,
    /// `t0_m`
    T0,
    /// `r0_deg`
    R0,
    /// `gamma`
    Gamma,
    /// `epsilon_px`
    Epsilon,
    /// `template_px`
    TemplatePx,
    /// `search_px`
    SearchPx,
    /// `max_stall`
    MaxStall,
    /// `max_reseed`
    MaxReseed,
    /// `ransac_iter`
    RansacIter,
    /// `inlier_m`
    InlierM,
    /// `convergence_m`
    ConvergenceM,
    /// `reuse_fraction`
    ReuseFraction,
    /// `attempts_per_iter`
    AttemptsPerIter,
    /// `min_score`
    MinScore,
    /// `seeds`
    Seeds,
    /// `refine_iter`
    RefineIter,
}

/// A parameter outside its allowed range.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ParamError {
    /// The offending field.
    pub field: ParamField,
}

fn in_range(v: f32, lo: f32, hi: f32, lo_open: bool) -> bool {
    v.is_finite() && v <= hi && if lo_open { v > lo } else { v >= lo }
}

impl Params {
    /// The paper's parameters (§III, §IV).
    pub const fn paper() -> Self {
        Self {
            n_corr: DEFAULT_N_CORR,
            n_iter: DEFAULT_N_ITER,
            t0_m: DEFAULT_T0_M,
            r0_deg: DEFAULT_R0_DEG,
            gamma: DEFAULT_GAMMA,
            epsilon_px: DEFAULT_EPSILON_PX,
            template_px: DEFAULT_TEMPLATE_PX,
            search_px: search_px_for_template(DEFAULT_TEMPLATE_PX),
            sub_template: true,
            max_stall: DEFAULT_MAX_STALL,
            max_reseed: DEFAULT_MAX_RESEED,
            ransac_iter: DEFAULT_RANSAC_ITER,
            inlier_m: DEFAULT_INLIER_M,
            convergence_m: DEFAULT_CONVERGENCE_M,
            reuse_fraction: DEFAULT_REUSE_FRACTION,
            attempts_per_iter: DEFAULT_ATTEMPTS_PER_ITER,
            min_score: DEFAULT_MIN_SCORE,
            seeds: 0,
            refine_iter: DEFAULT_REFINE_ITER,
            mechanisms: Mechanisms {
                stall: true,
                reseed: true,
                anneal: true,
                distribute: true,
                reuse: true,
            },
        }
    }

    /// The paper's parameters with ℓ scaled to an image `width` pixels wide
    /// ([`template_px_for_width`]) and its search window
    /// ([`search_px_for_template`]).
    pub const fn for_image_width(width: u32) -> Self {
        Self::paper().with_template_px(template_px_for_width(width))
    }

    /// These parameters with template side `template_px` and the search-window
    /// cap that goes with it ([`search_px_for_template`]).
    #[must_use]
    pub const fn with_template_px(self, template_px: u16) -> Self {
        Self {
            template_px,
            search_px: search_px_for_template(template_px),
            ..self
        }
    }

    /// These parameters with t̃₀, r̃₀ from a prior's stated uncertainty
    /// (everything else, the number of seeds included, unchanged). Not
    /// checked here: [`Params::validate`] checks the result.
    #[must_use]
    pub const fn with_uncertainty(self, u: PriorUncertainty) -> Self {
        Self {
            t0_m: u.t_m,
            r0_deg: u.r_deg,
            ..self
        }
    }

    /// The prior uncertainty these parameters assume: (t̃₀, r̃₀).
    pub const fn uncertainty(&self) -> PriorUncertainty {
        PriorUncertainty {
            t_m: self.t0_m,
            r_deg: self.r0_deg,
        }
    }

    /// Check every field; the first one out of range is reported.
    pub fn validate(&self) -> Result<(), ParamError> {
        let err = |field| Err(ParamError { field });
        if !(3..=MAX_CORR as u16).contains(&self.n_corr) {
            return err(ParamField::NCorr);
        }
        if !(1..=MAX_ITER as u8).contains(&self.n_iter) {
            return err(ParamField::NIter);
        }
        self.uncertainty().validate()?;
        if !in_range(self.gamma, 0.0, 1.0, false) {
            return err(ParamField::Gamma);
        }
        if !in_range(self.epsilon_px, 0.0, 64.0, true) {
            return err(ParamField::Epsilon);
        }
        let l = self.template_px as usize;
        if !(MIN_TEMPLATE_PX..=MAX_TEMPLATE_PX).contains(&l) || l % 2 != 0 {
            return err(ParamField::TemplatePx);
        }
        if !(l..=MAX_SEARCH_PX).contains(&usize::from(self.search_px)) {
            return err(ParamField::SearchPx);
        }
        if !(1..=MAX_CONSECUTIVE_CAP as u8).contains(&self.max_stall) {
            return err(ParamField::MaxStall);
        }
        if !(1..=MAX_CONSECUTIVE_CAP as u8).contains(&self.max_reseed) {
            return err(ParamField::MaxReseed);
        }
        if !(1..=MAX_RANSAC_ITER as u16).contains(&self.ransac_iter) {
            return err(ParamField::RansacIter);
        }
        if !in_range(self.inlier_m, 0.0, 1.0, true) {
            return err(ParamField::InlierM);
        }
        if !in_range(self.convergence_m, 0.0, 0.1, false) {
            return err(ParamField::ConvergenceM);
        }
        if !in_range(self.reuse_fraction, 0.0, 1.0, false) {
            return err(ParamField::ReuseFraction);
        }
        if !(u32::from(self.n_corr)..=MAX_ATTEMPTS_PER_ITER as u32)
            .contains(&self.attempts_per_iter)
        {
            return err(ParamField::AttemptsPerIter);
        }
        if !(self.min_score.is_finite() && self.min_score > 0.0 && self.min_score < 1.0) {
            return err(ParamField::MinScore);
        }
        if self.seeds as usize > MAX_SEEDS {
            return err(ParamField::Seeds);
        }
        if usize::from(self.refine_iter) > MAX_REFINE_ITER {
            return err(ParamField::RefineIter);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::failure::FailureCode;

    /// Verifies: VTSM-CFG-002
    #[test]
    fn paper_params_are_valid() {
        assert_eq!(Params::paper().validate(), Ok(()));
    }

    /// Verifies: VTSM-CFG-003
    #[test]
    fn each_out_of_range_field_has_its_own_error() {
        type Case = (fn(&mut Params), ParamField);
        let cases: &[Case] = &[
            (|p| p.n_corr = 2, ParamField::NCorr),
            (|p| p.n_corr = MAX_CORR as u16 + 1, ParamField::NCorr),
            (|p| p.n_iter = 0, ParamField::NIter),
            (|p| p.n_iter = MAX_ITER as u8 + 1, ParamField::NIter),
            (|p| p.t0_m = 0.0, ParamField::T0),
            (|p| p.t0_m = f32::NAN, ParamField::T0),
            (|p| p.r0_deg = -1.0, ParamField::R0),
            (|p| p.r0_deg = f32::INFINITY, ParamField::R0),
            (|p| p.gamma = 1.5, ParamField::Gamma),
            (|p| p.epsilon_px = 0.0, ParamField::Epsilon),
            (|p| p.template_px = 255, ParamField::TemplatePx),
            (|p| p.template_px = 512, ParamField::TemplatePx),
            (|p| p.template_px = 8, ParamField::TemplatePx),
            (|p| p.search_px = 255, ParamField::SearchPx),
            (
                |p| p.search_px = MAX_SEARCH_PX as u16 + 1,
                ParamField::SearchPx,
            ),
            (|p| p.max_stall = 0, ParamField::MaxStall),
            (
                |p| p.max_reseed = MAX_CONSECUTIVE_CAP as u8 + 1,
                ParamField::MaxReseed,
            ),
            (|p| p.ransac_iter = 0, ParamField::RansacIter),
            (
                |p| p.ransac_iter = MAX_RANSAC_ITER as u16 + 1,
                ParamField::RansacIter,
            ),
            (|p| p.inlier_m = 0.0, ParamField::InlierM),
            (|p| p.convergence_m = -0.001, ParamField::ConvergenceM),
            (|p| p.reuse_fraction = 1.01, ParamField::ReuseFraction),
            (|p| p.attempts_per_iter = 10, ParamField::AttemptsPerIter),
            (|p| p.min_score = 1.0, ParamField::MinScore),
            (|p| p.seeds = MAX_SEEDS as u16 + 1, ParamField::Seeds),
            (
                |p| p.refine_iter = MAX_REFINE_ITER as u8 + 1,
                ParamField::RefineIter,
            ),
        ];
        for (mutate, field) in cases {
            let mut p = Params::paper();
            mutate(&mut p);
            assert_eq!(p.validate(), Err(ParamError { field: *field }), "{field:?}");
            assert_eq!(
                FailureCode::from(ParamError { field: *field }),
                FailureCode::ConfigParamOutOfRange
            );
        }
    }

    /// Verifies: VTSM-CFG-006
    #[test]
    fn prior_uncertainty_sets_t0_r0_within_their_ranges() {
        assert_eq!(PriorUncertainty::PAPER.validate(), Ok(()));
        assert_eq!(Params::paper().uncertainty(), PriorUncertainty::PAPER);
        let u = PriorUncertainty {
            t_m: 0.5,
            r_deg: 1.5,
        };
        let p = Params::paper().with_uncertainty(u);
        assert_eq!((p.t0_m, p.r0_deg, p.seeds), (0.5, 1.5, 0));
        assert_eq!(p.uncertainty(), u);
        assert_eq!(
            p,
            Params {
                t0_m: 0.5,
                ..Params::paper()
            }
        );
        assert_eq!(p.validate(), Ok(()));
        let top = PriorUncertainty {
            t_m: MAX_T0_M,
            r_deg: MAX_R0_DEG,
        };
        assert_eq!(top.validate(), Ok(()));
        let t0 = Err(ParamError {
            field: ParamField::T0,
        });
        let r0 = Err(ParamError {
            field: ParamField::R0,
        });
        for (t_m, r_deg, want) in [
            (0.0, 1.5, t0),
            (-0.1, 1.5, t0),
            (f32::NAN, 1.5, t0),
            (f32::INFINITY, 1.5, t0),
            (MAX_T0_M * 1.001, 1.5, t0),
            (0.5, 0.0, r0),
            (0.5, -1.0, r0),
            (0.5, f32::NAN, r0),
            (0.5, MAX_R0_DEG * 1.001, r0),
        ] {
            let u = PriorUncertainty { t_m, r_deg };
            assert_eq!(u.validate(), want, "{u:?}");
            // The engine's own check of the params sees the same.
            assert_eq!(Params::paper().with_uncertainty(u).validate(), want);
        }
    }

    /// Verifies: VTSM-CFG-005
    #[test]
    fn template_and_search_policy_match_the_f64_formula_at_every_width() {
        for width in 1..=MAX_IMAGE_DIM as u32 {
            let l = libm::round(256.0 * f64::from(width) / 5472.0) as u32;
            let l = (l.clamp(32, MAX_TEMPLATE_PX as u32) & !1) as u16;
            assert_eq!(template_px_for_width(width), l, "width {width}");
            let p = Params::for_image_width(width);
            assert_eq!(p.validate(), Ok(()), "width {width}");
            assert!(p.search_px >= 2 * p.template_px);
        }
        assert_eq!(template_px_for_width(5472), 256);
        assert_eq!(search_px_for_template(256), 819);
        assert_eq!(search_px_for_template(64), 204);
        assert_eq!(Params::paper().search_px, 819);
        let p = Params::paper().with_template_px(64);
        assert_eq!((p.template_px, p.search_px), (64, 204));
    }
}
