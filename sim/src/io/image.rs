//! Image files: PNG, JPEG, TIFF and PGM/PPM, 8 or 16 bit, gray or colour, loaded
//! as 8-bit gray ([`Gray8`]).
//!
//! The format is recognised from the file's content, not its name. Colour is
//! converted to gray with the ITU-R BT.601 luma weights in integer arithmetic,
//! `Y = (299 R + 587 G + 114 B + 500) / 1000`; 16-bit samples are scaled to
//! 8 bit with rounding, `(v · 255 + 32767) / 65535`, after the luma step, so
//! nothing is truncated twice. Alpha is ignored. Sizes are bounded by
//! `vtsm_core::config::MAX_IMAGE_DIM`.

use crate::error::{Error, Result};
use image::{DynamicImage, ImageFormat, ImageReader};
use std::io::Cursor;
use std::path::Path;
use vtsm_core::config::MAX_IMAGE_DIM;
use vtsm_core::image::GrayView;

/// An owned 8-bit gray image, row-major, stride = width.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Gray8 {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width · height` pixels, row 0 first (top of the image).
    pub pixels: Vec<u8>,
}

impl Gray8 {
    /// An image filled with `value`.
    pub fn filled(width: u32, height: u32, value: u8) -> Self {
        Self {
            width,
            height,
            pixels: vec![value; width as usize * height as usize],
        }
    }

    /// Pixel at `(x, y)`, `None` outside.
    pub fn get(&self, x: u32, y: u32) -> Option<u8> {
        if x >= self.width || y >= self.height {
            return None;
        }
        self.pixels
            .get(y as usize * self.width as usize + x as usize)
            .copied()
    }

    /// A checked core view of the image.
    ///
    /// # Errors
    /// The core's image failure code when the size is 0 or above `MAX_IMAGE_DIM`
    /// or the buffer does not match the size.
    pub fn view(&self) -> std::result::Result<GrayView<'_>, vtsm_core::FailureCode> {
        let w = self.width as usize;
        let h = self.height as usize;
        if self.pixels.len() != w * h {
            return Err(vtsm_core::FailureCode::ImageBufferTooShort);
        }
        GrayView::new(&self.pixels, w, h, w)
    }
}

/// BT.601 luma of an 8-bit RGB triple, integer, rounded.
pub fn luma8(r: u8, g: u8, b: u8) -> u8 {
    let y = (299 * u32::from(r) + 587 * u32::from(g) + 114 * u32::from(b) + 500) / 1000;
    // y ≤ 255 because the weights sum to 1000.
    y.min(255) as u8
}

/// BT.601 luma of a 16-bit RGB triple, integer, rounded (16-bit result).
pub fn luma16(r: u16, g: u16, b: u16) -> u16 {
    let y = (299 * u64::from(r) + 587 * u64::from(g) + 114 * u64::from(b) + 500) / 1000;
    y.min(65535) as u16
}

/// A 16-bit sample scaled to 8 bit with rounding.
pub fn to8(v: u16) -> u8 {
    ((u32::from(v) * 255 + 32767) / 65535).min(255) as u8
}

/// Decode image `bytes` (PNG, JPEG, TIFF or PGM/PPM) to 8-bit gray; `path` only names errors.
///
/// # Errors
/// Unknown format, decoding error, or a size of 0 or above `MAX_IMAGE_DIM`.
pub fn decode_gray(bytes: &[u8], path: &Path) -> Result<Gray8> {
    let reader = ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| Error::file(path, format!("cannot read image: {e}")))?;
    match reader.format() {
        Some(ImageFormat::Png | ImageFormat::Jpeg | ImageFormat::Tiff | ImageFormat::Pnm) => {}
        Some(f) => {
            return Err(Error::file(
                path,
                format!("unsupported image format {f:?} (expected PNG, JPEG, TIFF or PGM)"),
            ))
        }
        None => {
            return Err(Error::file(
                path,
                "not a PNG, JPEG, TIFF or PGM image (unrecognised header)",
            ))
        }
    }
    let img = reader
        .decode()
        .map_err(|e| Error::file(path, format!("cannot decode image: {e}")))?;
    let (w, h) = (img.width(), img.height());
    if w == 0 || h == 0 || w as usize > MAX_IMAGE_DIM || h as usize > MAX_IMAGE_DIM {
        return Err(Error::file(
            path,
            format!("image size {w}x{h} outside 1..={MAX_IMAGE_DIM} pixels per side"),
        ));
    }
    Ok(Gray8 {
        width: w,
        height: h,
        pixels: to_gray(img),
    })
}

