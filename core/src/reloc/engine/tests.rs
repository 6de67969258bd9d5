extern crate std;
use super::super::Focus;
use super::super::{Budget, PipelineStats};
use super::*;
use crate::config::{Mechanisms, DEFAULT_T0_M, MAX_T0_M};
use crate::geom::Vec3;
use crate::reloc::AttemptContext;
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use std::boxed::Box;
use std::vec::Vec;

/// Produces pairs with a unique id in `world.x`; fails when `fail(index, rng)` says so.
type FailFn = Box<dyn FnMut(u32, &mut Rng) -> Option<FailureCode>>;

struct FakeAttempt {
    fail: FailFn,
    next_id: u32,
    contexts: Vec<AttemptContext>,
    /// What `recheck` reports, and how often it was called.
    recheck: Result<(), FailureCode>,
    rechecks: u32,
    /// When set, each pair is a point 2–4 m in front of the camera seen
    /// from this `world_from_left` (a scene), not an arbitrary pair.
    truth: Option<Pose>,
    /// The template variant of pair `id` (Sobel at ℓ unless set); a gray
    /// one is rejected when the context asks for gradient matches only.
    variant: fn(u32) -> u8,
}

impl FakeAttempt {
    fn new(fail: impl FnMut(u32, &mut Rng) -> Option<FailureCode> + 'static) -> Self {
        Self {
            fail: Box::new(fail),
            next_id: 0,
            contexts: Vec::new(),
            recheck: Ok(()),
            rechecks: 0,
            truth: None,
            variant: |_| 1,
        }
    }

    fn seen_from(truth: Pose) -> Self {
        Self {
            truth: Some(truth),
            ..Self::ok()
        }
    }
    fn ok() -> Self {
        Self::new(|_, _| None)
    }
}

impl Attempt for FakeAttempt {
    fn attempt(
        &mut self,
        ctx: &AttemptContext,
        rng: &mut Rng,
        stats: &mut PipelineStats,
    ) -> Result<Correspondence, FailureCode> {
        self.contexts.push(*ctx);
        stats.renders += 2;
        if let Some(code) = (self.fail)(ctx.index, rng) {
            return Err(code);
        }
        let id = self.next_id;
        self.next_id += 1;
        let variant = (self.variant)(id);
        if ctx.gradient_only && !super::super::policy::is_gradient_variant(variant) {
            return Err(FailureCode::NccLowScore);
        }
        if let Some(truth) = self.truth {
            let cam = Vec3::new(
                2.0 * rng.next_f32() - 1.0,
                2.0 * rng.next_f32() - 1.0,
                2.0 + 2.0 * rng.next_f32(),
            );
            return Ok(Correspondence {
                world: truth.transform_point(&cam),
                cam,
                sigma_m: 0.01,
                variant,
            });
        }
        let v = ctx.world_from_viewpoint.translation();
        Ok(Correspondence {
            world: Vec3::new(id as f32, rng.next_f32(), rng.next_f32()),
            // The viewpoint centre travels with the pair so solvers can see it.
            cam: v,
            sigma_m: 0.01,
            variant,
        })
    }

    fn recheck(&mut self) -> Result<(), FailureCode> {
        self.rechecks += 1;
        self.recheck
    }
}

type Script = Box<dyn FnMut(u32, &[Correspondence], &mut [bool]) -> Result<Solution, FailureCode>>;

struct FakeSolver {
    script: Script,
    /// Answers the solves made while the σ scale is above 1, when set.
    wide: Option<Script>,
    scale: f32,
    /// The σ scale of each solve.
    scales: Vec<f32>,
    calls: Vec<Vec<Correspondence>>,
}

impl FakeSolver {
    fn new(
        f: impl FnMut(u32, &[Correspondence], &mut [bool]) -> Result<Solution, FailureCode> + 'static,
    ) -> Self {
        Self {
            script: Box::new(f),
            wide: None,
            scale: 1.0,
            scales: Vec::new(),
            calls: Vec::new(),
        }
    }

    fn with_wide(
        mut self,
        f: impl FnMut(u32, &[Correspondence], &mut [bool]) -> Result<Solution, FailureCode> + 'static,
    ) -> Self {
        self.wide = Some(Box::new(f));
        self
    }
}

impl Solver for FakeSolver {
    fn solve(
        &mut self,
        pairs: &[Correspondence],
        rng: &mut Rng,
        mask: &mut [bool],
    ) -> Result<Solution, FailureCode> {
        let _ = rng.next_u32();
        let call = self.calls.len() as u32;
        self.calls.push(pairs.to_vec());
        self.scales.push(self.scale);
        match self.wide.as_mut() {
            Some(wide) if self.scale > 1.0 => wide(call, pairs, mask),
            _ => (self.script)(call, pairs, mask),
        }
    }

    fn set_sigma_scale(&mut self, scale: f32) {
        self.scale = scale;
    }
}

fn at_x(x: f32) -> Pose {
    Pose::new(UnitQuaternion::identity(), Vec3::new(x, 0.0, 0.0))
}

/// A solution at `pose` whose inliers are the pairs with an even id.
fn even_inliers(pose: Pose, pairs: &[Correspondence], mask: &mut [bool]) -> Solution {
    let mut n = 0u16;
    for (p, m) in pairs.iter().zip(mask.iter_mut()) {
        *m = (p.world.x as u32) % 2 == 0;
        n += u16::from(*m);
    }
    Solution {
        pose,
        inliers: n,
        rms_m: 0.01,
        iterations: 10,
        candidates: heapless::Vec::new(),
    }
}

fn small_params() -> Params {
    Params {
        n_corr: 20,
        n_iter: 5,
        attempts_per_iter: 50,
        max_stall: 3,
        max_reseed: 4,
        template_px: 64,
        ..Params::paper()
    }
}

/// Options of the search tests: the fakes' poses and points are not a
/// scene, so the integrity gates (tested on their own) are off.
fn opts(p: &Params) -> Options {
    Options {
        min_inliers: 5,
        gates: super::super::Gates::OFF,
        first_fix_rounds: 0,
        ..Options::for_params(p)
    }
}

