//! A checked map product's view without its borrow of the bytes: what
//! [`MapView::new_checked`] found, attached again to the very same bytes
//! without a second check.
//!
//! A bounded retry loop that reads a product into a buffer and checks it
//! cannot hand the view of the pass that passed out of the loop (the borrow
//! of the buffer would have to outlive the passes that write to it); it
//! keeps a [`CheckedMap`] instead and attaches it to the buffer once the
//! loop is over.

use super::format::{Layout, SEC_TEXTURE};
use super::view::MapView;
use crate::geom::Vec3;
use crate::image::GrayView;

/// What the check of a map product found, without the bytes. Made by
/// [`MapView::detach`]; [`CheckedMap::attach`] gives the view back over the
/// same memory only (same address and length), so no byte that was not
/// checked can be read through it.
#[derive(Clone, Copy, Debug)]
pub struct CheckedMap {
    addr: usize,
    len: usize,
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
    texture_size: (usize, usize),
    score_total: u32,
}

impl MapView<'_> {
    /// This view's check result without its borrow of the bytes.
    pub fn detach(&self) -> CheckedMap {
        CheckedMap {
            addr: self.bytes.as_ptr() as usize,
            len: self.bytes.len(),
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
            texture_size: (self.texture.width(), self.texture.height()),
            score_total: self.score_total,
        }
    }
}

impl CheckedMap {
    /// The view over `bytes` when they are the bytes this check was made
    /// over (same address and length; the caller has not written to them
    /// since), else `None`.
    pub fn attach<'b>(&self, bytes: &'b [u8]) -> Option<MapView<'b>> {
        if bytes.as_ptr() as usize != self.addr || bytes.len() != self.len {
            return None;
        }
        self.view_over(bytes)
    }

    /// This check's layout over `bytes`, whatever they hold: the one
    /// construction of a view from a check already made ([`Self::attach`]
    /// after its address test; `MapView::with_changed_bytes` for upset
    /// campaigns). The accessors stay bounds-checked.
    pub(super) fn view_over<'b>(&self, bytes: &'b [u8]) -> Option<MapView<'b>> {
        let tex = self
            .layout
            .sec
            .get(SEC_TEXTURE)
            .copied()
            .unwrap_or_default();
        let (w, h) = self.texture_size;
        let texture =
            GrayView::new(bytes.get(tex.off..tex.off.checked_add(tex.len)?)?, w, h, w).ok()?;
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
            score_total: self.score_total,
        })
    }
}
