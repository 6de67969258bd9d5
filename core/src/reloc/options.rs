//! The engine's [`Options`] beside [`Params`]: acceptance, the work and tick
//! [`Budget`], the multi-seed spread, [`Focus`], the integrity [`Gates`] and the
//! [`Verify`] upset checks, with the defaults derived from the parameters.

use crate::config::Params;
use crate::failure::FailureCode;

/// A work and tick budget after which the best pose so far is returned with
/// [`FailureCode::RelocBudgetExhausted`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Budget {
    /// Largest number of work units (attempts + solves); `u32::MAX` = only the structural bound.
    pub max_work_units: u32,
    /// Caller ticks at or after which no more work is done; `u64::MAX` = none.
    pub deadline_tick: u64,
}

impl Budget {
    /// No budget beyond the structural bound of the parameters.
    pub const UNLIMITED: Budget = Budget {
        max_work_units: u32::MAX,
        deadline_tick: u64::MAX,
    };
}

/// Engine options that are not part of [`Params`].
///
/// Start from [`Options::for_params`] and change values with the `with_*`
/// methods, each of which refuses a value out of its range with
/// [`FailureCode::ConfigParamOutOfRange`]; the checks that need the
/// parameters (`min_inliers` ≤ N_corr, Focus votes ≤ N_corr) are made again,
/// with every other one, where the options meet them
/// ([`Setup::with_options`](super::Setup::with_options), [`Setup::build`](super::Setup::build)).
/// Values are read through accessors of the fields' names.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    pub(super) min_inliers: u16,
    pub(super) seed_t_m: f32,
    pub(super) seed_r_deg: f32,
    pub(super) budget: Budget,
    pub(super) no_evidence_attempts: u32,
    pub(super) first_fix_rounds: u8,
    pub(super) first_fix_sigma_scale: f32,
    pub(super) gates: Gates,
    pub(super) verify: Verify,
    pub(super) focus: Focus,
    pub(super) final_gradient_only: bool,
    pub(super) final_pairs: u16,
    pub(super) search: Search,
    pub(super) accuracy: Option<Accuracy>,
}

/// Radius of [`Near::ON`], metres: half a 0.5 m map tile, a few
/// template footprints at the working distances.
pub const DEFAULT_NEAR_RADIUS_M: f32 = 0.25;

/// The search mechanisms a caller may turn on or off, carried as one value
/// from every front door (`Job`, the host's request, the CLI's
/// `--revisit` and `--near`) to [`Options::with_search`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Search {
    /// Revisit ([`Options::revisit`]).
    pub revisit: bool,
    /// Near ([`Near`]).
    pub near: Near,
}

impl Search {
    /// The engine's default: Revisit on, Near off (it trades accuracy for
    /// attempts; `fsw-docs/eval/near.md`).
    pub const DEFAULT: Self = Self {
        revisit: true,
        near: Near::OFF,
    };

    /// Both off: every attempt draws its vertex anywhere in the map.
    pub const OFF: Self = Self {
        revisit: false,
        near: Near::OFF,
    };
}

impl Default for Search {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Near (VTSM-RELOC-047): in the rounds after a pose update, the last one
/// excepted, a share of the drawn attempts look for their vertex near the
/// vertex of a pair that agreed with that update (an inlier, reused or to be
/// revisited) instead of anywhere in the map. Under a changed light whole
/// regions of the depot stop matching (a moved shadow, a slope now lit from
/// behind) while others keep matching; the neighbours of a vertex that
/// matched share its light. The last round draws anywhere: the final pose
/// rests on pairs spread over the view, not clustered where earlier rounds
/// matched (clustered pairs share their templates' bias under the new light
/// and average less of it away; measured in `fsw-docs/eval/near.md`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Near {
    /// Share of the drawn attempts that look near an agreeing vertex, in
    /// 1/256 (0 = off, 256 = every drawn attempt).
    pub share_256: u16,
    /// How far from the agreeing vertex a drawn vertex may lie, metres
    /// (0, 10].
    pub radius_m: f32,
}

impl Near {
    /// Near off: every drawn attempt draws from the whole map.
    pub const OFF: Self = Self {
        share_256: 0,
        radius_m: DEFAULT_NEAR_RADIUS_M,
    };

