//! The list of the best few separated candidates a coarse level keeps, kept
//! sorted in place as positions are offered.

use super::{beats, Cand, Sink};
use crate::fmt::present;
use crate::ncc::{key_beats, order_key, Score, MAX_CANDIDATES};

impl Sink for TopK {
    #[inline]
    fn floor(&self) -> Option<Score> {
        // Only a full list rejects by its last entry (a list shortened by
        // near entries leaving takes any offer that is not near a better one).
        (self.len == self.cap)
            .then(|| self.as_slice().last().map(|c| c.s))
            .flatten()
    }

    #[inline]
    fn offer(&mut self, x: usize, y: usize, s: Score) {
        TopK::offer(self, Cand { x, y, s });
    }
}

/// The best few positions, sorted best first, pairwise farther apart than `radius`
/// (Chebyshev). The first entry is always the exact argmax of everything offered
/// (ties keep the earliest offered, i.e. the first in raster order).
#[derive(Clone, Copy, Debug)]
pub(in crate::ncc) struct TopK {
    pub(in crate::ncc) items: [Cand; MAX_CANDIDATES],
    /// [`order_key`] of each entry.
    keys: [f64; MAX_CANDIDATES],
    /// Each entry's position (`x`, `y` as u32: positions lie in a window of at
    /// most `MAX_SEARCH_PX` pixels), for the near test over the whole list.
    xs: [u32; MAX_CANDIDATES],
    ys: [u32; MAX_CANDIDATES],
    pub(in crate::ncc) len: usize,
    pub(in crate::ncc) cap: usize,
    pub(in crate::ncc) radius: usize,
    /// Index of the entry that rejected the last offer for being near and at
    /// least as good, or of the last entry inserted: neighbouring offers in
    /// raster order are usually rejected by the same entry, so [`TopK::offer`]
    /// tries it before scanning the list. Any index is correct (the scan
    /// decides whenever the hint does not reject).
    hint: usize,
}

/// The first index `i` of `cur` (with its key) for which `pred` is false, `pred`
/// being true up to some index and false from there on (a binary search: few
/// comparisons, which on targets without hardware f64 are the exact integer
/// ones).
fn pairs_partition_point(cur: &[Cand], keys: &[f64], pred: impl Fn(&Cand, f64) -> bool) -> usize {
    let (mut lo, mut hi) = (0usize, cur.len().min(keys.len()));
    while lo < hi {
        // lo < hi ≤ MAX_CANDIDATES: no overflow.
        let mid = lo.wrapping_add(hi.wrapping_sub(lo) / 2);
        let (Some(e), Some(&k)) = (cur.get(mid), keys.get(mid)) else {
            break;
        };
        if pred(e, k) {
            lo = mid.wrapping_add(1);
        } else {
            hi = mid;
        }
    }
    lo
}

/// Bit `i` set for each entry `i < len` whose position (`xs[i]`, `ys[i]`) is
/// within `r` of `(cx, cy)` on both axes (`e − c + r ≤ span = 2r`, wrapping).
/// On the vector targets eight entries at a time, branch-free (vectorized);
/// elsewhere entry by entry, touching the 64-bit mask only for near entries
/// (rare; 64-bit shifts are several instructions on a 32-bit core).
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
#[inline]
fn near_mask(
    xs: &[u32; MAX_CANDIDATES],
    ys: &[u32; MAX_CANDIDATES],
    len: usize,
    (cx, cy): (u32, u32),
    (r, span): (u32, u32),
) -> u64 {
    let mut near = 0u64;
    let blocks = xs.as_chunks::<8>().0.iter().zip(ys.as_chunks::<8>().0);
    for (b, (xb, yb)) in (0u32..).zip(blocks).take(len.div_ceil(8)) {
        let mut m = 0u64;
        for (i, (&x, &y)) in (0u32..).zip(xb.iter().zip(yb)) {
            let n = (x.wrapping_sub(cx).wrapping_add(r) <= span)
                & (y.wrapping_sub(cy).wrapping_add(r) <= span);
            m |= u64::from(n).wrapping_shl(i);
        }
        near |= m.wrapping_shl(b.wrapping_mul(8));
    }
    // Slots past `len` hold stale positions.
    near & u64::MAX
        .checked_shr(64u32.saturating_sub(u32::try_from(len).unwrap_or(64)))
        .unwrap_or(0)
}

/// [`near_mask`] entry by entry.
#[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
#[inline]
fn near_mask(
    xs: &[u32; MAX_CANDIDATES],
    ys: &[u32; MAX_CANDIDATES],
    len: usize,
    (cx, cy): (u32, u32),
    (r, span): (u32, u32),
) -> u64 {
    let mut near = 0u64;
    for (i, (&x, &y)) in (0u32..64).zip(xs.iter().zip(ys)).take(len) {
        if x.wrapping_sub(cx).wrapping_add(r) <= span && y.wrapping_sub(cy).wrapping_add(r) <= span
        {
            near |= 1u64.wrapping_shl(i);
        }
    }
    near
}

/// A position as u32 (positions lie in a window of at most `MAX_SEARCH_PX`
/// pixels; saturating, so nothing wraps).
#[inline]
fn pos_u32(v: usize) -> u32 {
    u32::try_from(v).unwrap_or(u32::MAX)
}

