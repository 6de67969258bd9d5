//! Wavefront OBJ meshes with MTL textures.
//!
//! Statements read: `v x y z [w]` and the common vertex-colour extension
//! `v x y z r g b` (colour in [0, 1], or [0, 255] when any component exceeds 1);
//! `vt u [v [w]]`; `f` with corners `a`, `a/b`, `a/b/c` or `a//c`, positive
//! (1-based) or negative (relative to the end) indices, polygons fan-triangulated
//! around their first corner; `mtllib` and `usemtl`. `vn` and every other
//! statement (`o`, `g`, `s`, `l`, ...) are ignored; `#` starts a comment.
//!
//! Materials: `newmtl` and `map_Kd [options] file` in the MTL file, with the
//! texture path relative to the MTL file. Of the options, `-s u [v [w]]` and
//! `-o u [v [w]]` are applied to the texture coordinates of the material's faces
//! (`u' = u · s + o`), `-mm`, `-imfchan`, `-t` and `-type` are refused (they change
//! gray levels or coordinates in ways a map product cannot hold), the rest do not
//! change a diffuse lookup and are skipped. Textures are loaded by
//! [`crate::io::image`] and converted to 8-bit gray. Faces whose materials use
//! several textures (texture pages) get one atlas ([`crate::io::atlas`]); then
//! every face needs a textured material.
//!
//! Errors name the OBJ or MTL file and line. Bounds: counts fit `u32`; lines are
//! processed one at a time, so memory grows with the mesh only.

use crate::error::{Error, Result};
use crate::io::atlas;
use crate::io::image::Gray8;
use crate::io::mesh::raw::{check_capacity, CornerUvs, RawMesh};
use crate::io::{clip, parse_finite, parse_finite_f64};
use indicatif::ProgressBar;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Lines between two progress updates.
const PROGRESS_LINES: usize = 1 << 16;

/// A material of an MTL file: only its diffuse texture matters here.
#[derive(Clone, Debug, PartialEq)]
struct Material {
    /// Its `map_Kd`, if any.
    map_kd: Option<TextureRef>,
}

/// A `map_Kd` statement: the texture and how it maps texture coordinates.
#[derive(Clone, Debug, PartialEq)]
struct TextureRef {
    /// Resolved texture path.
    file: PathBuf,
    /// MTL file and line that named it.
    mtl: PathBuf,
    line: usize,
    /// `-s u v`: texture coordinates are multiplied by this ...
    scale: [f32; 2],
    /// ... then `-o u v` is added.
    offset: [f32; 2],
}

/// Read an OBJ file. With `appearance`, also read its MTL libraries and texture;
/// without, only geometry and texture coordinates (for mask meshes).
///
/// # Errors
/// See the module doc.
pub fn read(path: &Path, appearance: bool) -> Result<RawMesh> {
    read_with_progress(path, appearance, &ProgressBar::hidden())
}

/// [`read`], reporting the bytes parsed so far on `bar` (its length is set to the file's).
///
/// # Errors
/// See the module doc.
pub fn read_with_progress(path: &Path, appearance: bool, bar: &ProgressBar) -> Result<RawMesh> {
    let bytes = super::read_file(path)?;
    parse_with_progress(&bytes, path, appearance, bar)
}

/// Parse OBJ `bytes`; `path` names errors and locates MTL files.
///
/// # Errors
/// See the module doc.
pub fn parse(bytes: &[u8], path: &Path, appearance: bool) -> Result<RawMesh> {
    parse_with_progress(bytes, path, appearance, &ProgressBar::hidden())
}

