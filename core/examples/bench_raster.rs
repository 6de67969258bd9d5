//! Rasterizer benchmark: renders many 256² and 128² template windows of a
//! depot-sized textured heightfield map at random paper-profile views and prints
//! throughput. Not a test: run it on a quiet machine.
//!
//! `cargo run --release -p vtsm-core --example bench_raster [-- <views> <seed>]`

#![allow(clippy::expect_used)] // a benchmark harness: a failed setup step should stop it loudly

use std::time::Instant;

use nalgebra::{Matrix3, Rotation3, UnitQuaternion};
use vtsm_core::geom::{Camera, Pose, Vec3};
use vtsm_core::image::{GrayView, Rect};
use vtsm_core::map::{encode, encoded_len, MapSource, MapView};
use vtsm_core::raster::{render_window, template_mask, Target, DEPTH_NONE};
use vtsm_core::rng::Rng;

const GRID: usize = 320; // cells a side: 2·320² = 204 800 triangles
const SIZE_M: f32 = 12.0;
const TEX: usize = 2048;

fn height(x: f32, y: f32) -> f32 {
    0.15 * (x * 0.9).sin() * (y * 0.7).cos() + 0.04 * (x * 5.3 + y * 3.1).sin()
}

fn look_at(eye: Vec3, target: Vec3) -> Pose {
    let z = (target - eye).normalize();
    let x = z.cross(&Vec3::new(0.0, 0.0, 1.0)).normalize();
    let y = z.cross(&x);
    let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
    Pose::new(UnitQuaternion::from_rotation_matrix(&r), eye)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let views: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(1000);
    let seed: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    // Optional: window sides to run ("256,128") and "nomask" to skip the second pass
    // (for instruction counting under callgrind, one configuration at a time).
    let sides: Vec<u32> = args
        .get(3)
        .map(|s| s.split(',').filter_map(|v| v.parse().ok()).collect())
        .unwrap_or_else(|| vec![256, 128]);
    let with_mask = args.get(4).map(|s| s != "nomask").unwrap_or(true);

    // Depot-sized textured heightfield, rock-like mask on a sparse pattern of cells.
    let mut vertices = Vec::with_capacity((GRID + 1) * (GRID + 1));
    for j in 0..=GRID {
        for i in 0..=GRID {
            let (x, y) = (
                SIZE_M * i as f32 / GRID as f32,
                SIZE_M * j as f32 / GRID as f32,
            );
            vertices.push([x, y, height(x, y)]);
        }
    }
    let (mut triangles, mut uvs, mut mask) = (Vec::new(), Vec::new(), Vec::new());
    let uv = |i: usize, j: usize| [i as f32 / GRID as f32, j as f32 / GRID as f32];
    for j in 0..GRID {
        for i in 0..GRID {
            let a = (j * (GRID + 1) + i) as u32;
            let (b, c, d) = (a + 1, a + GRID as u32 + 1, a + GRID as u32 + 2);
            let m = (i / 8 + j / 8) % 3 == 0;
            triangles.push([a, b, d]);
            uvs.push([uv(i, j), uv(i + 1, j), uv(i + 1, j + 1)]);
            triangles.push([a, d, c]);
            uvs.push([uv(i, j), uv(i + 1, j + 1), uv(i, j + 1)]);
            mask.push(m);
            mask.push(m);
        }
    }
    let tex: Vec<u8> = (0..TEX * TEX)
        .map(|k| {
            let (x, y) = ((k % TEX) as f32, (k / TEX) as f32);
            (128.0
                + 60.0 * (x * 0.05).sin() * (y * 0.07).cos()
                + 40.0 * ((x * 0.31 + y * 0.17).sin())) as u8
        })
        .collect();
    let src = MapSource {
        vertices: &vertices,
        triangles: &triangles,
        uvs: &uvs,
        mask: &mask,
        texture: GrayView::new(&tex, TEX, TEX, TEX).expect("texture"),
        tile_size_m: 0.5,
        origin: [0.0; 3],
        vertex_scores: None,
    };
    let t0 = Instant::now();
    let mut bytes = vec![0u8; encoded_len(&src).expect("encoded_len")];
    let n = encode(&src, &mut bytes).expect("encode");
    bytes.truncate(n);
    let t_encode = t0.elapsed();
    let t0 = Instant::now();
    let map = MapView::new_checked(&bytes).expect("map");
    let t_check = t0.elapsed();
    println!(
        "map: {} triangles, {} vertices, {} tiles, texture {}², {:.1} MB; encode {:.1} ms, new_checked {:.1} ms",
        map.triangle_count(),
        map.vertex_count(),
        map.tile_count(),
        TEX,
        n as f64 / 1e6,
        t_encode.as_secs_f64() * 1e3,
        t_check.as_secs_f64() * 1e3
    );

    // Paper profile camera: 5472×3648, 77° HFOV.
    let cam = Camera::from_hfov(5472, 3648, 77.0).expect("camera");
    let mut rng = Rng::new(seed);
    let mut poses = Vec::with_capacity(views);
    while poses.len() < views {
        let eye = Vec3::new(rng.uniform(2.0, 10.0), rng.uniform(2.0, 10.0), 0.0);
        let eye = Vec3::new(eye.x, eye.y, height(eye.x, eye.y) + rng.uniform(1.0, 2.0));
        let ang = rng.uniform(0.0, std::f32::consts::TAU);
        let dist = rng.uniform(1.5, 5.0);
        let tx = (eye.x + dist * ang.cos()).clamp(0.5, SIZE_M - 0.5);
        let ty = (eye.y + dist * ang.sin()).clamp(0.5, SIZE_M - 0.5);
        let target = Vec3::new(tx, ty, height(tx, ty));
        let pose = look_at(eye, target);
        // Window centred on a point near the optical axis, jittered across the image.
        let u = cam.cx() + rng.uniform(-1500.0, 1500.0);
        let v = cam.cy() + rng.uniform(-1000.0, 1000.0);
        poses.push((pose, u, v));
    }

    let mut intensity = vec![0u8; 256 * 256];
    let mut depth = vec![0u32; 256 * 256];
    let mut mask_depth = vec![0u32; 256 * 256];
    let mut out_mask = vec![0u8; 256 * 256];
    let window = |side: u32, u: f32, v: f32| {
        Rect::new(
            u as i32 - side as i32 / 2,
            v as i32 - side as i32 / 2,
            side,
            side,
        )
    };
    for side in sides {
        let npx = (side * side) as usize;
        let mut checksum = 0u64;
        let (mut tris, mut drawn, mut written, mut spans, mut empty, mut kept) =
            (0u64, 0u64, 0u64, 0u64, 0u64, 0u64);
        let mut linear = 0u64;
        let mut covered = 0u64;
        // Pass 1: render only.
        let (wall0, cpu0) = (Instant::now(), thread_cpu_ns());
        for (pose, u, v) in &poses {
            let mut t = Target {
                intensity: &mut intensity,
                depth: &mut depth,
                mask_depth: &mut mask_depth,
            };
            match render_window(&map, &cam, pose, window(side, *u, *v), &mut t) {
                Ok(s) => {
                    tris += u64::from(s.triangles_tested);
                    drawn += u64::from(s.triangles_drawn);
                    linear += u64::from(s.triangles_linear);
                    written += u64::from(s.pixels_written);
                    spans += u64::from(s.spans);
                }
                Err(_) => empty += 1,
            }
            covered += depth[..npx].iter().filter(|d| **d != DEPTH_NONE).count() as u64;
            for (k, p) in intensity[..npx].iter().enumerate().step_by(97) {
                checksum = checksum
                    .wrapping_mul(31)
                    .wrapping_add(u64::from(*p) ^ k as u64);
            }
        }
        let (wall_render, cpu_render) = (
            wall0.elapsed().as_secs_f64(),
            (thread_cpu_ns() - cpu0) as f64 * 1e-9,
        );
        // Pass 2: render and form the template mask; the mask's cost is the difference.
        let cpu1 = thread_cpu_ns();
        for (pose, u, v) in poses.iter().filter(|_| with_mask) {
            let mut t = Target {
                intensity: &mut intensity,
                depth: &mut depth,
                mask_depth: &mut mask_depth,
            };
            let _ = render_window(&map, &cam, pose, window(side, *u, *v), &mut t);
            kept += u64::from(template_mask(
                &depth,
                &mask_depth,
                side as usize,
                side as usize,
                &mut out_mask,
            ));
        }
        let cpu_both = (thread_cpu_ns() - cpu1) as f64 * 1e-9;
        let nv = poses.len() as f64;
        let px = nv * f64::from(side * side);
        println!(
            "{side}²: {views} windows; render {:.1} µs/template CPU ({:.1} µs wall), {:.1} Mpix/s CPU; \
             template_mask {:.1} µs CPU; covered {:.1}%; per window: {:.0} triangles tested, {:.0} drawn ({:.0} linear), \
             {:.0} spans, {:.0} pixels written, {:.0} kept by mask; {empty} empty; checksum {checksum:016x}",
            cpu_render / nv * 1e6,
            wall_render / nv * 1e6,
            px / cpu_render / 1e6,
            (cpu_both - cpu_render) / nv * 1e6,
            100.0 * covered as f64 / px,
            tris as f64 / nv,
            drawn as f64 / nv,
            linear as f64 / nv,
            spans as f64 / nv,
            written as f64 / nv,
            kept as f64 / nv,
        );
    }
}

/// Time this thread has spent on a CPU, ns (Linux `/proc/thread-self/schedstat`),
/// so time lost to other processes on a shared machine is not charged to the renderer.
fn thread_cpu_ns() -> u64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next().and_then(|v| v.parse().ok()))
        .expect("/proc/thread-self/schedstat")
}
