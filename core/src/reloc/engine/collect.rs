//! Collecting correspondences: one attempt after another from viewpoints around
//! the round's centre (RandomizeViewpoint, SamplePoint, Synthesize, Match, Valid,
//! Stereo in the pipeline), Focus on agreeing pairs, and the start of each round.

use super::{Phase, Relocalizer};
use crate::failure::FailureCode;
use crate::geom::{Pose, Vec3};
use crate::reloc::{Attempt, Correspondence, Solver, Stage, StageStep};

impl<A: Attempt, S: Solver> Relocalizer<A, S> {
    /// The first stage of a new attempt: its viewpoint and random stream,
    /// counted as one work unit.
    pub(super) fn begin_attempt(&mut self, now: u64) -> Stage {
        let (ctx, mut rng) = self.draw_attempt(self.stats.attempts);
        self.count_attempt();
        let step = self.attempt.begin(&ctx, &mut rng, &mut self.stats.pipeline);
        self.attempt_stage_done(step, now)
    }

    /// Count the attempt that begins now (its own work unit), whoever runs it.
    pub(super) fn count_attempt(&mut self) {
        self.stats.attempts = self.stats.attempts.saturating_add(1);
        self.stats.work_units = self.stats.work_units.saturating_add(1);
        self.round_attempts = self.round_attempts.saturating_add(1);
    }

    /// After a stage of an attempt: wait for the next stage, or take the
    /// attempt's result.
    pub(super) fn attempt_stage_done(&mut self, step: StageStep, now: u64) -> Stage {
        match step.ended {
            None => self.phase = Phase::Attempt,
            Some(result) => {
                self.phase = Phase::Collect;
                self.end_attempt(result, now);
            }
        }
        step.stage
    }

    pub(super) fn end_attempt(&mut self, result: Result<Correspondence, FailureCode>, now: u64) {
        // The attempt was counted when it began.
        let index = self.stats.attempts.saturating_sub(1);
        match result {
            Ok(c) => {
                if self.pairs.push(c).is_ok() {
                    self.stats.correspondences = self.stats.correspondences.saturating_add(1);
                    self.focus();
                }
            }
            // The frames cannot be read: no later attempt can match either.
            Err(FailureCode::RelocFrameReadFailed) => {
                self.finish(Some(FailureCode::RelocFrameReadFailed), now);
                return;
            }
            Err(code) => self.log.record(code, now, index),
        }
        let cap = self.opts.no_evidence_attempts;
        if cap > 0 && self.stats.correspondences == 0 && self.stats.attempts >= cap {
            self.finish(Some(FailureCode::RelocNoEvidence), now);
        } else if self.pairs.len() >= self.round_pairs() {
            self.phase = Phase::Solve;
        } else if self.round_attempts >= self.params.attempts_per_iter
            && self.pairs.len() >= usize::from(self.params.n_corr)
        {
            // A last round that could not collect its larger count solves
            // on what it has, as any round would.
            self.phase = Phase::Solve;
        } else if self.round_attempts >= self.params.attempts_per_iter {
            self.log
                .record(FailureCode::RelocSampleCapReached, now, self.round);
            self.round_failed(FailureCode::RelocSampleCapReached, now);
        }
    }

    /// [`crate::reloc::Focus`], after a pair joined the round: O(pairs) work. A
    /// focused round runs at `f.t_m` (until a failed round restores t̃₀), so
    /// the width check also keeps a round from focusing twice.
    pub(super) fn focus(&mut self) {
        let f = self.opts.focus;
        if f.votes == 0 || self.seeding || self.stats.successes > 0 || self.t_m <= f.t_m {
            return;
        }
        let r = self.anchor.rotation();
        let hypothesis = |c: &Correspondence| c.world - r * c.cam;
        let Some(newest) = self.pairs.last().map(hypothesis) else {
            return;
        };
        let (n, sum) = self
            .pairs
            .iter()
            .map(hypothesis)
            .filter(|h| (h - newest).norm() <= f.radius_m)
            .fold((0u16, Vec3::zeros()), |(n, s), h| {
                (n.saturating_add(1), s + h)
            });
        if n < u16::from(f.votes) {
            return;
        }
        let mean = sum / f32::from(n);
        let within = (mean - self.prior.translation()).norm() <= self.params.t0_m + f.radius_m;
        if !(within && mean.iter().all(|v| v.is_finite())) {
            return;
        }
        self.center = Pose::new(r, mean);
        self.t_m = f.t_m;
        self.stats.focused_rounds = self.stats.focused_rounds.saturating_add(1);
    }

    /// Whether the round under way is the final one and keeps only
    /// gradient-domain pairs ([`Options::final_gradient_only`]): see
    /// [`Self::last_round`].
    pub(super) fn final_round(&self) -> bool {
        self.opts.final_gradient_only && self.last_round()
    }

    /// Whether the round under way is the last one: a success now would be
    /// the `n_iter`-th and no round has failed since the last update (every
    /// failed round that goes on counts a Stall or a Reseed, and an update
    /// clears both; so a restricted last round that fails runs again as any
    /// round). Never while seeding.
    pub(super) fn last_round(&self) -> bool {
        !self.seeding
            && self.stats.successes > 0
            && self.consecutive_stall == 0
            && self.consecutive_reseed == 0
            && self.stats.successes.saturating_add(1) >= u16::from(self.params.n_iter)
    }

    /// Correspondences the round under way collects before its solve:
    /// N_corr, or [`Options::final_pairs`](crate::reloc::Options::final_pairs) in the last round.
    pub(super) fn round_pairs(&self) -> usize {
        let n = usize::from(self.params.n_corr);
        if self.opts.final_pairs > 0 && self.last_round() {
            n.max(usize::from(self.opts.final_pairs))
        } else {
            n
        }
    }

    pub(super) fn start_round(&mut self) {
        if self.widened {
            self.widened = false;
            self.solver.set_sigma_scale(1.0);
        }
        self.round = self.round.saturating_add(1);
        self.stats.rounds = self.stats.rounds.saturating_add(1);
        if self.final_round() {
            self.stats.gradient_rounds = self.stats.gradient_rounds.saturating_add(1);
        }
        self.round_attempts = 0;
        self.round_kept = u16::try_from(self.pairs.len()).unwrap_or(u16::MAX);
        self.phase = Phase::Collect;
    }
}
