//! Photometric renderer of the simulator: ray casting over the terrain heightfield.
//!
//! Independent of the core's rasterizer, so test images are not made the way virtual
//! templates are. Inputs: a [`Terrain`], a [`Lighting`] (sun direction from time of day
//! and latitude, a cast-shadow map computed once per sun position), a pinhole
//! [`Camera`] with a `world_from_cam` [`Pose`] (design §3 conventions) and
//! [`RenderOptions`]. Output: an 8-bit gray image, row-major, stride = width.
//!
//! Shading: Lambertian sun term × cast shadow (soft-edged by the sun's angular radius)
//! plus sky ambient × sky visibility, computed once per cell centre with the shadow map
//! and interpolated bilinearly, times the albedo with its sub-cell grain; camera exposure
//! keyed to sunlit flat ground, gamma 2.2, optional vignetting, seeded Gaussian read and
//! shot noise, `s × s` supersampling. Camera and shadow rays walk the terrain's maximum
//! quadtree ([`Terrain::max_mip`]) front to back and meet each bilinear patch exactly,
//! so the first hit is exact up to rounding. Rows render in parallel
//! with rayon; every pixel depends only on its coordinates and the seed, so output is
//! byte-identical for any thread count. Work per pixel is bounded by [`MAX_RAY_STEPS`].

use crate::terrain::Terrain;
use rayon::prelude::*;
use vtsm_core::geom::{Camera, Pose, Vec3};
use vtsm_core::rng::Rng;

/// Latitude of the simulated depot (the Mars Yard's, Pasadena), degrees north.
pub const DEFAULT_LATITUDE_DEG: f32 = 34.2;
/// Solar declination of the simulated captures (late November), degrees.
pub const DEFAULT_DECLINATION_DEG: f32 = -20.0;
/// Sky irradiance relative to the direct sun on a surface facing it.
pub const SKY_AMBIENT: f32 = 0.22;
/// Cap on max-mip node visits per ray.
pub const MAX_RAY_STEPS: usize = 20_000;
/// Sun angular radius, radians (soft shadow edge).
const SUN_RADIUS_RAD: f32 = 0.0046;

/// Sun position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sun {
    /// Unit vector towards the sun, world frame (x east, y north, z up).
    pub dir: [f32; 3],
    /// Elevation above the horizon, degrees.
    pub elevation_deg: f32,
    /// Azimuth clockwise from north, degrees.
    pub azimuth_deg: f32,
    /// Local solar time, hours.
    pub hours: f32,
}

impl Sun {
    /// The sun at local solar time `hours` for a latitude and declination (degrees).
    pub fn at(hours: f32, latitude_deg: f32, declination_deg: f32) -> Self {
        let h = (15.0 * (hours - 12.0)).to_radians();
        let (phi, dec) = (latitude_deg.to_radians(), declination_deg.to_radians());
        let east = -dec.cos() * h.sin();
        let north = dec.sin() * phi.cos() - dec.cos() * h.cos() * phi.sin();
        let up = dec.sin() * phi.sin() + dec.cos() * h.cos() * phi.cos();
        let n = (east * east + north * north + up * up).sqrt();
        let dir = [east / n, north / n, up / n];
        Self {
            dir,
            elevation_deg: dir[2].asin().to_degrees(),
            azimuth_deg: dir[0].atan2(dir[1]).to_degrees().rem_euclid(360.0),
            hours,
        }
    }

    /// The sun over the simulated depot at `hours` (default latitude and declination).
    pub fn depot(hours: f32) -> Self {
        Self::at(hours, DEFAULT_LATITUDE_DEG, DEFAULT_DECLINATION_DEG)
    }

