//! Map pre-analysis: how likely each sample point's template is to match,
//! scored once at map build and shipped in the map product (version 3).
//!
//! Input: a textured mesh ([`MeshData`]) as any tool exports it; nothing of
//! the simulator's truth (sun, albedo, terrain) is read, so a photogrammetry
//! map is scored the same way. Output: one score per vertex, 0–255, that the
//! core's SamplePoint draws mask vertices in proportion to.
//!
//! "Up" below is the mesh's main facing (the dominant axis of its normals):
//! a depot's vertical, a facade's outward normal. A score is the product of
//! three terms:
//! - **structure**: the RMS gradient of the log-texture over the template's
//!   ground footprint, counted on lit texels only (lit: not darker than 0.4
//!   of the mean of its surroundings nor than a third of the texture's
//!   median, so a shadow baked into the map is not counted). The logarithm
//!   turns the map-time shading (a smooth factor on the albedo) into a
//!   smooth term that adds little gradient, so what is counted is mostly the
//!   albedo's own texture. It enters as its square root;
//! - **facing up**: a ramp on the vertex normal's vertical component. Rover
//!   cameras look down at the depot from all sides: a surface facing up is
//!   seen unforeshortened from every direction and its shading changes by a
//!   common factor under a new sun, which NCC removes; a steep flank is seen
//!   obliquely or not at all, and its shading turns over with the sun;
//! - **exposure**: the fraction of 16 azimuths along which nothing within
//!   40 cm rises above 25° seen from the vertex (on the mesh's height grid):
//!   a point at the foot of a rock is in that rock's shadow for a sun from
//!   behind it, in the map or in the live images, and its template then
//!   matches nothing.
//!
//! What the score predicts, measured (`vtsm eval --suite paper --profile
//! demo --score-deciles`, `fsw-docs/eval/map-scores.md`): the lowest decile
//! of the mask matches several times less often than the rest after a change
//! of light on the rock masks; above it the rate is nearly flat. Where a
//! point lies in the live view decides more than anything a map can know.
//!
//! Scores are the product scaled so the 95th percentile of the mask's
//! vertices is 255, with a floor of 1 on mask vertices: every point the mask
//! holds can still be drawn. Work: O(texels + triangles + vertices), the
//! texture box-averaged first to at most [`MAX_ANALYSIS_TEXELS`].

use crate::io::mesh::MeshData;
use rayon::prelude::*;

/// Largest texture (texels) analysed at full resolution; a larger one is
/// box-averaged by an integer factor first (bounds memory: five `f64`/`f32`
/// planes of this size).
pub const MAX_ANALYSIS_TEXELS: usize = 4096 * 4096;

/// How the map is scored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScoreOptions {
    /// Side of a template's ground footprint, metres (ℓ pixels times the
    /// camera's ground sample distance at working range).
    pub footprint_m: f32,
    /// Normal vertical component at and below which a vertex scores 0 for
    /// facing (a flank steeper than about 78°).
    pub facing_min: f32,
    /// Normal vertical component at and above which facing scores 1.
    pub facing_full: f32,
    /// Sun elevation of the exposure term, degrees.
    pub horizon_deg: f32,
    /// Farthest distance the horizon is searched to, metres.
    pub horizon_m: f32,
}

impl Default for ScoreOptions {
    /// A 32-pixel template at about 2.5 mm per pixel (the paper's camera at
    /// 1.5–2 m): an 8 cm footprint.
    fn default() -> Self {
        Self {
            footprint_m: 0.08,
            facing_min: 0.2,
            facing_full: 0.8,
            horizon_deg: 25.0,
            horizon_m: 0.4,
        }
    }
}

/// The terms of one vertex's score, before scaling (for reports and tests).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Terms {
    /// RMS log-texture gradient over the lit texels of the footprint.
    pub structure: f32,
    /// Fraction of the footprint's texels outside cast shadow (reported; not
    /// a factor of the score: alone it predicted nothing).
    pub lit: f32,
    /// Facing term, 0–1.
    pub facing: f32,
    /// Fraction of azimuths whose horizon, seen from the vertex, stays
    /// below [`ScoreOptions::horizon_deg`]: how often a sun from anywhere
    /// at that elevation would light it.
    pub exposure: f32,
}

impl Terms {
    /// The unscaled score.
    pub fn raw(&self) -> f32 {
        self.structure.sqrt() * self.facing * self.exposure
    }
}