impl TopK {
    pub(in crate::ncc) fn new(cap: usize, radius: usize) -> Self {
        Self {
            items: [Cand::default(); MAX_CANDIDATES],
            keys: [0.0; MAX_CANDIDATES],
            xs: [0; MAX_CANDIDATES],
            ys: [0; MAX_CANDIDATES],
            len: 0,
            cap: cap.clamp(1, MAX_CANDIDATES),
            radius,
            hint: 0,
        }
    }

    pub(in crate::ncc) fn as_slice(&self) -> &[Cand] {
        present(self.items.get(..self.len))
    }

    pub(in crate::ncc) fn near(&self, a: &Cand, b: &Cand) -> bool {
        a.x.abs_diff(b.x) <= self.radius && a.y.abs_diff(b.y) <= self.radius
    }

    /// Offer `c`: rejected when the list is full and `c` is not better than its
    /// last entry, or when an entry near `c` is at least as good; otherwise the
    /// entries near `c` (all worse) leave, `c` goes in after every entry at
    /// least as good as it, and the list is cut to `cap`.
    ///
    /// The two cheap rejections (the last entry, the hinted entry) are tried
    /// here; whatever they let through goes to [`TopK::offer_scan`].
    #[inline]
    pub(in crate::ncc) fn offer(&mut self, c: Cand) {
        let cur = self.as_slice();
        if self.len == self.cap {
            if let Some(last) = cur.last() {
                if !beats(&c.s, &last.s) {
                    return;
                }
            }
        }
        if let Some(h) = cur.get(self.hint) {
            if self.near(h, &c) && !beats(&c.s, &h.s) {
                return;
            }
        }
        self.offer_scan(c);
    }

    /// [`TopK::offer`] past its cheap rejections: the entries near `c` (one
    /// branch-free pass) reject it if any is at least as good; otherwise `c`
    /// goes in before the first entry it beats (the near ones all lie after it:
    /// `c` beats them), the entries from there to the first near one move one
    /// place right, and those after it move left over the near ones, all in place.
    /// Comparisons go through the entries' cached order keys ([`key_beats`]).
    #[inline(never)]
    fn offer_scan(&mut self, c: Cand) {
        let len = self.len.min(self.cap).min(MAX_CANDIDATES);
        let (Some(cur), Some(keys)) = (self.items.get(..len), self.keys.get(..len)) else {
            return;
        };
        // |e − c| ≤ r as `e − c + r ≤ 2r` in wrapping u32 arithmetic (positions
        // are far below 2³¹; a radius of 2³⁰ or more makes everything near, as
        // it is), eight entries at a time.
        let r = u32::try_from(self.radius).unwrap_or(u32::MAX).min(1 << 30);
        let span = r.wrapping_mul(2);
        let (cx, cy) = (pos_u32(c.x), pos_u32(c.y));
        let near = near_mask(&self.xs, &self.ys, len, (cx, cy), (r, span));
        let kc = order_key(&c.s);
        let mut m = near;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m.wrapping_sub(1);
            if let (Some(e), Some(&ke)) = (cur.get(i), keys.get(i)) {
                if !key_beats(kc, &c.s, ke, &e.s) {
                    self.hint = i;
                    return;
                }
            }
        }
        // Sorted best first: "c beats e" is false up to some index and true
        // from there on.
        let pos = pairs_partition_point(cur, keys, |e, ke| !key_beats(kc, &c.s, ke, &e.s));
        // The first near entry (every near one lies at or after `pos`), or `len`.
        let first_near = if near == 0 {
            len
        } else {
            near.trailing_zeros() as usize
        };
        // The kept entries after the first near one close up over the near
        // ones, from the slot after it (`c` adds one entry before them).
        let mut w = first_near.saturating_add(1);
        for i in first_near.saturating_add(1)..len {
            // i < len ≤ MAX_CANDIDATES = 64: the shift is in range.
            if near & 1u64.wrapping_shl(u32::try_from(i).unwrap_or(u32::MAX)) != 0 {
                continue;
            }
            self.move_entry(i, w);
            // w ≤ i < len ≤ MAX_CANDIDATES.
            w = w.wrapping_add(1);
        }
        // Entries `pos..first_near` move one right (the last falls off a full
        // list without near entries), and `c` takes `pos`.
        let end = if near == 0 {
            len.saturating_add(1).min(self.cap)
        } else {
            w
        };
        let mut i = first_near.min(self.cap.saturating_sub(1));
        while i > pos {
            self.move_entry(i.wrapping_sub(1), i);
            i = i.wrapping_sub(1);
        }
        if let (Some(d), Some(dk), Some(dx), Some(dy)) = (
            self.items.get_mut(pos),
            self.keys.get_mut(pos),
            self.xs.get_mut(pos),
            self.ys.get_mut(pos),
        ) {
            *d = c;
            *dk = kc;
            *dx = pos_u32(c.x);
            *dy = pos_u32(c.y);
        }
        self.len = end;
        self.hint = pos;
    }

    /// Copy entry `from` (and its key) to slot `to`.
    #[inline]
    fn move_entry(&mut self, from: usize, to: usize) {
        if let (Some(&e), Some(&k), Some(&x), Some(&y)) = (
            self.items.get(from),
            self.keys.get(from),
            self.xs.get(from),
            self.ys.get(from),
        ) {
            if let (Some(d), Some(dk), Some(dx), Some(dy)) = (
                self.items.get_mut(to),
                self.keys.get_mut(to),
                self.xs.get_mut(to),
                self.ys.get_mut(to),
            ) {
                *d = e;
                *dk = k;
                *dx = x;
                *dy = y;
            }
        }
    }
}
