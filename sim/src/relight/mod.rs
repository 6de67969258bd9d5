//! Relighting a map's texture from the sun it was made under to the sun of
//! the live pairs (the paper's future work: "synthetically relight the depot
//! map on the fly").
//!
//! Input: a textured mesh ([`MeshData`]) as any tool exports it, the sun
//! direction at mapping time and the sun direction at capture time, both
//! unit vectors in the mesh's frame with `z` up. Nothing of the simulator's
//! truth (albedo, terrain, shadow maps) is read: the geometry is the map's
//! own mesh, so a photogrammetry map is relit the same way.
//!
//! The model is the one a gray, matte depot under a sun and a sky follows:
//! irradiance `E(p) = max(0, n·s) · lit_s(p) + a · (½ + ½ n_z)` (direct sun
//! on the surface normal `n`, cast shadow `lit_s` of the mesh, sky ambient
//! `a` on a surface tilted away from the zenith), and the texture is
//! `tone(albedo · E_map)` with a gamma `γ`. Relighting divides out the
//! mapping-time irradiance and multiplies in the capture-time one, texel by
//! texel: `t' = tone(g · lin(t) · E_cap / E_map)`, with one gain `g` that keeps
//! the mean linear radiance of the texture (NCC takes out any gain; `g` only
//! keeps the result inside 8 bits).
//!
//! - **Normals** are the mesh's own: area-weighted vertex normals,
//!   interpolated across each triangle (faces turned to the `+z` side).
//! - **Cast shadows** come from a shadow map of the mesh for each sun: an
//!   orthographic depth map along the sun direction on a grid of half the
//!   median edge length, each texel's point tested against it with a slope
//!   bias over 3 × 3 cells (a soft edge a cell wide).
//! - **Texels** are reached through the mesh's UVs (each triangle rasterized
//!   in texture space), so atlases from photogrammetry tools work; a texel
//!   no triangle covers keeps its value.
//!
//! Work: O(triangles + texels); bounded by [`MAX_SHADOW_CELLS`] per shadow
//! map and [`MAX_RELIGHT_TEXELS`] texels. Deterministic: one thread, fixed
//! order.
//!
//! What it cannot do is named in `fsw-docs/eval/relight.md`: shading at a
//! scale finer than the mesh (a 2 cm mesh of a 1 cm pebble), light scattered
//! between rocks, and a surface whose brightness depends on the view.

use crate::error::{Error, Result};
use crate::io::image::Gray8;
use crate::io::mesh::MeshData;
use crate::render::SKY_AMBIENT;
use vtsm_core::FailureCode;

/// Largest shadow map, cells (the cell grows to stay inside it).
pub const MAX_SHADOW_CELLS: usize = 4096 * 4096;
/// Largest texture relit, texels.
pub const MAX_RELIGHT_TEXELS: usize = 8192 * 8192;
/// Lowest sun elevation relit, degrees. The direct term under a lower sun is
/// a grazing sliver that the mesh's normals cannot resolve.
pub const MIN_SUN_ELEVATION_DEG: f32 = 1.0;

/// How a texture is relit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RelightOptions {
    /// Sky irradiance relative to the direct sun on a surface facing it.
    pub ambient: f32,
    /// Gamma of the texture's encoding (linear = (t / 255)^γ).
    pub gamma: f32,
    /// Largest factor a texel's linear radiance is multiplied by (a texel in
    /// a map-time shadow brought into the sun is noise times this).
    pub max_ratio: f32,
}

impl Default for RelightOptions {
    fn default() -> Self {
        Self {
            ambient: SKY_AMBIENT,
            gamma: 2.2,
            max_ratio: 8.0,
        }
    }
}

/// A sun direction: azimuth clockwise from the map's `+y` ("north") and
/// elevation above its `xy` plane, degrees.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SunAngles {
    /// Azimuth clockwise from `+y`, degrees.
    pub azimuth_deg: f32,
    /// Elevation above the `xy` plane, degrees.
    pub elevation_deg: f32,
}

impl From<&crate::render::Sun> for SunAngles {
    /// The angles of a simulated sun (same convention: azimuth clockwise
    /// from north = `+y`, elevation above the horizon).
    fn from(sun: &crate::render::Sun) -> Self {
        Self {
            azimuth_deg: sun.azimuth_deg,
            elevation_deg: sun.elevation_deg,
        }
    }
}

