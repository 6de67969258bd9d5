//! The ROS form of `calib.json`: a physical stereo pair given as the two
//! `camera_info` YAML files that ROS's `camera_calibration` (and
//! `camera_info_manager`) write, one per camera.
//!
//! ```json
//! {"ros_camera_info": {"left": "left.yaml", "right": "right.yaml"}}
//! ```
//!
//! Relative paths are resolved against the directory of `calib.json`. Each YAML
//! file holds `image_width`, `image_height`, `camera_matrix` (3×3), the
//! `distortion_model` (`plumb_bob`: 4 or 5 coefficients, or
//! `rational_polynomial`: 8), `distortion_coefficients`, `rectification_matrix`
//! (3×3, the rotation `R_i` from camera i to the rectified frame) and
//! `projection_matrix` (3×4, `P_i`), each matrix as `{rows, cols, data}` with
//! `data` row-major. The pair becomes the OpenCV form ([`OpenCvCalib`]): with
//! `X_rect_i = R_i · X_i` and the right rectified camera `B = −P₂[0][3] / P₂[0][0]`
//! metres along the left rectified camera's +x,
//! `X_right = R₂ᵀ·R₁ · X_left − R₂ᵀ·(B, 0, 0)ᵀ`, so `R = R₂ᵀR₁`, `T = −R₂ᵀ(B,0,0)ᵀ`.
//! Then the pair is rectified on the host like any OpenCV calibration
//! ([`crate::rectify`]); the stored `P₁`, `P₂` are not used beyond the baseline,
//! so the rectified cameras are the host rectifier's, as for the OpenCV form.
//! Only horizontal pairs are accepted (`P₂[1][3] = 0`), as the core needs.

use super::model::{OpenCvCalib, OpenCvCamera};
use super::yaml::{get, number_list, resolve, yaml_mapping};
use crate::error::{Error, Result};
use crate::io::json::short_number;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use yaml_rust2::Yaml;

/// Largest accepted size of one `camera_info` file, bytes.
pub const MAX_CAMERA_INFO_BYTES: usize = 1 << 20;
/// Largest accepted deviation of the two cameras' rectified projections
/// (`P₁`, `P₂`: focal lengths and principal point) from each other, pixels; a
/// pair rectified by one `stereoRectify` call shares them.
pub const PROJECTION_TOL_PX: f64 = 1.0e-6;

/// `calib.json` in the ROS form: the paths of the two `camera_info` files.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RosCalibFile {
    /// The two files.
    pub ros_camera_info: RosPairPaths,
}

/// Paths of the left and the right `camera_info` YAML files.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RosPairPaths {
    /// Left camera.
    pub left: PathBuf,
    /// Right camera.
    pub right: PathBuf,
}

/// One camera of a ROS `camera_info` file, as read.
#[derive(Clone, Debug, PartialEq)]
pub struct RosCameraInfo {
    /// `image_width`, `image_height`.
    pub size: [u32; 2],
    /// `camera_matrix`, row-major 3×3.
    pub k: [[f64; 3]; 3],
    /// `distortion_coefficients` (`k1,k2,p1,p2[,k3[,k4,k5,k6]]`).
    pub dist: Vec<f64>,
    /// `rectification_matrix`, row-major 3×3.
    pub r: [[f64; 3]; 3],
    /// `projection_matrix`, row-major 3×4.
    pub p: [[f64; 4]; 3],
}

/// The `data` of a `{rows, cols, data}` matrix, checked against the expected
/// shape (`rows` and `cols`, when given, must match).
fn matrix(
    doc: &Yaml,
    key: &str,
    rows: usize,
    cols: usize,
) -> std::result::Result<Vec<f64>, String> {
    let m = get(doc, key).ok_or_else(|| format!("`{key}` is missing"))?;
    for (field, want) in [("rows", rows), ("cols", cols)] {
        if let Some(v) = get(m, field) {
            if v.as_i64() != i64::try_from(want).ok() {
                return Err(format!("`{key}.{field}` must be {want}"));
            }
        }
    }
    number_list(get(m, "data"), &format!("{key}.data"), rows * cols)
}

fn m3(v: &[f64]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for (i, x) in v.iter().take(9).enumerate() {
        m[i / 3][i % 3] = *x;
    }
    m
}

