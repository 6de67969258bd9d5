//! Scanline rasterizer for virtual templates (paper §III-C, `Synthesize`).
//!
//! Renders a window (pixel rectangle) of a virtual pinhole camera placed at
//! `world_from_cam` over a [`MapView`], into caller buffers: 8-bit intensity
//! (bilinear texture sample with perspective-correct UVs), depth, and the depth of
//! the mask sub-mesh M̂ where M̂ is the visible surface. [`template_mask`] turns the
//! two depth buffers into the template mask.
//!
//! Pipeline per call: tiles whose box lies outside the window frustum (four side
//! planes and the near plane) are skipped; each remaining triangle is rejected
//! if all corners lie outside one window side plane (world frame), moved to the
//! camera frame, rejected if all corners lie in front of the near plane,
//! clipped in camera space against the near plane and, only when a corner lies
//! outside it, against the guard band ([`RASTER_GUARD_PX`] beyond the window);
//! the clipped convex polygon is snapped to 28.4 fixed point in absolute image
//! pixels and filled span by span as one polygon (never fanned, so snapping
//! cannot make pieces of one triangle overlap). Coverage is decided exactly on
//! integers with a top-left style tie rule (a pixel centre on an edge belongs to
//! the polygon that holds the centre moved by (ε, ε²)), so triangles sharing an
//! edge cover each pixel exactly once. Back faces are drawn (photogrammetry meshes
//! have arbitrary winding). A triangle of small depth range (at most 1/32 of its
//! depth, and small enough that texture coordinates move by at most 1/32 texel;
//! see `Affine`) that needs no clipping gets depth and UVs linear in the image,
//! as an exact integer plane stepped once per pixel along each span. Any other
//! triangle gets them from its unclipped plane (1/Z, u/Z, v/Z linear in the
//! image), evaluated exactly at every 8th absolute pixel column and stepped
//! linearly in fixed point in between when depth changes by at most 1/64 over
//! the 8 pixels (exactly at every pixel otherwise). Nothing that decides a pixel
//! depends on the window, so a window render equals the same crop of a full
//! render bit for bit.
//!
//! Depth format: `u32` camera-frame Z (along the optical axis) in units of
//! 2⁻¹⁶ m ([`DEPTH_FRAC_BITS`]), [`DEPTH_NONE`] where nothing was drawn; see
//! `fsw-docs/budgets/numeric.md`.
//!
//! Bounds: window ≤ [`MAX_RENDER_PX`]² pixels; tiles ≤ `MAX_MAP_TILES`, triangles
//! ≤ `MAX_MAP_TRIANGLES` per call (each visited at most once); a clipped polygon has
//! at most [`MAX_CLIP_VERTS`] corners; each polygon's rows and spans are
//! clipped to the window. [`RenderStats`] reports the work.

use crate::config::{
    MAX_IMAGE_DIM, MAX_RENDER_PX, RASTER_FAR_M, RASTER_GUARD_PX, RASTER_NEAR_M,
    TEMPLATE_MASK_JUMP_M, TEMPLATE_MASK_JUMP_REL_DIV, TEMPLATE_MASK_RADIUS_PX,
};
use crate::failure::FailureCode;
use crate::geom::{Camera, Pose, Vec3};
use crate::image::Rect;
use crate::map::MapView;

/// Depth value of a pixel where no surface was drawn.
pub const DEPTH_NONE: u32 = u32::MAX;
/// Fractional bits of the depth format: depth = round(Z · 2^16), Z in metres.
pub const DEPTH_FRAC_BITS: u32 = 16;
/// Largest depth value a surface can have (one below [`DEPTH_NONE`]), ≈ 65 535.99 m.
pub const DEPTH_MAX: u32 = u32::MAX - 1;
/// Fractional bits of the snapped vertex positions (28.4 fixed point).
pub const SUBPIXEL_BITS: u32 = 4;
/// Most corners of a triangle clipped by the near plane and four guard planes.
pub const MAX_CLIP_VERTS: usize = 8;

const SUB: f32 = (1 << SUBPIXEL_BITS) as f32;
const DEPTH_SCALE: f32 = (1u32 << DEPTH_FRAC_BITS) as f32;
/// Slack (metres) of the tile-versus-frustum test, so rounding never culls a visible tile.
const CULL_SLACK_M: f32 = 0.01;

/// Convert camera Z in metres to the depth format (rounded, saturating at [`DEPTH_MAX`]).
#[inline]
#[allow(
    clippy::cast_possible_truncation,
    reason = "float-to-int `as` saturates; the result is capped at DEPTH_MAX"
)]
pub fn depth_from_m(z_m: f32) -> u32 {
    // `as` saturates: NaN and negatives give 0, values beyond u32 give u32::MAX.
    ((z_m * DEPTH_SCALE + 0.5) as u32).min(DEPTH_MAX)
}

/// Convert a depth value to metres; `None` for [`DEPTH_NONE`].
#[inline]
pub fn depth_to_m(depth: u32) -> Option<f32> {
    (depth != DEPTH_NONE).then(|| depth as f32 / DEPTH_SCALE)
}

/// Render target for one window: three row-major buffers of at least `w·h`
/// elements, stride = window width. Elements past `w·h` are never touched.
#[derive(Debug)]
pub struct Target<'b> {
    /// Intensity, 0 where nothing was drawn.
    pub intensity: &'b mut [u8],
    /// Depth of the visible surface, [`DEPTH_NONE`] where nothing was drawn.
    pub depth: &'b mut [u32],
    /// Depth where the visible surface belongs to M̂, else [`DEPTH_NONE`].
    pub mask_depth: &'b mut [u32],
}

/// Work done by one [`render_window`] call.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RenderStats {
    /// Non-empty tiles tested against the frustum.
    pub tiles_tested: u32,
    /// Tiles whose box intersects the frustum.
    pub tiles_visible: u32,
    /// Triangles of visible tiles examined.
    pub triangles_tested: u32,
    /// Clipped triangles (one polygon each) whose spans were filled.
    pub triangles_drawn: u32,
    /// Drawn triangles whose depth and texture coordinates were interpolated
    /// linearly in the image (small depth range), the others perspective-correct.
    pub triangles_linear: u32,
    /// Non-empty row spans filled.
    pub spans: u32,
    /// Depth-test passes (pixel writes; a pixel overwritten by a nearer surface counts twice).
    pub pixels_written: u32,
}

/// One pixel that a triangle covers, handed to the pixel sink.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Frag {
    /// Index into the window buffers (`y · w + x`).
    pub idx: usize,
    /// Depth in the depth format (see [`DEPTH_FRAC_BITS`]).
    pub depth: u32,
    /// Texture coordinates in texture pixels, 16.16 fixed point.
    pub u_q16: i64,
    pub v_q16: i64,
    /// The triangle belongs to M̂.
    pub mask: bool,
}

/// Receives every covered pixel of a render.
pub(crate) trait PixelSink {
    fn put(&mut self, f: Frag);

