//! The depot map product (design §4): one versioned little-endian binary that
//! the core reads through a borrowed byte slice.
//!
//! Inputs: the bytes of a product ([`MapView::new_checked`]) or a mesh in memory
//! ([`MapSource`], encoded by [`encode`] into a caller buffer). Outputs: checked,
//! panic-free accessors for vertices, triangles (with the M̂ mask bit), per-corner
//! UVs, tiles with 3D bounds for frustum culling, the gray texture and the list of
//! mask vertices, and the map's f64 origin. Bounds: every count is capped by
//! `config::MAX_MAP_*` and `config::MAX_TEXTURE_DIM`; validation and encoding are
//! O(vertices + triangles + tiles + texels), each a loop over a capped count.
//!
//! # Frames
//!
//! Everything in the product (vertices, bounds, tiles) is in the map's *local*
//! frame: metres, axes parallel to the mesh's own (user) frame, and
//! `p_user = p_local + origin` with `origin` an f64 triple in the header. The
//! core works in the local frame only (so f32 keeps sub-millimetre steps even
//! for a mesh in UTM coordinates); the desktop tools convert poses between the
//! frames in f64. [`MapView::origin`] reports it; a version-1 product has none
//! and reads as origin 0.
//!
//! # Layout (version 2)
//!
//! | offset | field |
//! |---|---|
//! | 0 | magic `b"VTSMMAP\0"` |
//! | 8 | version u32 = 2 |
//! | 12 | header length u32 = [`HEADER_LEN`] (176) |
//! | 16..48 | vertex, triangle, tile, mask-vertex counts; texture width, height; tiles_x, tiles_y (u32) |
//! | 48 | tile size, metres (f32) |
//! | 52..76 | bounds min xyz, max xyz (f32, local frame) |
//! | 76..148 | six sections × (offset u32, length u32, CRC-32 u32) |
//! | 148..172 | origin x, y, z (f64, metres in the user frame), finite, each within ±[`MAX_MAP_ORIGIN_M`] |
//! | 172 | CRC-32 of bytes 0..172 |
//!
//! Version 1 is the same without the origin: header length [`HEADER_LEN_V1`]
//! (152), the header CRC at 148 over bytes 0..148, sections from 152. It is
//! still read (origin 0); the encoder writes version 2 only.
//!
//! Sections follow the header contiguously in this order: tiles (32 B: min xyz,
//! max xyz f32, first triangle u32, triangle count u32), vertices (12 B: xyz f32,
//! local metres), triangles (16 B: three vertex indices u32, flags u32 with bit 0 =
//! member of M̂, other bits zero), UVs (24 B: three corners × (x, y) f32 in texture
//! pixels, x right, y down, pixel centres on integers), texture (width·height bytes,
//! row-major, stride = width), mask vertices (u32 vertex indices, strictly increasing).
//! Triangles are sorted by tile; tile `ty·tiles_x + tx` covers the cell of the x-y
//! grid holding the triangle's centroid, and its box bounds all its triangles.
//! Every byte is covered by a CRC, so any single corrupted byte is detected.

use crate::config::{
    MAX_MAP_ORIGIN_M, MAX_MAP_TILES, MAX_MAP_TRIANGLES, MAX_MAP_VERTICES, MAX_TEXTURE_DIM,
};
use crate::failure::FailureCode;
use crate::geom::Vec3;
use crate::image::GrayView;

/// First eight bytes of every map product.
pub const MAGIC: [u8; 8] = *b"VTSMMAP\0";
/// Format version written by this build (version 1 is also read).
pub const VERSION: u32 = 2;
/// Length of the version-2 header in bytes (including its own CRC).
pub const HEADER_LEN: usize = 176;
/// Length of the version-1 header in bytes (no origin).
pub const HEADER_LEN_V1: usize = 152;
/// Bytes per tile record.
pub const TILE_BYTES: usize = 32;
/// Bytes per vertex record.
pub const VERTEX_BYTES: usize = 12;
/// Bytes per triangle record.
pub const TRIANGLE_BYTES: usize = 16;
/// Bytes per triangle UV record.
pub const UV_BYTES: usize = 24;
/// Bytes per mask-vertex record.
pub const MASK_VERTEX_BYTES: usize = 4;
/// Triangle flag: the triangle belongs to the sampling mask M̂.
pub const FLAG_MASK: u32 = 1;
/// Largest magnitude of a texture coordinate in the product, texture pixels
/// (2^20 = 64 · `MAX_TEXTURE_DIM`). Coordinates beyond the texture sample its edge
/// texels, so nothing farther is needed; the rasterizer clamps interpolated
/// coordinates to the same range.
pub const MAX_UV_PX: f32 = (1u32 << 20) as f32;