/// Parse one `camera_info` YAML file.
///
/// # Errors
/// Not YAML, a missing field, a matrix of the wrong shape, a non-finite number,
/// an image size outside the core's range, or a distortion model other than
/// `plumb_bob` (4 or 5 coefficients) or `rational_polynomial` (8); the message
/// names the field.
pub fn parse_camera_info(bytes: &[u8], path: &Path) -> Result<RosCameraInfo> {
    let doc = yaml_mapping(bytes, path, MAX_CAMERA_INFO_BYTES, "a camera_info")?;
    let doc = &doc;
    let bad = |why: String| Error::file(path, why);
    let mut size = [0u32; 2];
    for (o, key) in size.iter_mut().zip(["image_width", "image_height"]) {
        let v = get(doc, key)
            .and_then(Yaml::as_i64)
            .ok_or_else(|| bad(format!("`{key}` is missing or not an integer")))?;
        *o = u32::try_from(v)
            .ok()
            .filter(|v| vtsm_core::geom::image_dim_ok(*v))
            .ok_or_else(|| {
                bad(format!(
                    "`{key}` {v} is outside 1..={}",
                    vtsm_core::config::MAX_IMAGE_DIM
                ))
            })?;
    }
    let model = get(doc, "distortion_model")
        .and_then(Yaml::as_str)
        .ok_or_else(|| bad("`distortion_model` is missing or not a string".into()))?;
    let dist = {
        let d = get(doc, "distortion_coefficients")
            .ok_or_else(|| bad("`distortion_coefficients` is missing".into()))?;
        let n = get(d, "data").and_then(Yaml::as_vec).map_or(0, Vec::len);
        let ok = match model {
            "plumb_bob" => n == 4 || n == 5,
            "rational_polynomial" => n == 8,
            _ => {
                return Err(bad(format!(
                "`distortion_model` {model:?} is not supported (plumb_bob or rational_polynomial)"
            )))
            }
        };
        if !ok {
            return Err(bad(format!(
                "`distortion_coefficients` has {n} numbers; {model} takes {}",
                if model == "plumb_bob" { "4 or 5" } else { "8" }
            )));
        }
        matrix(doc, "distortion_coefficients", 1, n).map_err(bad)?
    };
    let k = m3(&matrix(doc, "camera_matrix", 3, 3).map_err(bad)?);
    let r = m3(&matrix(doc, "rectification_matrix", 3, 3).map_err(bad)?);
    let pv = matrix(doc, "projection_matrix", 3, 4).map_err(bad)?;
    let mut p = [[0.0; 4]; 3];
    for (i, x) in pv.iter().enumerate() {
        p[i / 4][i % 4] = *x;
    }
    Ok(RosCameraInfo {
        size,
        k,
        dist,
        r,
        p,
    })
}

/// The OpenCV form of a ROS pair (module docs).
///
/// # Errors
/// Different image sizes, rectified projections that differ between the two
/// cameras, a vertical or zero baseline, or a right camera on the left; then
/// everything [`OpenCvCalib::validate`] checks (named as in the OpenCV form).
pub fn to_opencv(
    left: &RosCameraInfo,
    right: &RosCameraInfo,
) -> std::result::Result<OpenCvCalib, String> {
    if left.size != right.size {
        return Err(format!(
            "the two cameras' image sizes differ ({}×{} and {}×{})",
            left.size[0], left.size[1], right.size[0], right.size[1]
        ));
    }
    let (p1, p2) = (&left.p, &right.p);
    for (what, a, b) in [
        ("fx", p1[0][0], p2[0][0]),
        ("fy", p1[1][1], p2[1][1]),
        ("cy", p1[1][2], p2[1][2]),
    ] {
        if (a - b).abs() > PROJECTION_TOL_PX {
            return Err(format!(
                "projection_matrix: the rectified {what} differs between the cameras ({} and {}); \
                 both must come from one stereo rectification",
                short_number(a),
                short_number(b)
            ));
        }
    }
    if !p1[0][0].is_finite() || p1[0][0] <= 0.0 || p1[0][3] != 0.0 || p1[1][3] != 0.0 {
        return Err(
            "left projection_matrix: must be [fx 0 cx 0; 0 fy cy 0; 0 0 1 0] with fx > 0".into(),
        );
    }
    if p2[1][3] != 0.0 {
        return Err("right projection_matrix: P[1][3] ≠ 0 is a vertical pair; the core needs a horizontal one".into());
    }
    let b = -p2[0][3] / p2[0][0];
    if !b.is_finite() || b <= 0.0 {
        return Err(format!(
            "right projection_matrix: baseline −P[0][3]/P[0][0] = {} m; the right camera must be on the right (> 0)",
            short_number(b)
        ));
    }
    let (r1, r2) = (&left.r, &right.r);
    let mut r = [[0.0; 3]; 3];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| r2[k][i] * r1[k][j]).sum();
        }
    }
    let t = [-r2[0][0] * b, -r2[0][1] * b, -r2[0][2] * b];
    let c = OpenCvCalib {
        image_size: left.size,
        left: OpenCvCamera {
            k: left.k,
            dist: left.dist.clone(),
        },
        right: OpenCvCamera {
            k: right.k,
            dist: right.dist.clone(),
        },
        r,
        t,
    };
    c.validate().map_err(|(field, why)| match field.as_str() {
        "R" => format!("rectification_matrix (R = R₂ᵀR₁): {why}"),
        "T" => format!("projection_matrix / rectification_matrix (T = −R₂ᵀ·(B,0,0)): {why}"),
        f => format!("`{f}`: {why}"),
    })?;
    Ok(c)
}