fn to_gray(img: DynamicImage) -> Vec<u8> {
    match img {
        DynamicImage::ImageLuma8(b) => b.into_raw(),
        DynamicImage::ImageLumaA8(b) => b.pixels().map(|p| p.0[0]).collect(),
        DynamicImage::ImageRgb8(b) => b.pixels().map(|p| luma8(p.0[0], p.0[1], p.0[2])).collect(),
        DynamicImage::ImageRgba8(b) => b.pixels().map(|p| luma8(p.0[0], p.0[1], p.0[2])).collect(),
        DynamicImage::ImageLuma16(b) => b.pixels().map(|p| to8(p.0[0])).collect(),
        DynamicImage::ImageLumaA16(b) => b.pixels().map(|p| to8(p.0[0])).collect(),
        DynamicImage::ImageRgb16(b) => b
            .pixels()
            .map(|p| to8(luma16(p.0[0], p.0[1], p.0[2])))
            .collect(),
        DynamicImage::ImageRgba16(b) => b
            .pixels()
            .map(|p| to8(luma16(p.0[0], p.0[1], p.0[2])))
            .collect(),
        // Floating-point images (some TIFFs): through 16-bit RGB, which clamps to [0, 1].
        other => other
            .to_rgb16()
            .pixels()
            .map(|p| to8(luma16(p.0[0], p.0[1], p.0[2])))
            .collect(),
    }
}

/// Read an image file as 8-bit gray.
///
/// # Errors
/// As [`decode_gray`], plus I/O errors.
pub fn read_gray(path: &Path) -> Result<Gray8> {
    let bytes = super::read_file(path)?;
    decode_gray(&bytes, path)
}

/// Read an image file as 8-bit gray and require its size to be `width × height`
/// (the size in `calib.json`).
///
/// # Errors
/// As [`read_gray`], plus a size mismatch.
pub fn read_gray_sized(path: &Path, width: u32, height: u32) -> Result<Gray8> {
    let img = read_gray(path)?;
    if img.width != width || img.height != height {
        return Err(Error::file(
            path,
            format!(
                "image is {}x{} but the calibration says {width}x{height}",
                img.width, img.height
            ),
        ));
    }
    Ok(img)
}

/// Encode an 8-bit gray image as PNG.
///
/// # Errors
/// When the pixel buffer does not match the size or the encoder fails.
pub fn encode_png(img: &Gray8) -> Result<Vec<u8>> {
    let buf = image::GrayImage::from_raw(img.width, img.height, img.pixels.clone())
        .ok_or_else(|| Error::msg("image buffer does not match its size"))?;
    let mut out = Cursor::new(Vec::new());
    buf.write_to(&mut out, ImageFormat::Png)
        .map_err(|e| Error::msg(format!("cannot encode PNG: {e}")))?;
    Ok(out.into_inner())
}

/// Write an 8-bit gray image as PNG, atomically (see [`super::write_atomic`]).
///
/// # Errors
/// Encoding or I/O errors, or an existing file without `force`.
pub fn write_png(path: &Path, img: &Gray8, force: bool) -> Result<()> {
    let bytes = encode_png(img)?;
    super::write_atomic(path, &bytes, force)
}