impl SunAngles {
    /// Unit vector towards the sun (`x` east, `y` north, `z` up).
    pub fn dir(self) -> [f32; 3] {
        let (e, a) = (
            self.elevation_deg.to_radians(),
            self.azimuth_deg.to_radians(),
        );
        [a.sin() * e.cos(), a.cos() * e.cos(), e.sin()]
    }

    /// Check the angles: finite, elevation in
    /// [[`MIN_SUN_ELEVATION_DEG`], 90].
    ///
    /// # Errors
    /// A one-line reason (the caller names the file and code).
    pub fn check(self) -> std::result::Result<Self, String> {
        if !(self.azimuth_deg.is_finite() && self.elevation_deg.is_finite()) {
            return Err("sun angles are not finite".into());
        }
        if !(MIN_SUN_ELEVATION_DEG..=90.0).contains(&self.elevation_deg) {
            return Err(format!(
                "sun elevation {}° is outside [{MIN_SUN_ELEVATION_DEG}, 90]°",
                self.elevation_deg
            ));
        }
        Ok(self)
    }

    /// Parse `AZ,EL` (degrees), as `--map-sun` takes it.
    ///
    /// # Errors
    /// Not two numbers, or [`SunAngles::check`] fails.
    pub fn parse(s: &str) -> std::result::Result<Self, String> {
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        let [a, e] = parts.as_slice() else {
            return Err(format!("expected AZIMUTH,ELEVATION in degrees, got {s:?}"));
        };
        let num = |t: &str| {
            t.parse::<f32>()
                .map_err(|_| format!("{t:?} is not a number of degrees"))
        };
        Self {
            azimuth_deg: num(a)?,
            elevation_deg: num(e)?,
        }
        .check()
    }
}

/// What a relighting did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RelightStats {
    /// Texels reached through a triangle (the others kept their value).
    pub texels_relit: usize,
    /// Texels whose ratio hit [`RelightOptions::max_ratio`].
    pub texels_clamped: usize,
    /// Cells of the map-time and the capture-time shadow maps.
    pub shadow_cells: [usize; 2],
    /// Fraction of the relit texels in the mesh's cast shadow at mapping
    /// and at capture time (lit < ½).
    pub shadowed: [f32; 2],
}

