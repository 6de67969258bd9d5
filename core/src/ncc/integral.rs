//! Integral images of window levels (window sums and sums of squares) and the
//! per-search table scratch.

use super::pyramid::{Tpl, Win};
use super::Run;
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

    /// (Σf, Σf²) over `w × h` pixels at region coordinates `(x, y)` (the
    /// RISC-V targets' window sums, and the tests' reference for
    /// [`Integral::rect_row`]).
    #[cfg(any(test, target_arch = "riscv32", target_arch = "riscv64"))]
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
    #[cfg(any(test, not(any(target_arch = "riscv32", target_arch = "riscv64"))))]
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

/// Window sums `[Σf, Σf²]` of an unmasked `tw × th` template over a band of
/// positions, from running column sums instead of integral tables: the
/// column sums of the template's rows under the current position row, one per
/// window column of the band, moved down a row by adding the row that enters
/// and subtracting the row that leaves, and summed across `tw` columns by a
/// sliding sum. A refinement region of `p × p` positions of an ℓ-pixel
/// template reads its `(ℓ + p − 1)²` pixels once with vectorizable adds, where
/// the tables cost two stored entries per pixel and a serial running sum
/// along each row. The sums are the same integers (u32 wrapping, exact as in
/// [`Integral::build`]).
pub(super) struct ColumnSums<'s> {
    /// Σf down each column of the band (`rw` entries).
    cs: &'s mut [u32],
    /// Σf² down each column.
    cq: &'s mut [u32],
    /// Window-level column of the band's first position.
    x0: usize,
    /// Window-level row of the positions the column sums stand for.
    y: usize,
    tw: usize,
    th: usize,
}

impl<'s> ColumnSums<'s> {
    /// The column sums of `rw` columns of `win` from `(x0, y0)` over `th` rows
    /// (the positions of row `y0`), in `buf` (at least `2·rw` entries).
    ///
    /// # Errors
    /// [`FailureCode::NccScratchTooSmall`] when `buf` is too short or the
    /// rows leave the window.
    pub(super) fn new(
        win: &Win,
        (x0, y0, rw): (usize, usize, usize),
        (tw, th): (usize, usize),
        buf: &'s mut [u32],
    ) -> Result<Self, FailureCode> {
        let (cs, rest) = buf
            .split_at_mut_checked(rw)
            .ok_or(FailureCode::NccScratchTooSmall)?;
        let cq = rest.get_mut(..rw).ok_or(FailureCode::NccScratchTooSmall)?;
        init_columns(win, (x0, y0), th, cs, cq).ok_or(FailureCode::NccScratchTooSmall)?;
        Ok(Self {
            cs,
            cq,
            x0,
            y: y0,
            tw,
            th,
        })
    }

    /// `[Σf, Σf²]` of the positions `(x + i, y)`, `i < out.len()`, into
    /// `out[i]`. Rows are asked for in increasing order and columns from the
    /// band's first on (a row before the current one, a column before the
    /// band's or rows leaving the window give zeros: never, by the contract);
    /// the column sums move down to `y` first.
    pub(super) fn row(&mut self, win: &Win, x: usize, y: usize, out: &mut [[u32; 2]]) {
        while self.y < y {
            let (Some(leave), Some(enter)) = (
                win.span(self.x0, self.y, self.cs.len()),
                self.y
                    .checked_add(self.th)
                    .and_then(|e| win.span(self.x0, e, self.cs.len())),
            ) else {
                out.fill([0, 0]);
                return;
            };
            move_down(self.cs, self.cq, leave, enter);
            // y < usize::MAX: the loop condition.
            self.y = self.y.wrapping_add(1);
        }
        let (Some(i0), true) = (x.checked_sub(self.x0), self.y == y) else {
            out.fill([0, 0]);
            return;
        };
        let (Some(cs), Some(cq)) = (self.cs.get(i0..), self.cq.get(i0..)) else {
            out.fill([0, 0]);
            return;
        };
        let (Some(first_s), Some(first_q)) = (cs.get(..self.tw), cq.get(..self.tw)) else {
            out.fill([0, 0]);
            return;
        };
        let fold = |c: &[u32]| c.iter().fold(0u32, |a, &v| a.wrapping_add(v));
        let (mut s, mut q) = (fold(first_s), fold(first_q));
        // Position i + 1 gains column i + tw and loses column i.
        let enter = cs
            .get(self.tw..)
            .unwrap_or(&[])
            .iter()
            .zip(cq.get(self.tw..).unwrap_or(&[]));
        let leave = cs.iter().zip(cq.iter());
        let mut steps = enter.zip(leave);
        for o in out.iter_mut() {
            *o = [s, q];
            match steps.next() {
                Some(((&es, &eq), (&ls, &lq))) => {
                    s = s.wrapping_add(es).wrapping_sub(ls);
                    q = q.wrapping_add(eq).wrapping_sub(lq);
                }
                None => {
                    s = 0;
                    q = 0;
                }
            }
        }
    }
}

