//! The depot map product the way a ground team would make it (paper §V-A).
//!
//! Input: a [`Terrain`] and the [`Lighting`] at mapping time. Output: [`MeshData`], plain
//! Rust data that the file writers and `core::map::MapSource` take: a regular grid of
//! vertices (1–2 cm, i.e. decimated relative to the terrain's millimetre cells) with
//! reconstruction noise (white plus a smooth low-frequency warp), two triangles per
//! quad with the diagonal that better follows the true surface, per-corner UVs
//! (normalized, OBJ convention: v = 0 is the bottom row of the texture), a gray texture
//! that bakes albedo × mapping-time shading with mapping-time cast shadows through the
//! same exposure and gamma as the cameras, and the sampling mask M̂ as one flag per
//! triangle (rocks only on Flagstone and CFA6, everything on CFA2).
//!
//! Simplification: the texture is baked orthographically from the true surface, so
//! surfaces the mapping cameras would not see (overhangs do not exist in a heightfield;
//! steep rock flanks facing away from every mapping stop) are still textured.
//!
//! [`render_mesh`] is a small float z-buffer rasterizer of such a mesh (perspective-correct
//! UVs, bilinear texture) used to check the product against the photometric renderer.

use crate::io::image::Gray8;
pub use crate::io::mesh::MeshData;
use crate::render::{radiance, tone, Lighting};
use crate::terrain::{fbm, Terrain, DEPOT_HALF_X_M, DEPOT_HALF_Y_M};
use rayon::prelude::*;
use vtsm_core::geom::{Camera, Pose, Vec3};
use vtsm_core::rng::Rng;

/// How the map is made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MappingOptions {
    /// Grid spacing of the mesh vertices, metres.
    pub vertex_m: f32,
    /// Texel size, metres.
    pub texel_m: f32,
    /// Radiance samples per texel along each axis (the texel is their mean,
    /// as a camera pixel integrates its footprint).
    pub texel_samples: u32,
    /// Standard deviation of per-vertex white height noise, metres.
    pub noise_m: f32,
    /// Amplitude of the smooth height warp (wavelength ~0.5 m), metres.
    pub warp_m: f32,
    /// Half-extent along x of the mapped region, metres.
    pub half_x_m: f32,
    /// Half-extent along y of the mapped region, metres.
    pub half_y_m: f32,
    /// Seed of the reconstruction noise.
    pub seed: u64,
}

impl MappingOptions {
    /// The same options for imagery `k` times coarser: vertex spacing, texel
    /// size and samples per texel axis × `k` (`k` ≤ 1 changes nothing), so a
    /// coarse texel is the mean over its whole footprint at the fine
    /// sampling density, as a coarser camera's pixel would be, not a
    /// subsampled copy of the fine texture.
    pub fn coarsened(self, k: u32) -> Self {
        if k <= 1 {
            return self;
        }
        let scale = k as f32;
        Self {
            vertex_m: self.vertex_m * scale,
            texel_m: self.texel_m * scale,
            texel_samples: self.texel_samples.saturating_mul(k),
            ..self
        }
    }
}

impl Default for MappingOptions {
    fn default() -> Self {
        Self {
            vertex_m: 0.02,
            texel_m: 0.004,
            texel_samples: 2,
            noise_m: 0.0015,
            warp_m: 0.003,
            half_x_m: DEPOT_HALF_X_M,
            half_y_m: DEPOT_HALF_Y_M,
            seed: 1,
        }
    }
}

