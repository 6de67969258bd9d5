//! The encoder: a mesh, texture and mask in memory ([`MapSource`]) to the
//! product bytes, tiled on a square grid with triangles ordered by tile, and
//! [`reseal`] to recompute the CRC after a deliberate change.
//!
//! Input: a [`MapSource`] within the config caps; output: the byte count
//! written into the caller's buffer ([`encoded_len`] gives it first). Bounded
//! by the vertex, triangle and tile caps; no allocation (the tile order is
//! derived in the output buffer itself).

use super::crc::crc32;
use super::format::*;
use crate::config::{MAX_MAP_TILES, MAX_MAP_TRIANGLES, MAX_MAP_VERTICES, MAX_TEXTURE_DIM};
use crate::failure::FailureCode;
use crate::geom::Vec3;
use crate::image::GrayView;

// ---- encoder -----------------------------------------------------------------

/// A textured mesh in memory, to be encoded into a map product.
#[derive(Clone, Copy, Debug)]
pub struct MapSource<'s> {
    /// Vertex positions, local metres (user frame minus `origin`).
    pub vertices: &'s [[f32; 3]],
    /// Triangles as vertex indices.
    pub triangles: &'s [[u32; 3]],
    /// Texture coordinates per triangle corner, OBJ convention: normalized [0, 1],
    /// v = 0 at the bottom row of the texture image.
    pub uvs: &'s [[[f32; 2]; 3]],
    /// Per triangle: member of the sampling mask M̂.
    pub mask: &'s [bool],
    /// Gray texture.
    pub texture: GrayView<'s>,
    /// Side of a tile of the x-y grid, metres.
    pub tile_size_m: f32,
    /// Origin of the local frame in the user frame, metres (see the module doc);
    /// must pass [`origin_ok`].
    pub origin: [f64; 3],
    /// Sampling score of each vertex (one per entry of `vertices`), or `None`.
    /// With scores the product is version 3 and carries the running sum of
    /// the mask vertices' scores, so mask vertices are drawn in proportion to
    /// them; without, it is version 2 (mask vertices drawn uniformly).
    /// Scores of vertices outside the mask are not stored.
    pub vertex_scores: Option<&'s [u8]>,
}

#[derive(Clone, Copy, Debug)]
pub(super) struct Plan {
    pub(super) min: Vec3,
    pub(super) max: Vec3,
    pub(super) tiles_x: u32,
    pub(super) tiles_y: u32,
    pub(super) layout: Layout,
}

impl Plan {
    #[allow(
        clippy::arithmetic_side_effects,
        clippy::cast_possible_truncation,
        reason = "float-to-int `as` saturates (NaN gives 0) before the clamp to the grid; tiles_x, tiles_y ≤ MAX_MAP_TILES"
    )]
    pub(super) fn cell_of(&self, x: f32, y: f32, tile: f32) -> usize {
        let cx = libm::floorf((x - self.min.x) / tile);
        let cy = libm::floorf((y - self.min.y) / tile);
        // Float-to-int `as` saturates and maps NaN to 0; the clamp keeps the cell in the grid.
        // `max(0)`: a plan always has a tile, but a clamp with its bounds the
        // wrong way round would panic.
        let cx = (cx as i64).clamp(0, (i64::from(self.tiles_x) - 1).max(0)) as usize;
        let cy = (cy as i64).clamp(0, (i64::from(self.tiles_y) - 1).max(0)) as usize;
        // Within the grid of at most MAX_MAP_TILES cells.
        cy.wrapping_mul(self.tiles_x as usize).wrapping_add(cx)
    }
}

pub(super) fn vertex_of(src: &MapSource, i: u32) -> Result<Vec3, FailureCode> {
    let p = src
        .vertices
        .get(i as usize)
        .ok_or(FailureCode::MapIndexOutOfRange)?;
    Ok(Vec3::new(p[0], p[1], p[2]))
}