fn parse_with_progress(
    bytes: &[u8],
    path: &Path,
    appearance: bool,
    bar: &ProgressBar,
) -> Result<RawMesh> {
    bar.set_length(bytes.len() as u64);
    let mut done = 0usize;
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut vertices: Vec<[f64; 3]> = Vec::new();
    let mut colours: Vec<Option<[f32; 3]>> = Vec::new();
    let mut texcoords: Vec<[f32; 2]> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut tri_vt: Vec<Option<[u32; 3]>> = Vec::new();
    let mut tri_mat: Vec<Option<usize>> = Vec::new();
    let mut tri_line: Vec<usize> = Vec::new();
    let mut materials: BTreeMap<String, usize> = BTreeMap::new();
    let mut mat_list: Vec<Material> = Vec::new();
    let mut current: Option<usize> = None;
    let mut saw_usemtl = false;

    for (i, raw_line) in bytes.split(|&b| b == b'\n').enumerate() {
        let ln = i + 1;
        done += raw_line.len() + 1;
        if i % PROGRESS_LINES == 0 {
            bar.set_position(done as u64);
        }
        let err = |m: String| Error::at(path, ln, m);
        let text =
            std::str::from_utf8(raw_line).map_err(|_| err("line is not UTF-8 text".to_string()))?;
        let text = text.split('#').next().unwrap_or("");
        let mut toks = text.split_whitespace();
        let Some(key) = toks.next() else { continue };
        match key {
            "v" => {
                let vals: Vec<&str> = toks.collect();
                if !matches!(vals.len(), 3 | 4 | 6 | 7) {
                    return Err(err(format!(
                        "vertex needs 3 coordinates (optionally w or r g b), found {} values",
                        vals.len()
                    )));
                }
                // f64: coordinates may be georeferenced (the map origin is taken off later).
                let mut f = [0f64; 6];
                for (k, (slot, tok)) in f.iter_mut().zip(vals.iter()).enumerate() {
                    *slot =
                        parse_finite_f64(tok, &format!("vertex value {}", k + 1)).map_err(err)?;
                }
                if vertices.len() >= u32::MAX as usize {
                    return Err(err("too many vertices".to_string()));
                }
                vertices.push([f[0], f[1], f[2]]);
                colours.push((vals.len() == 6).then_some([f[3] as f32, f[4] as f32, f[5] as f32]));
            }
            "vt" => {
                let vals: Vec<&str> = toks.collect();
                if vals.is_empty() || vals.len() > 3 {
                    return Err(err(format!(
                        "texture coordinate needs 1 to 3 values, found {}",
                        vals.len()
                    )));
                }
                let u = parse_finite(vals[0], "texture u").map_err(err)?;
                let v = match vals.get(1) {
                    Some(t) => parse_finite(t, "texture v").map_err(err)?,
                    None => 0.0,
                };
                if texcoords.len() >= u32::MAX as usize {
                    return Err(err("too many texture coordinates".to_string()));
                }
                texcoords.push([u, v]);
            }
            "f" => {
                let corners: Vec<&str> = toks.collect();
                if corners.len() < 3 {
                    return Err(err(format!(
                        "face needs at least 3 corners, found {}",
                        corners.len()
                    )));
                }
                let mut vi = Vec::with_capacity(corners.len());
                let mut ti = Vec::with_capacity(corners.len());
                for c in &corners {
                    let (v, t) = parse_corner(c, vertices.len(), texcoords.len()).map_err(err)?;
                    vi.push(v);
                    ti.push(t);
                }
                let with_vt = ti.iter().filter(|t| t.is_some()).count();
                if with_vt != 0 && with_vt != ti.len() {
                    return Err(err(
                        "face mixes corners with and without texture coordinates".to_string(),
                    ));
                }
                for k in 1..vi.len() - 1 {
                    if triangles.len() >= u32::MAX as usize {
                        return Err(err("too many triangles".to_string()));
                    }
                    triangles.push([vi[0], vi[k], vi[k + 1]]);
                    tri_vt.push(match (ti[0], ti[k], ti[k + 1]) {
                        (Some(a), Some(b), Some(c)) => Some([a, b, c]),
                        _ => None,
                    });
                    tri_mat.push(current);
                    tri_line.push(ln);
                }
            }
            "mtllib" if appearance => {
                let rest: Vec<&str> = toks.collect();
                if rest.is_empty() {
                    return Err(err("mtllib names no file".to_string()));
                }
                let joined = rest.join(" ");
                let names: Vec<String> = if dir.join(&joined).is_file() || rest.len() == 1 {
                    vec![joined]
                } else {
                    rest.iter().map(|s| s.to_string()).collect()
                };
                for name in names {
                    let mtl_path = dir.join(name.replace('\\', "/"));
                    let bytes = std::fs::read(&mtl_path).map_err(|e| {
                        err(format!(
                            "cannot read material library `{}`: {}",
                            mtl_path.display(),
                            super::io_reason(&e)
                        ))
                    })?;
                    for (mname, m) in parse_mtl(&bytes, &mtl_path)? {
                        let idx = mat_list.len();
                        mat_list.push(m);
                        materials.insert(mname, idx);
                    }
                }
            }
            "usemtl" if appearance => {
                let name = toks.collect::<Vec<_>>().join(" ");
                if name.is_empty() {
                    return Err(err("usemtl names no material".to_string()));
                }
                let Some(&idx) = materials.get(&name) else {
                    return Err(err(format!(
                        "material `{}` is not defined by any mtllib before this line",
                        clip(&name)
                    )));
                };
                current = Some(idx);
                saw_usemtl = true;
            }
            _ => {}
        }
    }

    if triangles.is_empty() {
        return Err(Error::file(path, "no faces"));
    }

    let all_vt = tri_vt.iter().all(Option::is_some);
    let uvs: Option<Vec<[[f32; 2]; 3]>> = if all_vt {
        Some(
            tri_vt
                .iter()
                .flatten()
                .map(|t| t.map(|k| texcoords.get(k as usize).copied().unwrap_or([0.0, 0.0])))
                .collect(),
        )
    } else {
        None
    };

    bar.set_position(bytes.len() as u64);
    let vertex_gray = vertex_gray(&colours);
    let mut uvs = uvs;
    let texture = if appearance {
        check_capacity(path, vertices.len(), triangles.len())?;
        let faces = FaceMaterials {
            mats: &mat_list,
            tri_mat: &tri_mat,
            tri_vt: &tri_vt,
            tri_line: &tri_line,
            saw_usemtl,
        };
        load_textures(path, &faces, uvs.as_deref_mut())?
    } else {
        None
    };
    Ok(RawMesh {
        vertices,
        triangles,
        uvs,
        vertex_gray,
        texture,
    })
}

