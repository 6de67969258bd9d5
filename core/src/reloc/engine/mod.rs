//! The [`Relocalizer`] state machine: rounds of correspondence collection and
//! GetTransform, with the §III-E mechanisms, one work unit per [`Relocalizer::step`]
//! (one [`Stage`] per [`Relocalizer::step_stage`]).
//!
//! This file holds the state, the constructors and the stepping entry points;
//! each kind of work unit has its own file: `collect` (an attempt, Focus, the
//! start of a round), `solve` (GetTransform, whole or in chunks, and its
//! repetition for `Verify::repeat_solve`), `rounds` (what a round's success
//! or failure does: Anneal, Distribute, Reuse, Stall, Reseed, multi-seed) and
//! `conclude` (the refined final estimate, the integrity gates, the outcome).

use super::viewpoint::randomize;
use super::{
    Attempt, Candidate, Correspondence, Options, Outcome, Quality, Solution, Solver, Stage, Stats,
    MAX_ATTEMPT_STAGES,
};
use crate::config::{Params, MAX_CORR, MAX_POSE_CANDIDATES};
use crate::failure::{FailureCode, FailureLog};
use crate::geom::Pose;
use crate::rng::Rng;

/// Stream of per-attempt generators (forked by global attempt index).
const STREAM_ATTEMPT: u64 = 1;
/// Stream of per-round GetTransform generators (forked by round index).
const STREAM_SOLVE: u64 = 2;
/// Stream of Reseed perturbations (forked by round index).
const STREAM_RESEED: u64 = 3;
/// Stream of multi-seed poses (forked by seed index).
const STREAM_SEED: u64 = 4;
/// Stream of the repeated final solve of `Verify::repeat_solve` (forked by round).
const STREAM_VERIFY: u64 = 5;

mod collect;
mod conclude;
mod rounds;
mod solve;
mod tickets;
use solve::Pass;
pub use tickets::{work_ticket, Commit, Epoch, Ticket, Worked};
#[cfg(test)]
mod tests;
#[cfg(feature = "upset-injection")]
mod upset;
#[cfg(feature = "upset-injection")]
pub use upset::UpsetRegion;

/// What [`Relocalizer::step`] reports.
///
/// `Done` borrows the outcome kept by the engine (no copy of it per call);
/// clone it, or read it later with [`Relocalizer::outcome`].
#[derive(Clone, Copy, Debug)]
pub enum StepResult<'o> {
    /// More work remains; call `step` again.
    Running,
    /// Finished; the outcome is final and further calls return it again.
    Done(&'o Outcome),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    Collect,
    /// A staged attempt is under way: its next stage is due.
    Attempt,
    Solve,
    /// A chunked solve is under way.
    Chunks,
    /// The repeated final solve (`Verify::repeat_solve`) starts.
    Verify,
    /// The repeated final solve is under way in chunks.
    VerifyChunks,
}

/// The relocalization engine. Generic over the per-attempt pipeline `A` and
/// the GetTransform solver `S`; every buffer is a fixed-size field.
pub struct Relocalizer<A, S> {
    attempt: A,
    solver: S,
    params: Params,
    opts: Options,
    root: Rng,
    prior: Pose,
    /// Last successful estimate (the prior before any success).
    anchor: Pose,
    /// Centre of the viewpoints of the current round (anchor, or reseeded).
    center: Pose,
    t_m: f32,
    r_rad: f32,
    phase: Phase,
    pairs: heapless::Vec<Correspondence, MAX_CORR>,
    inlier_mask: [bool; MAX_CORR],
    /// Mask vertices of the last update's inliers that Reuse did not keep:
    /// the first attempts of the next round ([`Options::revisit`]).
    revisit: heapless::Vec<u32, MAX_CORR>,
    /// Pairs Reuse kept at the front of `pairs` when the round started:
    /// with `revisit`, the agreeing vertices Near draws around.
    round_kept: u16,
    /// Inliers of the repeated final solve.
    verify_mask: [bool; MAX_CORR],
    candidates: heapless::Vec<Candidate, MAX_POSE_CANDIDATES>,
    round: u32,
    round_attempts: u32,
    round_chunks: u32,
    consecutive_stall: u8,
    consecutive_reseed: u8,
    /// Rounds ended without a consensus before the first pose update (after
    /// the multi-seed mode, if any).
    rounds_without_fix: u8,
    /// Whether this round's pairs were solved again with the first-fix gate
    /// ([`Options::first_fix_sigma_scale`]).
    widened: bool,
    /// Next seed to evaluate while `seeding`.
    seed_index: u16,
    seeding: bool,
    /// Best seed so far: its solution, pairs given to it, inlier spread.
    best_seed: Option<(Solution, u16, f32)>,
    max_units: u32,
    quality: Quality,
    stats: Stats,
    log: FailureLog,
    done: Option<Outcome>,
}

