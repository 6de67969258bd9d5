//! The OpenCV FileStorage form of `calib.json`: a physical stereo pair as the
//! YAML files `cv::FileStorage` (`cv2.FileStorage`) writes after
//! `cv::stereoCalibrate`, for example OpenCV's own `stereo_calib` sample
//! (`intrinsics.yml` with `M1 D1 M2 D2`, `extrinsics.yml` with `R T R1 R2 P1 P2
//! Q`).
//!
//! ```json
//! {"opencv_storage": "stereo.yml"}
//! {"opencv_storage": ["intrinsics.yml", "extrinsics.yml"], "image_size": [W, H], "T_unit": "mm"}
//! ```
//!
//! Paths are resolved against the directory of `calib.json`. A YAML file that
//! begins with `%YAML`, or an XML file, may also be given as `--calib`
//! itself; it is read as `{"opencv_storage": that file}`.
//!
//! The files are read together; each item is looked up under the names OpenCV
//! code writes it with ([`KEYS`]): the left camera matrix as `M1`, `K1` or
//! `cameraMatrix1`, its distortion as `D1` or `distCoeffs1`, the right
//! camera's likewise with `2`, and `R`, `T` of `X_right = R · X_left + T`. `R`
//! is a 3×3 matrix or a 3-vector taken as a rotation vector (`cv::Rodrigues`).
//! Values are `!!opencv-matrix` mappings (`rows`, `cols`, `dt`, `data`; `rows`
//! and `cols` checked against `data`) or plain YAML lists. The image size is
//! `image_size` or `imageSize` (two numbers, in either file) or `image_width`
//! with `image_height`, or else `image_size` of `calib.json`; given in both
//! places, they must agree. `T` is in metres unless `T_unit` (`m`, `cm` or
//! `mm`; only in `calib.json`) says otherwise: `stereoCalibrate` returns `T` in
//! the unit of the calibration target's square size. Other keys (`R1`, `P1`,
//! `Q`, `E`, `F`, RMS figures, ...) are ignored; the host rectifier computes
//! the rectification itself. Both YAML headers OpenCV writes are read
//! (`%YAML:1.0` of OpenCV 2–4, `%YAML 1.2` of OpenCV 5), and the XML form
//! ([`xml`]); the JSON form of FileStorage is refused with a message saying
//! so.

use super::model::{OpenCvCalib, OpenCvCamera};
use super::yaml::{bounded_text, get, resolve, yaml_mapping};
use crate::error::{Error, Result};
use nalgebra::{Rotation3, Vector3};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use yaml_rust2::Yaml;

/// Largest accepted size of one FileStorage file, bytes.
pub const MAX_STORAGE_BYTES: usize = 1 << 20;
/// What a FileStorage file is called in messages.
const WHAT: &str = "a FileStorage calibration";
/// Most files one `opencv_storage` list may name.
pub const MAX_STORAGE_FILES: usize = 8;

/// The names each item of the pair is looked up under, in the order tried:
/// `(item, names)`. `item` is the field of the OpenCV form it fills.
pub const KEYS: [(&str, &[&str]); 6] = [
    ("left.K", &["M1", "K1", "cameraMatrix1"]),
    ("left.dist", &["D1", "distCoeffs1"]),
    ("right.K", &["M2", "K2", "cameraMatrix2"]),
    ("right.dist", &["D2", "distCoeffs2"]),
    ("R", &["R"]),
    ("T", &["T"]),
];

/// One or several file names.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum StorageFiles {
    /// One file holding every item.
    One(PathBuf),
    /// Several files, read together.
    Many(Vec<PathBuf>),
}

/// `calib.json` in the FileStorage form.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StorageCalibFile {
    /// The FileStorage YAML file or files.
    pub opencv_storage: StorageFiles,
    /// `[width, height]` when the files do not hold it.
    #[serde(default)]
    pub image_size: Option<[u32; 2]>,
    /// Unit of `T` in the files: `m` (default), `cm` or `mm`.
    #[serde(default, rename = "T_unit")]
    pub t_unit: Option<String>,
}

