//! Focus: re-centring a wide prior's round on the position its pairs agree on,
//! and its options.

use super::*;

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