/// Columns summed per pass of [`init_columns`]: one 128-bit vector of bytes.
const COL_CHUNK: usize = 16;
/// Rows whose byte sums a u16 lane holds exactly (257 · 255 = 65 535).
const U16_ROWS: usize = 257;

/// Sum `th` rows of `win` from `(x0, y0)` down each of the `cs.len()` columns
/// (Σf into `cs`, Σf² into `cq`), [`COL_CHUNK`] columns at a time with their
/// sums in registers through the rows: Σf in u16 lanes, flushed to u32 every
/// [`U16_ROWS`] rows, the squares in u16 (at most 255² < 2¹⁶) added to u32
/// lanes. `None` when a row leaves the window.
fn init_columns(
    win: &Win,
    (x0, y0): (usize, usize),
    th: usize,
    cs: &mut [u32],
    cq: &mut [u32],
) -> Option<()> {
    const C: usize = COL_CHUNK;
    cs.fill(0);
    cq.fill(0);
    let rw = cs.len().min(cq.len());
    let row = |r: usize, x: usize, n: usize| win.span(x0.checked_add(x)?, y0.checked_add(r)?, n);
    let (s_chunks, s_tail) = cs.as_chunks_mut::<C>();
    let (q_chunks, q_tail) = cq.as_chunks_mut::<C>();
    for (c, (sc, qc)) in (0usize..).zip(s_chunks.iter_mut().zip(q_chunks.iter_mut())) {
        // c < rw / C: no overflow.
        let x = c.wrapping_mul(C);
        let mut q = [0u32; C];
        let mut r0 = 0usize;
        while r0 < th {
            let r1 = r0.saturating_add(U16_ROWS).min(th);
            let mut s = [0u16; C];
            for r in r0..r1 {
                let f: &[u8; C] = row(r, x, C)?.first_chunk()?;
                for ((s, q), &f) in s.iter_mut().zip(q.iter_mut()).zip(f) {
                    let v = u16::from(f);
                    *s = s.wrapping_add(v);
                    *q = q.wrapping_add(u32::from(v.wrapping_mul(v)));
                }
            }
            for (o, &v) in sc.iter_mut().zip(&s) {
                *o = o.wrapping_add(u32::from(v));
            }
            r0 = r1;
        }
        *qc = q;
    }
    let nt = s_tail.len();
    let xt = rw.wrapping_sub(nt);
    for r in 0..th {
        for ((s, q), &f) in s_tail
            .iter_mut()
            .zip(q_tail.iter_mut())
            .zip(row(r, xt, nt)?)
        {
            let v = u16::from(f);
            *s = s.wrapping_add(u32::from(v));
            *q = q.wrapping_add(u32::from(v.wrapping_mul(v)));
        }
    }
    Some(())
}

/// Move the column sums down a row: add the row that enters, subtract the
/// row that leaves ([`COL_CHUNK`] columns at a time, differences in i16 and
/// i32 lanes added with wrapping: exact modulo 2³² as above).
fn move_down(cs: &mut [u32], cq: &mut [u32], leave: &[u8], enter: &[u8]) {
    const C: usize = COL_CHUNK;
    let step = |s: &mut u32, q: &mut u32, a: u8, b: u8| {
        let (a, b) = (i32::from(a), i32::from(b));
        *s = s.wrapping_add_signed(a.wrapping_sub(b));
        *q = q.wrapping_add_signed(a.wrapping_mul(a).wrapping_sub(b.wrapping_mul(b)));
    };
    let (sc, st) = cs.as_chunks_mut::<C>();
    let (qc, qt) = cq.as_chunks_mut::<C>();
    let (ec, et) = enter.as_chunks::<C>();
    let (lc, lt) = leave.as_chunks::<C>();
    for ((s, q), (e, l)) in sc.iter_mut().zip(qc.iter_mut()).zip(ec.iter().zip(lc)) {
        for ((s, q), (&a, &b)) in s.iter_mut().zip(q.iter_mut()).zip(e.iter().zip(l)) {
            step(s, q, a, b);
        }
    }
    for ((s, q), (&a, &b)) in st.iter_mut().zip(qt.iter_mut()).zip(et.iter().zip(lt)) {
        step(s, q, a, b);
    }
}