/// Verifies: VTSM-RELOC-002
#[test]
fn invalid_prior_params_or_options_are_refused() {
    let p = small_params();
    let o = opts(&p);
    let mk = |prior: &Pose, p: &Params, o: &Options| {
        Relocalizer::new(
            FakeAttempt::ok(),
            FakeSolver::new(|_, _, _| Err(FailureCode::PoseDegenerate)),
            p,
            o,
            prior,
            1,
        )
        .err()
    };
    assert_eq!(
        mk(&at_x(f32::NAN), &p, &o),
        Some(FailureCode::RelocPriorInvalid)
    );
    let non_unit = Pose {
        iso: Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 0.0),
            UnitQuaternion::new_unchecked(Quaternion::new(1.5, 0.0, 0.0, 0.0)),
        ),
    };
    assert_eq!(mk(&non_unit, &p, &o), Some(FailureCode::RelocPriorInvalid));
    let bad = Params { n_corr: 1, ..p };
    assert_eq!(
        mk(&at_x(0.0), &bad, &o),
        Some(FailureCode::ConfigParamOutOfRange)
    );
    let bad_o = Options {
        min_inliers: p.n_corr + 1,
        ..o
    };
    assert_eq!(
        mk(&at_x(0.0), &p, &bad_o),
        Some(FailureCode::ConfigParamOutOfRange)
    );
    let bad_o = Options {
        seed_t_m: f32::NAN,
        ..o
    };
    assert_eq!(
        mk(&at_x(0.0), &p, &bad_o),
        Some(FailureCode::ConfigParamOutOfRange)
    );
    assert_eq!(mk(&at_x(0.0), &p, &o), None);
}

/// Verifies: VTSM-RELOC-005, VTSM-RELOC-006
#[test]
fn ransac_failure_stalls_then_reseeds_then_returns_cap_code() {
    let p = small_params();
    let solver = FakeSolver::new(|call, pairs, mask| {
        if call == 0 {
            Ok(even_inliers(at_x(0.5), pairs, mask))
        } else {
            Err(FailureCode::PoseRansacNoConsensus)
        }
    });
    let mut r = Relocalizer::new(FakeAttempt::ok(), solver, &p, &opts(&p), &at_x(0.0), 7).unwrap();
    // Watch the mechanism chosen after each failed solve.
    let mut sequence = Vec::new();
    let mut last = (0u16, 0u16);
    let out = loop {
        match r.step(0) {
            StepResult::Done(o) => break o.clone(),
            StepResult::Running => {
                let s = r.stats();
                if (s.stalls, s.reseeds) != last {
                    sequence.push(if s.stalls != last.0 { 'S' } else { 'R' });
                    last = (s.stalls, s.reseeds);
                }
            }
        }
    };
    assert_eq!(std::string::String::from_iter(&sequence), "SSSRRRR");
    assert_eq!(out.failure, Some(FailureCode::RelocReseedCapReached));
    assert_eq!(out.stats.successes, 1);
    assert_eq!(out.stats.solves, 1 + 3 + 4 + 1);
    assert_eq!(out.log.count(FailureCode::PoseRansacNoConsensus), 8);
    // The pose reported is the last successful one, not a reseeded guess.
    assert_eq!(out.pose, at_x(0.5));

    // Without Reseed, the Stall cap ends the run with its own code.
    let mut p2 = p;
    p2.mechanisms.reseed = false;
    let solver = FakeSolver::new(|call, pairs, mask| {
        if call == 0 {
            Ok(even_inliers(at_x(0.5), pairs, mask))
        } else {
            Err(FailureCode::PoseDegenerate)
        }
    });
    let out = Relocalizer::new(FakeAttempt::ok(), solver, &p2, &opts(&p2), &at_x(0.0), 7)
        .unwrap()
        .run_to_completion(0);
    assert_eq!(out.failure, Some(FailureCode::RelocStallCapReached));
    assert_eq!((out.stats.stalls, out.stats.reseeds), (3, 0));

    // With neither, the first failure's own code is returned.
    let mut p3 = p2;
    p3.mechanisms.stall = false;
    let solver = FakeSolver::new(|_, _, _| Err(FailureCode::PoseDegenerate));
    let out = Relocalizer::new(FakeAttempt::ok(), solver, &p3, &opts(&p3), &at_x(0.0), 7)
        .unwrap()
        .run_to_completion(0);
    assert_eq!(out.failure, Some(FailureCode::PoseDegenerate));
    assert_eq!(out.stats.solves, 1);
    assert_eq!(out.pose, at_x(0.0));
}

/// Verifies: VTSM-RELOC-005
#[test]
fn stall_needs_a_prior_success_and_reseed_moves_the_centre() {
    let p = small_params();
    let solver = FakeSolver::new(|_, _, _| Err(FailureCode::PoseRansacNoConsensus));
    let mut r = Relocalizer::new(FakeAttempt::ok(), solver, &p, &opts(&p), &at_x(0.0), 3).unwrap();
    let out = r.run_to_completion(0);
    assert_eq!((out.stats.stalls, out.stats.reseeds), (0, 4));
    assert_eq!(out.failure, Some(FailureCode::RelocReseedCapReached));
    // Viewpoints of round 0 lie within t̃ of the prior; reseeded rounds are centred
    // on a perturbed pose, so some reach beyond t̃ of the prior (up to 2 t̃).
    let ctxs = &r.attempt_ref().contexts;
    let n = usize::from(p.n_corr);
    let dist = |c: &AttemptContext| c.world_from_viewpoint.translation().norm();
    assert!(ctxs[..n].iter().all(|c| dist(c) <= p.t0_m + 1e-6));
    assert!(ctxs[n..].iter().all(|c| dist(c) <= 2.0 * p.t0_m + 1e-6));
    assert!(ctxs[n..].iter().any(|c| dist(c) > p.t0_m));
}

/// Verifies: VTSM-RELOC-007
#[test]
fn anneal_shrinks_bounds_by_gamma_after_each_success() {
    for anneal in [true, false] {
        let mut p = small_params();
        p.gamma = 0.5;
        p.mechanisms.anneal = anneal;
        let solver = FakeSolver::new(|call, pairs, mask| {
            Ok(even_inliers(at_x(0.1 * (call + 1) as f32), pairs, mask))
        });
        let mut r =
            Relocalizer::new(FakeAttempt::ok(), solver, &p, &opts(&p), &at_x(0.0), 5).unwrap();
        let out = r.run_to_completion(0);
        assert_eq!(out.failure, None);
        assert_eq!(out.quality.history.len(), usize::from(p.n_iter));
        let mut t = p.t0_m;
        let mut rr = p.r0_deg.to_radians();
        for rec in &out.quality.history {
            assert_eq!((rec.t_m, rec.r_rad), (t, rr));
            if anneal {
                t *= 0.5;
                rr *= 0.5;
            }
        }
        // Every attempt used the bounds of its iteration.
        for c in &r.attempt_ref().contexts {
            assert!(out
                .quality
                .history
                .iter()
                .any(|h| h.t_m == c.t_m && h.r_rad == c.r_rad));
        }
    }
}