    /// The afternoon local solar time at which the depot's sun
    /// ([`Sun::depot`]) stands `elevation_deg` above the horizon, by
    /// bisection between noon and 18 h (40 halvings, well under a second of
    /// time); `None` when the sun is never there in the afternoon.
    pub fn depot_afternoon_at(elevation_deg: f32) -> Option<f32> {
        let el = |h: f32| Self::depot(h).elevation_deg;
        let (mut lo, mut hi) = (12.0f32, 18.0f32);
        if !(el(hi)..=el(lo)).contains(&elevation_deg) {
            return None;
        }
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if el(mid) > elevation_deg {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        Some(0.5 * (lo + hi))
    }

    /// A sun from explicit elevation and azimuth (degrees, azimuth clockwise from north).
    pub fn from_angles(elevation_deg: f32, azimuth_deg: f32) -> Self {
        let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
        Self {
            dir: [a.sin() * e.cos(), a.cos() * e.cos(), e.sin()],
            elevation_deg,
            azimuth_deg,
            hours: f32::NAN,
        }
    }
}

/// Which parts of the sunlight a [`Lighting`] models. The simulated depot is
/// [`LightModel::Full`]; the other two take one part out of the mapping-time and the
/// live lighting alike, to measure how much each contributes to the error after a
/// change of the time of day (`vtsm eval --light-model`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LightModel {
    /// Cast shadows and attached shading (the simulated depot).
    #[default]
    Full,
    /// No cast shadows: every cell has lit fraction 1 while the sun is up.
    NoCastShadows,
    /// No attached shading: the irradiance of every cell is that of a surface
    /// facing straight up (the sun term is the sun's elevation, the sky term
    /// the open-sky value times the cell's sky visibility); cast shadows stay.
    NoAttachedShading,
    /// Neither: every cell lit and facing up, so a change of the time of day
    /// only changes the sun's elevation (a gain the exposure takes out).
    Flat,
}

impl LightModel {
    /// Every model, in the order of [`LightModel::name`]'s list.
    pub const ALL: [Self; 4] = [
        Self::Full,
        Self::NoCastShadows,
        Self::NoAttachedShading,
        Self::Flat,
    ];

    /// The name `--light-model` takes: `full`, `no-cast-shadows`,
    /// `no-attached-shading`, `flat`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Full => "full",
            Self::NoCastShadows => "no-cast-shadows",
            Self::NoAttachedShading => "no-attached-shading",
            Self::Flat => "flat",
        }
    }

    /// Parse a name of [`LightModel::name`].
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == s)
    }
}

/// Lighting of one terrain at one sun position: the cast-shadow map and exposure.
#[derive(Clone, Debug)]
pub struct Lighting {
    /// The sun.
    pub sun: Sun,
    /// Linear exposure multiplier (auto-exposure keyed to sunlit flat ground).
    pub exposure: f32,
    /// Lit fraction per terrain cell (1 = full sun), same layout as the terrain grid.
    lit: Vec<f32>,
    /// Irradiance per terrain cell relative to the direct sun on a surface facing it:
    /// sun term × lit fraction plus sky ambient × sky visibility.
    irr: Vec<f32>,
    nx: usize,
    ny: usize,
    x0: f32,
    y0: f32,
    cell_m: f32,
}

impl Lighting {
    /// Compute the shadow map of `terrain` for `sun` by tracing from every cell toward
    /// the sun through the terrain's max-mip. Cost ∝ cells; done once per sun position.
    pub fn new(terrain: &Terrain, sun: Sun) -> Self {
        Self::with_model(terrain, sun, LightModel::Full)
    }

