//! Image domains (gray, Sobel, Laplacian) of a window region and the 2× box
//! downsample of the pyramids.

use super::Filter;
use crate::failure::FailureCode;
use crate::fmt::present;
use crate::image::{GrayView, Rect};

#[inline]
fn px_at(row: &[u8], x: usize) -> i32 {
    row.get(x).map_or(0, |&v| i32::from(v))
}

/// Apply `filter` to the pixels of `region` of `src`, writing `region.w × region.h`
/// bytes row-major into `out`. Neighbours outside `src` are replicated from its
/// border, so a region's output equals the same pixels of the filtered whole image.
///
/// # Errors
/// [`FailureCode::NccWindowOutsideImage`] if `region` is not inside `src`;
/// [`FailureCode::NccScratchTooSmall`] if `out` is too short.
#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "i32 sums of at most eight 8-bit pixels with weights ≤ 4 (|gx|, |gy|, |lap| ≤ 1020); `as u8` of values already within 0..=255"
)]
pub fn filter_region(
    src: &GrayView,
    region: Rect,
    filter: Filter,
    out: &mut [u8],
) -> Result<(), FailureCode> {
    if region.w == 0 || region.h == 0 || !src.rect().contains(&region) {
        return Err(FailureCode::NccWindowOutsideImage);
    }
    let (rx, ry, rw, rh) = (
        region.x as usize,
        region.y as usize,
        region.w as usize,
        region.h as usize,
    );
    let out = out
        .get_mut(..rw.saturating_mul(rh))
        .ok_or(FailureCode::NccScratchTooSmall)?;
    let (iw, ih) = (src.width(), src.height());
    // Columns of the region whose neighbours x − 1 and x + 1 lie inside the
    // image (region coordinates `lo..hi`): these go through the row kernels,
    // the (at most two) columns on the image's left and right edges through
    // the per-pixel form with replicated neighbours. Same values either way.
    let lo = usize::from(rx == 0).min(rw);
    let hi = if rx.wrapping_add(rw) >= iw {
        rw.saturating_sub(1)
    } else {
        rw
    }
    .max(lo);
    // The region lies inside `src` (checked above), so the pixel coordinates
    // below stay within the image and the wrapping additions never wrap.
    for (dy, orow) in (0..rh).zip(out.chunks_exact_mut(rw)) {
        let y = ry.wrapping_add(dy);
        // Rows of a region inside `src` (checked above) and their clamped
        // neighbours: present by construction.
        let r0 = present(src.row(y));
        if filter == Filter::Gray {
            if let Some(s) = r0.get(rx..).and_then(|r| r.get(..rw)) {
                orow.copy_from_slice(s);
            }
            continue;
        }
        let rm = present(src.row(y.saturating_sub(1)));
        let rp = present(src.row(y.wrapping_add(1).min(ih.saturating_sub(1))));
        // Interior columns: image columns rx + lo − 1 ..= rx + hi (inside the image).
        let from = rx.wrapping_add(lo).wrapping_sub(1);
        let n = hi.wrapping_sub(lo);
        let rows = [rm, r0, rp].map(|r| r.get(from..).and_then(|r| r.get(..n.wrapping_add(2))));
        if let (Some(mid), [Some(a), Some(b), Some(c)]) = (orow.get_mut(lo..hi), rows) {
            match filter {
                Filter::Sobel => sobel_row(a, b, c, mid),
                Filter::Laplacian => laplacian_row(a, b, c, mid),
                Filter::Gray => {}
            }
        }
        let edges = (0..lo).chain(hi..rw);
        for dx in edges {
            let Some(o) = orow.get_mut(dx) else {
                continue;
            };
            let x = rx.wrapping_add(dx);
            let (xm, xp) = (
                x.saturating_sub(1),
                x.wrapping_add(1).min(iw.saturating_sub(1)),
            );
            *o = match filter {
                Filter::Sobel => {
                    let gx = px_at(rm, xp) + 2 * px_at(r0, xp) + px_at(rp, xp)
                        - px_at(rm, xm)
                        - 2 * px_at(r0, xm)
                        - px_at(rp, xm);
                    let gy = px_at(rp, xm) + 2 * px_at(rp, x) + px_at(rp, xp)
                        - px_at(rm, xm)
                        - 2 * px_at(rm, x)
                        - px_at(rm, xp);
                    // |gx| + |gy| <= 2040, so /8 is at most 255.
                    (gx.unsigned_abs().wrapping_add(gy.unsigned_abs()) >> 3).min(255) as u8
                }
                Filter::Laplacian => {
                    let lap = px_at(rm, x) + px_at(rp, x) + px_at(r0, xm) + px_at(r0, xp)
                        - 4 * px_at(r0, x);
                    // lap in [-1020, 1020]: floor(lap/8) in [-128, 127].
                    ((lap >> 3).wrapping_add(128)).clamp(0, 255) as u8
                }
                Filter::Gray => px_at(r0, x) as u8,
            };
        }
    }
    Ok(())
}