/// Parse the ROS form of `calib.json` (module docs) and read the two files it
/// names, relative to `path`'s directory.
///
/// # Errors
/// Malformed JSON or an unknown key (naming `path`); a file that cannot be read
/// or parsed (naming that file); a pair that [`to_opencv`] refuses (naming
/// `path`).
pub fn parse_ros_calib(bytes: &[u8], path: &Path) -> Result<OpenCvCalib> {
    let f: RosCalibFile = crate::io::json::parse_json(bytes, path)?;
    let read = |p: &Path| {
        let full = resolve(path, p);
        parse_camera_info(&crate::io::read_file(&full)?, &full)
    };
    let left = read(&f.ros_camera_info.left)?;
    let right = read(&f.ros_camera_info.right)?;
    to_opencv(&left, &right).map_err(|why| Error::file(path, why))
}

/// Serialise one camera as a `camera_info` YAML file in the layout ROS's
/// `camera_calibration` writes (flow lists, every number in the shortest form
/// that reads back to the same `f64`).
pub fn camera_info_text(name: &str, c: &RosCameraInfo) -> String {
    let num = |v: f64| serde_json::Value::from(v).to_string();
    let list = |v: &[f64]| v.iter().map(|&x| num(x)).collect::<Vec<_>>().join(", ");
    let mat = |key: &str, rows: usize, cols: usize, v: &[f64]| {
        format!(
            "{key}:\n  rows: {rows}\n  cols: {cols}\n  data: [{}]\n",
            list(v)
        )
    };
    let flat3 = |m: &[[f64; 3]; 3]| m.iter().flatten().copied().collect::<Vec<_>>();
    let model = if c.dist.len() == 8 {
        "rational_polynomial"
    } else {
        "plumb_bob"
    };
    format!(
        "image_width: {}\nimage_height: {}\ncamera_name: {name}\n{}distortion_model: {model}\n{}{}{}",
        c.size[0],
        c.size[1],
        mat("camera_matrix", 3, 3, &flat3(&c.k)),
        mat("distortion_coefficients", 1, c.dist.len(), &c.dist),
        mat("rectification_matrix", 3, 3, &flat3(&c.r)),
        mat("projection_matrix", 3, 4, &c.p.iter().flatten().copied().collect::<Vec<_>>()),
    )
}