    /// [`Lighting::new`] with the parts of the sunlight that `model` keeps.
    pub fn with_model(terrain: &Terrain, sun: Sun, model: LightModel) -> Self {
        let (nx, ny, c) = (terrain.nx, terrain.ny, terrain.cell_m);
        let horiz = (sun.dir[0] * sun.dir[0] + sun.dir[1] * sun.dir[1])
            .sqrt()
            .max(1e-6);
        let (ux, uy) = (sun.dir[0] / horiz, sun.dir[1] / horiz);
        let slope = sun.dir[2] / horiz; // rise per metre of horizontal travel
        let mut lit = vec![1.0f32; nx * ny];
        if sun.dir[2] <= 0.0 {
            lit.iter_mut().for_each(|l| *l = 0.0);
        } else if !matches!(model, LightModel::NoCastShadows | LightModel::Flat) {
            let flat = terrain.height_grid();
            lit.par_chunks_mut(nx).enumerate().for_each(|(j, row)| {
                for (i, l) in row.iter_mut().enumerate() {
                    let z0 = flat[j * nx + i] + 0.25 * c;
                    *l = trace_to_sun(terrain, [i as f32, j as f32], z0, ux, uy, slope);
                }
            });
        }
        // Irradiance at every cell centre, so shading a hit is one bilinear lookup.
        let mut irr = vec![0.0f32; nx * ny];
        irr.par_chunks_mut(nx).enumerate().for_each(|(j, row)| {
            let y = terrain.y0 + j as f32 * c;
            for (i, e) in row.iter_mut().enumerate() {
                let x = terrain.x0 + i as f32 * c;
                let n = if matches!(model, LightModel::NoAttachedShading | LightModel::Flat) {
                    [0.0, 0.0, 1.0]
                } else {
                    terrain.normal(x, y)
                };
                *e = irradiance(&sun, n, lit[j * nx + i], terrain.sky_visibility(x, y));
            }
        });
        // Auto-exposure: sunlit flat ground of albedo 0.25 maps to linear 0.30.
        let flat = 0.25 * (sun.dir[2].max(0.05) + SKY_AMBIENT);
        Self {
            sun,
            exposure: 0.30 / flat,
            lit,
            irr,
            nx,
            ny,
            x0: terrain.x0,
            y0: terrain.y0,
            cell_m: c,
        }
    }

    /// Lit fraction at `(x, y)` (bilinear; 1 outside the grid).
    pub fn lit(&self, x: f32, y: f32) -> f32 {
        self.bilinear(&self.lit, x, y)
            .unwrap_or(if self.sun.dir[2] > 0.0 { 1.0 } else { 0.0 })
    }

    /// Irradiance at `(x, y)` relative to the direct sun on a surface facing it (bilinear
    /// between cell centres; open flat ground beyond them).
    pub fn irradiance(&self, x: f32, y: f32) -> f32 {
        self.bilinear(&self.irr, x, y).unwrap_or_else(|| {
            let lit = if self.sun.dir[2] > 0.0 { 1.0 } else { 0.0 };
            irradiance(&self.sun, [0.0, 0.0, 1.0], lit, 1.0)
        })
    }

    /// Bilinear lookup of a per-cell `grid` (`nx × ny`, row-major) at `(x, y)`;
    /// `None` outside the grid's cell centres.
    fn bilinear(&self, grid: &[f32], x: f32, y: f32) -> Option<f32> {
        let gx = (x - self.x0) / self.cell_m;
        let gy = (y - self.y0) / self.cell_m;
        if gx < 0.0 || gy < 0.0 || gx > (self.nx - 1) as f32 || gy > (self.ny - 1) as f32 {
            return None;
        }
        // Non-negative here, so truncation is the floor.
        let (i, j) = (gx as usize, gy as usize);
        let (i1, j1) = ((i + 1).min(self.nx - 1), (j + 1).min(self.ny - 1));
        let (tx, ty) = (gx - i as f32, gy - j as f32);
        let g = |a: usize, b: usize| grid[b * self.nx + a];
        let top = g(i, j) + (g(i1, j) - g(i, j)) * tx;
        let bot = g(i, j1) + (g(i1, j1) - g(i, j1)) * tx;
        Some(top + (bot - top) * ty)
    }

    /// Fraction of the terrain grid in full shadow (lit < 0.5).
    pub fn shadow_fraction(&self) -> f32 {
        self.lit.iter().filter(|&&l| l < 0.5).count() as f32 / self.lit.len() as f32
    }
}

/// A ray over the heightfield in grid coordinates: `g(t) = g0 + gd·t` (cells, with cell
/// centre `(i, j)` at integer coordinates) and `z(t) = z0 + dz·t` (metres).
#[derive(Clone, Copy, Debug)]
struct GridRay {
    g0: [f32; 2],
    gd: [f32; 2],
    z0: f32,
    dz: f32,
}

impl GridRay {
    #[inline]
    fn at(&self, t: f32) -> [f32; 2] {
        [self.g0[0] + self.gd[0] * t, self.g0[1] + self.gd[1] * t]
    }

