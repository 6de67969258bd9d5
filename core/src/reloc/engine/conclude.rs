//! The end of a run: the refined final estimate, the integrity gates and map
//! re-check, and the [`Outcome`] — also the anytime one when a budget runs out.

use super::{pose_is_valid, Relocalizer};
use crate::failure::FailureCode;
use crate::reloc::{Attempt, Outcome, Solution, Solver};

impl<A: Attempt, S: Solver> Relocalizer<A, S> {
    /// The final estimate, in the unit that concludes the last solve: the
    /// solver refines the anchor on the last inlier set (pairs and mask are
    /// still those of that solve) and gives its covariance. A refinement that
    /// fails is logged and the RANSAC pose stays. (A multi-seed winner that
    /// ends the run has no pairs left: nothing to refine.)
    pub(super) fn refine_final(&mut self, now: u64) {
        match self.refine_anchor() {
            Some(Ok(r)) => self.keep_refinement(&r, r.stats.accepted),
            Some(Err(code)) => self.log.record(code, now, self.round),
            None => {}
        }
    }

    /// The anchor refined on this solve's inliers (pairs and mask are those
    /// of the last solve); `None` without pairs or without a refinement.
    fn refine_anchor(&mut self) -> Option<Result<crate::pose::Refined, FailureCode>> {
        let n = self.pairs.len();
        if n == 0 {
            return None;
        }
        let mask = crate::fmt::present(self.inlier_mask.get(..n));
        self.solver.refine(&self.pairs, mask, &self.anchor)
    }

    /// Make `r` the final refinement: its counters, covariance and
    /// reprojection RMS, and its pose as the anchor when `use_pose` and valid.
    fn keep_refinement(&mut self, r: &crate::pose::Refined, use_pose: bool) {
        self.stats.refine = r.stats;
        self.quality.covariance = Some(r.covariance);
        self.quality.reproj_rms_px = r.rms_px;
        if use_pose && pose_is_valid(&r.pose) {
            self.anchor = r.pose;
        }
    }

    /// Whether the estimate after this pose update meets the caller's
    /// [`Accuracy`](crate::reloc::Accuracy): the anchor refined on this
    /// solve's inliers, as [`Self::refine_final`] does, states a 1-σ
    /// uncertainty within it. Then that refinement is kept as the final one
    /// (covariance, reprojection RMS, refined pose); otherwise nothing of it
    /// is kept and the rounds go on as without an accuracy. No accuracy, or
    /// no pairs: false, without a refinement.
    pub(super) fn accuracy_met(&mut self, now: u64) -> bool {
        let Some(acc) = self.opts.accuracy else {
            return false;
        };
        if self.pairs.is_empty() {
            return false;
        }
        self.stats.accuracy_checks = self.stats.accuracy_checks.saturating_add(1);
        match self.refine_anchor() {
            Some(Ok(r)) if r.stats.accepted && acc.met_by(&r.covariance) => {
                self.keep_refinement(&r, true);
                true
            }
            Some(Err(code)) => {
                self.log.record(code, now, self.round);
                false
            }
            _ => false,
        }
    }

    /// The last unit of a run whose search succeeded: the integrity gates,
    /// then the map re-check, then success.
    pub(super) fn accept(&mut self, now: u64) {
        let (t, r) = if self.params.seeds > 0 {
            (
                self.params.t0_m.max(self.opts.seed_t_m),
                self.params.r0_deg.max(self.opts.seed_r_deg),
            )
        } else {
            (self.params.t0_m, self.params.r0_deg)
        };
        let refined = self.quality.covariance.is_some();
        let ev = crate::reloc::integrity::Evidence {
            pose: self.anchor,
            prior: self.prior,
            prior_t_m: t,
            prior_r_rad: r.to_radians(),
            spread_m: self.quality.spread_m,
            reproj_px: refined.then_some(self.quality.reproj_rms_px),
        };
        let mut code = crate::reloc::integrity::check(&self.opts.gates, &ev);
        if code.is_none() && self.opts.verify.recheck_map {
            code = self.attempt.recheck().err();
        }
        self.finish(code, now);
    }

    /// Make `sol` (fitted to `pairs` correspondences) the current estimate.
    pub(super) fn record_fit(&mut self, sol: &Solution, pairs: u16) {
        self.quality.inliers = sol.inliers;
        self.quality.rms_m = sol.rms_m;
        self.quality.inlier_ratio = if pairs > 0 {
            f32::from(sol.inliers) / f32::from(pairs)
        } else {
            0.0
        };
        self.anchor = sol.pose;
    }

    pub(super) fn finish_budget(&mut self, now: u64) -> &Outcome {
        // Anytime: the best seed so far beats the prior if seeding was cut short.
        if self.seeding {
            if let Some((sol, pairs, spread)) = self.best_seed.take() {
                self.record_fit(&sol, pairs);
                self.quality.spread_m = spread;
            }
        }
        self.finish(Some(FailureCode::RelocBudgetExhausted), now)
    }

    pub(super) fn finish(&mut self, failure: Option<FailureCode>, now: u64) -> &Outcome {
        if let Some(code) = failure {
            self.log.record(code, now, self.stats.work_units);
        }
        self.done.insert(Outcome {
            pose: self.anchor,
            failure,
            quality: self.quality.clone(),
            stats: self.stats,
            log: self.log.clone(),
        })
    }
}
