//! Where the real stereo pair's pixels come from.
//!
//! The engine never needs a whole frame at once: each attempt matches inside
//! two search windows (at most `params.search_px`² pixels each) and the
//! preflight samples [`crate::reloc::preflight::PREFLIGHT_ROWS`] pairs of rows.
//! A [`FrameSource`] serves exactly those rectangles on demand, so the pair
//! may stay where the camera put it — its frame buffer, or mass memory behind
//! a driver — and RAM holds only the windows the workspace copies them into.
//!
//! [`StereoPair`] is the source over two in-memory [`GrayView`]s (the desktop
//! tools, the tests, the in-RAM runner path). A source over a device lives in
//! the HAL (`vtsm_hal::FrameStore`).
//!
//! [`read_with_halo`] is the one place the engine copies pixels: the window
//! plus the one-pixel ring the 3×3 filters read, clipped to the frame, so a
//! filter over the copy sees exactly the pixels (and the border replication)
//! it would see over the whole frame, and matching gives bit-identical results.

use crate::failure::FailureCode;
use crate::image::{GrayView, Rect};

/// One camera of the rectified pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Eye {
    /// The left (reference) camera.
    Left,
    /// The right camera.
    Right,
}

/// Random-access reads of rectangles of the two frames of one stereo pair.
///
/// Both frames have the same size, [`FrameSource::size`], fixed while the
/// source is in use.
pub trait FrameSource {
    /// Width and height of each frame, pixels.
    fn size(&self) -> (usize, usize);

    /// Copy the pixels of `rect` of `eye`'s frame into `out`, row-major with
    /// `rect.w` bytes per row (`rect.w · rect.h` bytes in all).
    ///
    /// # Contract
    /// * `rect` lies inside `0..width × 0..height` and is not empty, and `out`
    ///   holds at least `rect.w · rect.h` bytes; otherwise nothing is read and
    ///   the result is an error.
    /// * On `Ok(())` the first `rect.w · rect.h` bytes of `out` are the
    ///   frame's pixels, the same on every read of the same rectangle.
    /// * On `Err(code)` the contents of `out` are unspecified; `code` says why
    ///   (the engine ends the relocalization with
    ///   [`FailureCode::RelocFrameReadFailed`]).
    /// * Bounded: the work is proportional to `rect.w · rect.h`.
    ///
    /// # Errors
    /// A code of the source's choice (e.g. [`FailureCode::ImageSizeMismatch`]
    /// for a bad rectangle, a hardware code for a device fault).
    fn read_window(&mut self, eye: Eye, rect: Rect, out: &mut [u8]) -> Result<(), FailureCode>;
}

impl<T: FrameSource + ?Sized> FrameSource for &mut T {
    fn size(&self) -> (usize, usize) {
        T::size(self)
    }
    fn read_window(&mut self, eye: Eye, rect: Rect, out: &mut [u8]) -> Result<(), FailureCode> {
        T::read_window(self, eye, rect, out)
    }
}

/// A stereo pair held in memory: the [`FrameSource`] over two checked views.
#[derive(Clone, Copy, Debug)]
pub struct StereoPair<'a> {
    /// Left image.
    pub left: GrayView<'a>,
    /// Right image.
    pub right: GrayView<'a>,
}

impl<'a> StereoPair<'a> {
    /// The pair `left`, `right` (their sizes are checked against the rig by
    /// [`crate::reloc::Setup::validate`]).
    pub const fn new(left: GrayView<'a>, right: GrayView<'a>) -> Self {
        Self { left, right }
    }

    /// The view of `eye`.
    pub const fn view(&self, eye: Eye) -> &GrayView<'a> {
        match eye {
            Eye::Left => &self.left,
            Eye::Right => &self.right,
        }
    }
}

/// Copy `rect` of `src` row-major into `out` (`rect.w` bytes per row).
///
/// # Errors
/// [`FailureCode::ImageSizeMismatch`] if `rect` is empty or not inside `src`,
/// [`FailureCode::ImageBufferTooShort`] if `out` is shorter than `rect.w · rect.h`.
pub fn copy_rect(src: &GrayView, rect: Rect, out: &mut [u8]) -> Result<(), FailureCode> {
    let sub = src.sub(rect).ok_or(FailureCode::ImageSizeMismatch)?;
    let w = sub.width();
    let out = out
        .get_mut(..w.saturating_mul(sub.height()))
        .ok_or(FailureCode::ImageBufferTooShort)?;
    // `max(1)`: `chunks_exact_mut(0)` panics (a checked view is never empty).
    for (y, dst) in (0..sub.height()).zip(out.chunks_exact_mut(w.max(1))) {
        // Rows of a checked sub-view are present and `w` long.
        // A zip, not `copy_from_slice`: no length check to fail (a memcpy
        // all the same once optimized).
        if let Some(row) = sub.row(y) {
            for (d, p) in dst.iter_mut().zip(row) {
                *d = *p;
            }
        }
    }
    Ok(())
}

