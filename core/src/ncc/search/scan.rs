//! The scan of one region of positions: window sums from the integral tables,
//! Σ t·f from the correlation kernel, each position handed to a [`Sink`]
//! through a [`Delivery`]. One scan per kernel: column blocks on the vector
//! targets, row blocks elsewhere; both deliver the same positions in the same
//! (raster) order.

use super::{Delivery, Positions, Sink, Strip, Terms};
use crate::ncc::integral::Sums;
#[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
use crate::ncc::kernel::{dot_block, KERNEL_BLOCK};
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
use crate::ncc::kernel::{dot_col, COL_BLOCK};
use crate::ncc::pyramid::{Tpl, Win};

#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
use super::STRIP_W;

/// The vector targets' scan: strips of up to [`COL_BLOCK`] rows, their window
/// sums a row at a time, their Σ t·f column by column with [`dot_col`] (one
/// pass over the window rows per column of positions), handed on row by row.
/// A column whose positions are all flat skips the kernel. Regions wider than
/// [`STRIP_W`] go a row of positions at a time ([`scan_wide`]). Returns
/// (scored, flat) counts.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
pub(super) fn scan<S: Sink>(
    t: &Tpl,
    win: &Win,
    sums: &mut Sums<'_>,
    at: Positions,
    strip: &mut Strip,
    terms: Terms,
    sink: &mut S,
) -> (u64, u64) {
    let (x0, y0, x1, y1) = at.bounds;
    let mut out = Delivery::new(terms, sink);
    let width = x1.wrapping_sub(x0).wrapping_add(1);
    if width > STRIP_W {
        scan_wide(t, win, sums, at, strip, &mut out);
        return out.counts;
    }
    let mut ys = y0;
    loop {
        let hs = y1.wrapping_sub(ys).wrapping_add(1).min(COL_BLOCK);
        // Window sums, a row of positions at a time.
        for (j, row) in (0..hs).zip(strip.sums.iter_mut()) {
            if let Some(row) = row.get_mut(..width) {
                sums.row(t, win, x0, ys.wrapping_add(j), row);
            }
        }
        strip_dots(t, win, at, (ys, hs), &terms, strip);
        // Hand the positions on, row by row.
        for (j, (sums, dots)) in (0..hs).zip(strip.sums.iter().zip(&strip.dots)) {
            let y = ys.wrapping_add(j);
            if at.skips_span(x0, x1, y) {
                continue;
            }
            for (x, (&[a, b], &d)) in (x0..=x1).zip(sums.iter().zip(dots)) {
                if at.skips(x, y) {
                    continue;
                }
                let v = terms.var_f(a, b);
                out.deliver(x, y, v, d);
            }
        }
        ys = ys.wrapping_add(hs);
        if ys > y1 {
            break;
        }
    }
    out.counts
}

/// [`scan`] of a region wider than [`STRIP_W`]: a row of positions at a
/// time, in pieces of at most [`STRIP_W`] window sums, Σ t·f one position at
/// a time.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
fn scan_wide<S: Sink>(
    t: &Tpl,
    win: &Win,
    sums: &mut Sums<'_>,
    at: Positions,
    strip: &mut Strip,
    out: &mut Delivery<'_, S>,
) {
    let (x0, y0, x1, y1) = at.bounds;
    let [row, ..] = &mut strip.sums;
    for y in y0..=y1 {
        let mut xc = x0;
        while xc <= x1 {
            let n = x1.wrapping_sub(xc).wrapping_add(1).min(STRIP_W);
            let Some(row) = row.get_mut(..n) else {
                break;
            };
            sums.row(t, win, xc, y, row);
            for (x, &[sf, sff]) in (xc..=x1).zip(row.iter()) {
                if at.skips(x, y) {
                    continue;
                }
                let v = out.terms.var_f(sf, sff);
                let dot = if v.1 > 0 {
                    let [d] = dot_col::<1>(t, win, x, y);
                    d
                } else {
                    0
                };
                out.deliver(x, y, v, dot);
            }
            xc = xc.wrapping_add(n);
        }
    }
}

