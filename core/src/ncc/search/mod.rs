//! Scoring positions: the [`Sink`]s that receive scored positions, the positions
//! one call scores, and [`eval_positions`], which turns window sums and Σ t·f
//! into scores. The scan itself is in `scan` (one per kernel), the candidate list
//! in `topk`, the search over the pyramid in `coarse_to_fine`.

use core::cmp::Ordering;

use super::integral::Tables;
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
use super::kernel::COL_BLOCK;
use super::pyramid::{Tpl, Win};
use super::{cmp_keys_f64, cmp_scores, FailureCode, MatchStats, Score};

mod coarse_to_fine;
mod scan;
#[cfg(test)]
mod tests;
mod topk;

pub(super) use coarse_to_fine::coarse_to_fine;
use scan::scan;
pub(super) use topk::TopK;

/// Receiver of the scored positions of [`eval_positions`], in raster order.
pub(super) trait Sink {
    /// A score such that offering any score not strictly better than it
    /// changes nothing (`None`: any offer may count). Read again after every
    /// offer; positions clearly below it are not offered.
    fn floor(&self) -> Option<Score>;
    /// Take the score of position `(x, y)`.
    fn offer(&mut self, x: usize, y: usize, s: Score);
}

/// The argmax of the offered positions (ties keep the first offered).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct ArgMax(pub(super) Option<Cand>);

impl Sink for ArgMax {
    #[inline]
    fn floor(&self) -> Option<Score> {
        self.0.map(|b| b.s)
    }

    #[inline]
    fn offer(&mut self, x: usize, y: usize, s: Score) {
        if self.0.as_ref().is_none_or(|b| beats(&s, &b.s)) {
            self.0 = Some(Cand { x, y, s });
        }
    }
}

/// The positions one [`eval_positions`] call scores: every top-left position
/// `(x, y)` with `x0 ≤ x ≤ x1`, `y0 ≤ y ≤ y1` (`bounds`) that does not lie in
/// `skip` (same form; `None` skips nothing). A climbing refinement step passes
/// the region it scored just before: those positions were offered to the same
/// [`ArgMax`] already, so offering them again could not change it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Positions {
    pub(super) bounds: (usize, usize, usize, usize),
    pub(super) skip: Option<(usize, usize, usize, usize)>,
}

impl Positions {
    /// Every position of `bounds`.
    pub(super) const fn all(bounds: (usize, usize, usize, usize)) -> Self {
        Self { bounds, skip: None }
    }

    /// Whether `(x, y)` lies in `skip`.
    #[inline]
    fn skips(&self, x: usize, y: usize) -> bool {
        self.skips_span(x, x, y)
    }

    /// Whether `skip` holds every position of row `y` from `xa` to `xb`.
    #[inline]
    fn skips_span(&self, xa: usize, xb: usize, y: usize) -> bool {
        self.skip
            .is_some_and(|(x0, y0, x1, y1)| x0 <= xa && xb <= x1 && y0 <= y && y <= y1)
    }
}

/// Whether `s` is clearly below `floor` (by the f64 shortcut of
/// [`cmp_scores`]; never where that defers to the integers).
#[inline]
fn below(s: &Score, floor: Option<&Score>) -> bool {
    floor.is_some_and(|f| cmp_keys_f64(s, f) == Some(Ordering::Less))
}

/// Positions per row a [`Strip`] holds: a region wider than this is scored one
/// row at a time (exhaustive searches of wide windows).
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
pub(super) const STRIP_W: usize = 128;

/// Working memory of [`eval_positions`] on the vector targets: a strip of up
/// to [`COL_BLOCK`] rows of positions, its window sums (computed a row at a
/// time from the integral tables) and Σ t·f (column by column, [`dot_col`]),
/// handed on row by row, in raster order. One per search.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
pub(super) struct Strip {
    /// Window sums `[Σf, Σf²]`.
    sums: [[[u32; 2]; STRIP_W]; COL_BLOCK],
    dots: [[u32; STRIP_W]; COL_BLOCK],
}

/// Working memory of [`eval_positions`]: none with the portable kernel.
#[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
pub(super) struct Strip;

impl Strip {
    #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
    pub(super) fn new() -> Self {
        Self {
            sums: [[[0; 2]; STRIP_W]; COL_BLOCK],
            dots: [[0; STRIP_W]; COL_BLOCK],
        }
    }

    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    pub(super) fn new() -> Self {
        Self
    }
}