#[allow(
    clippy::cast_possible_truncation,
    reason = "n is finite and ≤ MAX_MAP_TILES (checked just above) before the cast"
)]
pub(super) fn plan(src: &MapSource) -> Result<Plan, FailureCode> {
    use FailureCode as F;
    let (nv, nt) = (src.vertices.len(), src.triangles.len());
    if !(3..=MAX_MAP_VERTICES).contains(&nv) || !(1..=MAX_MAP_TRIANGLES).contains(&nt) {
        return Err(F::MapCountOutOfRange);
    }
    if src.uvs.len() != nt
        || src.mask.len() != nt
        || src.vertex_scores.is_some_and(|s| s.len() != nv)
    {
        return Err(F::MapInconsistent);
    }
    let (tw, th) = (src.texture.width(), src.texture.height());
    if tw > MAX_TEXTURE_DIM || th > MAX_TEXTURE_DIM {
        return Err(F::MapCountOutOfRange);
    }
    if !(src.tile_size_m.is_finite() && src.tile_size_m > 0.0) {
        return Err(F::MapTileSizeOutOfRange);
    }
    if !origin_ok(&src.origin) {
        return Err(F::MapOriginOutOfRange);
    }
    let mut min = Vec3::repeat(f32::INFINITY);
    let mut max = Vec3::repeat(f32::NEG_INFINITY);
    for p in src.vertices {
        let p = Vec3::new(p[0], p[1], p[2]);
        if !vec_finite(&p) {
            return Err(F::MapNonFinite);
        }
        min = min.inf(&p);
        max = max.sup(&p);
    }
    let mut mask_tris = 0usize;
    let mut surface = false;
    // Whether some vertex of a mask triangle has a positive score.
    let mut scored = false;
    let (tw_f, th_f) = (tw as f32, th as f32);
    for ((t, uv), m) in src.triangles.iter().zip(src.uvs).zip(src.mask) {
        if t.iter().any(|v| *v as usize >= nv) {
            return Err(F::MapIndexOutOfRange);
        }
        if !uv.iter().flatten().all(|c| c.is_finite()) {
            return Err(F::MapNonFinite);
        }
        // The texture-pixel coordinates `encode` writes (same expressions).
        if !uv
            .iter()
            .all(|st| uv_in_range(st[0] * tw_f - 0.5) && uv_in_range((1.0 - st[1]) * th_f - 0.5))
        {
            return Err(F::MapUvOutOfRange);
        }
        if !surface {
            let (a, b, c) = (
                vertex_of(src, t[0])?,
                vertex_of(src, t[1])?,
                vertex_of(src, t[2])?,
            );
            surface = has_area(&a, &b, &c);
        }
        mask_tris = mask_tris.saturating_add(usize::from(*m));
        if *m && !scored {
            scored = src
                .vertex_scores
                .is_some_and(|s| t.iter().any(|v| s.get(*v as usize).is_some_and(|x| *x > 0)));
        }
    }
    if !surface {
        return Err(F::MapNoSurface);
    }
    if src.vertex_scores.is_some() && mask_tris > 0 && !scored {
        return Err(F::MapBadScores);
    }
    let cells = |lo: f32, hi: f32| -> Result<u32, FailureCode> {
        let extent = hi - lo;
        if !extent.is_finite() {
            return Err(F::MapCountOutOfRange);
        }
        let n = libm::floorf(extent / src.tile_size_m) + 1.0;
        if !(n.is_finite() && n <= MAX_MAP_TILES as f32) {
            return Err(F::MapTileSizeOutOfRange);
        }
        Ok((n as u32).max(1))
    };
    let (tiles_x, tiles_y) = (cells(min.x, max.x)?, cells(min.y, max.y)?);
    let tiles = (tiles_x as usize).saturating_mul(tiles_y as usize);
    if tiles > MAX_MAP_TILES {
        return Err(F::MapTileSizeOutOfRange);
    }
    let masks_max = nv.min(mask_tris.saturating_mul(3));
    Ok(Plan {
        min,
        max,
        tiles_x,
        tiles_y,
        layout: Layout::new(header_len(src), nv, nt, tiles, masks_max, tw, th),
    })
}

/// The header length of the version `src` is written in: version 3 with
/// scores, version 2 without.
fn header_len(src: &MapSource) -> usize {
    if src.vertex_scores.is_some() {
        HEADER_LEN_V3
    } else {
        HEADER_LEN
    }
}

