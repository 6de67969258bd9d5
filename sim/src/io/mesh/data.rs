//! The textured mesh with its sampling mask ([`MeshData`]): a raw mesh given
//! its texture ([`MeshData::from_raw`], [`synthesize_atlas`]), the mask M̂
//! ([`MeshData::apply_mask`]) and the map product ([`MeshData::encode_map`]).
//! See the folder's doc ([`crate::io::mesh`]).

use super::raw::{check_capacity, CornerUvs, RawMesh};
use crate::error::{Error, Result};
use crate::io::image::Gray8;
use crate::io::json::short_number;
use std::collections::{BTreeMap, HashMap};
use std::path::Path;
use vtsm_core::config::{MAX_IMAGE_DIM, MAX_MAP_TILES};
use vtsm_core::map::{self, MapSource};
use vtsm_core::FailureCode;

/// Side, in texels, of the atlas cell synthesised for each triangle of a
/// vertex-coloured mesh.
pub const ATLAS_CELL_PX: u32 = 4;

/// Two vertices closer than this in every coordinate (metres) are the same
/// vertex when matching a mask mesh against a mesh.
pub const MASK_MATCH_TOL_M: f32 = 1.0e-4;

/// A textured triangle mesh with its sampling mask: the in-memory form of a
/// depot map before it is encoded as a map product.
///
/// Invariants (checked by [`MeshData::check`]): `triangles`, `uvs` and `mask`
/// have the same length; every index is below `vertices.len()`; all numbers are
/// finite; counts fit `u32`; the texture is non-empty, at most `MAX_IMAGE_DIM`
/// per side, and holds `width · height` bytes.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshData {
    /// Vertex positions, metres (z up) in the local frame: user frame minus `origin`.
    pub vertices: Vec<[f32; 3]>,
    /// Triangles as vertex indices.
    pub triangles: Vec<[u32; 3]>,
    /// Per-corner texture coordinates, normalised, OBJ convention (`v = 0` bottom).
    pub uvs: Vec<[[f32; 2]; 3]>,
    /// Whether each triangle belongs to the sampling mask M̂.
    pub mask: Vec<bool>,
    /// Gray texture, row 0 at the top.
    pub texture: Gray8,
    /// Origin of the local frame in the user frame, metres (`[0, 0, 0]` for
    /// the simulator's own scenes): `p_user = vertex + origin`, in f64.
    pub origin: [f64; 3],
}

/// What [`MeshData::apply_mask`] matched.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MaskStats {
    /// Triangles in the mask mesh.
    pub mask_triangles: usize,
    /// Mask triangles found in the mesh.
    pub matched: usize,
    /// Mesh triangles now in M̂ (several mesh triangles may share one key).
    pub marked: usize,
}

impl MeshData {
    /// Give a raw mesh its texture (see the module doc). `path` names errors.
    /// Every triangle starts in the mask M̂ (no mask mesh = sample everywhere).
    ///
    /// # Errors
    /// No texture and no vertex colour, a texture without texture coordinates,
    /// an atlas that would exceed `MAX_IMAGE_DIM`, or a failed [`MeshData::check`].
    pub fn from_raw(raw: RawMesh, path: &Path) -> Result<Self> {
        Self::from_raw_at(raw, path, None)
    }

    /// [`MeshData::from_raw`] with the map origin given (`None`:
    /// [`crate::frame::default_origin`] of the vertices).
    ///
    /// # Errors
    /// As [`MeshData::from_raw`], plus an unusable origin or a vertex out of f32
    /// range about it.
    pub fn from_raw_at(raw: RawMesh, path: &Path, origin: Option<[f64; 3]>) -> Result<Self> {
        let RawMesh {
            vertices,
            triangles,
            uvs,
            vertex_gray,
            texture,
        } = raw;
        if triangles.is_empty() {
            return Err(Error::file(path, "mesh has no faces"));
        }
        check_capacity(path, vertices.len(), triangles.len())?;
        let origin = origin.unwrap_or_else(|| crate::frame::default_origin(&vertices));
        let vertices = crate::frame::local_vertices(&vertices, origin)
            .map_err(|m| Error::file(path, m).with_code(FailureCode::MapOriginOutOfRange))?;
        let (uvs, texture) =
            match (texture, uvs, vertex_gray) {
                (Some(tex), Some(uvs), _) => (uvs, tex),
                (Some(_), None, _) => {
                    return Err(Error::file(
                        path,
                        "mesh names a texture but its faces have no texture coordinates",
                    ))
                }
                (None, _, Some(gray)) => {
                    synthesize_atlas(&triangles, &gray).map_err(|m| Error::file(path, m))?
                }
                (None, _, None) => return Err(Error::file(
                    path,
                    "mesh has neither a texture (MTL map_Kd / PLY TextureFile) nor vertex colours",
                )),
            };
        let mesh = Self {
            mask: vec![true; triangles.len()],
            vertices,
            triangles,
            uvs,
            texture,
            origin,
        };
        mesh.check().map_err(|m| Error::file(path, m))?;
        Ok(mesh)
    }