/// Verifies: VTSM-RELOC-009
#[test]
fn reuse_carries_the_configured_fraction_of_inliers() {
    for (reuse, fraction) in [(true, 0.5f32), (true, 0.25), (false, 0.5)] {
        let mut p = small_params();
        p.mechanisms.reuse = reuse;
        p.reuse_fraction = fraction;
        let solver = FakeSolver::new(|call, pairs, mask| {
            Ok(even_inliers(at_x(0.1 * (call + 1) as f32), pairs, mask))
        });
        let mut r =
            Relocalizer::new(FakeAttempt::ok(), solver, &p, &opts(&p), &at_x(0.0), 5).unwrap();
        let out = r.run_to_completion(0);
        let calls = &r.solver_ref().calls;
        assert_eq!(calls.len(), usize::from(p.n_iter));
        let mut reused_total = 0;
        for w in calls.windows(2) {
            let prev_inliers: Vec<u32> = w[0]
                .iter()
                .map(|c| c.world.x as u32)
                .filter(|id| id % 2 == 0)
                .collect();
            let expect = if reuse {
                (fraction * prev_inliers.len() as f32).floor() as usize
            } else {
                0
            };
            let carried: Vec<u32> = w[1]
                .iter()
                .map(|c| c.world.x as u32)
                .filter(|id| w[0].iter().any(|c| c.world.x as u32 == *id))
                .collect();
            assert_eq!(carried, prev_inliers[..expect].to_vec());
            assert_eq!(w[1].len(), usize::from(p.n_corr));
            reused_total += expect;
        }
        assert_eq!(out.stats.reused as usize, reused_total);
    }
}

/// Verifies: VTSM-RELOC-041
#[test]
fn the_final_round_keeps_gradient_domain_pairs_only() {
    // (option on, variant of pair id, the fifth solve fails, gradient final round expected)
    let sobel_two_thirds: fn(u32) -> u8 = |id| [0, 1, 4][(id % 3) as usize];
    let cases = [
        (true, sobel_two_thirds, false, true),
        (false, sobel_two_thirds, false, false),
        // The restricted final round fails: it runs again with every variant.
        (true, sobel_two_thirds, true, true),
    ];
    for (on, variant, fail_final, restricted) in cases {
        let p = small_params();
        let mut o = opts(&p);
        o.final_gradient_only = on;
        let solver = FakeSolver::new(move |call, pairs, mask| {
            if fail_final && call == u32::from(p.n_iter) - 1 {
                return Err(FailureCode::PoseRansacNoConsensus);
            }
            Ok(even_inliers(at_x(0.1 * (call + 1) as f32), pairs, mask))
        });
        let mut attempt = FakeAttempt::ok();
        attempt.variant = variant;
        let mut r = Relocalizer::new(attempt, solver, &p, &o, &at_x(0.0), 5).unwrap();
        let out = r.run_to_completion(0);
        assert!(out.failure.is_none(), "{:?}", out.failure);
        assert_eq!(
            out.stats.gradient_rounds,
            u16::from(restricted),
            "{on} {fail_final}"
        );
        let calls = &r.solver_ref().calls;
        let gray = |c: &[Correspondence]| {
            c.iter()
                .filter(|q| !super::super::policy::is_gradient_variant(q.variant))
                .count()
        };
        let contexts = &r.attempt_ref().contexts;
        // The rounds before the final one take every variant.
        let before = usize::from(p.n_iter) - 1;
        assert!(calls[..before].iter().all(|c| gray(c) > 0));
        let final_solves = &calls[before..];
        assert_eq!(final_solves.len(), 1 + usize::from(fail_final));
        let restricted_attempts = contexts.iter().filter(|c| c.gradient_only).count();
        if restricted {
            let first = &final_solves[0];
            assert_eq!(first.len(), usize::from(p.n_corr));
            assert_eq!(gray(first), 0);
            // Pairs carried into it by Reuse are gradient ones too, and
            // its new pairs came from gradient-only attempts, the gray
            // third of whose ids was rejected.
            let prev = &calls[before - 1];
            let carried = first
                .iter()
                .filter(|c| prev.iter().any(|q| q.world.x == c.world.x))
                .count();
            assert!(carried > 0);
            let new = usize::from(p.n_corr) - carried;
            assert!(
                restricted_attempts >= new + new / 2 - 1,
                "{restricted_attempts} attempts for {new} pairs"
            );
        } else {
            assert_eq!(restricted_attempts, 0);
        }
        // The solve that ends the run: gradient pairs only exactly when the
        // restricted final round is the one that succeeded.
        let last = final_solves.last().unwrap();
        assert_eq!(
            gray(last) == 0,
            restricted && !fail_final,
            "{on} {fail_final}"
        );
    }
}

/// Verifies: VTSM-RELOC-008
#[test]
fn distribute_draws_viewpoints_around_candidates_by_inliers() {
    for distribute in [true, false] {
        let mut p = small_params();
        p.n_corr = 100;
        p.attempts_per_iter = 100;
        p.n_iter = 2;
        p.mechanisms.distribute = distribute;
        p.mechanisms.anneal = false;
        p.t0_m = 0.05;
        let solver = FakeSolver::new(|_, pairs, mask| {
            let mut s = even_inliers(at_x(0.0), pairs, mask);
            s.pose = at_x(0.5);
            s.candidates
                .push(Candidate {
                    pose: at_x(10.0),
                    inliers: 30,
                })
                .unwrap();
            s.candidates
                .push(Candidate {
                    pose: at_x(20.0),
                    inliers: 10,
                })
                .unwrap();
            Ok(s)
        });
        let mut o = opts(&p);
        o.min_inliers = 10;
        let mut r = Relocalizer::new(FakeAttempt::ok(), solver, &p, &o, &at_x(0.0), 5).unwrap();
        let out = r.run_to_completion(0);
        assert_eq!(out.failure, None);
        let second = &r.attempt_ref().contexts[100..];
        let near = |x: f32| {
            second
                .iter()
                .filter(|c| (c.world_from_viewpoint.translation().x - x).abs() <= 0.05 + 1e-5)
                .count()
        };
        if distribute {
            assert_eq!(near(10.0) + near(20.0), second.len());
            // 30 : 10 inliers → 75 % of the viewpoints around the first candidate.
            let f = near(10.0) as f32 / second.len() as f32;
            assert!(second.len() >= 50 && (0.6..=0.9).contains(&f), "{f}");
        } else {
            assert_eq!(near(0.5), second.len());
        }
    }
}

