//! Photometric renderer of the simulator: ray casting over the terrain heightfield.
//!
//! Independent of the core's rasterizer, so test images are not made the way virtual
//! templates are. Inputs: a [`Terrain`], a [`Lighting`] (sun direction from time of day
//! and latitude, a cast-shadow map computed once per sun position), a pinhole
//! [`Camera`] with a `world_from_cam` [`Pose`] (design §3 conventions) and
//! [`RenderOptions`]. Output: an 8-bit gray image, row-major, stride = width.
//!
//! Shading: Lambertian sun term × cast shadow (soft-edged by the sun's angular radius)
//! + sky ambient × sky visibility; camera exposure keyed to sunlit flat ground, gamma
//! 2.2, optional vignetting, seeded Gaussian read + shot noise, `s × s` supersampling.
//! Rays march the heightfield with space skipping from max-filtered heights
//! ([`Terrain::max_height_near`]), then bisect to the surface. Rows render in parallel
//! with rayon; every pixel depends only on its coordinates and the seed, so output is
//! byte-identical for any thread count. Work per pixel is bounded by [`MAX_RAY_STEPS`].

use crate::terrain::{Terrain, ACCEL_RADII};
use rayon::prelude::*;
use vtsm_core::geom::{Camera, Pose, Vec3};
use vtsm_core::rng::Rng;

/// Latitude of the simulated depot (the Mars Yard's, Pasadena), degrees north.
pub const DEFAULT_LATITUDE_DEG: f32 = 34.2;
/// Solar declination of the simulated captures (late November), degrees.
pub const DEFAULT_DECLINATION_DEG: f32 = -20.0;
/// Sky irradiance relative to the direct sun on a surface facing it.
pub const SKY_AMBIENT: f32 = 0.22;
/// Cap on marching steps per ray (fine steps plus skips).
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

/// Lighting of one terrain at one sun position: the cast-shadow map and exposure.
#[derive(Clone, Debug)]
pub struct Lighting {
    /// The sun.
    pub sun: Sun,
    /// Linear exposure multiplier (auto-exposure keyed to sunlit flat ground).
    pub exposure: f32,
    /// Lit fraction per terrain cell (1 = full sun), same layout as the terrain grid.
    lit: Vec<f32>,
    nx: usize,
    ny: usize,
    x0: f32,
    y0: f32,
    cell_m: f32,
}

impl Lighting {
    /// Compute the shadow map of `terrain` for `sun` by marching from every cell toward
    /// the sun (with space skipping). Cost ∝ cells; done once per sun position.
    pub fn new(terrain: &Terrain, sun: Sun) -> Self {
        let (nx, ny, c) = (terrain.nx, terrain.ny, terrain.cell_m);
        let horiz = (sun.dir[0] * sun.dir[0] + sun.dir[1] * sun.dir[1])
            .sqrt()
            .max(1e-6);
        let (ux, uy) = (sun.dir[0] / horiz, sun.dir[1] / horiz);
        let slope = sun.dir[2] / horiz; // rise per metre of horizontal travel
        let mut lit = vec![1.0f32; nx * ny];
        if sun.dir[2] <= 0.0 {
            lit.iter_mut().for_each(|l| *l = 0.0);
        } else {
            lit.par_chunks_mut(nx).enumerate().for_each(|(j, row)| {
                let y = terrain.y0 + j as f32 * c;
                for (i, l) in row.iter_mut().enumerate() {
                    let x = terrain.x0 + i as f32 * c;
                    let z0 = terrain.height(x, y) + 0.25 * c;
                    *l = march_to_sun(terrain, x, y, z0, ux, uy, slope);
                }
            });
        }
        // Auto-exposure: sunlit flat ground of albedo 0.25 maps to linear 0.30.
        let flat = 0.25 * (sun.dir[2].max(0.05) + SKY_AMBIENT);
        Self {
            sun,
            exposure: 0.30 / flat,
            lit,
            nx,
            ny,
            x0: terrain.x0,
            y0: terrain.y0,
            cell_m: c,
        }
    }

    /// Lit fraction at `(x, y)` (bilinear; 1 outside the grid).
    pub fn lit(&self, x: f32, y: f32) -> f32 {
        let gx = (x - self.x0) / self.cell_m;
        let gy = (y - self.y0) / self.cell_m;
        if gx < 0.0 || gy < 0.0 || gx > (self.nx - 1) as f32 || gy > (self.ny - 1) as f32 {
            return if self.sun.dir[2] > 0.0 { 1.0 } else { 0.0 };
        }
        let (i, j) = (gx.floor() as usize, gy.floor() as usize);
        let (i1, j1) = ((i + 1).min(self.nx - 1), (j + 1).min(self.ny - 1));
        let (tx, ty) = (gx - i as f32, gy - j as f32);
        let g = |a: usize, b: usize| self.lit[b * self.nx + a];
        let top = g(i, j) + (g(i1, j) - g(i, j)) * tx;
        let bot = g(i, j1) + (g(i1, j1) - g(i, j1)) * tx;
        top + (bot - top) * ty
    }

    /// Fraction of the terrain grid in full shadow (lit < 0.5).
    pub fn shadow_fraction(&self) -> f32 {
        self.lit.iter().filter(|&&l| l < 0.5).count() as f32 / self.lit.len() as f32
    }
}