/// The map product of `mesh` with tiles of `tile_size_m`: scored
/// ([`score_vertices`], version 3) when `scored`, else version 2, as
/// `--map-scores` asks of every command that builds a map from a mesh.
///
/// # Errors
/// As [`MeshData::encode_scored_map`].
pub fn encode(mesh: &MeshData, tile_size_m: f32, scored: bool) -> crate::Result<Vec<u8>> {
    let scores = scored.then(|| score_vertices(mesh, &ScoreOptions::default()));
    mesh.encode_scored_map(tile_size_m, scores.as_deref())
}

/// Score every vertex of `mesh` (0 for vertices outside the mask M̂).
pub fn score_vertices(mesh: &MeshData, opts: &ScoreOptions) -> Vec<u8> {
    let terms = vertex_terms(mesh, opts);
    scale(mesh, &terms)
}

/// The unscaled terms of every vertex (default terms for vertices that no
/// mask triangle uses).
pub fn vertex_terms(mesh: &MeshData, opts: &ScoreOptions) -> Vec<Terms> {
    let planes = Planes::of(&mesh.texture);
    let nv = mesh.vertices.len();
    // In the frame of the mesh's main facing: "up" is where it is seen from.
    let vertices = in_facing_frame(mesh);
    // Per vertex: its texel position (from the first mask triangle corner
    // naming it), the metres per texel there, and its area-weighted normal.
    let mut at: Vec<Option<([f32; 2], f32)>> = vec![None; nv];
    let mut normal = vec![[0f32; 3]; nv];
    let (tw, th) = (mesh.texture.width as f32, mesh.texture.height as f32);
    for ((t, uv), &m) in mesh.triangles.iter().zip(&mesh.uvs).zip(&mesh.mask) {
        let p = t.map(|k| vertices.get(k as usize).copied().unwrap_or([0.0; 3]));
        let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
        let px = uv.map(|st| [st[0] * tw - 0.5, (1.0 - st[1]) * th - 0.5]);
        let m_per_texel = metres_per_texel(&p, &px);
        for (c, &k) in t.iter().enumerate() {
            let Some(slot) = normal.get_mut(k as usize) else {
                continue;
            };
            for (a, b) in slot.iter_mut().zip(n) {
                *a += b;
            }
            if m && at[k as usize].is_none() {
                if let Some(s) = m_per_texel {
                    at[k as usize] = Some((px[c], s));
                }
            }
        }
    }
    let f = planes.factor as f32;
    let heights = HeightGrid::of(&vertices, &mesh.triangles, 0.01);
    (0..nv)
        .into_par_iter()
        .map(|k| {
            let Some((px, m_per_texel)) = at[k] else {
                return Terms::default();
            };
            let n = normal[k];
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            let nz = if len > 0.0 { n[2].abs() / len } else { 0.0 };
            let facing = ((nz - opts.facing_min) / (opts.facing_full - opts.facing_min).max(1e-6))
                .clamp(0.0, 1.0);
            // Footprint half-side in analysis texels, at least 2, at most 64.
            let r = (0.5 * opts.footprint_m / (m_per_texel * f)).clamp(2.0, 64.0);
            let (structure, lit) = planes.footprint([px[0] / f, px[1] / f], r);
            Terms {
                structure,
                lit,
                facing,
                exposure: heights.exposure(vertices[k], opts),
            }
        })
        .collect()
}

/// Every vertex's membership of the mask M̂ (a corner of a mask triangle),
/// in vertex order: the product lists the members in this order, so the
/// `k`-th `true` is mask index `k`.
pub fn mask_members(mesh: &MeshData) -> Vec<bool> {
    let mut in_mask = vec![false; mesh.vertices.len()];
    for (t, &m) in mesh.triangles.iter().zip(&mesh.mask) {
        if m {
            for &k in t {
                if let Some(s) = in_mask.get_mut(k as usize) {
                    *s = true;
                }
            }
        }
    }
    in_mask
}