/// Verifies: VTSM-RELOC-010
#[test]
fn converges_when_the_update_is_below_threshold() {
    let p = small_params();
    // Solver returns the prior itself: the first update is 0 m.
    let solver = FakeSolver::new(|_, pairs, mask| Ok(even_inliers(at_x(0.0), pairs, mask)));
    let out = Relocalizer::new(FakeAttempt::ok(), solver, &p, &opts(&p), &at_x(0.0), 1)
        .unwrap()
        .run_to_completion(0);
    assert_eq!(out.failure, None);
    assert_eq!(out.stats.successes, 1);
    assert_eq!(out.quality.inliers, 10);
    assert!((out.quality.inlier_ratio - 0.5).abs() < 1e-6);
    // Too few inliers is not a success.
    let mut o = opts(&p);
    o.min_inliers = 11;
    let solver = FakeSolver::new(|_, pairs, mask| Ok(even_inliers(at_x(0.3), pairs, mask)));
    let out = Relocalizer::new(FakeAttempt::ok(), solver, &p, &o, &at_x(0.0), 1)
        .unwrap()
        .run_to_completion(0);
    assert_eq!(out.failure, Some(FailureCode::RelocReseedCapReached));
    assert_eq!(out.pose, at_x(0.0));
    assert_eq!(out.quality.inliers, 0);
}

/// Viewpoint half-widths and centres of a run from `prior` with t̃₀ =
/// `t0`, whose pairs come from `attempt`; the solver never reaches a
/// consensus, so every round is a round before the first fix.
fn focus_run(t0: f32, focus: Focus, attempt: FakeAttempt) -> (Vec<AttemptContext>, Stats) {
    let mut p = small_params();
    p.t0_m = t0;
    let o = Options { focus, ..opts(&p) };
    let solver = FakeSolver::new(|_, _, _| Err(FailureCode::PoseDegenerate));
    let mut r = Relocalizer::new(attempt, solver, &p, &o, &at_x(0.0), 9).unwrap();
    let out = r.run_to_completion(0);
    assert_eq!(out.failure, Some(FailureCode::RelocReseedCapReached));
    (r.attempt_ref().contexts.clone(), out.stats)
}

/// Verifies: VTSM-RELOC-040
#[test]
fn a_wide_prior_focuses_on_the_position_its_pairs_agree_on() {
    let p = small_params();
    let on = Focus::for_params(&p);
    let truth = at_x(0.4);
    let (ctxs, stats) = focus_run(0.5, on, FakeAttempt::seen_from(truth));
    let rounds = usize::from(p.max_reseed) + 1;
    assert_eq!(ctxs.len(), rounds * usize::from(p.n_corr));
    assert_eq!(stats.focused_rounds as usize, rounds);
    let votes = usize::from(on.votes);
    for round in ctxs.chunks(usize::from(p.n_corr)) {
        // Until `votes` pairs agree: the stated uncertainty, around the
        // prior (or a Reseed centre within t̃₀ of it).
        for c in &round[..votes] {
            assert_eq!(c.t_m, 0.5);
            assert!(c.world_from_viewpoint.translation().norm() <= 1.0 + 1e-5);
        }
        // Then the focused half-width, around the truth (the one-point
        // hypotheses of an exact scene all equal its translation).
        for c in &round[votes..] {
            assert_eq!(c.t_m, on.t_m);
            let d = c.world_from_viewpoint.translation() - truth.translation();
            assert!(d.norm() <= on.t_m + 1e-5, "{d:?}");
        }
    }

    // Pairs that agree on nothing (scattered hypotheses), or on a position
    // outside the prior's stated uncertainty: never focused, and the same
    // viewpoints as with Focus off.
    for attempt in [
        || FakeAttempt::ok(),
        || FakeAttempt::seen_from(at_x(0.5 + 0.1 + 0.01)),
    ] {
        let (ctxs, stats) = focus_run(0.5, on, attempt());
        assert_eq!(stats.focused_rounds, 0);
        assert!(ctxs.iter().all(|c| c.t_m == 0.5));
        let (off, _) = focus_run(0.5, Focus::OFF, attempt());
        assert_eq!(ctxs, off);
    }

    // A prior of the default uncertainty is never focused.
    let (ctxs, stats) = focus_run(DEFAULT_T0_M, on, FakeAttempt::seen_from(at_x(0.15)));
    assert_eq!(stats.focused_rounds, 0);
    let (off, _) = focus_run(DEFAULT_T0_M, Focus::OFF, FakeAttempt::seen_from(at_x(0.15)));
    assert_eq!(ctxs, off);
}

/// Verifies: VTSM-RELOC-040
#[test]
fn the_first_fix_of_a_focused_round_anneals_from_the_focused_width() {
    let mut p = small_params();
    p.t0_m = 0.5;
    let truth = at_x(0.4);
    let solver = FakeSolver::new(move |_, pairs, mask| {
        mask.iter_mut().for_each(|m| *m = true);
        Ok(Solution {
            pose: truth,
            inliers: pairs.len() as u16,
            rms_m: 0.01,
            iterations: 10,
            candidates: heapless::Vec::new(),
        })
    });
    let o = opts(&p);
    let mut r =
        Relocalizer::new(FakeAttempt::seen_from(truth), solver, &p, &o, &at_x(0.0), 3).unwrap();
    let out = r.run_to_completion(0);
    assert_eq!(out.failure, None);
    assert_eq!(out.stats.focused_rounds, 1);
    let h = &out.quality.history;
    assert_eq!(h[0].t_m, o.focus.t_m);
    if h.len() > 1 {
        assert!((h[1].t_m - o.focus.t_m * p.gamma).abs() <= 1e-6);
    }
}