    /// A run of `n ≥ 1` covered pixels at consecutive indices from `idx`, with
    /// depth and texture coordinates stepped linearly: pixel `k` has
    /// `(acc + k·step) >> RUN_SHIFT` (depth, u, v). Same effect as [`Self::put`]
    /// on each pixel in order.
    #[inline]
    fn put_run(&mut self, idx: usize, n: usize, acc: [i64; 3], step: [i64; 3], mask: bool) {
        let mut acc = acc;
        for k in 0..n {
            self.put(run_frag(idx.wrapping_add(k), acc, mask));
            acc = [
                acc[0].wrapping_add(step[0]),
                acc[1].wrapping_add(step[1]),
                acc[2].wrapping_add(step[2]),
            ];
        }
    }
}

/// The fragment of a linear run at accumulator `acc` (values scaled by `2^RUN_SHIFT`).
#[inline(always)]
#[allow(
    clippy::cast_possible_truncation,
    reason = "clamped to 0..=DEPTH_MAX (< 2^32) before the cast"
)]
fn run_frag(idx: usize, acc: [i64; 3], mask: bool) -> Frag {
    Frag {
        idx,
        depth: (acc[0] >> RUN_SHIFT).clamp(0, i64::from(DEPTH_MAX)) as u32,
        u_q16: acc[1] >> RUN_SHIFT,
        v_q16: acc[2] >> RUN_SHIFT,
        mask,
    }
}

impl<F: FnMut(Frag)> PixelSink for F {
    #[inline]
    fn put(&mut self, f: Frag) {
        self(f)
    }
}

/// The render target's pixel sink: depth test, mask depth, textured intensity.
struct ZBuffer<'t, 'b> {
    intensity: &'b mut [u8],
    depth: &'b mut [u32],
    mask_depth: &'b mut [u32],
    tex: &'t [u8],
    tw: usize,
    th: usize,
    written: u32,
}

impl PixelSink for ZBuffer<'_, '_> {
    #[inline(always)]
    fn put(&mut self, f: Frag) {
        let d = f.depth;
        if let Some(slot) = self.depth.get_mut(f.idx) {
            if d < *slot {
                *slot = d;
                if let Some(m) = self.mask_depth.get_mut(f.idx) {
                    *m = if f.mask { d } else { DEPTH_NONE };
                }
                if let Some(p) = self.intensity.get_mut(f.idx) {
                    *p = sample_bilinear(self.tex, self.tw, self.th, f.u_q16, f.v_q16);
                }
                self.written = self.written.saturating_add(1);
            }
        }
    }

    #[inline(always)]
    #[allow(
        clippy::cast_possible_truncation,
        reason = "clamped to 0..=DEPTH_MAX (< 2^32) before the cast"
    )]
    fn put_run(&mut self, idx: usize, n: usize, acc: [i64; 3], step: [i64; 3], mask: bool) {
        let end = idx.wrapping_add(n);
        // One bounds check per run: the three buffers have the same length (w·h).
        let (Some(ds), Some(ms), Some(is), true) = (
            self.depth.get_mut(idx..end),
            self.mask_depth.get_mut(idx..end),
            self.intensity.get_mut(idx..end),
            n >= 1,
        ) else {
            // Not reached for runs inside the window; the per-pixel path skips
            // out-of-range pixels the same way.
            let mut acc = acc;
            for k in 0..n {
                self.put(run_frag(idx.wrapping_add(k), acc, mask));
                acc = [
                    acc[0].wrapping_add(step[0]),
                    acc[1].wrapping_add(step[1]),
                    acc[2].wrapping_add(step[2]),
                ];
            }
            return;
        };
        let (tex, tw, th) = (self.tex, self.tw, self.th);
        // Values are linear along the run, so their extremes are at its ends: when
        // both ends lie inside the depth range and at least one texel from the
        // texture's right and bottom edges, every pixel does, and the clamps of
        // `run_frag` and `sample_bilinear` are the identity (same pixels, less work).
        // Accumulators stay within ±2^58 (see `fill_polygon`), so no i64 overflow.
        let last = n.saturating_sub(1) as i64;
        let lo_hi = |a: i64, s: i64| {
            let b = a.wrapping_add(s.wrapping_mul(last));
            (a.min(b) >> RUN_SHIFT, a.max(b) >> RUN_SHIFT)
        };
        let (d0, d1) = lo_hi(acc[0], step[0]);
        let (u0, u1) = lo_hi(acc[1], step[1]);
        let (v0, v1) = lo_hi(acc[2], step[2]);
        let inner = d0 >= 0
            && d1 <= i64::from(DEPTH_MAX)
            && u0 >= 0
            && v0 >= 0
            && u1 < (tw as i64).saturating_sub(1) << 16
            && v1 < (th as i64).saturating_sub(1) << 16;
        let not_mask = if mask { 0 } else { DEPTH_NONE };
        if inner {
            let written = if mask {
                run_inner::<true>(ds, ms, is, tex, tw, acc, step)
            } else {
                run_inner::<false>(ds, ms, is, tex, tw, acc, step)
            };
            self.written = self.written.saturating_add(written);
            return;
        }
        let mut acc = acc;
        let mut written = 0u32;
        for ((slot, m), p) in ds.iter_mut().zip(ms.iter_mut()).zip(is.iter_mut()) {
            let d = (acc[0] >> RUN_SHIFT).clamp(0, i64::from(DEPTH_MAX)) as u32;
            if d < *slot {
                *slot = d;
                *m = d | not_mask;
                *p = sample_bilinear(tex, tw, th, acc[1] >> RUN_SHIFT, acc[2] >> RUN_SHIFT);
                written = written.wrapping_add(1);
            }
            acc = [
                acc[0].wrapping_add(step[0]),
                acc[1].wrapping_add(step[1]),
                acc[2].wrapping_add(step[2]),
            ];
        }
        self.written = self.written.saturating_add(written);
    }
}

/// The depth-test loop of a run whose depths lie in `0..=DEPTH_MAX` and whose
/// texture coordinates lie inside the texture by one texel (see `put_run`); a
/// function of its own so its state stays in registers. Returns the pixels written.
#[inline(never)]
#[allow(
    clippy::cast_possible_truncation,
    reason = "an inner run's depth is within 0..=DEPTH_MAX (checked by put_run before it calls this)"
)]
fn run_inner<const MASK: bool>(
    ds: &mut [u32],
    ms: &mut [u32],
    is: &mut [u8],
    tex: &[u8],
    tw: usize,
    acc: [i64; 3],
    step: [i64; 3],
) -> u32 {
    let [mut z, mut u, mut v] = acc;
    let [sz, su, sv] = step;
    // The caller guarantees tw ≤ MAX_TEXTURE_DIM (map validation); the min tells the compiler.
    let tw = tw.min(crate::config::MAX_TEXTURE_DIM);
    let mut written = 0u32;
    for ((slot, m), p) in ds.iter_mut().zip(ms.iter_mut()).zip(is.iter_mut()) {
        let d = (z >> RUN_SHIFT) as u32;
        if d < *slot {
            *slot = d;
            *m = if MASK { d } else { DEPTH_NONE };
            *p = sample_inner(tex, tw, u, v);
            // At most MAX_RENDER_PX per run.
            written = written.wrapping_add(1);
        }
        // The caller bounds the accumulators (|acc| < 2^58): no i64 overflow.
        z = z.wrapping_add(sz);
        u = u.wrapping_add(su);
        v = v.wrapping_add(sv);
    }
    written
}

