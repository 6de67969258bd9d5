//! The depot map product (design §4): one versioned little-endian binary that
//! the core reads through a borrowed byte slice.
//!
//! Inputs: the bytes of a product ([`MapView::new_checked`]) or a mesh in memory
//! ([`MapSource`], encoded by [`encode`] into a caller buffer). Outputs: checked,
//! panic-free accessors for vertices, triangles (with the M̂ mask bit), per-corner
//! UVs, tiles with 3D bounds for frustum culling, the gray texture and the list of
//! mask vertices, the map's f64 origin and (version 3) each mask vertex's
//! sampling score, with draws in proportion to it. Bounds: every count is capped by
//! `config::MAX_MAP_*` and `config::MAX_TEXTURE_DIM`; validation and encoding are
//! O(vertices + triangles + tiles + texels), each a loop over a capped count;
//! a draw ([`MapView::draw_mask_index`]) is a binary search of at most 33 steps.
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
//! # Layout (versions 2 and 3)
//!
//! | offset | field |
//! |---|---|
//! | 0 | magic `b"VTSMMAP\0"` |
//! | 8 | version u32 = 2 ([`VERSION`]) or 3 ([`VERSION_SCORED`]) |
//! | 12 | header length u32 = [`HEADER_LEN`] (176, version 2) or [`HEADER_LEN_V3`] (188, version 3) |
//! | 16..48 | vertex, triangle, tile, mask-vertex counts; texture width, height; tiles_x, tiles_y (u32) |
//! | 48 | tile size, metres (f32) |
//! | 52..76 | bounds min xyz, max xyz (f32, local frame) |
//! | 76..148 | six sections × (offset u32, length u32, CRC-32 u32) |
//! | 148..172 | origin x, y, z (f64, metres in the user frame), finite, each within ±[`MAX_MAP_ORIGIN_M`](crate::config::MAX_MAP_ORIGIN_M) |
//! | 172 | version 2: CRC-32 of bytes 0..172 (end of the header) |
//! | 172..184 | version 3: the score section's (offset u32, length u32, CRC-32 u32) |
//! | 184 | version 3: CRC-32 of bytes 0..184 |
//!
//! Version 1 is version 2 without the origin: header length [`HEADER_LEN_V1`]
//! (152), the header CRC at 148 over bytes 0..148, sections from 152. It is
//! still read (origin 0). The encoder writes version 2 for a source without
//! scores and version 3 for one with them ([`MapSource::vertex_scores`]);
//! versions 1 and 2 read as unscored ([`MapView::scored`] false).
//!
//! Sections follow the header contiguously in this order: tiles (32 B: min xyz,
//! max xyz f32, first triangle u32, triangle count u32), vertices (12 B: xyz f32,
//! local metres), triangles (16 B: three vertex indices u32, flags u32 with bit 0 =
//! member of M̂, other bits zero), UVs (24 B: three corners × (x, y) f32 in texture
//! pixels, x right, y down, pixel centres on integers), texture (width·height bytes,
//! row-major, stride = width), mask vertices (u32 vertex indices, strictly increasing),
//! and in version 3 the scores ([`MASK_SCORE_BYTES`] = 4 B per mask vertex, in
//! mask order: u32 `cum[k]`, the running sum of the scores of mask vertices
//! 0..=k, so `score[k] = cum[k] − cum[k−1]` with `cum[−1] = 0`; each step
//! 0..=[`MAX_MASK_SCORE`] (255), the last entry the total, positive unless the
//! mask is empty, else [`MAP_BAD_SCORES`](crate::failure::FailureCode::MapBadScores)).
//! Triangles are sorted by tile; tile `ty·tiles_x + tx` covers the cell of the x-y
//! grid holding the triangle's centroid, and its box bounds all its triangles.
//! Every byte is covered by a CRC, so any single corrupted byte is detected.

//!
//! Files, imported one way: `mod.rs` (this summary and the public names),
//! `encode.rs` (mesh to bytes, [`reseal`]) and `view.rs` (bytes to the checked
//! [`MapView`]) above `format.rs` (layout constants, field readers and writers,
//! record checks) and `crc.rs` (the checksum).

mod crc;
mod detached;
mod encode;
mod format;
mod view;

pub use crc::crc32;
pub use detached::CheckedMap;
pub use encode::{encode, encoded_len, reseal, MapSource};
pub use format::{
    origin_ok, FLAG_MASK, HEADER_LEN, HEADER_LEN_V1, HEADER_LEN_V3, MAGIC, MASK_SCORE_BYTES,
    MASK_VERTEX_BYTES, MAX_MASK_SCORE, MAX_UV_PX, TILE_BYTES, TRIANGLE_BYTES, UV_BYTES, VERSION,
    VERSION_SCORED, VERTEX_BYTES,
};
pub use view::{MapView, Tile, Triangle};

#[cfg(test)]
pub(crate) mod tests;
