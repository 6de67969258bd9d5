//! Integral images of window levels (window sums and sums of squares) and the
//! per-search table scratch.

use super::pyramid::Win;
use crate::failure::FailureCode;

/// Integral images (sum and sum of squares) of a rectangle of a window level.
pub(super) struct Integral<'s> {
    pub(super) sum: &'s [u32],
    pub(super) sq: &'s [u32],
    /// Row length of the tables (region width + 1).
    pub(super) w1: usize,
    /// Window-level coordinates of the rectangle's top-left pixel.
    pub(super) x0: usize,
    pub(super) y0: usize,
}

impl<'s> Integral<'s> {
    /// Build the tables of `rw × rh` pixels of `win` starting at `(x0, y0)` in `buf`.
    ///
    /// u32 wrapping: the tables themselves may wrap, but a window sum is a signed
    /// combination of four entries, which is exact modulo 2³², and every true
    /// window sum (≤ 65 536·255² < 2³²) is below 2³², so the result is exact.
    pub(super) fn build(
        win: &Win,
        x0: usize,
        y0: usize,
        rw: usize,
        rh: usize,
        buf: &'s mut [u32],
    ) -> Result<Self, FailureCode> {
        // Saturating: sizes no scratch can hold are refused by the split.
        let w1 = rw.saturating_add(1);
        let n = w1.saturating_mul(rh.saturating_add(1));
        let (sum, rest) = buf
            .split_at_mut_checked(n)
            .ok_or(FailureCode::NccScratchTooSmall)?;
        let sq = rest.get_mut(..n).ok_or(FailureCode::NccScratchTooSmall)?;
        fill_tables(win, x0, y0, rw, rh, sum, sq);
        Ok(Self {
            sum,
            sq,
            w1,
            x0,
            y0,
        })
    }

    /// The tables of a whole `w × h` window level already built in `buf`.
    pub(super) fn view(w: usize, h: usize, buf: &'s [u32]) -> Result<Self, FailureCode> {
        let w1 = w.saturating_add(1);
        let n = w1.saturating_mul(h.saturating_add(1));
        let (sum, rest) = buf
            .split_at_checked(n)
            .ok_or(FailureCode::NccScratchTooSmall)?;
        let sq = rest.get(..n).ok_or(FailureCode::NccScratchTooSmall)?;
        Ok(Self {
            sum,
            sq,
            w1,
            x0: 0,
            y0: 0,
        })
    }

    /// (Σf, Σf²) over `w × h` pixels at region coordinates `(x, y)`.
    #[inline]
    pub(super) fn rect(&self, x: usize, y: usize, w: usize, h: usize) -> (u32, u32) {
        // Wrapping: a rectangle inside the region (the contract) never wraps; one
        // outside reads some entry or 0 through `get`, never out of bounds.
        let i00 = y.wrapping_mul(self.w1).wrapping_add(x);
        let i01 = i00.wrapping_add(w);
        let i10 = y.wrapping_add(h).wrapping_mul(self.w1).wrapping_add(x);
        let i11 = i10.wrapping_add(w);
        let g = |t: &[u32], i: usize| t.get(i).copied().unwrap_or(0);
        let s = g(self.sum, i11)
            .wrapping_sub(g(self.sum, i10))
            .wrapping_sub(g(self.sum, i01))
            .wrapping_add(g(self.sum, i00));
        let q = g(self.sq, i11)
            .wrapping_sub(g(self.sq, i10))
            .wrapping_sub(g(self.sq, i01))
            .wrapping_add(g(self.sq, i00));
        (s, q)
    }