pub(super) fn pose_is_valid(p: &Pose) -> bool {
    let q = p.q();
    let n = libm::sqrtf(q.iter().map(|v| v * v).sum::<f32>());
    p.is_finite() && (n - 1.0).abs() <= 1.0e-3
}

impl<A: Attempt, S: Solver> Relocalizer<A, S> {
    /// A relocalizer ready to run from `prior` (`world_from_left`), over any
    /// pipeline and solver: the tests' fakes. Every other caller builds the
    /// engine with [`super::Setup::build`].
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] for invalid `params` or `opts`;
    /// [`FailureCode::RelocPriorInvalid`] for a non-finite or non-unit prior.
    #[cfg(test)]
    pub(crate) fn new(
        attempt: A,
        solver: S,
        params: &Params,
        opts: &Options,
        prior: &Pose,
        seed: u64,
    ) -> Result<Self, FailureCode> {
        params.validate()?;
        opts.validate(params)?;
        if !pose_is_valid(prior) {
            return Err(FailureCode::RelocPriorInvalid);
        }
        Ok(Self::from_checked(
            attempt, solver, params, opts, prior, seed,
        ))
    }

    /// A relocalizer for inputs the caller has already validated
    /// ([`super::Setup::build`]).
    pub(super) fn from_checked(
        attempt: A,
        solver: S,
        params: &Params,
        opts: &Options,
        prior: &Pose,
        seed: u64,
    ) -> Self {
        let mut me = Self {
            attempt,
            solver,
            params: *params,
            opts: *opts,
            root: Rng::new(seed),
            prior: *prior,
            anchor: *prior,
            center: *prior,
            t_m: params.t0_m,
            r_rad: params.r0_deg.to_radians(),
            phase: Phase::Collect,
            pairs: heapless::Vec::new(),
            inlier_mask: [false; MAX_CORR],
            revisit: heapless::Vec::new(),
            round_kept: 0,
            verify_mask: [false; MAX_CORR],
            candidates: heapless::Vec::new(),
            round: 0,
            round_attempts: 0,
            round_chunks: 0,
            consecutive_stall: 0,
            consecutive_reseed: 0,
            rounds_without_fix: 0,
            widened: false,
            seed_index: 0,
            seeding: params.seeds > 0,
            best_seed: None,
            max_units: Self::max_work_units(params),
            quality: Quality::default(),
            stats: Stats::default(),
            log: FailureLog::new(),
            done: None,
        };
        me.stats.rounds = 1;
        if me.seeding {
            me.center = me.seed_pose(0);
            me.stats.seeds_tried = 1;
        }
        me
    }

    /// Structural bound on the work units of a whole run for `params`.
    ///
    /// Between two successes there are at most `max_stall + max_reseed` failed
    /// rounds that continue (the next failure ends the run); there are at most
    /// `n_iter` successes, plus `seeds` seed rounds; each round does at most
    /// `attempts_per_iter` attempts, one solve start and ⌈`ransac_iter` /
    /// [`super::RANSAC_CHUNK`]⌉ RANSAC chunks; the repeated final solve of
    /// [`super::Verify::repeat_solve`] adds one solve start and its chunks;
    /// each of the at most `max_reseed + 1` rounds before the first fix may
    /// add one more solve ([`super::Options::first_fix_sigma_scale`]).
    pub fn max_work_units(params: &Params) -> u32 {
        let fails = u64::from(params.max_stall) + u64::from(params.max_reseed);
        let n_iter = u64::from(params.n_iter);
        let rounds = u64::from(params.seeds) + n_iter + (n_iter + 1) * fails + 1;
        let solve = 1 + u64::from(Self::max_chunks(params));
        let per_round = u64::from(params.attempts_per_iter) + solve;
        // A round before the first fix may be solved again with the first-fix
        // gate (Options::first_fix_sigma_scale); before a fix only Reseed
        // rounds follow a failed one, so there are at most max_reseed + 1.
        let widened = (u64::from(params.max_reseed) + 1) * solve;
        let units = rounds * per_round + solve + widened;
        u32::try_from(units).unwrap_or(u32::MAX)
    }

    /// Do one unit of work (one attempt or one GetTransform) at caller time `now`.
    pub fn step(&mut self, now: u64) -> StepResult<'_> {
        if self.done.is_none() {
            self.work_one(now);
        }
        self.status()
    }

    /// Do one stage of work at caller time `now` — one [`Stage`] of an
    /// attempt, or a whole unit of any other kind — and say which stage it
    /// was (`None` when the run was already done). A caller that reads its
    /// clock around each call learns where the time goes; the core reads none.
    ///
    /// Budgets are checked where a unit starts, as with [`Self::step`]: an
    /// attempt under way always runs to its end (at most
    /// [`MAX_ATTEMPT_STAGES`] calls). With the same `now` at the start of
    /// each unit, the outcome is bit-identical to stepping by whole units.
    pub fn step_stage(&mut self, now: u64) -> (Option<Stage>, StepResult<'_>) {
        let stage = if self.done.is_none() {
            Some(self.work_stage(now))
        } else {
            None
        };
        (stage, self.status())
    }

    /// One unit: its first stage, then the rest of an attempt under way.
    fn work_one(&mut self, now: u64) {
        self.work_stage(now);
        for _ in 1..MAX_ATTEMPT_STAGES {
            if self.phase != Phase::Attempt || self.done.is_some() {
                break;
            }
            self.work_stage(now);
        }
    }

    fn work_stage(&mut self, now: u64) -> Stage {
        if self.phase == Phase::Attempt {
            let step = self.attempt.resume(&mut self.stats.pipeline);
            return self.attempt_stage_done(step, now);
        }
        let unit_cap = self.opts.budget.max_work_units.min(self.max_units);
        if self.stats.work_units >= unit_cap || now >= self.opts.budget.deadline_tick {
            self.finish_budget(now);
            return Stage::Stop;
        }
        let (pass, chunk) = match self.phase {
            Phase::Collect | Phase::Attempt => return self.begin_attempt(now),
            Phase::Solve => (Pass::Round, false),
            Phase::Chunks => (Pass::Round, true),
            Phase::Verify => (Pass::Verify, false),
            Phase::VerifyChunks => (Pass::Verify, true),
        };
        if chunk {
            self.solve_chunk(pass, now);
        } else {
            self.solve_start(pass, now);
        }
        match pass {
            Pass::Round => Stage::Pose,
            Pass::Verify => Stage::Verify,
        }
    }

    fn status(&self) -> StepResult<'_> {
        match &self.done {
            Some(o) => StepResult::Done(o),
            None => StepResult::Running,
        }
    }

    /// Do up to `units` units of work at caller time `now`.
    pub fn step_n(&mut self, now: u64, units: u32) -> StepResult<'_> {
        for _ in 0..units.max(1) {
            if self.done.is_some() {
                break;
            }
            self.work_one(now);
        }
        self.status()
    }

    /// End the run now, at caller time `now`: the anytime result (the best pose
    /// so far, [`FailureCode::RelocBudgetExhausted`]) unless it is already done.
    /// A caller whose own tick or step budget ran out ends the run with this.
    pub fn stop(&mut self, now: u64) -> &Outcome {
        match self.done {
            Some(ref o) => o,
            None => self.finish_budget(now),
        }
    }

    /// End the run before any work with `code` (the preflight refused the inputs).
    pub(super) fn end_early(&mut self, code: FailureCode) {
        self.finish(Some(code), 0);
    }

    /// Run until done at a fixed caller time: a loop over [`Self::step`],
    /// bounded by [`Self::max_work_units`] + 1 calls.
    pub fn run_to_completion(&mut self, now: u64) -> Outcome {
        for _ in 0..=u64::from(self.max_units) {
            if self.done.is_some() {
                break;
            }
            self.work_one(now);
        }
        // The bound above always ends the run; `stop` keeps this total.
        self.stop(now).clone()
    }

    /// The final outcome, once done.
    pub fn outcome(&self) -> Option<&Outcome> {
        self.done.as_ref()
    }

    /// Counters so far (also while running).
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// Current search bounds (t̃ metres, r̃ radians).
    pub fn bounds(&self) -> (f32, f32) {
        (self.t_m, self.r_rad)
    }

    /// The per-attempt pipeline.
    pub fn attempt_ref(&self) -> &A {
        &self.attempt
    }

    /// The per-attempt pipeline, mutable (tests drive single attempts).
    #[cfg(test)]
    pub(crate) fn attempt_mut(&mut self) -> &mut A {
        &mut self.attempt
    }

    /// The solver.
    pub fn solver_ref(&self) -> &S {
        &self.solver
    }

    fn seed_pose(&self, k: u16) -> Pose {
        let mut rng = self.root.fork(STREAM_SEED).fork(u64::from(k));
        randomize(
            &self.prior,
            self.opts.seed_t_m,
            self.opts.seed_r_deg.to_radians(),
            true,
            &mut rng,
        )
    }

    /// Chunks allowed per solve: enough for `ransac_iter` hypotheses.
    fn max_chunks(params: &Params) -> u32 {
        u32::from(params.ransac_iter.div_ceil(super::RANSAC_CHUNK))
    }
}
