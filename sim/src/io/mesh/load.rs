//! The one reader of every mesh form: OBJ + MTL ([`crate::io::obj`]) or PLY
//! ([`crate::io::ply`]) by extension, into a [`RawMesh`] and then a
//! [`MeshData`].

use super::data::MeshData;
use super::raw::RawMesh;
use crate::error::{Error, Result};
use crate::io::{has_extension, obj, ply};
use indicatif::ProgressBar;
use std::path::Path;

/// Load a textured mesh, OBJ or PLY by extension.
///
/// # Errors
/// Unknown extension or any reader error.
pub fn load_mesh(path: &Path) -> Result<MeshData> {
    load_mesh_at(path, None)
}

/// [`load_mesh`] with the map origin given (`None`: the default origin).
///
/// # Errors
/// As [`MeshData::from_raw_at`].
pub fn load_mesh_at(path: &Path, origin: Option<[f64; 3]>) -> Result<MeshData> {
    load_mesh_with_progress(path, origin, &ProgressBar::hidden())
}

/// [`load_mesh_at`], reporting the bytes of the file parsed so far on `bar`.
///
/// # Errors
/// Unknown extension or any reader error.
pub fn load_mesh_with_progress(
    path: &Path,
    origin: Option<[f64; 3]>,
    bar: &ProgressBar,
) -> Result<MeshData> {
    let raw = load_raw(path, true, bar)?;
    MeshData::from_raw_at(raw, path, origin)
}

/// Load only the geometry of a mesh (for a mask mesh: textures are not read).
///
/// # Errors
/// Unknown extension or any reader error.
pub fn load_geometry(path: &Path) -> Result<RawMesh> {
    load_raw(path, false, &ProgressBar::hidden())
}

fn load_raw(path: &Path, appearance: bool, bar: &ProgressBar) -> Result<RawMesh> {
    if has_extension(path, "obj") {
        obj::read_with_progress(path, appearance, bar)
    } else if has_extension(path, "ply") {
        ply::read_with_progress(path, appearance, bar)
    } else {
        Err(Error::file(
            path,
            "unknown mesh format (expected a .obj or .ply file)",
        ))
    }
}
