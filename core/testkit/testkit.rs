//! Test fixtures shared by the core's unit tests and examples: random poses,
//! a heightfield mesh builder, and a synthetic scene — a textured bumpy
//! heightfield over [0, 8] × [-4, 4] m (every triangle in M̂), a 640×480
//! stereo rig, and a full-image renderer built on `raster`.
//!
//! Compiled into the library only under `cfg(test)` and included by the
//! examples and by `vtsm-tests` (`vtsm_tests::testkit`) with `#[path]`; it uses
//! `std` and is never part of a flight build.
#![allow(clippy::unwrap_used, clippy::expect_used, dead_code)]

extern crate std;

use nalgebra::{Matrix3, Rotation3, UnitQuaternion};
use std::vec;
use std::vec::Vec;
use vtsm_core::config::Params;
use vtsm_core::geom::{Camera, Pose, StereoRig, Vec3};
use vtsm_core::image::{GrayView, Rect};
use vtsm_core::map::{MapSource, MapView};
use vtsm_core::raster::{self, Target};
use vtsm_core::rng::Rng;

/// Side of the square terrain, metres.
pub const EXTENT_M: f32 = 8.0;
/// Vertices per side of the heightfield grid.
pub const GRID: usize = 81;
/// Side of the square texture, texels.
pub const TEX: usize = 1024;
/// Image size of [`rig`].
pub const WIDTH: usize = 640;
/// Image size of [`rig`].
pub const HEIGHT: usize = 480;

/// A random pose: rotation up to 3.1 rad about a random axis, translation in ±5 m.
pub fn random_pose(rng: &mut Rng) -> Pose {
    let axis = rng.unit_vector3();
    let angle = rng.uniform(-3.1, 3.1);
    let t = Vec3::new(
        rng.uniform(-5.0, 5.0),
        rng.uniform(-5.0, 5.0),
        rng.uniform(-5.0, 5.0),
    );
    Pose::new(UnitQuaternion::from_scaled_axis(axis * angle), t)
}

/// Value noise: random lattice values every `cell` texels, bilinear in between.
pub fn value_noise(rng: &mut Rng, cell: usize, amp: f32, out: &mut [f32]) {
    let n = TEX / cell + 2;
    let lattice: Vec<f32> = (0..n * n).map(|_| rng.uniform(-amp, amp)).collect();
    for y in 0..TEX {
        for x in 0..TEX {
            let (gx, gy) = (x / cell, y / cell);
            let fx = (x % cell) as f32 / cell as f32;
            let fy = (y % cell) as f32 / cell as f32;
            let at = |i: usize, j: usize| lattice[j * n + i];
            let top = at(gx, gy) * (1.0 - fx) + at(gx + 1, gy) * fx;
            let bot = at(gx, gy + 1) * (1.0 - fx) + at(gx + 1, gy + 1) * fx;
            out[y * TEX + x] += top * (1.0 - fy) + bot * fy;
        }
    }
}

/// A heightfield mesh: vertices, triangles and per-corner texture coordinates.
pub struct GridMesh {
    /// Vertices, row by row (`j * n + i`), metres.
    pub vertices: Vec<[f32; 3]>,
    /// Two triangles per grid cell, counter-clockwise seen from above.
    pub triangles: Vec<[u32; 3]>,
    /// Texture coordinates of each triangle's corners: the texture spans the grid once.
    pub uvs: Vec<[[f32; 2]; 3]>,
}

/// An `n`×`n`-vertex heightfield over [0, `side_m`] × [−`side_m`/2, `side_m`/2]
/// with `z = height(x, y)` (`n` ≥ 2).
pub fn grid_mesh(n: usize, side_m: f32, height: impl Fn(f32, f32) -> f32) -> GridMesh {
    let step = side_m / (n - 1) as f32;
    let y0 = -0.5 * side_m;
    let mut vertices = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (i as f32 * step, y0 + j as f32 * step);
            vertices.push([x, y, height(x, y)]);
        }
    }
    let uv_of = |i: usize, j: usize| [i as f32 / (n - 1) as f32, j as f32 / (n - 1) as f32];
    let (mut triangles, mut uvs) = (Vec::new(), Vec::new());
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let v = |i: usize, j: usize| (j * n + i) as u32;
            triangles.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
            uvs.push([uv_of(i, j), uv_of(i + 1, j), uv_of(i + 1, j + 1)]);
            triangles.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
            uvs.push([uv_of(i, j), uv_of(i + 1, j + 1), uv_of(i, j + 1)]);
        }
    }
    GridMesh {
        vertices,
        triangles,
        uvs,
    }
}

/// The encoded map product of the scene for `seed`.
pub fn build_map(seed: u64) -> Vec<u8> {
    build_map_with_mask(seed, |_| true)
}

/// [`build_map`] with triangle `i` in M̂ when `in_mask(i)`.
pub fn build_map_with_mask(seed: u64, in_mask: impl Fn(usize) -> bool) -> Vec<u8> {
    build_map_scored(seed, in_mask, None)
}

