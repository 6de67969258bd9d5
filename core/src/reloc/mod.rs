//! The relocalization engine: paper Alg. 1 with Stall, Reseed, Anneal,
//! Distribute and Reuse (§III-B..E), as a bounded, resumable state machine.
//!
//! Inputs: a prior `world_from_left` pose, validated [`Params`](crate::config::Params), [`Options`]
//! (acceptance, budget, multi-seed spread), a seed, and two pieces of work
//! behind traits so each side is testable alone:
//! * [`Attempt`] — one correspondence attempt from a given virtual viewpoint
//!   (SamplePoint → Synthesize → Match → Valid → Stereo), implemented by the
//!   real pipeline and by fakes in tests;
//! * [`Solver`] — GetTransform (Umeyama + RANSAC) on the collected pairs.
//!
//! Output: an [`Outcome`] with the pose, an optional [`FailureCode`](crate::failure::FailureCode), its
//! [`Quality`] (inliers, RMS, per-iteration history) and work [`Stats`].
//!
//! Integrity: a success is reported only when the final estimate passes the
//! [`Gates`] of [`integrity`] (pose within a factor of the prior's
//! uncertainty, spread-out inliers, reprojection residual within the
//! matcher's tolerance), each with its own failure code; [`Verify`] adds the
//! upset checks (the final solve repeated from a second random stream and
//! compared, the map product re-checked before the result is returned).
//!
//! Bounds: every call to [`Relocalizer::step`] does exactly one work unit (one
//! attempt, the start of a solve, or one chunk of [`RANSAC_CHUNK`] RANSAC hypotheses); the number of units of a whole run is bounded by
//! [`Relocalizer::max_work_units`], computed from validated parameters. All
//! buffers are fixed-size fields sized by `config` capacities. Random draws come
//! from streams forked per attempt / round index, so the outcome does not
//! depend on how the work is split across calls.
//!
//! Stages: [`Relocalizer::step_stage`] does a smaller piece — one [`Stage`] of
//! an attempt (at most [`MAX_ATTEMPT_STAGES`] per attempt) or one unit of any
//! other kind — and says which stage it ran, so a caller that reads a clock
//! around each call can attribute time to stages; the core itself reads none.
//! The outcome is the same as with whole units.
//!
//! Layout, one concept per file: `setup` (the one constructor, [`Setup`]),
//! `engine/` (the state machine: `mod` stepping and accessors, `collect`
//! attempts and Focus, `solve` GetTransform, `rounds` the §III-E mechanisms,
//! `conclude` the final estimate and the outcome), `pipeline/` (the real
//! [`Attempt`]: `sample` SamplePoint and Synthesize, `window` search windows,
//! `matching` Match, Valid + Stereo in `mod`), `work` (the [`Attempt`] and
//! [`Solver`] traits), `options`, `outcome`, and beside them `policy`,
//! `solver`, `viewpoint`, `integrity`, `preflight`, `workspace`.

mod engine;
pub mod integrity;
mod options;
mod outcome;
pub mod pipeline;
pub mod policy;
pub mod preflight;
mod setup;
pub mod solver;
pub mod viewpoint;
mod work;
pub mod workspace;

#[cfg(feature = "upset-injection")]
pub use engine::UpsetRegion;
pub use engine::{work_ticket, Commit, Epoch, Relocalizer, StepResult, Ticket, Worked};
pub use pipeline::Pipeline;
pub use policy::{MatchPolicy, Variant};
pub use setup::{Engine, Setup};
pub use solver::RansacSolver;
pub use workspace::{
    Storage, Workspace, WorkspaceSizes, PAPER_WORKSPACE_BYTES, TEST_WORKSPACE_BYTES,
};

pub use crate::pose::{Candidate, Correspondence};
pub use options::{
    first_fix_sigma_scale, footprint_scale, Accuracy, Budget, Focus, Gates, Near, Options, Search,
    Verify, DEFAULT_FIRST_FIX_ROUNDS, DEFAULT_FOCUS_RADIUS_M, DEFAULT_FOCUS_VOTES,
    DEFAULT_NEAR_RADIUS_M, DEFAULT_PRIOR_FACTOR, MAX_FIRST_FIX_SIGMA_SCALE,
};
pub use outcome::{IterationRecord, Outcome, PipelineStats, Quality, Stats, MATCH_VARIANTS};
pub use work::{
    Attempt, AttemptContext, Solution, Solver, Stage, StageStep, MAX_ATTEMPT_STAGES, RANSAC_CHUNK,
};
