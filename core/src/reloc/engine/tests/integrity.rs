//! The integrity gates and the upset checks (repeated solve, map re-check) on a
//! success.

use super::*;

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
            gates: crate::reloc::Gates {
                prior_factor: 3.0,
                ..crate::reloc::Gates::OFF
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
        gates: crate::reloc::Gates {
            prior_factor: 0.5,
            ..crate::reloc::Gates::OFF
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
    let verify = crate::reloc::Verify::for_params(&p);
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
            verify: crate::reloc::Verify {
                recheck_map: on,
                ..crate::reloc::Verify::off(&p)
            },
            ..opts(&p)
        };
        let mut r = Relocalizer::new(attempt, solver, &p, &o, &at_x(0.0), 1).unwrap();
        let out = r.run_to_completion(0);
        assert_eq!(out.failure, want);
        assert_eq!(r.attempt_ref().rechecks, u32::from(on));
    }
}
