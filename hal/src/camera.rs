//! Stereo camera: one synchronised, rectified left/right pair per capture,
//! written into buffers the caller owns.
//!
//! Input: two caller buffers and a timeout in clock ticks. Output: a
//! [`FrameInfo`] describing the layout of both images. [`FrameInfo::views`]
//! checks the info against the buffers once, after which the images are read
//! through panic-free [`GrayView`]s.

use crate::error::ErrorType;
use vtsm_core::image::GrayView;
use vtsm_core::FailureCode;

/// Layout and metadata of a captured stereo pair (both images share it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FrameInfo {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Distance between the starts of two rows, in bytes (≥ width).
    pub stride: u32,
    /// Capture counter of the camera; increases by one per delivered pair.
    pub sequence: u32,
    /// Capture time in ticks of the system [`crate::Clock`].
    pub timestamp_ticks: u64,
    /// Exposure time in microseconds.
    pub exposure_us: u32,
}

impl FrameInfo {
    /// Bytes one image of this layout occupies: `(height-1)*stride + width`.
    ///
    /// `None` if the layout is empty or the size overflows `usize`.
    pub fn image_len(&self) -> Option<usize> {
        let w = usize::try_from(self.width).ok()?;
        let h = usize::try_from(self.height).ok()?;
        let s = usize::try_from(self.stride).ok()?;
        if w == 0 || h == 0 || s < w {
            return None;
        }
        (h - 1).checked_mul(s)?.checked_add(w)
    }

    /// Check this info against the expected image size and the two buffers and
    /// return checked views of the left and right images.
    ///
    /// Fails with [`FailureCode::HalFrameInfoInvalid`] when the size differs
    /// from `expected` (width, height) or a buffer is too short for the layout,
    /// and with the image codes of [`GrayView::new`] otherwise.
    pub fn views<'a>(
        &self,
        expected: (u32, u32),
        left: &'a [u8],
        right: &'a [u8],
    ) -> Result<(GrayView<'a>, GrayView<'a>), FailureCode> {
        if (self.width, self.height) != expected {
            return Err(FailureCode::HalFrameInfoInvalid);
        }
        let need = self.image_len().ok_or(FailureCode::HalFrameInfoInvalid)?;
        if left.len() < need || right.len() < need {
            return Err(FailureCode::HalFrameInfoInvalid);
        }
        // Lossless: image_len() succeeded, so all three fit in usize.
        let (w, h, s) = (
            self.width as usize,
            self.height as usize,
            self.stride as usize,
        );
        Ok((
            GrayView::new(left, w, h, s)?,
            GrayView::new(right, w, h, s)?,
        ))
    }
}

/// A rectified stereo camera pair with a shared trigger.
pub trait StereoCamera: ErrorType {
    /// Capture one stereo pair into `left` and `right`.
    ///
    /// # Contract
    /// * Blocks for at most `timeout_ticks` ticks of the system clock; if no pair
    ///   is complete by then, returns an error of kind
    ///   [`Timeout`](crate::ErrorKind::Timeout).
    /// * On `Ok(info)`, both buffers hold a complete image with the layout of
    ///   `info` (`info.image_len()` bytes each, row-major, 8-bit gray,
    ///   rectified), taken at the same instant, and `info.sequence` is larger
    ///   than that of every earlier `Ok`.
    /// * If the transfer ended early, returns kind
    ///   [`Truncated`](crate::ErrorKind::Truncated); if the link detected
    ///   damage, kind [`Corrupted`](crate::ErrorKind::Corrupted). After any
    ///   error the buffer contents are unspecified and must not be used.
    /// * If a buffer is shorter than one image, returns an error without
    ///   writing past it (kind [`Other`](crate::ErrorKind::Other)).
    /// * Never writes outside `left` and `right`; keeps no reference to them.
    fn capture(
        &mut self,
        left: &mut [u8],
        right: &mut [u8],
        timeout_ticks: u64,
    ) -> Result<FrameInfo, Self::Error>;
}

impl<T: StereoCamera + ?Sized> StereoCamera for &mut T {
    fn capture(
        &mut self,
        left: &mut [u8],
        right: &mut [u8],
        timeout_ticks: u64,
    ) -> Result<FrameInfo, Self::Error> {
        T::capture(self, left, right, timeout_ticks)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info(w: u32, h: u32, s: u32) -> FrameInfo {
        FrameInfo {
            width: w,
            height: h,
            stride: s,
            sequence: 0,
            timestamp_ticks: 0,
            exposure_us: 0,
        }
    }

    /// Verifies: VTSM-HAL-003
    #[test]
    fn frame_info_is_checked_against_buffers_and_expected_size() {
        let buf = [9u8; 64];
        assert_eq!(info(4, 3, 6).image_len(), Some(16));
        assert_eq!(info(4, 3, 3).image_len(), None);
        assert_eq!(info(0, 3, 3).image_len(), None);
        let (l, r) = info(4, 3, 6).views((4, 3), &buf, &buf[..16]).unwrap();
        assert_eq!((l.width(), l.height(), r.get(3, 2)), (4, 3, Some(9)));
        assert_eq!(
            info(4, 3, 6).views((4, 4), &buf, &buf).err(),
            Some(FailureCode::HalFrameInfoInvalid)
        );
        assert_eq!(
            info(4, 3, 6).views((4, 3), &buf, &buf[..15]).err(),
            Some(FailureCode::HalFrameInfoInvalid)
        );
        assert_eq!(
            info(4, 3, 2).views((4, 3), &buf, &buf).err(),
            Some(FailureCode::HalFrameInfoInvalid)
        );
    }
}