/// The decile (0 lowest … 9 highest) of each mask vertex's unscaled score
/// among the mask's, indexed by mask index (ties in a seeded shuffled order).
pub fn mask_deciles(mesh: &MeshData, terms: &[Terms]) -> Vec<u8> {
    let raw: Vec<f32> = terms
        .iter()
        .zip(mask_members(mesh))
        .filter(|(_, m)| *m)
        .map(|(t, _)| t.raw())
        .collect();
    // Ties (a flat or fully exposed region scores the same) broken by a
    // hash of the index, not by vertex order: vertex order is position on
    // the map, and a decile of one region would measure the region.
    let mix: Vec<u32> = (0..raw.len())
        .map(|k| vtsm_core::rng::Rng::new(k as u64).next_u32())
        .collect();
    let mut order: Vec<usize> = (0..raw.len()).collect();
    order.sort_by(|&a, &b| {
        raw[a]
            .total_cmp(&raw[b])
            .then(mix[a].cmp(&mix[b]))
            .then(a.cmp(&b))
    });
    let mut deciles = vec![0u8; raw.len()];
    for (rank, &k) in order.iter().enumerate() {
        deciles[k] = (rank * 10 / raw.len().max(1)).min(9) as u8;
    }
    deciles
}

/// Scale raw scores so the mask's 95th percentile is 255; floor 1 on mask
/// vertices, 0 elsewhere.
pub fn scale(mesh: &MeshData, terms: &[Terms]) -> Vec<u8> {
    let in_mask = mask_members(mesh);
    let mut raw: Vec<f32> = terms
        .iter()
        .zip(&in_mask)
        .filter(|(_, &m)| m)
        .map(|(t, _)| t.raw())
        .filter(|r| r.is_finite())
        .collect();
    raw.sort_by(f32::total_cmp);
    let p95 = raw
        .get((raw.len() * 95 / 100).min(raw.len().saturating_sub(1)))
        .copied()
        .unwrap_or(0.0);
    terms
        .iter()
        .zip(&in_mask)
        .map(|(t, &m)| {
            if !m {
                return 0;
            }
            let r = t.raw();
            if !(p95 > 0.0 && r.is_finite()) {
                return 1;
            }
            (255.0 * r / p95).round().clamp(1.0, 255.0) as u8
        })
        .collect()
}

