//! The NCC speed cases shared by `core/examples/bench_ncc.rs` and `vtsm bench`
//! (`sim/src/cli/bench.rs`), which both include this file with `#[path]`, so
//! that both time the very same pixels the same way.
//!
//! An 800×800 multi-octave value-noise image ([`textured`]) and four searches
//! ([`CASES`]): 256-in-800 and 128-in-800 (the paper profile's ℓ and ℓ/2 in
//! its ~800² window), 64-in-200 and 32-in-96 (the searches of the demo and
//! test profiles, over the whole of a crop of the image). Each template is cut
//! from its image under gain 0.9, offset +12 and ±3 noise ([`cut`]).
//! [`Case::image_file`] and [`Case::template_file`] are the PGM names that
//! `sim/bench/opencv_ncc.py` reads.
//!
//! Uses `std`; never part of a flight build.
#![allow(dead_code)]

use std::time::Instant;
use std::vec::Vec;
use vtsm_core::image::{GrayView, Rect};
use vtsm_core::ncc::{self, Filter, Run, Scratch, ScratchSizes, Search};
use vtsm_core::rng::Rng;
use vtsm_core::FailureCode;

/// Side of the square test image, pixels.
pub const IMAGE_SIDE: usize = 800;
/// Seed of the test image's noise.
pub const IMAGE_SEED: u64 = 7;

/// One template search of the benchmark.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Case {
    /// Template side ℓ, pixels.
    pub l: usize,
    /// Side of the searched (square) image, pixels: the test image or a crop of it.
    pub side: usize,
    /// Top-left corner of the crop in the test image.
    pub crop: (usize, usize),
    /// Top-left corner of the template in the searched image: the true match.
    pub at: (usize, usize),
    /// Matches per timed sample, so that a sample lasts about a millisecond.
    pub inner: usize,
}

/// The four cases, largest first.
pub const CASES: [Case; 4] = [
    Case {
        l: 256,
        side: 800,
        crop: (0, 0),
        at: (331, 217),
        inner: 1,
    },
    Case {
        l: 128,
        side: 800,
        crop: (0, 0),
        at: (509, 402),
        inner: 1,
    },
    Case {
        l: 64,
        side: 200,
        crop: (150, 260),
        at: (71, 53),
        inner: 10,
    },
    Case {
        l: 32,
        side: 96,
        crop: (420, 130),
        at: (37, 29),
        inner: 50,
    },
];

impl Case {
    /// `ℓ-in-side`, e.g. `64-in-200`.
    pub fn name(&self) -> std::string::String {
        std::format!("{}-in-{}", self.l, self.side)
    }

    /// File name of the searched image: `image.pgm` for the whole test
    /// image, `image<side>.pgm` for a crop.
    pub fn image_file(&self) -> std::string::String {
        if self.side == IMAGE_SIDE {
            "image.pgm".into()
        } else {
            std::format!("image{}.pgm", self.side)
        }
    }

    /// File name of the template: `t<ℓ>.pgm`.
    pub fn template_file(&self) -> std::string::String {
        std::format!("t{}.pgm", self.l)
    }

    /// The searched image (`side × side`, row-major) from the test image
    /// `full` ([`IMAGE_SIDE`]²).
    pub fn image(&self, full: &[u8]) -> Vec<u8> {
        if self.side == IMAGE_SIDE {
            return full.to_vec();
        }
        let (cx, cy) = self.crop;
        (0..self.side)
            .flat_map(|r| {
                let row = (cy + r) * IMAGE_SIDE + cx;
                full[row..row + self.side].iter().copied()
            })
            .collect()
    }

    /// The template (`ℓ × ℓ`), cut at [`Case::at`] from the searched `image`.
    pub fn template(&self, image: &[u8]) -> Vec<u8> {
        cut(
            image,
            self.side,
            self.at.0,
            self.at.1,
            self.l,
            self.l as u64,
        )
    }
}

/// Multi-octave value noise, `w × h`, stretched to 0..=255.
pub fn textured(w: usize, h: usize, seed: u64) -> Vec<u8> {
    let mut acc = std::vec![0f32; w * h];
    let mut rng = Rng::new(seed);
    let mut amp = 1.0f32;
    for cell in [64usize, 32, 16, 8, 4, 2] {
        let gw = w / cell + 2;
        let gh = h / cell + 2;
        let grid: Vec<f32> = (0..gw * gh).map(|_| rng.uniform(-1.0, 1.0)).collect();
        for y in 0..h {
            let fy = y as f32 / cell as f32;
            let (y0, ty) = (fy as usize, fy - fy.floor());
            for x in 0..w {
                let fx = x as f32 / cell as f32;
                let (x0, tx) = (fx as usize, fx - fx.floor());
                let g = |i: usize, j: usize| grid[j * gw + i];
                let top = g(x0, y0) * (1.0 - tx) + g(x0 + 1, y0) * tx;
                let bot = g(x0, y0 + 1) * (1.0 - tx) + g(x0 + 1, y0 + 1) * tx;
                acc[y * w + x] += amp * (top * (1.0 - ty) + bot * ty);
            }
        }
        amp *= 0.7;
    }
    let (lo, hi) = acc
        .iter()
        .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    acc.iter()
        .map(|&v| ((v - lo) / (hi - lo) * 255.0).round() as u8)
        .collect()
}

