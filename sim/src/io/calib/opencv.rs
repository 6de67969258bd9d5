//! The OpenCV stereo form of `calib.json`: a physical (unrectified, distorted)
//! pair as `cv2.stereoCalibrate` describes it.
//!
//! ```json
//! {"image_size": [W, H],
//!  "left":  {"K": [[fx,0,cx],[0,fy,cy],[0,0,1]], "dist": [k1,k2,p1,p2,k3]},
//!  "right": {"K": [[...]], "dist": [...]},
//!  "R": [[...],[...],[...]], "T": [tx,ty,tz]}
//! ```
//!
//! `X_right = R · X_left + T`, metres. Distortion follows OpenCV's model with
//! 4 (`k1,k2,p1,p2`), 5 (`+k3`) or 8 (`+k4,k5,k6`, the rational model)
//! coefficients; the thin-prism and tilt terms (12 and 14 coefficients) are
//! refused. [`super::read_calib_any`] tells this form apart by its `image_size`
//! key. The checks ([`super::model::OpenCvCalib::validate`]) refuse what the
//! rectifier ([`crate::rectify`]) and the core cannot use, naming the field.

use super::model::{OpenCvCalib, OpenCvCamera};
use crate::error::{Error, Result};
use crate::io::json;
use std::path::Path;

/// The 1-based line of the field named `dotted` (`"left.K"`, `"T"`): the first
/// occurrence of each key after the previous one.
fn dotted_key_line(text: &str, dotted: &str) -> Option<usize> {
    let mut pos = 0usize;
    for key in dotted.split('.') {
        let needle = format!("\"{key}\"");
        pos += text.get(pos..)?.find(&needle)?;
    }
    Some(text.get(..pos)?.matches('\n').count() + 1)
}

/// Parse and validate the OpenCV form.
///
/// # Errors
/// Malformed JSON, a missing or unknown field, or a value out of range; the
/// message names the field (`left.K`, `right.dist`, `R`, `T`, `image_size`).
pub fn parse_opencv_calib(bytes: &[u8], path: &Path) -> Result<OpenCvCalib> {
    let c: OpenCvCalib = json::parse_json(bytes, path)?;
    c.validate().map_err(|(field, why)| {
        let text = String::from_utf8_lossy(bytes);
        let msg = format!("`{field}`: {why}");
        match dotted_key_line(&text, &field) {
            Some(l) => Error::at(path, l, msg),
            None => Error::file(path, msg),
        }
    })?;
    Ok(c)
}

/// Serialise the OpenCV form, one matrix row per line; every number in the
/// shortest form that reads back to the same `f64`.
pub fn opencv_calib_text(c: &OpenCvCalib) -> String {
    let num = |v: f64| serde_json::Value::from(v).to_string();
    let list = |v: &[f64]| {
        let items: Vec<String> = v.iter().map(|&x| num(x)).collect();
        format!("[{}]", items.join(", "))
    };
    let m3 = |m: &[[f64; 3]; 3], indent: &str| {
        let rows: Vec<String> = m.iter().map(|r| list(r)).collect();
        format!("[{}]", rows.join(&format!(",\n{indent}")))
    };
    let cam = |k: &OpenCvCamera| {
        format!(
            "{{\"K\": {},\n           \"dist\": {}}}",
            m3(&k.k, "                  "),
            list(&k.dist)
        )
    };
    format!(
        "{{\"image_size\": [{}, {}],\n \"left\":  {},\n \"right\": {},\n \"R\": {},\n \"T\": {}}}\n",
        c.image_size[0],
        c.image_size[1],
        cam(&c.left),
        cam(&c.right),
        m3(&c.r, "       "),
        list(&c.t)
    )
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// The writer's text reads back to the same calibration, bit for bit.
    ///
    /// Verifies: VTSM-CLI-032
    #[test]
    fn text_round_trips() {
        let c = OpenCvCalib {
            image_size: [640, 480],
            left: OpenCvCamera {
                k: [[500.1, 0.0, 321.7], [0.0, 499.9, 238.2], [0.0, 0.0, 1.0]],
                dist: vec![-0.1, 0.02, 1.0 / 3.0e4, -0.0004, 0.0],
            },
            right: OpenCvCamera {
                k: [[498.0, 0.0, 318.0], [0.0, 497.5, 241.0], [0.0, 0.0, 1.0]],
                dist: vec![-0.09, 0.01, 0.0, 0.0],
            },
            r: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            t: [-0.4, 0.1f64.sqrt() * 1e-2, 0.0],
        };
        let text = opencv_calib_text(&c);
        let back = parse_opencv_calib(text.as_bytes(), Path::new("c.json")).unwrap();
        assert_eq!(back, c, "{text}");
    }
}
