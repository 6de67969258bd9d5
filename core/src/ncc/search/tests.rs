extern crate std;
use super::super::test_util::*;
use super::super::*;
use super::*;
use crate::rng::Rng;
use std::vec::Vec;

/// The in-place `TopK::offer` keeps exactly the list the copying version
/// (the one before the in-place rewrite, kept here as the reference) keeps.
#[test]
fn top_k_offer_equals_copying_reference() {
    fn ref_offer(items: &mut Vec<Cand>, cap: usize, radius: usize, c: Cand) {
        let near = |a: &Cand, b: &Cand| a.x.abs_diff(b.x) <= radius && a.y.abs_diff(b.y) <= radius;
        if items.len() == cap && cmp_scores(&c.s, &items[cap - 1].s) != Ordering::Greater {
            return;
        }
        if items
            .iter()
            .any(|e| near(e, &c) && cmp_scores(&c.s, &e.s) != Ordering::Greater)
        {
            return;
        }
        let mut out = Vec::new();
        let mut placed = false;
        for e in items.iter().filter(|e| !near(e, &c)) {
            if !placed && cmp_scores(&c.s, &e.s) == Ordering::Greater {
                out.push(c);
                placed = true;
            }
            if out.len() < cap {
                out.push(*e);
            }
        }
        if !placed && out.len() < cap {
            out.push(c);
        }
        out.truncate(cap);
        *items = out;
    }
    let mut rng = Rng::new(32);
    for case in 0..300 {
        let cap = 1 + rng.below(MAX_CANDIDATES as u32) as usize;
        let radius = rng.below(4) as usize;
        let mut top = TopK::new(cap, radius);
        let mut want = Vec::new();
        for _ in 0..400 {
            // Few distinct values, so ties and near duplicates are common.
            let c = Cand {
                x: rng.below(30) as usize,
                y: rng.below(30) as usize,
                s: Score {
                    num: i64::from(rng.below(40)) - 10,
                    var_f: 1 + i64::from(rng.below(5)),
                    var_t: 7,
                },
            };
            top.offer(c);
            ref_offer(&mut want, cap, radius, c);
            let got: Vec<(usize, usize, Score)> =
                top.as_slice().iter().map(|e| (e.x, e.y, e.s)).collect();
            let exp: Vec<(usize, usize, Score)> = want.iter().map(|e| (e.x, e.y, e.s)).collect();
            assert_eq!(got, exp, "case {case}");
        }
    }
}

/// Agreement of coarse-to-fine with exhaustive search on `cases` textured
/// matches (template cut under gain, offset and noise), and the MACs of both.
fn agreement(seed: u64, cases: u32, filter: Filter, masked: bool) -> (u32, u64, u64) {
    agreement_with(
        seed,
        cases,
        filter,
        masked,
        &SearchConfig::for_filter(filter),
    )
}