/// Fractional bits of the run accumulators handed to [`PixelSink::put_run`].
const RUN_SHIFT: u32 = 16;
// `run_inner` hands the 16.16 texture accumulators to `sample_inner` as 32.32.
const _: () = assert!(RUN_SHIFT == 16);
/// Perspective division is exact at every `SEG`-th absolute pixel column and
/// linear in between (16.16 / depth-format fixed point): one division per 8 pixels.
const SEG_SHIFT: u32 = 3;
const SEG: i64 = 1 << SEG_SHIFT;
/// A segment is interpolated linearly only when its depth changes by at most 1/64.
const LINEAR_MAX_DZ_INV: i64 = 64;
/// Texture coordinates are clamped to ±2^20 texture pixels before fixed-point
/// conversion (beyond the texture they sample the edge texel anyway).
const UV_LIMIT: f32 = crate::map::MAX_UV_PX;

/// Exact depth and texture coordinates at one pixel; `None` where the triangle's
/// plane is beyond `RASTER_FAR_M` or behind the camera (possible only outside
/// the triangle, when a segment end is extrapolated).
#[inline]
#[allow(
    clippy::cast_possible_truncation,
    reason = "float-to-int `as` saturates; |u|, |v| ≤ UV_LIMIT and depth ≤ the far plane keep the Q16 values far inside i64"
)]
fn exact_at(xn: f32, inv_z_row: f32, u_row: f32, v_row: f32, it: &Interp) -> Option<[i64; 3]> {
    let inv_z = it.inv_z.x * xn + inv_z_row;
    // NaN fails this test too.
    let in_range = inv_z > 1.0 / RASTER_FAR_M;
    if !in_range {
        return None;
    }
    let z = 1.0 / inv_z;
    let u = ((it.u_over_z.x * xn + u_row) * z).clamp(-UV_LIMIT, UV_LIMIT);
    let v = ((it.v_over_z.x * xn + v_row) * z).clamp(-UV_LIMIT, UV_LIMIT);
    Some([
        (z * DEPTH_SCALE + 0.5) as i64,
        (u * 65536.0) as i64,
        (v * 65536.0) as i64,
    ])
}

#[derive(Clone, Copy, Debug)]
struct Plane {
    n: Vec3,
    d: f32,
}

impl Plane {
    #[inline]
    fn dist(&self, p: &Vec3) -> f32 {
        self.n.x * p.x + self.n.y * p.y + self.n.z * p.z + self.d
    }
}

/// Window geometry derived once per call. Everything that decides coverage or
/// values (clip region, snapping, edge functions, interpolation) is in absolute
/// image pixels and independent of the window, so a window render equals the
/// same crop of a larger render bit for bit; the window only bounds the spans.
struct Frame {
    /// Camera-from-world rotation as a matrix and translation (cheaper per
    /// vertex than the quaternion).
    rot: nalgebra::Matrix3<f32>,
    trans: Vec3,
    /// Window frustum (near plane and the four pixel-edge side planes) in the
    /// world frame, for tile culling and the per-triangle reject.
    world_planes: [Plane; 5],
    /// Per world plane: −`CULL_SLACK_M`·|n|, the tile test's threshold.
    world_slack: [f32; 5],
    /// Near plane and guard-band side planes, camera frame.
    clip_planes: [Plane; 5],
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    inv_fx: f32,
    inv_fy: f32,
    /// Window origin and size, pixels.
    wx: i64,
    wy: i64,
    w: i64,
    h: i64,
    /// Snapped coordinates are clamped to this box (28.4), a little outside the guard band.
    lim: [i64; 4],
    /// The image grown by the guard band (x0, y0, x1, y1 in pixels), independent
    /// of the window: triangles projecting inside it may be interpolated linearly.
    image_guard: [f32; 4],
}