/// Size of the output buffer [`encode`] needs for `src`, in bytes. This is an
/// upper bound: it counts the mask-vertex list (and with scores, the score
/// section) at its largest, `min(vertices, 3 · mask triangles)` entries;
/// [`encode`] returns the exact length.
///
/// # Errors
/// As [`encode`], except [`FailureCode::MapEncodeBufferTooSmall`].
pub fn encoded_len(src: &MapSource) -> Result<usize, FailureCode> {
    Ok(plan(src)?.layout.total)
}

/// Encode `src` into `out` (at least [`encoded_len`] bytes) and return the
/// length of the product, `out[..n]`. No allocation: the per-tile counting sort
/// keeps its counters in the tile section and the mask-vertex deduplication marks
/// vertices in the vertex section before the vertices are written.
///
/// Triangles are grouped by the grid cell of their centroid (stable within a
/// cell); UVs are converted from OBJ convention to texture pixels (see [`Triangle`](super::Triangle)).
/// Without [`MapSource::vertex_scores`] the product is version 2; with them,
/// version 3 with the running sum of the mask vertices' scores, in mask order.
///
/// # Errors
/// [`FailureCode::MapCountOutOfRange`] (counts or texture size above the caps,
/// vertex extent beyond f32), [`FailureCode::MapTileSizeOutOfRange`] (tile size
/// not positive and finite, or a tile grid above `MAX_MAP_TILES`),
/// [`FailureCode::MapInconsistent`] (slice lengths disagree, scores included),
/// [`FailureCode::MapBadScores`] (scores given, and every vertex of every mask
/// triangle scores 0),
/// [`FailureCode::MapOriginOutOfRange`] (origin not finite or beyond ±[`MAX_MAP_ORIGIN_M`](crate::config::MAX_MAP_ORIGIN_M)),
/// [`FailureCode::MapNonFinite`], [`FailureCode::MapUvOutOfRange`] (a UV beyond
/// ±[`MAX_UV_PX`] texture pixels once converted), [`FailureCode::MapNoSurface`]
/// (every triangle has zero area), [`FailureCode::MapIndexOutOfRange`],
/// [`FailureCode::MapEncodeBufferTooSmall`]. Nothing is written on a check failure
/// other than the buffer-size one, which writes nothing either.
pub fn encode(src: &MapSource, out: &mut [u8]) -> Result<usize, FailureCode> {
    let plan = plan(src)?;
    let lay = plan.layout;
    let buf = out
        .get_mut(..lay.total)
        .ok_or(FailureCode::MapEncodeBufferTooSmall)?;
    buf.fill(0);
    let masks = write_vertices(src, &lay, buf)?;
    write_scores(src, &lay, masks, buf)?;
    let tiles = write_tiles_and_triangles(src, &plan, buf)?;
    write_texture(src, &lay, buf)?;
    write_header(src, &plan, tiles, masks, buf)
}

/// Offset of record `i` of `stride` bytes from `base`. Offsets stay within the
/// planned layout (≤ its total, the length of the buffer); saturating, so an
/// impossible overflow is a failed `get`, not a panic.
fn at(base: usize, i: usize, stride: usize) -> usize {
    base.saturating_add(i.saturating_mul(stride))
}

/// The mask-vertex list (one mark byte per vertex in the not yet written vertex
/// section, then the marked indices in order) and the vertex section. Returns
/// the number of mask vertices.
#[allow(
    clippy::cast_possible_truncation,
    reason = "vertex indices are below MAX_MAP_VERTICES < u32::MAX (checked by plan())"
)]
fn write_vertices(src: &MapSource, lay: &Layout, buf: &mut [u8]) -> Result<usize, FailureCode> {
    let (o_vert, o_mask) = (lay.off(SEC_VERTICES), lay.off(SEC_MASK));
    for (t, m) in src.triangles.iter().zip(src.mask) {
        if *m {
            for v in t {
                *buf.get_mut(o_vert.saturating_add(*v as usize))
                    .ok_or(FailureCode::MapEncodeBufferTooSmall)? = 1;
            }
        }
    }
    let mut masks = 0usize;
    for v in 0..src.vertices.len() {
        if buf.get(o_vert.saturating_add(v)).copied() == Some(1) {
            wr_u32(buf, at(o_mask, masks, MASK_VERTEX_BYTES), v as u32)?;
            masks = masks.saturating_add(1);
        }
    }
    for (i, p) in src.vertices.iter().enumerate() {
        wr_vec3(
            buf,
            at(o_vert, i, VERTEX_BYTES),
            &Vec3::new(p[0], p[1], p[2]),
        )?;
    }
    Ok(masks)
}