const SECTIONS: usize = 6;
const SEC_TILES: usize = 0;
const SEC_VERTICES: usize = 1;
const SEC_TRIANGLES: usize = 2;
const SEC_UVS: usize = 3;
const SEC_TEXTURE: usize = 4;
const SEC_MASK: usize = 5;
const OFF_SECTIONS: usize = 76;
const OFF_ORIGIN: usize = 148;

// ---- CRC-32 (IEEE 802.3, reflected, poly 0xEDB88320) ------------------------

// Const evaluation: `i < 256` is the loop bound, so `t[i]` is in range (and an
// out-of-range index would fail the build, not the flight code).
#[allow(clippy::indexing_slicing)]
#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "table index i < 256 and bit counter k < 8: the increments and the cast are exact"
)]
const fn crc_table() -> [u32; 256] {
    let mut t = [0u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
            k += 1;
        }
        t[i] = c;
        i += 1;
    }
    t
}

/// The slicing-by-8 tables: `CRC_TABLES[0]` is the bytewise table,
/// `CRC_TABLES[k][i]` the CRC state after byte `i` followed by `k` zero bytes.
#[allow(
    clippy::indexing_slicing,
    clippy::arithmetic_side_effects,
    reason = "const evaluation over fixed 8 × 256 bounds: k < 8, i < 256, the index (c & 0xFF) < 256"
)]
const fn crc_tables() -> [[u32; 256]; 8] {
    let mut t = [[0u32; 256]; 8];
    t[0] = crc_table();
    let mut k = 1;
    while k < 8 {
        let mut i = 0;
        while i < 256 {
            let c = t[k - 1][i];
            t[k][i] = t[0][(c & 0xFF) as usize] ^ (c >> 8);
            i += 1;
        }
        k += 1;
    }
    t
}

static CRC_TABLES: [[u32; 256]; 8] = crc_tables();

/// CRC-32 (IEEE 802.3, the zlib/PNG one) of `bytes`. `crc32(b"123456789") == 0xCBF43926`.
///
/// Slicing-by-8: eight bytes per step through eight 256-entry tables (8 KiB of
/// constant data), the same value as the bytewise recurrence (checked against
/// it in the map tests) at several times its speed; the map check reads the
/// whole product through it.
pub fn crc32(bytes: &[u8]) -> u32 {
    let [t0, t1, t2, t3, t4, t5, t6, t7] = &CRC_TABLES;
    // Every index below is a byte (`& 0xFF` or `>> 24`), so `get` never fails.
    let g = |t: &[u32; 256], i: u32| t.get((i & 0xFF) as usize).copied().unwrap_or(0);
    let mut c = 0xFFFF_FFFFu32;
    let mut chunks = bytes.chunks_exact(8);
    for ch in &mut chunks {
        let Some((lo, hi)) = ch.split_first_chunk::<4>() else {
            break;
        };
        let a = c ^ u32::from_le_bytes(*lo);
        let b = hi.first_chunk::<4>().map_or(0, |h| u32::from_le_bytes(*h));
        c = g(t7, a)
            ^ g(t6, a >> 8)
            ^ g(t5, a >> 16)
            ^ g(t4, a >> 24)
            ^ g(t3, b)
            ^ g(t2, b >> 8)
            ^ g(t1, b >> 16)
            ^ g(t0, b >> 24);
    }
    for b in chunks.remainder() {
        c = g(t0, c ^ u32::from(*b)) ^ (c >> 8);
    }
    !c
}

// ---- little-endian helpers ----------------------------------------------------

#[inline]
fn rd_u32(b: &[u8], off: usize) -> Option<u32> {
    let s = b.get(off..off.checked_add(4)?)?;
    let mut a = [0u8; 4];
    a.copy_from_slice(s);
    Some(u32::from_le_bytes(a))
}

#[inline]
fn rd_f32(b: &[u8], off: usize) -> Option<f32> {
    rd_u32(b, off).map(f32::from_bits)
}