    /// Parameter interval over which the ray lies above the patch domain
    /// `[0, w] × [0, h]`, intersected with `[t0, t1]`; `None` if empty.
    fn clip(&self, w: f32, h: f32, t0: f32, t1: f32) -> Option<(f32, f32)> {
        let (mut lo, mut hi) = (t0, t1);
        for (a, (o, d)) in [w, h].into_iter().zip(self.g0.into_iter().zip(self.gd)) {
            if d == 0.0 {
                if o < 0.0 || o > a {
                    return None;
                }
            } else {
                let (ta, tb) = ((0.0 - o) / d, (a - o) / d);
                lo = lo.max(ta.min(tb));
                hi = hi.min(ta.max(tb));
            }
        }
        (lo <= hi).then_some((lo, hi))
    }
}

/// How a max-mip traversal ended.
enum Walk<R> {
    /// The leaf test reported a result.
    Found(R),
    /// The ray left the grid (or reached the end of its interval) at this parameter.
    Left(f32),
}

/// Walk the max-mip of `t` along `ray` over `[t_in, t_end]` (already clipped to the
/// grid), front to back. A node whose bound `m` satisfies `skip(m, ta, tb)` for the
/// ray's interval `[ta, tb]` over it is stepped over; otherwise its children are
/// visited, and at level 0 `leaf(i, j, ta, tb)` tests patch `(i, j)`. Node indices only
/// move in the ray's direction, and the walk stops after [`MAX_RAY_STEPS`] node visits.
fn walk<R>(
    t: &Terrain,
    ray: &GridRay,
    t_in: f32,
    t_end: f32,
    skip: impl Fn(f32, f32, f32) -> bool,
    mut leaf: impl FnMut(usize, usize, f32, f32) -> Option<R>,
) -> Walk<R> {
    let mip = t.max_mip();
    let top = mip.num_levels() - 1;
    let (pw, ph) = mip.dims(0);
    let p = ray.at(t_in);
    let lx = (p[0].max(0.0) as usize).min(pw - 1);
    let ly = (p[1].max(0.0) as usize).min(ph - 1);
    let (mut lvl, mut ix, mut iy) = (top, lx >> top, ly >> top);
    let inv = [1.0 / ray.gd[0], 1.0 / ray.gd[1]];
    let (sx, sy) = (ray.gd[0] > 0.0, ray.gd[1] > 0.0);
    let mut tc = t_in;
    for _ in 0..MAX_RAY_STEPS {
        // Parameter where the ray leaves node (ix, iy) of level lvl, and through which side.
        let bound = |i: usize, n: usize, pos: bool| {
            let k = if pos { i + 1 } else { i };
            ((k << lvl).min(n)) as f32
        };
        let tx = if ray.gd[0] == 0.0 {
            f32::INFINITY
        } else {
            (bound(ix, pw, sx) - ray.g0[0]) * inv[0]
        };
        let ty = if ray.gd[1] == 0.0 {
            f32::INFINITY
        } else {
            (bound(iy, ph, sy) - ray.g0[1]) * inv[1]
        };
        let step_x = tx <= ty;
        let t_out = tx.min(ty).min(t_end).max(tc);
        if !skip(mip.node_max(lvl, ix, iy), tc, t_out) {
            if lvl == 0 {
                if let Some(r) = leaf(ix, iy, tc, t_out) {
                    return Walk::Found(r);
                }
            } else {
                // Descend into the child that contains the ray at tc.
                lvl -= 1;
                let (cw, ch) = mip.dims(lvl);
                let q = ray.at(tc);
                let child = |i: usize, qc: f32, pos: bool, n: usize| {
                    let mid = ((2 * i + 1) << lvl) as f32;
                    let hi = qc > mid || (qc == mid && pos);
                    (2 * i + usize::from(hi)).min(n - 1)
                };
                ix = child(ix, q[0], sx, cw);
                iy = child(iy, q[1], sy, ch);
                continue;
            }
        }
        // Step to the neighbour across the exit side, climbing one level when the
        // neighbour has a different parent.
        tc = t_out;
        if tc >= t_end {
            return Walk::Left(t_end);
        }
        let (w, h) = mip.dims(lvl);
        let (old, new) = if step_x {
            let n = if sx { ix + 1 } else { ix.wrapping_sub(1) };
            if n >= w {
                return Walk::Left(tc);
            }
            (ix, n)
        } else {
            let n = if sy { iy + 1 } else { iy.wrapping_sub(1) };
            if n >= h {
                return Walk::Left(tc);
            }
            (iy, n)
        };
        if step_x {
            ix = new;
        } else {
            iy = new;
        }
        if lvl < top && (old >> 1) != (new >> 1) {
            lvl += 1;
            ix >>= 1;
            iy >>= 1;
        }
    }
    Walk::Left(tc)
}

