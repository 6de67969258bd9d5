//! Picture panels for reports (like the paper's Fig. 6b): an RGB canvas onto
//! which gray images are blitted (scaled by nearest neighbour), boxes drawn and
//! short labels written with a built-in 5×7 bitmap font, saved as PNG.

use crate::error::{Error, Result};
use crate::locate;
use std::path::Path;
use vtsm_core::geom::{Camera, Pose};
use vtsm_core::map::MapView;
use vtsm_core::rng::Rng;

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

/// The template of the map around `p_world` as seen from `pose`, if in view.
fn template(
    map: &MapView,
    cam: &Camera,
    pose: &Pose,
    p_world: &vtsm_core::geom::Vec3,
    l: usize,
) -> Option<(Vec<u8>, Vec<u8>)> {
    let uv = cam.project(&pose.inverse().transform_point(p_world))?;
    let t = locate::render_template(map, cam, pose, uv, l)?;
    Some((t.intensity, t.mask))
}

/// The Fig. 6b-like panel of a relocalization (`vtsm demo`'s `panel.png`,
/// `vtsm eval --suite dataset --panels`): the real left image with the
/// template locations, then per sampled mask point: the template at the
/// prior, the real image around the point's true location, and the
/// template at the final pose. Every pose is the core's left camera in the
/// map's local frame; `truth` places the points (the final pose when no
/// truth is known), `seed` picks them.
#[allow(clippy::too_many_arguments)]
pub fn result_panel(
    map: &MapView,
    cam: &Camera,
    left: &[u8],
    prior: &Pose,
    fin: &Pose,
    truth: &Pose,
    template_px: u16,
    seed: u64,
) -> Canvas {
    const K: usize = 6;
    let l = usize::from(template_px);
    let cell = 150usize;
    let pad = 12usize;
    let (w, h) = (cam.width() as usize, cam.height() as usize);
    let img_w = K * (cell + pad) - pad;
    let img_h = img_w * h / w;
    let label_h = 26;
    let width = img_w + 2 * pad;
    let height = pad + label_h + img_h + 3 * (label_h + cell) + 2 * pad;
    let mut c = Canvas::new(width, height, [24, 24, 28]);
    let white = [235, 235, 235];
    c.text(
        pad as i64,
        pad as i64,
        "REAL LEFT IMAGE WITH SAMPLED POINTS",
        2,
        white,
    );
    let y_img = (pad + label_h) as i64;
    c.blit_gray(left, w, h, None, pad as i64, y_img, img_w, img_h);

    // Mask vertices in view (with a template's margin) at the true pose.
    let mut rng = Rng::new(seed).fork(0x50414E454C);
    let mut points = Vec::new();
    let n = map.mask_vertex_count();
    for _ in 0..(64 * K) {
        if points.len() == K || n == 0 {
            break;
        }
        let Some(p) = map.mask_vertex(rng.below(n)).and_then(|i| map.vertex(i)) else {
            continue;
        };
        let Some([u, v]) = cam.project(&truth.inverse().transform_point(&p)) else {
            continue;
        };
        if cam.contains(u, v, l as f32)
            && points
                .iter()
                .all(|(_, q): &(vtsm_core::geom::Vec3, [f32; 2])| {
                    (q[0] - u).hypot(q[1] - v) > l as f32
                })
        {
            points.push((p, [u, v]));
        }
    }
    let colors = [
        [230, 80, 60],
        [80, 200, 90],
        [70, 140, 240],
        [240, 200, 50],
        [200, 90, 220],
        [60, 210, 210],
    ];
    let rows = [
        ("SYNTHETIC AT PRIOR (RANDOM START)", 0),
        ("REAL IMAGE", 1),
        ("SYNTHETIC AT FINAL POSE", 2),
    ];
    for (title, r) in rows {
        let y = y_img + (img_h + pad + r * (label_h + cell)) as i64;
        c.text(pad as i64, y + 4, title, 2, white);
    }
    for (k, (p, [u, v])) in points.iter().enumerate() {
        let color = colors[k % colors.len()];
        let (sx, sy) = (img_w as f32 / w as f32, img_h as f32 / h as f32);
        let bx = pad as i64 + ((u - l as f32 / 2.0) * sx) as i64;
        let by = y_img + ((v - l as f32 / 2.0) * sy) as i64;
        c.rect(
            bx,
            by,
            (l as f32 * sx) as i64,
            (l as f32 * sy) as i64,
            2,
            color,
        );
        let x = (pad + k * (cell + pad)) as i64;
        let row_y = |r: usize| y_img + (img_h + pad + r * (label_h + cell) + label_h) as i64;
        if let Some((t, m)) = template(map, cam, prior, p, l) {
            c.blit_gray(&t, l, l, Some(&m), x, row_y(0), cell, cell);
        }
        let crop: Vec<u8> = (0..l * l)
            .map(|i| {
                let xx =
                    (*u as i64 - l as i64 / 2 + (i % l) as i64).clamp(0, w as i64 - 1) as usize;
                let yy =
                    (*v as i64 - l as i64 / 2 + (i / l) as i64).clamp(0, h as i64 - 1) as usize;
                left[yy * w + xx]
            })
            .collect();
        c.blit_gray(&crop, l, l, None, x, row_y(1), cell, cell);
        if let Some((t, m)) = template(map, cam, fin, p, l) {
            c.blit_gray(&t, l, l, Some(&m), x, row_y(2), cell, cell);
        }
        for r in 0..3 {
            c.rect(
                x - 2,
                row_y(r) - 2,
                cell as i64 + 4,
                cell as i64 + 4,
                2,
                color,
            );
        }
    }
    c
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
