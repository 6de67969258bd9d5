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
//! The image, the cases and the timing loop are in `core/testkit/ncc_cases.rs`,
//! shared with `vtsm bench` (`fsw-docs/budgets/speed.md`).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

#[path = "../testkit/ncc_cases.rs"]
mod ncc_cases;
use ncc_cases::{textured, time_search, IMAGE_SEED, IMAGE_SIDE};
use vtsm_core::ncc::Search;

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
    let img = textured(IMAGE_SIDE, IMAGE_SIDE, IMAGE_SEED);
    let write = |name: &str, px: &[u8], side: usize| {
        if let Some(dir) = &out {
            std::fs::write(dir.join(name), ncc_cases::pgm(px, side, side)).unwrap();
        }
    };
    if let Some(dir) = &out {
        std::fs::create_dir_all(dir).unwrap();
    }
    write("image.pgm", &img, IMAGE_SIDE);
    println!("# {IMAGE_SIDE}x{IMAGE_SIDE} image, single thread, gray filter; ms = wall-clock median over runs, cpu_ms = thread CPU time / runs");
    for case in ncc_cases::CASES {
        let (l, w) = (case.l, case.side);
        let (tx, ty) = case.at;
        if only.is_some_and(|o| o != l) {
            continue;
        }
        let crop = case.image(&img);
        if w != IMAGE_SIDE {
            write(&case.image_file(), &crop, w);
        }
        let tpl = case.template(&crop);
        write(&case.template_file(), &tpl, l);
        let modes: &[Search] = if exhaustive && w == IMAGE_SIDE {
            &[Search::Exhaustive, Search::CoarseToFine]
        } else {
            &[Search::CoarseToFine]
        };
        for &mode in modes {
            let n = if mode == Search::Exhaustive {
                1
            } else {
                repeat
            };
            let t = time_search(&crop, w, &tpl, l, mode, n, case.inner).unwrap();
            let (m, st) = (t.found, t.stats);
            println!(
                "{l}-in-{w} {:<13} ms_per_match {:>9.3}  cpu_ms_per_match {:>9.3}  macs_per_match {:>12}  positions {:>7}  levels {}  at ({},{}) truth ({tx},{ty}) score {:.6} runner_up {:.4}  scratch_bytes {}",
                format!("{mode:?}"),
                t.ms_per_match,
                t.cpu_ms_per_match,
                st.macs,
                st.positions_scored,
                st.levels,
                m.x,
                m.y,
                m.score,
                m.runner_up,
                t.scratch_bytes
            );
        }
    }
}
