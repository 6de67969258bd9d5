//! The correlation kernel: exact Σ t·f of a template level at a block of
//! neighbouring window positions.

use super::pyramid::{Tpl, Win};

/// Template bytes per step of the correlation kernel (one 128-bit vector).
pub(super) const KERNEL_CHUNK: usize = 16;
/// Neighbouring x positions the correlation kernel scores per pass over the
/// template rows.
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

/// Σ t·f of the template at the `B` neighbouring positions `(px + b, py)` of the
/// window, `b < B`, on x86-64 and AArch64: explicit 256-bit integer vectors
/// ([`wide`], safe, `no_std`, no allocation). Every template chunk of 16 bytes is
/// widened to i16 once and feeds `B` widening multiply-adds (`pmaddwd` on SSE2,
/// `vpmaddwd` with AVX2, `smull`/`addp` on NEON) into `B` vector accumulators
/// that stay in registers across all rows; each position is reduced to a scalar
/// once, at the end. Exact: u8 values widened to i16 multiply into pair sums
/// below 2¹⁸, and the accumulators wrap modulo 2³² like the portable kernel's
/// (each true sum < 2³², numeric.md), so both kernels return the same bits
/// (`blocked_kernel_equals_scalar_reference`). Same contract as
/// [`dot_block_portable`].
///
/// The auto-vectorized portable kernel reduces every 16-byte chunk to a scalar
/// (the shape LLVM vectorizes reliably under fat LTO), which on rows of 16–64
/// bytes costs as much as the multiply-adds; here the reduction happens once
/// per position (`fsw-docs/budgets/ncc.md`).
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
#[allow(
    clippy::arithmetic_side_effects,
    reason = "vector lane addition wraps (wide's documented semantics); exact modulo 2^32 as above"
)]
pub(super) fn dot_block<const B: usize>(t: &Tpl, win: &Win, px: usize, py: usize) -> [u32; B] {
    use wide::{i16x16, i32x8, u8x16};
    const C: usize = KERNEL_CHUNK;
    let mut acc = [i32x8::ZERO; B];
    let mut s = [0u32; B];
    let widen = |c: &[u8; C]| i16x16::from(u8x16::from(*c));
    let span = t.w.saturating_add(B.saturating_sub(1));
    for (r, trow) in t.px.chunks_exact(t.w.max(1)).take(t.h).enumerate() {
        let Some(frow) = py.checked_add(r).and_then(|y| win.span(px, y, span)) else {
            continue;
        };
        let (tc, rem) = trow.as_chunks::<C>();
        let mut o = 0usize;
        for tt in tc {
            let tv = widen(tt);
            let Some(fw) = frow
                .get(o..)
                .and_then(|f| f.get(..C.saturating_add(B).saturating_sub(1)))
            else {
                break;
            };
            for (b, ab) in acc.iter_mut().enumerate() {
                if let Some(ff) = fw.get(b..).and_then(|f| f.first_chunk::<C>()) {
                    *ab += tv.dot(widen(ff));
                }
            }
            o = o.saturating_add(C);
        }
        for (j, &p) in rem.iter().enumerate() {
            let Some(fw) = frow.get(o.saturating_add(j)..).and_then(|f| f.get(..B)) else {
                break;
            };
            for (sb, &q) in s.iter_mut().zip(fw) {
                *sb = sb.wrapping_add(u32::from(p).wrapping_mul(u32::from(q)));
            }
        }
    }
    for (sb, ab) in s.iter_mut().zip(acc) {
        *sb = sb.wrapping_add(ab.reduce_add().cast_unsigned());
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

    /// The blocked kernel equals the scalar reference at every position of every
    /// block, for widths that are and are not multiples of the chunk and block,
    /// with masked (zeroed) template pixels and at the largest template.
    #[test]
    fn blocked_kernel_equals_scalar_reference() {
        let mut rng = Rng::new(31);
        for case in 0..400 {
            let (tw, th) = if case == 0 {
                (MAX_TEMPLATE_PX, MAX_TEMPLATE_PX)
            } else {
                (1 + rng.below(70) as usize, 1 + rng.below(40) as usize)
            };
            let (ww, wh) = (
                tw + KERNEL_BLOCK - 1 + rng.below(20) as usize,
                th + rng.below(10) as usize,
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
            let t = Tpl {
                px: &px,
                runs: None,
                w: tw,
                h: th,
                n: 1,
                st: 0,
                var_t: 1,
            };
            let w = Win {
                px: &win,
                w: ww,
                h: wh,
            };
            for _ in 0..4 {
                let x = rng.below((ww + 2 - tw - KERNEL_BLOCK) as u32) as usize;
                let y = rng.below((wh - th + 1) as u32) as usize;
                let got = dot_block::<KERNEL_BLOCK>(&t, &w, x, y);
                for (b, &g) in got.iter().enumerate() {
                    let want = ref_dot(&px, tw, th, &win, ww, x + b, y);
                    assert!(want < 1 << 32, "case {case}: reference {want} exceeds u32");
                    assert_eq!(
                        u64::from(g),
                        want,
                        "case {case}: {tw}x{th} at ({}, {y})",
                        x + b
                    );
                }
                assert_eq!(
                    got,
                    dot_block_portable::<KERNEL_BLOCK>(&t, &w, x, y),
                    "case {case}: vector and portable kernels differ"
                );
                let [one] = dot_block::<1>(&t, &w, x, y);
                assert_eq!(
                    u64::from(one),
                    ref_dot(&px, tw, th, &win, ww, x, y),
                    "case {case}"
                );
            }
        }
    }
}
