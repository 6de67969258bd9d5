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
        for (dx, o) in (0..rw).zip(orow.iter_mut()) {
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
