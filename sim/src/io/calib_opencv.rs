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
//! refused. [`read_calib_any`] tells the two forms of `calib.json` apart by the
//! `image_size` key. The checks ([`OpenCvCalib::validate`]) refuse what the
//! rectifier ([`crate::rectify`]) and the core cannot use, naming the field.

use super::json::{self, short_number, Calib};
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;
use vtsm_core::geom;

/// Largest accepted deviation of `RᵀR` from the identity (any element) and of
/// `det R` from 1.
pub const ROTATION_TOL: f64 = 1.0e-5;
/// Largest accepted angle, degrees, between the right camera's centre seen from
/// the left camera and the left camera's +x axis (the core needs a horizontal
/// pair with the right camera on the right).
pub const MAX_BASELINE_TILT_DEG: f64 = 20.0;
/// Largest accepted baseline, metres.
pub const MAX_BASELINE_M: f64 = 100.0;
/// Largest accepted magnitude of a distortion coefficient.
pub const MAX_DIST_COEFF: f64 = 1.0e3;

/// One camera of the OpenCV form: intrinsic matrix and distortion coefficients.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OpenCvCamera {
    /// Intrinsic matrix `[[fx,0,cx],[0,fy,cy],[0,0,1]]`, pixels (pixel-centre
    /// convention, as OpenCV).
    #[serde(rename = "K")]
    pub k: [[f64; 3]; 3],
    /// Distortion `k1,k2,p1,p2[,k3[,k4,k5,k6]]`.
    pub dist: Vec<f64>,
}

impl OpenCvCamera {
    /// `(fx, fy, cx, cy)`.
    pub fn intrinsics(&self) -> (f64, f64, f64, f64) {
        (self.k[0][0], self.k[1][1], self.k[0][2], self.k[1][2])
    }

    /// The 8 coefficients `k1,k2,p1,p2,k3,k4,k5,k6` (missing ones are 0).
    pub fn dist8(&self) -> [f64; 8] {
        let mut d = [0.0; 8];
        for (o, v) in d.iter_mut().zip(&self.dist) {
            *o = *v;
        }
        d
    }
}

/// `calib.json` in the OpenCV stereo form.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OpenCvCalib {
    /// `[width, height]`, pixels, of both cameras.
    pub image_size: [u32; 2],
    /// Left camera.
    pub left: OpenCvCamera,
    /// Right camera.
    pub right: OpenCvCamera,
    /// Rotation of `X_right = R · X_left + T`.
    #[serde(rename = "R")]
    pub r: [[f64; 3]; 3],
    /// Translation of `X_right = R · X_left + T`, metres.
    #[serde(rename = "T")]
    pub t: [f64; 3],
}

/// Either form of `calib.json`.
#[derive(Clone, Debug, PartialEq)]
pub enum CalibFile {
    /// An ideal rectified pair (`width`, `height`, `fx`, ...).
    Rectified(Calib),
    /// A physical pair as OpenCV calibrates it.
    OpenCv(Box<OpenCvCalib>),
}

fn mat_ok(m: &[[f64; 3]; 3]) -> bool {
    m.iter().flatten().all(|v| v.is_finite())
}

impl OpenCvCamera {
    fn validate(&self, side: &'static str) -> std::result::Result<(), (String, String)> {
        let field = |f: &str| format!("{side}.{f}");
        if !mat_ok(&self.k) {
            return Err((field("K"), "has a non-finite element".into()));
        }
        let k = &self.k;
        if k[1][0] != 0.0 || k[2][0] != 0.0 || k[2][1] != 0.0 || k[2][2] != 1.0 {
            return Err((
                field("K"),
                "must be [[fx,0,cx],[0,fy,cy],[0,0,1]] (last row 0,0,1; K[1][0] = 0)".into(),
            ));
        }
        if k[0][1] != 0.0 {
            return Err((
                field("K"),
                format!("skew K[0][1] = {} is not supported", short_number(k[0][1])),
            ));
        }
        let (fx, fy, cx, cy) = self.intrinsics();
        for (name, f) in [("fx", fx), ("fy", fy)] {
            if !geom::focal_px_ok(f as f32) {
                return Err((
                    field("K"),
                    format!(
                        "{name} = {} px is outside the accepted focal length range (0, {}] px",
                        short_number(f),
                        short_number(f64::from(geom::MAX_FOCAL_PX))
                    ),
                ));
            }
        }
        for (name, c) in [("cx", cx), ("cy", cy)] {
            if !geom::principal_px_ok(c as f32) {
                return Err((
                    field("K"),
                    format!(
                        "{name} = {} px is outside the accepted principal point range ±{} px",
                        short_number(c),
                        short_number(f64::from(geom::MAX_PRINCIPAL_PX))
                    ),
                ));
            }
        }
        if ![4, 5, 8].contains(&self.dist.len()) {
            return Err((
                field("dist"),
                format!(
                    "has {} coefficients; give 4 (k1,k2,p1,p2), 5 (+k3) or 8 (+k4,k5,k6)",
                    self.dist.len()
                ),
            ));
        }
        if let Some(v) = self
            .dist
            .iter()
            .find(|v| !(v.is_finite() && v.abs() <= MAX_DIST_COEFF))
        {
            return Err((
                field("dist"),
                format!(
                    "coefficient {} is not finite or exceeds {} in magnitude",
                    short_number(*v),
                    short_number(MAX_DIST_COEFF)
                ),
            ));
        }
        Ok(())
    }
}