/// Smallest `s` in `[0, len]` where the ray `(u0 + du·s, v0 + dv·s, z0 + dz·s)` meets or
/// goes below the bilinear patch with corner heights `c` over `[0, 1]²` (exact: the
/// height difference along the ray is a quadratic in `s`).
#[inline]
fn patch_hit(c: [f32; 4], u0: f32, v0: f32, z0: f32, d: [f32; 3], len: f32) -> Option<f32> {
    let (a, b, cc) = (
        f64::from(c[0]),
        f64::from(c[1] - c[0]),
        f64::from(c[2] - c[0]),
    );
    let e = f64::from(c[0]) - f64::from(c[1]) - f64::from(c[2]) + f64::from(c[3]);
    let (u0, v0, z0) = (f64::from(u0), f64::from(v0), f64::from(z0));
    let (du, dv, dz) = (f64::from(d[0]), f64::from(d[1]), f64::from(d[2]));
    let qa = e * du * dv;
    let qb = b * du + cc * dv + e * (u0 * dv + v0 * du) - dz;
    let qc = a + b * u0 + cc * v0 + e * u0 * v0 - z0;
    if qc >= 0.0 {
        return Some(0.0);
    }
    let len = f64::from(len);
    let root = if qa.abs() < 1e-12 {
        (qb > 0.0).then(|| -qc / qb)
    } else {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc < 0.0 {
            None
        } else {
            let q = -0.5 * (qb + qb.signum() * disc.sqrt());
            let (r1, r2) = (q / qa, if q != 0.0 { qc / q } else { f64::INFINITY });
            let (lo, hi) = (r1.min(r2), r1.max(r2));
            if lo >= 0.0 {
                Some(lo)
            } else if hi >= 0.0 {
                Some(hi)
            } else {
                None
            }
        }
    };
    root.filter(|&s| s <= len).map(|s| s as f32)
}

/// Height of a bilinear patch with corner heights `c` at local `(u, v)` in `[0, 1]²`.
#[inline]
fn patch_height(c: [f32; 4], u: f32, v: f32) -> f32 {
    let (u, v) = (u.clamp(0.0, 1.0), v.clamp(0.0, 1.0));
    let top = c[0] + (c[1] - c[0]) * u;
    let bot = c[2] + (c[3] - c[2]) * u;
    top + (bot - top) * v
}

/// Lit fraction of grid point `g` at height `z0`: trace toward the sun (horizontal unit
/// direction `(ux, uy)`, rise `slope` per metre) through the max-mip, tracking the
/// smallest angular clearance over the terrain; nodes that clear the ray by more than
/// the sun's radius cannot change the result and are skipped.
fn trace_to_sun(t: &Terrain, g: [f32; 2], z0: f32, ux: f32, uy: f32, slope: f32) -> f32 {
    let c = t.cell_m;
    let (pw, ph) = t.max_mip().dims(0);
    // Parameter: horizontal distance, metres.
    let ray = GridRay {
        g0: g,
        gd: [ux / c, uy / c],
        z0,
        dz: slope,
    };
    let s0 = 0.5 * c;
    let s_top = if slope > 0.0 {
        (t.max_height_m - z0).max(0.0) / slope
    } else {
        f32::INFINITY
    };
    let Some((s_in, s_end)) = ray.clip(pw as f32, ph as f32, s0, s_top) else {
        return 1.0;
    };
    let r = SUN_RADIUS_RAD;
    let mut min_margin = f32::MAX;
    // Clearance above `m` by at least r·s at both ends ⇒ everywhere (it is linear in s).
    let skip = |m: f32, sa: f32, sb: f32| (z0 + (slope - r) * sa).min(z0 + (slope - r) * sb) > m;
    let found = walk(t, &ray, s_in, s_end, skip, |i, j, sa, sb| {
        let corners = t.patch(i, j);
        for s in [sa, 0.5 * (sa + sb), sb] {
            let q = ray.at(s);
            let h = patch_height(corners, q[0] - i as f32, q[1] - j as f32);
            let margin = (z0 + slope * s - h) / s;
            min_margin = min_margin.min(margin);
        }
        (min_margin < -r).then_some(())
    });
    if matches!(found, Walk::Found(())) {
        return 0.0;
    }
    (0.5 + min_margin / (2.0 * r)).clamp(0.0, 1.0)
}

