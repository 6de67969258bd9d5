//! GetTransform on a round's correspondences, whole or in RANSAC chunks, and the
//! repeated final solve of `Verify::repeat_solve` that checks the estimate.

use super::{pose_is_valid, Phase, Relocalizer, STREAM_SOLVE, STREAM_VERIFY};
use crate::failure::FailureCode;
use crate::reloc::{Attempt, Solution, Solver};

/// Which GetTransform a solve unit belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Pass {
    /// The round's, on the pairs collected for it.
    Round,
    /// The repeated final solve of `Verify::repeat_solve`, on the pairs of
    /// the final solve, from a second random stream.
    Verify,
}

impl<A: Attempt, S: Solver> Relocalizer<A, S> {
    /// The first unit of a GetTransform of the current pairs (of `pass`):
    /// the whole solve, or its start when the solver works in chunks.
    pub(super) fn solve_start(&mut self, pass: Pass, now: u64) {
        self.stats.work_units = self.stats.work_units.saturating_add(1);
        let stream = match pass {
            Pass::Round => {
                self.stats.solves = self.stats.solves.saturating_add(1);
                STREAM_SOLVE
            }
            Pass::Verify => {
                self.stats.verify_units = self.stats.verify_units.saturating_add(1);
                STREAM_VERIFY
            }
        };
        let mut rng = self.root.fork(stream).fork(u64::from(self.round));
        let n = self.pairs.len();
        let mask = match pass {
            Pass::Round => &mut self.inlier_mask,
            Pass::Verify => &mut self.verify_mask,
        };
        mask.iter_mut().for_each(|m| *m = false);
        self.round_chunks = 0;
        match self.solver.start(&self.pairs, rng) {
            Ok(true) => {
                let mask = crate::fmt::present_mut(mask.get_mut(..n));
                let result = self.solver.solve(&self.pairs, &mut rng, mask);
                self.solve_end(pass, result, now);
            }
            Ok(false) => {
                self.phase = match pass {
                    Pass::Round => Phase::Chunks,
                    Pass::Verify => Phase::VerifyChunks,
                }
            }
            Err(code) => self.solve_end(pass, Err(code), now),
        }
    }

    /// One chunk of [`crate::reloc::RANSAC_CHUNK`] hypotheses of a chunked
    /// GetTransform (of `pass`), and its end after the last chunk.
    pub(super) fn solve_chunk(&mut self, pass: Pass, now: u64) {
        self.stats.work_units = self.stats.work_units.saturating_add(1);
        match pass {
            Pass::Round => {
                self.stats.ransac_chunks = self.stats.ransac_chunks.saturating_add(1);
            }
            Pass::Verify => {
                self.stats.verify_units = self.stats.verify_units.saturating_add(1);
            }
        }
        self.round_chunks = self.round_chunks.saturating_add(1);
        let done = match self
            .solver
            .run_chunk(&self.pairs, crate::reloc::RANSAC_CHUNK)
        {
            Ok(done) => done || self.round_chunks >= Self::max_chunks(&self.params),
            Err(code) => return self.solve_end(pass, Err(code), now),
        };
        if done {
            let n = self.pairs.len();
            let mask = match pass {
                Pass::Round => &mut self.inlier_mask,
                Pass::Verify => &mut self.verify_mask,
            };
            let mask = crate::fmt::present_mut(mask.get_mut(..n));
            let result = self.solver.finish(&self.pairs, mask);
            self.solve_end(pass, result, now);
        }
    }

    /// The result of a GetTransform of `pass`, to the end that judges it.
    fn solve_end(&mut self, pass: Pass, result: Result<Solution, FailureCode>, now: u64) {
        match pass {
            Pass::Round => self.conclude(result, now),
            Pass::Verify => self.verify_conclude(result, now),
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
