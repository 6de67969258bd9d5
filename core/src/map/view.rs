//! The checked read-only view of an encoded map ([`MapView`]) and its records
//! ([`Triangle`], [`Tile`]).
//!
//! Input: the product's bytes; [`MapView::new_checked`] verifies the header,
//! the CRC, the section layout and every record once, in time linear in the
//! product, so the accessors afterwards only bound-check an index. Output:
//! vertices, triangles, tiles, texture and mask as values, never a panic, and
//! (version 3) draws of a mask vertex in proportion to its score, a binary
//! search of at most 33 steps.

use super::crc::crc32;
use super::format::*;
use crate::config::{MAX_MAP_TILES, MAX_MAP_TRIANGLES, MAX_MAP_VERTICES, MAX_TEXTURE_DIM};
use crate::failure::FailureCode;
use crate::geom::Vec3;
use crate::image::GrayView;

// ---- public records ----------------------------------------------------------

/// One triangle of the map.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Triangle {
    /// Vertex indices (validated `< vertex_count`).
    pub v: [u32; 3],
    /// Texture coordinates per corner, in texture pixels: x right, y down,
    /// pixel centres on integers (so `(0,0)` is the centre of the top-left texel).
    pub uv: [[f32; 2]; 3],
    /// Member of the sampling mask M̂.
    pub mask: bool,
}

/// One tile: a contiguous run of triangles and the 3D box that bounds them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tile {
    /// Lower corner of the box, world metres.
    pub min: Vec3,
    /// Upper corner of the box, world metres.
    pub max: Vec3,
    /// Index of the tile's first triangle.
    pub first_triangle: u32,
    /// Number of triangles in the tile (may be 0 for an empty grid cell).
    pub triangle_count: u32,
}

#[cfg(feature = "defmt")]
impl defmt::Format for Tile {
    fn format(&self, f: defmt::Formatter) {
        defmt::write!(
            f,
            "Tile {{ min: [{}, {}, {}], max: [{}, {}, {}], first_triangle: {}, triangle_count: {} }}",
            self.min.x,
            self.min.y,
            self.min.z,
            self.max.x,
            self.max.y,
            self.max.z,
            self.first_triangle,
            self.triangle_count
        );
    }
}

/// A validated map product. Construction checks everything once; afterwards
/// every accessor is O(1) (a draw, [`Self::draw_mask_index`], a binary search),
/// cannot panic and returns `None` only for an index outside its count (or a
/// draw from a product without scores).
#[derive(Clone, Copy, Debug)]
pub struct MapView<'a> {
    pub(super) bytes: &'a [u8],
    pub(super) layout: Layout,
    pub(super) vertex_count: u32,
    pub(super) triangle_count: u32,
    pub(super) tile_count: u32,
    pub(super) mask_vertex_count: u32,
    pub(super) tiles_x: u32,
    pub(super) tiles_y: u32,
    pub(super) tile_size_m: f32,
    pub(super) min: Vec3,
    pub(super) max: Vec3,
    pub(super) origin: [f64; 3],
    pub(super) texture: GrayView<'a>,
    /// Sum of the mask vertices' scores (the last entry of the score
    /// section); 0 without one.
    pub(super) score_total: u32,
}