/// Where a camera ray meets the ground.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Surface point, world metres.
    pub p: [f32; 3],
    /// Distance along the (unit) ray, metres.
    pub t: f32,
}

/// Cast a ray from `o` along unit `d` (world frame) to the terrain; `None` = sky.
///
/// The ray walks the terrain's max-mip ([`Terrain::max_mip`]) front to back and meets
/// each bilinear patch it may touch exactly (a quadratic along the ray). Beyond the grid
/// the ground is the plane `z = 0`.
pub fn cast_ray(t: &Terrain, o: [f32; 3], d: [f32; 3]) -> Option<Hit> {
    let c = t.cell_m;
    let top = t.max_height_m + 1e-3;
    let at = |tt: f32| [o[0] + d[0] * tt, o[1] + d[1] * tt, o[2] + d[2] * tt];
    let beyond = |tt: f32| {
        let p = at(tt);
        if d[2] < 0.0 && p[2] > 0.0 {
            let tz = tt + p[2] / -d[2];
            Some(Hit { p: at(tz), t: tz })
        } else if p[2] <= 0.0 {
            Some(Hit { p, t: tt })
        } else {
            None
        }
    };
    // The stretch of the ray at or below the highest terrain point.
    let (t0, t1) = if d[2] < 0.0 {
        ((o[2] - top).max(0.0) / -d[2], f32::INFINITY)
    } else if o[2] > top {
        return None;
    } else if d[2] > 0.0 {
        (0.0, (top - o[2]) / d[2])
    } else {
        (0.0, f32::INFINITY)
    };
    let ray = GridRay {
        g0: [(o[0] - t.x0) / c, (o[1] - t.y0) / c],
        gd: [d[0] / c, d[1] / c],
        z0: o[2],
        dz: d[2],
    };
    let (pw, ph) = t.max_mip().dims(0);
    let Some((t_in, t_end)) = ray.clip(pw as f32, ph as f32, t0, t1) else {
        return beyond(t0);
    };
    let skip = |m: f32, ta: f32, tb: f32| (ray.z0 + ray.dz * ta).min(ray.z0 + ray.dz * tb) > m;
    let leaf = |i: usize, j: usize, ta: f32, tb: f32| {
        let g = ray.at(ta);
        let z = ray.z0 + ray.dz * ta;
        let (u, v) = (g[0] - i as f32, g[1] - j as f32);
        patch_hit(
            t.patch(i, j),
            u,
            v,
            z,
            [ray.gd[0], ray.gd[1], ray.dz],
            tb - ta,
        )
        .map(|s| ta + s)
    };
    match walk(t, &ray, t_in, t_end, skip, leaf) {
        Walk::Found(th) => {
            let q = at(th);
            Some(Hit {
                p: [q[0], q[1], t.height(q[0], q[1])],
                t: th,
            })
        }
        Walk::Left(tl) if tl >= t1 => None,
        Walk::Left(tl) => beyond(tl),
    }
}

/// Irradiance of a surface with unit normal `n`, lit fraction `lit` and sky visibility
/// `sky`: Lambertian sun term plus sky ambient, relative to the direct sun.
#[inline]
fn irradiance(sun: &Sun, n: [f32; 3], lit: f32, sky: f32) -> f32 {
    let s = sun.dir;
    let cos_i = (n[0] * s[0] + n[1] * s[1] + n[2] * s[2]).max(0.0);
    cos_i * lit + SKY_AMBIENT * (0.5 + 0.5 * n[2]) * sky
}