    /// Near on as measured (`fsw-docs/eval/near.md`): every drawn attempt
    /// of the middle rounds looks within [`DEFAULT_NEAR_RADIUS_M`] of an
    /// agreeing vertex.
    pub const ON: Self = Self {
        share_256: 256,
        radius_m: DEFAULT_NEAR_RADIUS_M,
    };

    /// Whether the share and radius are in range.
    pub fn validate(&self) -> bool {
        self.share_256 <= 256 && self.radius_m > 0.0 && self.radius_m <= 10.0
    }
}

/// The accuracy a caller needs: the run ends after the first pose update
/// (of the `n_iter` it may make) whose refined estimate states a 1-σ
/// uncertainty at or below both bounds in every axis (the largest
/// translation and rotation standard deviations of its covariance,
/// [`crate::pose::Covariance`]), instead of always running `n_iter` updates.
/// The covariance is that of the final refinement, whose 95 % ellipsoid
/// holds the true error about 95 % of the time on the simulated depots
/// (`fsw-docs/eval/covariance.md`); the check costs one refinement per pose
/// update, counted in [`Stats::accuracy_checks`](super::Stats::accuracy_checks).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Accuracy {
    /// Largest 1-σ translation uncertainty accepted, metres, in (0, 1].
    pub sigma_t_m: f32,
    /// Largest 1-σ rotation uncertainty accepted, degrees, in (0, 10].
    pub sigma_r_deg: f32,
}

impl Accuracy {
    /// Whether both bounds are in range.
    pub fn validate(&self) -> bool {
        let t = self.sigma_t_m;
        let r = self.sigma_r_deg;
        t.is_finite() && t > 0.0 && t <= 1.0 && r.is_finite() && r > 0.0 && r <= 10.0
    }

    /// Whether the covariance `c` states at most this uncertainty.
    pub fn met_by(&self, c: &crate::pose::Covariance) -> bool {
        let st = c.sigma_t_m();
        let sr = c.sigma_r_rad();
        let r_max = self.sigma_r_deg.to_radians();
        st.iter().all(|&v| v.is_finite() && v <= self.sigma_t_m)
            && sr.iter().all(|&v| v.is_finite() && v <= r_max)
    }
}

/// Focus: before the first pose update, from a prior more uncertain than
/// [`Focus::t_m`], re-centre the rest of a round's viewpoints on the camera
/// position its correspondences agree on.
///
/// With the prior's rotation `R`, each correspondence gives a one-point
/// translation hypothesis `world − R·cam`: the camera position that puts the
/// triangulated point on its map point. When at least `votes` of the round's
/// hypotheses lie within `radius_m` of the newest one, and their mean within
/// the prior's stated uncertainty (t̃₀ + `radius_m`) of the prior, the
/// round's remaining viewpoints are drawn around that mean (with the prior's
/// rotation) with translation half-width `t_m` instead of t̃₀. A round that
/// then fails restores t̃₀ before its Reseed draw.
///
/// The solve is untouched: every pair is a measurement of the real images,
/// whichever viewpoint rendered its template. Only where the next templates
/// are rendered from changes: from a 0.5 m prior, few random viewpoints are
/// close enough to the truth for their templates to match inside the capped
/// search windows (`fsw-docs/eval/uncertainty50.md`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Focus {
    /// Agreeing hypotheses needed, the newest included: 0 = off, else
    /// 2..=n_corr.
    pub votes: u8,
    /// Agreement radius, metres, (0, 1]. The prior's rotation error moves a
    /// hypothesis by up to r̃₀·|cam| (7.9 cm for 1.5° at 3 m), in the same
    /// direction for points seen in the same direction.
    pub radius_m: f32,
    /// Translation half-width of the focused viewpoints, metres,
    /// (0, [`crate::config::MAX_T0_M`]]. Focus runs only while the current
    /// half-width is larger.
    pub t_m: f32,
}

/// Default [`Focus::votes`]: four agreeing pairs, so that a chance
/// agreement of wrong matches (scattered over the whole prior region) is rare.
pub const DEFAULT_FOCUS_VOTES: u8 = 4;
/// Default [`Focus::radius_m`], metres.
pub const DEFAULT_FOCUS_RADIUS_M: f32 = 0.10;

