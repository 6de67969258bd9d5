//! Attempts as tickets: the correspondence attempts of a round handed out
//! ahead of time, run by other workers (the host's threads, a flight
//! integrator's tasks) each with its own pipeline and workspace, and taken
//! back in attempt order.
//!
//! An attempt depends only on the round's state (centre, bounds, Distribute
//! candidates, the final-round restriction) and its global index, whose
//! random stream is forked from the seed by that index. [`Relocalizer::ticket`]
//! gives the attempt of an index under the state of now; [`Relocalizer::commit`]
//! takes a worked ticket back exactly as [`Relocalizer::step`] would have done
//! the attempt itself, if it is the next attempt and the state it was drawn
//! under still holds (the same round, no Focus since). Otherwise it is stale:
//! its work is dropped and the attempt is handed out again under the new
//! state. So the outcome — pose, failure code, quality, every counter and the
//! failure log — is bit-identical to one worker's, whatever the number of
//! workers and the order in which they finish; only discarded work differs.

use super::{Phase, Relocalizer, STREAM_ATTEMPT};
use crate::failure::FailureCode;
use crate::reloc::viewpoint::{pick_candidate, randomize};
use crate::reloc::{Attempt, AttemptContext, Correspondence, PipelineStats, Solver};
use crate::rng::Rng;

/// The state an attempt was drawn under: the round (every round start
/// changes it) and the Focus count (a Focus re-centres the round).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Epoch {
    rounds: u32,
    focused: u16,
}

/// One attempt handed out by [`Relocalizer::ticket`]: what a worker needs to
/// run it on its own pipeline ([`work_ticket`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ticket {
    /// The attempt's viewpoint, bounds and index (`ctx.index`).
    pub ctx: AttemptContext,
    /// The attempt's random stream, after the draws of its viewpoint.
    rng: Rng,
    epoch: Epoch,
}

impl Ticket {
    /// The attempt's global index.
    pub fn index(&self) -> u32 {
        self.ctx.index
    }
}

/// A ticket's attempt, run: its result and the pipeline work it did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Worked {
    /// The ticket that was run.
    pub ticket: Ticket,
    /// The correspondence, or the code of the step that rejected it.
    pub result: Result<Correspondence, FailureCode>,
    /// The pipeline work of this attempt alone.
    pub stats: PipelineStats,
}

/// What [`Relocalizer::commit`] did with a worked ticket.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Commit {
    /// Taken as the next attempt. `keep`: the tickets handed out after it
    /// are still valid (same round, no Focus, still collecting); when false
    /// they are stale and the caller drops them.
    Taken {
        /// Whether later tickets still hold.
        keep: bool,
    },
    /// Not the next attempt, drawn under a state that no longer holds, or
    /// the engine is not collecting: its work is dropped, nothing changed.
    Stale,
    /// The work budget or the deadline ran out before it could be taken:
    /// the run ended with its anytime result, as [`Relocalizer::step`] ends it.
    Ended,
}

/// Run `ticket` on a worker's own pipeline `attempt` (built with
/// [`crate::reloc::Engine::worker`] or any [`Attempt`] equal to the engine's):
/// the whole attempt ([`Attempt::attempt`]), its pipeline work counted apart.
pub fn work_ticket<A: Attempt>(attempt: &mut A, ticket: &Ticket) -> Worked {
    let mut rng = ticket.rng;
    let mut stats = PipelineStats::default();
    let result = attempt.attempt(&ticket.ctx, &mut rng, &mut stats);
    Worked {
        ticket: *ticket,
        result,
        stats,
    }
}

impl<A: Attempt, S: Solver> Relocalizer<A, S> {
    /// The state attempts are drawn under now.
    pub(super) fn epoch(&self) -> Epoch {
        Epoch {
            rounds: self.stats.rounds,
            focused: self.stats.focused_rounds,
        }
    }

    /// The context and random stream of attempt `index` under the state of
    /// now: the one draw both [`Self::step`] and [`Self::ticket`] make.
    pub(super) fn draw_attempt(&self, index: u32) -> (AttemptContext, Rng) {
        let mut rng = self.root.fork(STREAM_ATTEMPT).fork(u64::from(index));
        let planar = self.stats.successes == 0;
        let center = if self.params.mechanisms.distribute && !self.seeding {
            pick_candidate(&self.candidates, &mut rng).unwrap_or(self.center)
        } else {
            self.center
        };
        let world_from_viewpoint = randomize(&center, self.t_m, self.r_rad, planar, &mut rng);
        let revisit = self.revisit_vertex(index);
        let near = if revisit.is_none() {
            self.near_vertex(&mut rng)
        } else {
            None
        };
        let ctx = AttemptContext {
            world_from_viewpoint,
            t_m: self.t_m,
            r_rad: self.r_rad,
            gradient_only: self.final_round(),
            revisit,
            near,
            near_radius_m: self.opts.search.near.radius_m,
            index,
            round: self.round,
        };
        (ctx, rng)
    }