    /// Bilinear texture lookup at normalized `(u, v)` (OBJ convention), 0..255
    /// (0 outside a texture that does not hold `width · height` bytes).
    pub fn sample_texture(&self, u: f32, v: f32) -> f32 {
        let (w, h, t) = (
            self.texture.width,
            self.texture.height,
            &self.texture.pixels,
        );
        let fx = (u * w as f32 - 0.5).clamp(0.0, (w.max(1) - 1) as f32);
        let fy = ((1.0 - v) * h as f32 - 0.5).clamp(0.0, (h.max(1) - 1) as f32);
        let (i, j) = (fx.floor() as usize, fy.floor() as usize);
        let (i1, j1) = (
            (i + 1).min(w.max(1) as usize - 1),
            (j + 1).min(h.max(1) as usize - 1),
        );
        let (ax, ay) = (fx - i as f32, fy - j as f32);
        let g = |a: usize, b: usize| f32::from(t.get(b * w as usize + a).copied().unwrap_or(0));
        let top = g(i, j) + (g(i1, j) - g(i, j)) * ax;
        let bot = g(i, j1) + (g(i1, j1) - g(i, j1)) * ax;
        top + (bot - top) * ay
    }

    /// Check the invariants listed on [`MeshData`].
    ///
    /// # Errors
    /// A one-line reason.
    pub fn check(&self) -> std::result::Result<(), String> {
        let nv = self.vertices.len();
        let nt = self.triangles.len();
        if u32::try_from(nv).is_err() || u32::try_from(nt).is_err() {
            return Err(format!("too many vertices ({nv}) or triangles ({nt})"));
        }
        if self.uvs.len() != nt || self.mask.len() != nt {
            return Err(format!(
                "{} uv triples and {} mask flags for {nt} triangles",
                self.uvs.len(),
                self.mask.len()
            ));
        }
        if let Some(i) = self
            .vertices
            .iter()
            .position(|v| !v.iter().all(|c| c.is_finite()))
        {
            return Err(format!("vertex {} is not finite", i + 1));
        }
        if let Some(i) = self
            .triangles
            .iter()
            .position(|t| t.iter().any(|&k| k as usize >= nv))
        {
            return Err(format!(
                "triangle {} refers to a vertex beyond the {nv} vertices",
                i + 1
            ));
        }
        if let Some(i) = self
            .uvs
            .iter()
            .position(|t| !t.iter().flatten().all(|c| c.is_finite()))
        {
            return Err(format!(
                "texture coordinates of triangle {} are not finite",
                i + 1
            ));
        }
        let (w, h) = (self.texture.width as usize, self.texture.height as usize);
        if w == 0 || h == 0 || w > MAX_IMAGE_DIM || h > MAX_IMAGE_DIM {
            return Err(format!(
                "texture size {w}x{h} outside 1..={MAX_IMAGE_DIM} pixels per side"
            ));
        }
        if self.texture.pixels.len() != w * h {
            return Err("texture buffer does not match its size".to_string());
        }
        Ok(())
    }