/// The score section, when `src` has scores: the running sum of the mask
/// vertices' scores in mask order, right after the `masks` entries of the
/// mask-vertex list (where the exact layout puts it; the planned layout
/// counted the list at its largest, so it fits).
fn write_scores(
    src: &MapSource,
    lay: &Layout,
    masks: usize,
    buf: &mut [u8],
) -> Result<(), FailureCode> {
    use FailureCode as F;
    let Some(scores) = src.vertex_scores else {
        return Ok(());
    };
    let o_mask = lay.off(SEC_MASK);
    let o_scores = at(o_mask, masks, MASK_VERTEX_BYTES);
    let mut cum = 0u32;
    for k in 0..masks {
        let v = rd_u32(buf, at(o_mask, k, MASK_VERTEX_BYTES)).ok_or(F::MapEncodeBufferTooSmall)?;
        let s = scores.get(v as usize).ok_or(F::MapIndexOutOfRange)?;
        // At most MAX_MAP_VERTICES · 255 < u32::MAX.
        cum = cum.saturating_add(u32::from(*s));
        wr_u32(buf, at(o_scores, k, MASK_SCORE_BYTES), cum)?;
    }
    Ok(())
}

/// The grid cell of triangle `t`'s centroid.
#[allow(
    clippy::arithmetic_side_effects,
    reason = "f32 arithmetic on checked finite vertices"
)]
fn centroid_cell(src: &MapSource, plan: &Plan, t: &[u32; 3]) -> Result<usize, FailureCode> {
    let (a, b, c) = (
        vertex_of(src, t[0])?,
        vertex_of(src, t[1])?,
        vertex_of(src, t[2])?,
    );
    let (x, y) = ((a.x + b.x + c.x) / 3.0, (a.y + b.y + c.y) / 3.0);
    Ok(plan.cell_of(x, y, src.tile_size_m))
}

/// The tile and triangle sections: a counting sort of the triangles by the
/// cell of their centroid (stable within a cell; the counters live in the
/// tiles' count fields), each tile's box grown over its triangles, a
/// degenerate box for an empty cell. Returns the tile count.
fn write_tiles_and_triangles(
    src: &MapSource,
    plan: &Plan,
    buf: &mut [u8],
) -> Result<usize, FailureCode> {
    let tiles = (plan.tiles_x as usize).saturating_mul(plan.tiles_y as usize);
    start_tiles(src, plan, tiles, buf)?;
    write_triangles(src, plan, buf)?;
    close_empty_tiles(plan, tiles, src.tile_size_m, buf)?;
    Ok(tiles)
}

/// Count the triangles of each tile, then give each tile its first slot, an
/// empty box and a zero count (the count is filled again as triangles land).
fn start_tiles(
    src: &MapSource,
    plan: &Plan,
    tiles: usize,
    buf: &mut [u8],
) -> Result<(), FailureCode> {
    let o_tiles = plan.layout.off(SEC_TILES);
    for t in src.triangles {
        let o = at(o_tiles, centroid_cell(src, plan, t)?, TILE_BYTES).saturating_add(28);
        let n = rd_u32(buf, o).ok_or(FailureCode::MapEncodeBufferTooSmall)?;
        // Counts stay ≤ the triangle count; saturating keeps an impossible
        // overflow an out-of-range slot (refused below) instead of a panic.
        wr_u32(buf, o, n.saturating_add(1))?;
    }
    let mut first = 0u32;
    for k in 0..tiles {
        let o = at(o_tiles, k, TILE_BYTES);
        let n = rd_u32(buf, o.saturating_add(28)).ok_or(FailureCode::MapEncodeBufferTooSmall)?;
        wr_vec3(buf, o, &Vec3::repeat(f32::INFINITY))?;
        wr_vec3(buf, o.saturating_add(12), &Vec3::repeat(f32::NEG_INFINITY))?;
        wr_u32(buf, o.saturating_add(24), first)?;
        wr_u32(buf, o.saturating_add(28), 0)?;
        first = first.saturating_add(n);
    }
    Ok(())
}