impl<'a> MapView<'a> {
    /// Check a map product and return a view of it.
    ///
    /// Checks, in order: length of the header ([`FailureCode::MapTruncated`]),
    /// magic ([`FailureCode::MapBadMagic`]), version 1, 2 or 3 ([`FailureCode::MapUnsupportedVersion`]),
    /// header CRC ([`FailureCode::MapCrcMismatch`]), the origin (versions 2 and 3:
    /// [`FailureCode::MapOriginOutOfRange`] unless [`origin_ok`]), counts against the `config`
    /// caps ([`FailureCode::MapCountOutOfRange`]), section table against the
    /// layout implied by the counts ([`FailureCode::MapInconsistent`]), total length
    /// ([`FailureCode::MapTruncated`] if short, [`FailureCode::MapInconsistent`] if
    /// trailing bytes), section CRCs, then content: finite vertices, UVs and
    /// bounds ([`FailureCode::MapNonFinite`]), UVs within ±[`MAX_UV_PX`]
    /// ([`FailureCode::MapUvOutOfRange`]), vertex and triangle indices
    /// ([`FailureCode::MapIndexOutOfRange`]), at least one triangle of non-zero
    /// area ([`FailureCode::MapNoSurface`]), tile runs covering the triangles in
    /// order, boxes bounding their triangles, vertices inside the header bounds,
    /// triangle flags, strictly increasing mask vertices ([`FailureCode::MapInconsistent`]),
    /// and in version 3 the score section: non-decreasing running sums, each
    /// step at most [`MAX_MASK_SCORE`], a positive total when there are mask
    /// vertices ([`FailureCode::MapBadScores`]).
    ///
    /// # Errors
    /// The first failed check's code, as above.
    #[allow(
        clippy::arithmetic_side_effects,
        clippy::cast_possible_truncation,
        reason = "capacities from config are below u32::MAX; header offsets are constants of the layout (i < SECTIONS, k < 3, header_len from header_len_of ≥ 4 + the fixed fields), and the tile product is formed in u64 from two u32"
    )]
    pub fn new_checked(bytes: &'a [u8]) -> Result<Self, FailureCode> {
        use FailureCode as F;
        let (version, header_len) = check_header(bytes)?;
        let h = |off: usize| rd_u32(bytes, off).ok_or(F::MapTruncated);
        let origin = if version == 1 {
            [0.0; 3]
        } else {
            let c = |k: usize| rd_f64(bytes, OFF_ORIGIN + 8 * k).ok_or(F::MapTruncated);
            [c(0)?, c(1)?, c(2)?]
        };
        if !origin_ok(&origin) {
            return Err(F::MapOriginOutOfRange);
        }
        let (vc, tc, kc, mc) = (h(16)?, h(20)?, h(24)?, h(28)?);
        let (tw, th, tx, ty) = (h(32)?, h(36)?, h(40)?, h(44)?);
        let counts_ok = (3..=MAX_MAP_VERTICES as u32).contains(&vc)
            && (1..=MAX_MAP_TRIANGLES as u32).contains(&tc)
            && (1..=MAX_MAP_TILES as u32).contains(&kc)
            && mc <= vc
            && (1..=MAX_TEXTURE_DIM as u32).contains(&tw)
            && (1..=MAX_TEXTURE_DIM as u32).contains(&th)
            && (1..=MAX_MAP_TILES as u32).contains(&tx)
            && (1..=MAX_MAP_TILES as u32).contains(&ty);
        if !counts_ok {
            return Err(F::MapCountOutOfRange);
        }
        if u64::from(tx) * u64::from(ty) != u64::from(kc) {
            return Err(F::MapInconsistent);
        }
        let tile_size_m = f32::from_bits(h(48)?);
        let min = rd_vec3(bytes, 52).ok_or(F::MapTruncated)?;
        let max = rd_vec3(bytes, 64).ok_or(F::MapTruncated)?;
        if !(tile_size_m.is_finite() && vec_finite(&min) && vec_finite(&max)) {
            return Err(F::MapNonFinite);
        }
        if tile_size_m <= 0.0 || !(min.x <= max.x && min.y <= max.y && min.z <= max.z) {
            return Err(F::MapInconsistent);
        }
        let layout = Layout::new(
            header_len,
            vc as usize,
            tc as usize,
            kc as usize,
            mc as usize,
            tw as usize,
            th as usize,
        );
        check_sections(bytes, &layout)?;
        let tex_sec = layout.sec.get(SEC_TEXTURE).copied().unwrap_or_default();
        let tex_bytes = bytes
            .get(tex_sec.off..tex_sec.off.saturating_add(tex_sec.len))
            .ok_or(F::MapTruncated)?;
        let texture = GrayView::new(tex_bytes, tw as usize, th as usize, tw as usize)
            .map_err(|_| F::MapCountOutOfRange)?;
        let mut view = Self {
            bytes,
            layout,
            vertex_count: vc,
            triangle_count: tc,
            tile_count: kc,
            mask_vertex_count: mc,
            tiles_x: tx,
            tiles_y: ty,
            tile_size_m,
            min,
            max,
            origin,
            texture,
            score_total: 0,
        };
        view.check_content()?;
        view.score_total = view.check_scores()?;
        Ok(view)
    }

    /// The score section of a version-3 product: running sums that never
    /// decrease, by at most [`MAX_MASK_SCORE`] per mask vertex, to a positive
    /// total when there are mask vertices. Returns the total (0 without a
    /// score section).
    ///
    /// # Errors
    /// [`FailureCode::MapBadScores`]; [`FailureCode::MapTruncated`] for an
    /// entry outside the bytes (a checked layout never has one).
    fn check_scores(&self) -> Result<u32, FailureCode> {
        use FailureCode as F;
        if !self.layout.scored() {
            return Ok(0);
        }
        let mut prev = 0u32;
        for k in 0..self.mask_vertex_count {
            let cum = self.cumulative(k).ok_or(F::MapTruncated)?;
            let step = cum.checked_sub(prev).ok_or(F::MapBadScores)?;
            if step > MAX_MASK_SCORE {
                return Err(F::MapBadScores);
            }
            prev = cum;
        }
        if self.mask_vertex_count > 0 && prev == 0 {
            return Err(F::MapBadScores);
        }
        Ok(prev)
    }

    #[allow(
        clippy::cast_possible_truncation,
        reason = "i < triangle_count, itself a u32"
    )]
    pub(super) fn check_content(&self) -> Result<(), FailureCode> {
        use FailureCode as F;
        for i in 0..self.vertex_count {
            let p = self.vertex(i).ok_or(F::MapTruncated)?;
            if !vec_finite(&p) {
                return Err(F::MapNonFinite);
            }
            if !inside(&p, &self.min, &self.max) {
                return Err(F::MapInconsistent);
            }
        }
        let tri_off = self.layout.off(SEC_TRIANGLES);
        // Whether some triangle has non-zero area (checked until one has).
        let mut surface = false;
        for i in 0..self.triangle_count as usize {
            let flags = record_at(tri_off, i as u32, TRIANGLE_BYTES)
                .and_then(|o| rd_u32(self.bytes, o.checked_add(12)?))
                .ok_or(F::MapTruncated)?;
            if flags & !FLAG_MASK != 0 {
                return Err(F::MapInconsistent);
            }
            let t = self.triangle(i as u32).ok_or(F::MapTruncated)?;
            if t.v.iter().any(|v| *v >= self.vertex_count) {
                return Err(F::MapIndexOutOfRange);
            }
            if !t.uv.iter().flatten().all(|c| c.is_finite()) {
                return Err(F::MapNonFinite);
            }
            if !t.uv.iter().flatten().all(|c| uv_in_range(*c)) {
                return Err(F::MapUvOutOfRange);
            }
            if !surface {
                let w = self
                    .triangle_vertices(i as u32)
                    .ok_or(F::MapIndexOutOfRange)?;
                surface = has_area(&w[0], &w[1], &w[2]);
            }
        }
        if !surface {
            return Err(F::MapNoSurface);
        }
        let mut next = 0u32;
        for k in 0..self.tile_count {
            let tile = self.tile(k).ok_or(F::MapTruncated)?;
            if !(vec_finite(&tile.min) && vec_finite(&tile.max)) {
                return Err(F::MapNonFinite);
            }
            if tile.first_triangle != next {
                return Err(F::MapInconsistent);
            }
            let end = tile
                .first_triangle
                .checked_add(tile.triangle_count)
                .filter(|e| *e <= self.triangle_count)
                .ok_or(F::MapIndexOutOfRange)?;
            for i in tile.first_triangle..end {
                let t = self.triangle(i).ok_or(F::MapTruncated)?;
                for v in t.v {
                    let p = self.vertex(v).ok_or(F::MapIndexOutOfRange)?;
                    if !inside(&p, &tile.min, &tile.max) {
                        return Err(F::MapInconsistent);
                    }
                }
            }
            next = end;
        }
        if next != self.triangle_count {
            return Err(F::MapInconsistent);
        }
        let mut prev: Option<u32> = None;
        for k in 0..self.mask_vertex_count {
            let v = self.mask_vertex(k).ok_or(F::MapTruncated)?;
            if v >= self.vertex_count {
                return Err(F::MapIndexOutOfRange);
            }
            if prev.is_some_and(|p| v <= p) {
                return Err(F::MapInconsistent);
            }
            prev = Some(v);
        }
        Ok(())
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> u32 {
        self.vertex_count
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> u32 {
        self.triangle_count
    }

    /// Number of tiles (`tiles_x · tiles_y`, empty cells included).
    pub fn tile_count(&self) -> u32 {
        self.tile_count
    }

    /// Tiling grid: cells along x, cells along y, cell size in metres.
    pub fn tile_grid(&self) -> (u32, u32, f32) {
        (self.tiles_x, self.tiles_y, self.tile_size_m)
    }

    /// Bounds of all vertices (min, max), local metres.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (self.min, self.max)
    }

    /// Origin of the local frame in the mesh's own (user) frame, metres:
    /// `p_user = p_local + origin`, in f64. `[0, 0, 0]` for a version-1 product.
    pub fn origin(&self) -> [f64; 3] {
        self.origin
    }

    /// Format version of the product (1, 2 or 3).
    pub fn version(&self) -> u32 {
        version_of(self.layout.header_len())
    }

    /// Vertex `i` in local metres.
    #[inline]
    pub fn vertex(&self, i: u32) -> Option<Vec3> {
        if i >= self.vertex_count {
            return None;
        }
        rd_vec3(
            self.bytes,
            record_at(self.layout.off(SEC_VERTICES), i, VERTEX_BYTES)?,
        )
    }

    /// Triangle `i` with its UVs and mask bit.
    #[inline]
    #[allow(
        clippy::arithmetic_side_effects,
        reason = "k < 3 corner index: the field offsets are small constants"
    )]
    pub fn triangle(&self, i: u32) -> Option<Triangle> {
        if i >= self.triangle_count {
            return None;
        }
        let t = record_at(self.layout.off(SEC_TRIANGLES), i, TRIANGLE_BYTES)?;
        let u = record_at(self.layout.off(SEC_UVS), i, UV_BYTES)?;
        let b = self.bytes;
        // One bounds check per record; the fields then sit at constant offsets.
        let tri: &[u8; TRIANGLE_BYTES] = b.get(t..)?.first_chunk()?;
        let uvs: &[u8; UV_BYTES] = b.get(u..)?.first_chunk()?;
        let c = |k: usize| -> Option<[f32; 2]> {
            let at = uvs.get(8 * k..)?;
            Some([rd_f32(at, 0)?, rd_f32(at, 4)?])
        };
        Some(Triangle {
            v: [rd_u32(tri, 0)?, rd_u32(tri, 4)?, rd_u32(tri, 8)?],
            uv: [c(0)?, c(1)?, c(2)?],
            mask: rd_u32(tri, 12)? & FLAG_MASK != 0,
        })
    }

    /// The three corners of triangle `i` in local metres (one read of its indices
    /// and vertices, without its UVs and flags).
    #[inline]
    #[allow(
        clippy::arithmetic_side_effects,
        reason = "k < 3 corner index: the field offsets are small constants"
    )]
    pub fn triangle_vertices(&self, i: u32) -> Option<[Vec3; 3]> {
        if i >= self.triangle_count {
            return None;
        }
        let t = record_at(self.layout.off(SEC_TRIANGLES), i, TRIANGLE_BYTES)?;
        let b = self.bytes;
        let tri: &[u8; TRIANGLE_BYTES] = b.get(t..)?.first_chunk()?;
        let sec = self.layout.off(SEC_VERTICES);
        let v = |k: usize| -> Option<Vec3> {
            let j = rd_u32(tri.get(4 * k..)?, 0)?;
            if j >= self.vertex_count {
                return None;
            }
            rd_vec3(b, record_at(sec, j, VERTEX_BYTES)?)
        };
        Some([v(0)?, v(1)?, v(2)?])
    }

    /// Tile `i`.
    #[inline]
    pub fn tile(&self, i: u32) -> Option<Tile> {
        if i >= self.tile_count {
            return None;
        }
        let o = record_at(self.layout.off(SEC_TILES), i, TILE_BYTES)?;
        let rec: &[u8; TILE_BYTES] = self.bytes.get(o..)?.first_chunk()?;
        Some(Tile {
            min: rd_vec3(rec, 0)?,
            max: rd_vec3(rec, 12)?,
            first_triangle: rd_u32(rec, 24)?,
            triangle_count: rd_u32(rec, 28)?,
        })
    }

    /// The gray texture (stride = width).
    pub fn texture(&self) -> GrayView<'a> {
        self.texture
    }

    /// The whole encoded product this view was checked from (to check it again).
    pub fn bytes(&self) -> &'a [u8] {
        self.bytes
    }

    /// This view's layout (counts, bounds, section offsets) over `bytes`,
    /// unchecked: what the engine reads when the memory holding a checked
    /// product has changed since its check, for upset campaigns (feature
    /// `upset-injection`, never in a flight build). The accessors stay
    /// bounds-checked; their contents are whatever `bytes` hold. `None`
    /// unless `bytes` is exactly as long as the checked product.
    #[cfg(feature = "upset-injection")]
    pub fn with_changed_bytes<'b>(&self, bytes: &'b [u8]) -> Option<MapView<'b>> {
        if bytes.len() != self.bytes.len() {
            return None;
        }
        self.detach().view_over(bytes)
    }

    /// The texture's texels, row-major with stride = width (`width · height` bytes).
    pub fn texture_bytes(&self) -> &'a [u8] {
        // The view was made from exactly the texture section (stride = width).
        self.texture.data()
    }

    /// Number of vertices of the sampling mask M̂.
    pub fn mask_vertex_count(&self) -> u32 {
        self.mask_vertex_count
    }

    /// The `k`-th vertex index of M̂ (indices are strictly increasing in `k`).
    pub fn mask_vertex(&self, k: u32) -> Option<u32> {
        if k >= self.mask_vertex_count {
            return None;
        }
        rd_u32(
            self.bytes,
            record_at(self.layout.off(SEC_MASK), k, MASK_VERTEX_BYTES)?,
        )
    }

    /// Whether the product carries sampling scores for its mask vertices
    /// (version 3). Without them, mask vertices are drawn uniformly.
    pub fn scored(&self) -> bool {
        self.layout.scored()
    }

    /// Score of the `k`-th mask vertex (the weight [`Self::draw_mask_index`]
    /// gives it); `None` for a product without scores or `k` outside the mask.
    pub fn mask_score(&self, k: u32) -> Option<u8> {
        let cum = self.cumulative(k)?;
        let prev = match k.checked_sub(1) {
            Some(j) => self.cumulative(j)?,
            None => 0,
        };
        u8::try_from(cum.checked_sub(prev)?).ok()
    }

    /// Sum of the mask vertices' scores; 0 for a product without scores (or
    /// without mask vertices).
    pub fn score_total(&self) -> u32 {
        self.score_total
    }

    /// The tile whose x-y cell holds the point (`x`, `y`), local metres
    /// (cells of [`Self::tile_grid`] from the bounds' minimum corner, as the
    /// encoder assigns triangles by centroid); `None` outside the grid or
    /// for a non-finite coordinate.
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "the cell coordinates are checked finite and inside 0..tiles before the casts"
    )]
    pub fn tile_at(&self, x: f32, y: f32) -> Option<u32> {
        let cx = libm::floorf((x - self.min.x) / self.tile_size_m);
        let cy = libm::floorf((y - self.min.y) / self.tile_size_m);
        let inside = |c: f32, n: u32| c.is_finite() && c >= 0.0 && c < n as f32;
        if !(inside(cx, self.tiles_x) && inside(cy, self.tiles_y)) {
            return None;
        }
        (cy as u32)
            .checked_mul(self.tiles_x)?
            .checked_add(cx as u32)
            .filter(|&t| t < self.tile_count)
    }

    /// The index `k` in M̂ of vertex `v` (so that `mask_vertex(k) == Some(v)`),
    /// `None` when `v` is not a mask vertex. A binary search of at most 33
    /// steps over the strictly increasing mask.
    pub fn mask_index_of(&self, v: u32) -> Option<u32> {
        let k = partition_point(self.mask_vertex_count, |k| Some(self.mask_vertex(k)? < v))?;
        (self.mask_vertex(k)? == v).then_some(k)
    }

    /// The mask vertex (its index `k` in the mask, as for [`Self::mask_vertex`])
    /// drawn by `r`, uniform in `0..score_total()`: the `k` whose running sums
    /// enclose it, `cum[k-1] ≤ r < cum[k]` (`cum[-1] = 0`), so each `k` is hit
    /// by exactly its score's worth of values and a zero score never.
    /// `None` for a product without scores or `r ≥ score_total()`.
    /// A binary search of at most 33 steps.
    pub fn draw_mask_index(&self, r: u32) -> Option<u32> {
        if !self.scored() || r >= self.score_total {
            return None;
        }
        // The first k with cum[k] > r: cum is non-decreasing (checked) and
        // cum[mask_vertex_count - 1] = score_total > r.
        let k = partition_point(self.mask_vertex_count, |k| Some(self.cumulative(k)? <= r))?;
        (k < self.mask_vertex_count).then_some(k)
    }

    /// Entry `k` of the score section (the running sum through mask vertex
    /// `k`); `None` without a score section or for `k` outside the mask.
    fn cumulative(&self, k: u32) -> Option<u32> {
        if !self.scored() || k >= self.mask_vertex_count {
            return None;
        }
        rd_u32(
            self.bytes,
            record_at(self.layout.off(SEC_SCORES), k, MASK_SCORE_BYTES)?,
        )
    }
}

