//! GetTransform on a round's correspondences, whole or in RANSAC chunks, and the
//! repeated final solve of `Verify::repeat_solve` that checks the estimate.

use super::{pose_is_valid, Phase, Relocalizer, STREAM_SOLVE, STREAM_VERIFY};
use crate::failure::FailureCode;
use crate::reloc::{Attempt, Solution, Solver};

impl<A: Attempt, S: Solver> Relocalizer<A, S> {
    pub(super) fn solve(&mut self, now: u64) {
        self.stats.work_units = self.stats.work_units.saturating_add(1);
        self.stats.solves = self.stats.solves.saturating_add(1);
        let mut rng = self.root.fork(STREAM_SOLVE).fork(u64::from(self.round));
        let n = self.pairs.len();
        self.inlier_mask.iter_mut().for_each(|m| *m = false);
        self.round_chunks = 0;
        match self.solver.start(&self.pairs, rng) {
            Ok(true) => {
                let mask = crate::fmt::present_mut(self.inlier_mask.get_mut(..n));
                let result = self.solver.solve(&self.pairs, &mut rng, mask);
                self.conclude(result, now);
            }
            Ok(false) => self.phase = Phase::Chunks,
            Err(code) => self.conclude(Err(code), now),
        }
    }

    pub(super) fn solve_chunk(&mut self, now: u64) {
        self.stats.work_units = self.stats.work_units.saturating_add(1);
        self.stats.ransac_chunks = self.stats.ransac_chunks.saturating_add(1);
        self.round_chunks = self.round_chunks.saturating_add(1);
        let done = match self
            .solver
            .run_chunk(&self.pairs, crate::reloc::RANSAC_CHUNK)
        {
            Ok(done) => done || self.round_chunks >= Self::max_chunks(&self.params),
            Err(code) => return self.conclude(Err(code), now),
        };
        if done {
            let n = self.pairs.len();
            let mask = crate::fmt::present_mut(self.inlier_mask.get_mut(..n));
            let result = self.solver.finish(&self.pairs, mask);
            self.conclude(result, now);
        }
    }

    pub(super) fn conclude(&mut self, result: Result<Solution, FailureCode>, now: u64) {
        let n = self.pairs.len();
        match result {
            Ok(sol) => {
                self.stats.ransac_iterations = self
                    .stats
                    .ransac_iterations
                    .saturating_add(u32::from(sol.iterations));
                if sol.inliers >= self.opts.min_inliers
                    && usize::from(sol.inliers) <= n
                    && pose_is_valid(&sol.pose)
                {
                    self.round_succeeded(sol, now);
                } else {
                    let code = FailureCode::PoseRansacNoConsensus;
                    self.log.record(code, now, u32::from(sol.inliers));
                    if !self.widen_first_fix() {
                        self.round_failed(code, now);
                    }
                }
            }
            Err(code) => {
                self.log.record(code, now, self.round);
                self.round_failed(code, now);
            }
        }
    }

    /// Before the first fix (not while seeding), once per round: solve the
    /// same pairs again with the gate's σ term widened by
    /// [`Options::first_fix_sigma_scale`] instead of failing the round.
    /// Whether that solve was scheduled.
    pub(super) fn widen_first_fix(&mut self) -> bool {
        let scale = self.opts.first_fix_sigma_scale;
        if self.widened || self.seeding || self.stats.successes > 0 || scale <= 1.0 {
            return false;
        }
        self.widened = true;
        self.stats.widened_solves = self.stats.widened_solves.saturating_add(1);
        self.solver.set_sigma_scale(scale);
        self.phase = Phase::Solve;
        true
    }

    /// Verify::repeat_solve, first unit: GetTransform again on the pairs of
    /// the final solve, from a second random stream.
    pub(super) fn verify_start(&mut self, now: u64) {
        self.stats.work_units = self.stats.work_units.saturating_add(1);
        self.stats.verify_units = self.stats.verify_units.saturating_add(1);
        let mut rng = self.root.fork(STREAM_VERIFY).fork(u64::from(self.round));
        let n = self.pairs.len();
        self.verify_mask.iter_mut().for_each(|m| *m = false);
        self.round_chunks = 0;
        match self.solver.start(&self.pairs, rng) {
            Ok(true) => {
                let mask = self.verify_mask.get_mut(..n).unwrap_or(&mut []);
                let result = self.solver.solve(&self.pairs, &mut rng, mask);
                self.verify_conclude(result, now);
            }
            Ok(false) => self.phase = Phase::VerifyChunks,
            Err(code) => self.verify_conclude(Err(code), now),
        }
    }

    pub(super) fn verify_chunk(&mut self, now: u64) {
        self.stats.work_units = self.stats.work_units.saturating_add(1);
        self.stats.verify_units = self.stats.verify_units.saturating_add(1);
        self.round_chunks = self.round_chunks.saturating_add(1);
        let done = match self
            .solver
            .run_chunk(&self.pairs, crate::reloc::RANSAC_CHUNK)
        {
            Ok(done) => done || self.round_chunks >= Self::max_chunks(&self.params),
            Err(code) => return self.verify_conclude(Err(code), now),
        };
        if done {
            let n = self.pairs.len();
            let mask = self.verify_mask.get_mut(..n).unwrap_or(&mut []);
            let result = self.solver.finish(&self.pairs, mask);
            self.verify_conclude(result, now);
        }
    }

    /// Compare the repeated solve, refined the same way as the final
    /// estimate, with it: a disagreement beyond the tolerances (or a repeat
    /// that finds no acceptable solution) means one of the two computations
    /// was upset, and neither is trusted.
    pub(super) fn verify_conclude(&mut self, result: Result<Solution, FailureCode>, now: u64) {
        let n = self.pairs.len();
        let again = match result {
            Ok(sol) if sol.inliers >= self.opts.min_inliers && pose_is_valid(&sol.pose) => {
                let mask = self.verify_mask.get(..n).unwrap_or(&[]);
                match self.solver.refine(&self.pairs, mask, &sol.pose) {
                    Some(Ok(r)) if r.stats.accepted && pose_is_valid(&r.pose) => Some(r.pose),
                    _ => Some(sol.pose),
                }
            }
            Ok(sol) => {
                self.log.record(
                    FailureCode::PoseRansacNoConsensus,
                    now,
                    u32::from(sol.inliers),
                );
                None
            }
            Err(code) => {
                self.log.record(code, now, self.round);
                None
            }
        };
        let v = self.opts.verify;
        let agree = again.is_some_and(|p| {
            let (dt, dr) = crate::reloc::integrity::distance_to(&self.anchor, &p);
            self.quality.verify_diff = Some((dt, dr));
            dt <= v.tolerance_m && dr <= v.tolerance_rad
        });
        if agree {
            self.accept(now);
        } else {
            self.finish(Some(FailureCode::RelocVerifyDisagree), now);
        }
    }
}
