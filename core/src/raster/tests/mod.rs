extern crate std;

mod accuracy;
mod coverage;
mod inputs;
mod mask;

use super::*;
use crate::config::{TEMPLATE_MASK_JUMP_M, TEMPLATE_MASK_JUMP_REL_DIV, TEMPLATE_MASK_RADIUS_PX};
use crate::image::GrayView;
use crate::map::{encode, encoded_len, MapSource};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion};
use proptest::prelude::*;
use std::vec;
use std::vec::Vec;

/// A mesh in memory for tests (UVs in OBJ convention).
#[derive(Clone, Default)]
struct Scene {
    vertices: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
    uvs: Vec<[[f32; 2]; 3]>,
    mask: Vec<bool>,
    tex: Vec<u8>,
    tw: usize,
    th: usize,
}

impl Scene {
    fn new() -> Self {
        Self {
            tex: vec![128; 4],
            tw: 2,
            th: 2,
            ..Default::default()
        }
    }
    fn tri(&mut self, p: [[f32; 3]; 3], uv: [[f32; 2]; 3], mask: bool) {
        let base = self.vertices.len() as u32;
        self.vertices.extend_from_slice(&p);
        self.triangles.push([base, base + 1, base + 2]);
        self.uvs.push(uv);
        self.mask.push(mask);
    }
    fn bytes(&self, tile_size_m: f32) -> Vec<u8> {
        let src = MapSource {
            vertices: &self.vertices,
            triangles: &self.triangles,
            uvs: &self.uvs,
            mask: &self.mask,
            texture: GrayView::new(&self.tex, self.tw, self.th, self.tw).unwrap(),
            tile_size_m,
            origin: [0.0; 3],
            vertex_scores: None,
        };
        let mut out = vec![0u8; encoded_len(&src).unwrap()];
        let n = encode(&src, &mut out).unwrap();
        out.truncate(n);
        out
    }
    /// Heightfield grid over [x0, x0+size]² with `n` cells a side, shared vertices.
    fn terrain(n: usize, x0: f32, size: f32, height: impl Fn(f32, f32) -> f32) -> Self {
        let mut s = Self::new();
        for j in 0..=n {
            for i in 0..=n {
                let (x, y) = (
                    x0 + size * i as f32 / n as f32,
                    x0 + size * j as f32 / n as f32,
                );
                s.vertices.push([x, y, height(x, y)]);
            }
        }
        for j in 0..n {
            for i in 0..n {
                let a = (j * (n + 1) + i) as u32;
                let (b, c, d) = (a + 1, a + n as u32 + 1, a + n as u32 + 2);
                let uv = |i: usize, j: usize| [i as f32 / n as f32, j as f32 / n as f32];
                s.triangles.push([a, b, d]);
                s.uvs.push([uv(i, j), uv(i + 1, j), uv(i + 1, j + 1)]);
                s.triangles.push([a, d, c]);
                s.uvs.push([uv(i, j), uv(i + 1, j + 1), uv(i, j + 1)]);
                s.mask.push((i + j) % 3 == 0);
                s.mask.push(i % 4 == 1);
            }
        }
        s.tw = 64;
        s.th = 64;
        s.tex = (0..64 * 64)
            .map(|k| {
                (128.0
                    + 100.0 * libm::sinf((k % 64) as f32 * 0.4) * libm::cosf((k / 64) as f32 * 0.3))
                    as u8
            })
            .collect();
        s
    }
}

fn camera(w: u32, h: u32, f: f32) -> Camera {
    Camera::new(f, f, (w as f32 - 1.0) * 0.5, (h as f32 - 1.0) * 0.5, w, h).unwrap()
}

/// world_from_cam for an OpenCV camera at `eye` looking at `target`, world z up.
fn look_at(eye: [f32; 3], target: [f32; 3]) -> Pose {
    let eye = Vec3::from(eye);
    let z = (Vec3::from(target) - eye).normalize();
    let x = z.cross(&Vec3::new(0.0, 0.0, 1.0)).normalize();
    let y = z.cross(&x);
    let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
    Pose::new(UnitQuaternion::from_rotation_matrix(&r), eye)
}

struct Render {
    intensity: Vec<u8>,
    depth: Vec<u32>,
    mask_depth: Vec<u32>,
    result: Result<RenderStats, FailureCode>,
}

fn render(map: &MapView, cam: &Camera, pose: &Pose, win: Rect) -> Render {
    let n = (win.w * win.h) as usize;
    let (mut intensity, mut depth, mut mask_depth) = (vec![0u8; n], vec![0u32; n], vec![0u32; n]);
    let mut t = Target {
        intensity: &mut intensity,
        depth: &mut depth,
        mask_depth: &mut mask_depth,
    };
    let result = render_window(map, cam, pose, win, &mut t);
    Render {
        intensity,
        depth,
        mask_depth,
        result,
    }
}

/// Coverage count per window pixel (test-only use of the pixel sink).
fn coverage(map: &MapView, cam: &Camera, pose: &Pose, win: Rect) -> Vec<u32> {
    let n = (win.w * win.h) as usize;
    let mut count = vec![0u32; n];
    let mut outside = 0usize;
    rasterize(
        map,
        cam,
        pose,
        win,
        &mut |f: Frag| match count.get_mut(f.idx) {
            Some(c) => *c += 1,
            None => outside += 1,
        },
    )
    .unwrap();
    assert_eq!(outside, 0, "fragment outside the window");
    count
}
