//! NCC speed: ms per match and multiply-accumulates per match for 256-in-800
//! and 128-in-800 (exhaustive and coarse-to-fine) and for the small searches the
//! engine runs at the demo and test profiles, 64-in-200 and 32-in-96
//! (coarse-to-fine, default `SearchConfig`), on a deterministic textured image
//! (multi-octave value noise) with a template cut from it under gain, offset and
//! noise. The small cases search the whole of a crop of the 800² image.
//!
//! ```text
//! cargo run --release -p vtsm-core --example bench_ncc -- [--repeat N] [--out DIR] [--no-exhaustive] [--only L]
//! ```
//! `--out DIR` also writes `image.pgm`, `t256.pgm`, `t128.pgm`, `image200.pgm`,
//! `t64.pgm`, `image96.pgm` and `t32.pgm` so that `sim/bench/opencv_ncc.py DIR`
//! can time OpenCV on the very same pixels. Each timed sample of a small case
//! runs several matches (`inner`) so that a sample lasts about a millisecond.
//! `--only L` runs only the case with template side L (for instruction counts).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::time::Instant;
use vtsm_core::image::{GrayView, Rect};
use vtsm_core::ncc::{self, Filter, Run, Scratch, ScratchSizes, Search};
use vtsm_core::rng::Rng;

/// Multi-octave value noise, `w × h`, stretched to 0..=255.
fn textured(w: usize, h: usize, seed: u64) -> Vec<u8> {
    let mut acc = vec![0f32; w * h];
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
fn cut(img: &[u8], w: usize, x: usize, y: usize, l: usize, seed: u64) -> Vec<u8> {
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

fn write_pgm(path: &std::path::Path, px: &[u8], w: usize, h: usize) {
    let mut bytes = format!("P5\n{w} {h}\n255\n").into_bytes();
    bytes.extend_from_slice(px);
    std::fs::write(path, bytes).unwrap();
}

/// CPU time of this thread in nanoseconds (Linux `schedstat`), so that numbers
/// stay meaningful on a shared, loaded machine; `None` elsewhere.
fn thread_cpu_ns() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    s.split_whitespace().next()?.parse().ok()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Template side, image side, crop origin in the 800² image, template offset in the crop.
type Case = (usize, usize, (usize, usize), (usize, usize));

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let mut repeat = 21usize;
    let mut out: Option<std::path::PathBuf> = None;
    let mut exhaustive = true;
    let mut only: Option<usize> = None;
    let mut i = 1;
    while i < args.len() {
        match args[i].as_str() {
            "--repeat" => {
                repeat = args[i + 1].parse().unwrap();
                i += 1;
            }
            "--out" => {
                out = Some(args[i + 1].clone().into());
                i += 1;
            }
            "--no-exhaustive" => exhaustive = false,
            "--only" => {
                only = Some(args[i + 1].parse().unwrap());
                i += 1;
            }
            a => panic!("unknown argument {a}"),
        }
        i += 1;
    }
    let (w, h) = (800usize, 800usize);
    let img = textured(w, h, 7);
    if let Some(dir) = &out {
        std::fs::create_dir_all(dir).unwrap();
        write_pgm(&dir.join("image.pgm"), &img, w, h);
    }
    println!("# {w}x{h} image, single thread, gray filter; ms = wall-clock median over runs, cpu_ms = thread CPU time / runs");
    let cases: [Case; 4] = [
        (256, 800, (0, 0), (331, 217)),
        (128, 800, (0, 0), (509, 402)),
        (64, 200, (150, 260), (71, 53)),
        (32, 96, (420, 130), (37, 29)),
    ];
    for (l, side, (cx, cy), (tx, ty)) in cases {
        if only.is_some_and(|o| o != l) {
            continue;
        }
        let crop: Vec<u8> = if side == w {
            img.clone()
        } else {
            (0..side)
                .flat_map(|r| {
                    img[(cy + r) * w + cx..(cy + r) * w + cx + side]
                        .iter()
                        .copied()
                })
                .collect()
        };
        if let Some(dir) = &out {
            if side != w {
                write_pgm(&dir.join(format!("image{side}.pgm")), &crop, side, side);
            }
        }
        let image = GrayView::new(&crop, side, side, side).unwrap();
        let (w, h) = (side, side);
        let tpl = cut(&crop, w, tx, ty, l, l as u64);
        if let Some(dir) = &out {
            write_pgm(&dir.join(format!("t{l}.pgm")), &tpl, l, l);
        }
        let template = GrayView::new(&tpl, l, l, l).unwrap();
        let search = Rect::new(0, 0, w as u32, h as u32);
        let modes: &[Search] = if exhaustive && side == 800 {
            &[Search::Exhaustive, Search::CoarseToFine]
        } else {
            &[Search::CoarseToFine]
        };
        // Matches per timed sample: about a millisecond each.
        let inner = match side {
            96 => 50,
            200 => 10,
            _ => 1,
        };
        for &mode in modes {
            let sz = ScratchSizes::new(l, l, w, h, mode);
            let mut wb = vec![0u8; sz.window];
            let mut tb = vec![0u8; sz.template];
            let mut ib = vec![0u32; sz.integral];
            let mut rb = vec![Run::default(); sz.runs];
            let mut scratch = Scratch {
                window: &mut wb,
                template: &mut tb,
                integral: &mut ib,
                runs: &mut rb,
            };
            let n = if mode == Search::Exhaustive {
                1
            } else {
                repeat
            };
            let mut times = Vec::with_capacity(n);
            let mut last = None;
            let cpu0 = thread_cpu_ns();
            for _ in 0..n {
                let t0 = Instant::now();
                for _ in 0..inner {
                    let r = ncc::match_template(
                        template,
                        None,
                        image,
                        search,
                        Filter::Gray,
                        mode,
                        &mut scratch,
                    )
                    .unwrap();
                    last = Some(r);
                }
                times.push(t0.elapsed().as_secs_f64() * 1e3 / inner as f64);
            }
            let cpu_ms = match (cpu0, thread_cpu_ns()) {
                (Some(a), Some(b)) => (b - a) as f64 * 1e-6 / (n * inner) as f64,
                _ => f64::NAN,
            };
            let (m, st) = last.unwrap();
            let scratch_bytes = sz.window + sz.template + 4 * sz.integral + 6 * sz.runs;
            println!(
                "{l}-in-{w} {:<13} ms_per_match {:>9.3}  cpu_ms_per_match {:>9.3}  macs_per_match {:>12}  positions {:>7}  levels {}  at ({},{}) truth ({tx},{ty}) score {:.6} runner_up {:.4}  scratch_bytes {}",
                format!("{mode:?}"),
                median(times),
                cpu_ms,
                st.macs,
                st.positions_scored,
                st.levels,
                m.x,
                m.y,
                m.score,
                m.runner_up,
                scratch_bytes
            );
        }
    }
}