    /// `[Σf, Σf²]` over the `w × h` rectangles at region coordinates
    /// `(x + i, y)`, `i < out.len()`, into `out[i]` (with `add`, added to it,
    /// wrapping): four rows of each table combined entry by entry. Rectangles
    /// outside the region (never, by the contract) give zeros, or add nothing.
    #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
    pub(super) fn rect_row(
        &self,
        x: usize,
        y: usize,
        w: usize,
        h: usize,
        out: &mut [[u32; 2]],
        add: bool,
    ) {
        let n = out.len();
        // Wrapping: a rectangle inside the region (the contract) never wraps;
        // otherwise `get` refuses the rows.
        let i00 = y.wrapping_mul(self.w1).wrapping_add(x);
        let i10 = y.wrapping_add(h).wrapping_mul(self.w1).wrapping_add(x);
        let rows = |t: &'s [u32]| {
            let row = |i: usize| t.get(i..).and_then(|r| r.get(..n));
            Some((
                row(i10.wrapping_add(w))?,
                row(i10)?,
                row(i00.wrapping_add(w))?,
                row(i00)?,
            ))
        };
        let (Some(s), Some(q)) = (rows(self.sum), rows(self.sq)) else {
            if !add {
                out.fill([0, 0]);
            }
            return;
        };
        // One pass of slice zips (no per-entry bounds checks or branches, so
        // the compiler vectorizes it); `add` chooses the loop, not the entry.
        let ((s11, s10, s01, s00), (q11, q10, q01, q00)) = (s, q);
        let ss = s11.iter().zip(s10).zip(s01.iter().zip(s00));
        let qs = q11.iter().zip(q10).zip(q01.iter().zip(q00));
        let rect = |((&a, &b), (&c, &d)): ((&u32, &u32), (&u32, &u32))| {
            a.wrapping_sub(b).wrapping_sub(c).wrapping_add(d)
        };
        if add {
            for (o, (sv, qv)) in out.iter_mut().zip(ss.zip(qs)) {
                *o = [o[0].wrapping_add(rect(sv)), o[1].wrapping_add(rect(qv))];
            }
        } else {
            for (o, (sv, qv)) in out.iter_mut().zip(ss.zip(qs)) {
                *o = [rect(sv), rect(qv)];
            }
        }
    }
}

/// The integral-table scratch of one search: either the tables of a whole window
/// level, built once and shared by every evaluation at that level, or nothing
/// kept, each evaluation building the tables of its own region.
pub(super) struct Tables<'b> {
    pub(super) buf: &'b mut [u32],
    /// Level, width and height of the whole-level tables held in `buf`.
    pub(super) whole: Option<(usize, usize, usize)>,
}

impl<'b> Tables<'b> {
    pub(super) fn new(buf: &'b mut [u32]) -> Self {
        Self { buf, whole: None }
    }

    /// Start level `k` of window `win`: build its whole-level tables when `whole`
    /// and they fit (a caller may size the scratch for another configuration; the
    /// region tables give the same sums).
    pub(super) fn level(&mut self, k: usize, win: &Win, whole: bool) -> Result<(), FailureCode> {
        self.whole = None;
        let need = win
            .w
            .saturating_add(1)
            .saturating_mul(win.h.saturating_add(1))
            .saturating_mul(2);
        if whole && self.buf.len() >= need {
            Integral::build(win, 0, 0, win.w, win.h, self.buf)?;
            self.whole = Some((k, win.w, win.h));
        }
        Ok(())
    }

    /// Tables covering the `rw × rh` rectangle at `(x0, y0)` of level `k` of `win`.
    pub(super) fn region(
        &mut self,
        k: usize,
        win: &Win,
        (x0, y0, rw, rh): (usize, usize, usize, usize),
    ) -> Result<Integral<'_>, FailureCode> {
        match self.whole {
            Some((lk, w, h)) if lk == k && w == win.w && h == win.h => {
                Integral::view(w, h, self.buf)
            }
            _ => Integral::build(win, x0, y0, rw, rh, self.buf),
        }
    }
}

