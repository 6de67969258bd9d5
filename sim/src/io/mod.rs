//! File formats read and written by the desktop tools (design §5; the interface
//! control document is `fsw-docs/interfaces/files.md`).
//!
//! Readers: Wavefront OBJ + MTL ([`obj`]), PLY ([`ply`]), PNG / JPEG / TIFF / PGM
//! images ([`image`]), the JSON files `calib.json`, `prior.json` / `truth.json` and
//! `result.json` ([`json`]). Meshes of either format load into [`mesh::MeshData`],
//! the in-memory form that becomes a map product ([`mesh::MeshData::encode_map`]);
//! faces on several texture pages get one repacked texture ([`atlas`]).
//!
//! Every reader checks everything it reads: a bad file gives one
//! [`crate::Error`] naming the file, the line (text formats) or byte offset
//! (binary formats) and the reason, never a panic. Writers go through
//! [`write_atomic`], so an output appears complete or not at all, and an
//! existing output is only replaced when asked.

pub mod atlas;
pub mod calib;
pub mod image;
pub mod json;
pub mod mesh;
pub mod obj;
pub mod ply;

use crate::error::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Read a whole file, mapping I/O errors to a one-line [`Error`] naming it.
pub fn read_file(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| Error::file(path, format!("cannot read: {}", io_reason(&e))))
}

/// A short reason for an I/O error (without the OS error number noise).
pub fn io_reason(e: &std::io::Error) -> String {
    match e.kind() {
        std::io::ErrorKind::NotFound => "no such file".to_string(),
        std::io::ErrorKind::PermissionDenied => "permission denied".to_string(),
        _ => e.to_string(),
    }
}

/// Fail unless `path` may be written: it must not exist unless `force`.
///
/// Commands call this before doing any work, so a refused output costs nothing.
pub fn check_output(path: &Path, force: bool) -> Result<()> {
    if path.as_os_str().is_empty() {
        return Err(Error::msg("output path is empty"));
    }
    if path.is_dir() {
        return Err(Error::file(path, "output is a directory"));
    }
    if path.exists() && !force {
        return Err(Error::file(
            path,
            "output exists; pass --force to overwrite it",
        ));
    }
    let dir = parent_dir(path);
    if !dir.is_dir() {
        return Err(Error::file(path, "output directory does not exist"));
    }
    Ok(())
}

fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Write `bytes` to `path` atomically: write a temporary file in the same
/// directory, flush it to disk, then rename it over `path`. On any error the
/// temporary file is removed and `path` is untouched. An existing `path` is
/// replaced only when `force` is set.
pub fn write_atomic(path: &Path, bytes: &[u8], force: bool) -> Result<()> {
    check_output(path, force)?;
    let dir = parent_dir(path);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".to_string());
    let tmp = dir.join(format!(".{name}.tmp.{}", std::process::id()));
    let write = || -> std::io::Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        Ok(())
    };
    if let Err(e) = write() {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::file(
            path,
            format!("cannot write: {}", io_reason(&e)),
        ));
    }
    // Re-check just before the rename: another process may have created it meanwhile.
    if path.exists() && !force {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::file(
            path,
            "output exists; pass --force to overwrite it",
        ));
    }
    if let Err(e) = std::fs::rename(&tmp, path) {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::file(
            path,
            format!("cannot write: {}", io_reason(&e)),
        ));
    }
    Ok(())
}

/// Whether a path's extension equals `ext`, ignoring ASCII case.
pub fn has_extension(path: &Path, ext: &str) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case(ext))
}

/// Parse one finite `f32` token; `what` names the field in the error message.
pub(crate) fn parse_finite(tok: &str, what: &str) -> std::result::Result<f32, String> {
    let v: f32 = tok
        .parse()
        .map_err(|_| format!("{what}: `{}` is not a number", clip(tok)))?;
    if !v.is_finite() {
        return Err(format!("{what}: `{}` is not finite", clip(tok)));
    }
    Ok(v)
}

/// Parse one finite `f64` token (mesh vertex coordinates, which may be
/// georeferenced); `what` names the field in the error message.
pub(crate) fn parse_finite_f64(tok: &str, what: &str) -> std::result::Result<f64, String> {
    let v: f64 = tok
        .parse()
        .map_err(|_| format!("{what}: `{}` is not a number", clip(tok)))?;
    if !v.is_finite() {
        return Err(format!("{what}: `{}` is not finite", clip(tok)));
    }
    Ok(v)
}

/// A token clipped for an error message, so a garbage line cannot flood the terminal.
pub(crate) fn clip(s: &str) -> String {
    const MAX: usize = 40;
    if s.chars().count() <= MAX {
        s.to_string()
    } else {
        let head: String = s.chars().take(MAX).collect();
        format!("{head}...")
    }
}

/// `text` damaged as the file-reader fuzz tests damage it: line `drop_line`
/// left out, cut to `cut` bytes (at least one), then each `(at, byte)` of
/// `edits` written at `at` modulo the length.
#[cfg(test)]
pub(crate) fn damaged(
    text: &str,
    cut: usize,
    edits: &[(usize, u8)],
    drop_line: Option<usize>,
) -> Vec<u8> {
    let text: String = match drop_line {
        Some(k) => text
            .lines()
            .enumerate()
            .filter(|(i, _)| *i != k)
            .map(|(_, s)| format!("{s}\n"))
            .collect(),
        None => text.to_string(),
    };
    let mut bytes = text.into_bytes();
    bytes.truncate(cut.max(1).min(bytes.len()));
    for &(at, b) in edits {
        let n = bytes.len();
        if let Some(slot) = bytes.get_mut(at % n.max(1)) {
            *slot = b;
        }
    }
    bytes
}
