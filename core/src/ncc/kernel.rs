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
/// 2–4× slower (`fsw-docs/budgets/ncc.md`).
pub(super) fn dot_block<const B: usize>(t: &Tpl, win: &Win, px: usize, py: usize) -> [u32; B] {
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