/// Fill the sum and sum-of-squares tables (`(rw + 1) × (rh + 1)` each), row by
/// row in one pass: the running sums of the row's pixels plus the entries above
/// (read from the previous row, not from what this pass has just stored).
pub(super) fn fill_tables(
    win: &Win,
    x0: usize,
    y0: usize,
    rw: usize,
    rh: usize,
    sum: &mut [u32],
    sq: &mut [u32],
) {
    let w1 = rw.saturating_add(1);
    let n = w1.saturating_mul(rh.saturating_add(1));
    let (Some(sum), Some(sq)) = (sum.get_mut(..n), sq.get_mut(..n)) else {
        return;
    };
    let (Some((s_top, s_rows)), Some((q_top, q_rows))) =
        (sum.split_at_mut_checked(w1), sq.split_at_mut_checked(w1))
    else {
        return;
    };
    s_top.fill(0);
    q_top.fill(0);
    // The rows above, from column 1 (their column 0 is zero).
    let (mut s_prev, mut q_prev): (&[u32], &[u32]) =
        (s_top.get(1..).unwrap_or(&[]), q_top.get(1..).unwrap_or(&[]));
    // `(0..rh).zip(…)` rather than `enumerate()`: the same pairs without the
    // enumerate counter's overflow check.
    let rows = s_rows
        .chunks_exact_mut(w1.max(1))
        .zip(q_rows.chunks_exact_mut(w1.max(1)));
    for (r, (cs, cq)) in (0..rh).zip(rows) {
        // Checked: a window smaller than the contract ends the fill.
        let Some(frow) = y0.checked_add(r).and_then(|y| win.span(x0, y, rw)) else {
            return;
        };
        let (Some((cs0, cs)), Some((cq0, cq))) = (cs.split_first_mut(), cq.split_first_mut())
        else {
            return;
        };
        *cs0 = 0;
        *cq0 = 0;
        // u32 wrapping throughout (see `Integral::build`).
        let (mut run_s, mut run_q) = (0u32, 0u32);
        let above = s_prev.iter().zip(q_prev);
        for (((s, q), (&ps, &pq)), &f) in cs.iter_mut().zip(cq.iter_mut()).zip(above).zip(frow) {
            let v = u32::from(f);
            run_s = run_s.wrapping_add(v);
            run_q = run_q.wrapping_add(v.wrapping_mul(v));
            *s = run_s.wrapping_add(ps);
            *q = run_q.wrapping_add(pq);
        }
        // The finished rows are the next one's "above".
        s_prev = &*cs;
        q_prev = &*cq;
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::super::test_util::*;
    use super::super::*;
    use super::*;
    use crate::rng::Rng;
    use std::vec;

    /// Tables of a whole level and of a region of it give the same window sums.
    #[test]
    fn whole_level_tables_equal_region_tables() {
        let mut rng = Rng::new(5);
        let (w, h) = (37usize, 29usize);
        let px = random_px(w * h, &mut rng);
        let win = Win {
            px: &px,
            w,
            h,
            stride: w,
        };
        let mut whole = vec![0u32; 2 * (w + 1) * (h + 1)];
        let mut region = vec![0u32; 2 * (w + 1) * (h + 1)];
        Integral::build(&win, 0, 0, w, h, &mut whole).unwrap();
        let all = Integral::view(w, h, &whole).unwrap();
        for (x0, y0, rw, rh) in [
            (0, 0, w, h),
            (3, 5, 20, 11),
            (17, 2, 20, 27),
            (36, 28, 1, 1),
        ] {
            let part = Integral::build(&win, x0, y0, rw, rh, &mut region).unwrap();
            for (x, y, cw, ch) in [
                (0, 0, rw, rh),
                (0, 0, 1, 1),
                (rw / 2, rh / 3, rw - rw / 2, rh - rh / 3),
            ] {
                assert_eq!(part.rect(x, y, cw, ch), all.rect(x0 + x, y0 + y, cw, ch));
            }
        }
    }

    /// A search in the minimum scratch (per-region tables everywhere) returns the
    /// same match and statistics as one in the full scratch (whole-level tables).
    #[test]
    fn searches_are_identical_with_and_without_whole_level_tables() {
        let mut rng = Rng::new(77);
        for (tw, iw, filter) in [
            (32usize, 96usize, Filter::Gray),
            (48, 150, Filter::Sobel),
            (33, 90, Filter::Laplacian),
        ] {
            let img = textured(iw, iw, &mut rng);
            let t = crop(&img, iw, iw / 3, iw / 4, tw, tw);
            let cfg = SearchConfig::for_filter(filter);
            let full = ScratchSizes::with_config(tw, tw, iw, iw, Search::CoarseToFine, &cfg);
            let min = ScratchSizes::minimum(tw, tw, iw, iw, Search::CoarseToFine, &cfg);
            assert!(full.integral > min.integral, "{tw} in {iw}");
            let mut results = vec![];
            for n in [full.integral, min.integral] {
                let mut b = Bufs::with_config(tw, tw, iw, iw, Search::CoarseToFine, &cfg);
                b.i.truncate(n);
                results.push(
                    match_template(
                        view(&t, tw, tw),
                        None,
                        view(&img, iw, iw),
                        Rect::new(0, 0, iw as u32, iw as u32),
                        filter,
                        Search::CoarseToFine,
                        &mut b.scratch(),
                    )
                    .unwrap(),
                );
            }
            assert_eq!(results[0], results[1], "{tw} in {iw}");
        }
    }
}