/// Build the map product of `terrain` under the mapping-time `light`.
pub fn build_map(terrain: &Terrain, light: &Lighting, opts: &MappingOptions) -> MeshData {
    let s = opts.vertex_m.max(1e-3);
    let (hx, hy) = (opts.half_x_m, opts.half_y_m);
    let nvx = (2.0 * hx / s).round() as usize + 1;
    let nvy = (2.0 * hy / s).round() as usize + 1;
    let rng = Rng::new(opts.seed).fork(0x3A9_0000);
    let vx = |i: usize| -hx + i as f32 * s;
    let vy = |j: usize| -hy + j as f32 * s;
    let mut vertices = Vec::with_capacity(nvx * nvy);
    for j in 0..nvy {
        for i in 0..nvx {
            let (x, y) = (vx(i), vy(j));
            let mut r = rng.at(((j * nvx + i) as u64) << 2);
            let warp = opts.warp_m * 2.0 * fbm(opts.seed ^ 0x3A9, x, y, 0.5, 2);
            vertices.push([
                x,
                y,
                terrain.height(x, y) + opts.noise_m * r.normal() + warp,
            ]);
        }
    }
    let uv = |x: f32, y: f32| [(x + hx) / (2.0 * hx), (y + hy) / (2.0 * hy)];
    let mut triangles = Vec::with_capacity(2 * (nvx - 1) * (nvy - 1));
    let mut uvs = Vec::with_capacity(triangles.capacity());
    let mut mask = Vec::with_capacity(triangles.capacity());
    for j in 0..nvy - 1 {
        for i in 0..nvx - 1 {
            let a = (j * nvx + i) as u32;
            let b = a + 1;
            let c = a + nvx as u32;
            let d = c + 1;
            let h = |k: u32| terrain.height(vertices[k as usize][0], vertices[k as usize][1]);
            let centre = terrain.height(vx(i) + 0.5 * s, vy(j) + 0.5 * s);
            let tris =
                if (0.5 * (h(a) + h(d)) - centre).abs() <= (0.5 * (h(b) + h(c)) - centre).abs() {
                    [[a, b, d], [a, d, c]]
                } else {
                    [[a, b, c], [b, d, c]]
                };
            for t in tris {
                let p = t.map(|k| vertices[k as usize]);
                let (cx, cy) = (
                    (p[0][0] + p[1][0] + p[2][0]) / 3.0,
                    (p[0][1] + p[1][1] + p[2][1]) / 3.0,
                );
                triangles.push(t);
                uvs.push(p.map(|q| uv(q[0], q[1])));
                mask.push(terrain.in_mask(cx, cy));
            }
        }
    }
    let tw = (2.0 * hx / opts.texel_m).round().max(1.0) as usize;
    let th = (2.0 * hy / opts.texel_m).round().max(1.0) as usize;
    let (tx, ty) = (2.0 * hx / tw as f32, 2.0 * hy / th as f32);
    let mut tex = vec![0u8; tw * th];
    let n = opts.texel_samples.clamp(1, 64);
    tex.par_chunks_mut(tw).enumerate().for_each(|(r, row)| {
        for (c, px) in row.iter_mut().enumerate() {
            // n×n samples per texel, at the centres of an n×n subgrid.
            let mut sum = 0.0;
            for j in 0..n {
                for i in 0..n {
                    let x = -hx + (c as f32 + (i as f32 + 0.5) / n as f32) * tx;
                    let y = hy - (r as f32 + (j as f32 + 0.5) / n as f32) * ty;
                    sum += radiance(terrain, light, x, y);
                }
            }
            *px = tone(sum / (n * n) as f32, light.exposure).round() as u8;
        }
    });
    MeshData {
        vertices,
        triangles,
        uvs,
        mask,
        texture: Gray8 {
            width: tw as u32,
            height: th as u32,
            pixels: tex,
        },
        origin: [0.0; 3],
    }
}

