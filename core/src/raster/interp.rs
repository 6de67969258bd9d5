//! Depth and texture-coordinate interpolation over one triangle: an exact
//! integer plane in the image ([`Affine`]) for triangles of small depth range,
//! perspective-correct 1/Z, u/Z, v/Z otherwise ([`Interp`]).
//!
//! Input: the triangle's corners in the camera frame, their projections and
//! texture coordinates; output: an [`Attr`], or `None` for a triangle neither
//! form can interpolate. Depends on the triangle and the camera only, never on
//! the window. Fixed-point magnitudes are bounded below (see each item).

use super::depth::DEPTH_SCALE;
use super::frame::Frame;
use super::target::RUN_SHIFT;
use crate::config::{RASTER_FAR_M, RASTER_NEAR_M};
use crate::geom::Vec3;

/// Perspective division is exact at every `SEG`-th absolute pixel column and
/// linear in between (16.16 / depth-format fixed point): one division per 8 pixels.
pub(super) const SEG_SHIFT: u32 = 3;

pub(super) const SEG: i64 = 1 << SEG_SHIFT;

/// A segment is interpolated linearly only when its depth changes by at most 1/64.
pub(super) const LINEAR_MAX_DZ_INV: i64 = 64;

/// Texture coordinates are clamped to ±2^20 texture pixels before fixed-point
/// conversion (beyond the texture they sample the edge texel anyway).
pub(super) const UV_LIMIT: f32 = crate::map::MAX_UV_PX;

/// Exact depth and texture coordinates at one pixel; `None` where the triangle's
/// plane is beyond `RASTER_FAR_M` or behind the camera (possible only outside
/// the triangle, when a segment end is extrapolated).
#[inline]
#[allow(
    clippy::cast_possible_truncation,
    reason = "float-to-int `as` saturates; |u|, |v| ≤ UV_LIMIT and depth ≤ the far plane keep the Q16 values far inside i64"
)]
pub(super) fn exact_at(
    xn: f32,
    inv_z_row: f32,
    u_row: f32,
    v_row: f32,
    it: &Interp,
) -> Option<[i64; 3]> {
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

/// Perspective-correct interpolation of one triangle: 1/Z, u/Z and v/Z are
/// linear in the normalized image coordinates r = (x', y', 1), with
/// x' = (U − cx)/fx for absolute pixel column U. Derived from the unclipped
/// triangle in the camera frame, so clipping and windowing do not change values.
#[derive(Clone, Copy, Debug)]
pub(super) struct Interp {
    pub(super) inv_z: Vec3,
    pub(super) u_over_z: Vec3,
    pub(super) v_over_z: Vec3,
}

impl Interp {
    /// `None` for a degenerate triangle or one whose plane passes through the camera centre.
    #[allow(
        clippy::arithmetic_side_effects,
        reason = "f32 vector arithmetic (nalgebra); no integer operation"
    )]
    pub(super) fn new(p: &[Vec3; 3], uv: &[[f32; 2]; 3]) -> Option<Self> {
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

/// How depth and texture coordinates are evaluated over one triangle.
pub(super) enum Attr {
    /// Linear in the image (exact integer plane), for triangles of small depth range.
    Affine(Affine),
    /// Perspective-correct (1/Z, u/Z, v/Z linear in the image).
    Perspective(Interp),
}

/// A triangle is interpolated linearly in the image when its depth range δ
/// (relative to its nearest corner) is at most 1/`AFFINE_MAX_DZ_INV`: depth then
/// deviates from the perspective-correct value by at most δ²/4 ≤ 2.5·10⁻⁴ of depth.
pub(super) const AFFINE_MAX_DZ_INV: f32 = 32.0;

/// ... and δ times its texture extent (texels) is at most 1/`AFFINE_MAX_UV_INV`:
/// texture coordinates then deviate by at most δ·extent/4 ≤ 1/32 texel.
pub(super) const AFFINE_MAX_UV_INV: f32 = 8.0;

/// Largest gradient (depth units or 2⁻¹⁶ texel per pixel) of a linear triangle,
/// so the integer plane stays far from i64 overflow.
pub(super) const AFFINE_MAX_GRAD: f32 = (1u32 << 24) as f32;

/// Depth (depth format + ½ for rounding) and texture coordinates (16.16) as an
/// exact integer plane over absolute pixels, with `RUN_SHIFT` fractional bits:
/// value(x, y) = (base + gx·(x − ax) + gy·(y − ay)) >> RUN_SHIFT.
#[derive(Clone, Copy, Debug)]
pub(super) struct Affine {
    pub(super) base: [i64; 3],
    pub(super) gx: [i64; 3],
    pub(super) gy: [i64; 3],
    pub(super) ax: i64,
    pub(super) ay: i64,
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
    pub(super) fn new(
        frame: &Frame,
        p: &[Vec3; 3],
        s: &[(f32, f32); 3],
        uv: &[[f32; 2]; 3],
    ) -> Option<Self> {
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

/// Depth and texture interpolation of the triangle `p` (camera frame) with
/// projected corners `s`: linear when [`Affine::new`] accepts it, perspective-correct
/// otherwise; `None` for a triangle neither can interpolate.
pub(super) fn attributes(
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