impl Focus {
    /// Never focus.
    pub const OFF: Focus = Focus {
        votes: 0,
        radius_m: DEFAULT_FOCUS_RADIUS_M,
        t_m: crate::config::DEFAULT_T0_M,
    };

    /// The defaults: [`DEFAULT_FOCUS_VOTES`] (at most N_corr) within
    /// [`DEFAULT_FOCUS_RADIUS_M`], focused to the default prior uncertainty
    /// ([`crate::config::DEFAULT_T0_M`]), the one the first round is measured
    /// from on every suite. A prior no more uncertain than that never focuses.
    #[allow(
        clippy::cast_possible_truncation,
        reason = "the minimum with DEFAULT_FOCUS_VOTES fits u8"
    )]
    pub fn for_params(params: &Params) -> Self {
        Self {
            votes: u16::from(DEFAULT_FOCUS_VOTES).min(params.n_corr) as u8,
            ..Self::OFF
        }
    }

    pub(super) fn validate(&self, params: &Params) -> bool {
        let votes_ok = self.votes == 0 || (2..=params.n_corr).contains(&u16::from(self.votes));
        votes_ok && self.validate_widths()
    }

    /// The checks that do not need the parameters: radius in (0, 1] m,
    /// width in (0, [`crate::config::MAX_T0_M`]].
    fn validate_widths(&self) -> bool {
        self.radius_m.is_finite()
            && self.radius_m > 0.0
            && self.radius_m <= 1.0
            && self.t_m.is_finite()
            && self.t_m > 0.0
            && self.t_m <= crate::config::MAX_T0_M
    }
}

/// Integrity gates on the final estimate ("is this answer the depot seen from
/// near the prior?"). Each gate that fails ends the run with its own code; the
/// pose is then returned untrusted. A threshold of 0 turns its gate off.
///
/// The thresholds follow from the geometry of the problem, not from tuning:
/// the prior's stated uncertainty, the size of the scene the inliers must
/// span to fix a rotation, and the matcher's pixel noise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gates {
    /// The estimate must lie within `prior_factor` × the prior's uncertainty
    /// of the prior, in translation and in rotation, else
    /// [`FailureCode::RelocPoseOutsidePrior`]. The uncertainty is (t̃₀, r̃₀),
    /// or the multi-seed spread when it is larger and seeds are used. 0 = off,
    /// else [1, 100].
    pub prior_factor: f32,
    /// Smallest RMS spread of the final inliers' camera points about their
    /// centroid, across their principal direction (√λ₂ of their scatter),
    /// metres, else [`FailureCode::RelocInliersDegenerate`]. 0 = off, else ≤ 100.
    pub min_spread_m: f32,
    /// Largest RMS reprojection residual of the final inliers, pixels per
    /// observation, else [`FailureCode::RelocResidualHigh`] (checked only
    /// when the final refinement ran). 0 = off, else ≤ 1000.
    pub max_reproj_px: f32,
}

impl Gates {
    /// Every gate off: acceptance is the inlier count alone.
    pub const OFF: Gates = Gates {
        prior_factor: 0.0,
        min_spread_m: 0.0,
        max_reproj_px: 0.0,
    };

    fn validate(&self) -> bool {
        let off_or = |v: f32, lo: f32, hi: f32| v == 0.0 || (v.is_finite() && v >= lo && v <= hi);
        off_or(self.prior_factor, 1.0, 100.0)
            && off_or(self.min_spread_m, 0.0, 100.0)
            && off_or(self.max_reproj_px, 0.0, 1000.0)
    }
}

/// Upset tolerance in the style of onboard localization that runs a
/// computation twice and compares before trusting it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Verify {
    /// After the final estimate, run GetTransform again on the same
    /// correspondences with a second random stream, refine it the same way,
    /// and fail with [`FailureCode::RelocVerifyDisagree`] when the two poses
    /// differ by more than `tolerance_m` or `tolerance_rad`. Costs one more
    /// solve (at most ⌈ransac_iter / RANSAC_CHUNK⌉ + 1 work units).
    pub repeat_solve: bool,
    /// Translation tolerance of `repeat_solve`, metres, > 0.
    pub tolerance_m: f32,
    /// Rotation tolerance of `repeat_solve`, radians, > 0.
    pub tolerance_rad: f32,
    /// Re-check the map product's CRCs before a success is returned (it was
    /// checked at load), else [`FailureCode::RelocMapChanged`]. Costs one
    /// pass over the map bytes in the last work unit.
    pub recheck_map: bool,
}