/// The first `k` in `0..n` for which `below(k)` is false, or `n` when it holds
/// for all of them, for a `below` that holds on a prefix of `0..n` and fails
/// after it; `None` as soon as `below` does. A binary search of at most 33
/// steps: each halves `hi - lo ≤ u32::MAX`, so 32 empty it.
fn partition_point(n: u32, mut below: impl FnMut(u32) -> Option<bool>) -> Option<u32> {
    let (mut lo, mut hi) = (0u32, n);
    for _ in 0..33 {
        if lo >= hi {
            break;
        }
        // lo < hi ≤ u32::MAX, so neither form wraps; the wrapping forms leave
        // no overflow check (a panic path) in a checked build.
        let mid = lo.wrapping_add(hi.wrapping_sub(lo) >> 1);
        if below(mid)? {
            lo = mid.wrapping_add(1);
        } else {
            hi = mid;
        }
    }
    Some(lo)
}

/// The fixed start of the header: length, magic, a known version, the header
/// CRC and the header-length field. Returns the version and its header length.
///
/// # Errors
/// [`FailureCode::MapTruncated`], [`FailureCode::MapBadMagic`],
/// [`FailureCode::MapUnsupportedVersion`], [`FailureCode::MapCrcMismatch`],
/// [`FailureCode::MapInconsistent`], the first that applies in that order.
#[allow(
    clippy::arithmetic_side_effects,
    reason = "header_len from header_len_of is at least 4 + the fixed fields"
)]
fn check_header(bytes: &[u8]) -> Result<(u32, usize), FailureCode> {
    use FailureCode as F;
    if bytes.len() < HEADER_LEN_V1 {
        return Err(F::MapTruncated);
    }
    if bytes.get(0..8) != Some(&MAGIC[..]) {
        return Err(F::MapBadMagic);
    }
    let h = |off: usize| rd_u32(bytes, off).ok_or(F::MapTruncated);
    let version = h(8)?;
    let header_len = header_len_of(version).ok_or(F::MapUnsupportedVersion)?;
    if bytes.len() < header_len {
        return Err(F::MapTruncated);
    }
    let crc_off = header_len - 4;
    let head = bytes.get(..crc_off).ok_or(F::MapTruncated)?;
    if crc32(head) != h(crc_off)? {
        return Err(F::MapCrcMismatch);
    }
    if h(12)? as usize != header_len {
        return Err(F::MapInconsistent);
    }
    Ok((version, header_len))
}