#[inline]
fn rd_vec3(b: &[u8], off: usize) -> Option<Vec3> {
    Some(Vec3::new(
        rd_f32(b, off)?,
        rd_f32(b, off.checked_add(4)?)?,
        rd_f32(b, off.checked_add(8)?)?,
    ))
}

/// Offset of record `i` of `stride` bytes in the section at `base`; `None` where
/// it would not fit in `usize` (a validated layout never gets there).
#[inline]
fn record_at(base: usize, i: u32, stride: usize) -> Option<usize> {
    (i as usize).checked_mul(stride)?.checked_add(base)
}

#[inline]
fn rd_f64(b: &[u8], off: usize) -> Option<f64> {
    let s = b.get(off..off.checked_add(8)?)?;
    let mut a = [0u8; 8];
    a.copy_from_slice(s);
    Some(f64::from_le_bytes(a))
}

/// Header length of a format version, `None` for a version this build cannot read.
fn header_len_of(version: u32) -> Option<usize> {
    match version {
        1 => Some(HEADER_LEN_V1),
        VERSION => Some(HEADER_LEN),
        _ => None,
    }
}

/// Whether a map origin is usable: finite, each coordinate within ±[`MAX_MAP_ORIGIN_M`].
pub fn origin_ok(o: &[f64; 3]) -> bool {
    o.iter()
        .all(|c| c.is_finite() && c.abs() <= MAX_MAP_ORIGIN_M)
}

#[inline]
fn wr_u32(b: &mut [u8], off: usize, v: u32) -> Result<(), FailureCode> {
    let end = off
        .checked_add(4)
        .ok_or(FailureCode::MapEncodeBufferTooSmall)?;
    let s = b
        .get_mut(off..end)
        .ok_or(FailureCode::MapEncodeBufferTooSmall)?;
    s.copy_from_slice(&v.to_le_bytes());
    Ok(())
}

#[inline]
fn wr_f32(b: &mut [u8], off: usize, v: f32) -> Result<(), FailureCode> {
    wr_u32(b, off, v.to_bits())
}

fn wr_vec3(b: &mut [u8], off: usize, v: &Vec3) -> Result<(), FailureCode> {
    let s: &mut [u8; 12] = b
        .get_mut(off..)
        .and_then(|s| s.first_chunk_mut())
        .ok_or(FailureCode::MapEncodeBufferTooSmall)?;
    for (dst, c) in s.chunks_exact_mut(4).zip([v.x, v.y, v.z]) {
        dst.copy_from_slice(&c.to_bits().to_le_bytes());
    }
    Ok(())
}

fn vec_finite(v: &Vec3) -> bool {
    v.x.is_finite() && v.y.is_finite() && v.z.is_finite()
}

/// Whether a texture coordinate (texture pixels) is within ±[`MAX_UV_PX`] (NaN is not).
fn uv_in_range(c: f32) -> bool {
    c.abs() <= MAX_UV_PX
}

/// Whether the triangle `a b c` has non-zero area (f32 cross product of its edges;
/// an infinite one counts, a NaN one does not).
#[allow(
    clippy::arithmetic_side_effects,
    reason = "f32 vector arithmetic (nalgebra); no integer operation"
)]
fn has_area(a: &Vec3, b: &Vec3, c: &Vec3) -> bool {
    (b - a).cross(&(c - a)).norm_squared() > 0.0
}

fn inside(p: &Vec3, min: &Vec3, max: &Vec3) -> bool {
    p.x >= min.x && p.y >= min.y && p.z >= min.z && p.x <= max.x && p.y <= max.y && p.z <= max.z
}

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

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Section {
    off: usize,
    len: usize,
}

/// Sizes and offsets of every section, derived from the counts only.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Layout {
    sec: [Section; SECTIONS],
    total: usize,
}

impl Layout {
    fn new(
        header: usize,
        v: usize,
        t: usize,
        tiles: usize,
        masks: usize,
        tw: usize,
        th: usize,
    ) -> Self {
        // Saturating: counts beyond the capacities give a total no buffer or
        // product can match, so they are refused by the length checks.
        let lens = [
            tiles.saturating_mul(TILE_BYTES),
            v.saturating_mul(VERTEX_BYTES),
            t.saturating_mul(TRIANGLE_BYTES),
            t.saturating_mul(UV_BYTES),
            tw.saturating_mul(th),
            masks.saturating_mul(MASK_VERTEX_BYTES),
        ];
        let mut sec = [Section::default(); SECTIONS];
        let mut off = header;
        for (s, len) in sec.iter_mut().zip(lens) {
            *s = Section { off, len };
            off = off.saturating_add(len);
        }
        Self { sec, total: off }
    }