/// Each triangle (indices, flags, UVs converted from OBJ convention to texture
/// pixels) into the next slot of its tile, growing the tile's box.
#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "slots are below the triangle count (checked by plan()); f32 UV arithmetic"
)]
fn write_triangles(src: &MapSource, plan: &Plan, buf: &mut [u8]) -> Result<(), FailureCode> {
    use FailureCode as F;
    let lay = &plan.layout;
    let (o_tiles, o_tri, o_uv) = (lay.off(SEC_TILES), lay.off(SEC_TRIANGLES), lay.off(SEC_UVS));
    let (tw, th) = (src.texture.width() as f32, src.texture.height() as f32);
    for ((t, uv), m) in src.triangles.iter().zip(src.uvs).zip(src.mask) {
        let o = at(o_tiles, centroid_cell(src, plan, t)?, TILE_BYTES);
        let first = rd_u32(buf, o.saturating_add(24)).ok_or(F::MapEncodeBufferTooSmall)?;
        let n = rd_u32(buf, o.saturating_add(28)).ok_or(F::MapEncodeBufferTooSmall)?;
        wr_u32(buf, o.saturating_add(28), n.saturating_add(1))?;
        let slot = first.saturating_add(n) as usize;
        let mut lo = rd_vec3(buf, o).ok_or(F::MapEncodeBufferTooSmall)?;
        let mut hi = rd_vec3(buf, o.saturating_add(12)).ok_or(F::MapEncodeBufferTooSmall)?;
        let to = at(o_tri, slot, TRIANGLE_BYTES);
        let uo = at(o_uv, slot, UV_BYTES);
        for (c, (v, st)) in (0..3usize).zip(t.iter().zip(uv)) {
            let p = vertex_of(src, *v)?;
            lo = lo.inf(&p);
            hi = hi.sup(&p);
            wr_u32(buf, at(to, c, 4), *v)?;
            wr_f32(buf, at(uo, c, 8), st[0] * tw - 0.5)?;
            wr_f32(
                buf,
                at(uo, c, 8).saturating_add(4),
                (1.0 - st[1]) * th - 0.5,
            )?;
        }
        wr_u32(buf, to.saturating_add(12), if *m { FLAG_MASK } else { 0 })?;
        wr_vec3(buf, o, &lo)?;
        wr_vec3(buf, o.saturating_add(12), &hi)?;
    }
    Ok(())
}

/// Empty cells get a degenerate box at the cell's corner on the map floor.
#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "cell indices are below MAX_MAP_TILES (checked by plan()); f32 arithmetic"
)]
fn close_empty_tiles(
    plan: &Plan,
    tiles: usize,
    ts: f32,
    buf: &mut [u8],
) -> Result<(), FailureCode> {
    let o_tiles = plan.layout.off(SEC_TILES);
    for k in 0..tiles {
        let o = at(o_tiles, k, TILE_BYTES);
        if rd_u32(buf, o.saturating_add(28)) == Some(0) {
            let (cx, cy) = (
                // tiles_x ≥ 1 (the plan has a tile); checked forms keep the
                // division free of its zero-divisor panic path.
                k.checked_rem(plan.tiles_x as usize).unwrap_or(0) as f32,
                k.checked_div(plan.tiles_x as usize).unwrap_or(0) as f32,
            );
            let p = Vec3::new(
                (plan.min.x + cx * ts).min(plan.max.x),
                (plan.min.y + cy * ts).min(plan.max.y),
                plan.min.z,
            );
            wr_vec3(buf, o, &p)?;
            wr_vec3(buf, o.saturating_add(12), &p)?;
        }
    }
    Ok(())
}

/// The texture section, row by row.
fn write_texture(src: &MapSource, lay: &Layout, buf: &mut [u8]) -> Result<(), FailureCode> {
    let o_tex = lay.off(SEC_TEXTURE);
    let w = src.texture.width();
    for y in 0..src.texture.height() {
        let row = src.texture.row(y).ok_or(FailureCode::MapInconsistent)?;
        buf.get_mut(at(o_tex, y, w)..)
            .and_then(|d| d.get_mut(..row.len()))
            .ok_or(FailureCode::MapEncodeBufferTooSmall)?
            .copy_from_slice(row);
    }
    Ok(())
}