/// Mean metres per texel of a triangle: its 3-D edge lengths over its
/// texture edge lengths (`None` for a triangle degenerate in either).
fn metres_per_texel(p: &[[f32; 3]; 3], px: &[[f32; 2]; 3]) -> Option<f32> {
    let (mut m, mut t) = (0.0, 0.0);
    for (a, b) in [(0, 1), (1, 2), (2, 0)] {
        let d = sub(p[b], p[a]);
        m += (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let (dx, dy) = (px[b][0] - px[a][0], px[b][1] - px[a][1]);
        t += (dx * dx + dy * dy).sqrt();
    }
    let s = m / t;
    (s.is_finite() && s > 0.0).then_some(s)
}

/// The vertices in a frame whose third axis is the mesh's main facing
/// ([`main_facing`]): a depot's up, a facade's outward normal. Facing and
/// horizons are measured along it, so a map in any orientation is scored
/// as it is seen.
fn in_facing_frame(mesh: &MeshData) -> Vec<[f32; 3]> {
    let d = main_facing(mesh);
    // Any unit vector not along d, then two orthogonal to d.
    let a = if d[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let u = normalized(cross(a, d));
    let v = cross(d, u);
    mesh.vertices
        .iter()
        .map(|p| [dot(*p, u), dot(*p, v), dot(*p, d)])
        .collect()
}

/// The mesh's main facing: the dominant axis of its triangles'
/// area-weighted normals (the leading eigenvector of `Σ n nᵀ / |n|`, `n`
/// the unnormalized normal, by 64 steps of power iteration from the
/// normals' sum), signed along that sum (the winding's outside); +z for a
/// mesh without area.
fn main_facing(mesh: &MeshData) -> [f32; 3] {
    let mut m = [[0f64; 3]; 3];
    let mut sum = [0f64; 3];
    for t in &mesh.triangles {
        let p = t.map(|k| mesh.vertices.get(k as usize).copied().unwrap_or([0.0; 3]));
        let n = cross(sub(p[1], p[0]), sub(p[2], p[0])).map(f64::from);
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        if !(len > 0.0 && len.is_finite()) {
            continue;
        }
        // Weight by area: n nᵀ / |n| (|n| is twice the area).
        for i in 0..3 {
            sum[i] += n[i];
            for j in 0..3 {
                m[i][j] += n[i] * n[j] / len;
            }
        }
    }
    // From the normals' sum (a start no eigenvector can be orthogonal to
    // unless the winding cancels), else from the largest diagonal's axis.
    let start = {
        let l = (sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]).sqrt();
        if l > 0.0 && l.is_finite() {
            sum.map(|c| c / l)
        } else {
            let k = (0..3)
                .max_by(|&a, &b| m[a][a].total_cmp(&m[b][b]))
                .unwrap_or(2);
            [0, 1, 2].map(|i| f64::from(u8::from(i == k)))
        }
    };
    let mut d = start;
    for _ in 0..64 {
        let next = [0, 1, 2].map(|i| m[i][0] * d[0] + m[i][1] * d[1] + m[i][2] * d[2]);
        let len = (next[0] * next[0] + next[1] * next[1] + next[2] * next[2]).sqrt();
        if !(len > 0.0 && len.is_finite()) {
            return [0.0, 0.0, 1.0];
        }
        d = next.map(|c| c / len);
    }
    let sign = if sum[0] * d[0] + sum[1] * d[1] + sum[2] * d[2] < 0.0 {
        -1.0
    } else {
        1.0
    };
    d.map(|c| (sign * c) as f32)
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalized(a: [f32; 3]) -> [f32; 3] {
    let l = dot(a, a).sqrt();
    if l > 0.0 {
        a.map(|c| c / l)
    } else {
        [0.0, 0.0, 1.0]
    }
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The texture's analysis planes as summed-area tables: gradient energy on
/// lit texels, lit texels, and intensity (for the shadow test's window mean).
struct Planes {
    w: usize,
    h: usize,
    /// Texture texels per analysis texel along each axis.
    factor: usize,
    /// Summed-area tables, `(w + 1) · (h + 1)`, row 0 and column 0 zero.
    sat_energy: Vec<f64>,
    sat_lit: Vec<f64>,
}

impl Planes {
    fn of(tex: &crate::io::image::Gray8) -> Self {
        let (tw, th) = (tex.width as usize, tex.height as usize);
        let mut factor = 1;
        while (tw / factor).max(1) * (th / factor).max(1) > MAX_ANALYSIS_TEXELS {
            factor += 1;
        }
        let (w, h) = ((tw / factor).max(1), (th / factor).max(1));
        // Box-averaged intensity, then its logarithm (offset 8 DN keeps the
        // dark noise of a shadow from becoming gradient).
        let inten: Vec<f32> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let mut s = 0u32;
                let mut n = 0u32;
                for yy in y * factor..((y + 1) * factor).min(th) {
                    for xx in x * factor..((x + 1) * factor).min(tw) {
                        s += u32::from(tex.pixels.get(yy * tw + xx).copied().unwrap_or(0));
                        n += 1;
                    }
                }
                s as f32 / n.max(1) as f32
            })
            .collect();
        let log: Vec<f32> = inten.par_iter().map(|v| (v + 8.0).ln()).collect();
        let sat_inten = summed(&inten, w, h);
        // Shadow: below 0.4 of the mean of a window 2·R_SHADOW + 1 analysis
        // texels wide (a shadow's edge against its lit surroundings), or
        // below a third of the texture's median (inside a shadow wider than
        // that window: sky light alone is a small fraction of the sun's).
        const R_SHADOW: usize = 40;
        let median = {
            let mut hist = [0usize; 256];
            for &p in &tex.pixels {
                hist[usize::from(p)] += 1;
            }
            let mut seen = 0;
            let half = tex.pixels.len() / 2;
            hist.iter()
                .position(|&c| {
                    seen += c;
                    seen > half
                })
                .unwrap_or(0) as f32
        };
        let lit: Vec<u8> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let mean = box_mean(&sat_inten, w, h, x, y, R_SHADOW);
                u8::from(inten[i] >= 0.4 * mean && inten[i] >= median / 3.0)
            })
            .collect();
        // Gradient energy of the 3×3-smoothed log image, lit texels only.
        let smooth: Vec<f32> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let mut s = 0.0;
                for dy in [-1i64, 0, 1] {
                    for dx in [-1i64, 0, 1] {
                        s += log[clamp_idx(x, dx, w) + clamp_idx(y, dy, h) * w];
                    }
                }
                s / 9.0
            })
            .collect();
        let energy: Vec<f32> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let gx = 0.5
                    * (smooth[clamp_idx(x, 1, w) + y * w] - smooth[clamp_idx(x, -1, w) + y * w]);
                let gy = 0.5
                    * (smooth[x + clamp_idx(y, 1, h) * w] - smooth[x + clamp_idx(y, -1, h) * w]);
                f32::from(lit[i]) * (gx * gx + gy * gy)
            })
            .collect();
        let litf: Vec<f32> = lit.iter().map(|&l| f32::from(l)).collect();
        Self {
            w,
            h,
            factor,
            sat_energy: summed(&energy, w, h),
            sat_lit: summed(&litf, w, h),
        }
    }

    /// RMS gradient over the lit texels and the lit fraction of the square
    /// of half-side `r` around `p` (analysis texels).
    fn footprint(&self, p: [f32; 2], r: f32) -> (f32, f32) {
        let (w, h) = (self.w, self.h);
        let cx = p[0].round().clamp(0.0, (w - 1) as f32) as usize;
        let cy = p[1].round().clamp(0.0, (h - 1) as f32) as usize;
        let r = r.round() as usize;
        let (x0, x1) = (cx.saturating_sub(r), (cx + r + 1).min(w));
        let (y0, y1) = (cy.saturating_sub(r), (cy + r + 1).min(h));
        let area = ((x1 - x0) * (y1 - y0)) as f64;
        let lit = rect_sum(&self.sat_lit, w, x0, y0, x1, y1);
        let energy = rect_sum(&self.sat_energy, w, x0, y0, x1, y1);
        let structure = if lit > 0.0 {
            (energy / lit).sqrt() as f32
        } else {
            0.0
        };
        (structure, (lit / area.max(1.0)) as f32)
    }
}

