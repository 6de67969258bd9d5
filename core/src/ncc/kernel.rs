//! The correlation kernels: exact Σ t·f of a template level at a block of
//! neighbouring window positions (a column of positions on x86-64 and AArch64,
//! a row elsewhere).

use super::pyramid::{Tpl, Win};

/// Template bytes per step of the correlation kernel (one 128-bit vector).
pub(super) const KERNEL_CHUNK: usize = 16;
/// Neighbouring x positions the portable kernel scores per pass over the
/// template rows.
#[cfg_attr(
    any(target_arch = "x86_64", target_arch = "aarch64"),
    allow(
        dead_code,
        reason = "the column kernel serves these targets; tests run both"
    )
)]
pub(super) const KERNEL_BLOCK: usize = 4;

/// Σ t·f of one `C`-byte chunk, written as one reduction: LLVM's SLP vectorizer
/// turns this shape (and not a per-lane accumulator array) into widening
/// multiply-adds (`pmaddwd` on x86-64, see `fsw-docs/budgets/ncc.md`).
#[inline(always)]
#[allow(
    clippy::arithmetic_side_effects,
    reason = "u8 × u8 < 2^16 in u32; the sum wraps explicitly (exact, numeric.md)"
)]
fn chunk_dot<const C: usize>(t: &[u8; C], f: &[u8; C]) -> u32 {
    t.iter().zip(f).fold(0u32, |s, (&a, &b)| {
        s.wrapping_add(u32::from(a) * u32::from(b))
    })
}

/// Vertically neighbouring positions the vector kernel scores per pass over
/// the window rows ([`dot_col`]).
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
pub(super) const COL_BLOCK: usize = 8;

/// Σ t·f of the template at the `B` vertically neighbouring positions
/// `(px, py + j)` of the window, `j < B`, on x86-64 and AArch64: explicit
/// integer vectors ([`wide`], safe, `no_std`, no allocation).
///
/// The template level is stored as i16 ([`Tpl::px`], widened once per search),
/// so only the window is widened here: each 16-pixel chunk of window row
/// `py + yy` is widened once (`punpck{l,h}bw` on SSE2, `vpmovzxbw` with AVX2,
/// `zip1`/`zip2` on NEON) and feeds one widening multiply-add (`pmaddwd`,
/// `vpmaddwd`, `smull`/`addp`) for each of the `B` positions whose template row
/// `yy − j` lies on it, into `B` vector accumulators that stay in registers;
/// each position is reduced to a scalar once, at the end. Exact: u8 values in
/// i16 lanes multiply into pair sums below 2¹⁸, and the accumulators wrap modulo
/// 2³² like the portable kernel's (each true sum < 2³², numeric.md), so both
/// kernels return the same bits (`kernels_equal_scalar_reference`).
/// Every position must be a valid top-left position (`px + t.w ≤ win.w`,
/// `py + B − 1 + t.h ≤ win.h`); rows outside the window read nothing.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
#[allow(
    clippy::arithmetic_side_effects,
    reason = "vector lane addition wraps (wide's documented semantics); exact modulo 2^32 as above"
)]
#[inline]
pub(super) fn dot_col<const B: usize>(t: &Tpl, win: &Win, px: usize, py: usize) -> [u32; B] {
    const C: usize = KERNEL_CHUNK;
    if t.w % C == 0 && t.h >= B {
        // A 16-byte-aligned template (the usual case: the scratch is allocated
        // aligned and carved at multiples of 16) is read as whole aligned
        // vectors: on SSE2 without AVX `pmaddwd` takes it straight from memory;
        // on AArch64 with strict alignment (aarch64-unknown-none) the 16-bit
        // lanes of a byte-aligned chunk would be assembled byte by byte.
        #[cfg(any(
            target_arch = "aarch64",
            all(target_arch = "x86_64", not(target_feature = "avx"))
        ))]
        if let Ok(v) = wide::bytemuck::try_cast_slice::<u8, wide::i16x8>(t.px) {
            let rows = v.as_chunks::<2>().0;
            match t.w / C {
                1 => return dot_col_fixed::<Aligned, B, 1>(rows, t.h, win, px, py),
                2 => return dot_col_fixed::<Aligned, B, 2>(rows, t.h, win, px, py),
                3 => return dot_col_fixed::<Aligned, B, 3>(rows, t.h, win, px, py),
                4 => return dot_col_fixed::<Aligned, B, 4>(rows, t.h, win, px, py),
                _ => {}
            }
        }
        let rows = t.px.as_chunks::<{ 2 * C }>().0;
        match t.w / C {
            1 => return dot_col_fixed::<Bytes, B, 1>(rows, t.h, win, px, py),
            2 => return dot_col_fixed::<Bytes, B, 2>(rows, t.h, win, px, py),
            3 => return dot_col_fixed::<Bytes, B, 3>(rows, t.h, win, px, py),
            4 => return dot_col_fixed::<Bytes, B, 4>(rows, t.h, win, px, py),
            _ => {}
        }
    }
    dot_col_rows::<B>(t, win, px, py)
}