/// An orthographic depth map of a mesh along a sun direction.
struct ShadowMap {
    s: [f32; 3],
    e1: [f32; 3],
    e2: [f32; 3],
    origin: [f32; 2],
    cell: f32,
    nu: usize,
    nv: usize,
    /// Highest `p·s` (nearest the sun) per cell; `-inf` where nothing lies.
    depth: Vec<f32>,
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn unit(a: [f32; 3]) -> Option<[f32; 3]> {
    let n = dot(a, a).sqrt();
    (n.is_finite() && n > 0.0).then(|| a.map(|x| x / n))
}

/// Barycentric weights of `p` in the 2-D triangle `q` (`None`: degenerate).
fn barycentric(q: [[f32; 2]; 3], p: [f32; 2]) -> Option<[f32; 3]> {
    let d = (q[1][0] - q[0][0]) * (q[2][1] - q[0][1]) - (q[2][0] - q[0][0]) * (q[1][1] - q[0][1]);
    if d.abs() < 1e-12 {
        return None;
    }
    let w1 = ((p[0] - q[0][0]) * (q[2][1] - q[0][1]) - (q[2][0] - q[0][0]) * (p[1] - q[0][1])) / d;
    let w2 = ((q[1][0] - q[0][0]) * (p[1] - q[0][1]) - (p[0] - q[0][0]) * (q[1][1] - q[0][1])) / d;
    Some([1.0 - w1 - w2, w1, w2])
}

/// Visit the integer cells `(i, j)` whose centres `(i + ½, j + ½)` lie in the
/// 2-D triangle `q` (edges shared by two triangles are visited by both),
/// inside `[0, w) × [0, h)`, with their barycentric weights.
fn scan(q: [[f32; 2]; 3], w: usize, h: usize, mut f: impl FnMut(usize, usize, [f32; 3])) {
    let lo = |k: usize| q.iter().map(|p| p[k]).fold(f32::INFINITY, f32::min);
    let hi = |k: usize| q.iter().map(|p| p[k]).fold(f32::NEG_INFINITY, f32::max);
    if !(lo(0).is_finite() && hi(0).is_finite() && lo(1).is_finite() && hi(1).is_finite()) {
        return;
    }
    let i0 = (lo(0) - 0.5).ceil().max(0.0) as usize;
    let j0 = (lo(1) - 0.5).ceil().max(0.0) as usize;
    let i1 = ((hi(0) - 0.5).floor().min(w as f32 - 1.0)).max(-1.0);
    let j1 = ((hi(1) - 0.5).floor().min(h as f32 - 1.0)).max(-1.0);
    if i1 < 0.0 || j1 < 0.0 {
        return;
    }
    let (i1, j1) = (i1 as usize, j1 as usize);
    const EPS: f32 = -1e-5;
    for j in j0..=j1 {
        for i in i0..=i1 {
            let p = [i as f32 + 0.5, j as f32 + 0.5];
            if let Some(b) = barycentric(q, p) {
                if b.iter().all(|&x| x >= EPS) {
                    f(i, j, b);
                }
            }
        }
    }
}

impl ShadowMap {
    fn build(mesh: &MeshData, s: [f32; 3], cell: f32) -> Option<Self> {
        let helper = if s[2].abs() < 0.9 {
            [0.0, 0.0, 1.0]
        } else {
            [1.0, 0.0, 0.0]
        };
        let e1 = unit(cross(helper, s))?;
        let e2 = cross(s, e1);
        let proj = |p: [f32; 3]| [dot(p, e1), dot(p, e2)];
        let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for &v in &mesh.vertices {
            let q = proj(v);
            for k in 0..2 {
                lo[k] = lo[k].min(q[k]);
                hi[k] = hi[k].max(q[k]);
            }
        }
        if !(lo[0].is_finite() && hi[0].is_finite() && lo[1].is_finite() && hi[1].is_finite()) {
            return None;
        }
        let mut cell = cell.max(1e-4);
        // Saturating: a float cast saturates, and so does the margin.
        let dims = |c: f32| {
            (
                (((hi[0] - lo[0]) / c).ceil() as usize).saturating_add(3),
                (((hi[1] - lo[1]) / c).ceil() as usize).saturating_add(3),
            )
        };
        // The cell grows by 1.25 a step: 400 steps cover any finite extent.
        for _ in 0..400 {
            if dims(cell).0.saturating_mul(dims(cell).1) <= MAX_SHADOW_CELLS {
                break;
            }
            cell *= 1.25;
        }
        let (nu, nv) = dims(cell);
        if nu.saturating_mul(nv) > MAX_SHADOW_CELLS {
            return None;
        }
        let origin = [lo[0] - cell, lo[1] - cell];
        let mut map = Self {
            s,
            e1,
            e2,
            origin,
            cell,
            nu,
            nv,
            depth: vec![f32::NEG_INFINITY; nu * nv],
        };
        for t in &mesh.triangles {
            let p = t.map(|k| mesh.vertices[k as usize]);
            let q = p.map(|v| map.grid(v));
            let d = p.map(|v| dot(v, s));
            let (nu, depth) = (map.nu, &mut map.depth);
            scan(q, nu, nv, |i, j, b| {
                let z = b[0] * d[0] + b[1] * d[1] + b[2] * d[2];
                let c = &mut depth[j * nu + i];
                if z > *c {
                    *c = z;
                }
            });
        }
        Some(map)
    }

    /// Grid coordinates (cells) of `p`.
    fn grid(&self, p: [f32; 3]) -> [f32; 2] {
        [
            (dot(p, self.e1) - self.origin[0]) / self.cell,
            (dot(p, self.e2) - self.origin[1]) / self.cell,
        ]
    }

