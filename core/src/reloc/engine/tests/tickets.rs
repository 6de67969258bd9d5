//! Attempts handed out as tickets to several workers, finished in any order
//! and taken back in attempt order: the outcome is bit-identical to one
//! worker's, and stale work is never counted.

use super::*;
use crate::reloc::{work_ticket, Commit, Worked};
use std::collections::BTreeMap;
use std::vec;

/// An attempt whose result depends only on its context and random stream
/// (what a worker's pipeline is): pairs seen from `truth` with a unique id
/// from the attempt index, rejected when the stream says so.
#[derive(Clone, Copy)]
struct PureAttempt {
    truth: Pose,
    p_fail: f32,
}

impl Attempt for PureAttempt {
    fn attempt(
        &mut self,
        ctx: &AttemptContext,
        rng: &mut Rng,
        stats: &mut PipelineStats,
    ) -> Result<Correspondence, FailureCode> {
        stats.renders += 1;
        stats.ncc_macs += u64::from(ctx.index % 7);
        stats.near_drawn += u32::from(ctx.near.is_some());
        if rng.next_f32() < self.p_fail {
            return Err(FailureCode::NccLowScore);
        }
        let cam = Vec3::new(
            2.0 * rng.next_f32() - 1.0,
            2.0 * rng.next_f32() - 1.0,
            2.0 + 2.0 * rng.next_f32(),
        );
        // The viewpoint moves the point a little, so Focus and Distribute
        // change what later attempts see; so does a Near vertex.
        let near = ctx.near.map_or(0.0, |k| (k % 5) as f32 * 0.001);
        let v = ctx.world_from_viewpoint.translation() * 0.01;
        Ok(Correspondence {
            world: self.truth.transform_point(&cam) + v + Vec3::new(near, 0.0, 0.0),
            cam,
            sigma_m: 0.01,
            variant: (ctx.index % 3) as u8,
            mask_index: ctx.index,
        })
    }
}

fn solver() -> FakeSolver {
    FakeSolver::new(|call, pairs, mask| {
        if call % 4 == 2 {
            return Err(FailureCode::PoseRansacNoConsensus);
        }
        let mean =
            pairs.iter().fold(Vec3::zeros(), |a, c| a + c.world - c.cam) / pairs.len() as f32;
        let mut n = 0u16;
        for (i, m) in mask.iter_mut().take(pairs.len()).enumerate() {
            *m = i % 3 != 0;
            n += u16::from(*m);
        }
        let mut s = Solution {
            pose: Pose::new(UnitQuaternion::identity(), mean),
            inliers: n,
            rms_m: 0.01,
            iterations: 10,
            candidates: heapless::Vec::new(),
        };
        s.candidates
            .push(Candidate {
                pose: s.pose,
                inliers: n,
            })
            .unwrap();
        Ok(s)
    })
}

type Engine = Relocalizer<PureAttempt, FakeSolver>;

fn engine(p: &Params, o: &Options, seed: u64) -> Engine {
    let a = PureAttempt {
        truth: at_x(0.3),
        p_fail: 0.35,
    };
    Relocalizer::new(a, solver(), p, o, &at_x(0.0), seed).unwrap()
}

/// Drive `r` with `workers` workers and `window` tickets in flight; each
/// step the worker chosen by a scrambling stream finishes its ticket, so
/// results come back out of order. Returns the tickets whose work was
/// dropped as stale.
fn drive_tickets(r: &mut Engine, workers: usize, window: u32, scramble: u64) -> u32 {
    let mut pipes = vec![*r.attempt_ref(); workers];
    let mut order = Rng::new(scramble);
    // Index -> (worker, finished work).
    let mut flight: BTreeMap<u32, Option<Worked>> = BTreeMap::new();
    let mut dropped = 0u32;
    for _ in 0..100_000 {
        if r.outcome().is_some() {
            return dropped;
        }
        if !r.collecting() {
            dropped += flight.len() as u32;
            flight.clear();
            let _ = r.step(0);
            continue;
        }
        let next = r.stats().attempts + flight.len() as u32;
        for i in next..next + window.saturating_sub(flight.len() as u32) {
            match r.ticket(i) {
                Some(_) => {
                    flight.insert(i, None);
                }
                None => break,
            }
        }
        if flight.is_empty() {
            // No ticket can be handed out (the budget): the engine ends it.
            let _ = r.step(0);
            continue;
        }
        // A random unfinished ticket finishes on a random worker.
        let open: Vec<u32> = flight
            .iter()
            .filter(|(_, w)| w.is_none())
            .map(|(i, _)| *i)
            .collect();
        if let Some(&i) = open.get(order.below(open.len() as u32) as usize) {
            let w = order.below(workers as u32) as usize;
            let t = r.ticket(i).unwrap();
            flight.insert(i, Some(work_ticket(&mut pipes[w], &t)));
        }
        // Take back every finished ticket in attempt order.
        while let Some(Some(w)) = flight.first_key_value().map(|(_, w)| *w) {
            flight.pop_first();
            match r.commit(&w, 0) {
                Commit::Taken { keep: true } => {}
                Commit::Taken { keep: false } | Commit::Ended => {
                    dropped += flight.len() as u32;
                    flight.clear();
                }
                Commit::Stale => panic!("ticket {} stale in order", w.ticket.index()),
            }
        }
    }
    panic!("the ticket drive did not end");
}