/// The integral-table scratch of one search: either the tables of a whole window
/// level, built once and shared by every evaluation at that level, or nothing
/// kept, each evaluation taking the window sums of its own region (running
/// column sums or region tables, [`Tables::sums`]) in it.
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

    /// The window sums of the positions `(x0..=x1, y0..=y1)` of template `t`
    /// at level `k` of `win`: the whole-level tables when they are held;
    /// otherwise, for an unmasked template, running column sums
    /// ([`ColumnSums`]); otherwise the tables of the positions' region.
    pub(super) fn sums(
        &mut self,
        k: usize,
        win: &Win,
        t: &Tpl,
        (x0, y0, x1, y1): (usize, usize, usize, usize),
    ) -> Result<Sums<'_>, FailureCode> {
        let rw = x1.saturating_sub(x0).saturating_add(t.w);
        if !self.holds(k, win) && t.runs.is_none() {
            return ColumnSums::new(win, (x0, y0, rw), (t.w, t.h), self.buf).map(Sums::Columns);
        }
        let rh = y1.saturating_sub(y0).saturating_add(t.h);
        self.region(k, win, (x0, y0, rw, rh)).map(Sums::Tables)
    }

    /// Tables covering the `rw × rh` rectangle at `(x0, y0)` of level `k` of `win`.
    pub(super) fn region(
        &mut self,
        k: usize,
        win: &Win,
        (x0, y0, rw, rh): (usize, usize, usize, usize),
    ) -> Result<Integral<'_>, FailureCode> {
        if self.holds(k, win) {
            Integral::view(win.w, win.h, self.buf)
        } else {
            Integral::build(win, x0, y0, rw, rh, self.buf)
        }
    }

    /// Whether `buf` holds the whole-level tables of level `k` of `win`.
    fn holds(&self, k: usize, win: &Win) -> bool {
        self.whole == Some((k, win.w, win.h))
    }
}

/// A mask run as a rectangle of the template: column and row offsets, width
/// and height (`x1 ≥ x0` by construction; wrapping otherwise, and a rectangle
/// outside the tables reads zeros).
#[inline]
fn run_rect(run: &Run) -> (usize, usize, usize, usize) {
    (
        usize::from(run.x0),
        usize::from(run.row),
        usize::from(run.x1.wrapping_sub(run.x0)),
        usize::from(run.rows),
    )
}