/// Side planes through the camera centre keeping pixel columns `u0..=u1` and rows
/// `v0..=v1` (absolute pixel coordinates): fx·X − (u0 − cx)·Z ≥ 0 etc.
fn side_planes(cam: &Camera, u0: f32, u1: f32, v0: f32, v1: f32) -> [Plane; 4] {
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
    fn new(cam: &Camera, world_from_cam: &Pose, window: Rect) -> Self {
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
    fn box_visible(&self, min: &Vec3, max: &Vec3) -> bool {
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
fn clip_poly(
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

/// Perspective-correct interpolation of one triangle: 1/Z, u/Z and v/Z are
/// linear in the normalized image coordinates r = (x', y', 1), with
/// x' = (U − cx)/fx for absolute pixel column U. Derived from the unclipped
/// triangle in the camera frame, so clipping and windowing do not change values.
#[derive(Clone, Copy, Debug)]
struct Interp {
    inv_z: Vec3,
    u_over_z: Vec3,
    v_over_z: Vec3,
}

impl Interp {
    /// `None` for a degenerate triangle or one whose plane passes through the camera centre.
    #[allow(
        clippy::arithmetic_side_effects,
        reason = "f32 vector arithmetic (nalgebra); no integer operation"
    )]
    fn new(p: &[Vec3; 3], uv: &[[f32; 2]; 3]) -> Option<Self> {
        let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
        let n = e1.cross(&e2);
        let nn = n.dot(&n);
        let d = n.dot(&p[0]);
        if !(nn > 0.0 && d != 0.0 && nn.is_finite() && d.is_finite()) {
            return None;
        }
        // Z along ray r: Z = d / (n·r), so 1/Z = (n/d)·r.
        let k = n / d;
        // Attribute a = a0 + G·(P − P0) with G = ((a1−a0)(e2×n) + (a2−a0)(n×e1)) / |n|²;
        // a/Z = G·r + (a0 − G·P0)·(1/Z).
        let (b, c) = (e2.cross(&n), n.cross(&e1));
        let lin = |a0: f32, a1: f32, a2: f32| -> Vec3 {
            let g = (b * (a1 - a0) + c * (a2 - a0)) / nn;
            g + k * (a0 - g.dot(&p[0]))
        };
        let it = Self {
            inv_z: k,
            u_over_z: lin(uv[0][0], uv[1][0], uv[2][0]),
            v_over_z: lin(uv[0][1], uv[1][1], uv[2][1]),
        };
        let finite = |v: &Vec3| v.x.is_finite() && v.y.is_finite() && v.z.is_finite();
        (finite(&it.inv_z) && finite(&it.u_over_z) && finite(&it.v_over_z)).then_some(it)
    }
}

/// A clipped polygon corner in absolute 28.4 fixed-point pixel coordinates.
#[derive(Clone, Copy, Debug, Default)]
struct ScreenVert {
    x: i64,
    y: i64,
}

#[inline]
fn floor_div(n: i64, d: i64) -> i64 {
    // Callers divide by a non-zero edge-function step well inside i64; the
    // wrapping forms only keep a zero divisor or `i64::MIN / −1` from panicking.
    let q = n.checked_div(d).unwrap_or(0);
    if n.checked_rem(d).unwrap_or(0) != 0 && ((n < 0) != (d < 0)) {
        q.wrapping_sub(1)
    } else {
        q
    }
}

#[inline]
fn ceil_div(n: i64, d: i64) -> i64 {
    floor_div(n.wrapping_neg(), d).wrapping_neg()
}

/// Which bound an edge puts on a row's pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Side {
    /// `A > 0`: the first covered column.
    Left,
    /// `A < 0`: the last covered column.
    Right,
    /// `A = 0`: the whole row is in or out.
    #[default]
    Flat,
}

/// One edge `E(x, y) = A·x + B·y + C` (owner offset `t`) of [`fill_polygon`],
/// walked row by row without a division per row. With `k = B·y + C`, the
/// pixel centre `x` is inside when `A·x ≥ t − k`: for `A > 0` from
/// `x ≥ ⌈(t − k)/A⌉`, for `A < 0` up to `x ≤ ⌊(t − k)/A⌋`, for `A = 0` on the
/// whole row when `k ≥ t`. Each bound is kept as `q = ⌊m / d⌋` with
/// `m = q·d + r`, `0 ≤ r < d = |A|`, where `m` moves by a fixed `δ` per row:
/// `m = t − k + A − 1` (`δ = −B`) on the left, `m = k − t` (`δ = B`) on the
/// right, so a row's step is `q += ⌊δ/d⌋`, `r += δ mod d` and one carry. The
/// same integers as the per-row divisions: one division per edge, not per row.
/// (`A = 0` keeps `m = k − t`, `δ = B`.) Magnitudes stay below 2^42 (edge
/// terms < 2^40, rows within the guard band), so the wrapping forms never wrap.
#[derive(Clone, Copy, Debug, Default)]
struct EdgeWalk {
    side: Side,
    q: i64,
    r: i64,
    d: i64,
    dq: i64,
    dr: i64,
    /// `A = 0`: `k − t` of the current row, and its step `B`.
    m: i64,
    b: i64,
}

impl EdgeWalk {
    fn new((a, b, c, t): (i64, i64, i64, i64), py: i64) -> Self {
        let k = b.wrapping_mul(py).wrapping_add(c);
        if a == 0 {
            return Self {
                side: Side::Flat,
                m: k.wrapping_sub(t),
                b,
                ..Self::default()
            };
        }
        let (side, d, m, delta) = if a > 0 {
            let m = t.wrapping_sub(k).wrapping_add(a).wrapping_sub(1);
            (Side::Left, a, m, b.wrapping_neg())
        } else {
            (Side::Right, a.wrapping_neg(), k.wrapping_sub(t), b)
        };
        let q = floor_div(m, d);
        let dq = floor_div(delta, d);
        Self {
            side,
            q,
            r: m.wrapping_sub(q.wrapping_mul(d)),
            d,
            dq,
            dr: delta.wrapping_sub(dq.wrapping_mul(d)),
            m: 0,
            b: 0,
        }
    }

    /// On to the next row.
    #[inline]
    fn step(&mut self) {
        if self.side == Side::Flat {
            self.m = self.m.wrapping_add(self.b);
            return;
        }
        self.q = self.q.wrapping_add(self.dq);
        self.r = self.r.wrapping_add(self.dr);
        if self.r >= self.d {
            self.r = self.r.wrapping_sub(self.d);
            self.q = self.q.wrapping_add(1);
        }
    }
}

/// Fill one clipped, snapped convex polygon (`v[..n]`, n ≤ [`MAX_CLIP_VERTS`]).
/// Coverage is exact integer arithmetic on 28.4 coordinates (magnitudes < 2^18,
/// edge terms < 2^40 in i64): a pixel is covered when it is inside every edge's
/// half-plane, so one polygon covers a pixel at most once even when snapping
/// made it slightly non-convex (a reflex corner then only trims a sliver). The
/// sink is called once per covered pixel inside the window.
#[allow(
    clippy::cast_possible_truncation,
    reason = "row and span lengths are pixel offsets inside the window (≤ MAX_RENDER_PX²), formed with wrapping arithmetic on coordinates bounded by the guard band"
)]
fn fill_polygon<S: PixelSink>(
    v: &[ScreenVert; MAX_CLIP_VERTS],
    n: usize,
    make_attr: impl FnOnce() -> Option<Attr>,
    mask: bool,
    frame: &Frame,
    stats: &mut RenderStats,
    sink: &mut S,
) {
    let n = n.min(MAX_CLIP_VERTS);
    if n < 3 {
        return;
    }
    // Twice the signed area (shoelace), for the orientation.
    let mut area = 0i64;
    let (mut minx, mut maxx, mut miny, mut maxy) = (i64::MAX, i64::MIN, i64::MAX, i64::MIN);
    // Corner pairs (v0, v1), (v1, v2), …, (v[n−1], v0).
    let pairs = || v.iter().take(n).zip(v.iter().take(n).cycle().skip(1));
    // Wrapping arithmetic in the polygon setup: snapped coordinates lie within
    // the frame's guard band (|x|, |y| < 2^18 in 28.4), so products stay below
    // 2^40 and nothing wraps; the wrapping forms only remove the panic paths.
    for (&p, &q) in pairs() {
        area = area.wrapping_add(p.x.wrapping_mul(q.y).wrapping_sub(q.x.wrapping_mul(p.y)));
        minx = minx.min(p.x);
        maxx = maxx.max(p.x);
        miny = miny.min(p.y);
        maxy = maxy.max(p.y);
    }
    if area == 0 {
        return;
    }
    let s = i64::from(1u32 << SUBPIXEL_BITS);
    let x_lo = ceil_div(minx, s).max(frame.wx);
    let x_hi = floor_div(maxx, s).min(frame.wx.wrapping_add(frame.w).wrapping_sub(1));
    let y_lo = ceil_div(miny, s).max(frame.wy);
    let y_hi = floor_div(maxy, s).min(frame.wy.wrapping_add(frame.h).wrapping_sub(1));
    if x_lo > x_hi || y_lo > y_hi {
        return;
    }
    // Attribute setup only for polygons that reach a pixel centre of the window.
    let Some(attr) = make_attr() else {
        return;
    };
    let attr = &attr;
    stats.triangles_drawn = stats.triangles_drawn.saturating_add(1);
    if matches!(attr, Attr::Affine(_)) {
        stats.triangles_linear = stats.triangles_linear.saturating_add(1);
    }
    // Edge (p→q), walked counter-clockwise in the image (area > 0):
    // E(px,py) = A·px + B·py + C, positive inside.
    let mut edges = [(0i64, 0i64, 0i64, 0i64); MAX_CLIP_VERTS];
    let mut ne = 0;
    for (&p, &q) in pairs() {
        let (mut p, mut q) = (p, q);
        if area < 0 {
            core::mem::swap(&mut p, &mut q);
        }
        if p.x == q.x && p.y == q.y {
            continue;
        }
        let (dx, dy) = (q.x.wrapping_sub(p.x), q.y.wrapping_sub(p.y));
        let a = s.wrapping_mul(dy).wrapping_neg();
        let b = s.wrapping_mul(dx);
        let c = dy.wrapping_mul(p.x).wrapping_sub(dx.wrapping_mul(p.y));
        // Owner rule: a pixel centre on the edge is inside iff the centre moved by
        // (ε, ε²) is, i.e. A > 0 or (A == 0 and B > 0). Exactly one of two
        // polygons sharing the edge (opposite directions) owns it.
        let t = if a > 0 || (a == 0 && b > 0) { 0 } else { 1 };
        if let Some(e) = edges.get_mut(ne) {
            *e = (a, b, c, t);
            // `get_mut` succeeded: ne < MAX_CLIP_VERTS.
            ne = usize::wrapping_add(ne, 1);
        }
    }
    // `ne` never exceeds the array; were it to, an empty edge list would fill the
    // whole bounding box, so draw nothing instead.
    let Some(edges) = edges.get(..ne) else {
        return;
    };
    let (wx, wy, w) = (frame.wx, frame.wy, frame.w);
    let mut walks = [EdgeWalk::default(); MAX_CLIP_VERTS];
    for (wk, &e) in walks.iter_mut().zip(edges) {
        *wk = EdgeWalk::new(e, y_lo);
    }
    let walks = walks.get_mut(..edges.len()).unwrap_or(&mut []);
    for py in y_lo..=y_hi {
        let mut xl = x_lo;
        let mut xr = x_hi;
        let mut empty = false;
        for wk in walks.iter_mut() {
            match wk.side {
                Side::Left => xl = xl.max(wk.q),
                Side::Right => xr = xr.min(wk.q),
                Side::Flat => empty |= wk.m < 0,
            }
            wk.step();
        }
        if empty || xl > xr {
            continue;
        }
        stats.spans = stats.spans.saturating_add(1);
        let row = py.wrapping_sub(wy).wrapping_mul(w).wrapping_sub(wx) as usize;
        match attr {
            Attr::Affine(af) => {
                // Exact integer plane: the value at pixel x is the same whichever
                // pixel the span starts at. Bounds: |base| ≤ 2^53, |gradient| ≤ 2^40,
                // pixel offsets < 2^15, so every accumulator stays below 2^57.
                let (dx, dy) = (xl.wrapping_sub(af.ax), py.wrapping_sub(af.ay));
                let mut acc = af.base;
                for ((a, gx), gy) in acc.iter_mut().zip(af.gx).zip(af.gy) {
                    *a = a
                        .wrapping_add(gx.wrapping_mul(dx))
                        .wrapping_add(gy.wrapping_mul(dy));
                }
                sink.put_run(
                    row.wrapping_add(xl as usize),
                    xr.wrapping_sub(xl).wrapping_add(1) as usize,
                    acc,
                    af.gx,
                    mask,
                );
            }
            Attr::Perspective(it) => fill_span_perspective(it, frame, py, xl, xr, row, mask, sink),
        }
    }
}