/// A FileStorage value as a matrix: `(rows, cols, row-major data)`.
fn matrix(y: &Yaml) -> std::result::Result<(usize, usize, Vec<f64>), String> {
    let number = |v: &Yaml| match v {
        Yaml::Real(_) => v.as_f64(),
        Yaml::Integer(i) => Some(*i as f64),
        _ => None,
    };
    let numbers = |list: &[Yaml]| {
        list.iter()
            .map(number)
            .collect::<Option<Vec<f64>>>()
            .ok_or_else(|| "has an element that is not a number".to_string())
    };
    let (rows, cols, data) = match y {
        Yaml::Hash(_) => {
            let data = get(y, "data")
                .and_then(Yaml::as_vec)
                .ok_or("is a mapping without a `data` list")?;
            let data = numbers(data)?;
            let dim = |k: &str| -> std::result::Result<Option<usize>, String> {
                match get(y, k) {
                    None => Ok(None),
                    Some(v) => v
                        .as_i64()
                        .and_then(|n| usize::try_from(n).ok())
                        .map(Some)
                        .ok_or_else(|| format!("`{k}` is not a count")),
                }
            };
            let (rows, cols) = match (dim("rows")?, dim("cols")?) {
                (Some(r), Some(c)) => (r, c),
                (Some(r), None) => (r, data.len() / r.max(1)),
                (None, Some(c)) => (data.len() / c.max(1), c),
                (None, None) => (1, data.len()),
            };
            if rows.checked_mul(cols) != Some(data.len()) {
                return Err(format!(
                    "has rows × cols = {rows} × {cols} but {} numbers in `data`",
                    data.len()
                ));
            }
            (rows, cols, data)
        }
        Yaml::Array(list) if list.iter().all(|r| r.as_vec().is_some()) && !list.is_empty() => {
            let rows: Vec<Vec<f64>> = list
                .iter()
                .map(|r| numbers(r.as_vec().map_or(&[][..], Vec::as_slice)))
                .collect::<std::result::Result<_, _>>()?;
            let cols = rows[0].len();
            if rows.iter().any(|r| r.len() != cols) {
                return Err("has rows of different lengths".into());
            }
            (rows.len(), cols, rows.concat())
        }
        Yaml::Array(list) => {
            let data = numbers(list)?;
            (1, data.len(), data)
        }
        _ => return Err("is not a matrix (`!!opencv-matrix` mapping or list)".into()),
    };
    if !data.iter().all(|v| v.is_finite()) {
        return Err("has a non-finite element".into());
    }
    Ok((rows, cols, data))
}

/// A matrix that is a vector (one row or one column).
fn vector(y: &Yaml) -> std::result::Result<Vec<f64>, String> {
    let (rows, cols, data) = matrix(y)?;
    if rows != 1 && cols != 1 {
        return Err(format!("is {rows} × {cols}, not a vector"));
    }
    Ok(data)
}

fn m3(y: &Yaml) -> std::result::Result<[[f64; 3]; 3], String> {
    let (rows, cols, d) = matrix(y)?;
    if (rows, cols) != (3, 3) && !(d.len() == 9 && (rows == 1 || cols == 1)) {
        return Err(format!("is {rows} × {cols}, not 3 × 3"));
    }
    Ok([[d[0], d[1], d[2]], [d[3], d[4], d[5]], [d[6], d[7], d[8]]])
}

/// The top-level mapping of one FileStorage file (`bytes`, read from
/// `path`): XML through [`xml`], YAML with the `%YAML:1.0` directive of
/// OpenCV 2–4 (not YAML) turned into a comment, line numbers kept.
fn storage_doc(bytes: &[u8], path: &Path) -> Result<Yaml> {
    let text = bounded_text(bytes, path, MAX_STORAGE_BYTES, WHAT)?;
    let head = text.trim_start();
    if xml::is_xml(head.as_bytes()) {
        return xml::parse(text, path);
    }
    if head.starts_with('{') {
        return Err(Error::file(
            path,
            "FileStorage JSON is not read; write the calibration as YAML or XML (cv2.FileStorage(\"….yml\", …))",
        ));
    }
    let mut yaml = text.as_bytes().to_vec();
    if head.starts_with("%YAML:") {
        yaml[text.len() - head.len()] = b'#';
    }
    lower_special_reals(&mut yaml);
    yaml_mapping(&yaml, path, MAX_STORAGE_BYTES, WHAT)
}

/// OpenCV writes NaN and infinities as `.Nan` and `.Inf`, which YAML does not
/// read as numbers; as whole tokens (between white space, `[`, `,`, `]`, `:`
/// or a sign and the next of those) they become `.nan` and `.inf`, so such a
/// value is refused as non-finite rather than as not a number.
fn lower_special_reals(text: &mut [u8]) {
    let edge = |b: Option<&u8>| b.is_none_or(|b| b" \t\r\n[],:-+".contains(b));
    for word in [&b".Nan"[..], b".Inf"] {
        let mut i = 0;
        while i + word.len() <= text.len() {
            let hit = text[i..].starts_with(word)
                && edge(i.checked_sub(1).and_then(|j| text.get(j)))
                && edge(text.get(i + word.len()));
            if hit {
                for b in &mut text[i + 1..i + word.len()] {
                    b.make_ascii_lowercase();
                }
                i += word.len();
            } else {
                i += 1;
            }
        }
    }
}

/// One file of the set, read: its path and top-level mapping.
struct Storage {
    path: PathBuf,
    doc: Yaml,
}