/// The template terms `eval_positions` turns window sums and Σ t·f into scores with.
#[derive(Clone, Copy)]
struct Terms {
    n: i64,
    st: i64,
    var_t: i64,
}

impl Terms {
    /// (Σf, var_f) from the window sums: N·Σf² − (Σf)² < 2⁴⁸ (numeric.md), no
    /// wrap for templates within the caps.
    #[inline]
    fn var_f(&self, sf: u32, sff: u32) -> (i64, i64) {
        let (sf, sff) = (i64::from(sf), i64::from(sff));
        (
            sf,
            self.n.wrapping_mul(sff).wrapping_sub(sf.wrapping_mul(sf)),
        )
    }

    /// The score from Σf, var_f and Σ t·f: N·Σft − Σf·Σt < 2⁴⁸ (numeric.md).
    #[inline]
    fn score(&self, sf: i64, var_f: i64, dot: u32) -> Score {
        Score {
            num: self
                .n
                .wrapping_mul(i64::from(dot))
                .wrapping_sub(sf.wrapping_mul(self.st)),
            var_f,
            var_t: self.var_t,
        }
    }
}

/// Score every position of `at` (all valid top-left positions; [`Positions`])
/// and hand each non-flat one that is not clearly below the sink's floor to
/// `sink`, in raster order; every non-flat position scored counts as scored.
/// The integral tables cover `at.bounds`; skipped positions read no pixels.
#[allow(
    clippy::arithmetic_side_effects,
    reason = "x1 ≥ x0 and y1 ≥ y0 are checked at entry"
)]
pub(super) fn eval_positions<S: Sink>(
    t: &Tpl,
    (k, win): (usize, &Win),
    at: Positions,
    tables: &mut Tables,
    strip: &mut Strip,
    stats: &mut MatchStats,
    sink: &mut S,
) -> Result<(), FailureCode> {
    let (x0, y0, x1, y1) = at.bounds;
    if x1 < x0 || y1 < y0 {
        return Ok(());
    }
    // Wrapping index arithmetic below: positions lie in `[x0, x1] × [y0, y1]`
    // of a window that holds the template there (the contract), so nothing
    // wraps; the integral tables and the kernels read through `get` in any case.
    let mut sums = tables.sums(k, win, t, at.bounds)?;
    let terms = Terms {
        n: t.n,
        st: t.st,
        var_t: t.var_t,
    };
    let (scored, flat) = scan(t, win, &mut sums, at, strip, terms, sink);
    stats.positions_scored = stats.positions_scored.saturating_add(scored);
    stats.flat_positions = stats.flat_positions.saturating_add(flat);
    let per = t.w.saturating_mul(t.h) as u64;
    stats.macs = stats.macs.saturating_add(scored.saturating_mul(per));
    Ok(())
}

/// Where a scan hands its positions: the sink, its floor as last read (read
/// again after every offer), and the (scored, flat) counts.
struct Delivery<'s, S> {
    terms: Terms,
    sink: &'s mut S,
    floor: Option<Score>,
    counts: (u64, u64),
}

impl<'s, S: Sink> Delivery<'s, S> {
    /// Nothing delivered yet; the sink's floor as it stands.
    #[inline]
    fn new(terms: Terms, sink: &'s mut S) -> Self {
        let floor = sink.floor();
        Self {
            terms,
            sink,
            floor,
            counts: (0, 0),
        }
    }

    /// Hand one position (its Σf, var_f and Σ t·f) to the sink unless flat
    /// or clearly below the floor; counts it as scored or flat.
    #[inline]
    fn deliver(&mut self, x: usize, y: usize, (sf, var_f): (i64, i64), dot: u32) {
        if var_f <= 0 {
            self.counts.1 = self.counts.1.wrapping_add(1);
            return;
        }
        self.counts.0 = self.counts.0.wrapping_add(1);
        let s = self.terms.score(sf, var_f, dot);
        if below(&s, self.floor.as_ref()) {
            return;
        }
        self.sink.offer(x, y, s);
        self.floor = self.sink.floor();
    }
}

#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Cand {
    pub(super) x: usize,
    pub(super) y: usize,
    pub(super) s: Score,
}

/// `a` strictly better than `b` (scores of one template).
#[inline]
fn beats(a: &Score, b: &Score) -> bool {
    cmp_scores(a, b) == Ordering::Greater
}