/// The header with the exact mask count, the section table with each
/// section's CRC (the entries of the version written), and the header CRC
/// last. Returns the product's length.
#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "counts and sizes are checked against the config capacities (all below u32::MAX) by plan() before they are written as u32; header offsets are constants of the layout (i < 11 fields, k < 3, header_len ≥ 4 + the fixed fields)"
)]
fn write_header(
    src: &MapSource,
    plan: &Plan,
    tiles: usize,
    masks: usize,
    buf: &mut [u8],
) -> Result<usize, FailureCode> {
    use FailureCode as F;
    let nv = src.vertices.len();
    let ts = src.tile_size_m;
    let header = header_len(src);
    let version = version_of(header);
    let real = Layout::new(
        header,
        nv,
        src.triangles.len(),
        tiles,
        masks,
        src.texture.width(),
        src.texture.height(),
    );
    buf.get_mut(0..8)
        .ok_or(F::MapEncodeBufferTooSmall)?
        .copy_from_slice(&MAGIC);
    let fields = [
        version,
        header as u32,
        nv as u32,
        src.triangles.len() as u32,
        tiles as u32,
        masks as u32,
        src.texture.width() as u32,
        src.texture.height() as u32,
        plan.tiles_x,
        plan.tiles_y,
        ts.to_bits(),
    ];
    for (i, f) in fields.iter().enumerate() {
        wr_u32(buf, 8 + 4 * i, *f)?;
    }
    wr_vec3(buf, 52, &plan.min)?;
    wr_vec3(buf, 64, &plan.max)?;
    for (k, c) in src.origin.iter().enumerate() {
        buf.get_mut(OFF_ORIGIN + 8 * k..OFF_ORIGIN + 8 * k + 8)
            .ok_or(F::MapEncodeBufferTooSmall)?
            .copy_from_slice(&c.to_le_bytes());
    }
    for (s, e) in real.sec.iter().zip(ENTRY_OFF).take(real.entries()) {
        let crc = crc32(
            buf.get(s.off..s.off.saturating_add(s.len))
                .ok_or(F::MapEncodeBufferTooSmall)?,
        );
        // e is an ENTRY_OFF constant: e + 4 and e + 8 never wrap.
        wr_u32(buf, e, s.off as u32)?;
        wr_u32(buf, e.wrapping_add(4), s.len as u32)?;
        wr_u32(buf, e.wrapping_add(8), crc)?;
    }
    let hcrc = crc32(buf.get(..header - 4).ok_or(F::MapEncodeBufferTooSmall)?);
    wr_u32(buf, header - 4, hcrc)?;
    Ok(real.total)
}

/// Recompute every CRC of a product in place (header last). For tools and tests
/// that edit a product on purpose; a product edited without this is rejected.
/// The header length and the number of section entries follow the version
/// field (an unknown version is treated as version 2).
///
/// # Errors
/// [`FailureCode::MapTruncated`] if `bytes` is shorter than its header or sections say.
#[allow(
    clippy::arithmetic_side_effects,
    reason = "header_len ≥ 4 + the fixed fields (header_len_of)"
)]
pub fn reseal(bytes: &mut [u8]) -> Result<(), FailureCode> {
    use FailureCode as F;
    let version = rd_u32(bytes, 8).ok_or(F::MapTruncated)?;
    let header_len = header_len_of(version).unwrap_or(HEADER_LEN);
    if bytes.len() < header_len {
        return Err(F::MapTruncated);
    }
    for e in ENTRY_OFF.into_iter().take(entries_of(header_len)) {
        let off = rd_u32(bytes, e).ok_or(F::MapTruncated)? as usize;
        let len = rd_u32(bytes, e.wrapping_add(4)).ok_or(F::MapTruncated)? as usize;
        let end = off.checked_add(len).ok_or(F::MapTruncated)?;
        let crc = crc32(bytes.get(off..end).ok_or(F::MapTruncated)?);
        wr_u32(bytes, e.wrapping_add(8), crc).map_err(|_| F::MapTruncated)?;
    }
    let hcrc = crc32(bytes.get(..header_len - 4).ok_or(F::MapTruncated)?);
    wr_u32(bytes, header_len - 4, hcrc).map_err(|_| F::MapTruncated)
}
