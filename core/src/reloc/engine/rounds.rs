//! The end of a round (§III-E): a success anneals the bounds, distributes the
//! next viewpoints and reuses inliers; a failure stalls or reseeds until the caps.
//! Multi-seed rounds keep the best seed.

use super::{Phase, Relocalizer, STREAM_RESEED};
use crate::failure::FailureCode;
use crate::reloc::viewpoint::randomize;
use crate::reloc::{Attempt, IterationRecord, Solution, Solver};

impl<A: Attempt, S: Solver> Relocalizer<A, S> {
    pub(super) fn next_seed(&mut self, now: u64) {
        self.pairs.clear();
        self.seed_index = self.seed_index.saturating_add(1);
        if self.seed_index < self.params.seeds {
            self.center = self.seed_pose(self.seed_index);
            self.stats.seeds_tried = self.stats.seeds_tried.saturating_add(1);
            self.start_round();
            return;
        }
        self.seeding = false;
        self.center = self.anchor;
        match self.best_seed.take() {
            Some((sol, pairs, spread)) => {
                self.apply_success(sol, pairs, spread, now);
            }
            // No seed gave a transform: search from the prior as without seeds.
            None => self.start_round(),
        }
    }

    pub(super) fn round_succeeded(&mut self, sol: Solution, now: u64) {
        let pairs = u16::try_from(self.pairs.len()).unwrap_or(u16::MAX);
        let n = self.pairs.len();
        let spread = crate::reloc::integrity::spread_m(
            &self.pairs,
            self.inlier_mask.get(..n).unwrap_or(&[]),
        );
        if self.seeding {
            let better = self
                .best_seed
                .as_ref()
                .is_none_or(|(b, _, _)| sol.inliers > b.inliers);
            if better {
                self.best_seed = Some((sol, pairs, spread));
            }
            self.next_seed(now);
            return;
        }
        self.apply_success(sol, pairs, spread, now);
    }

    pub(super) fn apply_success(&mut self, sol: Solution, pairs: u16, spread_m: f32, now: u64) {
        let update_m = (sol.pose.translation() - self.anchor.translation()).norm();
        // At most n_iter ≤ MAX_ITER successes are recorded, so the push cannot fail.
        let _ = self.quality.history.push(IterationRecord {
            round: self.round,
            inliers: sol.inliers,
            pairs,
            rms_m: sol.rms_m,
            t_m: self.t_m,
            r_rad: self.r_rad,
            update_m,
        });
        self.record_fit(&sol, pairs);
        self.quality.spread_m = spread_m;
        self.center = sol.pose;
        self.stats.successes = self.stats.successes.saturating_add(1);
        self.consecutive_stall = 0;
        self.consecutive_reseed = 0;
        let m = self.params.mechanisms;
        self.candidates.clear();
        if m.distribute {
            self.candidates = sol.candidates;
        }
        if m.anneal {
            self.t_m *= self.params.gamma;
            self.r_rad *= self.params.gamma;
        }
        let enough = self.stats.successes >= u16::from(self.params.n_iter);
        let converged = update_m < self.params.convergence_m;
        // The caller's accuracy met before the last update: its refinement
        // is the final one.
        let known = !(enough || converged) && self.accuracy_met(now);
        if known {
            let saved = u16::from(self.params.n_iter).saturating_sub(self.stats.successes);
            self.stats.rounds_saved = saved;
        }
        if enough || converged || known {
            if !known {
                self.refine_final(now);
            }
            if self.opts.verify.repeat_solve && !self.pairs.is_empty() {
                self.phase = Phase::Verify;
            } else {
                self.accept(now);
            }
        } else {
            self.reuse_inliers(sol.inliers);
            self.start_round();
        }
    }

    /// Reuse: keep the first ⌊fraction · inliers⌋ inlier pairs (in collection
    /// order), fewer than N_corr; drop everything when Reuse is off.
    pub(super) fn reuse_inliers(&mut self, inliers: u16) {
        let keep = if self.params.mechanisms.reuse {
            let k = libm::floorf(self.params.reuse_fraction * f32::from(inliers)) as usize;
            k.min(usize::from(self.params.n_corr).saturating_sub(1))
        } else {
            0
        };
        // Into the final round only gradient-domain pairs (the success just
        // counted makes the next round the final one).
        let gradient_only = self.final_round();
        let revisit = self.opts.search.revisit;
        self.revisit.clear();
        let mut write = 0usize;
        for read in 0..self.pairs.len() {
            if write >= keep && !revisit {
                break;
            }
            let inlier = self.inlier_mask.get(read).copied().unwrap_or(false);
            let Some(p) = self.pairs.get(read).copied().filter(|_| inlier) else {
                continue;
            };
            let usable = !gradient_only || crate::reloc::policy::is_gradient_variant(p.variant);
            if write < keep && usable {
                if let Some(slot) = self.pairs.get_mut(write) {
                    *slot = p;
                }
                write += 1;
            } else if revisit && p.mask_index != crate::pose::MASK_INDEX_UNKNOWN {
                // At most one entry per pair read: fits MAX_CORR.
                let _ = self.revisit.push(p.mask_index);
            }
        }
        self.pairs.truncate(write);
        self.stats.reused = self
            .stats
            .reused
            .saturating_add(u32::try_from(write).unwrap_or(u32::MAX));
    }

    pub(super) fn round_failed(&mut self, code: FailureCode, now: u64) {
        self.pairs.clear();
        self.revisit.clear();
        if self.stats.successes == 0 {
            // A focused round that failed: back to the stated uncertainty.
            self.t_m = self.params.t0_m;
        }
        if self.seeding {
            self.next_seed(now);
            return;
        }
        if self.stats.successes == 0 {
            self.rounds_without_fix = self.rounds_without_fix.saturating_add(1);
            let cap = self.opts.first_fix_rounds;
            if cap > 0 && self.rounds_without_fix >= cap {
                self.finish(Some(FailureCode::RelocNoConsensus), now);
                return;
            }
        }
        let m = self.params.mechanisms;
        if m.stall && self.stats.successes > 0 && self.consecutive_stall < self.params.max_stall {
            self.consecutive_stall += 1;
            self.stats.stalls = self.stats.stalls.saturating_add(1);
            self.center = self.anchor;
            self.start_round();
        } else if m.reseed && self.consecutive_reseed < self.params.max_reseed {
            self.consecutive_reseed += 1;
            self.stats.reseeds = self.stats.reseeds.saturating_add(1);
            let mut rng = self.root.fork(STREAM_RESEED).fork(u64::from(self.round));
            let planar = self.stats.successes == 0;
            self.center = randomize(&self.anchor, self.t_m, self.r_rad, planar, &mut rng);
            self.candidates.clear();
            self.start_round();
        } else {
            let end = if m.reseed {
                FailureCode::RelocReseedCapReached
            } else if m.stall && self.stats.successes > 0 {
                FailureCode::RelocStallCapReached
            } else {
                code
            };
            self.finish(Some(end), now);
        }
    }
}
