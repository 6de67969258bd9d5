//! Integral images of window levels (window sums and sums of squares) and the
//! per-search table scratch.

use super::pyramid::Win;
use crate::failure::FailureCode;

/// Integral images (sum and sum of squares) of a rectangle of a window level,
/// interleaved: entry `i` is `tab[2i]` (Σf) and `tab[2i + 1]` (Σf², mod 2³²).
///
/// Read as one u64 `Σf + 2³²·Σf²` per entry, window sums are one wrapping
/// combination of four entries: every true Σf of a window level (at most
/// `MAX_SEARCH_PX`² · 255 < 2³²) and Σf² of a window (≤ 65 536·255² < 2³²) is
/// below 2³², so a rectangle's combination modulo 2⁶⁴ is `Σf + 2³²·Σf²` of the
/// rectangle exactly, its halves the two sums.
pub(super) struct Integral<'s> {
    pub(super) tab: &'s [u32],
    /// Row length of the tables (region width + 1).
    pub(super) w1: usize,
    /// Window-level coordinates of the rectangle's top-left pixel.
    pub(super) x0: usize,
    pub(super) y0: usize,
}

/// An entry (`[Σf, Σf²]`) as `Σf + 2³²·Σf²`.
#[inline(always)]
fn packed(e: &[u32; 2]) -> u64 {
    u64::from(e[0]) | u64::from(e[1]) << 32
}

/// (Σf, Σf²) from a packed rectangle sum.
#[inline(always)]
#[allow(
    clippy::cast_possible_truncation,
    reason = "the two 32-bit halves of the packed sums"
)]
pub(super) fn unpack(v: u64) -> (u32, u32) {
    (v as u32, (v >> 32) as u32)
}

impl<'s> Integral<'s> {
    /// Build the tables of `rw × rh` pixels of `win` starting at `(x0, y0)` in `buf`.
    pub(super) fn build(
        win: &Win,
        x0: usize,
        y0: usize,
        rw: usize,
        rh: usize,
        buf: &'s mut [u32],
    ) -> Result<Self, FailureCode> {
        // Saturating: sizes no scratch can hold are refused by `get_mut`.
        let w1 = rw.saturating_add(1);
        let n = w1.saturating_mul(rh.saturating_add(1)).saturating_mul(2);
        let tab = buf.get_mut(..n).ok_or(FailureCode::NccScratchTooSmall)?;
        fill_tables(win, x0, y0, rw, rh, tab);
        Ok(Self { tab, w1, x0, y0 })
    }

    /// The tables of a whole `w × h` window level already built in `buf`.
    pub(super) fn view(w: usize, h: usize, buf: &'s [u32]) -> Result<Self, FailureCode> {
        let w1 = w.saturating_add(1);
        let n = w1.saturating_mul(h.saturating_add(1)).saturating_mul(2);
        let tab = buf.get(..n).ok_or(FailureCode::NccScratchTooSmall)?;
        Ok(Self {
            tab,
            w1,
            x0: 0,
            y0: 0,
        })
    }

    /// Entry `i` packed, 0 outside the tables.
    #[inline]
    fn entry(&self, i: usize) -> u64 {
        self.tab
            .get(i.wrapping_mul(2)..)
            .and_then(|t| t.first_chunk::<2>())
            .map_or(0, packed)
    }

    /// (Σf, Σf²) over `w × h` pixels at region coordinates `(x, y)`.
    #[inline]
    pub(super) fn rect(&self, x: usize, y: usize, w: usize, h: usize) -> (u32, u32) {
        unpack(self.rect_packed(x, y, w, h))
    }