impl Verify {
    /// Nothing repeated; tolerances of [`Verify::for_params`].
    pub fn off(params: &Params) -> Self {
        let refine = crate::pose::RefineConfig::from_params(params);
        Self {
            repeat_solve: false,
            tolerance_m: refine.max_step_m,
            tolerance_rad: refine.max_step_rad,
            recheck_map: false,
        }
    }

    /// Both checks on; tolerances are the final refinement's safeguard
    /// (2 × the RANSAC inlier gate, [`crate::pose::DEFAULT_MAX_STEP_RAD`]):
    /// more than a consistent inlier set moves a pose, less than a different
    /// solution.
    pub fn for_params(params: &Params) -> Self {
        Self {
            repeat_solve: true,
            recheck_map: true,
            ..Self::off(params)
        }
    }

    fn validate(&self) -> bool {
        let pos = |v: f32| v.is_finite() && v > 0.0;
        pos(self.tolerance_m) && pos(self.tolerance_rad)
    }
}

impl Options {
    /// Defaults for `params`: at least 30 % of N_corr as inliers, seeds within
    /// 0.5 m / 1.5°, no evidence after max(4·N_corr, 200) attempts; the
    /// integrity gates on (prior factor [`DEFAULT_PRIOR_FACTOR`]; inlier
    /// spread at least the RANSAC inlier gate `inlier_m`, below which the
    /// inliers are a line within the gate's own tolerance; reprojection RMS at
    /// most the Valid step's row tolerance `epsilon_px`, beyond which the
    /// inliers are not a consistent set of stereo matches); the upset checks
    /// off ([`Verify::off`]).
    ///
    /// The no-evidence cap is far above what a frame of the depot needs: on
    /// the simulated and the other renderer's pairs a correspondence comes
    /// every 2–3 attempts even under a 6 h lighting change, so 200 attempts
    /// without any is a frame that does not show the map here.
    pub fn for_params(params: &Params) -> Self {
        Self {
            min_inliers: ((u32::from(params.n_corr) * 3).div_ceil(10)).max(3) as u16,
            seed_t_m: 0.5,
            seed_r_deg: params.r0_deg,
            budget: Budget::UNLIMITED,
            no_evidence_attempts: (4 * u32::from(params.n_corr)).max(200),
            first_fix_rounds: if params.t0_m <= crate::config::DEFAULT_T0_M
                && params.r0_deg <= crate::config::DEFAULT_R0_DEG
            {
                DEFAULT_FIRST_FIX_ROUNDS
            } else {
                0
            },
            first_fix_sigma_scale: first_fix_sigma_scale(params.template_px),
            gates: Gates {
                prior_factor: DEFAULT_PRIOR_FACTOR,
                min_spread_m: params.inlier_m,
                // ε at ℓ ≤ 64, growing with ℓ above: the residual a lighting
                // change leaves on correct poses scales with the template's
                // footprint (largest measured 6.2 px at ℓ = 32, 6.3 px at
                // ℓ = 64, 22.8 px at ℓ = 256 under 3–6 h; fsw-docs/eval/integrity.md).
                max_reproj_px: params.epsilon_px * footprint_scale(params.template_px),
            },
            verify: Verify::off(params),
            focus: Focus::for_params(params),
            final_gradient_only: true,
            final_pairs: 0,
            search: Search::DEFAULT,
            accuracy: None,
        }
    }

    /// A solution with fewer inliers is treated as a failed GetTransform
    /// (3..=n_corr); this is what keeps a wrong prior from yielding a confident pose.
    pub const fn min_inliers(&self) -> u16 {
        self.min_inliers
    }

    /// Translation spread of the multi-seed mode (prior uncertainty), metres, (0, 5].
    pub const fn seed_t_m(&self) -> f32 {
        self.seed_t_m
    }

    /// Rotation spread of the multi-seed mode, degrees, (0, 45].
    pub const fn seed_r_deg(&self) -> f32 {
        self.seed_r_deg
    }

    /// Work / tick budget.
    pub const fn budget(&self) -> Budget {
        self.budget
    }

