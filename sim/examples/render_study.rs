//! Render-time study of the photometric renderer (fsw-docs/budgets/sim.md).
//!
//! Generates a depot, computes the shadow map for one sun position and renders one
//! stereo pair of the capture grid, printing wall-clock and CPU time (user + system of
//! the whole process over the step, all threads, from `/proc/self/stat`) for each step.
//! With `--out DIR` the left and right images are written as PNG for inspection.
//!
//! ```text
//! cargo run --release -p vtsm-sim --example render_study -- [--profile paper]
//!     [--terrain cfa6] [--hours 15.5] [--seed 1] [--repeat 1] [--out DIR]
//! ```

#![allow(clippy::expect_used)] // a study harness: a failed setup step should stop it loudly

use std::path::PathBuf;
use std::time::Instant;
use vtsm_sim::scene::{parse_hours, Capture, Profile, Scene};
use vtsm_sim::terrain::TerrainKind;

/// CPU time (user + system) of this process so far, seconds (Linux; 0 elsewhere).
fn cpu_s() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    let Some((_, rest)) = stat.rsplit_once(')') else {
        return 0.0;
    };
    let f: Vec<&str> = rest.split_whitespace().collect();
    let tick = |k: usize| f.get(k).and_then(|s| s.parse::<f64>().ok()).unwrap_or(0.0);
    (tick(11) + tick(12)) / 100.0
}

/// Run `f`, print its wall and CPU time under `label`, return its result.
fn timed<T>(label: &str, f: impl FnOnce() -> T) -> T {
    let (w0, c0) = (Instant::now(), cpu_s());
    let r = f();
    println!(
        "{label}: wall {:.2} s, CPU {:.2} s",
        w0.elapsed().as_secs_f64(),
        cpu_s() - c0
    );
    r
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let profile = Profile::parse(&arg("--profile").unwrap_or_else(|| "paper".into()))
        .expect("--profile paper|demo|test");
    let kind = TerrainKind::parse(&arg("--terrain").unwrap_or_else(|| "cfa6".into()))
        .expect("--terrain flagstone|cfa6|cfa2");
    let hours = parse_hours(&arg("--hours").unwrap_or_else(|| "pm".into())).expect("--hours");
    let seed: u64 = arg("--seed").map_or(1, |s| s.parse().expect("--seed"));
    let repeat: u32 = arg("--repeat").map_or(1, |s| s.parse().expect("--repeat"));
    let out = arg("--out").map(PathBuf::from);
    let (w, h) = profile.image_size();
    println!(
        "{} {} seed {seed}, {w}x{h}, {hours} h, {} threads",
        kind.name(),
        profile.name(),
        rayon::current_num_threads()
    );
    let scene = timed("terrain", || Scene::new(kind, seed, profile));
    let light = timed("shadow map", || scene.lighting(hours));
    let cap = Capture::from_index(0, 0, 0.40);
    let mut pair = None;
    for _ in 0..repeat.max(1) {
        pair = Some(timed("stereo pair", || scene.capture(&light, &cap).2));
    }
    if let (Some(dir), Some(p)) = (out, pair) {
        std::fs::create_dir_all(&dir).expect("create --out");
        for (name, img) in [("left.png", p.left), ("right.png", p.right)] {
            image::GrayImage::from_raw(p.width, p.height, img)
                .expect("image size")
                .save(dir.join(name))
                .expect("write PNG");
        }
        println!("wrote {}", dir.display());
    }
}
