//! The Match policy (paper §III-D): which template variants to try, in what
//! order, and how to accept a match. Plain data, validated once.

use super::MATCH_VARIANTS;
use crate::config::Params;
use crate::failure::FailureCode;
use crate::ncc::{Filter, Search};

/// One template variant: size (ℓ or the centred ℓ/2) and filter domain.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Variant {
    /// Use the centred ℓ/2 sub-template.
    pub half: bool,
    /// Correlation domain.
    pub filter: Filter,
}

impl Variant {
    /// Index into [`PipelineStats::matches`](super::PipelineStats::matches): `size * 3 + filter`.
    pub const fn index(self) -> usize {
        let f = match self.filter {
            Filter::Gray => 0,
            Filter::Sobel => 1,
            Filter::Laplacian => 2,
        };
        (self.half as usize) * 3 + f
    }
}

/// Whether [`Variant::index`] `index` names a gradient-domain variant
/// (Sobel or Laplacian, at ℓ or ℓ/2); `false` for gray and for
/// [`VARIANT_UNKNOWN`](crate::pose::VARIANT_UNKNOWN).
pub const fn is_gradient_variant(index: u8) -> bool {
    (index as usize) < super::MATCH_VARIANTS && index % 3 != 0
}

/// Which variants to try, in what order, and how to accept a match.
///
/// A variant is accepted when both the left and the right search score at
/// least `min_score` and their runner-up is at most `max_runner_up_ratio` times
/// the score; the first accepted variant gives the pixel pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MatchPolicy {
    /// Variants in order of trial; `None` entries are skipped.
    pub variants: [Option<Variant>; MATCH_VARIANTS],
    /// Minimum NCC score, (0, 1).
    pub min_score: f32,
    /// Largest runner-up / score ratio, (0, 1].
    pub max_runner_up_ratio: f32,
    /// Search strategy.
    pub search: Search,
    /// Disparity 1-σ for the correspondence's sigma, pixels, ≥ 0.
    pub sigma_d_px: f32,
    /// Smallest plausible disparity, pixels, ≥ 0.
    pub min_disparity_px: f32,
    /// Extra margin added to the projected uncertainty, pixels.
    pub margin_px: u16,
    /// Search the right image only over the epipolar band of the accepted left
    /// match (VTSM-RELOC-034) instead of the whole right window.
    pub epipolar_band: bool,
}

/// Smallest template side at which [`MatchPolicy::for_params`] searches the
/// right image along the epipolar band only. The whole-window right search
/// rejects a false left match whenever the right image holds a stronger peak
/// elsewhere; the band gives that check up for a 30–60 % smaller NCC cost. At
/// ℓ = 64 (demo profile) the paper suite's accuracy was unchanged with the band,
/// at ℓ = 32 (test profile) the tail grew (`fsw-docs/eval/epipolar-band.md`).
pub const EPIPOLAR_BAND_MIN_TEMPLATE_PX: u16 = 64;

impl MatchPolicy {
    /// Sobel then gray at ℓ, then (with `params.sub_template`) Sobel then gray
    /// at ℓ/2; no Laplacian. `min_score` from `params`, runner-up ratio 0.9,
    /// coarse-to-fine search; the right search along the epipolar band from
    /// ℓ = [`EPIPOLAR_BAND_MIN_TEMPLATE_PX`] up.
    ///
    /// Chosen from the simulated-depot study in `fsw-docs/eval/matching.md`
    /// (`sim/examples/match_study.rs`): under a 3–6 h lighting change the
    /// Sobel domain gives the most correct matches and, tried first, the fewest
    /// false accepts at the same yield; the Laplacian domain has the lowest
    /// correct-match rate, its accepted matches are the most often wrong, and
    /// its coarse-to-fine search agrees least with the exhaustive one, so it
    /// only adds searches. The two free slots stay `None`.
    pub fn for_params(params: &Params) -> Self {
        let v = |half, filter| Some(Variant { half, filter });
        let sub = params.sub_template;
        Self {
            variants: [
                v(false, Filter::Sobel),
                v(false, Filter::Gray),
                if sub { v(true, Filter::Sobel) } else { None },
                if sub { v(true, Filter::Gray) } else { None },
                None,
                None,
            ],
            min_score: params.min_score,
            max_runner_up_ratio: 0.9,
            search: Search::CoarseToFine,
            sigma_d_px: 0.5,
            min_disparity_px: 1.0,
            margin_px: 4,
            epipolar_band: params.template_px >= EPIPOLAR_BAND_MIN_TEMPLATE_PX,
        }
    }

    /// Check the ranges documented on each field (the search-window cap is
    /// [`Params::search_px`], checked with the params).
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`].
    pub fn validate(&self) -> Result<(), FailureCode> {
        let ok = self.min_score.is_finite()
            && self.min_score > 0.0
            && self.min_score < 1.0
            && self.max_runner_up_ratio.is_finite()
            && self.max_runner_up_ratio > 0.0
            && self.max_runner_up_ratio <= 1.0
            && self.sigma_d_px.is_finite()
            && self.sigma_d_px >= 0.0
            && self.min_disparity_px.is_finite()
            && self.min_disparity_px >= 0.0
            && self.variants.iter().any(Option::is_some);
        if ok {
            Ok(())
        } else {
            Err(FailureCode::ConfigParamOutOfRange)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Verifies: VTSM-RELOC-017
    #[test]
    fn default_policy_orders_full_then_half_and_validates_ranges() {
        let mut p = Params::paper();
        let pol = MatchPolicy::for_params(&p);
        assert_eq!(pol.validate(), Ok(()));
        let idx: heapless::Vec<usize, 6> =
            pol.variants.iter().flatten().map(|v| v.index()).collect();
        // Sobel ℓ, gray ℓ, Sobel ℓ/2, gray ℓ/2 (index = half * 3 + filter).
        assert_eq!(idx.as_slice(), &[1, 0, 4, 3]);
        assert!(pol
            .variants
            .iter()
            .flatten()
            .all(|v| v.filter != Filter::Laplacian));
        p.sub_template = false;
        let pol = MatchPolicy::for_params(&p);
        assert_eq!(pol.variants.iter().flatten().count(), 2);
        assert!(pol.variants.iter().flatten().all(|v| !v.half));
        let bad = |f: fn(&mut MatchPolicy)| {
            let mut q = MatchPolicy::for_params(&Params::paper());
            f(&mut q);
            q.validate()
        };
        let err = Err(FailureCode::ConfigParamOutOfRange);
        assert_eq!(bad(|q| q.min_score = 1.0), err);
        assert_eq!(bad(|q| q.max_runner_up_ratio = 0.0), err);
        assert_eq!(bad(|q| q.sigma_d_px = f32::NAN), err);
        assert_eq!(bad(|q| q.variants = [None; MATCH_VARIANTS]), err);
    }
}