    /// Revisit (VTSM-RELOC-046): attempt `index`'s vertex when it is among
    /// the round's first attempts, one per vertex of the revisit list in its
    /// order; `None` otherwise or with [`Options::revisit`](crate::reloc::Options::revisit) off.
    fn revisit_vertex(&self, index: u32) -> Option<u32> {
        if !self.opts.search.revisit {
            return None;
        }
        let round_start = self.stats.attempts.saturating_sub(self.round_attempts);
        let k = index.checked_sub(round_start)?;
        self.revisit.get(usize::try_from(k).ok()?).copied()
    }

    /// Near (VTSM-RELOC-047): for a drawn attempt of a round after a pose
    /// update, the last round excepted, with probability `share_256`/256 an
    /// agreeing vertex to draw near, picked uniformly from the round's
    /// revisit list and the pairs Reuse kept (both fixed for the round, so a
    /// ticket draws the same). Two draws from the attempt's stream when Near
    /// applies and there is evidence, none otherwise.
    fn near_vertex(&self, rng: &mut Rng) -> Option<u32> {
        let share = u32::from(self.opts.search.near.share_256);
        if share == 0 || self.seeding || self.stats.successes == 0 || self.last_round() {
            return None;
        }
        let kept = self
            .pairs
            .get(..usize::from(self.round_kept))
            .unwrap_or(&[]);
        let known = |c: &&Correspondence| c.mask_index != crate::pose::MASK_INDEX_UNKNOWN;
        // Counted and indexed with saturating steps: `Iterator::count` and
        // `nth` would bring overflow-checked arithmetic (a panic path).
        let kept_n = kept
            .iter()
            .filter(known)
            .fold(0usize, |n, _| n.saturating_add(1));
        let total = u32::try_from(self.revisit.len().saturating_add(kept_n)).ok()?;
        if total == 0 || rng.below(256) >= share {
            return None;
        }
        let j = usize::try_from(rng.below(total)).ok()?;
        match self.revisit.get(j) {
            Some(&k) => Some(k),
            None => {
                let mut skip = j.saturating_sub(self.revisit.len());
                kept.iter()
                    .filter(known)
                    .find(|_| {
                        let hit = skip == 0;
                        skip = skip.saturating_sub(1);
                        hit
                    })
                    .map(|c| c.mask_index)
            }
        }
    }

    /// Whether the engine is between attempts of a round, so that its next
    /// work is an attempt that [`Self::ticket`] can hand out.
    pub fn collecting(&self) -> bool {
        self.done.is_none() && self.phase == Phase::Collect
    }

    /// Attempt `index` under the state of now, to run on another worker.
    /// `None` unless the engine is [collecting](Self::collecting), `index`
    /// is the next attempt or one after it, and the round's attempt cap and
    /// the work budget leave room for it (with every attempt before it).
    pub fn ticket(&self, index: u32) -> Option<Ticket> {
        if !self.collecting() {
            return None;
        }
        let ahead = index.checked_sub(self.stats.attempts)?;
        let round_room = self
            .params
            .attempts_per_iter
            .saturating_sub(self.round_attempts);
        let unit_cap = self.opts.budget.max_work_units.min(self.max_units);
        let unit_room = unit_cap.saturating_sub(self.stats.work_units);
        if ahead >= round_room || ahead >= unit_room {
            return None;
        }
        let (ctx, rng) = self.draw_attempt(index);
        Some(Ticket {
            ctx,
            rng,
            epoch: self.epoch(),
        })
    }

    /// Take `worked` back at caller time `now` as the next attempt, exactly
    /// as [`Self::step`] would have run it: counted, its pipeline work added,
    /// its correspondence collected (Focus, the round's end) or its code
    /// logged. See [`Commit`] for what comes back.
    pub fn commit(&mut self, worked: &Worked, now: u64) -> Commit {
        let t = &worked.ticket;
        if !self.collecting() || t.index() != self.stats.attempts || t.epoch != self.epoch() {
            return Commit::Stale;
        }
        let unit_cap = self.opts.budget.max_work_units.min(self.max_units);
        if self.stats.work_units >= unit_cap || now >= self.opts.budget.deadline_tick {
            self.finish_budget(now);
            return Commit::Ended;
        }
        self.count_attempt();
        self.stats.pipeline.add(&worked.stats);
        self.end_attempt(worked.result, now);
        Commit::Taken {
            keep: self.collecting() && t.epoch == self.epoch(),
        }
    }
}

impl<'a, F: crate::frame::FrameSource + Clone> crate::reloc::Engine<'a, '_, F> {
    /// A worker's pipeline for this engine's tickets, over its own workspace
    /// `ws` ([`crate::reloc::Pipeline::twin`]): carve it with the engine's
    /// [`crate::reloc::Setup::sizes`].
    ///
    /// # Errors
    /// [`FailureCode::ConfigCapacityTooSmall`] if `ws` is smaller than the
    /// engine's workspace.
    pub fn worker<'v>(
        &self,
        ws: crate::reloc::Workspace<'v>,
    ) -> Result<crate::reloc::Pipeline<'a, 'v, F>, FailureCode> {
        self.attempt_ref().twin(ws)
    }
}
