//! Edge functions walked row by row ([`EdgeWalk`]): the first or last covered
//! column of each row of a polygon edge, with one division per edge, not per row.
//!
//! Input: an edge `E(x, y) = A·x + B·y + C` in 28.4 fixed point with its owner
//! offset; output: per row, the column bound the edge puts on the span.
//! Magnitudes stay below 2^42, so the wrapping forms never wrap.

#[inline]
pub(super) fn floor_div(n: i64, d: i64) -> i64 {
    // Callers divide by a non-zero edge-function step well inside i64; the
    // wrapping forms only keep a zero divisor or `i64::MIN / −1` from panicking.
    let q = n.checked_div(d).unwrap_or(0);
    if n.checked_rem(d).unwrap_or(0) != 0 && ((n < 0) != (d < 0)) {
        q.wrapping_sub(1)
    } else {
        q
    }
}

#[inline]
pub(super) fn ceil_div(n: i64, d: i64) -> i64 {
    floor_div(n.wrapping_neg(), d).wrapping_neg()
}

/// Which bound an edge puts on a row's pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) enum Side {
    /// `A > 0`: the first covered column.
    Left,
    /// `A < 0`: the last covered column.
    Right,
    /// `A = 0`: the whole row is in or out.
    #[default]
    Flat,
}

/// One edge `E(x, y) = A·x + B·y + C` (owner offset `t`) of [`fill_polygon`],
/// walked row by row without a division per row. With `k = B·y + C`, the
/// pixel centre `x` is inside when `A·x ≥ t − k`: for `A > 0` from
/// `x ≥ ⌈(t − k)/A⌉`, for `A < 0` up to `x ≤ ⌊(t − k)/A⌋`, for `A = 0` on the
/// whole row when `k ≥ t`. Each bound is kept as `q = ⌊m / d⌋` with
/// `m = q·d + r`, `0 ≤ r < d = |A|`, where `m` moves by a fixed `δ` per row:
/// `m = t − k + A − 1` (`δ = −B`) on the left, `m = k − t` (`δ = B`) on the
/// right, so a row's step is `q += ⌊δ/d⌋`, `r += δ mod d` and one carry. The
/// same integers as the per-row divisions: one division per edge, not per row.
/// (`A = 0` keeps `m = k − t`, `δ = B`.) Magnitudes stay below 2^42 (edge
/// terms < 2^40, rows within the guard band), so the wrapping forms never wrap.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct EdgeWalk {
    pub(super) side: Side,
    pub(super) q: i64,
    pub(super) r: i64,
    pub(super) d: i64,
    pub(super) dq: i64,
    pub(super) dr: i64,
    /// `A = 0`: `k − t` of the current row, and its step `B`.
    pub(super) m: i64,
    pub(super) b: i64,
}

impl EdgeWalk {
    pub(super) fn new((a, b, c, t): (i64, i64, i64, i64), py: i64) -> Self {
        let k = b.wrapping_mul(py).wrapping_add(c);
        if a == 0 {
            return Self {
                side: Side::Flat,
                m: k.wrapping_sub(t),
                b,
                ..Self::default()
            };
        }
        let (side, d, m, delta) = if a > 0 {
            let m = t.wrapping_sub(k).wrapping_add(a).wrapping_sub(1);
            (Side::Left, a, m, b.wrapping_neg())
        } else {
            (Side::Right, a.wrapping_neg(), k.wrapping_sub(t), b)
        };
        let q = floor_div(m, d);
        let dq = floor_div(delta, d);
        Self {
            side,
            q,
            r: m.wrapping_sub(q.wrapping_mul(d)),
            d,
            dq,
            dr: delta.wrapping_sub(dq.wrapping_mul(d)),
            m: 0,
            b: 0,
        }
    }

    /// On to the next row.
    #[inline]
    pub(super) fn step(&mut self) {
        if self.side == Side::Flat {
            self.m = self.m.wrapping_add(self.b);
            return;
        }
        self.q = self.q.wrapping_add(self.dq);
        self.r = self.r.wrapping_add(self.dr);
        if self.r >= self.d {
            self.r = self.r.wrapping_sub(self.d);
            self.q = self.q.wrapping_add(1);
        }
    }
}