/// The mesh's highest surface over an x-y grid: each triangle raises the
/// cells of its bounding box to its highest corner (a conservative
/// occluder, as a shadow's caster is).
struct HeightGrid {
    x0: f32,
    y0: f32,
    cell_m: f32,
    w: usize,
    h: usize,
    z: Vec<f32>,
}

impl HeightGrid {
    fn of(vertices: &[[f32; 3]], triangles: &[[u32; 3]], cell_m: f32) -> Self {
        let (lo, hi) = crate::io::mesh::bounds_of(vertices).unwrap_or(([0.0; 3], [0.0; 3]));
        let mut cell_m = cell_m;
        // At most 4096² cells.
        while ((hi[0] - lo[0]) / cell_m) * ((hi[1] - lo[1]) / cell_m) > 1.6e7 {
            cell_m *= 2.0;
        }
        let w = ((hi[0] - lo[0]) / cell_m).ceil() as usize + 1;
        let h = ((hi[1] - lo[1]) / cell_m).ceil() as usize + 1;
        let mut z = vec![f32::NEG_INFINITY; w * h];
        for t in triangles {
            let p = t.map(|k| vertices.get(k as usize).copied().unwrap_or(lo));
            let top = p[0][2].max(p[1][2]).max(p[2][2]);
            let cx = |x: f32| (((x - lo[0]) / cell_m) as usize).min(w - 1);
            let cy = |y: f32| (((y - lo[1]) / cell_m) as usize).min(h - 1);
            let (xa, xb) = (
                cx(p[0][0].min(p[1][0]).min(p[2][0])),
                cx(p[0][0].max(p[1][0]).max(p[2][0])),
            );
            let (ya, yb) = (
                cy(p[0][1].min(p[1][1]).min(p[2][1])),
                cy(p[0][1].max(p[1][1]).max(p[2][1])),
            );
            for y in ya..=yb {
                for x in xa..=xb {
                    let c = &mut z[y * w + x];
                    *c = c.max(top);
                }
            }
        }
        Self {
            x0: lo[0],
            y0: lo[1],
            cell_m,
            w,
            h,
            z,
        }
    }

    fn at(&self, x: f32, y: f32) -> Option<f32> {
        let fx = (x - self.x0) / self.cell_m;
        let fy = (y - self.y0) / self.cell_m;
        if !(fx >= 0.0 && fy >= 0.0) {
            return None;
        }
        let (cx, cy) = (fx as usize, fy as usize);
        (cx < self.w && cy < self.h)
            .then(|| self.z[cy * self.w + cx])
            .filter(|z| z.is_finite())
    }