    /// Lit fraction of point `p` with normal `n`: the share of the 3 × 3
    /// cells around it whose nearest surface to the sun is not above `p`
    /// by more than the slope bias.
    fn lit(&self, p: [f32; 3], n: [f32; 3]) -> f32 {
        let cos = dot(n, self.s).clamp(0.05, 1.0);
        let tan = (1.0 - cos * cos).sqrt() / cos;
        let bias = self.cell * (1.0 + 2.0 * tan).min(20.0);
        let d = dot(p, self.s);
        let g = self.grid(p);
        let (ci, cj) = (g[0].floor() as i64, g[1].floor() as i64);
        let (mut lit, mut all) = (0u32, 0u32);
        for dj in -1..=1 {
            for di in -1..=1 {
                let (i, j) = (ci + di, cj + dj);
                if i < 0 || j < 0 || i >= self.nu as i64 || j >= self.nv as i64 {
                    continue;
                }
                all += 1;
                if self.depth[j as usize * self.nu + i as usize] <= d + bias {
                    lit += 1;
                }
            }
        }
        if all == 0 {
            1.0
        } else {
            lit as f32 / all as f32
        }
    }
}

/// The triangles of `mesh` in a canonical order (by vertex indices, then
/// UV bits): a mesh and the map product made from it (whose triangles come
/// in tile order) are relit bit for bit alike.
fn canonical_order(mesh: &MeshData) -> Vec<usize> {
    let mut order: Vec<usize> = (0..mesh.triangles.len().min(mesh.uvs.len())).collect();
    order.sort_by_key(|&i| (mesh.triangles[i], mesh.uvs[i].map(|c| c.map(f32::to_bits))));
    order
}

/// Area-weighted vertex normals, each face turned to `+z`, summed in
/// `order`.
fn vertex_normals(mesh: &MeshData, order: &[usize]) -> Vec<[f32; 3]> {
    let mut n = vec![[0.0f32; 3]; mesh.vertices.len()];
    for t in order.iter().map(|&i| &mesh.triangles[i]) {
        let p = t.map(|k| mesh.vertices[k as usize]);
        let a = [0, 1, 2].map(|k| p[1][k] - p[0][k]);
        let b = [0, 1, 2].map(|k| p[2][k] - p[0][k]);
        let mut f = cross(a, b);
        if f[2] < 0.0 {
            f = f.map(|x| -x);
        }
        for &k in t {
            let v = &mut n[k as usize];
            for c in 0..3 {
                v[c] += f[c];
            }
        }
    }
    n.into_iter()
        .map(|v| unit(v).unwrap_or([0.0, 0.0, 1.0]))
        .collect()
}

/// Half the median triangle edge length (the shadow maps' cell), metres,
/// over at most ~4096 triangles taken in `order`.
fn shadow_cell(mesh: &MeshData, order: &[usize]) -> f32 {
    let step = (order.len() / 4096).max(1);
    let mut e: Vec<f32> = order
        .iter()
        .step_by(step)
        .map(|&i| &mesh.triangles[i])
        .flat_map(|t| {
            let p = t.map(|k| mesh.vertices[k as usize]);
            [(0, 1), (1, 2), (2, 0)].map(|(a, b)| {
                let d = [0, 1, 2].map(|k| p[a][k] - p[b][k]);
                dot(d, d).sqrt()
            })
        })
        .filter(|x| x.is_finite() && *x > 0.0)
        .collect();
    e.sort_by(f32::total_cmp);
    e.get(e.len() / 2).map_or(0.01, |m| 0.5 * m)
}

/// Irradiance of a surface with normal `n`, lit fraction `lit`, under sun
/// `s` (relative to the direct sun on a surface facing it).
fn irradiance(s: [f32; 3], n: [f32; 3], lit: f32, ambient: f32) -> f32 {
    dot(n, s).max(0.0) * lit + ambient * (0.5 + 0.5 * n[2])
}

/// The texture of `mesh` relit from `map_sun` to `capture_sun` (see the
/// module doc).
///
/// # Errors
/// A sun angle out of range, a texture larger than [`MAX_RELIGHT_TEXELS`],
/// or a mesh with no extent (`CONFIG_PARAM_OUT_OF_RANGE` or
/// `MAP_NO_SURFACE`).
pub fn relight(
    mesh: &MeshData,
    map_sun: SunAngles,
    capture_sun: SunAngles,
    opts: &RelightOptions,
) -> Result<(Gray8, RelightStats)> {
    let code = FailureCode::ConfigParamOutOfRange;
    let map_sun = map_sun
        .check()
        .map_err(|e| Error::msg(format!("map sun: {e}")).with_code(code))?;
    let capture_sun = capture_sun
        .check()
        .map_err(|e| Error::msg(format!("capture sun: {e}")).with_code(code))?;
    let tex = &mesh.texture;
    let (w, h) = (tex.width as usize, tex.height as usize);
    if w.saturating_mul(h) > MAX_RELIGHT_TEXELS || tex.pixels.len() != w * h {
        return Err(Error::msg(format!(
            "a {w} × {h} texture is more than relighting takes ({MAX_RELIGHT_TEXELS} texels)"
        ))
        .with_code(code));
    }
    if !(opts.ambient > 0.0 && opts.gamma > 0.0 && opts.max_ratio >= 1.0) {
        return Err(Error::msg("relighting options out of range").with_code(code));
    }
    let order = canonical_order(mesh);
    let cell = shadow_cell(mesh, &order);
    let no_surface = || {
        Error::msg("the mesh has no extent to cast shadows").with_code(FailureCode::MapNoSurface)
    };
    let (sm, sc) = (map_sun.dir(), capture_sun.dir());
    let shadow_map = ShadowMap::build(mesh, sm, cell).ok_or_else(no_surface)?;
    let shadow_cap = ShadowMap::build(mesh, sc, cell).ok_or_else(no_surface)?;
    let normals = vertex_normals(mesh, &order);
    let lin_lut: Vec<f32> = (0..256)
        .map(|t| (t as f32 / 255.0).powf(opts.gamma))
        .collect();
    // Pass 1: the ratio E_cap / E_map at every texel a triangle reaches.
    let mut ratio = vec![f32::NAN; w * h];
    let mut stats = RelightStats {
        shadow_cells: [shadow_map.depth.len(), shadow_cap.depth.len()],
        ..RelightStats::default()
    };
    let (mut shadowed_map, mut shadowed_cap) = (0usize, 0usize);
    for (t, uv) in order.iter().map(|&i| (&mesh.triangles[i], &mesh.uvs[i])) {
        let p = t.map(|k| mesh.vertices[k as usize]);
        let n = t.map(|k| normals[k as usize]);
        let q = uv.map(|c| [c[0] * w as f32, (1.0 - c[1]) * h as f32]);
        scan(q, w, h, |i, j, b| {
            let r = &mut ratio[j * w + i];
            if !r.is_nan() {
                return;
            }
            let at = |v: &[[f32; 3]; 3]| {
                [0, 1, 2].map(|k| b[0] * v[0][k] + b[1] * v[1][k] + b[2] * v[2][k])
            };
            let (x, nn) = (at(&p), unit(at(&n)).unwrap_or([0.0, 0.0, 1.0]));
            let (lm, lc) = (shadow_map.lit(x, nn), shadow_cap.lit(x, nn));
            shadowed_map += usize::from(lm < 0.5);
            shadowed_cap += usize::from(lc < 0.5);
            let em = irradiance(sm, nn, lm, opts.ambient);
            let ec = irradiance(sc, nn, lc, opts.ambient);
            *r = ec / em;
        });
    }
    // Pass 2: one gain keeping the mean linear radiance, then the tone.
    let (mut sum_in, mut sum_out) = (0.0f64, 0.0f64);
    for (r, &t) in ratio.iter_mut().zip(&tex.pixels) {
        if r.is_nan() {
            continue;
        }
        stats.texels_relit += 1;
        if *r > opts.max_ratio {
            *r = opts.max_ratio;
            stats.texels_clamped += 1;
        }
        let l = f64::from(lin_lut[usize::from(t)]);
        sum_in += l;
        sum_out += l * f64::from(*r);
    }
    let gain = if sum_out > 0.0 {
        (sum_in / sum_out) as f32
    } else {
        1.0
    };
    let inv_gamma = 1.0 / opts.gamma;
    let pixels = ratio
        .iter()
        .zip(&tex.pixels)
        .map(|(&r, &t)| {
            if r.is_nan() {
                t
            } else {
                let l = (lin_lut[usize::from(t)] * r * gain).clamp(0.0, 1.0);
                (255.0 * l.powf(inv_gamma)).round() as u8
            }
        })
        .collect();
    let n = stats.texels_relit.max(1) as f32;
    stats.shadowed = [shadowed_map as f32 / n, shadowed_cap as f32 / n];
    Ok((
        Gray8 {
            width: tex.width,
            height: tex.height,
            pixels,
        },
        stats,
    ))
}

/// `mesh` with its texture relit ([`relight`]).
///
/// # Errors
/// As [`relight`].
pub fn relit_mesh(
    mesh: &MeshData,
    map_sun: SunAngles,
    capture_sun: SunAngles,
    opts: &RelightOptions,
) -> Result<(MeshData, RelightStats)> {
    let (texture, stats) = relight(mesh, map_sun, capture_sun, opts)?;
    Ok((
        MeshData {
            vertices: mesh.vertices.clone(),
            triangles: mesh.triangles.clone(),
            uvs: mesh.uvs.clone(),
            mask: mesh.mask.clone(),
            texture,
            origin: mesh.origin,
        },
        stats,
    ))
}

/// The textured mesh a checked map product holds: its vertices (local
/// frame), triangles (in the product's tile order), UVs (normalized, OBJ
/// convention), mask flags, texture and origin.
///
/// # Errors
/// A record the checked view cannot give (not expected of a checked
/// product), with `MAP_INCONSISTENT`.
pub fn mesh_of_product(view: &vtsm_core::map::MapView<'_>) -> Result<MeshData> {
    let bad =
        || Error::msg("map product record out of range").with_code(FailureCode::MapInconsistent);
    let vertices = (0..view.vertex_count())
        .map(|i| view.vertex(i).map(|v| [v.x, v.y, v.z]).ok_or_else(bad))
        .collect::<Result<Vec<_>>>()?;
    let tex = view.texture();
    let (w, h) = (tex.width() as f32, tex.height() as f32);
    let mut triangles = Vec::with_capacity(view.triangle_count() as usize);
    let mut uvs = Vec::with_capacity(triangles.capacity());
    let mut mask = Vec::with_capacity(triangles.capacity());
    for i in 0..view.triangle_count() {
        let t = view.triangle(i).ok_or_else(bad)?;
        triangles.push(t.v);
        uvs.push(t.uv.map(|c| [(c[0] + 0.5) / w, 1.0 - (c[1] + 0.5) / h]));
        mask.push(t.mask);
    }
    let mut pixels = Vec::with_capacity(tex.width() * tex.height());
    for y in 0..tex.height() {
        pixels.extend_from_slice(tex.row(y).ok_or_else(bad)?);
    }
    Ok(MeshData {
        vertices,
        triangles,
        uvs,
        mask,
        texture: Gray8 {
            width: tex.width() as u32,
            height: tex.height() as u32,
            pixels,
        },
        origin: view.origin(),
    })
}

/// The sampling score of every vertex of a scored product (0 off the
/// mask), as [`MeshData::encode_scored_map`] takes them; `None` for an
/// unscored product.
pub fn scores_of_product(view: &vtsm_core::map::MapView<'_>) -> Option<Vec<u8>> {
    if !view.scored() {
        return None;
    }
    let mut scores = vec![0u8; view.vertex_count() as usize];
    for k in 0..view.mask_vertex_count() {
        if let (Some(v), Some(s)) = (view.mask_vertex(k), view.mask_score(k)) {
            if let Some(slot) = scores.get_mut(v as usize) {
                *slot = s;
            }
        }
    }
    Some(scores)
}

/// A checked map product relit from `map_sun` to `capture_sun`: the
/// product's mesh and texture ([`mesh_of_product`]) relit and encoded again
/// with the product's tile size and scores.
///
/// # Errors
/// As [`relight`], or the encoder's failure code.
pub fn relit_product(
    view: &vtsm_core::map::MapView<'_>,
    map_sun: SunAngles,
    capture_sun: SunAngles,
    opts: &RelightOptions,
) -> Result<(Vec<u8>, RelightStats)> {
    let mesh = mesh_of_product(view)?;
    let (relit, stats) = relit_mesh(&mesh, map_sun, capture_sun, opts)?;
    let tile = view.tile_grid().2;
    let bytes = relit.encode_scored_map(tile, scores_of_product(view).as_deref())?;
    Ok((bytes, stats))
}

#[cfg(test)]
mod tests;