impl FrameSource for StereoPair<'_> {
    /// The size both views share; `(0, 0)`, which no rig has, when they differ.
    fn size(&self) -> (usize, usize) {
        let (l, r) = (&self.left, &self.right);
        if (l.width(), l.height()) == (r.width(), r.height()) {
            (l.width(), l.height())
        } else {
            (0, 0)
        }
    }

    fn read_window(&mut self, eye: Eye, rect: Rect, out: &mut [u8]) -> Result<(), FailureCode> {
        copy_rect(self.view(eye), rect, out)
    }
}

/// A search window copied out of a frame: the view of the copy and where the
/// copy's pixel (0, 0) lies in the frame.
#[derive(Clone, Copy, Debug)]
pub struct Window<'b> {
    /// The copied pixels (the window and its clipped one-pixel ring).
    pub view: GrayView<'b>,
    /// Frame coordinates of the copy's top-left pixel.
    pub origin: (i32, i32),
}

impl Window<'_> {
    /// `r` (frame coordinates) in the copy's coordinates.
    pub fn local(&self, r: Rect) -> Rect {
        Rect::new(
            r.x.saturating_sub(self.origin.0),
            r.y.saturating_sub(self.origin.1),
            r.w,
            r.h,
        )
    }
}

/// Bytes [`read_with_halo`] needs for a window of at most `side` × `side`.
pub const fn halo_bytes(side: usize) -> usize {
    let s = side.saturating_add(2);
    s.saturating_mul(s)
}