/// Rasterize `mesh` as seen by `cam` at `world_from_cam`: returns the gray image and a
/// per-pixel coverage flag. Triangles with a vertex closer than 5 cm are skipped.
pub fn render_mesh(mesh: &MeshData, cam: &Camera, world_from_cam: &Pose) -> (Vec<u8>, Vec<bool>) {
    let (w, h) = (cam.width() as usize, cam.height() as usize);
    let mut inv_z = vec![0.0f32; w * h];
    let mut val = vec![0.0f32; w * h];
    let cam_from_world = world_from_cam.inverse();
    let pc: Vec<Vec3> = mesh
        .vertices
        .iter()
        .map(|v| cam_from_world.transform_point(&Vec3::new(v[0], v[1], v[2])))
        .collect();
    for (ti, tri) in mesh.triangles.iter().enumerate() {
        let p = tri.map(|k| pc[k as usize]);
        if p.iter().any(|q| q.z < 0.05) {
            continue;
        }
        let s = p.map(|q| {
            [
                cam.fx() * q.x / q.z + cam.cx(),
                cam.fy() * q.y / q.z + cam.cy(),
            ]
        });
        let area =
            (s[1][0] - s[0][0]) * (s[2][1] - s[0][1]) - (s[2][0] - s[0][0]) * (s[1][1] - s[0][1]);
        if area.abs() < 1e-12 {
            continue;
        }
        let minx = s
            .iter()
            .map(|q| q[0])
            .fold(f32::MAX, f32::min)
            .ceil()
            .max(0.0);
        let maxx = s
            .iter()
            .map(|q| q[0])
            .fold(f32::MIN, f32::max)
            .floor()
            .min(w as f32 - 1.0);
        let miny = s
            .iter()
            .map(|q| q[1])
            .fold(f32::MAX, f32::min)
            .ceil()
            .max(0.0);
        let maxy = s
            .iter()
            .map(|q| q[1])
            .fold(f32::MIN, f32::max)
            .floor()
            .min(h as f32 - 1.0);
        if minx > maxx || miny > maxy {
            continue;
        }
        let uv = mesh.uvs[ti];
        let iz = p.map(|q| 1.0 / q.z);
        for y in miny as usize..=maxy as usize {
            for x in minx as usize..=maxx as usize {
                let (fx, fy) = (x as f32, y as f32);
                let e = |a: [f32; 2], b: [f32; 2]| {
                    (b[0] - a[0]) * (fy - a[1]) - (b[1] - a[1]) * (fx - a[0])
                };
                let w0 = e(s[1], s[2]) / area;
                let w1 = e(s[2], s[0]) / area;
                let w2 = e(s[0], s[1]) / area;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z_inv = w0 * iz[0] + w1 * iz[1] + w2 * iz[2];
                let k = y * w + x;
                if z_inv <= inv_z[k] {
                    continue;
                }
                let u =
                    (w0 * uv[0][0] * iz[0] + w1 * uv[1][0] * iz[1] + w2 * uv[2][0] * iz[2]) / z_inv;
                let v =
                    (w0 * uv[0][1] * iz[0] + w1 * uv[1][1] * iz[1] + w2 * uv[2][1] * iz[2]) / z_inv;
                inv_z[k] = z_inv;
                val[k] = mesh.sample_texture(u, v);
            }
        }
    }
    let img = val
        .iter()
        .map(|v| v.round().clamp(0.0, 255.0) as u8)
        .collect();
    let cover = inv_z.iter().map(|&z| z > 0.0).collect();
    (img, cover)
}

/// Zero-mean normalized cross-correlation of two images over the pixels where `valid`.
pub fn ncc(a: &[u8], b: &[u8], valid: &[bool]) -> f64 {
    let mut n = 0.0f64;
    let (mut sa, mut sb, mut saa, mut sbb, mut sab) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
    for ((&x, &y), &ok) in a.iter().zip(b.iter()).zip(valid.iter()) {
        if ok {
            let (x, y) = (f64::from(x), f64::from(y));
            n += 1.0;
            sa += x;
            sb += y;
            saa += x * x;
            sbb += y * y;
            sab += x * y;
        }
    }
    let cov = n * sab - sa * sb;
    let va = n * saa - sa * sa;
    let vb = n * sbb - sb * sb;
    if va <= 0.0 || vb <= 0.0 {
        return 0.0;
    }
    cov / (va * vb).sqrt()
}
