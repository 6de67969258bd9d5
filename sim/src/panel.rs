//! Picture panels for reports (like the paper's Fig. 6b): an RGB canvas onto
//! which gray images are blitted (scaled by nearest neighbour), boxes drawn and
//! short labels written with a built-in 5×7 bitmap font, saved as PNG.

use crate::error::{Error, Result};
use std::path::Path;

/// An RGB canvas.
#[derive(Debug, Clone, PartialEq)]
pub struct Canvas {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// RGB bytes, row-major.
    pub rgb: Vec<u8>,
}

/// A colour.
pub type Rgb = [u8; 3];

impl Canvas {
    /// A canvas filled with `bg`.
    pub fn new(width: usize, height: usize, bg: Rgb) -> Self {
        let mut rgb = vec![0u8; width * height * 3];
        for px in rgb.chunks_exact_mut(3) {
            px.copy_from_slice(&bg);
        }
        Self { width, height, rgb }
    }

    /// Set one pixel (ignored outside the canvas).
    pub fn put(&mut self, x: i64, y: i64, c: Rgb) {
        if x < 0 || y < 0 || x as usize >= self.width || y as usize >= self.height {
            return;
        }
        let i = (y as usize * self.width + x as usize) * 3;
        if let Some(p) = self.rgb.get_mut(i..i + 3) {
            p.copy_from_slice(&c);
        }
    }

    /// Blit a gray image (`w × h`, row-major) scaled to `dw × dh` at `(x, y)`.
    /// Pixels where `mask` is given and zero are tinted, so dropped template
    /// pixels are visible.
    #[allow(clippy::too_many_arguments)]
    pub fn blit_gray(
        &mut self,
        gray: &[u8],
        w: usize,
        h: usize,
        mask: Option<&[u8]>,
        x: i64,
        y: i64,
        dw: usize,
        dh: usize,
    ) {
        if w == 0 || h == 0 || gray.len() < w * h {
            return;
        }
        for dy in 0..dh {
            let sy = dy * h / dh.max(1);
            for dx in 0..dw {
                let sx = dx * w / dw.max(1);
                let i = sy * w + sx;
                let g = gray.get(i).copied().unwrap_or(0);
                let keep = mask.and_then(|m| m.get(i)).is_none_or(|&m| m != 0);
                let c = if keep {
                    [g, g, g]
                } else {
                    [g / 3 + 60, g / 3, g / 3 + 90]
                };
                self.put(x + dx as i64, y + dy as i64, c);
            }
        }
    }

    /// Draw a rectangle outline of thickness `t`.
    pub fn rect(&mut self, x: i64, y: i64, w: i64, h: i64, t: i64, c: Rgb) {
        for k in 0..t {
            for xx in x..x + w {
                self.put(xx, y + k, c);
                self.put(xx, y + h - 1 - k, c);
            }
            for yy in y..y + h {
                self.put(x + k, yy, c);
                self.put(x + w - 1 - k, yy, c);
            }
        }
    }

    /// Write `text` at `(x, y)` with the 5×7 font scaled by `scale`.
    /// Characters outside the font are drawn as blanks.
    pub fn text(&mut self, x: i64, y: i64, text: &str, scale: i64, c: Rgb) {
        let mut cx = x;
        for ch in text.chars() {
            if let Some(g) = glyph(ch.to_ascii_uppercase()) {
                for (row, bits) in g.iter().enumerate() {
                    for col in 0..5 {
                        if bits & (0x10 >> col) != 0 {
                            for sy in 0..scale {
                                for sx in 0..scale {
                                    self.put(cx + col * scale + sx, y + row as i64 * scale + sy, c);
                                }
                            }
                        }
                    }
                }
            }
            cx += 6 * scale;
        }
    }

    /// Save as PNG (refusing to overwrite unless `force`).
    ///
    /// # Errors
    /// Existing file without `force`, or an encoding/I/O failure, naming the file.
    pub fn save_png(&self, path: &Path, force: bool) -> Result<()> {
        let mut bytes = Vec::new();
        let img =
            image::RgbImage::from_raw(self.width as u32, self.height as u32, self.rgb.clone())
                .ok_or_else(|| Error::file(path, "canvas size does not match its buffer"))?;
        img.write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .map_err(|e| Error::file(path, format!("cannot encode PNG: {e}")))?;
        crate::eval::write_bytes_new(path, &bytes, force)
    }
}

/// 5×7 glyphs: each row's low 5 bits, MSB = leftmost column.
fn glyph(c: char) -> Option<[u8; 7]> {
    Some(match c {
        '0' => [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E],
        '1' => [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E],
        '2' => [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F],
        '3' => [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E],
        '4' => [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02],
        '5' => [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E],
        '6' => [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E],
        '7' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E],
        '9' => [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C],
        'A' => [0x0E, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        'B' => [0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E],
        'C' => [0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E],
        'D' => [0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C],
        'E' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F],
        'F' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10],
        'G' => [0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F],
        'H' => [0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        'I' => [0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E],
        'J' => [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C],
        'K' => [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11],
        'L' => [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F],
        'M' => [0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11],
        'N' => [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11],
        'O' => [0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'P' => [0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10],
        'Q' => [0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D],
        'R' => [0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11],
        'S' => [0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E],
        'T' => [0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04],
        'U' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'V' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04],
        'W' => [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A],
        'X' => [0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11],
        'Y' => [0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04],
        'Z' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F],
        '.' => [0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C],
        ',' => [0x00, 0x00, 0x00, 0x00, 0x0C, 0x04, 0x08],
        ':' => [0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x0C, 0x00],
        '-' => [0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00],
        '+' => [0x00, 0x04, 0x04, 0x1F, 0x04, 0x04, 0x00],
        '/' => [0x00, 0x01, 0x02, 0x04, 0x08, 0x10, 0x00],
        '(' => [0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02],
        ')' => [0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08],
        '=' => [0x00, 0x00, 0x1F, 0x00, 0x1F, 0x00, 0x00],
        '%' => [0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03],
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blit_scales_and_tints_masked_pixels() {
        let mut c = Canvas::new(8, 4, [0, 0, 0]);
        let gray = [10u8, 200, 30, 40];
        let mask = [255u8, 0, 255, 255];
        c.blit_gray(&gray, 2, 2, Some(&mask), 0, 0, 4, 4);
        assert_eq!(&c.rgb[0..3], &[10, 10, 10]);
        // (2, 0) comes from source (1, 0), masked out: tinted, not gray.
        let p = &c.rgb[6..9];
        assert_ne!(p[0], p[1]);
        // Off-canvas writes are ignored.
        c.put(-1, 0, [1, 2, 3]);
        c.put(100, 100, [1, 2, 3]);
        c.text(0, 0, "OK 12%", 1, [255, 0, 0]);
        assert!(c.rgb.chunks_exact(3).any(|p| p == [255, 0, 0]));
    }
}