/// Fill pixels `xl..=xr` of row `py` with perspective-correct values: exact at
/// every `SEG`-th absolute column, linear in between where depth changes little.
#[allow(clippy::too_many_arguments)]
#[inline]
#[allow(
    clippy::cast_possible_truncation,
    reason = "pixel offsets inside the window (≤ MAX_RENDER_PX²); depth clamped to 0..=DEPTH_MAX before the cast"
)]
fn fill_span_perspective<S: PixelSink>(
    it: &Interp,
    frame: &Frame,
    py: i64,
    xl: i64,
    xr: i64,
    row: usize,
    mask: bool,
    sink: &mut S,
) {
    let yn = (py as f32 - frame.cy) * frame.inv_fy;
    let row_w = it.inv_z.y * yn + it.inv_z.z;
    let row_u = it.u_over_z.y * yn + it.u_over_z.z;
    let row_v = it.v_over_z.y * yn + it.v_over_z.z;
    let at = |x: i64| {
        exact_at(
            (x as f32 - frame.cx) * frame.inv_fx,
            row_w,
            row_u,
            row_v,
            it,
        )
    };
    let mut px = xl;
    // The exact values at the end of one segment are those at the start of the
    // next (same column, same arithmetic): evaluated once per boundary.
    let mut next: Option<(i64, Option<[i64; 3]>)> = None;
    // Bounded: each pass advances px to the next segment boundary (at most
    // w / SEG + 2 passes per span).
    while px <= xr {
        let s0 = px & !(SEG - 1);
        let s1 = s0.saturating_add(SEG);
        let end = xr.min(s1.saturating_sub(1));
        let e0 = match next {
            Some((col, e)) if col == s0 => e,
            _ => at(s0),
        };
        let e1 = at(s1);
        next = Some((s1, e1));
        match (e0, e1) {
            // Linear depth and UVs deviate from perspective-correct values by about
            // δ²/4 of depth with δ the relative change of depth over the segment;
            // segments with δ > 1/64 are evaluated exactly at every pixel instead.
            (Some(a), Some(b))
                if a[0] >= 0
                    && b[0]
                        .wrapping_sub(a[0])
                        .unsigned_abs()
                        .saturating_mul(LINEAR_MAX_DZ_INV as u64)
                        <= a[0] as u64 =>
            {
                // Bounded as documented below: the wrapping forms never wrap.
                let d = [
                    b[0].wrapping_sub(a[0]),
                    b[1].wrapping_sub(a[1]),
                    b[2].wrapping_sub(a[2]),
                ];
                let k = px.wrapping_sub(s0);
                // acc / SEG is the linear interpolation between the segment ends,
                // rescaled to RUN_SHIFT fractional bits (|a| ≤ 2^37, |d| ≤ 2^38:
                // below 2^54 after the shift).
                let sh = RUN_SHIFT - SEG_SHIFT;
                let lin =
                    |a: i64, d: i64| a.wrapping_mul(SEG).wrapping_add(d.wrapping_mul(k)) << sh;
                let acc = [lin(a[0], d[0]), lin(a[1], d[1]), lin(a[2], d[2])];
                sink.put_run(
                    row.wrapping_add(px as usize),
                    end.wrapping_sub(px).wrapping_add(1) as usize,
                    acc,
                    [d[0] << sh, d[1] << sh, d[2] << sh],
                    mask,
                );
            }
            _ => {
                for x in px..=end {
                    let e = at(x).unwrap_or([i64::from(DEPTH_MAX), 0, 0]);
                    sink.put(Frag {
                        idx: row.wrapping_add(x as usize),
                        depth: e[0].clamp(0, i64::from(DEPTH_MAX)) as u32,
                        u_q16: e[1],
                        v_q16: e[2],
                        mask,
                    });
                }
            }
        }
        let Some(next_px) = end.checked_add(1) else {
            break;
        };
        px = next_px;
    }
}