/// One face corner → (vertex index, texture index), both 0-based and range-checked.
fn parse_corner(
    tok: &str,
    nv: usize,
    nt: usize,
) -> std::result::Result<(u32, Option<u32>), String> {
    let parts: Vec<&str> = tok.split('/').collect();
    if parts.len() > 3 {
        return Err(format!("face corner `{}` has too many `/`", clip(tok)));
    }
    let v = resolve(parts[0], nv, "vertex", tok)?;
    let t = match parts.get(1) {
        Some(s) if !s.is_empty() => Some(resolve(s, nt, "texture coordinate", tok)?),
        _ => None,
    };
    if let Some(n) = parts.get(2).filter(|s| !s.is_empty()) {
        // Normals are not used, but a malformed index is still a malformed file.
        n.parse::<i64>()
            .map_err(|_| format!("normal index in `{}` is not an integer", clip(tok)))?;
    }
    Ok((v, t))
}

fn resolve(s: &str, count: usize, what: &str, tok: &str) -> std::result::Result<u32, String> {
    let i: i64 = s
        .parse()
        .map_err(|_| format!("{what} index in `{}` is not an integer", clip(tok)))?;
    let count_i = count as i64;
    let idx = if i > 0 {
        i - 1
    } else if i < 0 {
        count_i + i
    } else {
        return Err(format!(
            "{what} index 0 in `{}` (OBJ indices start at 1)",
            clip(tok)
        ));
    };
    if idx < 0 || idx >= count_i {
        return Err(format!(
            "{what} index {i} out of range: {count} {what}s defined so far"
        ));
    }
    Ok(idx as u32)
}

fn vertex_gray(colours: &[Option<[f32; 3]>]) -> Option<Vec<u8>> {
    if colours.is_empty() || colours.iter().any(Option::is_none) {
        return None;
    }
    let max = colours
        .iter()
        .flatten()
        .flat_map(|c| c.iter())
        .fold(0f32, |m, &v| m.max(v));
    let scale = if max > 1.0 { 1.0 } else { 255.0 };
    Some(
        colours
            .iter()
            .flatten()
            .map(|c| {
                let [r, g, b] = c.map(|v| (v * scale).round().clamp(0.0, 255.0) as u8);
                super::image::luma8(r, g, b)
            })
            .collect(),
    )
}

/// What the faces of an OBJ file use: their materials, texture indices and lines.
struct FaceMaterials<'a> {
    mats: &'a [Material],
    tri_mat: &'a [Option<usize>],
    tri_vt: &'a [Option<[u32; 3]>],
    tri_line: &'a [usize],
    saw_usemtl: bool,
}