/// How [`dot_col_fixed`] holds 16 template pixels (a chunk), 16 widened window
/// pixels and a position's accumulator.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
trait Lanes {
    type Chunk;
    type Px: Copy;
    type Acc: Copy;
    const ZERO: Self::Acc;
    fn widen(f: &[u8; 16]) -> Self::Px;
    fn mac(acc: &mut Self::Acc, t: &Self::Chunk, f: Self::Px);
    fn reduce(acc: Self::Acc) -> u32;
}

/// 16 window pixels as two vectors of 8 i16 lanes: interleaved with zero bytes
/// (`punpck{l,h}bw` on SSE2, `zip1`/`zip2` on NEON), which read as
/// little-endian i16 are the pixels.
#[cfg(all(
    any(target_arch = "x86_64", target_arch = "aarch64"),
    not(target_feature = "avx2")
))]
#[inline(always)]
fn widen_halves(f: &[u8; 16]) -> (wide::i16x8, wide::i16x8) {
    use wide::{bytemuck::cast, u8x16};
    let (u, z) = (u8x16::from(*f), u8x16::ZERO);
    (
        cast(u8x16::unpack_low(u, z)),
        cast(u8x16::unpack_high(u, z)),
    )
}

/// Template chunks as 32 unaligned bytes (16 little-endian i16). With AVX2 a
/// 256-bit accumulator fed by one `vpmaddwd` per chunk; otherwise (SSE2, NEON)
/// a 128-bit accumulator fed by two 8-lane multiply-adds, so that the
/// accumulators of a column block fit the registers.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
struct Bytes;

#[cfg(all(
    any(target_arch = "x86_64", target_arch = "aarch64"),
    target_feature = "avx2"
))]
impl Lanes for Bytes {
    type Chunk = [u8; 32];
    type Px = wide::i16x16;
    type Acc = wide::i32x8;
    const ZERO: wide::i32x8 = wide::i32x8::ZERO;

    #[inline(always)]
    fn widen(f: &[u8; 16]) -> wide::i16x16 {
        wide::i16x16::from(wide::u8x16::from(*f))
    }

    #[inline(always)]
    #[allow(
        clippy::arithmetic_side_effects,
        reason = "vector lane addition wraps (wide's documented semantics); exact modulo 2^32 (numeric.md)"
    )]
    fn mac(acc: &mut wide::i32x8, t: &[u8; 32], f: wide::i16x16) {
        *acc += wide::bytemuck::cast::<[u8; 32], wide::i16x16>(*t).dot(f);
    }

    #[inline(always)]
    fn reduce(acc: wide::i32x8) -> u32 {
        acc.reduce_add().cast_unsigned()
    }
}

#[cfg(all(
    any(target_arch = "x86_64", target_arch = "aarch64"),
    not(target_feature = "avx2")
))]
impl Lanes for Bytes {
    type Chunk = [u8; 32];
    type Px = (wide::i16x8, wide::i16x8);
    type Acc = wide::i32x4;
    const ZERO: wide::i32x4 = wide::i32x4::ZERO;

