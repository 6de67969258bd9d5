//! The XML form of `cv::FileStorage`, read into the same YAML values the
//! YAML form gives, so one reader serves both.
//!
//! ```xml
//! <?xml version="1.0"?>
//! <opencv_storage>
//! <M1 type_id="opencv-matrix">
//!   <rows>3</rows> <cols>3</cols> <dt>d</dt>
//!   <data>500.1 0. 321.7 0. 499.9 238.2 0. 0. 1.</data></M1>
//! <image_width>640</image_width>
//! </opencv_storage>
//! ```
//!
//! The subset OpenCV writes: one `opencv_storage` root; elements whose
//! content is either child elements (a mapping, or a sequence when every
//! child is `_`) or text; text of one token is a scalar, of several a list;
//! a token is a number (OpenCV's `.Nan` and `.Inf` included, as YAML reals),
//! else a string (quotes removed). Attributes are skipped, comments, the
//! declaration and a doctype too; entities other than the five predefined
//! ones, CDATA, mixed content and nesting deeper than [`MAX_DEPTH`] are
//! refused, each with its line.

use crate::error::{Error, Result};
use std::path::Path;
use yaml_rust2::yaml::Hash;
use yaml_rust2::Yaml;

/// Deepest element nesting accepted (the root is level 1; a matrix is 3).
pub const MAX_DEPTH: usize = 8;

struct Parser<'a> {
    text: &'a str,
    pos: usize,
    path: &'a Path,
}

impl<'a> Parser<'a> {
    fn err(&self, msg: impl Into<String>) -> Error {
        let line = self.text[..self.pos.min(self.text.len())]
            .matches('\n')
            .count()
            + 1;
        Error::at(self.path, line, format!("FileStorage XML: {}", msg.into()))
    }