fn agreement_with(
    seed: u64,
    cases: u32,
    filter: Filter,
    masked: bool,
    cfg: &SearchConfig,
) -> (u32, u64, u64) {
    let mut rng = Rng::new(seed);
    let mut agree = 0;
    let mut work = (0u64, 0u64);
    for case in 0..cases {
        let (l, iw, ih) = match case % 10 {
            0 => (128usize, 208usize, 200usize),
            1..=5 => (64, 150, 140),
            _ => (32, 120, 110),
        };
        let img = textured(iw, ih, &mut rng);
        let (tx, ty) = (
            rng.below((iw - l + 1) as u32) as usize,
            rng.below((ih - l + 1) as u32) as usize,
        );
        let gain = rng.uniform(0.7, 1.2);
        let off = rng.uniform(-20.0, 20.0);
        let t: Vec<u8> = crop(&img, iw, tx, ty, l, l)
            .iter()
            .map(|&v| {
                (f32::from(v) * gain + off + rng.uniform(-12.0, 12.0))
                    .round()
                    .clamp(0.0, 255.0) as u8
            })
            .collect();
        // A disc-shaped "rock" mask keeping about 60 % of the template.
        let mask: Vec<u8> = (0..l * l)
            .map(|i| {
                let (x, y) = ((i % l) as i64 - l as i64 / 2, (i / l) as i64 - l as i64 / 2);
                if 5 * (x * x + y * y) < 4 * (l * l / 4) as i64 {
                    255
                } else {
                    0
                }
            })
            .collect();
        let run = |mode| {
            let mut b = Bufs::with_config(l, l, iw, ih, mode, cfg);
            match_template_with(
                view(&t, l, l),
                masked.then(|| view(&mask, l, l)),
                view(&img, iw, ih),
                Rect::new(0, 0, iw as u32, ih as u32),
                filter,
                mode,
                cfg,
                &mut b.scratch(),
            )
            .unwrap()
        };
        let (e, es) = run(Search::Exhaustive);
        let (c, cs) = run(Search::CoarseToFine);
        work.0 += es.macs;
        work.1 += cs.macs;
        if (e.x, e.y) == (c.x, c.y) {
            assert_eq!(e.exact, c.exact);
            agree += 1;
        }
    }
    (agree, work.0, work.1)
}

/// Verifies: VTSM-NCC-012
#[test]
fn coarse_to_fine_agrees_with_exhaustive_on_textured_cases() {
    let cases = 200;
    let (agree, ex, ctf) = agreement(22, cases, Filter::Gray, false);
    let rate = f64::from(agree) / f64::from(cases);
    std::println!(
        "gray: coarse-to-fine == exhaustive on {agree}/{cases} = {:.1} %; MACs {ctf:.3e} vs {ex:.3e}",
        rate * 100.0
    );
    assert!(rate >= 0.99, "agreement {rate}");
    assert!(ctf * 5 < ex);
}

/// Verifies: VTSM-NCC-012
#[test]
fn coarse_to_fine_agrees_with_exhaustive_in_every_domain_and_masked() {
    for (filter, masked) in [
        (Filter::Gray, true),
        (Filter::Sobel, false),
        (Filter::Laplacian, false),
        (Filter::Sobel, true),
    ] {
        let cases = 100;
        let (agree, ex, ctf) = agreement(23, cases, filter, masked);
        let rate = f64::from(agree) / f64::from(cases);
        std::println!(
            "{filter:?} masked={masked}: coarse-to-fine == exhaustive on {agree}/{cases} = {:.1} %; MACs {ctf:.3e} vs {ex:.3e}",
            rate * 100.0
        );
        assert!(rate >= 0.95, "{filter:?} masked={masked}: agreement {rate}");
    }
}

/// The smallest and largest configurations, with the shallowest and deepest
/// pyramids, run in the scratch of [`ScratchSizes::with_config`], and the
/// largest agrees with the exhaustive search on the synthetic cases.
/// Verifies: VTSM-NCC-012
#[test]
fn every_search_config_agrees_on_textured_cases() {
    for min_coarse_px in [MIN_COARSE_PX, 64] {
        for (cand, radius) in [(1usize, 0usize), (MAX_CANDIDATES, MAX_REFINE_RADIUS_PX)] {
            let cfg = SearchConfig::for_filter(Filter::Sobel)
                .with_candidates(cand, cand)
                .and_then(|c| c.with_refine_radii_px(radius, radius, radius))
                .and_then(|c| c.with_coarse_px(min_coarse_px, min_coarse_px))
                .unwrap();
            let cases = 30;
            let (agree, _, _) = agreement_with(29, cases, Filter::Sobel, true, &cfg);
            std::println!("{cfg:?}: {agree}/{cases}");
            // The minimal search only has to run (its agreement is printed).
            let need = if cand == 1 { 0 } else { cases * 29 / 30 };
            assert!(agree >= need, "{cfg:?}: {agree}/{cases}");
        }
    }
}
