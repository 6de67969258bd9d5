//! Early stops and their codes, the first-fix second solve, budgets and the
//! multi-seed mode.

use super::*;

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
