//! A mesh as a file reader gives it ([`RawMesh`]), before it gets a texture,
//! and the capacity check every reader makes once the geometry is read.

use crate::error::{Error, Result};
use crate::io::image::Gray8;
use std::path::Path;
use vtsm_core::config::{MAX_MAP_TRIANGLES, MAX_MAP_VERTICES};
use vtsm_core::FailureCode;

/// Texture coordinates of a triangle's three corners (normalised, OBJ convention).
pub type CornerUvs = [[f32; 2]; 3];

/// A mesh as read from a file, before it is given a texture.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RawMesh {
    /// Vertex positions, metres in the file's own (user) frame, as read (f64).
    pub vertices: Vec<[f64; 3]>,
    /// Triangles as vertex indices (polygons already fan-triangulated).
    pub triangles: Vec<[u32; 3]>,
    /// Per-corner texture coordinates (normalised, OBJ convention), one entry
    /// per triangle, or `None` when the file had none.
    pub uvs: Option<Vec<[[f32; 2]; 3]>>,
    /// Per-vertex gray (BT.601 luma of the file's colour), if the file had colour.
    pub vertex_gray: Option<Vec<u8>>,
    /// The texture image, converted to gray, if the file named one.
    pub texture: Option<Gray8>,
}

/// Refuse a mesh above the map product's capacities (`config::MAX_MAP_VERTICES`,
/// `config::MAX_MAP_TRIANGLES`) before anything else is spent on it. The readers
/// call this once the geometry is read, before loading textures; `path` names the mesh.
///
/// # Errors
/// [`FailureCode::MapCountOutOfRange`] with a message giving the count and the cap.
pub fn check_capacity(path: &Path, vertices: usize, triangles: usize) -> Result<()> {
    let code = FailureCode::MapCountOutOfRange;
    let tag = format!("({}, 0x{:04x})", code.name(), code.code());
    let over = |what: &str, n: usize, cap: usize, name: &str| {
        Err(Error::file(
            path,
            format!(
                "mesh has {n} {what}, above the map product's capacity of {cap} \
                 (config::{name}); decimate it or split the depot {tag}"
            ),
        )
        .with_code(code))
    };
    if triangles > MAX_MAP_TRIANGLES {
        return over(
            "triangles",
            triangles,
            MAX_MAP_TRIANGLES,
            "MAX_MAP_TRIANGLES",
        );
    }
    if vertices > MAX_MAP_VERTICES {
        return over("vertices", vertices, MAX_MAP_VERTICES, "MAX_MAP_VERTICES");
    }
    Ok(())
}