/// Read `rect` of `eye` (inside the frame) with the one-pixel ring around it
/// that lies inside the frame into `buf`, and view the copy.
///
/// # Errors
/// The source's code for a failed read; [`FailureCode::ImageSizeMismatch`]
/// for an empty `rect` or one outside the frame;
/// [`FailureCode::ImageBufferTooShort`] if `buf` cannot hold the copy.
pub fn read_with_halo<'b, F: FrameSource + ?Sized>(
    src: &mut F,
    eye: Eye,
    rect: Rect,
    buf: &'b mut [u8],
) -> Result<Window<'b>, FailureCode> {
    let (w, h) = src.size();
    let frame = Rect::new(
        0,
        0,
        u32::try_from(w).unwrap_or(u32::MAX),
        u32::try_from(h).unwrap_or(u32::MAX),
    );
    if rect.w == 0 || rect.h == 0 || !frame.contains(&rect) {
        return Err(FailureCode::ImageSizeMismatch);
    }
    let grown = Rect::new(
        rect.x.saturating_sub(1),
        rect.y.saturating_sub(1),
        rect.w.saturating_add(2),
        rect.h.saturating_add(2),
    );
    let halo = grown
        .intersect(&frame)
        .ok_or(FailureCode::ImageSizeMismatch)?;
    let (hw, hh) = (halo.w as usize, halo.h as usize);
    let n = hw.saturating_mul(hh);
    let out = buf.get_mut(..n).ok_or(FailureCode::ImageBufferTooShort)?;
    src.read_window(eye, halo, out)?;
    let out: &'b [u8] = out;
    Ok(Window {
        view: GrayView::new(out, hw, hh, hw)?,
        origin: (halo.x, halo.y),
    })
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec;
    use std::vec::Vec;

    /// Verifies: VTSM-IMG-004
    #[test]
    fn halo_copy_holds_the_window_and_its_clipped_ring() {
        let (w, h) = (40usize, 30usize);
        let left: Vec<u8> = (0..w * h).map(|i| (i * 7 % 251) as u8).collect();
        let right: Vec<u8> = (0..w * h).map(|i| (i * 11 % 253) as u8).collect();
        let lv = GrayView::new(&left, w, h, w).unwrap();
        let rv = GrayView::new(&right, w, h, w).unwrap();
        let mut pair = StereoPair::new(lv, rv);
        let mut buf = vec![0u8; halo_bytes(20)];
        // Inside: the ring on all four sides.
        let r = Rect::new(5, 6, 20, 10);
        let win = read_with_halo(&mut pair, Eye::Right, r, &mut buf).unwrap();
        assert_eq!(win.origin, (4, 5));
        assert_eq!((win.view.width(), win.view.height()), (22, 12));
        assert_eq!(win.local(r), Rect::new(1, 1, 20, 10));
        for y in 0..12 {
            for x in 0..22 {
                assert_eq!(win.view.get(x, y), rv.get(x + 4, y + 5));
            }
        }
        // At the corner: the ring is clipped to the frame.
        let r = Rect::new(0, 0, 20, 20);
        let win = read_with_halo(&mut pair, Eye::Left, r, &mut buf).unwrap();
        assert_eq!(win.origin, (0, 0));
        assert_eq!((win.view.width(), win.view.height()), (21, 21));
        assert_eq!(win.view.get(20, 20), lv.get(20, 20));
        // Outside the frame, empty, or a short buffer: refused.
        let bad = Rect::new(30, 0, 20, 10);
        let e = read_with_halo(&mut pair, Eye::Left, bad, &mut buf).err();
        assert_eq!(e, Some(FailureCode::ImageSizeMismatch));
        let e = read_with_halo(&mut pair, Eye::Left, Rect::new(1, 1, 0, 5), &mut buf).err();
        assert_eq!(e, Some(FailureCode::ImageSizeMismatch));
        let e = read_with_halo(&mut pair, Eye::Left, r, &mut buf[..100]).err();
        assert_eq!(e, Some(FailureCode::ImageBufferTooShort));
        let e = pair
            .read_window(Eye::Left, Rect::new(0, 0, 41, 1), &mut buf)
            .err();
        assert_eq!(e, Some(FailureCode::ImageSizeMismatch));
    }

    /// Matching in a halo copy of the search window gives the match over the
    /// whole frame bit for bit (position, sub-pixel position, scores), in
    /// every domain and search mode, for windows inside the frame and at its
    /// borders and corners.
    ///
    /// Verifies: VTSM-IMG-004, VTSM-RELOC-037
    #[test]
    fn matching_in_a_window_copy_equals_matching_in_the_frame() {
        use crate::ncc::{self, Filter, Run, Scratch, ScratchSizes, Search};
        use crate::rng::Rng;
        let (w, h) = (160usize, 120usize);
        let mut rng = Rng::new(3);
        // Smooth texture plus noise: every domain has structure to match.
        let img: Vec<u8> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                let v = 128.0 + 60.0 * libm::sinf(x * 0.21) * libm::cosf(y * 0.17);
                (v as u32 + rng.below(24)).min(255) as u8
            })
            .collect();
        let frame = GrayView::new(&img, w, h, w).unwrap();
        let mut pair = StereoPair::new(frame, frame);
        let t = 24usize;
        let sizes = ScratchSizes::new(t, t, 72, 72, Search::CoarseToFine);
        let (mut sw, mut st, mut si, mut sr) = (
            vec![0u8; sizes.window],
            vec![0u8; sizes.template],
            vec![0u32; sizes.integral],
            vec![Run::default(); sizes.runs],
        );
        let mut buf = vec![0u8; halo_bytes(72)];
        let mut checked = 0;
        for k in 0..40u32 {
            let (tx, ty) = (
                rng.below((w - t) as u32) as usize,
                rng.below((h - t) as u32) as usize,
            );
            let tpl: Vec<u8> = (0..t * t)
                .map(|i| img[(ty + i / t) * w + tx + i % t])
                .collect();
            let tpl = GrayView::new(&tpl, t, t, t).unwrap();
            // Windows of 40..=72 px around the template, pushed against the
            // frame's edges every fourth draw.
            let side = 40 + rng.below(33) as i32;
            let mut x0 = tx as i32 - rng.below((side - t as i32) as u32) as i32;
            let mut y0 = ty as i32 - rng.below((side - t as i32) as u32) as i32;
            if k % 4 == 0 {
                x0 = 0;
            }
            if k % 4 == 1 {
                y0 = h as i32 - side;
            }
            let search = Rect::new(x0, y0, side as u32, side as u32)
                .intersect(&frame.rect())
                .unwrap();
            for filter in [Filter::Gray, Filter::Sobel, Filter::Laplacian] {
                for mode in [Search::CoarseToFine, Search::Exhaustive] {
                    let mut scratch = Scratch {
                        window: &mut sw,
                        template: &mut st,
                        integral: &mut si,
                        runs: &mut sr,
                    };
                    let whole =
                        ncc::match_template(tpl, None, frame, search, filter, mode, &mut scratch);
                    let win = read_with_halo(&mut pair, Eye::Left, search, &mut buf).unwrap();
                    let copy =
                        ncc::match_in_window(tpl, None, &win, search, filter, mode, &mut scratch);
                    match (whole, copy) {
                        (Ok((a, sa)), Ok((b, sb))) => {
                            assert_eq!((a.x, a.y, a.exact), (b.x, b.y, b.exact));
                            assert_eq!(a.sub_x.to_bits(), b.sub_x.to_bits());
                            assert_eq!(a.sub_y.to_bits(), b.sub_y.to_bits());
                            assert_eq!(a.runner_up.to_bits(), b.runner_up.to_bits());
                            assert_eq!(sa, sb);
                            checked += 1;
                        }
                        (a, b) => assert_eq!(a.err(), b.err()),
                    }
                }
            }
        }
        assert!(checked > 200, "{checked}");
    }
}