/// Project a camera-frame point to absolute image pixels.
#[inline]
fn project(frame: &Frame, p: &Vec3) -> (f32, f32) {
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
fn snap(frame: &Frame, (u, v): (f32, f32)) -> ScreenVert {
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

/// How depth and texture coordinates are evaluated over one triangle.
enum Attr {
    /// Linear in the image (exact integer plane), for triangles of small depth range.
    Affine(Affine),
    /// Perspective-correct (1/Z, u/Z, v/Z linear in the image).
    Perspective(Interp),
}

/// A triangle is interpolated linearly in the image when its depth range δ
/// (relative to its nearest corner) is at most 1/`AFFINE_MAX_DZ_INV`: depth then
/// deviates from the perspective-correct value by at most δ²/4 ≤ 2.5·10⁻⁴ of depth.
const AFFINE_MAX_DZ_INV: f32 = 32.0;
/// ... and δ times its texture extent (texels) is at most 1/`AFFINE_MAX_UV_INV`:
/// texture coordinates then deviate by at most δ·extent/4 ≤ 1/32 texel.
const AFFINE_MAX_UV_INV: f32 = 8.0;
/// Largest gradient (depth units or 2⁻¹⁶ texel per pixel) of a linear triangle,
/// so the integer plane stays far from i64 overflow.
const AFFINE_MAX_GRAD: f32 = (1u32 << 24) as f32;

/// Depth (depth format + ½ for rounding) and texture coordinates (16.16) as an
/// exact integer plane over absolute pixels, with `RUN_SHIFT` fractional bits:
/// value(x, y) = (base + gx·(x − ax) + gy·(y − ay)) >> RUN_SHIFT.
#[derive(Clone, Copy, Debug)]
struct Affine {
    base: [i64; 3],
    gx: [i64; 3],
    gy: [i64; 3],
    ax: i64,
    ay: i64,
}

impl Affine {
    /// The plane through the three projected corners `s` carrying their depth and
    /// texture coordinates; `None` when the triangle is not eligible (depth range or
    /// texture extent too large, corner near or behind the camera or outside the
    /// image's guard band, degenerate projection, gradient too large). Depends on
    /// the triangle and the camera only, never on the window.
    #[allow(
        clippy::arithmetic_side_effects,
        clippy::cast_possible_truncation,
        reason = "float-to-int `as` saturates (NaN gives 0); gradients are bounded by AFFINE_MAX_GRAD and the base is clamped to ±2^53 right after"
    )]
    fn new(frame: &Frame, p: &[Vec3; 3], s: &[(f32, f32); 3], uv: &[[f32; 2]; 3]) -> Option<Self> {
        let [p0, p1, p2] = p;
        let [s0, s1, s2] = *s;
        let [[u0, v0], [u1, v1], [u2, v2]] = *uv;
        let zmin = p0.z.min(p1.z).min(p2.z);
        let zmax = p0.z.max(p1.z).max(p2.z);
        let dz = zmax - zmin;
        let extent =
            (u0.max(u1).max(u2) - u0.min(u1).min(u2)).max(v0.max(v1).max(v2) - v0.min(v1).min(v2));
        let [gx0, gy0, gx1, gy1] = frame.image_guard;
        let inside = s
            .iter()
            .all(|&(x, y)| x >= gx0 && x <= gx1 && y >= gy0 && y <= gy1);
        // NaN fails these comparisons.
        let ok = zmin >= RASTER_NEAR_M
            && dz * AFFINE_MAX_DZ_INV <= zmin
            && dz * extent * AFFINE_MAX_UV_INV <= zmin
            && inside;
        if !ok {
            return None;
        }
        let (x1, y1) = (s1.0 - s0.0, s1.1 - s0.1);
        let (x2, y2) = (s2.0 - s0.0, s2.1 - s0.1);
        let det = x1 * y2 - x2 * y1;
        if det == 0.0 {
            return None;
        }
        let inv_det = 1.0 / det;
        let ax = libm::roundf(s0.0);
        let ay = libm::roundf(s0.1);
        let (ox, oy) = (ax - s0.0, ay - s0.1);
        let val = |q: &Vec3, u: f32, v: f32| -> [f32; 3] {
            [
                q.z * DEPTH_SCALE + 0.5,
                u.clamp(-UV_LIMIT, UV_LIMIT) * 65536.0,
                v.clamp(-UV_LIMIT, UV_LIMIT) * 65536.0,
            ]
        };
        let (a0, a1, a2) = (val(p0, u0, v0), val(p1, u1, v1), val(p2, u2, v2));
        let scale = (1u32 << RUN_SHIFT) as f32;
        let lim = (1u64 << 53) as f32;
        let mut out = Self {
            base: [0; 3],
            gx: [0; 3],
            gy: [0; 3],
            ax: ax as i64,
            ay: ay as i64,
        };
        let outs = out.base.iter_mut().zip(&mut out.gx).zip(&mut out.gy);
        for ((((base_q, gx_q), gy_q), c0), (c1, c2)) in outs.zip(a0).zip(a1.into_iter().zip(a2)) {
            let (d1, d2) = (c1 - c0, c2 - c0);
            let gx = (d1 * y2 - d2 * y1) * inv_det;
            let gy = (d2 * x1 - d1 * x2) * inv_det;
            // NaN fails the comparison.
            if !(gx.abs() <= AFFINE_MAX_GRAD && gy.abs() <= AFFINE_MAX_GRAD) {
                return None;
            }
            let base = c0 + gx * ox + gy * oy;
            *base_q = ((base * scale) as i64).clamp(-(lim as i64), lim as i64);
            *gx_q = (gx * scale) as i64;
            *gy_q = (gy * scale) as i64;
        }
        Some(out)
    }
}

/// Clip and fill one triangle given in the camera frame (not rejected against
/// the window frustum by `rasterize`).
fn draw_triangle<S: PixelSink>(
    frame: &Frame,
    p: [Vec3; 3],
    uv: &[[f32; 2]; 3],
    mask: bool,
    stats: &mut RenderStats,
    sink: &mut S,
) {
    let mut screen = [ScreenVert::default(); MAX_CLIP_VERTS];
    let clip = frame
        .clip_planes
        .iter()
        .any(|pl| p.iter().any(|c| pl.dist(c) < 0.0));
    if clip {
        let mut poly = [Vec3::zeros(); MAX_CLIP_VERTS];
        let mut tmp = [Vec3::zeros(); MAX_CLIP_VERTS];
        poly[..3].copy_from_slice(&p);
        let mut n = 3;
        for pl in &frame.clip_planes {
            if poly.iter().take(n).any(|c| pl.dist(c) < 0.0) {
                n = clip_poly(&poly, n, pl, &mut tmp);
                poly = tmp;
                if n < 3 {
                    return;
                }
            }
        }
        for (sv, c) in screen.iter_mut().zip(poly.iter().take(n)) {
            *sv = snap(frame, project(frame, c));
        }
        // The choice of interpolation depends on the triangle only (a triangle
        // inside the image's guard band is clipped only by rounding), so it is the
        // same whatever window, and hence guard band, the call uses.
        let make = || attributes(frame, &p, &p.map(|c| project(frame, &c)), uv);
        fill_polygon(&screen, n, make, mask, frame, stats, sink);
    } else {
        let s = p.map(|c| project(frame, &c));
        for (sv, c) in screen.iter_mut().zip(s) {
            *sv = snap(frame, c);
        }
        fill_polygon(
            &screen,
            3,
            || attributes(frame, &p, &s, uv),
            mask,
            frame,
            stats,
            sink,
        );
    }
}