/// [`build_map_with_mask`] with vertex `v` scored `score(v)` for
/// SamplePoint (a version-3 product), or unscored with `None`.
pub fn build_map_scored(
    seed: u64,
    in_mask: impl Fn(usize) -> bool,
    score: Option<&dyn Fn(usize) -> u8>,
) -> Vec<u8> {
    let mut rng = Rng::new(seed);
    let bumps: Vec<(f32, f32, f32)> = (0..25)
        .map(|_| {
            (
                rng.uniform(0.0, EXTENT_M),
                rng.uniform(-4.0, 4.0),
                rng.uniform(0.05, 0.3),
            )
        })
        .collect();
    let height = |x: f32, y: f32| {
        let mut z = 0.05 * libm::sinf(1.3 * x) * libm::cosf(1.1 * y);
        for (bx, by, h) in &bumps {
            let d2 = (x - bx) * (x - bx) + (y - by) * (y - by);
            z += h * libm::expf(-d2 / (2.0 * 0.3 * 0.3));
        }
        z
    };
    let GridMesh {
        vertices,
        triangles,
        uvs,
    } = grid_mesh(GRID, EXTENT_M, height);
    let mask: Vec<bool> = (0..triangles.len()).map(in_mask).collect();
    let scores: Option<Vec<u8>> = score.map(|f| (0..vertices.len()).map(f).collect());
    let mut acc = vec![128.0f32; TEX * TEX];
    value_noise(&mut rng, 64, 50.0, &mut acc);
    value_noise(&mut rng, 16, 40.0, &mut acc);
    value_noise(&mut rng, 4, 20.0, &mut acc);
    let texture: Vec<u8> = acc.iter().map(|v| v.clamp(0.0, 255.0) as u8).collect();
    let src = MapSource {
        vertices: &vertices,
        triangles: &triangles,
        uvs: &uvs,
        mask: &mask,
        texture: GrayView::new(&texture, TEX, TEX, TEX).unwrap(),
        tile_size_m: 1.0,
        origin: [0.0; 3],
        vertex_scores: scores.as_deref(),
    };
    let mut out = vec![0u8; vtsm_core::map::encoded_len(&src).unwrap()];
    let n = vtsm_core::map::encode(&src, &mut out).unwrap();
    out.truncate(n);
    out
}

/// 640×480, 70° horizontal field of view, 0.3 m baseline.
pub fn rig() -> StereoRig {
    StereoRig::new(
        Camera::from_hfov(WIDTH as u32, HEIGHT as u32, 70.0).unwrap(),
        0.3,
    )
    .unwrap()
}

/// Left camera at (x, y, 1.2 m) looking along world +x, pitched 40° down.
pub fn camera_pose(x: f32, y: f32) -> Pose {
    let p = 40.0f32.to_radians();
    let zc = Vec3::new(libm::cosf(p), 0.0, -libm::sinf(p));
    let xc = Vec3::new(0.0, -1.0, 0.0);
    let yc = zc.cross(&xc);
    let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[xc, yc, zc]));
    Pose::new(
        UnitQuaternion::from_rotation_matrix(&r),
        Vec3::new(x, y, 1.2),
    )
}

/// Render the full image in `MAX_RENDER_PX` tiles, then apply gain and offset.
pub fn render_full(map: &MapView, cam: &Camera, pose: &Pose, gain: f32, offset: f32) -> Vec<u8> {
    let (w, h) = (cam.width() as usize, cam.height() as usize);
    let mut img = vec![0u8; w * h];
    let t = vtsm_core::config::MAX_RENDER_PX;
    let (mut inten, mut depth, mut md) = (vec![0u8; t * t], vec![0u32; t * t], vec![0u32; t * t]);
    for ty in (0..h).step_by(t) {
        for tx in (0..w).step_by(t) {
            let (tw, th) = (t.min(w - tx), t.min(h - ty));
            let rect = Rect::new(tx as i32, ty as i32, tw as u32, th as u32);
            let mut target = Target {
                intensity: &mut inten,
                depth: &mut depth,
                mask_depth: &mut md,
            };
            if raster::render_window(map, cam, pose, rect, &mut target).is_err() {
                continue;
            }
            for y in 0..th {
                for x in 0..tw {
                    let v = f32::from(inten[y * tw + x]) * gain + offset;
                    img[(ty + y) * w + tx + x] = v.clamp(0.0, 255.0) as u8;
                }
            }
        }
    }
    img
}

/// The test profile of the engine: ℓ = 64, N_corr = 40, N_iter = 5.
pub fn test_params() -> Params {
    Params {
        template_px: 64,
        search_px: 256,
        n_corr: 40,
        n_iter: 5,
        attempts_per_iter: 400,
        ransac_iter: 400,
        max_reseed: 4,
        ..Params::paper()
    }
}