/// Verifies: VTSM-RELOC-040
#[test]
fn focus_options_out_of_range_are_refused() {
    let p = small_params();
    let on = Focus::for_params(&p);
    for focus in [
        Focus { votes: 1, ..on },
        Focus {
            votes: (p.n_corr + 1) as u8,
            ..on
        },
        Focus {
            radius_m: 0.0,
            ..on
        },
        Focus {
            radius_m: f32::NAN,
            ..on
        },
        Focus {
            radius_m: 1.5,
            ..on
        },
        Focus { t_m: 0.0, ..on },
        Focus {
            t_m: f32::INFINITY,
            ..on
        },
        Focus {
            t_m: MAX_T0_M + 0.5,
            ..on
        },
    ] {
        let o = Options { focus, ..opts(&p) };
        let r = Relocalizer::new(
            FakeAttempt::ok(),
            FakeSolver::new(|_, _, _| Err(FailureCode::PoseDegenerate)),
            &p,
            &o,
            &at_x(0.0),
            1,
        );
        assert_eq!(
            r.err(),
            Some(FailureCode::ConfigParamOutOfRange),
            "{focus:?}"
        );
    }
    for focus in [
        Focus::OFF,
        Focus { votes: 2, ..on },
        Focus { votes: 20, ..on },
    ] {
        let o = Options { focus, ..opts(&p) };
        assert!(Options::validate(&o, &p).is_ok(), "{focus:?}");
    }
}

/// Verifies: VTSM-RELOC-031
#[test]
fn a_success_far_from_the_prior_fails_with_the_prior_gate() {
    let p = Params {
        n_iter: 1,
        ..small_params()
    };
    for (x, want) in [
        (0.55, None),
        (0.65, Some(FailureCode::RelocPoseOutsidePrior)),
        (30.0, Some(FailureCode::RelocPoseOutsidePrior)),
    ] {
        let solver = FakeSolver::new(move |_, pairs, mask| Ok(even_inliers(at_x(x), pairs, mask)));
        let o = Options {
            gates: super::super::Gates {
                prior_factor: 3.0,
                ..super::super::Gates::OFF
            },
            ..opts(&p)
        };
        let out = Relocalizer::new(FakeAttempt::ok(), solver, &p, &o, &at_x(0.0), 1)
            .unwrap()
            .run_to_completion(0);
        // t̃₀ = 0.2 m: the gate is at 0.6 m.
        assert_eq!(out.failure, want, "x = {x}");
        assert_eq!(out.pose, at_x(x));
        assert_eq!(out.stats.successes, 1);
        if let Some(code) = want {
            assert_eq!(out.log.count(code), 1);
        }
    }
    // Options with a gate out of range are refused.
    let bad = Options {
        gates: super::super::Gates {
            prior_factor: 0.5,
            ..super::super::Gates::OFF
        },
        ..opts(&p)
    };
    let solver = FakeSolver::new(|_, _, _| Err(FailureCode::PoseDegenerate));
    assert_eq!(
        Relocalizer::new(FakeAttempt::ok(), solver, &p, &bad, &at_x(0.0), 1).err(),
        Some(FailureCode::ConfigParamOutOfRange)
    );
}

/// Verifies: VTSM-RELOC-032
#[test]
fn the_repeated_solve_must_agree_with_the_final_estimate() {
    let p = Params {
        n_iter: 1,
        ..small_params()
    };
    let verify = super::super::Verify::for_params(&p);
    // Tolerance: 2 × inlier gate = 0.1 m.
    for (second, want) in [
        (0.03, None),
        (0.5, Some(FailureCode::RelocVerifyDisagree)),
        (f32::NAN, Some(FailureCode::RelocVerifyDisagree)),
    ] {
        let solver = FakeSolver::new(move |call, pairs, mask| {
            let x = if call == 0 { 0.0 } else { second };
            Ok(even_inliers(at_x(x), pairs, mask))
        });
        let o = Options { verify, ..opts(&p) };
        let mut r = Relocalizer::new(FakeAttempt::ok(), solver, &p, &o, &at_x(0.0), 1).unwrap();
        let out = r.run_to_completion(0);
        assert_eq!(out.failure, want, "second solve at {second}");
        // One extra solve on the same pairs (the fake solver is not chunked).
        let calls = &r.solver_ref().calls;
        assert_eq!(calls.len(), 2);
        assert_eq!(calls[0], calls[1]);
        assert_eq!(out.stats.verify_units, 1);
        assert_eq!(
            out.stats.work_units,
            out.stats.attempts + out.stats.solves + out.stats.verify_units
        );
        assert_eq!(out.pose, at_x(0.0));
        if second.is_finite() {
            let (dt, _) = out.quality.verify_diff.unwrap();
            assert!((dt - second).abs() < 1e-6);
        }
    }
    // A repeat that finds no solution is a disagreement too.
    let solver = FakeSolver::new(|call, pairs, mask| {
        if call == 0 {
            Ok(even_inliers(at_x(0.0), pairs, mask))
        } else {
            Err(FailureCode::PoseRansacNoConsensus)
        }
    });
    let o = Options { verify, ..opts(&p) };
    let out = Relocalizer::new(FakeAttempt::ok(), solver, &p, &o, &at_x(0.0), 1)
        .unwrap()
        .run_to_completion(0);
    assert_eq!(out.failure, Some(FailureCode::RelocVerifyDisagree));
    // Off by default: no second solve.
    let solver = FakeSolver::new(|_, pairs, mask| Ok(even_inliers(at_x(0.0), pairs, mask)));
    let mut r = Relocalizer::new(FakeAttempt::ok(), solver, &p, &opts(&p), &at_x(0.0), 1).unwrap();
    let out = r.run_to_completion(0);
    assert_eq!(out.failure, None);
    assert_eq!(r.solver_ref().calls.len(), 1);
    assert_eq!((out.stats.verify_units, out.quality.verify_diff), (0, None));
}

/// Verifies: VTSM-RELOC-033
#[test]
fn the_map_recheck_runs_before_a_success_and_fails_it() {
    let p = Params {
        n_iter: 1,
        ..small_params()
    };
    for (recheck, on, want) in [
        (Ok(()), true, None),
        (
            Err(FailureCode::RelocMapChanged),
            true,
            Some(FailureCode::RelocMapChanged),
        ),
        (Err(FailureCode::RelocMapChanged), false, None),
    ] {
        let mut attempt = FakeAttempt::ok();
        attempt.recheck = recheck;
        let solver = FakeSolver::new(|_, pairs, mask| Ok(even_inliers(at_x(0.0), pairs, mask)));
        let o = Options {
            verify: super::super::Verify {
                recheck_map: on,
                ..super::super::Verify::off(&p)
            },
            ..opts(&p)
        };
        let mut r = Relocalizer::new(attempt, solver, &p, &o, &at_x(0.0), 1).unwrap();
        let out = r.run_to_completion(0);
        assert_eq!(out.failure, want);
        assert_eq!(r.attempt_ref().rechecks, u32::from(on));
    }
}