    fn rest(&self) -> &'a str {
        &self.text[self.pos..]
    }

    /// Skip white space, comments, processing instructions and a doctype.
    fn skip_misc(&mut self) -> Result<()> {
        loop {
            let trimmed = self.rest().trim_start();
            self.pos = self.text.len() - trimmed.len();
            let end = if trimmed.starts_with("<!--") {
                trimmed.find("-->").map(|i| i + 3)
            } else if trimmed.starts_with("<?") {
                trimmed.find("?>").map(|i| i + 2)
            } else if trimmed.starts_with("<!DOCTYPE") {
                trimmed.find('>').map(|i| i + 1)
            } else {
                return Ok(());
            };
            match end {
                Some(n) => self.pos += n,
                None => return Err(self.err("a comment or declaration is not closed")),
            }
        }
    }

    /// `<name ...>` or `<name .../>`: the name and whether it closes itself.
    fn open_tag(&mut self) -> Result<(String, bool)> {
        let rest = self.rest();
        if !rest.starts_with('<') || rest.starts_with("</") {
            return Err(self.err("an element was expected"));
        }
        let end = rest
            .find('>')
            .ok_or_else(|| self.err("a tag is not closed"))?;
        let tag = &rest[1..end];
        let name: String = tag
            .chars()
            .take_while(|c| !c.is_whitespace() && *c != '/')
            .collect();
        if name.is_empty() || name.starts_with("![CDATA[") {
            return Err(self.err("an element name was expected (CDATA is not read)"));
        }
        let self_closing = tag.ends_with('/');
        self.pos += end + 1;
        Ok((name, self_closing))
    }

    /// One element at nesting level `depth`: its name and value.
    fn element(&mut self, depth: usize) -> Result<(String, Yaml)> {
        if depth > MAX_DEPTH {
            return Err(self.err(format!("nested deeper than {MAX_DEPTH} levels")));
        }
        let (name, self_closing) = self.open_tag()?;
        if self_closing {
            return Ok((name, Yaml::Null));
        }
        let mut children: Vec<(String, Yaml)> = Vec::new();
        let mut text = String::new();
        loop {
            self.skip_comments_only()?;
            let rest = self.rest();
            if rest.is_empty() {
                return Err(self.err(format!("<{name}> is not closed")));
            }
            if let Some(close) = rest.strip_prefix("</") {
                let end = close
                    .find('>')
                    .ok_or_else(|| self.err("a tag is not closed"))?;
                if close[..end].trim() != name {
                    return Err(self.err(format!("</{}> closes <{name}>", close[..end].trim())));
                }
                self.pos += 2 + end + 1;
                break;
            }
            if rest.starts_with('<') {
                children.push(self.element(depth + 1)?);
            } else {
                let n = rest.find('<').unwrap_or(rest.len());
                text.push_str(&rest[..n]);
                self.pos += n;
            }
        }
        let text = text.trim();
        let value = match (children.is_empty(), text.is_empty()) {
            (true, _) => self.scalars(text)?,
            (false, true) if children.iter().all(|(n, _)| n == "_") => {
                Yaml::Array(children.into_iter().map(|(_, v)| v).collect())
            }
            (false, true) => {
                let mut h = Hash::new();
                for (k, v) in children {
                    if h.insert(Yaml::String(k.clone()), v).is_some() {
                        return Err(self.err(format!("<{name}> holds <{k}> twice")));
                    }
                }
                Yaml::Hash(h)
            }
            (false, false) => return Err(self.err(format!("<{name}> mixes text and elements"))),
        };
        Ok((name, value))
    }

    /// Skip comments between content.
    fn skip_comments_only(&mut self) -> Result<()> {
        loop {
            let trimmed = self.rest().trim_start();
            if !trimmed.starts_with("<!--") {
                return Ok(());
            }
            let at = self.text.len() - trimmed.len();
            match trimmed.find("-->") {
                Some(n) => self.pos = at + n + 3,
                None => return Err(self.err("a comment is not closed")),
            }
        }
    }

    /// Text content: nothing is null, one token a scalar, several a list.
    fn scalars(&self, text: &str) -> Result<Yaml> {
        let tokens: Vec<Yaml> = text
            .split_whitespace()
            .map(|t| self.scalar(t))
            .collect::<Result<_>>()?;
        Ok(match tokens.len() {
            0 => Yaml::Null,
            1 => tokens.into_iter().next().unwrap_or(Yaml::Null),
            _ => Yaml::Array(tokens),
        })
    }

    fn scalar(&self, t: &str) -> Result<Yaml> {
        if let Ok(i) = t.parse::<i64>() {
            return Ok(Yaml::Integer(i));
        }
        let special = matches!(
            t.to_ascii_lowercase().as_str(),
            ".nan" | ".inf" | "-.inf" | "+.inf"
        );
        if special || t.parse::<f64>().is_ok() {
            let real = match t.to_ascii_lowercase().as_str() {
                ".nan" => ".nan".to_string(),
                ".inf" | "+.inf" => ".inf".to_string(),
                "-.inf" => "-.inf".to_string(),
                _ => t.to_string(),
            };
            return Ok(Yaml::Real(real));
        }
        let t = t.trim_matches('"');
        if t.contains('&') {
            let s = t
                .replace("&lt;", "<")
                .replace("&gt;", ">")
                .replace("&quot;", "\"")
                .replace("&apos;", "'")
                .replace("&amp;", "&");
            if s.matches('&').count() != t.matches("&amp;").count() {
                return Err(self.err(format!("entity in `{}` is not read", crate::io::clip(t))));
            }
            return Ok(Yaml::String(s));
        }
        Ok(Yaml::String(t.to_string()))
    }
}

/// Whether `bytes` looks like FileStorage XML (a declaration or the root).
pub fn is_xml(head: &[u8]) -> bool {
    head.starts_with(b"<?xml") || head.starts_with(b"<opencv_storage")
}

/// The top-level mapping of a FileStorage XML file (`text`, read from
/// `path`).
///
/// # Errors
/// Not the subset of the module docs, or a root other than
/// `opencv_storage`, naming the line.
pub fn parse(text: &str, path: &Path) -> Result<Yaml> {
    let mut p = Parser { text, pos: 0, path };
    p.skip_misc()?;
    let root = p.pos;
    let (name, value) = p.element(1)?;
    if name != "opencv_storage" {
        p.pos = root;
        return Err(p.err(format!("the root is <{name}>, not <opencv_storage>")));
    }
    p.skip_misc()?;
    if !p.rest().is_empty() {
        return Err(p.err("content after </opencv_storage>"));
    }
    match value {
        Yaml::Hash(_) => Ok(value),
        Yaml::Null => Ok(Yaml::Hash(Hash::new())),
        _ => Err(p.err("<opencv_storage> must hold elements")),
    }
}
