//! The §III-E mechanisms: Stall and Reseed, Anneal, Reuse, the gradient-only
//! final round, Distribute, convergence.

use super::*;

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
                .filter(|q| !crate::reloc::policy::is_gradient_variant(q.variant))
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

/// `Options::final_pairs` makes the last round collect that many pairs (the
/// others N_corr), within the round's attempt cap; when the cap comes first
/// the last round solves on what it has (N_corr or more), and 0 or a count
/// outside N_corr..=MAX_CORR is the default or refused.
///
/// Verifies: VTSM-RELOC-044
#[test]
fn the_last_round_collects_its_own_count_of_pairs() {
    let p = small_params();
    let run = |final_pairs: u16, fail_every: Option<u32>| {
        let o = opts(&p).with_final_pairs(final_pairs).unwrap();
        let solver = FakeSolver::new(|call, pairs, mask| {
            Ok(even_inliers(at_x(0.1 * (call + 1) as f32), pairs, mask))
        });
        let attempt = match fail_every {
            Some(k) => {
                FakeAttempt::new(move |i, _| (i % k != 0).then_some(FailureCode::NccWindowFlat))
            }
            None => FakeAttempt::ok(),
        };
        let mut r = Relocalizer::new(attempt, solver, &p, &o, &at_x(0.0), 5).unwrap();
        let out = r.run_to_completion(0);
        assert!(out.failure.is_none(), "{:?}", out.failure);
        let sizes: Vec<usize> = r.solver_ref().calls.iter().map(Vec::len).collect();
        (sizes, out.stats.attempts)
    };
    let n = usize::from(p.n_corr);
    let (plain, plain_attempts) = run(0, None);
    assert_eq!(plain, std::vec![n; usize::from(p.n_iter)]);
    let (more, more_attempts) = run(45, None);
    let mut expect = std::vec![n; usize::from(p.n_iter)];
    *expect.last_mut().unwrap() = 45;
    assert_eq!(more, expect);
    assert!(more_attempts > plain_attempts);
    // One attempt in two matches: the last round reaches its cap of 50
    // attempts before 45 pairs and solves on what it has.
    let (capped, _) = run(45, Some(2));
    let last = *capped.last().unwrap();
    assert!((n..45).contains(&last), "{capped:?}");
    assert!(capped[..capped.len() - 1].iter().all(|&k| k == n));
    // Refused: above MAX_CORR at once, below N_corr where options meet params.
    assert_eq!(
        opts(&p).with_final_pairs(crate::config::MAX_CORR as u16 + 1),
        Err(FailureCode::ConfigParamOutOfRange)
    );
    let low = opts(&p).with_final_pairs(p.n_corr - 1).unwrap();
    let solver = FakeSolver::new(|_, pairs, mask| Ok(even_inliers(at_x(0.0), pairs, mask)));
    assert!(Relocalizer::new(FakeAttempt::ok(), solver, &p, &low, &at_x(0.0), 5).is_err());
}

/// A successful run of `p` and `o` whose every attempt makes a pair and
/// whose solves keep the even pairs as inliers at a pose moving 0.1 m per
/// call: the engine, its outcome and the rounds its attempts ran in.
fn run_moving(
    p: &Params,
    o: &Options,
) -> (Relocalizer<FakeAttempt, FakeSolver>, Outcome, Vec<u32>) {
    let solver = FakeSolver::new(|call, pairs, mask| {
        Ok(even_inliers(at_x(0.1 * (call + 1) as f32), pairs, mask))
    });
    let mut r = Relocalizer::new(FakeAttempt::ok(), solver, p, o, &at_x(0.0), 5).unwrap();
    let out = r.run_to_completion(0);
    assert!(out.failure.is_none(), "{:?}", out.failure);
    let mut rounds: Vec<u32> = r.attempt_ref().contexts.iter().map(|c| c.round).collect();
    rounds.dedup();
    (r, out, rounds)
}