/// The two `camera_info` files of an OpenCV calibration, with the rectification
/// the host rectifier computes for it ([`crate::rectify::stereo_rectify`]).
///
/// # Errors
/// As [`crate::rectify::stereo_rectify`].
pub fn from_opencv(c: &OpenCvCalib) -> std::result::Result<(RosCameraInfo, RosCameraInfo), String> {
    let rect = crate::rectify::stereo_rectify(c)?;
    let m = |r: &nalgebra::Matrix3<f64>| {
        let mut o = [[0.0; 3]; 3];
        for (i, row) in o.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = r[(i, j)];
            }
        }
        o
    };
    let cam = |k: &OpenCvCamera, r, p| RosCameraInfo {
        size: c.image_size,
        k: k.k,
        dist: k.dist.clone(),
        r,
        p,
    };
    Ok((
        cam(&c.left, m(&rect.r1), rect.p1),
        cam(&c.right, m(&rect.r2), rect.p2),
    ))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::panic)]
    use super::*;

    /// A physical pair: different intrinsics, distortion, a small rotation.
    fn physical() -> OpenCvCalib {
        let a = 0.5f64.to_radians();
        let (s, c) = a.sin_cos();
        // A rotation about y by 0.5°, then T such that the right camera is 0.3 m
        // to the right: centre C = (0.3, 0.002, −0.001), T = −R·C.
        let r = [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]];
        let cc = [0.3, 0.002, -0.001];
        let t = [0, 1, 2].map(|i| -(0..3).map(|k| r[i][k] * cc[k]).sum::<f64>());
        OpenCvCalib {
            image_size: [640, 480],
            left: OpenCvCamera {
                k: [[520.0, 0.0, 321.5], [0.0, 519.0, 238.25], [0.0, 0.0, 1.0]],
                dist: vec![-0.1, 0.02, 0.001, -0.0005, 0.0],
            },
            right: OpenCvCamera {
                k: [[523.0, 0.0, 318.0], [0.0, 522.5, 241.0], [0.0, 0.0, 1.0]],
                dist: vec![-0.09, 0.018, -0.0008, 0.0004, 0.001],
            },
            r,
            t,
        }
    }

    /// `R` and `T` of `got` within `tol` of `want`, element-wise.
    fn assert_same_r_t(got: &OpenCvCalib, want: &OpenCvCalib, tol: f64) {
        for i in 0..3 {
            let dt = (got.t[i] - want.t[i]).abs();
            assert!(dt < tol, "T[{i}]: {} vs {}", got.t[i], want.t[i]);
            for j in 0..3 {
                let dr = (got.r[i][j] - want.r[i][j]).abs();
                assert!(dr < tol, "R[{i}][{j}]: {} vs {}", got.r[i][j], want.r[i][j]);
            }
        }
    }

    fn parse(text: &str) -> RosCameraInfo {
        parse_camera_info(text.as_bytes(), Path::new("cam.yaml")).unwrap()
    }

    /// OpenCV form → (R₁, R₂, P₁, P₂ of the rectifier) → two YAML files →
    /// read back → the same R and T, to rounding.
    ///
    /// Verifies: VTSM-CLI-043
    #[test]
    fn a_pair_written_as_camera_info_reads_back_to_its_r_and_t() {
        let c = physical();
        let (l, r) = from_opencv(&c).unwrap();
        let (l2, r2) = (
            parse(&camera_info_text("left", &l)),
            parse(&camera_info_text("right", &r)),
        );
        assert_eq!((&l2, &r2), (&l, &r), "YAML text reads back bit for bit");
        let back = to_opencv(&l2, &r2).unwrap();
        assert_eq!(back.left, c.left);
        assert_eq!(back.right, c.right);
        assert_same_r_t(&back, &c, 1e-12);
    }

    /// What ROS's `camera_calibration` writes for an ideal rectified pair
    /// (identity rectification, P₂[0][3] = −fx·B): R = I, T = (−B, 0, 0).
    ///
    /// Verifies: VTSM-CLI-043
    #[test]
    fn an_ideal_ros_pair_is_identity_r_and_minus_baseline_t() {
        let yaml = |name: &str, tx: f64| {
            format!(
                "image_width: 640\nimage_height: 480\ncamera_name: {name}\ncamera_matrix:\n  rows: 3\n  cols: 3\n  \
                 data: [500, 0, 320, 0, 500, 240, 0, 0, 1]\ndistortion_model: plumb_bob\n\
                 distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0, 0, 0, 0, 0]\n\
                 rectification_matrix:\n  rows: 3\n  cols: 3\n  data:\n    - 1\n    - 0\n    - 0\n    - 0\n    - 1\n    - 0\n    - 0\n    - 0\n    - 1\n\
                 projection_matrix:\n  rows: 3\n  cols: 4\n  data: [500, 0, 320, {tx}, 0, 500, 240, 0, 0, 0, 1, 0]\n"
            )
        };
        let c = to_opencv(&parse(&yaml("left", 0.0)), &parse(&yaml("right", -150.0))).unwrap();
        assert_eq!(c.r, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
        assert_eq!(c.t, [-0.3, 0.0, 0.0]);
        assert_eq!(c.left.k[0][0], 500.0);
    }

    /// Bad files and pairs are refused, naming what is wrong.
    ///
    /// Verifies: VTSM-CLI-043
    #[test]
    fn bad_camera_info_is_refused_naming_the_field() {
        let c = physical();
        let (l, r) = from_opencv(&c).unwrap();
        let good = camera_info_text("left", &l);
        let err = |text: &str| {
            parse_camera_info(text.as_bytes(), Path::new("cam.yaml"))
                .unwrap_err()
                .to_string()
        };
        for (text, want) in [
            (
                good.replace("image_width: 640", "image_width: 0"),
                "image_width",
            ),
            (good.replace("plumb_bob", "equidistant"), "distortion_model"),
            (
                good.replace("rows: 3\n  cols: 4", "rows: 4\n  cols: 3"),
                "projection_matrix.rows",
            ),
            (
                good.replace("camera_matrix", "camera_matrx"),
                "camera_matrix",
            ),
            ("image_width: [1,\n".to_string(), "not YAML"),
            ("- a\n- b\n".to_string(), "one YAML mapping"),
        ] {
            let e = err(&text);
            assert!(e.contains(want), "{want}: {e}");
        }
        let nan = good.replacen("data: [520.0", "data: [.nan", 1);
        assert!(err(&nan).contains("camera_matrix.data"), "{}", err(&nan));
        // Pairs.
        let mut vertical = r.clone();
        vertical.p[1][3] = 5.0;
        assert!(to_opencv(&l, &vertical).unwrap_err().contains("vertical"));
        let mut left_side = r.clone();
        left_side.p[0][3] = -left_side.p[0][3];
        assert!(to_opencv(&l, &left_side)
            .unwrap_err()
            .contains("on the right"));
        let mut other_f = r.clone();
        other_f.p[0][0] += 1.0;
        assert!(to_opencv(&l, &other_f)
            .unwrap_err()
            .contains("rectified fx"));
        let mut small = r.clone();
        small.size = [320, 240];
        assert!(to_opencv(&l, &small)
            .unwrap_err()
            .contains("image sizes differ"));
        // calib.json itself: an unknown key, and a file it names that is not there.
        let dir = std::env::temp_dir().join(format!("vtsm-calib-ros-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("left.yaml"), &good).unwrap();
        let calib = dir.join("calib.json");
        for (json, want) in [
            (
                &br#"{"ros_camera_info": {"left": "left.yaml", "right": "nope.yaml"}}"#[..],
                ["nope.yaml", "cannot read"],
            ),
            (
                &br#"{"ros_camera_info": {"left": "left.yaml", "rigth": "r.yaml"}}"#[..],
                ["calib.json", "rigth"],
            ),
        ] {
            let e = parse_ros_calib(json, &calib).unwrap_err().to_string();
            assert!(want.iter().all(|w| e.contains(w)), "{e}");
        }
        let _ = std::fs::remove_dir_all(&dir);
        let mut skew = r;
        skew.r[0][1] += 0.01;
        assert!(to_opencv(&l, &skew)
            .unwrap_err()
            .contains("rectification_matrix"));
    }

    /// The example pair of `fsw-docs/interfaces/examples/ros/`, written by OpenCV's
    /// `stereoRectify` from `examples/calib-opencv.json`
    /// (`ros/from_opencv.py`), reads through `calib.json` back to that
    /// calibration's R and T.
    ///
    /// Verifies: VTSM-CLI-043
    #[test]
    fn the_opencv_written_example_pair_reads_back_to_its_calibration() {
        let ex = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fsw-docs/interfaces/examples");
        let want = super::super::read_calib_any(&ex.join("calib-opencv.json")).unwrap();
        let got = super::super::read_calib_any(&ex.join("ros/calib.json")).unwrap();
        let (super::super::CalibFile::OpenCv(want), super::super::CalibFile::OpenCv(got)) =
            (want, got)
        else {
            panic!("both are physical pairs");
        };
        assert_eq!(
            (&got.left, &got.right, got.image_size),
            (&want.left, &want.right, want.image_size)
        );
        assert_same_r_t(&got, &want, 1e-9);
    }

    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// A camera_info file cut short, with bytes overwritten, or with lines
        /// dropped is read or refused with an error; it never panics, and a
        /// pair that is read passes the OpenCV form's checks.
        ///
        /// Verifies: VTSM-CLI-043
        #[test]
        fn damaged_camera_info_never_panics(
            cut in 0usize..2000,
            edits in proptest::collection::vec((0usize..2000, any::<u8>()), 0..6),
            drop_line in proptest::option::of(0usize..20),
        ) {
            let (l, r) = from_opencv(&physical()).unwrap();
            let text = camera_info_text("right", &r);
            let bytes = crate::io::damaged(&text, cut, &edits, drop_line);
            if let Ok(right) = parse_camera_info(&bytes, Path::new("right.yaml")) {
                if let Ok(c) = to_opencv(&l, &right) {
                    prop_assert!(c.validate().is_ok());
                }
            }
        }
    }
}