fn same(a: &Outcome, b: &Outcome) {
    assert_eq!(a.pose.t().map(f32::to_bits), b.pose.t().map(f32::to_bits));
    assert_eq!(a.pose.q().map(f32::to_bits), b.pose.q().map(f32::to_bits));
    assert_eq!(a.failure, b.failure);
    assert_eq!(a.stats, b.stats);
    assert_eq!(a.quality, b.quality);
    assert_eq!(
        a.log.counters().collect::<Vec<_>>(),
        b.log.counters().collect::<Vec<_>>()
    );
}

/// Verifies: VTSM-RELOC-043
#[test]
fn tickets_on_any_number_of_workers_give_the_one_worker_outcome() {
    let mut focused = 0;
    let mut any_dropped = 0;
    let mut near_drawn = 0;
    let nears = [
        Near::OFF,
        Near {
            share_256: 256,
            radius_m: 0.25,
        },
        Near {
            share_256: 128,
            radius_m: 0.25,
        },
    ];
    for (k, seeds, t0, units, near) in [
        (1u64, 0u16, 0.5f32, u32::MAX, 0usize),
        (2, 2, 0.5, u32::MAX, 0),
        (3, 0, DEFAULT_T0_M, u32::MAX, 0),
        (4, 0, 0.5, 40, 0),
        (5, 0, 0.5, u32::MAX, 1),
        (6, 2, DEFAULT_T0_M, u32::MAX, 1),
        (7, 0, 0.5, u32::MAX, 2),
    ] {
        let mut p = small_params();
        p.seeds = seeds;
        p.t0_m = t0;
        let mut o = opts(&p).with_near(nears[near]).unwrap();
        o.budget = Budget {
            max_work_units: units,
            ..Budget::UNLIMITED
        };
        let one = engine(&p, &o, k).run_to_completion(0);
        focused += one.stats.focused_rounds;
        near_drawn += one.stats.pipeline.near_drawn;
        for (workers, window) in [(1usize, 1u32), (2, 2), (3, 6), (8, 16)] {
            let mut r = engine(&p, &o, k);
            any_dropped += drive_tickets(&mut r, workers, window, k * 31 + workers as u64);
            same(&one, r.outcome().unwrap());
        }
        if units < u32::MAX {
            assert_eq!(one.failure, Some(FailureCode::RelocBudgetExhausted));
        }
    }
    // The cases exercise Focus, Near and work thrown away as stale.
    assert!(focused > 0);
    assert!(near_drawn > 0);
    assert!(any_dropped > 0);
}

/// Verifies: VTSM-RELOC-043
#[test]
fn a_ticket_that_is_not_next_or_drawn_before_a_change_is_stale() {
    let p = small_params();
    let mut r = engine(&p, &opts(&p), 5);
    let mut pipe = *r.attempt_ref();
    // Not handed out behind the next attempt or beyond the round's cap.
    assert!(r.ticket(p.attempts_per_iter).is_none());
    let t0 = r.ticket(0).unwrap();
    let t1 = r.ticket(1).unwrap();
    let w1 = work_ticket(&mut pipe, &t1);
    // Out of order: refused, nothing counted.
    assert_eq!(r.commit(&w1, 0), Commit::Stale);
    assert_eq!(r.stats().attempts, 0);
    let w0 = work_ticket(&mut pipe, &t0);
    assert!(matches!(r.commit(&w0, 0), Commit::Taken { .. }));
    // Twice: refused.
    assert_eq!(r.commit(&w0, 0), Commit::Stale);
    assert_eq!(r.stats().attempts, 1);
    assert_eq!(r.stats().pipeline.renders, 1);
    // Run to the solve: a ticket of the old round is stale in the next one.
    while r.collecting() {
        let t = r.ticket(r.stats().attempts).unwrap();
        let w = work_ticket(&mut pipe, &t);
        let _ = r.commit(&w, 0);
    }
    assert!(r.ticket(r.stats().attempts).is_none());
    let old = r.stats().attempts;
    while !r.collecting() && r.outcome().is_none() {
        let _ = r.step(0);
    }
    let stale = Worked {
        ticket: {
            // Drawn under the finished round, at the index now due.
            let mut t = t0;
            t.ctx.index = old;
            t
        },
        ..w0
    };
    assert_eq!(r.commit(&stale, 0), Commit::Stale);
    // A deadline reached ends the run with the anytime result.
    let mut o = opts(&p);
    o.budget.deadline_tick = 10;
    let mut r = engine(&p, &o, 5);
    let w = work_ticket(&mut pipe, &r.ticket(0).unwrap());
    assert_eq!(r.commit(&w, 10), Commit::Ended);
    assert_eq!(
        r.outcome().unwrap().failure,
        Some(FailureCode::RelocBudgetExhausted)
    );
}
