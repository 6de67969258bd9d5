//! Checked image views with stride, borrowed from the caller.
//!
//! A view is built once by [`ImageView::new`] / [`ImageViewMut::new`], which
//! checks width, height, stride and buffer length against each other and against
//! [`MAX_IMAGE_DIM`]. After that every accessor returns `Option` and none can
//! panic. Pixels are row-major; pixel `(x, y)` is at `y * stride + x`.
//! 8-bit ([`GrayView`]) and 16-bit ([`Gray16View`]) views share one implementation.

use crate::config::MAX_IMAGE_DIM;
use crate::failure::FailureCode;

/// An axis-aligned pixel rectangle: top-left `(x, y)`, size `w × h`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Rect {
    /// Left column.
    pub x: i32,
    /// Top row.
    pub y: i32,
    /// Width in pixels.
    pub w: u32,
    /// Height in pixels.
    pub h: u32,
}

impl Rect {
    /// A rectangle from its top-left corner and size.
    pub const fn new(x: i32, y: i32, w: u32, h: u32) -> Self {
        Self { x, y, w, h }
    }

    /// Intersection with `other`, or `None` if they do not overlap.
    pub fn intersect(&self, other: &Rect) -> Option<Rect> {
        let x0 = i64::from(self.x).max(i64::from(other.x));
        let y0 = i64::from(self.y).max(i64::from(other.y));
        let x1 =
            (i64::from(self.x) + i64::from(self.w)).min(i64::from(other.x) + i64::from(other.w));
        let y1 =
            (i64::from(self.y) + i64::from(self.h)).min(i64::from(other.y) + i64::from(other.h));
        if x1 <= x0 || y1 <= y0 {
            return None;
        }
        Some(Rect {
            x: i32::try_from(x0).ok()?,
            y: i32::try_from(y0).ok()?,
            w: u32::try_from(x1 - x0).ok()?,
            h: u32::try_from(y1 - y0).ok()?,
        })
    }

    /// Whether `other` lies entirely inside `self`.
    pub fn contains(&self, other: &Rect) -> bool {
        self.intersect(other) == Some(*other)
    }
}

fn check_layout(width: usize, height: usize, stride: usize, len: usize) -> Result<(), FailureCode> {
    if width == 0 || height == 0 || width > MAX_IMAGE_DIM || height > MAX_IMAGE_DIM {
        return Err(FailureCode::ImageDimensionsInvalid);
    }
    if stride < width || stride > MAX_IMAGE_DIM * 2 {
        return Err(FailureCode::ImageStrideInvalid);
    }
    // Cannot overflow: both factors are bounded by 2·MAX_IMAGE_DIM.
    let needed = (height - 1) * stride + width;
    if len < needed {
        return Err(FailureCode::ImageBufferTooShort);
    }
    Ok(())
}

/// Index of pixel `(x, y)` with `stride` pixels per row. A checked view's
/// pixels never overflow (`(height − 1) · stride + width` is at most the buffer
/// length), but checked arithmetic keeps every accessor free of panic paths.
#[inline]
fn offset(y: usize, stride: usize, x: usize) -> Option<usize> {
    y.checked_mul(stride)?.checked_add(x)
}

/// A read-only image view.
#[derive(Clone, Copy, Debug)]
pub struct ImageView<'a, P: Copy = u8> {
    data: &'a [P],
    width: usize,
    height: usize,
    stride: usize,
}

/// A mutable image view.
#[derive(Debug)]
pub struct ImageViewMut<'a, P: Copy = u8> {
    data: &'a mut [P],
    width: usize,
    height: usize,
    stride: usize,
}

/// 8-bit gray view.
pub type GrayView<'a> = ImageView<'a, u8>;
/// 16-bit gray view.
pub type Gray16View<'a> = ImageView<'a, u16>;
/// Mutable 8-bit gray view.
pub type GrayViewMut<'a> = ImageViewMut<'a, u8>;
/// Mutable 16-bit gray view.
pub type Gray16ViewMut<'a> = ImageViewMut<'a, u16>;

impl<'a, P: Copy> ImageView<'a, P> {
    /// A checked view of `data` as `width × height` pixels with `stride` pixels per row.
    ///
    /// # Errors
    /// [`FailureCode::ImageDimensionsInvalid`], [`FailureCode::ImageStrideInvalid`] or
    /// [`FailureCode::ImageBufferTooShort`].
    pub fn new(
        data: &'a [P],
        width: usize,
        height: usize,
        stride: usize,
    ) -> Result<Self, FailureCode> {
        check_layout(width, height, stride, data.len())?;
        Ok(Self {
            data,
            width,
            height,
            stride,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Row stride in pixels.
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// The borrowed pixel buffer, as given to [`ImageView::new`] (at least
    /// `(height − 1) · stride + width` pixels).
    pub fn data(&self) -> &'a [P] {
        self.data
    }

    /// The whole image as a rectangle at the origin.
    pub fn rect(&self) -> Rect {
        Rect::new(0, 0, self.width as u32, self.height as u32)
    }

    /// Pixel at `(x, y)`, or `None` outside the image.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> Option<P> {
        if x >= self.width || y >= self.height {
            return None;
        }
        self.data.get(offset(y, self.stride, x)?).copied()
    }

    /// Row `y` (exactly `width` pixels), or `None` outside the image.
    #[inline]
    pub fn row(&self, y: usize) -> Option<&'a [P]> {
        if y >= self.height {
            return None;
        }
        let start = offset(y, self.stride, 0)?;
        self.data.get(start..start.checked_add(self.width)?)
    }