    /// Stop with [`FailureCode::RelocNoEvidence`] when this many attempts
    /// since the start have produced no correspondence at all (0 = never): the
    /// fast "no fix" for a frame that does not show the map from the prior.
    pub const fn no_evidence_attempts(&self) -> u32 {
        self.no_evidence_attempts
    }

    /// Stop with [`FailureCode::RelocNoConsensus`] when this many rounds
    /// have ended without a consensus before the first pose update (0 =
    /// only the Reseed cap ends such a run): the fast "no fix" for a frame
    /// whose matches trickle in but never agree on a pose. Rounds of the
    /// multi-seed mode are not counted (each seed is its own guess).
    pub const fn first_fix_rounds(&self) -> u8 {
        self.first_fix_rounds
    }

    /// Before the first pose update, a round whose pairs reach no consensus
    /// of `min_inliers` is solved once more, on the same pairs, with the
    /// depth-uncertainty term of the RANSAC inlier gate scaled by this factor
    /// ([`Solver::set_sigma_scale`](super::Solver::set_sigma_scale)); only if that also fails is the round a
    /// failed one. 1 = no second solve, else (1, [`MAX_FIRST_FIX_SIGMA_SCALE`]]. Rounds after the first
    /// fix, and first rounds that reach the consensus, keep the solver's gate.
    pub const fn first_fix_sigma_scale(&self) -> f32 {
        self.first_fix_sigma_scale
    }

    /// Integrity gates applied to the final estimate before it is reported
    /// as a success.
    pub const fn gates(&self) -> Gates {
        self.gates
    }

    /// Upset tolerance: repeat the final solve, re-check the map product.
    pub const fn verify(&self) -> Verify {
        self.verify
    }

    /// Before the first pose update from a wide prior, re-centre a round's
    /// viewpoints on the translation its pairs agree on.
    pub const fn focus(&self) -> Focus {
        self.focus
    }

    /// The final round (the one after `n_iter − 1` pose updates) accepts only
    /// gradient-domain matches, and Reuse carries only such pairs into it; a
    /// final round so restricted that fails is run again with every variant
    /// (VTSM-RELOC-041). A gray-domain match follows the
    /// shading baked into the map's texture, which a change of the time of
    /// day moves alike across the image, so a final solve on such pairs
    /// inherits that shift; the earlier rounds keep them, where the
    /// consensus needs their yield (`fsw-docs/eval/lighting.md`).
    pub const fn final_gradient_only(&self) -> bool {
        self.final_gradient_only
    }

    /// Correspondences the last round (the one whose success is the
    /// `n_iter`-th pose update) collects before its solve, N_corr..=
    /// [`MAX_CORR`](crate::config::MAX_CORR); 0 (the default) is N_corr like
    /// every round. The final estimate is refined on that round's inliers,
    /// so more of them give (and state) a smaller uncertainty where the
    /// matches are good. The round keeps the attempt cap of every round
    /// (`attempts_per_iter`): when the cap comes first, the round solves on
    /// what it has if that is N_corr or more, so the work bound is
    /// unchanged.
    pub const fn final_pairs(&self) -> u16 {
        self.final_pairs
    }

    /// Revisit (VTSM-RELOC-046): after a pose update, the next round's first
    /// attempts draw, one each, the mask vertices of that update's inliers
    /// that Reuse did not keep, from the round's new viewpoints; the
    /// attempts after them draw as always. A vertex whose template matched
    /// under this light is the likeliest to match again, and measured from a
    /// viewpoint closer to the truth its pair is better. The draws and their
    /// order follow from the attempt index, so every runner gives the same
    /// answer.
    pub const fn revisit(&self) -> bool {
        self.search.revisit
    }

    /// Near ([`Near`]): the share of drawn attempts that look near an
    /// agreeing vertex, and how near.
    pub const fn near(&self) -> Near {
        self.search.near
    }

    /// The accuracy the caller needs, when it stated one: the rounds end as
    /// soon as it is met ([`Accuracy`]); `None` (the default) runs the
    /// `n_iter` pose updates.
    pub const fn accuracy(&self) -> Option<Accuracy> {
        self.accuracy
    }

