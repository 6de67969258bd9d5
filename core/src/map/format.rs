//! The map product's byte layout: header constants and offsets, the section
//! table ([`Layout`]), little-endian field readers and writers, and the
//! per-record value checks shared by the encoder and the checked view.
//!
//! Input: byte slices and offsets; output: values (`None` when a read falls
//! outside the slice) or bytes written in place. No loop beyond one record.

use crate::config::MAX_MAP_ORIGIN_M;
use crate::failure::FailureCode;
use crate::geom::Vec3;

/// First eight bytes of every map product.
pub const MAGIC: [u8; 8] = *b"VTSMMAP\0";

/// Format version the encoder writes for a map without sampling scores
/// (version 1 is also read).
pub const VERSION: u32 = 2;

/// Format version the encoder writes for a map with sampling scores: the
/// version-2 header with a seventh section entry (the score section).
pub const VERSION_SCORED: u32 = 3;

/// Length of the version-2 header in bytes (including its own CRC).
pub const HEADER_LEN: usize = 176;

/// Length of the version-3 header in bytes: the version-2 fields, the score
/// section's entry at 172..184 and the header CRC at 184.
pub const HEADER_LEN_V3: usize = 188;

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

/// Bytes per entry of the score section (a u32 running sum of the mask
/// vertices' scores).
pub const MASK_SCORE_BYTES: usize = 4;

/// Largest score of one mask vertex (one byte): the largest step between two
/// consecutive entries of the score section.
pub const MAX_MASK_SCORE: u32 = 255;

/// Triangle flag: the triangle belongs to the sampling mask M̂.
pub const FLAG_MASK: u32 = 1;

/// Largest magnitude of a texture coordinate in the product, texture pixels
/// (2^20 = 64 · `MAX_TEXTURE_DIM`). Coordinates beyond the texture sample its edge
/// texels, so nothing farther is needed; the rasterizer clamps interpolated
/// coordinates to the same range.
pub const MAX_UV_PX: f32 = (1u32 << 20) as f32;

/// Sections of the layout; a version-1 or version-2 product has the first
/// six in its table and an empty score section.
pub(super) const SECTIONS: usize = 7;

/// Section table entries in a version-1 or version-2 header.
pub(super) const SECTIONS_V2: usize = 6;

pub(super) const SEC_TILES: usize = 0;

pub(super) const SEC_VERTICES: usize = 1;

pub(super) const SEC_TRIANGLES: usize = 2;

pub(super) const SEC_UVS: usize = 3;

pub(super) const SEC_TEXTURE: usize = 4;

pub(super) const SEC_MASK: usize = 5;

pub(super) const SEC_SCORES: usize = 6;

pub(super) const OFF_SECTIONS: usize = 76;

pub(super) const OFF_ORIGIN: usize = 148;

/// Header offset of each section's table entry (offset u32, length u32,
/// CRC-32 u32): six in a row from [`OFF_SECTIONS`], the score section's
/// after the origin (version 3 only).
pub(super) const ENTRY_OFF: [usize; SECTIONS] = [
    OFF_SECTIONS,
    OFF_SECTIONS + 12,
    OFF_SECTIONS + 24,
    OFF_SECTIONS + 36,
    OFF_SECTIONS + 48,
    OFF_SECTIONS + 60,
    OFF_ORIGIN + 24,
];

// The six version-2 entries end where the origin starts; the score entry and
// the header CRC end the version-3 header.
const _: () = assert!(OFF_SECTIONS + 12 * SECTIONS_V2 == OFF_ORIGIN);
const _: () = assert!(OFF_ORIGIN + 24 + 4 == HEADER_LEN);
const _: () = assert!(OFF_ORIGIN + 24 + 12 + 4 == HEADER_LEN_V3);

// ---- little-endian helpers ----------------------------------------------------

#[inline]
pub(super) fn rd_u32(b: &[u8], off: usize) -> Option<u32> {
    let s = b.get(off..off.checked_add(4)?)?;
    let mut a = [0u8; 4];
    a.copy_from_slice(s);
    Some(u32::from_le_bytes(a))
}

#[inline]
pub(super) fn rd_f32(b: &[u8], off: usize) -> Option<f32> {
    rd_u32(b, off).map(f32::from_bits)
}

#[inline]
pub(super) fn rd_vec3(b: &[u8], off: usize) -> Option<Vec3> {
    Some(Vec3::new(
        rd_f32(b, off)?,
        rd_f32(b, off.checked_add(4)?)?,
        rd_f32(b, off.checked_add(8)?)?,
    ))
}

/// Offset of record `i` of `stride` bytes in the section at `base`; `None` where
/// it would not fit in `usize` (a validated layout never gets there).
#[inline]
pub(super) fn record_at(base: usize, i: u32, stride: usize) -> Option<usize> {
    (i as usize).checked_mul(stride)?.checked_add(base)
}

