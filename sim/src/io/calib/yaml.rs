//! YAML helpers the ROS, Kalibr and FileStorage readers share: a bounded
//! UTF-8 text, one YAML mapping, key look-up, lists of finite numbers, and
//! paths relative to `calib.json`.

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};
use yaml_rust2::{Yaml, YamlLoader};

/// Look up `key` in a YAML mapping.
pub(super) fn get<'a>(doc: &'a Yaml, key: &str) -> Option<&'a Yaml> {
    doc.as_hash()?.get(&Yaml::String(key.into()))
}

/// A YAML number (integer or real) as `f64`.
fn number(y: &Yaml) -> Option<f64> {
    match y {
        Yaml::Real(_) => y.as_f64(),
        Yaml::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

/// `y` (the value named `name`, `None` when absent) as a list of exactly `n`
/// finite numbers.
pub(super) fn number_list(
    y: Option<&Yaml>,
    name: &str,
    n: usize,
) -> std::result::Result<Vec<f64>, String> {
    let list = y
        .and_then(Yaml::as_vec)
        .ok_or_else(|| format!("`{name}` is missing or not a list"))?;
    let v: Vec<f64> = list
        .iter()
        .map(number)
        .collect::<Option<_>>()
        .ok_or_else(|| format!("`{name}` has an element that is not a number"))?;
    if v.len() != n {
        return Err(format!("`{name}` has {} numbers, not {n}", v.len()));
    }
    if !v.iter().all(|x| x.is_finite()) {
        return Err(format!("`{name}` has a non-finite element"));
    }
    Ok(v)
}

/// `bytes` (the file `path`) as one YAML mapping: at most `max` bytes, UTF-8,
/// one document whose top level is a mapping (`what` names it in the message).
///
/// # Errors
/// Each of those conditions, naming `path` (and the line for a YAML syntax error).
pub(super) fn yaml_mapping(bytes: &[u8], path: &Path, max: usize, what: &str) -> Result<Yaml> {
    let text = bounded_text(bytes, path, max, what)?;
    let mut docs = YamlLoader::load_from_str(text).map_err(|e| {
        Error::at(
            path,
            e.marker().line().max(1),
            format!("not YAML: {}", e.info()),
        )
    })?;
    match docs.as_slice() {
        [d] if d.as_hash().is_some() => Ok(docs.remove(0)),
        _ => Err(Error::file(
            path,
            format!("must hold one YAML mapping ({what})"),
        )),
    }
}

/// `bytes` (the file `path`) as text: at most `max` bytes and UTF-8 (`what`
/// names the file in the message).
///
/// # Errors
/// Either condition, naming `path`.
pub(super) fn bounded_text<'a>(
    bytes: &'a [u8],
    path: &Path,
    max: usize,
    what: &str,
) -> Result<&'a str> {
    if bytes.len() > max {
        return Err(Error::file(
            path,
            format!("{} bytes; {what} file is at most {max}", bytes.len()),
        ));
    }
    std::str::from_utf8(bytes).map_err(|e| Error::file(path, format!("not UTF-8: {e}")))
}

/// `p` as named in `calib.json` at `path`: relative to its directory unless absolute.
pub(super) fn resolve(path: &Path, p: &Path) -> PathBuf {
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        path.parent().unwrap_or(Path::new("")).join(p)
    }
}