/// Crop `l × l` at `(x, y)` from `img` (width `w`) with gain, offset and ±3 noise.
pub fn cut(img: &[u8], w: usize, x: usize, y: usize, l: usize, seed: u64) -> Vec<u8> {
    let mut rng = Rng::new(seed);
    let mut t = Vec::with_capacity(l * l);
    for r in 0..l {
        for c in 0..l {
            let v = f32::from(img[(y + r) * w + x + c]) * 0.9 + 12.0 + rng.uniform(-3.0, 3.0);
            t.push(v.round().clamp(0.0, 255.0) as u8);
        }
    }
    t
}

/// A binary PGM (`P5`) file holding `px` (`w × h`, row-major).
pub fn pgm(px: &[u8], w: usize, h: usize) -> Vec<u8> {
    let mut bytes = std::format!("P5\n{w} {h}\n255\n").into_bytes();
    bytes.extend_from_slice(px);
    bytes
}

/// CPU time of this thread in nanoseconds (Linux `schedstat`), so that numbers
/// stay meaningful on a shared, loaded machine; `None` elsewhere.
pub fn thread_cpu_ns() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    s.split_whitespace().next()?.parse().ok()
}

/// Median of `v` (the upper one of an even count); NaN when empty.
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// What [`time_search`] measured.
#[derive(Clone, Copy, Debug)]
pub struct Timing {
    /// Median wall-clock time of one match over the samples, milliseconds.
    pub ms_per_match: f64,
    /// Thread CPU time over all matches divided by their number, milliseconds
    /// (NaN where the CPU time cannot be read).
    pub cpu_ms_per_match: f64,
    /// The best match of the last search.
    pub found: ncc::Match,
    /// Its work counters (multiply-accumulates, positions scored, levels).
    pub stats: ncc::MatchStats,
    /// Bytes of the search's scratch buffers.
    pub scratch_bytes: usize,
}

/// Time `ncc::match_template` of `template` (`l × l`) over the whole of
/// `image` (`side × side`), gray filter, in `mode`: `samples` timed samples
/// of `inner` searches each, in this thread.
///
/// # Errors
/// The core's failure code if it refuses the search.
pub fn time_search(
    image: &[u8],
    side: usize,
    template: &[u8],
    l: usize,
    mode: Search,
    samples: usize,
    inner: usize,
) -> Result<Timing, FailureCode> {
    let image_v = GrayView::new(image, side, side, side)?;
    let template_v = GrayView::new(template, l, l, l)?;
    let search = Rect::new(0, 0, side as u32, side as u32);
    let sz = ScratchSizes::new(l, l, side, side, mode);
    let (mut wb, mut tb, mut ib, mut rb) = (
        std::vec![0u8; sz.window],
        std::vec![0u8; sz.template],
        std::vec![0u32; sz.integral],
        std::vec![Run::default(); sz.runs],
    );
    let mut scratch = Scratch {
        window: &mut wb,
        template: &mut tb,
        integral: &mut ib,
        runs: &mut rb,
    };
    let (samples, inner) = (samples.max(1), inner.max(1));
    let mut times = Vec::with_capacity(samples);
    let mut last = None;
    let cpu0 = thread_cpu_ns();
    for _ in 0..samples {
        let t0 = Instant::now();
        for _ in 0..inner {
            last = Some(ncc::match_template(
                template_v,
                None,
                image_v,
                search,
                Filter::Gray,
                mode,
                &mut scratch,
            )?);
        }
        times.push(t0.elapsed().as_secs_f64() * 1e3 / inner as f64);
    }
    let cpu_ms_per_match = match (cpu0, thread_cpu_ns()) {
        (Some(a), Some(b)) => b.saturating_sub(a) as f64 * 1e-6 / (samples * inner) as f64,
        _ => f64::NAN,
    };
    let (found, stats) = last.ok_or(FailureCode::NccWindowFlat)?;
    Ok(Timing {
        ms_per_match: median(times),
        cpu_ms_per_match,
        found,
        stats,
        scratch_bytes: sz.window + sz.template + 4 * sz.integral + 6 * sz.runs,
    })
}