    /// With the accuracy the caller needs (`None`: run every pose update).
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] for a bound out of range
    /// ([`Accuracy::validate`]).
    pub fn with_accuracy(self, accuracy: Option<Accuracy>) -> Result<Self, FailureCode> {
        if accuracy.is_some_and(|a| !a.validate()) {
            return Err(FailureCode::ConfigParamOutOfRange);
        }
        Ok(Self { accuracy, ..self })
    }

    /// With at least `min_inliers` inliers for an accepted GetTransform.
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] below 3 (above N_corr is refused
    /// where the options meet the parameters).
    pub const fn with_min_inliers(self, min_inliers: u16) -> Result<Self, FailureCode> {
        if min_inliers < 3 {
            return Err(FailureCode::ConfigParamOutOfRange);
        }
        Ok(Self {
            min_inliers,
            ..self
        })
    }

    /// With the multi-seed spread `t_m` metres, `r_deg` degrees.
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] unless `t_m` is in (0, 5] and
    /// `r_deg` in (0, 45].
    pub fn with_seed_spread(self, t_m: f32, r_deg: f32) -> Result<Self, FailureCode> {
        if !(seed_t_ok(t_m) && seed_r_ok(r_deg)) {
            return Err(FailureCode::ConfigParamOutOfRange);
        }
        Ok(Self {
            seed_t_m: t_m,
            seed_r_deg: r_deg,
            ..self
        })
    }

    /// With the work and tick budget `budget` (any values).
    pub const fn with_budget(self, budget: Budget) -> Self {
        Self { budget, ..self }
    }

    /// With the no-evidence cap `attempts` (0 = never).
    pub const fn with_no_evidence_attempts(self, attempts: u32) -> Self {
        Self {
            no_evidence_attempts: attempts,
            ..self
        }
    }

    /// With the first-fix cap `rounds` (0 = the Reseed cap only) and the
    /// first-fix gate scale `sigma_scale`.
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] unless `sigma_scale` is in
    /// [1, [`MAX_FIRST_FIX_SIGMA_SCALE`]].
    pub fn with_first_fix(self, rounds: u8, sigma_scale: f32) -> Result<Self, FailureCode> {
        if !sigma_scale_ok(sigma_scale) {
            return Err(FailureCode::ConfigParamOutOfRange);
        }
        Ok(Self {
            first_fix_rounds: rounds,
            first_fix_sigma_scale: sigma_scale,
            ..self
        })
    }

    /// With the integrity gates `gates`.
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] for a gate out of its range.
    pub fn with_gates(self, gates: Gates) -> Result<Self, FailureCode> {
        if !gates.validate() {
            return Err(FailureCode::ConfigParamOutOfRange);
        }
        Ok(Self { gates, ..self })
    }

    /// With the upset checks `verify`.
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] unless both tolerances are
    /// finite and positive.
    pub fn with_verify(self, verify: Verify) -> Result<Self, FailureCode> {
        if !verify.validate() {
            return Err(FailureCode::ConfigParamOutOfRange);
        }
        Ok(Self { verify, ..self })
    }

    /// With the two upset checks switched on or off, the tolerances kept.
    pub const fn with_upset_checks(self, repeat_solve: bool, recheck_map: bool) -> Self {
        Self {
            verify: Verify {
                repeat_solve,
                recheck_map,
                ..self.verify
            },
            ..self
        }
    }

    /// With Focus `focus`.
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] for a radius or width out of
    /// range or a single vote (votes above N_corr are refused where the
    /// options meet the parameters).
    pub fn with_focus(self, focus: Focus) -> Result<Self, FailureCode> {
        if focus.votes == 1 || !focus.validate_widths() {
            return Err(FailureCode::ConfigParamOutOfRange);
        }
        Ok(Self { focus, ..self })
    }

    /// With the final round restricted to gradient-domain matches or not.
    pub const fn with_final_gradient_only(self, on: bool) -> Self {
        Self {
            final_gradient_only: on,
            ..self
        }
    }

    /// With Revisit on or off ([`Self::revisit`]).
    pub const fn with_revisit(self, on: bool) -> Self {
        Self {
            search: Search {
                revisit: on,
                ..self.search
            },
            ..self
        }
    }

    /// The search mechanisms as one value ([`Search`]).
    pub const fn search(&self) -> Search {
        self.search
    }

    /// With the search mechanisms `search` (Revisit and Near at once).
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] for a Near out of range
    /// ([`Self::with_near`]).
    pub fn with_search(self, search: Search) -> Result<Self, FailureCode> {
        if !search.near.validate() {
            return Err(FailureCode::ConfigParamOutOfRange);
        }
        Ok(Self { search, ..self })
    }

    /// With Near `near` ([`Self::near`]).
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] for a share above 256 or a
    /// radius out of (0, 10] m.
    pub fn with_near(self, near: Near) -> Result<Self, FailureCode> {
        self.with_search(Search {
            near,
            ..self.search
        })
    }

    /// With the last round collecting `final_pairs` correspondences
    /// ([`Self::final_pairs`]; 0 = N_corr).
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] for a count above
    /// [`MAX_CORR`](crate::config::MAX_CORR) (below N_corr is refused where
    /// the options meet the parameters).
    pub const fn with_final_pairs(self, final_pairs: u16) -> Result<Self, FailureCode> {
        if final_pairs as usize > crate::config::MAX_CORR {
            return Err(FailureCode::ConfigParamOutOfRange);
        }
        Ok(Self {
            final_pairs,
            ..self
        })
    }

    /// Every check, those against `params` included.
    pub(super) fn validate(&self, params: &Params) -> Result<(), FailureCode> {
        let ok = (3..=params.n_corr).contains(&self.min_inliers)
            && seed_t_ok(self.seed_t_m)
            && seed_r_ok(self.seed_r_deg)
            && sigma_scale_ok(self.first_fix_sigma_scale)
            && self.gates.validate()
            && self.verify.validate()
            && self.focus.validate(params)
            && (self.final_pairs == 0
                || (params.n_corr..=crate::config::MAX_CORR as u16).contains(&self.final_pairs))
            && self.accuracy.is_none_or(|a| a.validate());
        if ok {
            Ok(())
        } else {
            Err(FailureCode::ConfigParamOutOfRange)
        }
    }
}