    #[inline(always)]
    fn widen(f: &[u8; 16]) -> Self::Px {
        widen_halves(f)
    }

    #[inline(always)]
    #[allow(
        clippy::arithmetic_side_effects,
        reason = "vector lane addition wraps (wide's documented semantics); exact modulo 2^32 (numeric.md)"
    )]
    fn mac(acc: &mut wide::i32x4, t: &[u8; 32], f: Self::Px) {
        // Loaded as bytes, then reinterpreted: the chunk has byte alignment, and
        // a target with strict alignment (aarch64-unknown-none) would otherwise
        // assemble 16-bit lanes byte by byte.
        let [lo, hi] =
            t.as_chunks::<16>()
                .0
                .first_chunk::<2>()
                .map_or([wide::i16x8::ZERO; 2], |[a, b]| {
                    [
                        wide::bytemuck::cast(wide::u8x16::from(*a)),
                        wide::bytemuck::cast(wide::u8x16::from(*b)),
                    ]
                });
        *acc += lo.dot(f.0) + hi.dot(f.1);
    }

    #[inline(always)]
    fn reduce(acc: wide::i32x4) -> u32 {
        acc.reduce_add().cast_unsigned()
    }
}

/// Template chunks as two aligned 8-lane vectors (SSE2, NEON): both products
/// of a chunk go into one 128-bit accumulator.
#[cfg(any(
    target_arch = "aarch64",
    all(target_arch = "x86_64", not(target_feature = "avx"))
))]
struct Aligned;

#[cfg(any(
    target_arch = "aarch64",
    all(target_arch = "x86_64", not(target_feature = "avx"))
))]
impl Lanes for Aligned {
    type Chunk = [wide::i16x8; 2];
    type Px = (wide::i16x8, wide::i16x8);
    type Acc = wide::i32x4;
    const ZERO: wide::i32x4 = wide::i32x4::ZERO;

    #[inline(always)]
    fn widen(f: &[u8; 16]) -> Self::Px {
        widen_halves(f)
    }

    #[inline(always)]
    #[allow(
        clippy::arithmetic_side_effects,
        reason = "vector lane addition wraps (wide's documented semantics); exact modulo 2^32 (numeric.md)"
    )]
    fn mac(acc: &mut wide::i32x4, [lo, hi]: &[wide::i16x8; 2], f: Self::Px) {
        *acc += lo.dot(f.0) + hi.dot(f.1);
    }

    #[inline(always)]
    fn reduce(acc: wide::i32x4) -> u32 {
        acc.reduce_add().cast_unsigned()
    }
}

/// [`dot_col`] for templates of exactly `NC` 16-pixel chunks per row (`chunks`:
/// the level's chunks, row-major, `th` rows): every row is a fixed-size array,
/// so the loops over chunks and positions carry no bounds checks, and the `B`
/// template rows of a window row in the body of the pass are one fixed-size
/// block (rows `yy − B + 1 ..= yy`, position `j` on block row `B − 1 − j`).
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
#[inline]
fn dot_col_fixed<L: Lanes, const B: usize, const NC: usize>(
    chunks: &[L::Chunk],
    th: usize,
    win: &Win,
    px: usize,
    py: usize,
) -> [u32; B] {
    const C: usize = KERNEL_CHUNK;
    let rows = chunks.as_chunks::<NC>().0;
    let (Some(rows), Some(fstart)) = (
        rows.get(..th),
        py.checked_mul(win.stride).and_then(|o| o.checked_add(px)),
    ) else {
        return [0; B];
    };
    let mut acc = [L::ZERO; B];
    // Window rows py, py + 1, …, each as NC chunks of 16 pixels (None where
    // the window ends, never by the contract: such a row adds nothing).
    let mut frows = win
        .px
        .get(fstart..)
        .unwrap_or(&[])
        .chunks(win.stride.max(1))
        .map(|r| r.as_chunks::<C>().0.first_chunk::<NC>());
    // First B − 1 window rows: only positions j ≤ yy have a template row.
    for yy in 0..B.saturating_sub(1) {
        if let Some(Some(frow)) = frows.next() {
            edge_row::<L, B, NC>(&mut acc, rows, yy, frow);
        }
    }
    // Body: window row yy = B − 1 + i meets template rows i ..= i + B − 1,
    // one block (position j on block row B − 1 − j); the blocks and the window
    // rows advance together.
    for (blk, frow) in rows.windows(B).zip(frows.by_ref()) {
        let (Some(blk), Some(frow)) = (blk.first_chunk::<B>(), frow) else {
            continue;
        };
        for (c, f) in frow.iter().enumerate() {
            let fv = L::widen(f);
            for (a, row) in acc.iter_mut().zip(blk.iter().rev()) {
                if let Some(tt) = row.get(c) {
                    L::mac(a, tt, fv);
                }
            }
        }
    }
    // Last B − 1 window rows: only positions j > i have a template row.
    for yy in th..th.saturating_add(B).saturating_sub(1) {
        if let Some(Some(frow)) = frows.next() {
            edge_row::<L, B, NC>(&mut acc, rows, yy, frow);
        }
    }
    acc.map(L::reduce)
}

