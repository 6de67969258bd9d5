//! The one reader of every mesh form: OBJ + MTL ([`crate::io::obj`]) or PLY
//! ([`crate::io::ply`]) by extension, either of them possibly xz-compressed
//! (`mesh.obj.xz`, decompressed in memory), into a [`RawMesh`] and then a
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
    if has_extension(path, "xz") {
        let inner = path.with_extension("");
        let bytes = read_xz(path)?;
        bar.set_length(bytes.len() as u64);
        return if has_extension(&inner, "obj") {
            obj::parse(&bytes, &inner, appearance)
        } else if has_extension(&inner, "ply") {
            ply::parse(&bytes, &inner, appearance)
        } else {
            Err(Error::file(
                path,
                "unknown mesh format (expected a .obj.xz or .ply.xz file)",
            ))
        }
        .map_err(|mut e| {
            // Errors name the file as given, not the name inside it.
            if e.file.as_deref() == Some(inner.as_path()) {
                e.file = Some(path.to_path_buf());
            }
            e
        });
    }
    if has_extension(path, "obj") {
        obj::read_with_progress(path, appearance, bar)
    } else if has_extension(path, "ply") {
        ply::read_with_progress(path, appearance, bar)
    } else {
        Err(Error::file(
            path,
            "unknown mesh format (expected a .obj or .ply file, or either xz-compressed)",
        ))
    }
}

/// The decompressed content of the xz file `path` (a mesh exported as
/// `mesh.obj.xz`); the files it names (MTL, texture) are looked up beside it.
fn read_xz(path: &Path) -> Result<Vec<u8>> {
    let packed = crate::io::read_file(path)?;
    let mut out = Vec::new();
    lzma_rs::xz_decompress(&mut std::io::Cursor::new(packed), &mut out)
        .map_err(|e| Error::file(path, format!("not a valid xz file: {e}")))?;
    Ok(out)
}
