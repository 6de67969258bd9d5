//! PLY meshes (Stanford polygon format), `ascii 1.0`, `binary_little_endian 1.0`
//! and `binary_big_endian 1.0`.
//!
//! Read from the `vertex` element: `x y z`; optional colour `red green blue`
//! (also `r g b` or `diffuse_red ...`; integer types are scaled by their range,
//! float types are taken in [0, 1]) → per-vertex gray (BT.601); optional
//! texture coordinates `u v`, `s t`, `texture_u texture_v` or
//! `texture_s texture_t`. From the `face` element: the list `vertex_indices`
//! (or `vertex_index`), polygons fan-triangulated, and an optional list
//! `texcoord` of `2 n` values per face, which takes precedence over per-vertex
//! coordinates, and an optional scalar `texnumber` (as Metashape and MeshLab
//! write) selecting the face's texture page. Textures are named by
//! `comment TextureFile <file>` lines, relative to the PLY file, page 0 first;
//! with several, every face needs a `texnumber` below their count and the pages
//! are packed into one atlas ([`crate::io::atlas`]). Every other element and
//! property is read and skipped.
//!
//! Element counts are checked against the bytes (binary) or lines (ascii)
//! actually present before anything is allocated, so a forged header cannot
//! exhaust memory. Errors name the file and the header line, body line (ascii)
//! or byte offset (binary).

use crate::error::{Error, Result};
use crate::io::mesh::raw::{check_capacity, RawMesh};
use crate::io::{atlas, clip};
use indicatif::ProgressBar;
use std::path::{Path, PathBuf};