/// Linear radiance of the terrain surface at `(x, y)` under `light` (before exposure):
/// albedo × irradiance, the irradiance interpolated between cell centres
/// ([`Lighting::irradiance`]).
pub fn radiance(t: &Terrain, light: &Lighting, x: f32, y: f32) -> f32 {
    t.albedo(x, y) * light.irradiance(x, y)
}

/// Linear radiance of the sky (dusty, slightly brighter than sunlit ground).
pub fn sky_radiance(light: &Lighting) -> f32 {
    0.35 / light.exposure.max(1e-6) * 1.6
}

/// Exposure and gamma: linear radiance → 8-bit value before noise (0..255 as f32).
#[inline]
pub fn tone(radiance: f32, exposure: f32) -> f32 {
    255.0 * (radiance * exposure).clamp(0.0, 1.0).powf(1.0 / 2.2)
}

/// Rendering options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// Supersampling factor per axis (1 = one ray per pixel).
    pub supersample: u32,
    /// Read-noise standard deviation, 8-bit counts (0 = noiseless).
    pub read_noise_dn: f32,
    /// Shot-noise gain: variance added per count of signal.
    pub shot_gain: f32,
    /// Vignetting: relative fall-off at the image corner (0 = none).
    pub vignetting: f32,
    /// Seed of the sensor noise.
    pub noise_seed: u64,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            supersample: 2,
            read_noise_dn: 1.0,
            shot_gain: 0.02,
            vignetting: 0.12,
            noise_seed: 0,
        }
    }
}

impl RenderOptions {
    /// No noise, no vignetting (for geometric and photometric checks).
    pub fn clean(supersample: u32) -> Self {
        Self {
            supersample,
            read_noise_dn: 0.0,
            shot_gain: 0.0,
            vignetting: 0.0,
            noise_seed: 0,
        }
    }
}

/// Render an 8-bit gray image of `terrain` seen by `cam` at `world_from_cam`.
pub fn render(
    terrain: &Terrain,
    light: &Lighting,
    cam: &Camera,
    world_from_cam: &Pose,
    opts: &RenderOptions,
) -> Vec<u8> {
    render_rays(
        terrain,
        light,
        (cam.width(), cam.height()),
        [cam.cx(), cam.cy()],
        world_from_cam,
        opts,
        |fu, fv| {
            Some(Vec3::new(
                (fu - cam.cx()) / cam.fx(),
                (fv - cam.cy()) / cam.fy(),
                1.0,
            ))
        },
    )
}