    fn off(&self, i: usize) -> usize {
        self.sec.get(i).map_or(0, |s| s.off)
    }
}

/// A validated map product. Construction checks everything once; afterwards
/// every accessor is O(1), cannot panic and returns `None` only for an index
/// outside its count.
#[derive(Clone, Copy, Debug)]
pub struct MapView<'a> {
    bytes: &'a [u8],
    layout: Layout,
    vertex_count: u32,
    triangle_count: u32,
    tile_count: u32,
    mask_vertex_count: u32,
    tiles_x: u32,
    tiles_y: u32,
    tile_size_m: f32,
    min: Vec3,
    max: Vec3,
    origin: [f64; 3],
    texture: GrayView<'a>,
}

impl<'a> MapView<'a> {
    /// Check a map product and return a view of it.
    ///
    /// Checks, in order: length of the header ([`FailureCode::MapTruncated`]),
    /// magic ([`FailureCode::MapBadMagic`]), version 1 or 2 ([`FailureCode::MapUnsupportedVersion`]),
    /// header CRC ([`FailureCode::MapCrcMismatch`]), the origin (version 2:
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
    /// triangle flags, strictly increasing mask vertices ([`FailureCode::MapInconsistent`]).
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
        for (i, s) in layout.sec.iter().enumerate() {
            let e = OFF_SECTIONS + 12 * i;
            if h(e)? as usize != s.off || h(e + 4)? as usize != s.len {
                return Err(F::MapInconsistent);
            }
        }
        if bytes.len() < layout.total {
            return Err(F::MapTruncated);
        }
        if bytes.len() > layout.total {
            return Err(F::MapInconsistent);
        }
        for (i, s) in layout.sec.iter().enumerate() {
            let body = bytes
                .get(s.off..s.off.saturating_add(s.len))
                .ok_or(F::MapTruncated)?;
            // i < SECTIONS: the header offset is a small constant.
            if crc32(body)
                != h(OFF_SECTIONS
                    .wrapping_add(12usize.wrapping_mul(i))
                    .wrapping_add(8))?
            {
                return Err(F::MapCrcMismatch);
            }
        }
        let tex_sec = layout.sec.get(SEC_TEXTURE).copied().unwrap_or_default();
        let tex_bytes = bytes
            .get(tex_sec.off..tex_sec.off.saturating_add(tex_sec.len))
            .ok_or(F::MapTruncated)?;
        let texture = GrayView::new(tex_bytes, tw as usize, th as usize, tw as usize)
            .map_err(|_| F::MapCountOutOfRange)?;
        let view = Self {
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
        };
        view.check_content()?;
        Ok(view)
    }

    #[allow(
        clippy::cast_possible_truncation,
        reason = "i < triangle_count, itself a u32"
    )]
    fn check_content(&self) -> Result<(), FailureCode> {
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

    /// Format version of the product (1 or 2).
    pub fn version(&self) -> u32 {
        if self.layout.off(SEC_TILES) == HEADER_LEN_V1 {
            1
        } else {
            VERSION
        }
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
        let tex = self
            .layout
            .sec
            .get(SEC_TEXTURE)
            .copied()
            .unwrap_or_default();
        let texture = GrayView::new(
            bytes.get(tex.off..tex.off.checked_add(tex.len)?)?,
            self.texture.width(),
            self.texture.height(),
            self.texture.width(),
        )
        .ok()?;
        Some(MapView {
            bytes,
            layout: self.layout,
            vertex_count: self.vertex_count,
            triangle_count: self.triangle_count,
            tile_count: self.tile_count,
            mask_vertex_count: self.mask_vertex_count,
            tiles_x: self.tiles_x,
            tiles_y: self.tiles_y,
            tile_size_m: self.tile_size_m,
            min: self.min,
            max: self.max,
            origin: self.origin,
            texture,
        })
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
}

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
}

#[derive(Clone, Copy, Debug)]
struct Plan {
    min: Vec3,
    max: Vec3,
    tiles_x: u32,
    tiles_y: u32,
    layout: Layout,
}