    /// A sub-view of `r`, or `None` unless `r` lies inside the image.
    pub fn sub(&self, r: Rect) -> Option<ImageView<'a, P>> {
        if !self.rect().contains(&r) || r.w == 0 || r.h == 0 {
            return None;
        }
        let (x, y) = (r.x as usize, r.y as usize);
        let data = self.data.get(offset(y, self.stride, x)?..)?;
        ImageView::new(data, r.w as usize, r.h as usize, self.stride).ok()
    }
}

impl<'a, P: Copy> ImageViewMut<'a, P> {
    /// A checked mutable view; same checks as [`ImageView::new`].
    ///
    /// # Errors
    /// As [`ImageView::new`].
    pub fn new(
        data: &'a mut [P],
        width: usize,
        height: usize,
        stride: usize,
    ) -> Result<Self, FailureCode> {
        check_layout(width, height, stride, data.len())?;
        Ok(Self {
            data,
            width,
            height,
            stride,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Row stride in pixels.
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// A read-only view of the same pixels.
    pub fn as_view(&self) -> ImageView<'_, P> {
        ImageView {
            data: self.data,
            width: self.width,
            height: self.height,
            stride: self.stride,
        }
    }

    /// Pixel at `(x, y)`, or `None` outside the image.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> Option<P> {
        self.as_view().get(x, y)
    }

    /// Set pixel `(x, y)`; returns `false` (and writes nothing) outside the image.
    #[inline]
    pub fn set(&mut self, x: usize, y: usize, value: P) -> bool {
        if x >= self.width || y >= self.height {
            return false;
        }
        match offset(y, self.stride, x).and_then(|i| self.data.get_mut(i)) {
            Some(p) => {
                *p = value;
                true
            }
            None => false,
        }
    }

    /// Mutable row `y` (exactly `width` pixels), or `None` outside the image.
    #[inline]
    pub fn row_mut(&mut self, y: usize) -> Option<&mut [P]> {
        if y >= self.height {
            return None;
        }
        let start = offset(y, self.stride, 0)?;
        self.data.get_mut(start..start.checked_add(self.width)?)
    }

    /// Set every pixel to `value`.
    pub fn fill(&mut self, value: P) {
        for y in 0..self.height {
            if let Some(r) = self.row_mut(y) {
                r.fill(value);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Verifies: VTSM-IMG-001
    #[test]
    fn rejects_each_inconsistent_layout() {
        let buf = [0u8; 100];
        assert_eq!(
            GrayView::new(&buf, 0, 5, 10).err(),
            Some(FailureCode::ImageDimensionsInvalid)
        );
        assert_eq!(
            GrayView::new(&buf, 5, 0, 10).err(),
            Some(FailureCode::ImageDimensionsInvalid)
        );
        assert_eq!(
            GrayView::new(&buf, MAX_IMAGE_DIM + 1, 1, MAX_IMAGE_DIM + 1).err(),
            Some(FailureCode::ImageDimensionsInvalid)
        );
        assert_eq!(
            GrayView::new(&buf, 10, 5, 9).err(),
            Some(FailureCode::ImageStrideInvalid)
        );
        assert_eq!(
            GrayView::new(&buf, 10, 11, 10).err(),
            Some(FailureCode::ImageBufferTooShort)
        );
        // Last row needs only `width`, not `stride`, pixels.
        assert!(GrayView::new(&buf, 10, 10, 10).is_ok());
        assert!(GrayView::new(&buf[..95], 5, 10, 10).is_ok());
        assert_eq!(
            GrayView::new(&buf[..94], 5, 10, 10).err(),
            Some(FailureCode::ImageBufferTooShort)
        );
    }

    /// Verifies: VTSM-IMG-003
    #[test]
    fn sub_view_reads_the_right_pixels() {
        let buf: [u16; 20] = core::array::from_fn(|i| i as u16);
        let v = Gray16View::new(&buf, 4, 5, 4).unwrap();
        let s = v.sub(Rect::new(1, 2, 2, 3)).unwrap();
        assert_eq!(s.get(0, 0), Some(9));
        assert_eq!(s.get(1, 2), Some(18));
        assert_eq!(s.get(2, 0), None);
        assert_eq!(s.row(1), Some(&buf[13..15]));
        assert!(v.sub(Rect::new(3, 0, 2, 1)).is_none());
        assert!(v.sub(Rect::new(-1, 0, 1, 1)).is_none());
    }

    proptest! {
        /// Verifies: VTSM-IMG-002, VTSM-IMG-001
        #[test]
        fn accessors_never_panic(len in 0usize..400, w in 0usize..40, h in 0usize..40, s in 0usize..50,
                                 x in 0usize..60, y in 0usize..60, rx in -5i32..50, ry in -5i32..50,
                                 rw in 0u32..50, rh in 0u32..50) {
            let mut buf = [7u8; 400];
            let ok = w > 0 && h > 0 && s >= w && len >= (h - 1) * s + w;
            let v = GrayView::new(&buf[..len], w, h, s);
            prop_assert_eq!(v.is_ok(), ok);
            if let Ok(v) = v {
                prop_assert_eq!(v.get(x, y).is_some(), x < w && y < h);
                let _ = v.row(y);
                if let Some(sv) = v.sub(Rect::new(rx, ry, rw, rh)) {
                    for yy in 0..sv.height() { prop_assert_eq!(sv.row(yy).map(|r| r.len()), Some(sv.width())); }
                }
            }
            if let Ok(mut m) = GrayViewMut::new(&mut buf[..len], w, h, s) {
                prop_assert_eq!(m.set(x, y, 1), x < w && y < h);
                let _ = m.row_mut(y);
            }
        }
    }
}