/// [`render`] through any camera model: `ray(u, v)` gives the camera-frame
/// direction (any length) seen at the continuous pixel position `(u, v)`, or
/// `None` where the model has no ray (drawn black). `centre` is the image centre
/// of the vignetting. Used for the distorted physical cameras of
/// [`crate::scene::physical`]; with the pinhole ray it is [`render`], bit for bit.
pub fn render_rays<F>(
    terrain: &Terrain,
    light: &Lighting,
    size: (u32, u32),
    centre: [f32; 2],
    world_from_cam: &Pose,
    opts: &RenderOptions,
    ray: F,
) -> Vec<u8>
where
    F: Fn(f32, f32) -> Option<Vec3> + Sync,
{
    let (w, h) = (size.0 as usize, size.1 as usize);
    let mut out = vec![0u8; w * h];
    let s = opts.supersample.clamp(1, 8);
    let o = world_from_cam.translation();
    let origin = [o.x, o.y, o.z];
    let sky = sky_radiance(light);
    let noise = Rng::new(opts.noise_seed).fork(0x5E75_0000);
    let r_max2 = centre[0] * centre[0] + centre[1] * centre[1];
    out.par_chunks_mut(w).enumerate().for_each(|(v, row)| {
        for (u, px) in row.iter_mut().enumerate() {
            let mut sum = 0.0f32;
            for sj in 0..s {
                for si in 0..s {
                    let fu = u as f32 + (si as f32 + 0.5) / s as f32 - 0.5;
                    let fv = v as f32 + (sj as f32 + 0.5) / s as f32 - 0.5;
                    let Some(dc) = ray(fu, fv) else {
                        continue;
                    };
                    let dw = world_from_cam.transform_vector(&dc).normalize();
                    sum += match cast_ray(terrain, origin, [dw.x, dw.y, dw.z]) {
                        Some(hit) => radiance(terrain, light, hit.p[0], hit.p[1]),
                        None => sky,
                    };
                }
            }
            let mut lin = sum / (s * s) as f32;
            if opts.vignetting > 0.0 {
                let (du, dv) = (u as f32 - centre[0], v as f32 - centre[1]);
                lin *= 1.0 - opts.vignetting * (du * du + dv * dv) / r_max2;
            }
            let mut val = tone(lin, light.exposure);
            if opts.read_noise_dn > 0.0 || opts.shot_gain > 0.0 {
                let mut rng = noise.at(((v * w + u) as u64) << 2);
                let sd = (opts.read_noise_dn * opts.read_noise_dn + opts.shot_gain * val).sqrt();
                val += sd * rng.normal();
            }
            *px = val.round().clamp(0.0, 255.0) as u8;
        }
    });
    out
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
mod tests {
    use super::*;
    use crate::terrain::TerrainKind;

    #[test]
    fn sun_follows_the_day() {
        let am = Sun::depot(9.5);
        let noon = Sun::depot(12.0);
        let pm = Sun::depot(15.5);
        // Independent reference: noon elevation = 90° − |latitude − declination|.
        let expect = 90.0 - (DEFAULT_LATITUDE_DEG - DEFAULT_DECLINATION_DEG).abs();
        assert!(
            (noon.elevation_deg - expect).abs() < 0.01,
            "{}",
            noon.elevation_deg
        );
        assert!((noon.azimuth_deg - 180.0).abs() < 0.01);
        assert!(
            am.azimuth_deg > 90.0 && am.azimuth_deg < 180.0,
            "{}",
            am.azimuth_deg
        );
        assert!(
            pm.azimuth_deg > 180.0 && pm.azimuth_deg < 270.0,
            "{}",
            pm.azimuth_deg
        );
        assert!(am.elevation_deg < noon.elevation_deg && pm.elevation_deg < noon.elevation_deg);
        // Symmetric about noon.
        let h8 = Sun::depot_afternoon_at(8.0).unwrap();
        assert!(h8 > 15.5 && h8 < 17.0, "{h8}");
        assert!((Sun::depot(h8).elevation_deg - 8.0).abs() < 1e-3);
        assert_eq!(Sun::depot_afternoon_at(80.0), None);
        let a = Sun::depot(10.0);
        let b = Sun::depot(14.0);
        assert!((a.elevation_deg - b.elevation_deg).abs() < 1e-3);
        assert!((a.azimuth_deg + b.azimuth_deg - 360.0).abs() < 1e-2);
    }

    /// Verifies: VTSM-SIM-005
    #[test]
    fn ray_cast_hits_the_surface() {
        let t = Terrain::generate(TerrainKind::Cfa6, 2, 0.02);
        let mut rng = Rng::new(4);
        for _ in 0..500 {
            let o = [rng.uniform(-2.0, 2.0), rng.uniform(-4.0, 4.0), 1.0];
            let v = Vec3::new(rng.uniform(-0.6, 0.6), rng.uniform(-0.6, 0.6), -1.0).normalize();
            let hit = cast_ray(&t, o, [v.x, v.y, v.z]).unwrap();
            assert!((t.height(hit.p[0], hit.p[1]) - hit.p[2]).abs() < 1e-3);
            // No surface above the ray before the hit (checked by dense sampling).
            let n = 400;
            for k in 0..n {
                let tt = hit.t * k as f32 / n as f32;
                let p = [o[0] + v.x * tt, o[1] + v.y * tt, o[2] + v.z * tt];
                assert!(
                    t.height(p[0], p[1]) <= p[2] + 2e-3,
                    "surface above ray at t={tt}"
                );
            }
        }
    }
}