/// The section table against the layout implied by the counts, the total
/// length, then each section's CRC: the entries the product's version has
/// (six before version 3, seven in it).
///
/// # Errors
/// [`FailureCode::MapInconsistent`] (table or trailing bytes),
/// [`FailureCode::MapTruncated`], [`FailureCode::MapCrcMismatch`].
fn check_sections(bytes: &[u8], layout: &Layout) -> Result<(), FailureCode> {
    use FailureCode as F;
    let h = |off: usize| rd_u32(bytes, off).ok_or(F::MapTruncated);
    // Entry fields at e + 4 (length) and e + 8 (CRC) of an ENTRY_OFF constant:
    // small, so wrapping never wraps (and leaves no overflow check behind).
    let n = layout.entries();
    for (s, e) in layout.sec.iter().zip(ENTRY_OFF).take(n) {
        if h(e)? as usize != s.off || h(e.wrapping_add(4))? as usize != s.len {
            return Err(F::MapInconsistent);
        }
    }
    if bytes.len() < layout.total {
        return Err(F::MapTruncated);
    }
    if bytes.len() > layout.total {
        return Err(F::MapInconsistent);
    }
    for (s, e) in layout.sec.iter().zip(ENTRY_OFF).take(n) {
        let body = bytes
            .get(s.off..s.off.saturating_add(s.len))
            .ok_or(F::MapTruncated)?;
        if crc32(body) != h(e.wrapping_add(8))? {
            return Err(F::MapCrcMismatch);
        }
    }
    Ok(())
}