/// `r[from..from + len]`, or as much of it as `r` holds.
fn span(r: &[u8], from: usize, len: usize) -> &[u8] {
    let r = r.get(from..).unwrap_or(&[]);
    r.get(..len).unwrap_or(r)
}

/// Pixels a row kernel handles per pass (its i16 column terms live on the stack).
const ROW_CHUNK: usize = 256;

/// Sobel magnitude `(|gx| + |gy|) / 8` of one row's interior pixels: `out[i]` is
/// centred on column `i + 1` of the rows above (`a`), at (`b`) and below (`c`),
/// each `out.len() + 2` long. In two passes over i16 lanes (which the compiler
/// vectorizes): the column terms `a + 2b + c` and `c − a`, then their horizontal
/// differences and sums. Every intermediate is within ±1020 and the magnitude
/// below 2041, so i16 holds them exactly: the values of the per-pixel form.
#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "i16 sums of at most four 8-bit pixels (|·| ≤ 1020) and of two such (≤ 2040); the shifted magnitude is ≤ 255"
)]
fn sobel_row(a: &[u8], b: &[u8], c: &[u8], out: &mut [u8]) {
    let mut sm = [0i16; ROW_CHUNK + 2];
    let mut df = [0i16; ROW_CHUNK + 2];
    let mut at = 0usize;
    for o in out.chunks_mut(ROW_CHUNK) {
        let m = o.len().wrapping_add(2);
        let (a, b, c) = (span(a, at, m), span(b, at, m), span(c, at, m));
        for (((s, d), &p), (&q, &r)) in sm.iter_mut().zip(df.iter_mut()).zip(a).zip(b.iter().zip(c))
        {
            let (p, q, r) = (i16::from(p), i16::from(q), i16::from(r));
            *s = p.wrapping_add(q.wrapping_mul(2)).wrapping_add(r);
            *d = r.wrapping_sub(p);
        }
        let (s0, s2) = (sm.iter(), sm.get(2..).unwrap_or(&[]).iter());
        let (d0, d1, d2) = (
            df.iter(),
            df.get(1..).unwrap_or(&[]).iter(),
            df.get(2..).unwrap_or(&[]).iter(),
        );
        for ((o, (&sl, &sr)), ((&dl, &dc), &dr)) in
            o.iter_mut().zip(s0.zip(s2)).zip(d0.zip(d1).zip(d2))
        {
            // Wrapping forms of exact i16 operations (bounds above): no
            // overflow-check branch, so the loop vectorizes.
            let gx = sr.wrapping_sub(sl);
            let gy = dl.wrapping_add(dc.wrapping_mul(2)).wrapping_add(dr);
            *o = (gx.unsigned_abs().wrapping_add(gy.unsigned_abs()) >> 3).min(255) as u8;
        }
        at = at.wrapping_add(ROW_CHUNK);
    }
}

/// Laplacian `floor(lap / 8) + 128` of one row's interior pixels, laid out as for
/// [`sobel_row`]; `lap` is within ±1020, exact in i16.
#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "i16 sums of five 8-bit terms with weights ≤ 4 (|lap| ≤ 1020); the clamped value is within 0..=255"
)]
fn laplacian_row(a: &[u8], b: &[u8], c: &[u8], out: &mut [u8]) {
    let n = out.len();
    let (up, centre, down) = (span(a, 1, n), span(b, 1, n), span(c, 1, n));
    let (left, right) = (span(b, 0, n), span(b, 2, n));
    for (((o, (&u, &d)), &q), (&l, &r)) in out
        .iter_mut()
        .zip(up.iter().zip(down))
        .zip(centre)
        .zip(left.iter().zip(right))
    {
        let lap = i16::from(u)
            .wrapping_add(i16::from(d))
            .wrapping_add(i16::from(l))
            .wrapping_add(i16::from(r))
            .wrapping_sub(i16::from(q).wrapping_mul(4));
        *o = (lap >> 3).wrapping_add(128).clamp(0, 255) as u8;
    }
}