/// One of the first or last `B − 1` window rows of a [`dot_col_fixed`] pass:
/// window row `yy` meets template row `yy − j` of position `j` where that
/// exists. Indexed by the (unrolled) `j` only, so the accumulators stay in
/// registers once inlined.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
#[inline(always)]
fn edge_row<L: Lanes, const B: usize, const NC: usize>(
    acc: &mut [L::Acc; B],
    rows: &[[L::Chunk; NC]],
    yy: usize,
    frow: &[[u8; KERNEL_CHUNK]; NC],
) {
    let tr: [Option<&[L::Chunk; NC]>; B] =
        core::array::from_fn(|j| yy.checked_sub(j).and_then(|r| rows.get(r)));
    for (c, f) in frow.iter().enumerate() {
        let fv = L::widen(f);
        for (a, row) in acc.iter_mut().zip(&tr) {
            if let Some(tt) = row.and_then(|r| r.get(c)) {
                L::mac(a, tt, fv);
            }
        }
    }
}

/// [`dot_col`] for any template width: row by row, with a scalar tail.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
#[allow(
    clippy::arithmetic_side_effects,
    reason = "vector lane addition wraps (wide's documented semantics); exact modulo 2^32 as above"
)]
fn dot_col_rows<const B: usize>(t: &Tpl, win: &Win, px: usize, py: usize) -> [u32; B] {
    use wide::{bytemuck::cast, i16x16, i32x8, u8x16};
    const C: usize = KERNEL_CHUNK;
    let tw = t.w;
    let row_bytes = tw.saturating_mul(2);
    let mut acc = [i32x8::ZERO; B];
    let mut s = [0u32; B];
    let rows = t.h.saturating_add(B).saturating_sub(1);
    for yy in 0..rows {
        let Some(frow) = py.checked_add(yy).and_then(|y| win.span(px, y, tw)) else {
            continue;
        };
        let (fc, frem) = frow.as_chunks::<C>();
        // Template row `yy − j` for position j, empty where there is none.
        let mut tr: [&[u8]; B] = [&[]; B];
        for (j, slot) in tr.iter_mut().enumerate() {
            if let Some(row) = yy
                .checked_sub(j)
                .filter(|&r| r < t.h)
                .and_then(|r| r.checked_mul(row_bytes))
                .and_then(|o| t.px.get(o..))
                .and_then(|r| r.get(..row_bytes))
            {
                *slot = row;
            }
        }
        let tc = tr.map(|r| r.as_chunks::<{ 2 * C }>().0);
        for (c, f) in fc.iter().enumerate() {
            let fv = i16x16::from(u8x16::from(*f));
            for (a, tj) in acc.iter_mut().zip(&tc) {
                if let Some(tt) = tj.get(c) {
                    *a += cast::<[u8; 32], i16x16>(*tt).dot(fv);
                }
            }
        }
        if !frem.is_empty() {
            let o = fc.len().saturating_mul(2 * C);
            for (sj, trow) in s.iter_mut().zip(&tr) {
                let tail = trow.get(o..).unwrap_or(&[]).as_chunks::<2>().0;
                for (p, &q) in tail.iter().zip(frem) {
                    *sj = sj.wrapping_add(u32::from(u16::from_le_bytes(*p)) * u32::from(q));
                }
            }
        }
    }
    for (sj, aj) in s.iter_mut().zip(acc) {
        *sj = sj.wrapping_add(aj.reduce_add().cast_unsigned());
    }
    s
}

