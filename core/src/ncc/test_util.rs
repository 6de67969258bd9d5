//! Helpers and floating-point references shared by the NCC tests.

extern crate std;

use super::*;
use crate::rng::Rng;
use std::vec;
use std::vec::Vec;

/// Owned scratch for tests.
pub(super) struct Bufs {
    pub(super) w: Vec<u8>,
    pub(super) t: Vec<u8>,
    pub(super) i: Vec<u32>,
    pub(super) r: Vec<Run>,
}

impl Bufs {
    pub(super) fn new(tw: usize, th: usize, ww: usize, wh: usize, mode: Search) -> Self {
        Self::with_config(
            tw,
            th,
            ww,
            wh,
            mode,
            &SearchConfig::for_filter(Filter::Gray),
        )
    }
    pub(super) fn with_config(
        tw: usize,
        th: usize,
        ww: usize,
        wh: usize,
        mode: Search,
        cfg: &SearchConfig,
    ) -> Self {
        let s = ScratchSizes::with_config(tw, th, ww, wh, mode, cfg);
        Self {
            w: vec![0; s.window],
            t: vec![0; s.template],
            i: vec![0; s.integral],
            r: vec![Run::default(); s.runs],
        }
    }
    pub(super) fn scratch(&mut self) -> Scratch<'_> {
        Scratch {
            window: &mut self.w,
            template: &mut self.t,
            integral: &mut self.i,
            runs: &mut self.r,
        }
    }
}

pub(super) fn view(px: &[u8], w: usize, h: usize) -> GrayView<'_> {
    GrayView::new(px, w, h, w).unwrap()
}

pub(super) fn random_px(n: usize, rng: &mut Rng) -> Vec<u8> {
    (0..n).map(|_| rng.below(256) as u8).collect()
}

/// Smooth random texture (bilinear value noise, two octaves), `w × h`.
pub(super) fn textured(w: usize, h: usize, rng: &mut Rng) -> Vec<u8> {
    let mut acc = vec![0f64; w * h];
    for (cell, amp) in [(12usize, 1.0f64), (4, 0.5), (2, 0.25)] {
        let gw = w / cell + 2;
        let grid: Vec<f64> = (0..gw * (h / cell + 2))
            .map(|_| f64::from(rng.uniform(-1.0, 1.0)))
            .collect();
        for y in 0..h {
            for x in 0..w {
                let (fx, fy) = (x as f64 / cell as f64, y as f64 / cell as f64);
                let (x0, y0) = (fx as usize, fy as usize);
                let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
                let g = |i: usize, j: usize| grid[j * gw + i];
                let top = g(x0, y0) * (1.0 - tx) + g(x0 + 1, y0) * tx;
                let bot = g(x0, y0 + 1) * (1.0 - tx) + g(x0 + 1, y0 + 1) * tx;
                acc[y * w + x] += amp * (top * (1.0 - ty) + bot * ty);
            }
        }
    }
    acc.iter()
        .map(|v| (128.0 + 70.0 * v).round().clamp(0.0, 255.0) as u8)
        .collect()
}

pub(super) fn crop(img: &[u8], iw: usize, x: usize, y: usize, w: usize, h: usize) -> Vec<u8> {
    (0..h)
        .flat_map(|r| img[(y + r) * iw + x..(y + r) * iw + x + w].iter().copied())
        .collect()
}

/// Two-pass floating-point zero-mean NCC over the kept pixels (the reference).
#[allow(clippy::too_many_arguments)]
pub(super) fn ref_score(
    t: &[u8],
    tw: usize,
    th: usize,
    mask: Option<&[u8]>,
    img: &[u8],
    iw: usize,
    x: usize,
    y: usize,
) -> Option<f64> {
    let keep = |i: usize| mask.is_none_or(|m| m[i] != 0);
    let (mut n, mut mt, mut mf) = (0.0, 0.0, 0.0);
    for r in 0..th {
        for c in 0..tw {
            if keep(r * tw + c) {
                n += 1.0;
                mt += f64::from(t[r * tw + c]);
                mf += f64::from(img[(y + r) * iw + x + c]);
            }
        }
    }
    mt /= n;
    mf /= n;
    let (mut sft, mut stt, mut sff) = (0.0, 0.0, 0.0);
    for r in 0..th {
        for c in 0..tw {
            if keep(r * tw + c) {
                let a = f64::from(t[r * tw + c]) - mt;
                let b = f64::from(img[(y + r) * iw + x + c]) - mf;
                sft += a * b;
                stt += a * a;
                sff += b * b;
            }
        }
    }
    if stt <= 1e-9 || sff <= 1e-9 {
        return None;
    }
    Some(sft / (stt * sff).sqrt())
}

/// Reference filters, written independently of `filter_region`.
pub(super) fn ref_filter(img: &[u8], w: usize, h: usize, f: Filter) -> Vec<u8> {
    let at = |x: i64, y: i64| -> i64 {
        let x = x.clamp(0, w as i64 - 1) as usize;
        let y = y.clamp(0, h as i64 - 1) as usize;
        i64::from(img[y * w + x])
    };
    let sx = [[-1, 0, 1], [-2, 0, 2], [-1, 0, 1]];
    let sy = [[-1, -2, -1], [0, 0, 0], [1, 2, 1]];
    let lp = [[0, 1, 0], [1, -4, 1], [0, 1, 0]];
    let conv = |k: &[[i64; 3]; 3], x: i64, y: i64| -> i64 {
        let mut s = 0;
        for (j, row) in k.iter().enumerate() {
            for (i, c) in row.iter().enumerate() {
                s += c * at(x + i as i64 - 1, y + j as i64 - 1);
            }
        }
        s
    };
    let mut out = vec![0u8; w * h];
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            let v = match f {
                Filter::Gray => at(x, y),
                Filter::Sobel => (conv(&sx, x, y).abs() + conv(&sy, x, y).abs()) / 8,
                Filter::Laplacian => conv(&lp, x, y).div_euclid(8) + 128,
            };
            assert!((0..=255).contains(&v), "filter output {v} out of 8 bits");
            out[y as usize * w + x as usize] = v as u8;
        }
    }
    out
}

#[allow(clippy::too_many_arguments)]
pub(super) fn score_one(
    t: &[u8],
    tw: usize,
    th: usize,
    mask: Option<&[u8]>,
    img: &[u8],
    iw: usize,
    ih: usize,
    x: usize,
    y: usize,
    f: Filter,
) -> Result<Score, FailureCode> {
    let mut b = Bufs::new(tw, th, tw, th, Search::Exhaustive);
    score_at(
        view(t, tw, th),
        mask.map(|m| view(m, tw, th)),
        view(img, iw, ih),
        x as i32,
        y as i32,
        f,
        &mut b.scratch(),
    )
}

/// Plain scalar Σ t·f at (px, py), u64 so it cannot wrap (the reference).
pub(super) fn ref_dot(
    t: &[u8],
    tw: usize,
    th: usize,
    win: &[u8],
    ww: usize,
    px: usize,
    py: usize,
) -> u64 {
    let mut s = 0u64;
    for r in 0..th {
        for c in 0..tw {
            s += u64::from(t[r * tw + c]) * u64::from(win[(py + r) * ww + px + c]);
        }
    }
    s
}
