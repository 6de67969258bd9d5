//! Per-call window geometry ([`Frame`]): the camera transform, the window
//! frustum for culling, the near and guard-band clip planes, the polygon clip,
//! and projection and snapping to absolute 28.4 fixed-point pixels.
//!
//! Input: a checked camera, a finite pose and a window; output: the geometry
//! everything else reads. Nothing that decides a pixel depends on the window
//! (only the span bounds do). A clipped polygon has at most [`MAX_CLIP_VERTS`]
//! corners; snapped coordinates are clamped a little outside the guard band.

use crate::config::{RASTER_GUARD_PX, RASTER_NEAR_M};
use crate::geom::{Camera, Pose, Vec3};
use crate::image::Rect;

/// Fractional bits of the snapped vertex positions (28.4 fixed point).
pub const SUBPIXEL_BITS: u32 = 4;

/// Most corners of a triangle clipped by the near plane and four guard planes.
pub const MAX_CLIP_VERTS: usize = 8;

pub(super) const SUB: f32 = (1 << SUBPIXEL_BITS) as f32;

/// Slack (metres) of the tile-versus-frustum test, so rounding never culls a visible tile.
pub(super) const CULL_SLACK_M: f32 = 0.01;

#[derive(Clone, Copy, Debug)]
pub(super) struct Plane {
    pub(super) n: Vec3,
    pub(super) d: f32,
}

impl Plane {
    #[inline]
    pub(super) fn dist(&self, p: &Vec3) -> f32 {
        self.n.x * p.x + self.n.y * p.y + self.n.z * p.z + self.d
    }
}

/// Window geometry derived once per call. Everything that decides coverage or
/// values (clip region, snapping, edge functions, interpolation) is in absolute
/// image pixels and independent of the window, so a window render equals the
/// same crop of a larger render bit for bit; the window only bounds the spans.
pub(super) struct Frame {
    /// Camera-from-world rotation as a matrix and translation (cheaper per
    /// vertex than the quaternion).
    pub(super) rot: nalgebra::Matrix3<f32>,
    pub(super) trans: Vec3,
    /// Window frustum (near plane and the four pixel-edge side planes) in the
    /// world frame, for tile culling and the per-triangle reject.
    pub(super) world_planes: [Plane; 5],
    /// Per world plane: −`CULL_SLACK_M`·|n|, the tile test's threshold.
    pub(super) world_slack: [f32; 5],
    /// Near plane and guard-band side planes, camera frame.
    pub(super) clip_planes: [Plane; 5],
    pub(super) fx: f32,
    pub(super) fy: f32,
    pub(super) cx: f32,
    pub(super) cy: f32,
    pub(super) inv_fx: f32,
    pub(super) inv_fy: f32,
    /// Window origin and size, pixels.
    pub(super) wx: i64,
    pub(super) wy: i64,
    pub(super) w: i64,
    pub(super) h: i64,
    /// Snapped coordinates are clamped to this box (28.4), a little outside the guard band.
    pub(super) lim: [i64; 4],
    /// The image grown by the guard band (x0, y0, x1, y1 in pixels), independent
    /// of the window: triangles projecting inside it may be interpolated linearly.
    pub(super) image_guard: [f32; 4],
}

/// Side planes through the camera centre keeping pixel columns `u0..=u1` and rows
/// `v0..=v1` (absolute pixel coordinates): fx·X − (u0 − cx)·Z ≥ 0 etc.
pub(super) fn side_planes(cam: &Camera, u0: f32, u1: f32, v0: f32, v1: f32) -> [Plane; 4] {
    let (fx, fy) = (cam.fx, cam.fy);
    [
        Plane {
            n: Vec3::new(fx, 0.0, -(u0 - cam.cx)),
            d: 0.0,
        },
        Plane {
            n: Vec3::new(-fx, 0.0, u1 - cam.cx),
            d: 0.0,
        },
        Plane {
            n: Vec3::new(0.0, fy, -(v0 - cam.cy)),
            d: 0.0,
        },
        Plane {
            n: Vec3::new(0.0, -fy, v1 - cam.cy),
            d: 0.0,
        },
    ]
}