    /// Fraction of 16 azimuths along which nothing within
    /// `opts.horizon_m` rises above `opts.horizon_deg` seen from `p`.
    fn exposure(&self, p: [f32; 3], opts: &ScoreOptions) -> f32 {
        const AZIMUTHS: usize = 16;
        let tan_max = opts.horizon_deg.to_radians().tan();
        let mut open = 0;
        for a in 0..AZIMUTHS {
            let phi = a as f32 * std::f32::consts::TAU / AZIMUTHS as f32;
            let (dx, dy) = (phi.cos(), phi.sin());
            let mut r = 2.0 * self.cell_m;
            let mut blocked = false;
            while r <= opts.horizon_m {
                if let Some(z) = self.at(p[0] + r * dx, p[1] + r * dy) {
                    // 5 mm above the point: its own surface's noise is not a horizon.
                    if z - p[2] - 0.005 > tan_max * r {
                        blocked = true;
                        break;
                    }
                }
                r *= 1.25;
            }
            open += usize::from(!blocked);
        }
        open as f32 / AZIMUTHS as f32
    }
}

fn clamp_idx(x: usize, d: i64, n: usize) -> usize {
    (x as i64 + d).clamp(0, n as i64 - 1) as usize
}

/// Summed-area table of a `w × h` plane: `(w + 1) · (h + 1)` entries.
fn summed(v: &[f32], w: usize, h: usize) -> Vec<f64> {
    let mut s = vec![0f64; (w + 1) * (h + 1)];
    for y in 0..h {
        let mut row = 0f64;
        for x in 0..w {
            row += f64::from(v[y * w + x]);
            s[(y + 1) * (w + 1) + x + 1] = s[y * (w + 1) + x + 1] + row;
        }
    }
    s
}

/// Sum over `[x0, x1) × [y0, y1)` of the plane behind `sat`.
fn rect_sum(sat: &[f64], w: usize, x0: usize, y0: usize, x1: usize, y1: usize) -> f64 {
    let at = |x: usize, y: usize| sat[y * (w + 1) + x];
    at(x1, y1) - at(x0, y1) - at(x1, y0) + at(x0, y0)
}