#[inline]
pub(super) fn rd_f64(b: &[u8], off: usize) -> Option<f64> {
    let s = b.get(off..off.checked_add(8)?)?;
    let mut a = [0u8; 8];
    a.copy_from_slice(s);
    Some(f64::from_le_bytes(a))
}

/// Header length of a format version, `None` for a version this build cannot read.
pub(super) fn header_len_of(version: u32) -> Option<usize> {
    match version {
        1 => Some(HEADER_LEN_V1),
        VERSION => Some(HEADER_LEN),
        VERSION_SCORED => Some(HEADER_LEN_V3),
        _ => None,
    }
}

/// The version whose header is `header_len` bytes long (the inverse of
/// [`header_len_of`]; any other length reads as version 2, as a checked
/// layout never has one).
pub(super) fn version_of(header_len: usize) -> u32 {
    match header_len {
        HEADER_LEN_V1 => 1,
        HEADER_LEN_V3 => VERSION_SCORED,
        _ => VERSION,
    }
}

/// Entries of the section table in a header of `header_len` bytes: seven in
/// version 3, six before.
pub(super) fn entries_of(header_len: usize) -> usize {
    if header_len == HEADER_LEN_V3 {
        SECTIONS
    } else {
        SECTIONS_V2
    }
}

/// Whether a map origin is usable: finite, each coordinate within ±[`MAX_MAP_ORIGIN_M`].
pub fn origin_ok(o: &[f64; 3]) -> bool {
    o.iter()
        .all(|c| c.is_finite() && c.abs() <= MAX_MAP_ORIGIN_M)
}

#[inline]
pub(super) fn wr_u32(b: &mut [u8], off: usize, v: u32) -> Result<(), FailureCode> {
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
pub(super) fn wr_f32(b: &mut [u8], off: usize, v: f32) -> Result<(), FailureCode> {
    wr_u32(b, off, v.to_bits())
}

pub(super) fn wr_vec3(b: &mut [u8], off: usize, v: &Vec3) -> Result<(), FailureCode> {
    let s: &mut [u8; 12] = b
        .get_mut(off..)
        .and_then(|s| s.first_chunk_mut())
        .ok_or(FailureCode::MapEncodeBufferTooSmall)?;
    for (dst, c) in s.chunks_exact_mut(4).zip([v.x, v.y, v.z]) {
        dst.copy_from_slice(&c.to_bits().to_le_bytes());
    }
    Ok(())
}

pub(super) fn vec_finite(v: &Vec3) -> bool {
    v.x.is_finite() && v.y.is_finite() && v.z.is_finite()
}

/// Whether a texture coordinate (texture pixels) is within ±[`MAX_UV_PX`] (NaN is not).
pub(super) fn uv_in_range(c: f32) -> bool {
    c.abs() <= MAX_UV_PX
}

/// Whether the triangle `a b c` has non-zero area (f32 cross product of its edges;
/// an infinite one counts, a NaN one does not).
#[allow(
    clippy::arithmetic_side_effects,
    reason = "f32 vector arithmetic (nalgebra); no integer operation"
)]
pub(super) fn has_area(a: &Vec3, b: &Vec3, c: &Vec3) -> bool {
    (b - a).cross(&(c - a)).norm_squared() > 0.0
}

pub(super) fn inside(p: &Vec3, min: &Vec3, max: &Vec3) -> bool {
    p.x >= min.x && p.y >= min.y && p.z >= min.z && p.x <= max.x && p.y <= max.y && p.z <= max.z
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct Section {
    pub(super) off: usize,
    pub(super) len: usize,
}

/// Sizes and offsets of every section, derived from the header length (which
/// names the version) and the counts only. The score section has one entry
/// per mask vertex in version 3 and is empty before.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Layout {
    pub(super) sec: [Section; SECTIONS],
    pub(super) total: usize,
}

impl Layout {
    pub(super) fn new(
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
            if header == HEADER_LEN_V3 {
                masks.saturating_mul(MASK_SCORE_BYTES)
            } else {
                0
            },
        ];
        let mut sec = [Section::default(); SECTIONS];
        let mut off = header;
        for (s, len) in sec.iter_mut().zip(lens) {
            *s = Section { off, len };
            off = off.saturating_add(len);
        }
        Self { sec, total: off }
    }

    pub(super) fn off(&self, i: usize) -> usize {
        self.sec.get(i).map_or(0, |s| s.off)
    }

    /// Length of the header: where the first section starts.
    pub(super) fn header_len(&self) -> usize {
        self.off(SEC_TILES)
    }

    /// Whether the product has a score section (version 3).
    pub(super) fn scored(&self) -> bool {
        self.header_len() == HEADER_LEN_V3
    }

    /// Entries of the section table in this product's header.
    pub(super) fn entries(&self) -> usize {
        entries_of(self.header_len())
    }
}