/// Lit fraction of a point: march toward the sun, track the smallest clearance angle.
fn march_to_sun(t: &Terrain, x: f32, y: f32, z0: f32, ux: f32, uy: f32, slope: f32) -> f32 {
    let c = t.cell_m;
    let mut s = 0.5 * c;
    let mut min_margin = f32::MAX;
    for _ in 0..MAX_RAY_STEPS {
        let (px, py) = (x + ux * s, y + uy * s);
        let zr = z0 + slope * s;
        if !t.inside(px, py) || zr > t.max_height_m {
            break;
        }
        let mut skipped = false;
        for lvl in (0..ACCEL_RADII.len()).rev() {
            if zr > t.max_height_near(lvl, px, py) {
                s += (ACCEL_RADII[lvl] as f32 - 1.0) * c;
                skipped = true;
                break;
            }
        }
        if skipped {
            continue;
        }
        let h = t.height(px, py);
        // Angular clearance of the ray over the terrain at this distance.
        let margin = (zr - h) / s;
        min_margin = min_margin.min(margin);
        if min_margin < -SUN_RADIUS_RAD {
            return 0.0;
        }
        s += 0.5 * c;
    }
    (0.5 + min_margin / (2.0 * SUN_RADIUS_RAD)).clamp(0.0, 1.0)
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
pub fn cast_ray(t: &Terrain, o: [f32; 3], d: [f32; 3]) -> Option<Hit> {
    let c = t.cell_m;
    let top = t.max_height_m + 1e-3;
    let mut tt = 0.0f32;
    if o[2] > top {
        if d[2] >= 0.0 {
            return None;
        }
        tt = (o[2] - top) / -d[2];
    }
    let hd = (d[0] * d[0] + d[1] * d[1]).sqrt();
    let at = |tt: f32| [o[0] + d[0] * tt, o[1] + d[1] * tt, o[2] + d[2] * tt];
    // Ray parameter per cell of horizontal travel (steep rays: per cell of descent).
    let per_cell = c / hd.max(1e-3);
    let mut prev = tt;
    for _ in 0..MAX_RAY_STEPS {
        let p = at(tt);
        if !t.inside(p[0], p[1]) {
            // Beyond the grid the ground is the plane z = 0; rays never come back.
            if d[2] < 0.0 && p[2] > 0.0 {
                let tz = tt + p[2] / -d[2];
                return Some(Hit { p: at(tz), t: tz });
            }
            return if p[2] <= 0.0 {
                Some(Hit { p, t: tt })
            } else {
                None
            };
        }
        if p[2] > top && d[2] >= 0.0 {
            return None;
        }
        let mut skipped = false;
        for lvl in (0..ACCEL_RADII.len()).rev() {
            let step = (ACCEL_RADII[lvl] as f32 - 1.0) * per_cell;
            let z_end = p[2] + d[2].min(0.0) * step;
            if z_end > t.max_height_near(lvl, p[0], p[1]) {
                prev = tt;
                tt += step;
                skipped = true;
                break;
            }
        }
        if skipped {
            continue;
        }
        if t.height(p[0], p[1]) >= p[2] {
            // Bisect between the last point above and this one.
            let (mut a, mut b) = (prev, tt);
            for _ in 0..12 {
                let m = 0.5 * (a + b);
                let q = at(m);
                if t.height(q[0], q[1]) >= q[2] {
                    b = m;
                } else {
                    a = m;
                }
            }
            let q = at(b);
            return Some(Hit {
                p: [q[0], q[1], t.height(q[0], q[1])],
                t: b,
            });
        }
        prev = tt;
        tt += 0.5 * per_cell;
    }
    None
}

/// Linear radiance of the terrain surface at `(x, y)` under `light` (before exposure).
pub fn radiance(t: &Terrain, light: &Lighting, x: f32, y: f32) -> f32 {
    let n = t.normal(x, y);
    let s = light.sun.dir;
    let cos_i = (n[0] * s[0] + n[1] * s[1] + n[2] * s[2]).max(0.0);
    let sun = cos_i * light.lit(x, y);
    let sky = SKY_AMBIENT * (0.5 + 0.5 * n[2]) * t.sky_visibility(x, y);
    t.albedo(x, y) * (sun + sky)
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
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut out = vec![0u8; w * h];
    let s = opts.supersample.clamp(1, 8);
    let o = world_from_cam.translation();
    let origin = [o.x, o.y, o.z];
    let sky = sky_radiance(light);
    let noise = Rng::new(opts.noise_seed).fork(0x5E75_0000);
    let r_max2 = cam.cx * cam.cx + cam.cy * cam.cy;
    out.par_chunks_mut(w).enumerate().for_each(|(v, row)| {
        for (u, px) in row.iter_mut().enumerate() {
            let mut sum = 0.0f32;
            for sj in 0..s {
                for si in 0..s {
                    let fu = u as f32 + (si as f32 + 0.5) / s as f32 - 0.5;
                    let fv = v as f32 + (sj as f32 + 0.5) / s as f32 - 0.5;
                    let dc = Vec3::new((fu - cam.cx) / cam.fx, (fv - cam.cy) / cam.fy, 1.0);
                    let dw = world_from_cam.transform_vector(&dc).normalize();
                    sum += match cast_ray(terrain, origin, [dw.x, dw.y, dw.z]) {
                        Some(hit) => radiance(terrain, light, hit.p[0], hit.p[1]),
                        None => sky,
                    };
                }
            }
            let mut lin = sum / (s * s) as f32;
            if opts.vignetting > 0.0 {
                let (du, dv) = (u as f32 - cam.cx, v as f32 - cam.cy);
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