/// Revisit: after a pose update, the next round's first attempts carry, one
/// each and in collection order, the mask vertices of that update's inliers
/// that Reuse did not keep; the round's other attempts, the first round's
/// and every attempt with Revisit off carry none.
/// Verifies: VTSM-RELOC-046
#[test]
fn revisit_hands_the_unkept_inliers_to_the_next_rounds_first_attempts() {
    for on in [true, false] {
        let p = small_params();
        let (r, _, rounds) = run_moving(&p, &opts(&p).with_revisit(on));
        let calls = &r.solver_ref().calls;
        assert_eq!(calls.len(), usize::from(p.n_iter));
        let contexts = &r.attempt_ref().contexts;
        assert_eq!(rounds.len(), calls.len());
        let mut revisited = 0u32;
        for (k, round) in rounds.iter().enumerate() {
            // The fake gives every pair a fresh id (its mask index): the
            // pairs of solve k − 1 still in solve k are the ones Reuse kept.
            let expected: Vec<u32> = match k.checked_sub(1) {
                Some(prev) if on => calls[prev]
                    .iter()
                    .filter(|c| c.mask_index % 2 == 0)
                    .filter(|c| calls[k].iter().all(|q| q.mask_index != c.mask_index))
                    .map(|c| c.mask_index)
                    .collect(),
                _ => Vec::new(),
            };
            let given: Vec<Option<u32>> = contexts
                .iter()
                .filter(|c| c.round == *round)
                .map(|c| c.revisit)
                .collect();
            assert!(given.len() > expected.len());
            for (i, g) in given.iter().enumerate() {
                assert_eq!(*g, expected.get(i).copied(), "{on} round {k} attempt {i}");
            }
            revisited += expected.len() as u32;
        }
        assert_eq!(revisited > 0, on);
    }
}

/// Near: in the rounds after a pose update but the last, a drawn attempt
/// (no revisit vertex) carries, with the stated share, a vertex of a pair
/// that agreed with that update (an inlier of the previous solve, kept by
/// Reuse or not); never in the first or the last round, never with Near off.
/// Verifies: VTSM-RELOC-047
#[test]
fn near_draws_around_the_vertices_that_agreed() {
    let near = |share_256| Near {
        share_256,
        radius_m: 0.25,
    };
    for share in [256, 128, 0] {
        let p = small_params();
        let (r, out, rounds) = run_moving(&p, &opts(&p).with_near(near(share)).unwrap());
        let calls = &r.solver_ref().calls;
        let contexts = &r.attempt_ref().contexts;
        assert_eq!(rounds.len(), calls.len());
        assert!(rounds.len() >= 3, "a first, a middle and a last round");
        let (mut with, mut without) = (0u32, 0u32);
        for (k, round) in rounds.iter().enumerate() {
            // Every attempt makes a pair whose mask index is its own id.
            let agreed: Vec<u32> = match k.checked_sub(1) {
                Some(prev) => calls[prev]
                    .iter()
                    .filter(|c| c.mask_index % 2 == 0)
                    .map(|c| c.mask_index)
                    .collect(),
                None => Vec::new(),
            };
            let middle = k > 0 && k + 1 < rounds.len();
            for c in contexts.iter().filter(|c| c.round == *round) {
                match c.near {
                    Some(v) => {
                        assert!(
                            middle,
                            "share {share} round {k}: Near outside the middle rounds"
                        );
                        assert!(
                            c.revisit.is_none(),
                            "a revisit attempt draws no Near vertex"
                        );
                        assert_eq!(c.near_radius_m, 0.25);
                        assert!(agreed.contains(&v), "share {share} round {k}: vertex {v}");
                        with += 1;
                    }
                    None if middle && c.revisit.is_none() => without += 1,
                    None => {}
                }
            }
        }
        assert_eq!(out.stats.pipeline.near_drawn, 0, "the fake counts no draws");
        match share {
            0 => assert_eq!(with, 0),
            256 => assert!(with > 0 && without == 0, "{with} {without}"),
            // Half, within a wide margin on a few dozen draws.
            _ => assert!(with > 0 && without > 0 && with.abs_diff(without) < (with + without) / 2),
        }
    }
    // Refused: a share above 256, a radius out of (0, 10] m.
    let p = small_params();
    for bad in [
        near(257),
        Near {
            radius_m: 0.0,
            ..near(1)
        },
        Near {
            radius_m: f32::NAN,
            ..near(1)
        },
        Near {
            radius_m: 10.5,
            ..near(1)
        },
    ] {
        assert_eq!(
            opts(&p).with_near(bad),
            Err(FailureCode::ConfigParamOutOfRange),
            "{bad:?}"
        );
    }
}