/// A multi-seed translation spread in (0, 5] metres.
fn seed_t_ok(t_m: f32) -> bool {
    t_m.is_finite() && t_m > 0.0 && t_m <= 5.0
}

/// A multi-seed rotation spread in (0, 45] degrees.
fn seed_r_ok(r_deg: f32) -> bool {
    r_deg.is_finite() && r_deg > 0.0 && r_deg <= 45.0
}

/// A first-fix gate scale in [1, [`MAX_FIRST_FIX_SIGMA_SCALE`]].
fn sigma_scale_ok(scale: f32) -> bool {
    scale.is_finite() && (1.0..=MAX_FIRST_FIX_SIGMA_SCALE).contains(&scale)
}

/// Default [`Gates::prior_factor`]: the truth lies within the prior's
/// uncertainty by the prior's contract, and the estimate within a few
/// centimetres of the truth; 3× leaves room for a prior that understates its
/// uncertainty up to 3 times (a 0.25–0.50 m prior that states none, against
/// t̃₀ = 0.20 m, still passes) while a pose metres away does not. A prior that
/// states its uncertainty ([`crate::config::PriorUncertainty`]) widens the
/// gate with it.
pub const DEFAULT_PRIOR_FACTOR: f32 = 3.0;
/// Default [`Options::first_fix_rounds`] for a prior no more uncertain than
/// the defaults (t̃₀ ≤ [`crate::config::DEFAULT_T0_M`], r̃₀ ≤
/// [`crate::config::DEFAULT_R0_DEG`]): from such a prior the first round
/// reached the consensus on every simulator suite measured, while frames of
/// another place or depot start with failing rounds
/// (`fsw-docs/eval/integrity.md`). A larger stated uncertainty gets 0 (the
/// Reseed cap only): from a prior 0.46 m off with t̃₀ = 0.5 m the first fix
/// took up to 10 Reseed rounds, the search the paper's Reseed is for.
pub const DEFAULT_FIRST_FIX_ROUNDS: u8 = 1;

/// How much the pixel error of a match under a lighting change grows with the
/// template side `template_px` over that of a 64 px template: ℓ/64, at least 1.
/// The reprojection gate ([`Gates::max_reproj_px`]) and the first-fix gate
/// ([`first_fix_sigma_scale`]) scale with it.
pub fn footprint_scale(template_px: u16) -> f32 {
    (f32::from(template_px) / 64.0).max(1.0)
}