/// Verifies: VTSM-RELOC-011
#[test]
fn sample_cap_fails_the_iteration() {
    let p = small_params();
    let attempt = FakeAttempt::new(|_, _| Some(FailureCode::NccLowScore));
    let solver = FakeSolver::new(|_, _, _| Err(FailureCode::PoseDegenerate));
    let o = Options {
        no_evidence_attempts: 0,
        ..opts(&p)
    };
    let mut r = Relocalizer::new(attempt, solver, &p, &o, &at_x(0.0), 1).unwrap();
    let out = r.run_to_completion(0);
    let rounds = u32::from(p.max_reseed) + 1;
    assert_eq!(out.stats.attempts, rounds * p.attempts_per_iter);
    assert_eq!(out.stats.solves, 0);
    assert_eq!(
        out.log.count(FailureCode::RelocSampleCapReached) as u32,
        rounds
    );
    assert_eq!(
        out.log.count(FailureCode::NccLowScore) as u32,
        out.stats.attempts
    );
    assert_eq!(out.failure, Some(FailureCode::RelocReseedCapReached));
}

/// Verifies: VTSM-RELOC-021
#[test]
fn no_evidence_stops_early_with_its_own_code() {
    let p = small_params();
    for cap in [1u32, 37, 200] {
        let attempt = FakeAttempt::new(|_, _| Some(FailureCode::NccLowScore));
        let solver = FakeSolver::new(|_, _, _| Err(FailureCode::PoseDegenerate));
        let o = Options {
            no_evidence_attempts: cap,
            ..opts(&p)
        };
        let mut r = Relocalizer::new(attempt, solver, &p, &o, &at_x(0.0), 1).unwrap();
        let out = r.run_to_completion(0);
        assert_eq!(out.failure, Some(FailureCode::RelocNoEvidence), "cap {cap}");
        assert_eq!(out.stats.attempts, cap);
        assert_eq!(out.log.count(FailureCode::RelocNoEvidence), 1);
        assert_eq!(out.pose, at_x(0.0));
    }
    // One correspondence early on is evidence: the run goes on to its caps.
    let attempt = FakeAttempt::new(|i, _| (i != 3).then_some(FailureCode::NccLowScore));
    let solver = FakeSolver::new(|_, _, _| Err(FailureCode::PoseDegenerate));
    let o = Options {
        no_evidence_attempts: 10,
        ..opts(&p)
    };
    let mut r = Relocalizer::new(attempt, solver, &p, &o, &at_x(0.0), 1).unwrap();
    let out = r.run_to_completion(0);
    assert_eq!(out.failure, Some(FailureCode::RelocReseedCapReached));
    assert!(out.stats.attempts > 10);
}

/// Verifies: VTSM-RELOC-036
#[test]
fn no_consensus_before_the_first_fix_stops_early_with_its_own_code() {
    let p = small_params();
    // Every solve finds 10 inliers of 20 against a minimum of 11.
    let no_consensus =
        || FakeSolver::new(|_, pairs, mask| Ok(even_inliers(at_x(0.3), pairs, mask)));
    for k in [1u8, 2, 3] {
        let o = Options {
            min_inliers: 11,
            first_fix_rounds: k,
            ..opts(&p)
        };
        let mut r =
            Relocalizer::new(FakeAttempt::ok(), no_consensus(), &p, &o, &at_x(0.0), 1).unwrap();
        let out = r.run_to_completion(0);
        assert_eq!(out.failure, Some(FailureCode::RelocNoConsensus), "k {k}");
        assert_eq!(out.stats.solves, u32::from(k));
        assert_eq!(out.stats.attempts, u32::from(k) * u32::from(p.n_corr));
        assert_eq!(out.stats.reseeds, u16::from(k) - 1);
        assert_eq!(out.log.count(FailureCode::RelocNoConsensus), 1);
        assert_eq!(out.pose, at_x(0.0));
    }
    // 0: only the Reseed cap ends the run.
    let o = Options {
        min_inliers: 11,
        first_fix_rounds: 0,
        ..opts(&p)
    };
    let out = Relocalizer::new(FakeAttempt::ok(), no_consensus(), &p, &o, &at_x(0.0), 1)
        .unwrap()
        .run_to_completion(0);
    assert_eq!(out.failure, Some(FailureCode::RelocReseedCapReached));
    assert_eq!(out.stats.solves, u32::from(p.max_reseed) + 1);
    // After a pose update, failed rounds are Stall and Reseed rounds, not
    // a missing first fix.
    let solver = FakeSolver::new(|call, pairs, mask| {
        let mut s = even_inliers(at_x(0.3), pairs, mask);
        if call > 0 {
            s.inliers = 3;
        }
        Ok(s)
    });
    let o = Options {
        min_inliers: 10,
        first_fix_rounds: 1,
        ..opts(&p)
    };
    let out = Relocalizer::new(FakeAttempt::ok(), solver, &p, &o, &at_x(0.0), 1)
        .unwrap()
        .run_to_completion(0);
    assert_eq!(out.stats.successes, 1);
    assert_eq!(out.failure, Some(FailureCode::RelocReseedCapReached));
    assert_eq!(out.log.count(FailureCode::RelocNoConsensus), 0);
    assert_eq!(out.stats.stalls, u16::from(p.max_stall));
    // The default: one round from a prior of the default uncertainty, the
    // Reseed search from a more uncertain one.
    assert_eq!(Options::for_params(&Params::paper()).first_fix_rounds, 1);
    let wide = Params::paper().with_uncertainty(crate::config::PriorUncertainty {
        t_m: 0.5,
        r_deg: 1.5,
    });
    assert_eq!(Options::for_params(&wide).first_fix_rounds, 0);
}