    /// Mark as M̂ exactly the triangles that coincide with a triangle of `mask`
    /// (same three vertex positions within [`MASK_MATCH_TOL_M`], any order).
    ///
    /// # Errors
    /// When a triangle of `mask` is not found in the mesh, or `mask` has no
    /// triangle (`path` names the mask file; the message names the triangle).
    pub fn apply_mask(&mut self, mask: &RawMesh, path: &Path) -> Result<MaskStats> {
        // The mask's vertices in this mesh's local frame, converted exactly as its own.
        let mask_local = crate::frame::local_vertices(&mask.vertices, self.origin)
            .map_err(|m| Error::file(path, m))?;
        let index = VertexIndex::new(&self.vertices);
        // Canonical id of each mesh vertex: the lowest-numbered vertex at the same place,
        // so duplicated vertices (seams) do not split a triangle's identity.
        let canon: Vec<u32> = self
            .vertices
            .iter()
            .enumerate()
            .map(|(i, v)| index.find(v).unwrap_or(i as u32))
            .collect();
        let key_of = |t: &[u32; 3], ids: &dyn Fn(u32) -> Option<u32>| -> Option<[u32; 3]> {
            let mut k = [ids(t[0])?, ids(t[1])?, ids(t[2])?];
            k.sort_unstable();
            Some(k)
        };
        let mask_keys: Vec<Option<[u32; 3]>> = mask
            .triangles
            .iter()
            .map(|t| {
                let ids = |k: u32| mask_local.get(k as usize).and_then(|p| index.find(p));
                key_of(t, &ids)
            })
            .collect();
        // key -> whether some mesh triangle has it
        let mut wanted: BTreeMap<[u32; 3], bool> =
            mask_keys.iter().flatten().map(|k| (*k, false)).collect();
        let ids = |k: u32| canon.get(k as usize).copied();
        let mesh_keys: Vec<Option<[u32; 3]>> =
            self.triangles.iter().map(|t| key_of(t, &ids)).collect();
        for key in mesh_keys.iter().flatten() {
            if let Some(seen) = wanted.get_mut(key) {
                *seen = true;
            }
        }
        // Every mask triangle must be a mesh triangle: a stray one means the mask
        // was made from another mesh (or edited), and silently sampling a subset
        // of what was asked would hide that.
        for (k, (t, key)) in mask.triangles.iter().zip(&mask_keys).enumerate() {
            let found = key.is_some_and(|key| wanted.get(&key).copied().unwrap_or(false));
            if found {
                continue;
            }
            let why = t
                .iter()
                .find_map(|&v| {
                    let p = mask.vertices.get(v as usize)?;
                    let local = mask_local.get(v as usize)?;
                    index.find(local).is_none().then(|| {
                        format!(
                            "its vertex {} at ({}, {}, {}) is not a mesh vertex",
                            v + 1,
                            p[0],
                            p[1],
                            p[2]
                        )
                    })
                })
                .unwrap_or_else(|| "no mesh triangle has these three vertices".to_string());
            return Err(Error::file(
                path,
                format!(
                    "mask triangle {} (mask vertices {}, {}, {}) is not a triangle of the mesh: {why}",
                    k + 1,
                    t[0] + 1,
                    t[1] + 1,
                    t[2] + 1
                ),
            ));
        }
        if mask.triangles.is_empty() {
            return Err(Error::file(path, "the mask has no triangles"));
        }
        // Everything is checked before any flag changes, so a refused mask leaves
        // M̂ as it was.
        let mut marked = 0usize;
        for (key, m) in mesh_keys.iter().zip(self.mask.iter_mut()) {
            *m = key.is_some_and(|k| wanted.contains_key(&k));
            marked += usize::from(*m);
        }
        let matched = mask_keys
            .iter()
            .flatten()
            .filter(|k| wanted.get(*k).copied().unwrap_or(false))
            .count();
        Ok(MaskStats {
            mask_triangles: mask.triangles.len(),
            matched,
            marked,
        })
    }

    /// Number of triangles in M̂.
    pub fn mask_count(&self) -> usize {
        self.mask.iter().filter(|&&m| m).count()
    }