    /// [`Integral::rect`] packed (`Σf + 2³²·Σf²`).
    #[inline]
    pub(super) fn rect_packed(&self, x: usize, y: usize, w: usize, h: usize) -> u64 {
        // Wrapping: a rectangle inside the region (the contract) never wraps; one
        // outside reads some entry or 0 through `get`, never out of bounds.
        let i00 = y.wrapping_mul(self.w1).wrapping_add(x);
        let i01 = i00.wrapping_add(w);
        let i10 = y.wrapping_add(h).wrapping_mul(self.w1).wrapping_add(x);
        let i11 = i10.wrapping_add(w);
        self.entry(i11)
            .wrapping_sub(self.entry(i10))
            .wrapping_sub(self.entry(i01))
            .wrapping_add(self.entry(i00))
    }

    /// The packed sums over the `w × h` rectangles at region coordinates
    /// `(x + i, y)`, `i < out.len()`, into `out[i]` (with `add`, added to it,
    /// wrapping): four table rows combined entry by entry. Rectangles outside
    /// the region (never, by the contract) give zeros, or add nothing.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn rect_row(
        &self,
        x: usize,
        y: usize,
        w: usize,
        h: usize,
        out: &mut [u64],
        add: bool,
    ) {
        let n = out.len();
        // Wrapping: a rectangle inside the region (the contract) never wraps;
        // otherwise `get` refuses the rows.
        let i00 = y.wrapping_mul(self.w1).wrapping_add(x);
        let i10 = y.wrapping_add(h).wrapping_mul(self.w1).wrapping_add(x);
        let row = |i: usize| {
            self.tab
                .get(i.wrapping_mul(2)..)
                .map(|t| t.as_chunks::<2>().0)
                .and_then(|r| r.get(..n))
        };
        let (Some(a), Some(b), Some(c), Some(d)) = (
            row(i10.wrapping_add(w)),
            row(i10),
            row(i00.wrapping_add(w)),
            row(i00),
        ) else {
            if !add {
                out.fill(0);
            }
            return;
        };
        let rects = out.iter_mut().zip(a).zip(b).zip(c).zip(d);
        let v = |a, b, c, d| {
            packed(a)
                .wrapping_sub(packed(b))
                .wrapping_sub(packed(c))
                .wrapping_add(packed(d))
        };
        if add {
            for ((((o, a), b), c), d) in rects {
                *o = o.wrapping_add(v(a, b, c, d));
            }
        } else {
            for ((((o, a), b), c), d) in rects {
                *o = v(a, b, c, d);
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

/// Fill the interleaved tables (`(rw + 1) × (rh + 1)` entries), row by row:
/// the running packed sum of the row's pixels plus the entry above, one pass.
pub(super) fn fill_tables(win: &Win, x0: usize, y0: usize, rw: usize, rh: usize, tab: &mut [u32]) {
    let w2 = rw.saturating_add(1).saturating_mul(2);
    let n = w2.saturating_mul(rh.saturating_add(1));
    let Some(tab) = tab.get_mut(..n) else {
        return;
    };
    let Some((top, rows)) = tab.split_at_mut_checked(w2) else {
        return;
    };
    top.fill(0);
    // The row above, from entry 1 (its entry 0 is zero).
    let mut prev: &[u32] = top.get(2..).unwrap_or(&[]);
    for (r, cur) in rows.chunks_exact_mut(w2.max(1)).enumerate() {
        // Checked: a window smaller than the contract ends the fill.
        let Some(frow) = y0.checked_add(r).and_then(|y| win.span(x0, y, rw)) else {
            return;
        };
        let Some((first, cur)) = cur.split_first_chunk_mut::<2>() else {
            return;
        };
        *first = [0, 0];
        // u64 wrapping: the packed running sum of the row (Σf < 2³² here),
        // plus the entry above (read from the previous row, not from what this
        // pass has just stored).
        let mut run = 0u64;
        let above = prev.as_chunks::<2>().0;
        for ((e, a), &f) in cur.as_chunks_mut::<2>().0.iter_mut().zip(above).zip(frow) {
            let v = u64::from(f);
            run = run.wrapping_add(v | v.wrapping_mul(v).wrapping_shl(32));
            let (lo, hi) = unpack(run.wrapping_add(packed(a)));
            *e = [lo, hi];
        }
        // The finished row is the next one's "above".
        prev = &*cur;
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