/// Whether `a` and `b` are matrices with the same numbers in the same order
/// (as `!!opencv-matrix` and as a list, or 1 × N and N × 1).
fn same_numbers(a: &Yaml, b: &Yaml) -> bool {
    matches!((matrix(a), matrix(b)), (Ok((_, _, x)), Ok((_, _, y))) if x == y)
}

/// The first of `names` present in any of `files`, with the file it is in;
/// refused when two of the names, or one name in two files, give different
/// values.
fn find<'a>(
    files: &'a [Storage],
    names: &[&str],
    item: &str,
) -> Result<Option<(&'a Storage, &'a str, &'a Yaml)>> {
    let mut found: Option<(&Storage, &str, &Yaml)> = None;
    for f in files {
        for name in names {
            let Some((key, v)) = f
                .doc
                .as_hash()
                .and_then(|h| h.get_key_value(&Yaml::String((*name).into())))
            else {
                continue;
            };
            let Some(key) = key.as_str() else { continue };
            match found {
                None => found = Some((f, key, v)),
                Some((_, _, w)) if w == v || same_numbers(w, v) => {}
                Some((g, k, _)) => {
                    return Err(Error::file(
                        &f.path,
                        format!(
                            "`{key}` and `{k}` (in {}) both give {item}, differently",
                            g.path.display()
                        ),
                    ))
                }
            }
        }
    }
    Ok(found)
}

/// The image size from the files (`image_size`, `imageSize`, or
/// `image_width` with `image_height`), `None` when absent.
fn image_size(files: &[Storage]) -> Result<Option<(&Storage, [u32; 2])>> {
    let dim =
        |v: f64| (v.fract() == 0.0 && v >= 1.0 && v <= f64::from(u32::MAX)).then_some(v as u32);
    if let Some((f, key, v)) = find(files, &["image_size", "imageSize"], "the image size")? {
        let d = vector(v).map_err(|e| Error::file(&f.path, format!("`{key}` {e}")))?;
        return match d[..] {
            [w, h] => match (dim(w), dim(h)) {
                (Some(w), Some(h)) => Ok(Some((f, [w, h]))),
                _ => Err(Error::file(
                    &f.path,
                    format!("`{key}` must be two positive whole numbers"),
                )),
            },
            _ => Err(Error::file(
                &f.path,
                format!("`{key}` has {} numbers, not 2", d.len()),
            )),
        };
    }
    let w = find(files, &["image_width"], "the image width")?;
    let h = find(files, &["image_height"], "the image height")?;
    match (w, h) {
        (None, None) => Ok(None),
        (Some((f, _, w)), Some((_, _, h))) => match (w.as_i64(), h.as_i64()) {
            (Some(w), Some(h)) => match (u32::try_from(w), u32::try_from(h)) {
                (Ok(w), Ok(h)) if w > 0 && h > 0 => Ok(Some((f, [w, h]))),
                _ => Err(Error::file(
                    &f.path,
                    "`image_width`/`image_height` must be positive",
                )),
            },
            _ => Err(Error::file(
                &f.path,
                "`image_width`/`image_height` must be whole numbers",
            )),
        },
        (Some((f, ..)), None) | (None, Some((f, ..))) => Err(Error::file(
            &f.path,
            "gives only one of `image_width` and `image_height`",
        )),
    }
}