/// Element instances between two progress updates.
const PROGRESS_INSTANCES: usize = 1 << 16;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Ty {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Ty {
    fn parse(s: &str) -> Option<Ty> {
        Some(match s {
            "char" | "int8" => Ty::I8,
            "uchar" | "uint8" => Ty::U8,
            "short" | "int16" => Ty::I16,
            "ushort" | "uint16" => Ty::U16,
            "int" | "int32" => Ty::I32,
            "uint" | "uint32" => Ty::U32,
            "float" | "float32" => Ty::F32,
            "double" | "float64" => Ty::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Ty::I8 | Ty::U8 => 1,
            Ty::I16 | Ty::U16 => 2,
            Ty::I32 | Ty::U32 | Ty::F32 => 4,
            Ty::F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Ty::F32 | Ty::F64)
    }

    /// Full scale of a colour channel of this type.
    fn colour_scale(self) -> f64 {
        match self {
            Ty::U8 | Ty::I8 => 255.0,
            Ty::U16 | Ty::I16 => 65535.0,
            Ty::U32 | Ty::I32 => 4_294_967_295.0,
            Ty::F32 | Ty::F64 => 1.0,
        }
    }
}

#[derive(Clone, Debug)]
enum Prop {
    Scalar(String, Ty),
    List(String, Ty, Ty),
}

impl Prop {
    fn min_size(&self) -> usize {
        match self {
            Prop::Scalar(_, t) => t.size(),
            Prop::List(_, c, _) => c.size(),
        }
    }
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Prop>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Ascii,
    Le,
    Be,
}

/// Read a PLY file; with `appearance`, also its `TextureFile`.
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

/// Where a value came from, for error messages.
enum Loc {
    Line(usize),
    Byte(usize),
}

/// One face as read: vertex indices, optional `texcoord` list, optional
/// `texnumber`, and where it was.
struct Face {
    verts: Vec<f64>,
    texcoord: Option<Vec<f64>>,
    page: Option<f64>,
    loc: Loc,
}

/// The body as a stream of numbers.
struct Body<'a> {
    format: Format,
    bytes: &'a [u8],
    pos: usize,
    /// ascii: current line tokens and line number
    toks: Vec<&'a str>,
    tok_pos: usize,
    line: usize,
}

impl<'a> Body<'a> {
    fn loc(&self) -> Loc {
        match self.format {
            Format::Ascii => Loc::Line(self.line),
            _ => Loc::Byte(self.pos),
        }
    }

    /// ascii: move to the next non-empty line (one element instance per line).
    fn start_instance(&mut self) -> std::result::Result<(), String> {
        if self.format != Format::Ascii {
            return Ok(());
        }
        loop {
            if self.pos >= self.bytes.len() {
                return Err("file ends before all elements were read (truncated)".to_string());
            }
            let rest = self.bytes.get(self.pos..).unwrap_or(&[]);
            let end = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
            let line = rest.get(..end).unwrap_or(&[]);
            self.pos += end + 1;
            self.line += 1;
            let text =
                std::str::from_utf8(line).map_err(|_| "line is not UTF-8 text".to_string())?;
            self.toks = text.split_whitespace().collect();
            self.tok_pos = 0;
            if !self.toks.is_empty() {
                return Ok(());
            }
        }
    }

    fn end_instance(&self) -> std::result::Result<(), String> {
        if self.format == Format::Ascii && self.tok_pos != self.toks.len() {
            return Err(format!(
                "{} values on the line, expected {}",
                self.toks.len(),
                self.tok_pos
            ));
        }
        Ok(())
    }

    fn value(&mut self, ty: Ty) -> std::result::Result<f64, String> {
        match self.format {
            Format::Ascii => {
                let tok = self
                    .toks
                    .get(self.tok_pos)
                    .ok_or_else(|| "too few values on the line".to_string())?;
                self.tok_pos += 1;
                let v: f64 = if ty.is_float() {
                    tok.parse()
                        .map_err(|_| format!("`{}` is not a number", clip(tok)))?
                } else {
                    tok.parse::<i64>()
                        .map_err(|_| format!("`{}` is not an integer", clip(tok)))?
                        as f64
                };
                if !v.is_finite() {
                    return Err(format!("`{}` is not finite", clip(tok)));
                }
                Ok(v)
            }
            Format::Le | Format::Be => {
                let n = ty.size();
                let b = self.bytes.get(self.pos..self.pos + n).ok_or_else(|| {
                    "file ends before all elements were read (truncated)".to_string()
                })?;
                let mut a = [0u8; 8];
                if let Some(dst) = a.get_mut(..n) {
                    dst.copy_from_slice(b);
                }
                if self.format == Format::Be {
                    if let Some(dst) = a.get_mut(..n) {
                        dst.reverse();
                    }
                }
                self.pos += n;
                let v = match ty {
                    Ty::I8 => f64::from(a[0] as i8),
                    Ty::U8 => f64::from(a[0]),
                    Ty::I16 => f64::from(i16::from_le_bytes([a[0], a[1]])),
                    Ty::U16 => f64::from(u16::from_le_bytes([a[0], a[1]])),
                    Ty::I32 => f64::from(i32::from_le_bytes([a[0], a[1], a[2], a[3]])),
                    Ty::U32 => f64::from(u32::from_le_bytes([a[0], a[1], a[2], a[3]])),
                    Ty::F32 => f64::from(f32::from_le_bytes([a[0], a[1], a[2], a[3]])),
                    Ty::F64 => f64::from_le_bytes(a),
                };
                if !v.is_finite() {
                    return Err("value is not finite".to_string());
                }
                Ok(v)
            }
        }
    }
}

struct Header {
    format: Format,
    elements: Vec<Element>,
    /// `comment TextureFile` names with their header lines, in file order.
    textures: Vec<(String, usize)>,
    body_start: usize,
    header_lines: usize,
}

fn parse_header(bytes: &[u8], path: &Path) -> Result<Header> {
    if !bytes.starts_with(b"ply\n") && !bytes.starts_with(b"ply\r\n") {
        return Err(Error::at(path, 1, "not a PLY file (missing `ply` magic)"));
    }
    let mut pos = 0usize;
    let mut ln = 0usize;
    let mut format: Option<Format> = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut textures = Vec::new();
    loop {
        let rest = bytes.get(pos..).unwrap_or(&[]);
        let Some(end) = rest.iter().position(|&b| b == b'\n') else {
            return Err(Error::file(path, "header has no `end_header` (truncated)"));
        };
        ln += 1;
        let line = rest.get(..end).unwrap_or(&[]);
        pos += end + 1;
        let err = |m: String| Error::at(path, ln, m);
        let text = std::str::from_utf8(line)
            .map_err(|_| err("header line is not UTF-8 text".to_string()))?
            .trim_end_matches('\r');
        let toks: Vec<&str> = text.split_whitespace().collect();
        match toks.as_slice() {
            ["ply"] if ln == 1 => {}
            ["format", f, ver] => {
                format = Some(match *f {
                    "ascii" => Format::Ascii,
                    "binary_little_endian" => Format::Le,
                    "binary_big_endian" => Format::Be,
                    _ => return Err(err(format!("unknown format `{}`", clip(f)))),
                });
                if *ver != "1.0" {
                    return Err(err(format!("unsupported PLY version `{}`", clip(ver))));
                }
            }
            ["comment", "TextureFile", name @ ..] | ["comment", "texturefile", name @ ..]
                if !name.is_empty() =>
            {
                textures.push((name.join(" "), ln));
            }
            ["comment", ..] | ["obj_info", ..] | [] => {}
            ["element", name, count] => {
                let count: usize = count
                    .parse()
                    .map_err(|_| err(format!("element count `{}` is not a number", clip(count))))?;
                elements.push(Element {
                    name: (*name).to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            ["property", "list", c, t, name] => {
                let (Some(c), Some(t)) = (Ty::parse(c), Ty::parse(t)) else {
                    return Err(err("unknown property type".to_string()));
                };
                if c.is_float() {
                    return Err(err("list count type must be an integer type".to_string()));
                }
                let el = elements
                    .last_mut()
                    .ok_or_else(|| err("property before any element".to_string()))?;
                el.props.push(Prop::List((*name).to_string(), c, t));
            }
            ["property", t, name] => {
                let t = Ty::parse(t)
                    .ok_or_else(|| err(format!("unknown property type `{}`", clip(t))))?;
                let el = elements
                    .last_mut()
                    .ok_or_else(|| err("property before any element".to_string()))?;
                el.props.push(Prop::Scalar((*name).to_string(), t));
            }
            ["end_header"] => break,
            _ => return Err(err(format!("unrecognised header line `{}`", clip(text)))),
        }
    }
    let format = format.ok_or_else(|| Error::file(path, "header has no `format` line"))?;
    Ok(Header {
        format,
        elements,
        textures,
        body_start: pos,
        header_lines: ln,
    })
}

fn find_scalar(props: &[Prop], names: &[&str]) -> Option<(usize, Ty)> {
    names.iter().find_map(|n| {
        props.iter().enumerate().find_map(|(i, p)| match p {
            Prop::Scalar(pn, t) if pn == n => Some((i, *t)),
            _ => None,
        })
    })
}

fn find_list(props: &[Prop], names: &[&str]) -> Option<usize> {
    names.iter().find_map(|n| {
        props
            .iter()
            .position(|p| matches!(p, Prop::List(pn, _, _) if pn == n))
    })
}

/// Parse PLY `bytes`; `path` names errors and locates the texture.
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
    let h = parse_header(bytes, path)?;
    let body_len = bytes.len().saturating_sub(h.body_start);
    for el in &h.elements {
        let min = el.props.iter().map(Prop::min_size).sum::<usize>().max(1);
        let fits = match h.format {
            // An ascii instance takes at least 2 bytes ("0\n").
            Format::Ascii => el.count <= body_len / 2 + 1,
            _ => el.count.checked_mul(min).is_some_and(|n| n <= body_len),
        };
        if !fits || el.count > u32::MAX as usize {
            return Err(Error::file(
                path,
                format!(
                    "element `{}` declares {} instances but the file is too short (truncated)",
                    clip(&el.name),
                    el.count
                ),
            ));
        }
    }
    let mut body = Body {
        format: h.format,
        bytes,
        pos: h.body_start,
        toks: Vec::new(),
        tok_pos: 0,
        line: h.header_lines,
    };

    let mut vertices: Vec<[f64; 3]> = Vec::new();
    let mut gray: Vec<u8> = Vec::new();
    let mut vuv: Vec<[f32; 2]> = Vec::new();
    let mut has_colour = false;
    let mut has_vuv = false;
    let mut faces: Vec<Face> = Vec::new();
    let mut has_texnumber = false;
    let mut saw_vertex = false;
    let mut saw_face = false;

    for el in &h.elements {
        let is_vertex = el.name == "vertex" && !saw_vertex;
        let is_face = el.name == "face" && !saw_face;
        saw_vertex |= is_vertex;
        saw_face |= is_face;
        let (xyz, rgb, uv) = if is_vertex {
            let x = find_scalar(&el.props, &["x"]);
            let y = find_scalar(&el.props, &["y"]);
            let z = find_scalar(&el.props, &["z"]);
            let (Some(x), Some(y), Some(z)) = (x, y, z) else {
                return Err(Error::file(path, "vertex element lacks x, y or z"));
            };
            let r = find_scalar(&el.props, &["red", "r", "diffuse_red"]);
            let g = find_scalar(&el.props, &["green", "g", "diffuse_green"]);
            let b = find_scalar(&el.props, &["blue", "b", "diffuse_blue"]);
            let rgb = match (r, g, b) {
                (Some(r), Some(g), Some(b)) => Some([r, g, b]),
                _ => None,
            };
            let u = find_scalar(&el.props, &["u", "s", "texture_u", "texture_s"]);
            let v = find_scalar(&el.props, &["v", "t", "texture_v", "texture_t"]);
            let uv = match (u, v) {
                (Some(u), Some(v)) => Some([u.0, v.0]),
                _ => None,
            };
            has_colour = rgb.is_some();
            has_vuv = uv.is_some();
            vertices.reserve(el.count);
            (Some([x.0, y.0, z.0]), rgb, uv)
        } else {
            (None, None, None)
        };
        let (vidx, tidx, pidx) = if is_face {
            let Some(vi) = find_list(&el.props, &["vertex_indices", "vertex_index"]) else {
                return Err(Error::file(
                    path,
                    "face element lacks a vertex_indices list",
                ));
            };
            if let Some(Prop::List(_, _, t)) = el.props.get(vi) {
                if t.is_float() {
                    return Err(Error::file(
                        path,
                        "vertex_indices must have an integer type",
                    ));
                }
            }
            let texnumber = find_scalar(&el.props, &["texnumber"]);
            has_texnumber = texnumber.is_some();
            (
                Some(vi),
                find_list(&el.props, &["texcoord"]),
                texnumber.map(|t| t.0),
            )
        } else {
            (None, None, None)
        };

        let mut vals: Vec<f64> = Vec::with_capacity(el.props.len());
        for n in 0..el.count {
            if n % PROGRESS_INSTANCES == 0 {
                bar.set_position(body.pos as u64);
            }
            let fail = |b: &Body, m: String| match b.loc() {
                Loc::Line(l) => Error::at(path, l, m),
                Loc::Byte(o) => Error::file(path, format!("at byte {o}: {m}")),
            };
            body.start_instance().map_err(|m| fail(&body, m))?;
            let loc = body.loc();
            vals.clear();
            let mut flist: Vec<f64> = Vec::new();
            let mut tlist: Option<Vec<f64>> = None;
            for (pi, p) in el.props.iter().enumerate() {
                match p {
                    Prop::Scalar(_, t) => {
                        let v = body.value(*t).map_err(|m| fail(&body, m))?;
                        vals.push(v);
                    }
                    Prop::List(name, c, t) => {
                        let n = body.value(*c).map_err(|m| fail(&body, m))?;
                        if n < 0.0 {
                            return Err(fail(
                                &body,
                                format!("list `{}` has a negative length", clip(name)),
                            ));
                        }
                        let n = n as usize;
                        // Each item takes at least one byte (binary) or two (ascii).
                        if n > body_len {
                            return Err(fail(
                                &body,
                                format!("list `{}` is longer than the file", clip(name)),
                            ));
                        }
                        let mut items = Vec::with_capacity(n);
                        for _ in 0..n {
                            items.push(body.value(*t).map_err(|m| fail(&body, m))?);
                        }
                        vals.push(f64::NAN);
                        if Some(pi) == vidx {
                            flist = items;
                        } else if Some(pi) == tidx {
                            tlist = Some(items);
                        }
                    }
                }
            }
            body.end_instance().map_err(|m| fail(&body, m))?;
            let get = |i: usize| vals.get(i).copied().unwrap_or(0.0);
            if let Some([x, y, z]) = xyz {
                // f64: coordinates may be georeferenced (the map origin is taken off later).
                let p = [get(x), get(y), get(z)];
                if !p.iter().all(|c| c.is_finite()) {
                    return Err(fail(&body, "vertex coordinate is not finite".to_string()));
                }
                vertices.push(p);
                if let Some([r, g, b]) = rgb {
                    let c = |(i, t): (usize, Ty)| {
                        (get(i) / t.colour_scale() * 255.0)
                            .round()
                            .clamp(0.0, 255.0) as u8
                    };
                    gray.push(super::image::luma8(c(r), c(g), c(b)));
                }
                if let Some([u, v]) = uv {
                    vuv.push([get(u) as f32, get(v) as f32]);
                }
            }
            if is_face {
                if flist.len() < 3 {
                    return Err(fail(
                        &body,
                        format!("face needs at least 3 vertices, found {}", flist.len()),
                    ));
                }
                faces.push(Face {
                    verts: flist,
                    texcoord: tlist,
                    page: pidx.map(get),
                    loc,
                });
            }
        }
    }
    if !saw_vertex {
        return Err(Error::file(path, "no vertex element"));
    }
    if !saw_face || faces.is_empty() {
        return Err(Error::file(path, "no faces"));
    }
    if body.format != Format::Ascii && body.pos != bytes.len() {
        return Err(Error::file(
            path,
            format!("{} bytes after the last element", bytes.len() - body.pos),
        ));
    }

    let nv = vertices.len();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut face_uvs: Vec<[[f32; 2]; 3]> = Vec::new();
    let mut tri_page: Vec<u32> = Vec::new();
    let all_tc = faces.iter().all(|f| f.texcoord.is_some());
    let pages = if appearance { h.textures.len() } else { 0 };
    if pages > 1 && !has_texnumber {
        return Err(Error::file(
            path,
            format!(
                "the header names {pages} texture files but the face element has no \
                 `texnumber` property saying which one each face uses"
            ),
        ));
    }
    for Face {
        verts: fl,
        texcoord: tl,
        page,
        loc,
    } in &faces
    {
        let at = |m: String| match loc {
            Loc::Line(l) => Error::at(path, *l, m),
            Loc::Byte(o) => Error::file(path, format!("face at byte {o}: {m}")),
        };
        let mut idx = Vec::with_capacity(fl.len());
        for &v in fl {
            if v < 0.0 || v >= nv as f64 {
                return Err(at(format!("vertex index {v} out of range: {nv} vertices")));
            }
            idx.push(v as u32);
        }
        let tc: Option<Vec<[f32; 2]>> = match tl {
            Some(t) if all_tc => {
                if t.len() != 2 * fl.len() {
                    return Err(at(format!(
                        "texcoord has {} values for {} corners (expected {})",
                        t.len(),
                        fl.len(),
                        2 * fl.len()
                    )));
                }
                Some(t.chunks(2).map(|c| [c[0] as f32, c[1] as f32]).collect())
            }
            _ => None,
        };
        let page = match page {
            Some(p) if pages > 0 => {
                if !(*p >= 0.0 && *p < pages as f64) {
                    return Err(at(format!(
                        "texnumber {p} out of range: the header names {pages} texture file{}",
                        if pages == 1 { "" } else { "s" }
                    )));
                }
                *p as u32
            }
            _ => 0,
        };
        for k in 1..idx.len() - 1 {
            triangles.push([idx[0], idx[k], idx[k + 1]]);
            tri_page.push(page);
            if let Some(tc) = &tc {
                face_uvs.push([tc[0], tc[k], tc[k + 1]]);
            }
        }
    }
    let uvs = if all_tc {
        Some(face_uvs)
    } else if has_vuv {
        Some(
            triangles
                .iter()
                .map(|t| t.map(|k| vuv.get(k as usize).copied().unwrap_or([0.0, 0.0])))
                .collect(),
        )
    } else {
        None
    };
    bar.set_position(bytes.len() as u64);
    if appearance {
        check_capacity(path, vertices.len(), triangles.len())?;
    }
    let mut uvs = uvs;
    let texture = if appearance && !h.textures.is_empty() {
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut images = Vec::with_capacity(h.textures.len());
        for (name, ln) in &h.textures {
            let tex: PathBuf = dir.join(name.replace('\\', "/"));
            if !tex.is_file() {
                return Err(Error::at(
                    path,
                    *ln,
                    format!("texture `{}` not found", tex.display()),
                ));
            }
            images.push(atlas::Page {
                image: super::image::read_gray(&tex)?,
                name: tex.display().to_string(),
            });
        }
        match (images.len(), uvs.as_deref_mut()) {
            (1, _) | (_, None) => images.into_iter().next().map(|p| p.image),
            (_, Some(uvs)) => Some(
                atlas::pack(&images, &tri_page, uvs)
                    .map_err(|m| Error::file(path, m))?
                    .texture,
            ),
        }
    } else {
        None
    };
    Ok(RawMesh {
        vertices,
        triangles,
        uvs,
        vertex_gray: has_colour.then_some(gray),
        texture,
    })
}