/// 2× box downsample (rounded mean of each 2×2 block) of `src` into `dst`
/// (`src.width()/2 × src.height()/2`, row-major).
#[allow(
    clippy::cast_possible_truncation,
    reason = "the rounded mean of four bytes is ≤ 255"
)]
pub(super) fn downsample(src: &GrayView, dst: &mut [u8]) {
    let (dw, dh) = (src.width() / 2, src.height() / 2);
    if dw == 0 || dh == 0 {
        return;
    }
    for (y, drow) in (0..dh).zip(dst.chunks_exact_mut(dw)) {
        // y < dh = height / 2 and dw = width / 2: the doubled values fit.
        let (y2, w2) = (y.wrapping_mul(2), dw.wrapping_mul(2));
        let r0 = src.row(y2).and_then(|r| r.get(..w2));
        let r1 = src.row(y2.wrapping_add(1)).and_then(|r| r.get(..w2));
        if let (Some(r0), Some(r1)) = (r0, r1) {
            for ((d, a), b) in drow
                .iter_mut()
                .zip(r0.chunks_exact(2))
                .zip(r1.chunks_exact(2))
            {
                // Four bytes: at most 1020, far inside u16.
                let s = a
                    .iter()
                    .chain(b.iter())
                    .fold(0u16, |s, &v| s.wrapping_add(u16::from(v)));
                *d = (s.wrapping_add(2) >> 2) as u8;
            }
        }
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
    use std::vec::Vec;

    /// Verifies: VTSM-NCC-001, VTSM-NCC-006
    #[test]
    fn filtered_scores_equal_reference_on_reference_filtered_images() {
        let mut rng = Rng::new(12);
        for f in [Filter::Gray, Filter::Sobel, Filter::Laplacian] {
            for _ in 0..30 {
                let (tw, th) = (16 + rng.below(20) as usize, 16 + rng.below(20) as usize);
                let (iw, ih) = (
                    tw + 2 + rng.below(20) as usize,
                    th + 2 + rng.below(20) as usize,
                );
                let img = textured(iw, ih, &mut rng);
                let t = random_px(tw * th, &mut rng);
                let (x, y) = (
                    rng.below((iw - tw + 1) as u32) as usize,
                    rng.below((ih - th + 1) as u32) as usize,
                );
                let fi = ref_filter(&img, iw, ih, f);
                let ft = ref_filter(&t, tw, th, f);
                let s = score_one(&t, tw, th, None, &img, iw, ih, x, y, f);
                match ref_score(&ft, tw, th, None, &fi, iw, x, y) {
                    Some(r) => assert!((s.unwrap().to_f64() - r).abs() < 1e-9, "{f:?}"),
                    None => assert!(s.is_err(), "{f:?}"),
                }
            }
        }
    }

    /// Verifies: VTSM-NCC-006
    #[test]
    fn filter_region_equals_reference_filter_inside_and_at_borders() {
        let mut rng = Rng::new(13);
        let (w, h) = (37, 29);
        let img = random_px(w * h, &mut rng);
        for f in [Filter::Gray, Filter::Sobel, Filter::Laplacian] {
            let full = ref_filter(&img, w, h, f);
            for _ in 0..20 {
                let (x, y) = (rng.below(30) as usize, rng.below(20) as usize);
                let (rw, rh) = (
                    1 + rng.below((w - x) as u32) as usize,
                    1 + rng.below((h - y) as u32) as usize,
                );
                let mut out = vec![0u8; rw * rh];
                filter_region(
                    &view(&img, w, h),
                    Rect::new(x as i32, y as i32, rw as u32, rh as u32),
                    f,
                    &mut out,
                )
                .unwrap();
                assert_eq!(out, crop(&full, w, x, y, rw, rh), "{f:?}");
            }
        }
        // Rows wider than the row kernels' chunk (lengths around multiples of
        // ROW_CHUNK), regions on and off the image's left and right edges, and
        // 0/255 pixels, which reach the extremes of |gx| + |gy| and of lap.
        for (w, h, seed) in [
            (600usize, 5usize, 1u64),
            (ROW_CHUNK + 2, 4, 2),
            (3, 3, 3),
            (2, 6, 4),
        ] {
            let mut rng = Rng::new(seed);
            let noise = random_px(w * h, &mut rng);
            let binary: Vec<u8> = noise
                .iter()
                .map(|&v| if v & 1 == 0 { 0 } else { 255 })
                .collect();
            for img in [&noise, &binary] {
                for f in [Filter::Sobel, Filter::Laplacian] {
                    let full = ref_filter(img, w, h, f);
                    let spans = [
                        (0, w),
                        (1, w - 1),
                        (0, w.min(ROW_CHUNK + 1)),
                        (w / 3, w - w / 3),
                        (w - 1, 1),
                    ];
                    for (x, rw) in spans {
                        let rw = rw.max(1).min(w - x);
                        let mut out = vec![0u8; rw * h];
                        let r = Rect::new(x as i32, 0, rw as u32, h as u32);
                        filter_region(&view(img, w, h), r, f, &mut out).unwrap();
                        assert_eq!(
                            out,
                            crop(&full, w, x, 0, rw, h),
                            "{f:?} {w}x{h} at {x} width {rw}"
                        );
                    }
                }
            }
        }
        // Extremes of the 8-bit mappings: a vertical 0/255 step.
        let step: Vec<u8> = (0..16 * 16)
            .map(|i| if i % 16 < 8 { 0 } else { 255 })
            .collect();
        let mut out = vec![0u8; 256];
        filter_region(
            &view(&step, 16, 16),
            Rect::new(0, 0, 16, 16),
            Filter::Laplacian,
            &mut out,
        )
        .unwrap();
        assert_eq!(
            (out[7], out[8]),
            (((255 >> 3) + 128) as u8, ((-255i32 >> 3) + 128) as u8)
        );
        filter_region(
            &view(&step, 16, 16),
            Rect::new(0, 0, 16, 16),
            Filter::Sobel,
            &mut out,
        )
        .unwrap();
        assert_eq!(out[7], (4 * 255 / 8) as u8);
    }
}