/// Largest [`Options::first_fix_sigma_scale`].
pub const MAX_FIRST_FIX_SIGMA_SCALE: f32 = 16.0;

/// Default [`Options::first_fix_sigma_scale`] for templates of side `template_px`:
/// [`footprint_scale`] (at most [`MAX_FIRST_FIX_SIGMA_SCALE`]), so templates of
/// 64 px and less get no second solve.
///
/// The disparity noise behind each pair's σ ([`MatchPolicy::sigma_d_px`](super::MatchPolicy::sigma_d_px),
/// 0.5 px) is that of a match at ℓ ≤ 64. Under a lighting change a match
/// moves by a fraction of the template's footprint, so in pixels the error
/// grows with ℓ, as the residuals of correct poses do (the reprojection gate,
/// [`Gates::max_reproj_px`], scales by ℓ/64 for that reason). The first
/// round, whose templates are rendered from viewpoints up to (t̃₀, r̃₀) from
/// the truth, carries the largest such errors: at the paper profile
/// (ℓ = 256) after a 6 h change two flagstone views reached 24 and 28 of 100
/// pairs in consensus (30 needed) and failed, while their pairs held enough
/// correct ones to converge (`fsw-docs/eval/first-fix.md`).
pub fn first_fix_sigma_scale(template_px: u16) -> f32 {
    footprint_scale(template_px).min(MAX_FIRST_FIX_SIGMA_SCALE)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::MAX_T0_M;

    /// Every builder refuses a value out of its range with its code and keeps
    /// one in range.
    #[test]
    fn builders_refuse_out_of_range_values() {
        let p = Params::default();
        let o = Options::for_params(&p);
        let bad = Err(FailureCode::ConfigParamOutOfRange);
        assert_eq!(o.with_min_inliers(2), bad);
        assert_eq!(o.with_min_inliers(3).map(|o| o.min_inliers()), Ok(3));
        for (t, r) in [
            (0.0, 1.0),
            (5.5, 1.0),
            (f32::NAN, 1.0),
            (0.5, 0.0),
            (0.5, 46.0),
        ] {
            assert_eq!(o.with_seed_spread(t, r), bad, "({t}, {r})");
        }
        let spread = o.with_seed_spread(0.6, 2.0).unwrap();
        assert_eq!((spread.seed_t_m(), spread.seed_r_deg()), (0.6, 2.0));
        for s in [0.5, MAX_FIRST_FIX_SIGMA_SCALE + 1.0, f32::INFINITY] {
            assert_eq!(o.with_first_fix(1, s), bad, "{s}");
        }
        let ff = o.with_first_fix(2, 1.0).unwrap();
        assert_eq!(
            (ff.first_fix_rounds(), ff.first_fix_sigma_scale()),
            (2, 1.0)
        );
        let gates = Gates {
            prior_factor: 0.5,
            ..Gates::OFF
        };
        assert_eq!(o.with_gates(gates), bad);
        assert_eq!(o.with_gates(Gates::OFF).map(|o| o.gates()), Ok(Gates::OFF));
        let verify = Verify {
            tolerance_m: -1.0,
            ..o.verify()
        };
        assert_eq!(o.with_verify(verify), bad);
        let focus = Focus {
            votes: 1,
            ..o.focus()
        };
        assert_eq!(o.with_focus(focus), bad);
        let focus = Focus {
            t_m: MAX_T0_M * 2.0,
            ..o.focus()
        };
        assert_eq!(o.with_focus(focus), bad);
        assert_eq!(o.with_focus(Focus::OFF).map(|o| o.focus()), Ok(Focus::OFF));
        let budget = Budget {
            max_work_units: 9,
            deadline_tick: 10,
        };
        assert_eq!(o.with_budget(budget).budget(), budget);
        assert_eq!(o.with_no_evidence_attempts(0).no_evidence_attempts(), 0);
        assert!(!o.with_final_gradient_only(false).final_gradient_only());
        let on = o.with_upset_checks(true, true).verify();
        assert!(on.repeat_solve && on.recheck_map);
        assert_eq!(on.tolerance_m, o.verify().tolerance_m);
    }
}