/// The OpenCV form of the files `sources` (path and contents; module docs);
/// `size` and `t_scale` (metres per unit of `T`) from `calib.json`, `calib`
/// its path (for the messages about `image_size`).
fn from_files(
    sources: &[(PathBuf, Vec<u8>)],
    size: Option<[u32; 2]>,
    t_scale: f64,
    calib: &Path,
) -> Result<OpenCvCalib> {
    let mut files = Vec::with_capacity(sources.len());
    for (p, bytes) in sources {
        let doc = storage_doc(bytes, p)?;
        files.push(Storage {
            path: p.clone(),
            doc,
        });
    }
    let mut values = Vec::with_capacity(KEYS.len());
    for (item, names) in KEYS {
        let Some(found) = find(&files, names, item)? else {
            let listed: Vec<String> = sources
                .iter()
                .map(|(p, _)| p.display().to_string())
                .collect();
            return Err(Error::file(
                calib,
                format!(
                    "no {} in {} (looked for {})",
                    item,
                    listed.join(", "),
                    names
                        .iter()
                        .map(|n| format!("`{n}`"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        };
        values.push(found);
    }
    let bad = |(f, key, _): (&Storage, &str, &Yaml), e: String| {
        Error::file(&f.path, format!("`{key}` {e}"))
    };
    let k = |i: usize| m3(values[i].2).map_err(|e| bad(values[i], e));
    let d = |i: usize| vector(values[i].2).map_err(|e| bad(values[i], e));
    let r = match matrix(values[4].2).map_err(|e| bad(values[4], e))? {
        (_, _, v) if v.len() == 3 => {
            let m = Rotation3::from_scaled_axis(Vector3::new(v[0], v[1], v[2])).into_inner();
            [
                [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
                [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
                [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
            ]
        }
        _ => m3(values[4].2).map_err(|e| bad(values[4], format!("{e} (nor a rotation vector)")))?,
    };
    let t = d(5)?;
    let t: [f64; 3] = match t[..] {
        [x, y, z] => [x * t_scale, y * t_scale, z * t_scale],
        _ => return Err(bad(values[5], format!("has {} numbers, not 3", t.len()))),
    };
    let image_size = match (image_size(&files)?, size) {
        (Some((_, s)), None) | (None, Some(s)) => s,
        (Some((f, s)), Some(c)) if s != c => {
            return Err(Error::file(
                calib,
                format!(
                    "`image_size` [{}, {}] differs from the [{}, {}] of {}",
                    c[0],
                    c[1],
                    s[0],
                    s[1],
                    f.path.display()
                ),
            ))
        }
        (Some((_, s)), Some(_)) => s,
        (None, None) => {
            return Err(Error::file(
                calib,
                "no image size: the files hold no `image_size`, `imageSize` or \
                 `image_width`/`image_height`; give \"image_size\": [W, H] in calib.json",
            ))
        }
    };
    let c = OpenCvCalib {
        image_size,
        left: OpenCvCamera {
            k: k(0)?,
            dist: d(1)?,
        },
        right: OpenCvCamera {
            k: k(2)?,
            dist: d(3)?,
        },
        r,
        t,
    };
    c.validate().map_err(|(field, why)| {
        let at = KEYS.iter().position(|(item, _)| *item == field).map(|i| values[i]);
        let hint = if field == "T" && t_scale == 1.0 && why.contains("baseline") {
            " (T is read in metres; a calibration in millimetres needs \"T_unit\": \"mm\" in calib.json)"
        } else {
            ""
        };
        match at {
            Some((f, key, _)) => Error::file(&f.path, format!("`{key}` ({field}): {why}{hint}")),
            None => Error::file(calib, format!("`{field}`: {why}")),
        }
    })?;
    Ok(c)
}

/// Parse the FileStorage form of `calib.json` (module docs) and read the
/// files it names, relative to `path`'s directory.
///
/// # Errors
/// Malformed JSON or an unknown key (naming `path`); no file, more than
/// [`MAX_STORAGE_FILES`], or an unknown `T_unit`; a file that cannot be read
/// or is not a FileStorage YAML mapping (naming it); an item missing from
/// every file, given twice differently, or of the wrong shape; then what
/// [`OpenCvCalib::validate`] refuses, naming the file and key.
pub fn parse_storage_calib(bytes: &[u8], path: &Path) -> Result<OpenCvCalib> {
    let c: StorageCalibFile = crate::io::json::parse_json(bytes, path)?;
    let files = match c.opencv_storage {
        StorageFiles::One(p) => vec![p],
        StorageFiles::Many(v) => v,
    };
    if files.is_empty() || files.len() > MAX_STORAGE_FILES {
        return Err(Error::file(
            path,
            format!(
                "`opencv_storage` names 1 to {MAX_STORAGE_FILES} files, not {}",
                files.len()
            ),
        ));
    }
    let t_scale = match c.t_unit.as_deref() {
        None | Some("m") => 1.0,
        Some("cm") => 0.01,
        Some("mm") => 0.001,
        Some(u) => {
            return Err(Error::file(
                path,
                format!("`T_unit` `{u}` is not one of m, cm, mm"),
            ))
        }
    };
    let mut sources = Vec::with_capacity(files.len());
    for p in &files {
        let p = resolve(path, p);
        let bytes = crate::io::read_file(&p)?;
        sources.push((p, bytes));
    }
    from_files(&sources, c.image_size, t_scale, path)
}

/// Whether `bytes` is a FileStorage file given as `--calib` itself: YAML
/// beginning with `%YAML`, or XML.
pub fn is_storage_file(bytes: &[u8]) -> bool {
    bytes
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .is_some_and(|i| bytes[i..].starts_with(b"%YAML") || xml::is_xml(&bytes[i..]))
}

/// Parse one FileStorage file (`bytes`, read from `path`) given as
/// `--calib` itself: `T` in metres, the image size from the file.
///
/// # Errors
/// As [`parse_storage_calib`].
pub fn parse_storage_file(bytes: &[u8], path: &Path) -> Result<OpenCvCalib> {
    from_files(&[(path.to_path_buf(), bytes.to_vec())], None, 1.0, path)
}

#[cfg(test)]
mod tests;
pub mod xml;