impl OpenCvCalib {
    /// Width, height.
    pub fn size(&self) -> (u32, u32) {
        (self.image_size[0], self.image_size[1])
    }

    /// Check every field; returns the dotted name of the bad field and why.
    pub fn validate(&self) -> std::result::Result<(), (String, String)> {
        for (i, v) in self.image_size.iter().enumerate() {
            if !geom::image_dim_ok(*v) {
                return Err((
                    "image_size".into(),
                    format!(
                        "{} {v} is outside 1..={}",
                        ["width", "height"][i],
                        vtsm_core::config::MAX_IMAGE_DIM
                    ),
                ));
            }
        }
        self.left.validate("left")?;
        self.right.validate("right")?;
        let r = &self.r;
        if !mat_ok(r) {
            return Err(("R".into(), "has a non-finite element".into()));
        }
        for i in 0..3 {
            for j in 0..3 {
                let dot: f64 = (0..3).map(|k| r[k][i] * r[k][j]).sum();
                let want = if i == j { 1.0 } else { 0.0 };
                if (dot - want).abs() > ROTATION_TOL {
                    return Err((
                        "R".into(),
                        format!(
                            "is not orthonormal (RᵀR deviates from I by more than {ROTATION_TOL})"
                        ),
                    ));
                }
            }
        }
        let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
            - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
            + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
        if (det - 1.0).abs() > ROTATION_TOL {
            return Err((
                "R".into(),
                format!("has determinant {det:.6}, not 1 (a reflection?)"),
            ));
        }
        let t = &self.t;
        if !t.iter().all(|v| v.is_finite()) {
            return Err(("T".into(), "has a non-finite element".into()));
        }
        let n = t.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !(n > 1.0e-6 && n <= MAX_BASELINE_M) {
            return Err((
                "T".into(),
                format!(
                    "baseline |T| = {} m must be in (1e-6, {MAX_BASELINE_M}] m",
                    short_number(n)
                ),
            ));
        }
        // Centre of the right camera in the left frame: c = -Rᵀ T.
        let cx: f64 = -(0..3).map(|k| r[k][0] * t[k]).sum::<f64>();
        let cos = cx / n;
        if cos < MAX_BASELINE_TILT_DEG.to_radians().cos() {
            return Err((
                "T".into(),
                format!(
                    "the right camera is {:.1}° away from the left camera's +x axis \
                     (at most {MAX_BASELINE_TILT_DEG}°: a horizontal pair, right camera on the right)",
                    cos.clamp(-1.0, 1.0).acos().to_degrees()
                ),
            ));
        }
        Ok(())
    }
}

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

/// Parse any form of `calib.json`: a FileStorage file itself
/// ([`super::calib_storage`]) when it begins with `%YAML` or is XML, the FileStorage
/// form when the top-level object has an `opencv_storage` key, the Kalibr form
/// ([`super::calib_kalibr`]) when it has a `kalibr_camchain` key, the ROS form
/// ([`super::calib_ros`]) when it has a `ros_camera_info` key, the OpenCV form when it has an
/// `image_size` key, the rectified form otherwise. The ROS form is returned as
/// the OpenCV form it describes, as are the Kalibr and FileStorage forms.
///
/// # Errors
/// As [`json::parse_calib`], [`parse_opencv_calib`],
/// [`super::calib_storage::parse_storage_calib`],
/// [`super::calib_ros::parse_ros_calib`] or
/// [`super::calib_kalibr::parse_kalibr_calib`].
pub fn parse_calib_any(bytes: &[u8], path: &Path) -> Result<CalibFile> {
    if super::calib_storage::is_storage_file(bytes) {
        return super::calib_storage::parse_storage_file(bytes, path)
            .map(|c| CalibFile::OpenCv(Box::new(c)));
    }
    // The top-level keys, parsed once; malformed JSON is reported by the
    // rectified form's parser below.
    let top = serde_json::from_slice::<serde_json::Value>(bytes).ok();
    let has = |key: &str| {
        top.as_ref()
            .and_then(|v| v.as_object())
            .is_some_and(|o| o.contains_key(key))
    };
    if has("opencv_storage") {
        super::calib_storage::parse_storage_calib(bytes, path)
            .map(|c| CalibFile::OpenCv(Box::new(c)))
    } else if has("kalibr_camchain") {
        super::calib_kalibr::parse_kalibr_calib(bytes, path).map(|c| CalibFile::OpenCv(Box::new(c)))
    } else if has("ros_camera_info") {
        super::calib_ros::parse_ros_calib(bytes, path).map(|c| CalibFile::OpenCv(Box::new(c)))
    } else if has("image_size") {
        parse_opencv_calib(bytes, path).map(|c| CalibFile::OpenCv(Box::new(c)))
    } else {
        json::parse_calib(bytes, path).map(CalibFile::Rectified)
    }
}

/// Read either form of `calib.json`.
///
/// # Errors
/// As [`parse_calib_any`], plus I/O errors.
pub fn read_calib_any(path: &Path) -> Result<CalibFile> {
    parse_calib_any(&super::read_file(path)?, path)
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