/// Every other target (Cortex-M7, RISC-V without V) runs the portable kernel.
#[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
pub(super) use dot_block_portable as dot_block;

/// Σ t·f of the template at the `B` neighbouring positions `(px + b, py)` of the
/// window, `b < B`; exact (each true sum < 2³², see numeric.md; u32 wrapping
/// makes the order of the additions irrelevant). Every position must be a valid
/// top-left position (`px + B − 1 + t.w ≤ win.w`, `py + t.h ≤ win.h`).
///
/// Blocked by template row: each row's index arithmetic and bounds checks are
/// paid once for `B` positions, and the row (≤ 256 bytes) is read `B` times
/// while it sits in L1. The chunk loop runs inside the position loop on purpose:
/// with the chunk outside (one template load feeding `B` reductions in one basic
/// block) the SLP vectorizer emits `pmaddwd` in a non-LTO build but falls back to
/// scalar multiplies after the workspace's fat-LTO pre-link pipeline, measured
/// 2–4× slower (`fsw-docs/budgets/ncc.md`). On the Cortex-M7 it compiles to
/// `ldrb` + `smlabb` per byte.
#[cfg_attr(
    any(target_arch = "x86_64", target_arch = "aarch64"),
    allow(
        dead_code,
        reason = "the vector kernel serves these targets; tests compare both"
    )
)]
pub(super) fn dot_block_portable<const B: usize>(
    t: &Tpl,
    win: &Win,
    px: usize,
    py: usize,
) -> [u32; B] {
    const C: usize = KERNEL_CHUNK;
    let mut s = [0u32; B];
    // Checked index arithmetic, once per row and position: positions outside
    // the contract read nothing instead of panicking.
    for (r, trow) in t.px.chunks_exact(t.w.max(1)).take(t.h).enumerate() {
        let span = t.w.saturating_add(B.saturating_sub(1));
        let Some(frow) = py.checked_add(r).and_then(|y| win.span(px, y, span)) else {
            continue;
        };
        // `as_chunks`: fixed-size chunks without the divide by a runtime chunk
        // size (and its zero-divisor panic path) that `chunks_exact` + `zip` has.
        let (tc, rem) = trow.as_chunks::<C>();
        for (b, sb) in s.iter_mut().enumerate() {
            let Some(fb) = frow.get(b..).and_then(|f| f.get(..t.w)) else {
                continue;
            };
            let (fc, frem) = fb.as_chunks::<C>();
            let mut acc = *sb;
            for (tt, ff) in tc.iter().zip(fc) {
                acc = acc.wrapping_add(chunk_dot(tt, ff));
            }
            for (&p, &q) in rem.iter().zip(frem) {
                acc = acc.wrapping_add(u32::from(p).wrapping_mul(u32::from(q)));
            }
            *sb = acc;
        }
    }
    s
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::super::pyramid::{Tpl, Win};
    use super::super::test_util::*;
    use super::super::*;
    use super::*;
    use crate::rng::Rng;
    use std::vec;
    use std::vec::Vec;

    /// Rows of positions the test windows leave room for below a template.
    const COL_BLOCK_TEST: usize = 8;

    /// The template level as the vector kernel reads it (little-endian i16).
    fn widened(px: &[u8]) -> Vec<u8> {
        px.iter().flat_map(|&v| [v, 0]).collect()
    }

    /// The kernels equal the scalar reference at every position of every block,
    /// for widths that are and are not multiples of the chunk (with the fixed
    /// 16-, 32-, 48- and 64-pixel paths drawn often), templates shorter than a
    /// column block, masked (zeroed) template pixels and the largest template:
    /// the portable row kernel for blocks of 1 and `KERNEL_BLOCK` positions, and
    /// on the vector targets the column kernel for blocks of 1 to `COL_BLOCK`.
    #[test]
    fn kernels_equal_scalar_reference() {
        let mut rng = Rng::new(31);
        for case in 0..600 {
            let (tw, th) = match case {
                0 => (MAX_TEMPLATE_PX, MAX_TEMPLATE_PX),
                _ if case % 2 == 0 => {
                    (16 * (1 + rng.below(4) as usize), 1 + rng.below(40) as usize)
                }
                _ => (1 + rng.below(70) as usize, 1 + rng.below(40) as usize),
            };
            let (ww, wh) = (
                tw + KERNEL_BLOCK - 1 + rng.below(20) as usize,
                th + COL_BLOCK_TEST + rng.below(10) as usize,
            );
            let win: Vec<u8> = if case % 7 == 0 {
                vec![255; ww * wh]
            } else {
                random_px(ww * wh, &mut rng)
            };
            let mut px = if case % 7 == 0 {
                vec![255; tw * th]
            } else {
                random_px(tw * th, &mut rng)
            };
            if case % 3 == 1 {
                for p in px.iter_mut() {
                    if rng.below(3) == 0 {
                        *p = 0;
                    }
                }
            }
            // The i16 template at an aligned and at an odd address (the
            // aligned and the byte-aligned paths of the column kernel).
            let px16 = widened(&px);
            let odd_buf = [&[0u8][..], &px16].concat();
            let tpl = |px| Tpl {
                px,
                runs: None,
                w: tw,
                h: th,
                n: 1,
                st: 0,
                var_t: 1,
            };
            let t8 = tpl(&px);
            let w = Win {
                px: &win,
                w: ww,
                h: wh,
                stride: ww,
            };
            for _ in 0..4 {
                let x = rng.below((ww + 2 - tw - KERNEL_BLOCK) as u32) as usize;
                let y = rng.below((wh - th - COL_BLOCK_TEST + 1) as u32) as usize;
                let want = |dx: usize, dy: usize| {
                    let v = ref_dot(&px, tw, th, &win, ww, x + dx, y + dy);
                    assert!(v < 1 << 32, "case {case}: reference {v} exceeds u32");
                    v
                };
                let got = dot_block_portable::<KERNEL_BLOCK>(&t8, &w, x, y);
                for (b, &g) in got.iter().enumerate() {
                    assert_eq!(
                        u64::from(g),
                        want(b, 0),
                        "case {case}: {tw}x{th} at ({}, {y})",
                        x + b
                    );
                }
                let [one] = dot_block_portable::<1>(&t8, &w, x, y);
                assert_eq!(u64::from(one), want(0, 0), "case {case}");
                #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
                {
                    for t16 in [tpl(&px16), tpl(&odd_buf[1..])] {
                        let col = |got: &[u32]| {
                            for (j, &g) in got.iter().enumerate() {
                                assert_eq!(
                                    u64::from(g),
                                    want(0, j),
                                    "case {case}: {tw}x{th} at ({x}, {})",
                                    y + j
                                );
                            }
                        };
                        col(&dot_col::<1>(&t16, &w, x, y));
                        col(&dot_col::<2>(&t16, &w, x, y));
                        col(&dot_col::<3>(&t16, &w, x, y));
                        col(&dot_col::<4>(&t16, &w, x, y));
                        col(&dot_col::<5>(&t16, &w, x, y));
                        col(&dot_col::<COL_BLOCK>(&t16, &w, x, y));
                    }
                }
                #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
                let _ = &px16;
            }
        }
    }
}