    /// Axis-aligned bounds `(min, max)` of the vertices, `None` when empty.
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        bounds_of(&self.vertices)
    }

    /// Encode the mesh as a map product (design §4) with tiles of `tile_size_m`.
    ///
    /// # Errors
    /// A failed [`MeshData::check`], a bad tile size, or the core encoder's failure code.
    pub fn encode_map(&self, tile_size_m: f32) -> Result<Vec<u8>> {
        self.encode_scored_map(tile_size_m, None)
    }

    /// [`Self::encode_map`] with one sampling score per vertex
    /// ([`crate::mapscore`]): a version-3 product whose SamplePoint draws
    /// in proportion to them (`None`: version 2, as `encode_map`).
    ///
    /// # Errors
    /// As `encode_map`; scores not one per vertex (`MAP_INCONSISTENT`) or
    /// zero on every mask vertex (`MAP_BAD_SCORES`).
    pub fn encode_scored_map(&self, tile_size_m: f32, scores: Option<&[u8]>) -> Result<Vec<u8>> {
        self.check().map_err(Error::msg)?;
        if !(tile_size_m.is_finite() && tile_size_m > 0.0) {
            return Err(Error::msg(format!(
                "tile size {tile_size_m} m is not a positive number"
            ))
            .with_code(FailureCode::MapTileSizeOutOfRange));
        }
        encode_with_core(self, tile_size_m, scores).map_err(|e| match e.code {
            Some(code) => self.explain(code, tile_size_m).unwrap_or(e),
            None => e,
        })
    }

    /// A message in the mesh's terms for the core encoder's failures that
    /// depend on a parameter or on the geometry as a whole.
    fn explain(&self, code: FailureCode, tile_size_m: f32) -> Option<Error> {
        let tag = format!("({}, 0x{:04x})", code.name(), code.code());
        let msg = match code {
            FailureCode::MapNoSurface => format!(
                "every one of the {} triangles has zero area: the mesh has no surface to render {tag}",
                self.triangles.len()
            ),
            FailureCode::MapTileSizeOutOfRange => {
                let (lo, hi) = self.bounds()?;
                // f32, as the core's encoder computes the grid.
                let (ex, ey) = (hi[0] - lo[0], hi[1] - lo[1]);
                let cells = |e: f32| f64::from((e / tile_size_m).floor() + 1.0);
                format!(
                    "tile size {tile_size_m} m gives a {} x {} tile grid over the mesh's \
                     {} x {} m extent, above the cap of {MAX_MAP_TILES} tiles; use a larger \
                     --tile-size-m {tag}",
                    short_number(cells(ex)),
                    short_number(cells(ey)),
                    short_number(f64::from(ex)),
                    short_number(f64::from(ey))
                )
            }
            FailureCode::MapUvOutOfRange => {
                let (tw, th) = (self.texture.width as f32, self.texture.height as f32);
                let k = self.uvs.iter().position(|t| {
                    !t.iter().all(|st| {
                        (st[0] * tw - 0.5).abs() <= map::MAX_UV_PX
                            && ((1.0 - st[1]) * th - 0.5).abs() <= map::MAX_UV_PX
                    })
                })?;
                format!(
                    "texture coordinates of triangle {} lie beyond {} texture pixels {tag}",
                    k + 1,
                    map::MAX_UV_PX
                )
            }
            _ => return None,
        };
        Some(Error::msg(msg).with_code(code))
    }
}

/// Axis-aligned bounds `(min, max)` of `vertices`, `None` when empty.
pub fn bounds_of(vertices: &[[f32; 3]]) -> Option<([f32; 3], [f32; 3])> {
    let first = *vertices.first()?;
    Some(vertices.iter().fold((first, first), |(lo, hi), v| {
        (
            [lo[0].min(v[0]), lo[1].min(v[1]), lo[2].min(v[2])],
            [hi[0].max(v[0]), hi[1].max(v[1]), hi[2].max(v[2])],
        )
    }))
}

/// The map encoder of `vtsm_core::map`: sizes the buffer, encodes, trims.
fn encode_with_core(mesh: &MeshData, tile_size_m: f32, scores: Option<&[u8]>) -> Result<Vec<u8>> {
    let texture = mesh.texture.view().map_err(Error::from)?;
    let src = MapSource {
        vertices: &mesh.vertices,
        triangles: &mesh.triangles,
        uvs: &mesh.uvs,
        mask: &mesh.mask,
        texture,
        tile_size_m,
        origin: mesh.origin,
        vertex_scores: scores,
    };
    let len = map::encoded_len(&src).map_err(Error::from)?;
    let mut out = vec![0u8; len];
    let n = map::encode(&src, &mut out).map_err(Error::from)?;
    out.truncate(n);
    Ok(out)
}

/// Vertices bucketed on a grid of [`MASK_MATCH_TOL_M`] cells, for matching by position.
struct VertexIndex<'a> {
    vertices: &'a [[f32; 3]],
    // Only looked up, never iterated, so a hash map keeps results deterministic.
    cells: HashMap<[i64; 3], Vec<u32>>,
}

impl<'a> VertexIndex<'a> {
    fn cell(p: &[f32; 3]) -> [i64; 3] {
        // f64 so that the division is exact enough at any depot coordinate; the cast
        // saturates for absurd values, which then simply match nothing.
        let q = f64::from(MASK_MATCH_TOL_M);
        [
            (f64::from(p[0]) / q).floor() as i64,
            (f64::from(p[1]) / q).floor() as i64,
            (f64::from(p[2]) / q).floor() as i64,
        ]
    }