/// The faces' texture as one gray image: the one texture they use, or an atlas
/// of their texture pages ([`crate::io::atlas`]), with `uvs` transformed by the
/// materials' `map_Kd -s / -o` and remapped into the atlas. `None` when no face
/// uses a texture.
fn load_textures(
    path: &Path,
    f: &FaceMaterials,
    uvs: Option<&mut [CornerUvs]>,
) -> Result<Option<Gray8>> {
    // Material of each triangle that decides its texture: its usemtl, or without
    // any usemtl the library's one textured material.
    let textured: Vec<usize> = f
        .mats
        .iter()
        .enumerate()
        .filter(|(_, m)| m.map_kd.is_some())
        .map(|(i, _)| i)
        .collect();
    let default_mat = if f.saw_usemtl {
        None
    } else {
        match textured.as_slice() {
            [] => return Ok(None),
            [one] => Some(*one),
            _ => {
                return Err(Error::file(
                    path,
                    format!(
                        "the material libraries define {} textured materials but no face \
                         selects one with usemtl",
                        textured.len()
                    ),
                ))
            }
        }
    };
    let mat_of = |k: usize| -> Option<&Material> {
        let m = default_mat.or_else(|| f.tri_mat.get(k).copied().flatten())?;
        f.mats.get(m).filter(|m| m.map_kd.is_some())
    };
    // Distinct textures in order of first use; page of each triangle.
    let mut pages: Vec<&TextureRef> = Vec::new();
    let mut tri_page: Vec<Option<u32>> = Vec::with_capacity(f.tri_mat.len());
    for k in 0..f.tri_mat.len() {
        let page = mat_of(k).and_then(|m| m.map_kd.as_ref()).map(|t| {
            match pages.iter().position(|p| p.file == t.file) {
                Some(i) => i as u32,
                None => {
                    pages.push(t);
                    (pages.len() - 1) as u32
                }
            }
        });
        tri_page.push(page);
    }
    if pages.is_empty() {
        return Ok(None);
    }
    let line_of = |k: usize| f.tri_line.get(k).copied().unwrap_or(0);
    let Some(uvs) = uvs else {
        let k = f.tri_vt.iter().position(Option::is_none).unwrap_or(0);
        return Err(Error::at(
            path,
            line_of(k),
            "face has no texture coordinates (vt) but the mesh is textured",
        ));
    };
    for t in &pages {
        if !t.file.is_file() {
            return Err(Error::at(
                &t.mtl,
                t.line,
                format!("texture `{}` not found", t.file.display()),
            ));
        }
    }
    for (k, uv) in uvs.iter_mut().enumerate() {
        if let Some(m) = mat_of(k).and_then(|m| m.map_kd.as_ref()) {
            for st in uv.iter_mut() {
                *st = [
                    st[0] * m.scale[0] + m.offset[0],
                    st[1] * m.scale[1] + m.offset[1],
                ];
            }
        }
    }
    if let [one] = pages.as_slice() {
        return super::image::read_gray(&one.file).map(Some);
    }
    // Several pages: every face needs one.
    let mut tri_page_all: Vec<u32> = Vec::with_capacity(tri_page.len());
    for (k, p) in tri_page.iter().enumerate() {
        let Some(p) = p else {
            let why = match f.tri_mat.get(k).copied().flatten() {
                None => "no material (no usemtl before it)".to_string(),
                Some(_) => "a material without map_Kd".to_string(),
            };
            return Err(Error::at(
                path,
                line_of(k),
                format!(
                    "face has {why} while other faces use {} texture pages; every face \
                     of a multi-page mesh needs a textured material",
                    pages.len()
                ),
            ));
        };
        tri_page_all.push(*p);
    }
    let images = pages
        .iter()
        .map(|t| {
            Ok(atlas::Page {
                image: super::image::read_gray(&t.file)?,
                name: t.file.display().to_string(),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let packed = atlas::pack(&images, &tri_page_all, uvs).map_err(|m| Error::file(path, m))?;
    Ok(Some(packed.texture))
}

/// What an option of `map_Kd` does here, and how many values it takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum MapOption {
    /// Does not change a diffuse texture lookup; skipped (value count).
    Skip(usize),
    /// `-s` / `-o`: 1 to 3 numbers, applied to the texture coordinates.
    Scale,
    /// See [`MapOption::Scale`].
    Offset,
    /// Changes gray levels or coordinates in a way a map product cannot hold.
    Refuse(&'static str),
}

fn map_option(opt: &str) -> Option<MapOption> {
    Some(match opt {
        "-blendu" | "-blendv" | "-cc" | "-clamp" | "-bm" | "-boost" | "-texres" => {
            MapOption::Skip(1)
        }
        "-s" => MapOption::Scale,
        "-o" => MapOption::Offset,
        "-mm" => MapOption::Refuse("changes the texture's gray levels"),
        "-imfchan" => MapOption::Refuse("selects one channel instead of the colour"),
        "-t" => MapOption::Refuse("perturbs texture coordinates (turbulence)"),
        "-type" => MapOption::Refuse("is for reflection maps"),
        _ => return None,
    })
}

/// Parse `map_Kd [options] file` (tokens after the keyword) into the file name,
/// scale and offset.
fn parse_map_kd(rest: &[&str]) -> std::result::Result<(String, [f32; 2], [f32; 2]), String> {
    let mut k = 0usize;
    let (mut scale, mut offset) = ([1f32, 1.0], [0f32, 0.0]);
    while let Some(opt) = rest.get(k).and_then(|t| map_option(t)) {
        let name = rest.get(k).copied().unwrap_or("");
        k += 1;
        match opt {
            MapOption::Skip(n) => k += n,
            MapOption::Refuse(why) => {
                return Err(format!(
                    "map_Kd option {name} is not supported (it {why}); remove it"
                ))
            }
            MapOption::Scale | MapOption::Offset => {
                let mut vals: Vec<f32> = Vec::new();
                while vals.len() < 3 {
                    match rest.get(k).map(|t| t.parse::<f32>()) {
                        Some(Ok(v)) if v.is_finite() => {
                            vals.push(v);
                            k += 1;
                        }
                        _ => break,
                    }
                }
                let Some(&u) = vals.first() else {
                    return Err(format!("map_Kd option {name} needs 1 to 3 numbers"));
                };
                if opt == MapOption::Scale {
                    scale = [u, vals.get(1).copied().unwrap_or(1.0)];
                } else {
                    offset = [u, vals.get(1).copied().unwrap_or(0.0)];
                }
            }
        }
    }
    let file = rest.get(k..).map(|r| r.join(" ")).unwrap_or_default();
    if file.is_empty() {
        return Err("map_Kd names no texture file".to_string());
    }
    Ok((file, scale, offset))
}

/// Parse an MTL file into (material name, material). Texture paths are resolved
/// relative to the MTL file's directory.
fn parse_mtl(bytes: &[u8], mtl_path: &Path) -> Result<Vec<(String, Material)>> {
    let dir = mtl_path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut out: Vec<(String, Material)> = Vec::new();
    for (i, raw_line) in bytes.split(|&b| b == b'\n').enumerate() {
        let ln = i + 1;
        let err = |m: &str| Error::at(mtl_path, ln, m.to_string());
        let text = std::str::from_utf8(raw_line).map_err(|_| err("line is not UTF-8 text"))?;
        let text = text.split('#').next().unwrap_or("");
        let toks: Vec<&str> = text.split_whitespace().collect();
        let Some((&key, rest)) = toks.split_first() else {
            continue;
        };
        match key {
            "newmtl" => {
                if rest.is_empty() {
                    return Err(err("newmtl names no material"));
                }
                out.push((rest.join(" "), Material { map_kd: None }));
            }
            "map_Kd" | "map_kd" => {
                let (file, scale, offset) = parse_map_kd(rest).map_err(|m| err(&m))?;
                let Some((_, m)) = out.last_mut() else {
                    return Err(err("map_Kd before any newmtl"));
                };
                m.map_kd = Some(TextureRef {
                    file: dir.join(file.replace('\\', "/")),
                    mtl: mtl_path.to_path_buf(),
                    line: ln,
                    scale,
                    offset,
                });
            }
            _ => {}
        }
    }
    Ok(out)
}

/// Write a mesh as OBJ text (positions, per-corner `vt`, faces `a/b`), with an
/// optional `mtllib` line. Used to export meshes and to build test fixtures.
pub fn to_obj_text(
    vertices: &[[f32; 3]],
    triangles: &[[u32; 3]],
    uvs: Option<&[[[f32; 2]; 3]]>,
    mtllib: Option<(&str, &str)>,
) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    if let Some((lib, mat)) = mtllib {
        let _ = writeln!(s, "mtllib {lib}");
        let _ = writeln!(s, "usemtl {mat}");
    }
    for v in vertices {
        let _ = writeln!(s, "v {} {} {}", v[0], v[1], v[2]);
    }
    match uvs {
        Some(uvs) => {
            for t in uvs {
                for c in t {
                    let _ = writeln!(s, "vt {} {}", c[0], c[1]);
                }
            }
            for (k, t) in triangles.iter().enumerate() {
                let b = 3 * k + 1;
                let _ = writeln!(
                    s,
                    "f {}/{} {}/{} {}/{}",
                    t[0] + 1,
                    b,
                    t[1] + 1,
                    b + 1,
                    t[2] + 1,
                    b + 2
                );
            }
        }
        None => {
            for t in triangles {
                let _ = writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
            }
        }
    }
    s
}