/// Mean of the plane behind `sat` over the square of half-side `r` at `(x, y)`.
fn box_mean(sat: &[f64], w: usize, h: usize, x: usize, y: usize, r: usize) -> f32 {
    let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
    let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
    let area = ((x1 - x0) * (y1 - y0)).max(1) as f64;
    (rect_sum(sat, w, x0, y0, x1, y1) / area) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::image::Gray8;

    /// A flat 1 m square of 2×2 quads over a 100×100 texture: left half
    /// textured (checker), right half uniform.
    fn square(texture: Gray8, z_right: f32) -> MeshData {
        strip(2, texture, z_right)
    }

    /// `cols` quads of 0.5 m along x by two along y, the last column of
    /// vertices raised `z_right`; the texture spans the whole strip.
    fn strip(cols: u32, texture: Gray8, z_right: f32) -> MeshData {
        let w = cols + 1;
        let mut vertices = Vec::new();
        for j in 0..3 {
            for i in 0..w {
                let z = if i == cols { z_right } else { 0.0 };
                vertices.push([i as f32 * 0.5, j as f32 * 0.5, z]);
            }
        }
        let mut triangles = Vec::new();
        let mut uvs = Vec::new();
        for j in 0..2u32 {
            for i in 0..cols {
                let a = j * w + i;
                for t in [[a, a + 1, a + w + 1], [a, a + w + 1, a + w]] {
                    triangles.push(t);
                    uvs.push(t.map(|k| {
                        let v = vertices[k as usize];
                        [v[0] / (0.5 * cols as f32), v[1]]
                    }));
                }
            }
        }
        let n = triangles.len();
        MeshData {
            vertices,
            triangles,
            uvs,
            mask: vec![true; n],
            texture,
            origin: [0.0; 3],
        }
    }

    fn half_textured() -> Gray8 {
        let mut t = Gray8::filled(100, 100, 128);
        for y in 0..100 {
            for x in 0..50 {
                t.pixels[y * 100 + x] = if (x / 2 + y / 2) % 2 == 0 { 60 } else { 200 };
            }
        }
        t
    }

    /// Verifies: VTSM-SIM-021
    #[test]
    fn texture_scores_above_a_uniform_surface() {
        let mesh = square(half_textured(), 0.0);
        let s = score_vertices(&mesh, &ScoreOptions::default());
        // Vertex 0 (x = 0) sits in the checker, vertex 2 (x = 1 m) on the
        // uniform half.
        assert!(s[0] > 100, "textured vertex scored {}", s[0]);
        assert_eq!(s[2], 1, "uniform vertex is floored at 1, got {}", s[2]);
    }

    /// Verifies: VTSM-SIM-021
    #[test]
    fn a_steep_flank_scores_less_than_the_same_texture_facing_up() {
        let tex = Gray8 {
            width: 100,
            height: 100,
            pixels: (0..100 * 100)
                .map(|i| {
                    if (i % 100 / 2 + i / 100 / 2) % 2 == 0 {
                        60
                    } else {
                        200
                    }
                })
                .collect(),
        };
        // Ten columns, the last rising 2 m over 0.5 m: the flank is a
        // minority of the surface, so the main facing stays up.
        let flat = vertex_terms(&strip(10, tex.clone(), 0.0), &ScoreOptions::default());
        let steep = vertex_terms(&strip(10, tex, 2.0), &ScoreOptions::default());
        // Vertex 10 is the top of the rise: its normal is 76° from the
        // vertical (the main facing leans some way towards the flank, which
        // holds 30 % of the area).
        assert!(flat[10].facing > 0.99);
        assert!(steep[10].facing < 0.5, "facing {}", steep[10].facing);
        assert!(steep[5].facing > 0.99, "facing {}", steep[5].facing);
    }

    /// Verifies: VTSM-SIM-021
    #[test]
    fn a_cast_shadow_is_not_counted_as_lit() {
        let mut tex = half_textured();
        // A dark band (a shadow) over the top-left quarter.
        for y in 0..40 {
            for x in 0..50 {
                tex.pixels[y * 100 + x] /= 5;
            }
        }
        let terms = vertex_terms(&square(tex, 0.0), &ScoreOptions::default());
        let lit = vertex_terms(&square(half_textured(), 0.0), &ScoreOptions::default());
        // Vertex 6 (0, 1 m) lies at texture row 0 under the shadow.
        assert!(terms[6].lit < 0.5, "lit {}", terms[6].lit);
        assert!(lit[6].lit > 0.9, "lit {}", lit[6].lit);
    }

    /// Verifies: VTSM-SIM-021
    #[test]
    fn a_point_at_the_foot_of_a_wall_is_less_exposed_than_one_in_the_open() {
        // The right column of vertices raised 0.3 m: a wall 0.5 m from the
        // left column, 0.25 m from... no vertex; vertex 1 (x = 0.5 m) sits
        // at its foot.
        let open = vertex_terms(&square(half_textured(), 0.0), &ScoreOptions::default());
        let wall = vertex_terms(&square(half_textured(), 0.3), &ScoreOptions::default());
        assert_eq!(open[1].exposure, 1.0);
        assert!(
            wall[1].exposure < 0.75,
            "exposure at the wall's foot {}",
            wall[1].exposure
        );
        // The wall's top sees over everything.
        assert_eq!(wall[2].exposure, 1.0);
    }

    /// Verifies: VTSM-SIM-021
    #[test]
    fn a_facade_is_scored_as_a_depot_is_whatever_its_orientation() {
        // The same square stood up as a wall facing −y (x, y, z) → (x, −z, y):
        // the terms must not depend on which way the map is "up".
        let mesh = square(half_textured(), 0.3);
        let wall = MeshData {
            vertices: mesh.vertices.iter().map(|p| [p[0], -p[2], p[1]]).collect(),
            ..mesh.clone()
        };
        let flat = vertex_terms(&mesh, &ScoreOptions::default());
        let stood = vertex_terms(&wall, &ScoreOptions::default());
        for (k, (a, b)) in flat.iter().zip(&stood).enumerate() {
            assert!(
                (a.facing - b.facing).abs() < 1e-3,
                "vertex {k}: {a:?} {b:?}"
            );
            assert_eq!(a.exposure, b.exposure, "vertex {k}");
        }
    }

    /// Verifies: VTSM-SIM-021
    #[test]
    fn vertices_outside_the_mask_score_zero() {
        let mut mesh = square(half_textured(), 0.0);
        mesh.mask.iter_mut().skip(2).for_each(|m| *m = false);
        let s = score_vertices(&mesh, &ScoreOptions::default());
        assert_eq!(s[8], 0);
        assert!(s[0] >= 1);
    }
}