/// Σ t·f of the strip's `hs` rows of positions from row `ys`, a column of
/// positions at a time, over the runs of positions it needs (neither flat nor
/// skipped): column blocks of 8, 5, 4, 3, 2 and 1 positions over each run of
/// needed rows, each result written straight into its strip rows. The
/// strip's window sums of those rows are filled in already.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
fn strip_dots(
    t: &Tpl,
    win: &Win,
    at: Positions,
    (ys, hs): (usize, usize),
    terms: &Terms,
    strip: &mut Strip,
) {
    let (x0, _, x1, _) = at.bounds;
    let width = x1.wrapping_sub(x0).wrapping_add(1);
    for (i, x) in (0..width).zip(x0..=x1) {
        let need: [bool; COL_BLOCK] = core::array::from_fn(|j| {
            let [sf, sff] = strip
                .sums
                .get(j)
                .and_then(|r| r.get(i))
                .copied()
                .unwrap_or([0, 0]);
            j < hs && terms.var_f(sf, sff).1 > 0 && !at.skips(x, ys.wrapping_add(j))
        });
        let mut j = 0usize;
        while j < hs {
            if !need.get(j).copied().unwrap_or(false) {
                j = j.wrapping_add(1);
                continue;
            }
            let run = need.get(j..hs).map_or(0, |r| {
                r.iter()
                    .take_while(|&&n| n)
                    .fold(0usize, |c, _| c.wrapping_add(1))
            });
            let y = ys.wrapping_add(j);
            let Some(rows) = strip.dots.get_mut(j..) else {
                break;
            };
            let done = match run {
                8.. => put_column(rows, i, &dot_col::<8>(t, win, x, y)),
                5..=7 => put_column(rows, i, &dot_col::<5>(t, win, x, y)),
                4 => put_column(rows, i, &dot_col::<4>(t, win, x, y)),
                3 => put_column(rows, i, &dot_col::<3>(t, win, x, y)),
                2 => put_column(rows, i, &dot_col::<2>(t, win, x, y)),
                _ => put_column(rows, i, &dot_col::<1>(t, win, x, y)),
            };
            j = j.wrapping_add(done);
        }
    }
}

/// Write the column of Σ t·f `v` into column `i` of `rows`, one row each;
/// returns how many positions it holds.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
#[inline]
fn put_column(rows: &mut [[u32; STRIP_W]], i: usize, v: &[u32]) -> usize {
    for (row, &d) in rows.iter_mut().zip(v) {
        if let Some(o) = row.get_mut(i) {
            *o = d;
        }
    }
    v.len()
}

/// The portable scan: row by row, runs of [`KERNEL_BLOCK`] consecutive x
/// sharing one pass over the template rows ([`dot_block`]); a run whose
/// positions are all flat skips the kernel. Returns (scored, flat) counts.
#[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
pub(super) fn scan<S: Sink>(
    t: &Tpl,
    win: &Win,
    sums: &mut Sums<'_>,
    at: Positions,
    _strip: &mut Strip,
    terms: Terms,
    sink: &mut S,
) -> (u64, u64) {
    let (x0, y0, x1, y1) = at.bounds;
    let mut out = Delivery::new(terms, sink);
    for y in y0..=y1 {
        if at.skips_span(x0, x1, y) {
            continue;
        }
        // `x0, x0 + KERNEL_BLOCK, … ≤ x1` without `step_by` over an inclusive
        // range, whose `nth` has an overflow panic path.
        let mut next_xb = Some(x0);
        while let Some(xb) = next_xb {
            next_xb = xb.checked_add(KERNEL_BLOCK).filter(|&n| n <= x1);
            let n = x1.wrapping_sub(xb).saturating_add(1).min(KERNEL_BLOCK);
            let mut vs = [(0i64, 0i64); KERNEL_BLOCK];
            let mut live = [false; KERNEL_BLOCK];
            // `(0..n).zip(…)` rather than `enumerate().take(n)`: the same
            // pairs without the enumerate counter's overflow check.
            let mut skipped = [false; KERNEL_BLOCK];
            let mut block = [[0u32; 2]; KERNEL_BLOCK];
            if let Some(b) = block.get_mut(..n) {
                sums.row(t, win, xb, y, b);
            }
            for ((((i, v), l), k), &[sf, sff]) in (0..n)
                .zip(vs.iter_mut())
                .zip(live.iter_mut())
                .zip(skipped.iter_mut())
                .zip(&block)
            {
                let x = xb.wrapping_add(i);
                *k = at.skips(x, y);
                if *k {
                    continue;
                }
                *v = terms.var_f(sf, sff);
                *l = v.1 > 0;
            }
            let mut dots = [0u32; KERNEL_BLOCK];
            // A block pass costs less than three single ones (the template
            // byte is loaded once for all positions), more than two.
            // A fold with wrapping adds: `count` keeps an overflow panic path
            // under overflow checks (at most KERNEL_BLOCK here).
            let needed = live
                .iter()
                .fold(0usize, |c, &l| c.wrapping_add(usize::from(l)));
            if n == KERNEL_BLOCK && (needed >= 3 || (needed > 0 && !skipped.contains(&true))) {
                dots = dot_block::<KERNEL_BLOCK>(t, win, xb, y);
            } else {
                for ((i, d), &l) in (0..n).zip(dots.iter_mut()).zip(&live) {
                    if l {
                        let [v] = dot_block::<1>(t, win, xb.wrapping_add(i), y);
                        *d = v;
                    }
                }
            }
            for (((i, &s), &d), &k) in (0..n).zip(&vs).zip(&dots).zip(&skipped) {
                if k {
                    continue;
                }
                out.deliver(xb.wrapping_add(i), y, s, d);
            }
        }
    }
    out.counts
}
