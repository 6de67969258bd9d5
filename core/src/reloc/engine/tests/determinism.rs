//! Bit-identical outcomes whatever the step granularity, and the bounds of
//! every step.

use super::*;

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
        let o = Options { min_inliers: 3, gates: crate::reloc::Gates::OFF, ..Options::for_params(&p) };
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
