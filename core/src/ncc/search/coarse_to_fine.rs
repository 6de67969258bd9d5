//! The coarse-to-fine search over the pyramid: every position of the coarsest
//! level scored, the separated peaks kept, each refined level by level by a
//! bounded climb to the full-resolution candidates.

use super::{eval_positions, ArgMax, Positions, Strip, TopK};
use crate::fmt::present;
use crate::ncc::integral::Tables;
use crate::ncc::pyramid::{refine_plan, whole_level_tables, Tpl, Win};
use crate::ncc::{
    peak_radius_px, FailureCode, MatchStats, SearchConfig, MAX_CANDIDATES, MAX_CLIMB_STEPS,
    MAX_LEVELS,
};

/// Region centres already evaluated at one level: a climb that reaches one
/// stops, since the candidate that evaluated it carries that climb on (the
/// result is the same, without scoring the same positions twice).
struct Visited {
    centres: [(usize, usize); MAX_CANDIDATES * (MAX_CLIMB_STEPS + 1)],
    len: usize,
}

impl Visited {
    /// No centre visited.
    fn new() -> Self {
        Self {
            centres: [(usize::MAX, usize::MAX); MAX_CANDIDATES * (MAX_CLIMB_STEPS + 1)],
            len: 0,
        }
    }

    /// Record `c`; `false` when it was visited already.
    fn visit(&mut self, c: (usize, usize)) -> bool {
        let seen = present(self.centres.get(..self.len));
        if seen.contains(&c) {
            return false;
        }
        if let Some(v) = self.centres.get_mut(self.len) {
            *v = c;
            // `get_mut` succeeded: len < centres.len().
            self.len = self.len.wrapping_add(1);
        }
        true
    }
}

/// The template and window of level `k`.
fn level<'s>(
    tpls: &[Option<Tpl<'s>>; MAX_LEVELS],
    wins: &[Option<Win<'s>>; MAX_LEVELS],
    k: usize,
) -> Result<(Tpl<'s>, Win<'s>), FailureCode> {
    match (
        tpls.get(k).copied().flatten(),
        wins.get(k).copied().flatten(),
    ) {
        (Some(t), Some(w)) => Ok((t, w)),
        _ => Err(FailureCode::NccScratchTooSmall),
    }
}

/// Score every position of the coarsest level, keep the separated peaks, and
/// refine each at every finer level; returns the full-resolution candidates,
/// best first (the first is the winner).
#[allow(clippy::too_many_arguments)]
#[allow(
    clippy::cast_possible_truncation,
    reason = "a TopK holds at most MAX_CANDIDATES (< 256) entries"
)]
pub(in crate::ncc) fn coarse_to_fine(
    tpls: &[Option<Tpl>; MAX_LEVELS],
    wins: &[Option<Win>; MAX_LEVELS],
    levels: usize,
    (tw, th, ww, wh): (usize, usize, usize, usize),
    cfg: &SearchConfig,
    tables: &mut Tables,
    strip: &mut Strip,
    stats: &mut MatchStats,
) -> Result<TopK, FailureCode> {
    let radius0 = peak_radius_px(tw, th);
    let lc = levels.saturating_sub(1);
    let (tc, wc) = level(tpls, wins, lc)?;
    let (lx, ly) = wc.last_pos(tc.w, tc.h);
    tables.level(lc, &wc, true)?;
    let mut top = if lc == 0 {
        TopK::new(2, radius0)
    } else {
        TopK::new(cfg.candidates, cfg.nms_radius_px)
    };
    eval_positions(
        &tc,
        (lc, &wc),
        Positions::all((0, 0, lx, ly)),
        tables,
        strip,
        stats,
        &mut top,
    )?;
    stats.candidates = top.len as u8;

    for k in (0..lc).rev() {
        let (t, w) = level(tpls, wins, k)?;
        let (lx, ly) = w.last_pos(t.w, t.h);
        let (r, keep) = refine_plan(tw, th, k, lc, cfg);
        tables.level(k, &w, whole_level_tables(tw, th, ww, wh, k, lc, cfg))?;
        let mut next = TopK::new(MAX_CANDIDATES, 0);
        let mut visited = Visited::new();
        for c in top.as_slice().iter().take(keep) {
            let start = (c.x.saturating_mul(2).min(lx), c.y.saturating_mul(2).min(ly));
            let best = climb(
                &t,
                (k, &w),
                start,
                (r, lx, ly),
                &mut visited,
                (&mut *tables, &mut *strip),
                stats,
            )?;
            if let Some(b) = best.0 {
                next.offer(b);
            }
        }
        top = next;
    }
    Ok(top)
}

/// Refine one candidate at level `k` from `start` (its position one level
/// up, doubled): score the square of radius `r` around the centre (inside the
/// last position `(lx, ly)`), and move the centre to the region's argmax while
/// that sits on a border that is not the window's edge, at most
/// [`MAX_CLIMB_STEPS`] times, stopping at a centre already visited. Returns
/// the argmax of every region scored (ties keep the first offered).
fn climb(
    t: &Tpl,
    (k, w): (usize, &Win),
    start: (usize, usize),
    (r, lx, ly): (usize, usize, usize),
    visited: &mut Visited,
    (tables, strip): (&mut Tables, &mut Strip),
    stats: &mut MatchStats,
) -> Result<ArgMax, FailureCode> {
    let mut center = start;
    let mut best = ArgMax::default();
    // The region of the step before: its positions are in `best` already.
    let mut scored: Option<(usize, usize, usize, usize)> = None;
    for _ in 0..=MAX_CLIMB_STEPS {
        if !visited.visit(center) {
            break;
        }
        let (cx, cy) = center;
        let bounds = (
            cx.saturating_sub(r),
            cy.saturating_sub(r),
            cx.saturating_add(r).min(lx),
            cy.saturating_add(r).min(ly),
        );
        let at = Positions {
            bounds,
            skip: scored,
        };
        eval_positions(t, (k, w), at, tables, strip, stats, &mut best)?;
        scored = Some(bounds);
        let Some(b) = best.0.as_ref() else {
            break;
        };
        // Stop unless the peak sits on a border that is not the window's edge.
        let on_edge = (b.x == bounds.0 && b.x > 0)
            || (b.x == bounds.2 && b.x < lx)
            || (b.y == bounds.1 && b.y > 0)
            || (b.y == bounds.3 && b.y < ly);
        if !on_edge || (b.x, b.y) == center {
            break;
        }
        center = (b.x, b.y);
    }
    Ok(best)
}