/// Depth and texture interpolation of the triangle `p` (camera frame) with
/// projected corners `s`: linear when [`Affine::new`] accepts it, perspective-correct
/// otherwise; `None` for a triangle neither can interpolate.
fn attributes(
    frame: &Frame,
    p: &[Vec3; 3],
    s: &[(f32, f32); 3],
    uv: &[[f32; 2]; 3],
) -> Option<Attr> {
    match Affine::new(frame, p, s, uv) {
        Some(af) => Some(Attr::Affine(af)),
        None => Interp::new(p, uv).map(Attr::Perspective),
    }
}

#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "2·MAX_IMAGE_DIM and MAX_RENDER_PX are small constants that fit i32 and u32"
)]
fn check_inputs(world_from_cam: &Pose, window: Rect) -> Result<(), FailureCode> {
    let lim = 2 * MAX_IMAGE_DIM as i32;
    let window_ok = (1..=MAX_RENDER_PX as u32).contains(&window.w)
        && (1..=MAX_RENDER_PX as u32).contains(&window.h)
        && (-lim..=lim).contains(&window.x)
        && (-lim..=lim).contains(&window.y);
    if !window_ok {
        return Err(FailureCode::RasterWindowInvalid);
    }
    // `Camera` is a checked type (built only by `Camera::new`), so its image size
    // and intrinsics are within the bounds that `Frame` turns into fixed-point
    // limits (see `fill_polygon`'s overflow budget); no per-call re-check.
    if !world_from_cam.is_finite() {
        return Err(FailureCode::RasterPoseInvalid);
    }
    Ok(())
}

/// Walk the visible tiles and triangles, calling `sink` for every covered pixel.
#[allow(
    clippy::arithmetic_side_effects,
    reason = "f32 vector arithmetic (nalgebra); no integer operation"
)]
pub(crate) fn rasterize<S: PixelSink>(
    map: &MapView,
    cam: &Camera,
    world_from_cam: &Pose,
    window: Rect,
    sink: &mut S,
) -> Result<RenderStats, FailureCode> {
    check_inputs(world_from_cam, window)?;
    let frame = Frame::new(cam, world_from_cam, window);
    let mut stats = RenderStats::default();
    let to_cam = |p: Vec3| frame.rot * p + frame.trans;
    for k in 0..map.tile_count() {
        let Some(tile) = map.tile(k) else { break };
        if tile.triangle_count == 0 {
            continue;
        }
        stats.tiles_tested = stats.tiles_tested.saturating_add(1);
        if !frame.box_visible(&tile.min, &tile.max) {
            continue;
        }
        stats.tiles_visible = stats.tiles_visible.saturating_add(1);
        let end = tile.first_triangle.saturating_add(tile.triangle_count);
        for i in tile.first_triangle..end.min(map.triangle_count()) {
            stats.triangles_tested = stats.triangles_tested.saturating_add(1);
            let Some(w) = map.triangle_vertices(i) else {
                break;
            };
            // Reject triangles with all corners beyond one side plane of the window
            // (tested in the world frame, before the transform) or all in front of
            // the near plane. The side planes lie half a pixel outside the window's
            // outer pixel centres, far beyond rounding, so no covered pixel is lost.
            if frame
                .world_planes
                .iter()
                .skip(1)
                .any(|pl| w.iter().all(|c| pl.dist(c) < 0.0))
            {
                continue;
            }
            let p = w.map(to_cam);
            if p.iter().all(|c| c.z < RASTER_NEAR_M) {
                continue;
            }
            let Some(t) = map.triangle(i) else { break };
            draw_triangle(&frame, p, &t.uv, t.mask, &mut stats, sink);
        }
    }
    Ok(stats)
}

/// Bilinear sample of a texture (stride = width) at texture pixel `(u, v)`,
/// clamped to the edge texels; 8-bit weights, rounded. 32-bit arithmetic: the map
/// validates `1 ≤ tw, th ≤ MAX_TEXTURE_DIM = 2^14`, so clamped coordinates are
/// below 2^30 in 16.16, texel indices below 2^28, and every weighted sum below
/// 255·256·256 + 2^15 < 2^24 (the wrapping operations never wrap).
const _: () = assert!(crate::config::MAX_TEXTURE_DIM <= 1 << 14);

#[inline(always)]
#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "coordinates clamped to the texture (≤ MAX_TEXTURE_DIM = 2^14, asserted above) before the casts; x0 + 1, y0 + 1 < 2^15; the rounded lerp is ≤ 255"
)]
fn sample_bilinear(tex: &[u8], tw: usize, th: usize, u_q16: i64, v_q16: i64) -> u8 {
    // max/min rather than clamp: no bounds-order check per pixel.
    let u = u_q16.max(0).min((tw as i64).saturating_sub(1) << 16) as u32;
    let v = v_q16.max(0).min((th as i64).saturating_sub(1) << 16) as u32;
    let (x0, y0) = ((u >> 16) as usize, (v >> 16) as usize);
    let fx = (u >> 8) & 0xFF;
    let fy = (v >> 8) & 0xFF;
    let dx = usize::from(x0 + 1 < tw);
    let dy = if y0 + 1 < th { tw } else { 0 };
    let i = y0.wrapping_mul(tw).wrapping_add(x0);
    let px = |k: usize| u32::from(tex.get(k).copied().unwrap_or(0));
    let top = lerp8(px(i), px(i.wrapping_add(dx)), fx);
    let j = i.wrapping_add(dy);
    let bot = lerp8(px(j), px(j.wrapping_add(dx)), fx);
    (lerp8(top, bot, fy).wrapping_add(1 << 15) >> 16) as u8
}

/// [`sample_bilinear`] for a point at least one texel inside the right and bottom
/// edges, given as 32.32 fixed-point texel coordinates `u`, `v` with
/// `0 ≤ u < (tw − 1)·2^32`, `0 ≤ v < (th − 1)·2^32` and `tw ≤ MAX_TEXTURE_DIM`:
/// same result, without the clamps and with one bounds check for the four texels.
#[inline(always)]
#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "texel indices < 2^28 (texture ≤ 2^14 × 2^14, asserted above); the rounded lerp is ≤ 255"
)]
fn sample_inner(tex: &[u8], tw: usize, u: i64, v: i64) -> u8 {
    // The masks are the identity under the preconditions; they let the compiler
    // prove that the index arithmetic below cannot overflow.
    const MAX: usize = crate::config::MAX_TEXTURE_DIM - 1;
    let (x0, y0) = ((u >> 32) as usize & MAX, (v >> 32) as usize & MAX);
    let fx = ((u >> 24) & 0xFF) as u32;
    let fy = ((v >> 24) & 0xFF) as u32;
    let i = y0 * tw + x0;
    let Some((top, bottom)) = tex.get(i..i + tw + 2).and_then(|q| q.split_at_checked(tw)) else {
        return 0;
    };
    let (&[a, b, ..], &[c, d]) = (top, bottom) else {
        return 0;
    };
    let top = lerp8(u32::from(a), u32::from(b), fx);
    let bot = lerp8(u32::from(c), u32::from(d), fx);
    (lerp8(top, bot, fy).wrapping_add(1 << 15) >> 16) as u8
}