impl Frame {
    #[allow(
        clippy::arithmetic_side_effects,
        reason = "frame set-up on checked inputs (window and camera within ±2·MAX_IMAGE_DIM, guard band g ≤ MAX_IMAGE_DIM): every i64 sum stays below 2^20 before the 28.4 scaling; f32 vector arithmetic (nalgebra) otherwise"
    )]
    pub(super) fn new(cam: &Camera, world_from_cam: &Pose, window: Rect) -> Self {
        let (wx, wy) = (i64::from(window.x), i64::from(window.y));
        let (w, h) = (i64::from(window.w), i64::from(window.h));
        let near = Plane {
            n: Vec3::new(0.0, 0.0, 1.0),
            d: -RASTER_NEAR_M,
        };
        let [a, b, c, d] = side_planes(
            cam,
            wx as f32 - 0.5,
            (wx + w) as f32 - 0.5,
            wy as f32 - 0.5,
            (wy + h) as f32 - 0.5,
        );
        // Guard band: the image (and the window, if it sticks out) grown by RASTER_GUARD_PX.
        let g = i64::from(RASTER_GUARD_PX);
        let gx0 = wx.min(0) - g;
        let gy0 = wy.min(0) - g;
        let gx1 = (wx + w - 1).max(i64::from(cam.width) - 1) + g;
        let gy1 = (wy + h - 1).max(i64::from(cam.height) - 1) + g;
        let [ga, gb, gc, gd] = side_planes(cam, gx0 as f32, gx1 as f32, gy0 as f32, gy1 as f32);
        let cam_from_world = world_from_cam.inverse();
        let window_planes = [near, a, b, c, d];
        let r = cam_from_world.rotation();
        let t = cam_from_world.translation();
        // Plane in world: (Rᵀ n)·p_w + (n·t + d) ≥ 0.
        let world_planes = window_planes.map(|pl| Plane {
            n: r.inverse_transform_vector(&pl.n),
            d: pl.n.dot(&t) + pl.d,
        });
        let s = i64::from(1u32 << SUBPIXEL_BITS);
        Self {
            rot: *r.to_rotation_matrix().matrix(),
            trans: t,
            world_slack: world_planes.map(|pl| -CULL_SLACK_M * libm::sqrtf(pl.n.dot(&pl.n))),
            world_planes,
            clip_planes: [near, ga, gb, gc, gd],
            fx: cam.fx,
            fy: cam.fy,
            cx: cam.cx,
            cy: cam.cy,
            inv_fx: 1.0 / cam.fx,
            inv_fy: 1.0 / cam.fy,
            wx,
            wy,
            w,
            h,
            lim: [(gx0 - 8) * s, (gy0 - 8) * s, (gx1 + 8) * s, (gy1 + 8) * s],
            image_guard: [
                -(g as f32),
                -(g as f32),
                (i64::from(cam.width) - 1 + g) as f32,
                (i64::from(cam.height) - 1 + g) as f32,
            ],
        }
    }

    /// Whether a world box may intersect the window frustum.
    pub(super) fn box_visible(&self, min: &Vec3, max: &Vec3) -> bool {
        self.world_planes
            .iter()
            .zip(&self.world_slack)
            .all(|(pl, slack)| {
                let nw = pl.n;
                let p = Vec3::new(
                    if nw.x >= 0.0 { max.x } else { min.x },
                    if nw.y >= 0.0 { max.y } else { min.y },
                    if nw.z >= 0.0 { max.z } else { min.z },
                );
                nw.dot(&p) + pl.d >= *slack
            })
    }
}

/// Clip polygon `poly[..n]` against `pl`, into `out`; returns the new corner count.
/// The intersection on an edge is computed from its inside corner towards its
/// outside corner, so two triangles sharing the edge get bit-identical points.
#[allow(
    clippy::arithmetic_side_effects,
    reason = "i < n ≤ MAX_CLIP_VERTS, so (i + 1) % n has n ≥ 1; f32 vector arithmetic (nalgebra)"
)]
pub(super) fn clip_poly(
    poly: &[Vec3; MAX_CLIP_VERTS],
    n: usize,
    pl: &Plane,
    out: &mut [Vec3; MAX_CLIP_VERTS],
) -> usize {
    let mut m = 0;
    let mut push = |v: Vec3, m: &mut usize| {
        if let Some(slot) = out.get_mut(*m) {
            *slot = v;
            // `get_mut` succeeded: *m < MAX_CLIP_VERTS.
            *m = m.wrapping_add(1);
        }
    };
    for i in 0..n.min(MAX_CLIP_VERTS) {
        let (Some(a), Some(b)) = (poly.get(i), poly.get((i + 1) % n)) else {
            break;
        };
        let (da, db) = (pl.dist(a), pl.dist(b));
        if da >= 0.0 {
            push(*a, &mut m);
        }
        if (da >= 0.0) != (db >= 0.0) {
            let (inn, outv, di, dout) = if da >= 0.0 {
                (a, b, da, db)
            } else {
                (b, a, db, da)
            };
            let t = di / (di - dout);
            push(inn + (outv - inn) * t, &mut m);
        }
    }
    m
}

/// A clipped polygon corner in absolute 28.4 fixed-point pixel coordinates.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct ScreenVert {
    pub(super) x: i64,
    pub(super) y: i64,
}

/// Project a camera-frame point to absolute image pixels.
#[inline]
pub(super) fn project(frame: &Frame, p: &Vec3) -> (f32, f32) {
    let inv_z = 1.0 / p.z;
    (
        frame.fx * p.x * inv_z + frame.cx,
        frame.fy * p.y * inv_z + frame.cy,
    )
}

/// Snap a projected point to absolute 28.4 fixed point.
#[inline]
#[allow(
    clippy::cast_possible_truncation,
    reason = "float-to-int `as` saturates before the clamp to the guard band"
)]
pub(super) fn snap(frame: &Frame, (u, v): (f32, f32)) -> ScreenVert {
    // Clipping keeps corners within the guard band up to rounding; the clamp bounds
    // the fixed-point range for the overflow budget whatever the rounding did
    // (a NaN casts to 0, inside the range).
    // `max`/`min` rather than `clamp`: the same for ordered limits, and no
    // panic path for limits the other way round.
    let x = (libm::roundf(u * SUB) as i64)
        .max(frame.lim[0])
        .min(frame.lim[2]);
    let y = (libm::roundf(v * SUB) as i64)
        .max(frame.lim[1])
        .min(frame.lim[3]);
    ScreenVert { x, y }
}