/// Verifies: VTSM-RELOC-038
#[test]
fn a_first_round_without_consensus_is_solved_again_with_the_wider_gate() {
    // ℓ = 256: the default σ scale is 4.
    let p = Params {
        template_px: 256,
        ..small_params()
    };
    let o = Options {
        min_inliers: 11,
        first_fix_rounds: 1,
        ..opts(&p)
    };
    assert_eq!(o.first_fix_sigma_scale, 4.0);
    // 10 of 20 at the solver's gate, all 20 at the wider one.
    let all = |pairs: &[Correspondence], mask: &mut [bool]| {
        let mut s = even_inliers(at_x(0.3), pairs, mask);
        mask.iter_mut().take(pairs.len()).for_each(|m| *m = true);
        s.inliers = pairs.len() as u16;
        s
    };
    let solver = FakeSolver::new(|_, pairs, mask| Ok(even_inliers(at_x(0.3), pairs, mask)))
        .with_wide(move |_, pairs, mask| Ok(all(pairs, mask)));
    let mut r = Relocalizer::new(FakeAttempt::ok(), solver, &p, &o, &at_x(0.0), 1).unwrap();
    let out = r.run_to_completion(0);
    // The first fix came from the second solve of the first round; every
    // later round solved at the solver's own gate and failed, as Stall and
    // Reseed rounds (no second solve after a fix).
    assert_eq!(out.stats.widened_solves, 1);
    assert_eq!(out.stats.successes, 1);
    assert_eq!(out.log.count(FailureCode::RelocNoConsensus), 0);
    let scales = &r.solver_ref().scales;
    assert_eq!(scales.get(..2), Some(&[1.0, 4.0][..]));
    assert!(scales.iter().skip(2).all(|&s| s == 1.0), "{scales:?}");
    assert_eq!(out.stats.solves as usize, scales.len());
    // The same pairs went to both solves of the first round.
    let calls = &r.solver_ref().calls;
    assert_eq!(calls.first(), calls.get(1));

    // Without consensus at the wider gate either, the round fails as before.
    let never = || {
        FakeSolver::new(|_, pairs, mask| Ok(even_inliers(at_x(0.3), pairs, mask)))
            .with_wide(|_, pairs, mask| Ok(even_inliers(at_x(0.3), pairs, mask)))
    };
    let out = Relocalizer::new(FakeAttempt::ok(), never(), &p, &o, &at_x(0.0), 1)
        .unwrap()
        .run_to_completion(0);
    assert_eq!(out.failure, Some(FailureCode::RelocNoConsensus));
    assert_eq!((out.stats.solves, out.stats.widened_solves), (2, 1));

    // Scale 1 (ℓ ≤ 64 by default): no second solve.
    let o1 = Options {
        first_fix_sigma_scale: 1.0,
        ..o
    };
    let out = Relocalizer::new(FakeAttempt::ok(), never(), &p, &o1, &at_x(0.0), 1)
        .unwrap()
        .run_to_completion(0);
    assert_eq!((out.stats.solves, out.stats.widened_solves), (1, 0));
    assert_eq!(
        Options::for_params(&small_params()).first_fix_sigma_scale,
        1.0
    );

    // Out-of-range scales are refused.
    for bad in [0.5, f32::NAN, 16.5] {
        let ob = Options {
            first_fix_sigma_scale: bad,
            ..o
        };
        let err = Relocalizer::new(FakeAttempt::ok(), never(), &p, &ob, &at_x(0.0), 1).err();
        assert_eq!(err, Some(FailureCode::ConfigParamOutOfRange), "{bad}");
    }
}

/// Verifies: VTSM-RELOC-012
#[test]
fn budget_returns_best_pose_so_far() {
    let p = small_params();
    let mk = |budget: Budget| {
        let solver = FakeSolver::new(|call, pairs, mask| {
            Ok(even_inliers(at_x(0.1 * (call + 1) as f32), pairs, mask))
        });
        let o = Options { budget, ..opts(&p) };
        Relocalizer::new(FakeAttempt::ok(), solver, &p, &o, &at_x(0.0), 1).unwrap()
    };
    // Two full iterations (20 attempts + 1 solve each), then part of a third.
    let mut r = mk(Budget {
        max_work_units: 2 * 21 + 5,
        deadline_tick: u64::MAX,
    });
    let out = r.run_to_completion(0);
    assert_eq!(out.failure, Some(FailureCode::RelocBudgetExhausted));
    assert_eq!(out.stats.work_units, 47);
    assert_eq!(out.stats.successes, 2);
    assert_eq!(out.pose, at_x(0.2));
    assert_eq!(out.quality.history.len(), 2);
    // Tick deadline: work stops at the first step at or after it.
    let mut r = mk(Budget {
        max_work_units: u32::MAX,
        deadline_tick: 100,
    });
    for now in 0..30 {
        assert!(matches!(r.step(now), StepResult::Running));
    }
    match r.step(100) {
        StepResult::Done(o) => {
            assert_eq!(o.failure, Some(FailureCode::RelocBudgetExhausted));
            assert_eq!(o.stats.work_units, 30);
            assert_eq!(o.pose, at_x(0.1));
        }
        StepResult::Running => panic!("deadline ignored"),
    }
    assert!(matches!(r.step(0), StepResult::Done(_)));
}

/// Verifies: VTSM-RELOC-013
#[test]
fn multi_seed_continues_from_the_seed_with_most_inliers() {
    let mut p = small_params();
    p.seeds = 12;
    let truth = Vec3::new(0.3, -0.2, 0.0);
    // Inliers fall with the distance of the viewpoints' mean to the truth.
    let solver = FakeSolver::new(move |_, pairs, mask| {
        let mean = pairs.iter().fold(Vec3::zeros(), |a, c| a + c.cam) / pairs.len() as f32;
        let d = (mean - truth).norm();
        let n = (20.0 * (1.0 - d)).clamp(0.0, 20.0) as u16;
        for (i, m) in mask.iter_mut().enumerate() {
            *m = (i as u16) < n;
        }
        Ok(Solution {
            pose: Pose::new(UnitQuaternion::identity(), mean),
            inliers: n,
            rms_m: d,
            iterations: 1,
            candidates: heapless::Vec::new(),
        })
    });
    let mut o = opts(&p);
    o.seed_t_m = 0.6;
    let mut r = Relocalizer::new(FakeAttempt::ok(), solver, &p, &o, &at_x(0.0), 11).unwrap();
    let out = r.run_to_completion(0);
    assert_eq!(out.stats.seeds_tried, 12);
    let calls = &r.solver_ref().calls;
    let inl = |c: &Vec<Correspondence>| {
        let mean = c.iter().fold(Vec3::zeros(), |a, x| a + x.cam) / c.len() as f32;
        (20.0 * (1.0 - (mean - truth).norm())).clamp(0.0, 20.0) as u16
    };
    let best = calls[..12].iter().map(inl).max().unwrap();
    assert_eq!(out.quality.history[0].inliers, best);
    // Each seed is a planar draw within the seed spread of the prior.
    for c in &r.attempt_ref().contexts[..12 * 20] {
        let t = c.world_from_viewpoint.translation();
        assert!(t.norm() <= o.seed_t_m + p.t0_m + 1e-5);
        assert!(t.z.abs() < 1e-6);
    }
}