/// a·(256 − f) + b·f for f ≤ 256, computed as 256·a + (b − a)·f with wrapping
/// 32-bit operations: the exact result is below 2^24, so the wrapped
/// intermediate (b − a may be negative) gives it exactly.
#[inline(always)]
fn lerp8(a: u32, b: u32, f: u32) -> u32 {
    (a << 8).wrapping_add(b.wrapping_sub(a).wrapping_mul(f))
}

/// Render `window` (a pixel rectangle of the full virtual image of `cam`) of the
/// map seen from `world_from_cam` into `target`.
///
/// The three buffers are cleared over `w·h` (intensity 0, depths [`DEPTH_NONE`])
/// and then filled with a strict-less depth test; ties keep the first surface
/// drawn (deterministic map order).
///
/// # Errors
/// [`FailureCode::RasterWindowInvalid`] (empty, above [`MAX_RENDER_PX`], origin
/// beyond ±2·`MAX_IMAGE_DIM`), [`FailureCode::RasterBufferTooSmall`],
/// [`FailureCode::RasterPoseInvalid`] (non-finite pose),
/// [`FailureCode::RasterNothingVisible`] (no pixel written; buffers are cleared).
pub fn render_window(
    map: &MapView,
    cam: &Camera,
    world_from_cam: &Pose,
    window: Rect,
    target: &mut Target,
) -> Result<RenderStats, FailureCode> {
    check_inputs(world_from_cam, window)?;
    let n = (window.w as usize).saturating_mul(window.h as usize);
    let (Some(inten), Some(depth), Some(mdepth)) = (
        target.intensity.get_mut(..n),
        target.depth.get_mut(..n),
        target.mask_depth.get_mut(..n),
    ) else {
        return Err(FailureCode::RasterBufferTooSmall);
    };
    inten.fill(0);
    depth.fill(DEPTH_NONE);
    mdepth.fill(DEPTH_NONE);
    let tex = map.texture();
    let (tw, th) = (tex.width(), tex.height());
    let mut sink = ZBuffer {
        intensity: inten,
        depth,
        mask_depth: mdepth,
        tex: map.texture_bytes(),
        tw,
        th,
        written: 0,
    };
    let mut stats = rasterize(map, cam, world_from_cam, window, &mut sink)?;
    let written = sink.written;
    stats.pixels_written = written;
    if written == 0 {
        return Err(FailureCode::RasterNothingVisible);
    }
    Ok(stats)
}

/// Form the template mask of paper §III-C from a rendered window.
///
/// Rule: pixel p is kept (255) when M̂ is the visible surface there
/// (`mask_depth[p] != DEPTH_NONE`), or when some pixel q within
/// [`TEMPLATE_MASK_RADIUS_PX`] (Chebyshev) has `mask_depth[q]` set and p lies
/// behind it by a depth discontinuity: `depth[p] > mask_depth[q] + J(q)` with
/// `J(q) = TEMPLATE_MASK_JUMP_M + mask_depth[q] / TEMPLATE_MASK_JUMP_REL_DIV`
/// (empty pixels count as infinitely far). These are background pixels at rock
/// silhouettes. Everything else is 0. Returns the number of kept pixels.
///
/// Bounds: O(w·h·(2r+1)) with separable minimum filters; one row buffer of
/// [`MAX_RENDER_PX`] `u32` on the stack. Invalid sizes (`w`, `h` outside
/// `1..=MAX_RENDER_PX` or a slice shorter than `w·h`) write nothing and return 0.
#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "w, h ≤ MAX_RENDER_PX are checked first (w·h and h − 1 are exact); JUMP_Q16 is a constant below 2^32"
)]
pub fn template_mask(depth: &[u32], mask_depth: &[u32], w: usize, h: usize, out: &mut [u8]) -> u32 {
    // Sizes first: w·h is formed only for sizes within the cap (no overflow).
    if !((1..=MAX_RENDER_PX).contains(&w) && (1..=MAX_RENDER_PX).contains(&h)) {
        return 0;
    }
    let n = w * h;
    let (Some(depth), Some(mdepth), Some(out)) =
        (depth.get(..n), mask_depth.get(..n), out.get_mut(..n))
    else {
        return 0;
    };
    const JUMP_Q16: u32 = (TEMPLATE_MASK_JUMP_M * (1u32 << DEPTH_FRAC_BITS) as f32) as u32;
    let r = TEMPLATE_MASK_RADIUS_PX;
    // Separable minimum filter of mask_depth over the (2r+1)² neighbourhood, one
    // output row at a time: column minimum, then row minimum (straight slice loops).
    let mut colmin = [DEPTH_NONE; MAX_RENDER_PX];
    let mut nbmin = [DEPTH_NONE; MAX_RENDER_PX];
    let (Some(colmin), Some(nbmin)) = (colmin.get_mut(..w), nbmin.get_mut(..w)) else {
        return 0;
    };
    let mut kept = 0u32;
    for y in 0..h {
        // w, h ≤ MAX_RENDER_PX (checked above): no row offset below can wrap.
        let row_of = |y: usize| y.wrapping_mul(w)..y.wrapping_add(1).wrapping_mul(w);
        let (y0, y1) = (y.saturating_sub(r), y.saturating_add(r).min(h - 1));
        colmin.fill(DEPTH_NONE);
        for yy in y0..=y1 {
            if let Some(row) = mdepth.get(row_of(yy)) {
                for (c, m) in colmin.iter_mut().zip(row) {
                    *c = (*c).min(*m);
                }
            }
        }
        nbmin.copy_from_slice(colmin);
        for d in 1..=r.min(w.saturating_sub(1)) {
            let (Some(right), Some(left)) = (colmin.get(d..), colmin.get(..w.wrapping_sub(d)))
            else {
                break;
            };
            for (n, c) in nbmin.iter_mut().zip(right) {
                *n = (*n).min(*c);
            }
            if let Some(tail) = nbmin.get_mut(d..) {
                for (n, c) in tail.iter_mut().zip(left) {
                    *n = (*n).min(*c);
                }
            }
        }
        let (Some(drow), Some(mrow), Some(orow)) = (
            depth.get(row_of(y)),
            mdepth.get(row_of(y)),
            out.get_mut(row_of(y)),
        ) else {
            break;
        };
        for (((o, d), own), m) in orow.iter_mut().zip(drow).zip(mrow).zip(nbmin.iter()) {
            // J grows with depth, so the minimum of mask_depth + J is J applied to the minimum.
            let thr = m
                .saturating_add(JUMP_Q16)
                .saturating_add(m / TEMPLATE_MASK_JUMP_REL_DIV);
            let keep = *own != DEPTH_NONE || (*m != DEPTH_NONE && *d > thr);
            *o = if keep { 255 } else { 0 };
            kept = kept.saturating_add(u32::from(keep));
        }
    }
    kept
}

#[cfg(test)]
mod tests;