/// Where [`Tables::sums`] takes the window sums of one set of positions from.
pub(super) enum Sums<'s> {
    /// Integral tables (of the whole level, or of the positions' region).
    Tables(Integral<'s>),
    /// Running column sums of the positions' band (unmasked templates).
    Columns(ColumnSums<'s>),
}

impl Sums<'_> {
    /// `[Σf, Σf²]` of the window under the template's kept pixels at the
    /// positions `(x + i, y)`, `i < out.len()` (window-level coordinates),
    /// into `out[i]`. Rows in increasing order (see [`ColumnSums::row`]).
    pub(super) fn row(&mut self, t: &Tpl, win: &Win, x: usize, y: usize, out: &mut [[u32; 2]]) {
        match self {
            Sums::Columns(c) => c.row(win, x, y, out),
            // Position by position on RISC-V, where the scan asks for blocks
            // of four positions and the row form's slice setup per run costs
            // more than it saves: the firmware workload's engine took 2.0 %
            // fewer instructions on RV64 this way, but 2.5 % more on the
            // Cortex-M7, which keeps the row form (`fsw-docs/budgets/ncc.md`).
            #[cfg(any(target_arch = "riscv32", target_arch = "riscv64"))]
            Sums::Tables(integ) => {
                let (rx, ry) = (x.wrapping_sub(integ.x0), y.wrapping_sub(integ.y0));
                let n = out.len();
                for (i, o) in (0..n).zip(out.iter_mut()) {
                    let px = rx.wrapping_add(i);
                    let (s, q) = match t.runs {
                        None => integ.rect(px, ry, t.w, t.h),
                        Some(runs) => runs.iter().fold((0u32, 0u32), |(s, q), run| {
                            let (dx, dy, w, h) = run_rect(run);
                            let (a, b) = integ.rect(px.wrapping_add(dx), ry.wrapping_add(dy), w, h);
                            (s.wrapping_add(a), q.wrapping_add(b))
                        }),
                    };
                    *o = [s, q];
                }
            }
            #[cfg(not(any(target_arch = "riscv32", target_arch = "riscv64")))]
            Sums::Tables(integ) => {
                let (rx, ry) = (x.wrapping_sub(integ.x0), y.wrapping_sub(integ.y0));
                match t.runs {
                    None => integ.rect_row(rx, ry, t.w, t.h, out, false),
                    Some(runs) => {
                        out.fill([0, 0]);
                        for run in runs {
                            let (dx, dy, w, h) = run_rect(run);
                            let (x, y) = (rx.wrapping_add(dx), ry.wrapping_add(dy));
                            integ.rect_row(x, y, w, h, out, true);
                        }
                    }
                }
            }
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

    /// Running column sums give the window sums of the integral tables at
    /// every position of a band, asked row by row with rows skipped and from
    /// any column of the band, on random pixels and on all-255 pixels (the
    /// largest squares), in a window whose rows are longer than it is wide.
    #[test]
    fn column_sums_equal_table_sums() {
        let mut rng = Rng::new(11);
        // A wide window, and a tall one whose templates are taller than the
        // 257 rows a u16 column sum holds (`init_columns` flushes them).
        let wide: &[(usize, usize, usize, usize, usize, usize)] = &[
            (0, 0, 4, 4, 32, 32),
            (3, 5, 9, 14, 17, 21),
            (0, 0, 60, 46, 1, 1),
            (10, 2, 10, 2, 51, 45),
            (0, 0, 60 - 33, 46 - 40, 33, 40),
        ];
        let tall: &[(usize, usize, usize, usize, usize, usize)] = &[
            (0, 0, 3, 9, 20, 290),
            (2, 1, 2, 3, 19, 300),
            (0, 0, 5, 40, 18, 260),
        ];
        for ((w, h, stride), cases, bright) in [
            ((61usize, 47usize, 64usize), wide, false),
            ((61, 47, 64), wide, true),
            ((24, 304, 24), tall, false),
            ((24, 304, 24), tall, true),
        ] {
            let px: std::vec::Vec<u8> = if bright {
                vec![255; stride * h]
            } else {
                random_px(stride * h, &mut rng)
            };
            let win = Win {
                px: &px,
                w,
                h,
                stride,
            };
            let mut whole = vec![0u32; 2 * (w + 1) * (h + 1)];
            Integral::build(&win, 0, 0, w, h, &mut whole).unwrap();
            let all = Integral::view(w, h, &whole).unwrap();
            for &(x0, y0, x1, y1, tw, th) in cases {
                let mut buf = vec![0u32; 2 * w];
                let rw = x1 - x0 + tw;
                let mut c = ColumnSums::new(&win, (x0, y0, rw), (tw, th), &mut buf).unwrap();
                for y in (y0..=y1).step_by(if y1 > y0 + 3 { 2 } else { 1 }) {
                    for xs in [x0, (x0 + x1).div_ceil(2)] {
                        let mut out = vec![[0u32; 2]; x1 + 1 - xs];
                        c.row(&win, xs, y, &mut out);
                        for (i, o) in out.iter().enumerate() {
                            let (s, q) = all.rect(xs + i, y, tw, th);
                            assert_eq!(*o, [s, q], "({}, {y}) of {tw}×{th}", xs + i);
                        }
                    }
                }
                // A row asked for again after a later one, a column before
                // the band: zeros, no panic.
                let mut out = [[1u32; 2]; 2];
                if y1 > y0 {
                    c.row(&win, x0, y0, &mut out);
                    assert_eq!(out, [[0, 0]; 2]);
                }
                if x0 > 0 {
                    c.row(&win, x0 - 1, y1, &mut out);
                    assert_eq!(out, [[0, 0]; 2]);
                }
            }
        }
        // Scratch too short, rows past the window: refused.
        let px = vec![7u8; 16 * 16];
        let win = Win {
            px: &px,
            w: 16,
            h: 16,
            stride: 16,
        };
        let mut buf = vec![0u32; 15];
        assert!(ColumnSums::new(&win, (0, 0, 8), (8, 8), &mut buf).is_err());
        let mut buf = vec![0u32; 32];
        assert!(ColumnSums::new(&win, (0, 10, 8), (8, 8), &mut buf).is_err());
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