impl Plan {
    #[allow(
        clippy::arithmetic_side_effects,
        clippy::cast_possible_truncation,
        reason = "float-to-int `as` saturates (NaN gives 0) before the clamp to the grid; tiles_x, tiles_y ≤ MAX_MAP_TILES"
    )]
    fn cell_of(&self, x: f32, y: f32, tile: f32) -> usize {
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

fn vertex_of(src: &MapSource, i: u32) -> Result<Vec3, FailureCode> {
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
fn plan(src: &MapSource) -> Result<Plan, FailureCode> {
    use FailureCode as F;
    let (nv, nt) = (src.vertices.len(), src.triangles.len());
    if !(3..=MAX_MAP_VERTICES).contains(&nv) || !(1..=MAX_MAP_TRIANGLES).contains(&nt) {
        return Err(F::MapCountOutOfRange);
    }
    if src.uvs.len() != nt || src.mask.len() != nt {
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
    }
    if !surface {
        return Err(F::MapNoSurface);
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
        layout: Layout::new(HEADER_LEN, nv, nt, tiles, masks_max, tw, th),
    })
}

/// Size of the output buffer [`encode`] needs for `src`, in bytes. This is an
/// upper bound: it counts the mask-vertex list at its largest,
/// `min(vertices, 3 · mask triangles)` entries; [`encode`] returns the exact length.
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
/// cell); UVs are converted from OBJ convention to texture pixels (see [`Triangle`]).
///
/// # Errors
/// [`FailureCode::MapCountOutOfRange`] (counts or texture size above the caps,
/// vertex extent beyond f32), [`FailureCode::MapTileSizeOutOfRange`] (tile size
/// not positive and finite, or a tile grid above `MAX_MAP_TILES`),
/// [`FailureCode::MapInconsistent`] (slice lengths disagree),
/// [`FailureCode::MapOriginOutOfRange`] (origin not finite or beyond ±[`MAX_MAP_ORIGIN_M`]),
/// [`FailureCode::MapNonFinite`], [`FailureCode::MapUvOutOfRange`] (a UV beyond
/// ±[`MAX_UV_PX`] texture pixels once converted), [`FailureCode::MapNoSurface`]
/// (every triangle has zero area), [`FailureCode::MapIndexOutOfRange`],
/// [`FailureCode::MapEncodeBufferTooSmall`]. Nothing is written on a check failure
/// other than the buffer-size one, which writes nothing either.
#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "counts and sizes are checked against the config capacities (all below u32::MAX) by plan() before they are written as u32; header offsets are constants of the layout (i < 11 fields, k < 3, i < SECTIONS)"
)]
pub fn encode(src: &MapSource, out: &mut [u8]) -> Result<usize, FailureCode> {
    use FailureCode as F;
    let plan = plan(src)?;
    let lay = plan.layout;
    let buf = out.get_mut(..lay.total).ok_or(F::MapEncodeBufferTooSmall)?;
    buf.fill(0);
    let nv = src.vertices.len();
    // Offsets within the planned layout (≤ its total, the length of `buf`);
    // saturating, so an impossible overflow is a failed `get`, not a panic.
    let at = |base: usize, i: usize, stride: usize| base.saturating_add(i.saturating_mul(stride));
    let ts = src.tile_size_m;
    let (o_tiles, o_vert, o_tri, o_uv, o_tex, o_mask) = (
        lay.off(SEC_TILES),
        lay.off(SEC_VERTICES),
        lay.off(SEC_TRIANGLES),
        lay.off(SEC_UVS),
        lay.off(SEC_TEXTURE),
        lay.off(SEC_MASK),
    );

    // Mask vertices: one mark byte per vertex in the (not yet written) vertex section.
    for (t, m) in src.triangles.iter().zip(src.mask) {
        if *m {
            for v in t {
                *buf.get_mut(o_vert.saturating_add(*v as usize))
                    .ok_or(F::MapEncodeBufferTooSmall)? = 1;
            }
        }
    }
    let mut masks = 0usize;
    for v in 0..nv {
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

    // Counting sort by tile; counters live in the tiles' count fields.
    let centroid_cell = |t: &[u32; 3]| -> Result<usize, FailureCode> {
        let (a, b, c) = (
            vertex_of(src, t[0])?,
            vertex_of(src, t[1])?,
            vertex_of(src, t[2])?,
        );
        let (x, y) = ((a.x + b.x + c.x) / 3.0, (a.y + b.y + c.y) / 3.0);
        Ok(plan.cell_of(x, y, ts))
    };
    let tiles = (plan.tiles_x as usize).saturating_mul(plan.tiles_y as usize);
    for t in src.triangles {
        let o = at(o_tiles, centroid_cell(t)?, TILE_BYTES).saturating_add(28);
        let n = rd_u32(buf, o).ok_or(F::MapEncodeBufferTooSmall)?;
        // Counts stay ≤ the triangle count; saturating keeps an impossible
        // overflow an out-of-range slot (refused below) instead of a panic.
        wr_u32(buf, o, n.saturating_add(1))?;
    }
    let mut first = 0u32;
    for k in 0..tiles {
        let o = at(o_tiles, k, TILE_BYTES);
        let n = rd_u32(buf, o.saturating_add(28)).ok_or(F::MapEncodeBufferTooSmall)?;
        wr_vec3(buf, o, &Vec3::repeat(f32::INFINITY))?;
        wr_vec3(buf, o.saturating_add(12), &Vec3::repeat(f32::NEG_INFINITY))?;
        wr_u32(buf, o.saturating_add(24), first)?;
        wr_u32(buf, o.saturating_add(28), 0)?;
        first = first.saturating_add(n);
    }
    let (tw, th) = (src.texture.width() as f32, src.texture.height() as f32);
    for ((t, uv), m) in src.triangles.iter().zip(src.uvs).zip(src.mask) {
        let o = at(o_tiles, centroid_cell(t)?, TILE_BYTES);
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
    // Empty cells get a degenerate box at the cell's corner on the map floor.
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

    // Texture rows.
    let w = src.texture.width();
    for y in 0..src.texture.height() {
        let row = src.texture.row(y).ok_or(F::MapInconsistent)?;
        buf.get_mut(at(o_tex, y, w)..)
            .and_then(|d| d.get_mut(..row.len()))
            .ok_or(F::MapEncodeBufferTooSmall)?
            .copy_from_slice(row);
    }

    // Header with the exact mask count.
    let real = Layout::new(
        HEADER_LEN,
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
        VERSION,
        HEADER_LEN as u32,
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
    for (i, s) in real.sec.iter().enumerate() {
        let crc = crc32(
            buf.get(s.off..s.off.saturating_add(s.len))
                .ok_or(F::MapEncodeBufferTooSmall)?,
        );
        let e = OFF_SECTIONS + 12 * i;
        wr_u32(buf, e, s.off as u32)?;
        wr_u32(buf, e + 4, s.len as u32)?;
        wr_u32(buf, e + 8, crc)?;
    }
    let hcrc = crc32(
        buf.get(..HEADER_LEN - 4)
            .ok_or(F::MapEncodeBufferTooSmall)?,
    );
    wr_u32(buf, HEADER_LEN - 4, hcrc)?;
    Ok(real.total)
}

/// Recompute every CRC of a product in place (header last). For tools and tests
/// that edit a product on purpose; a product edited without this is rejected.
/// The header length follows the version field (an unknown version is treated
/// as the current one).
///
/// # Errors
/// [`FailureCode::MapTruncated`] if `bytes` is shorter than its header or sections say.
#[allow(
    clippy::arithmetic_side_effects,
    reason = "header offsets are constants of the layout (i < SECTIONS) and header_len ≥ 4 + the fixed fields (header_len_of)"
)]
pub fn reseal(bytes: &mut [u8]) -> Result<(), FailureCode> {
    use FailureCode as F;
    let version = rd_u32(bytes, 8).ok_or(F::MapTruncated)?;
    let header_len = header_len_of(version).unwrap_or(HEADER_LEN);
    if bytes.len() < header_len {
        return Err(F::MapTruncated);
    }
    for i in 0..SECTIONS {
        let e = OFF_SECTIONS + 12 * i;
        let off = rd_u32(bytes, e).ok_or(F::MapTruncated)? as usize;
        let len = rd_u32(bytes, e + 4).ok_or(F::MapTruncated)? as usize;
        let end = off.checked_add(len).ok_or(F::MapTruncated)?;
        let crc = crc32(bytes.get(off..end).ok_or(F::MapTruncated)?);
        wr_u32(bytes, e + 8, crc).map_err(|_| F::MapTruncated)?;
    }
    let hcrc = crc32(bytes.get(..header_len - 4).ok_or(F::MapTruncated)?);
    wr_u32(bytes, header_len - 4, hcrc).map_err(|_| F::MapTruncated)
}

#[cfg(test)]
pub(crate) mod tests;