    fn new(vertices: &'a [[f32; 3]]) -> Self {
        let mut cells: HashMap<[i64; 3], Vec<u32>> = HashMap::with_capacity(vertices.len());
        for (i, v) in vertices.iter().enumerate() {
            cells.entry(Self::cell(v)).or_default().push(i as u32);
        }
        Self { vertices, cells }
    }

    /// The lowest-numbered vertex within the tolerance of `p`, if any.
    fn find(&self, p: &[f32; 3]) -> Option<u32> {
        let c = Self::cell(p);
        let mut best: Option<u32> = None;
        for dx in -1i64..=1 {
            for dy in -1i64..=1 {
                for dz in -1i64..=1 {
                    let key = [
                        c[0].saturating_add(dx),
                        c[1].saturating_add(dy),
                        c[2].saturating_add(dz),
                    ];
                    for &i in self.cells.get(&key).into_iter().flatten() {
                        let near = self.vertices.get(i as usize).is_some_and(|v| {
                            v.iter()
                                .zip(p.iter())
                                .all(|(a, b)| (a - b).abs() <= MASK_MATCH_TOL_M)
                        });
                        if near && best.is_none_or(|b| i < b) {
                            best = Some(i);
                        }
                    }
                }
            }
        }
        best
    }
}

/// Build a texture atlas for a vertex-coloured mesh: one [`ATLAS_CELL_PX`]² cell
/// per triangle, cells laid out row by row in a square-ish image. Returns the
/// per-corner uvs and the texture.
///
/// # Errors
/// When the atlas would exceed `MAX_IMAGE_DIM` per side, or a triangle refers to
/// a vertex without a colour.
pub fn synthesize_atlas(
    triangles: &[[u32; 3]],
    vertex_gray: &[u8],
) -> std::result::Result<(Vec<CornerUvs>, Gray8), String> {
    let n = triangles.len().max(1);
    let cell = ATLAS_CELL_PX as usize;
    let mut cols = 1usize;
    while cols * cols < n {
        cols += 1;
    }
    let rows = n.div_ceil(cols);
    let (w, h) = (cols * cell, rows * cell);
    if w > MAX_IMAGE_DIM || h > MAX_IMAGE_DIM {
        return Err(format!(
            "{} triangles need a {w}x{h} colour atlas, above {MAX_IMAGE_DIM} pixels per side",
            triangles.len()
        ));
    }
    let mut tex = Gray8::filled(w as u32, h as u32, 0);
    let mut uvs = Vec::with_capacity(triangles.len());
    let last = (cell - 1) as f32;
    for (k, t) in triangles.iter().enumerate() {
        let mut g = [0f32; 3];
        for (gi, &vi) in g.iter_mut().zip(t.iter()) {
            *gi = f32::from(*vertex_gray.get(vi as usize).ok_or_else(|| {
                format!(
                    "triangle {} refers to vertex {} which has no colour",
                    k + 1,
                    vi + 1
                )
            })?);
        }
        let (x0, y0) = ((k % cols) * cell, (k / cols) * cell);
        // Corners at the centres of texels (0,0), (cell−1,0), (0,cell−1) of the cell.
        let corner =
            |i: usize, j: usize| -> [f32; 2] { [(x0 + i) as f32 + 0.5, (y0 + j) as f32 + 0.5] };
        let px = [corner(0, 0), corner(cell - 1, 0), corner(0, cell - 1)];
        uvs.push(px.map(|[x, y]| [x / w as f32, 1.0 - y / h as f32]));
        for j in 0..cell {
            for i in 0..cell {
                let (mut s, mut t2) = (i as f32 / last, j as f32 / last);
                if s + t2 > 1.0 {
                    // Outside the triangle: the value at the nearest point of its long edge.
                    let sum = s + t2;
                    s /= sum;
                    t2 /= sum;
                }
                let v = (1.0 - s - t2) * g[0] + s * g[1] + t2 * g[2];
                let idx = (y0 + j) * w + x0 + i;
                if let Some(p) = tex.pixels.get_mut(idx) {
                    *p = v.round().clamp(0.0, 255.0) as u8;
                }
            }
        }
    }
    Ok((uvs, tex))
}