fn noisy_run(seed: u64, p: &Params, how: u32) -> (Outcome, Vec<AttemptContext>) {
    let attempt =
        FakeAttempt::new(|_, rng| (rng.next_f32() < 0.3).then_some(FailureCode::NccAmbiguous));
    let solver = FakeSolver::new(|call, pairs, mask| {
        if call % 3 == 1 {
            Err(FailureCode::PoseRansacNoConsensus)
        } else {
            let mean = pairs.iter().fold(Vec3::zeros(), |a, c| a + c.cam) / pairs.len() as f32;
            let mut s = even_inliers(Pose::new(UnitQuaternion::identity(), mean), pairs, mask);
            s.candidates
                .push(Candidate {
                    pose: s.pose,
                    inliers: s.inliers,
                })
                .unwrap();
            s.candidates
                .push(Candidate {
                    pose: at_x(mean.x + 0.01),
                    inliers: 3,
                })
                .unwrap();
            Ok(s)
        }
    });
    let mut r = Relocalizer::new(attempt, solver, p, &opts(p), &at_x(0.2), seed).unwrap();
    let out = match how {
        0 => r.run_to_completion(0),
        // One stage at a time: an attempt without a staged form is one stage.
        u32::MAX => loop {
            match r.step_stage(0) {
                (_, StepResult::Done(o)) => break o.clone(),
                (Some(Stage::Attempt | Stage::Pose), StepResult::Running) => {}
                (stage, _) => panic!("unexpected stage {stage:?}"),
            }
        },
        n => loop {
            if let StepResult::Done(o) = r.step_n(0, n) {
                break o.clone();
            }
        },
    };
    (out, r.attempt_ref().contexts.clone())
}

/// Verifies: VTSM-RELOC-014
#[test]
fn outcome_is_bit_identical_whatever_the_step_granularity() {
    let mut p = small_params();
    p.seeds = 3;
    for seed in [1u64, 2, 99] {
        let (a, ca) = noisy_run(seed, &p, 0);
        for n in [1u32, 7, 1000, u32::MAX] {
            let (b, cb) = noisy_run(seed, &p, n);
            let bits = |o: &Outcome| {
                o.pose
                    .t()
                    .map(f32::to_bits)
                    .into_iter()
                    .chain(o.pose.q().map(f32::to_bits))
                    .collect::<Vec<_>>()
            };
            assert_eq!(bits(&a), bits(&b), "seed {seed} granularity {n}");
            assert_eq!(a.stats, b.stats);
            assert_eq!(a.quality, b.quality);
            assert_eq!(a.failure, b.failure);
            assert_eq!(ca, cb);
            assert_eq!(
                a.log.counters().collect::<Vec<_>>(),
                b.log.counters().collect::<Vec<_>>()
            );
        }
        // A different seed explores different viewpoints.
        let (_, other) = noisy_run(seed + 1000, &p, 0);
        assert_ne!(ca[0], other[0]);
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]
    /// Verifies: VTSM-RELOC-003
    #[test]
    fn every_work_counter_stays_under_its_cap(
        seed in 0u64..1_000_000,
        n_corr in 3u16..40,
        n_iter in 1u8..6,
        extra in 0u32..60,
        max_stall in 1u8..4,
        max_reseed in 1u8..4,
        seeds in 0u16..4,
        p_fail in 0.0f32..0.9,
        s_fail in 0u32..4,
        mech in 0u8..32,
    ) {
        let p = Params {
            n_corr, n_iter, attempts_per_iter: u32::from(n_corr) + extra,
            max_stall, max_reseed, seeds, ransac_iter: 50,
            mechanisms: Mechanisms {
                stall: mech & 1 != 0, reseed: mech & 2 != 0, anneal: mech & 4 != 0,
                distribute: mech & 8 != 0, reuse: mech & 16 != 0,
            },
            ..small_params()
        };
        let attempt = FakeAttempt::new(move |_, rng| {
            (rng.next_f32() < p_fail).then_some(FailureCode::NccLowScore)
        });
        let solver = FakeSolver::new(move |call, pairs, mask| {
            if s_fail > 0 && call % (s_fail + 1) == 0 {
                return Err(FailureCode::PoseRansacNoConsensus);
            }
            let mut s = even_inliers(at_x(0.01 * call as f32), pairs, mask);
            s.iterations = 50;
            Ok(s)
        });
        let o = Options { min_inliers: 3, gates: super::super::Gates::OFF, ..Options::for_params(&p) };
        let mut r = Relocalizer::new(attempt, solver, &p, &o, &at_x(0.0), seed).unwrap();
        let max = Relocalizer::<FakeAttempt, FakeSolver>::max_work_units(&p);
        let mut calls = 0u64;
        let out = loop {
            calls += 1;
            if let StepResult::Done(o) = r.step(0) { break o.clone(); }
        };
        let s = out.stats;
        proptest::prop_assert!(out.failure != Some(FailureCode::RelocBudgetExhausted));
        proptest::prop_assert!(calls <= u64::from(max) + 1);
        proptest::prop_assert_eq!(s.work_units, s.attempts + s.solves + s.ransac_chunks + s.verify_units);
        proptest::prop_assert_eq!(s.ransac_chunks, 0);
        proptest::prop_assert!(s.attempts <= s.rounds * p.attempts_per_iter);
        proptest::prop_assert!(s.successes <= u16::from(p.n_iter));
        proptest::prop_assert!(s.stalls <= u16::from(p.max_stall) * (s.successes + 1));
        proptest::prop_assert!(s.reseeds <= u16::from(p.max_reseed) * (s.successes + 1));
        proptest::prop_assert!(s.seeds_tried <= p.seeds);
        proptest::prop_assert!(s.ransac_iterations <= s.solves * u32::from(p.ransac_iter));
        proptest::prop_assert!(out.quality.history.len() == usize::from(s.successes));
        let calls = &r.solver_ref().calls;
        proptest::prop_assert!(calls.iter().all(|c| c.len() == usize::from(p.n_corr)));
        // No round does more attempts than the per-iteration cap.
        let mut per_round = std::collections::BTreeMap::<u32, u32>::new();
        for c in &r.attempt_ref().contexts {
            *per_round.entry(c.round).or_default() += 1;
        }
        proptest::prop_assert!(per_round.values().all(|n| *n <= p.attempts_per_iter));
        proptest::prop_assert!(per_round.len() as u32 <= s.rounds);
    }
}
