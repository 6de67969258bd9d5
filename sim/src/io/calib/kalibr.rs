//! The Kalibr form of `calib.json`: a physical stereo pair as the camera-chain
//! YAML file (`camchain.yaml`, `…-camchain.yaml`) that Kalibr's
//! `kalibr_calibrate_cameras` writes.
//!
//! ```json
//! {"kalibr_camchain": "camchain.yaml"}
//! {"kalibr_camchain": "camchain.yaml", "left": "cam1", "right": "cam0"}
//! ```
//!
//! The path is resolved against the directory of `calib.json`; `left` and
//! `right` (default `cam0` and `cam1`) name two neighbouring cameras of the
//! chain. Each camera holds `camera_model: pinhole`, `intrinsics: [fu, fv, pu,
//! pv]`, `distortion_model: radtan` with `distortion_coeffs: [k1, k2, r1, r2]`
//! (OpenCV's `k1, k2, p1, p2`), `resolution: [W, H]`, and every camera after
//! the first `T_cn_cnm1`, the 4×4 transform taking the previous camera's
//! coordinates to its own (Kalibr's `T_c1_c0` for `cam1`). With `right` the
//! camera after `left`, `R`, `T` of the OpenCV form ([`OpenCvCalib`],
//! `X_right = R · X_left + T`) are the right camera's `T_cn_cnm1`; with `left`
//! after `right`, its inverse. Other camera models (`omni`, `ds`, `eucm`) and
//! distortion models (`equidistant`, `fov`, `none` is accepted as zero
//! distortion) are refused: the host rectifier implements OpenCV's pinhole
//! model only.

use super::model::{OpenCvCalib, OpenCvCamera};
use super::yaml::{get, number_list, resolve, yaml_mapping};
use crate::error::{Error, Result};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use yaml_rust2::Yaml;

/// Largest accepted size of a camera-chain file, bytes.
pub const MAX_CAMCHAIN_BYTES: usize = 1 << 20;
/// Largest accepted deviation of the last row of `T_cn_cnm1` from `0 0 0 1`.
pub const HOMOGENEOUS_TOL: f64 = 1.0e-9;

/// `calib.json` in the Kalibr form.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KalibrCalibFile {
    /// The camera-chain YAML file.
    pub kalibr_camchain: PathBuf,
    /// The left camera's name in the chain (default `cam0`).
    #[serde(default = "cam0")]
    pub left: String,
    /// The right camera's name in the chain (default `cam1`).
    #[serde(default = "cam1")]
    pub right: String,
}

fn cam0() -> String {
    "cam0".into()
}

fn cam1() -> String {
    "cam1".into()
}

/// The list of `n` numbers under `key` of `cam`.
fn numbers(cam: &Yaml, key: &str, n: usize) -> std::result::Result<Vec<f64>, String> {
    number_list(get(cam, key), key, n)
}

/// One pinhole-radtan camera of the chain, and its `T_cn_cnm1` if it has one.
#[allow(clippy::type_complexity)]
fn camera(
    chain: &Yaml,
    name: &str,
) -> std::result::Result<(OpenCvCamera, [u32; 2], Option<[[f64; 4]; 4]>), String> {
    let cam = get(chain, name).ok_or_else(|| format!("no camera `{name}` in the chain"))?;
    let field = |why: String| format!("{name}.{why}");
    let model = get(cam, "camera_model")
        .and_then(Yaml::as_str)
        .unwrap_or("pinhole");
    if model != "pinhole" {
        return Err(field(format!(
            "camera_model {model:?} is not supported (pinhole only)"
        )));
    }
    let i = numbers(cam, "intrinsics", 4).map_err(field)?;
    let dist = match get(cam, "distortion_model").and_then(Yaml::as_str) {
        Some("radtan") => numbers(cam, "distortion_coeffs", 4).map_err(field)?,
        Some("none") => vec![0.0; 4],
        Some(m) => {
            return Err(field(format!(
                "distortion_model {m:?} is not supported (radtan or none)"
            )))
        }
        None => return Err(field("distortion_model is missing or not a string".into())),
    };
    let res = numbers(cam, "resolution", 2).map_err(field)?;
    let mut size = [0u32; 2];
    for (o, v) in size.iter_mut().zip(&res) {
        // `as` saturates (and maps NaN to 0); the round trip tells an integer.
        let u = *v as u32;
        *o = if f64::from(u) == *v && vtsm_core::geom::image_dim_ok(u) {
            u
        } else {
            return Err(field(format!(
                "resolution {v} is not an integer in 1..={}",
                vtsm_core::config::MAX_IMAGE_DIM
            )));
        };
    }
    let t = match get(cam, "T_cn_cnm1") {
        None => None,
        Some(t) => {
            let rows = t
                .as_vec()
                .filter(|r| r.len() == 4)
                .ok_or_else(|| field("T_cn_cnm1 must be a list of 4 rows".into()))?;
            let mut m = [[0.0; 4]; 4];
            for (i, (row, y)) in m.iter_mut().zip(rows).enumerate() {
                let v = number_list(Some(y), &format!("T_cn_cnm1[{i}]"), 4).map_err(field)?;
                row.copy_from_slice(&v);
            }
            let last = m[3];
            let want = [0.0, 0.0, 0.0, 1.0];
            if last
                .iter()
                .zip(want)
                .any(|(a, b)| (a - b).abs() > HOMOGENEOUS_TOL)
            {
                return Err(field("T_cn_cnm1 last row must be [0, 0, 0, 1]".into()));
            }
            Some(m)
        }
    };
    let k = [[i[0], 0.0, i[2]], [0.0, i[1], i[3]], [0.0, 0.0, 1.0]];
    Ok((OpenCvCamera { k, dist }, size, t))
}

/// The index of `cam<N>`, for the chain's order.
fn index(name: &str) -> Option<u32> {
    name.strip_prefix("cam")?.parse().ok()
}

/// The OpenCV form of cameras `left`, `right` of a parsed camera chain.
///
/// # Errors
/// A camera missing or not `cam<N>`, the two not neighbours in the chain, a
/// model other than pinhole-radtan, a field of the wrong shape, different
/// resolutions, or what [`OpenCvCalib::validate`] refuses (named as in the
/// OpenCV form).
pub fn to_opencv(
    chain: &Yaml,
    left: &str,
    right: &str,
) -> std::result::Result<OpenCvCalib, String> {
    let (Some(il), Some(ir)) = (index(left), index(right)) else {
        return Err(format!(
            "cameras are named cam0, cam1, …; not {left:?} and {right:?}"
        ));
    };
    let (lc, ls, lt) = camera(chain, left)?;
    let (rc, rs, rt) = camera(chain, right)?;
    if ls != rs {
        return Err(format!(
            "{left} and {right} have different resolutions ({}×{} and {}×{})",
            ls[0], ls[1], rs[0], rs[1]
        ));
    }
    // X_right = R · X_left + T.
    let (r, t) = if ir == il.wrapping_add(1) {
        let m = rt.ok_or_else(|| format!("{right}.T_cn_cnm1 is missing"))?;
        (
            [0, 1, 2].map(|i| [m[i][0], m[i][1], m[i][2]]),
            [m[0][3], m[1][3], m[2][3]],
        )
    } else if il == ir.wrapping_add(1) {
        // left's T_cn_cnm1 takes right to left: invert it.
        let m = lt.ok_or_else(|| format!("{left}.T_cn_cnm1 is missing"))?;
        let r = [0, 1, 2].map(|i| [m[0][i], m[1][i], m[2][i]]);
        let t = [0, 1, 2].map(|i| -(0..3).map(|k| r[i][k] * m[k][3]).sum::<f64>());
        (r, t)
    } else {
        return Err(format!(
            "{left} and {right} are not neighbours in the chain (T_cn_cnm1 links each camera to the one before)"
        ));
    };
    let c = OpenCvCalib {
        image_size: ls,
        left: lc,
        right: rc,
        r,
        t,
    };
    c.validate().map_err(|(field, why)| match field.as_str() {
        "R" | "T" => format!("T_cn_cnm1 ({field}): {why}"),
        f => format!("`{f}`: {why}"),
    })?;
    Ok(c)
}

/// Parse the Kalibr form of `calib.json` (module docs) and read the chain it
/// names, relative to `path`'s directory.
///
/// # Errors
/// Malformed JSON or an unknown key (naming `path`); a chain file that cannot
/// be read, is larger than [`MAX_CAMCHAIN_BYTES`], is not one YAML mapping, or
/// that [`to_opencv`] refuses (naming the chain file).
pub fn parse_kalibr_calib(bytes: &[u8], path: &Path) -> Result<OpenCvCalib> {
    let f: KalibrCalibFile = crate::io::json::parse_json(bytes, path)?;
    let full = resolve(path, &f.kalibr_camchain);
    let chain = yaml_mapping(
        &crate::io::read_file(&full)?,
        &full,
        MAX_CAMCHAIN_BYTES,
        "a camera chain: cam0, cam1, …",
    )?;
    to_opencv(&chain, &f.left, &f.right).map_err(|why| Error::file(&full, why))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::panic)]
    use super::*;
    use yaml_rust2::YamlLoader;

    /// Kalibr's wiki example layout (block lists for `T_cn_cnm1`, extra keys),
    /// with a right camera 0.11 m to the right and turned slightly.
    const CHAIN: &str = "\
cam0:
  camera_model: pinhole
  intrinsics: [461.629, 460.152, 362.680, 246.049]
  distortion_model: radtan
  distortion_coeffs: [-0.27695497, 0.06712482, 0.00087538, 0.00011556]
  T_cam_imu:
  - [0.01779318, 0.99967549, -0.01822936, 0.07008565]
  - [-0.9998017, 0.01795239, 0.00860714, -0.01771023]
  - [0.00893160, 0.01807260, 0.99979678, 0.00399246]
  - [0.0, 0.0, 0.0, 1.0]
  timeshift_cam_imu: -8.121e-05
  rostopic: /cam0/image_raw
  resolution: [752, 480]
cam1:
  camera_model: pinhole
  intrinsics: [465.0, 464.0, 360.0, 250.0]
  distortion_model: radtan
  distortion_coeffs: [-0.27, 0.066, 0.0004, -0.0002]
  T_cn_cnm1:
  - [1.0, 0.0, 0.0, -0.11]
  - [0.0, 0.99995, -0.0099998, 0.0005]
  - [0.0, 0.0099998, 0.99995, 0.001]
  - [0.0, 0.0, 0.0, 1.0]
  rostopic: /cam1/image_raw
  resolution: [752, 480]
";

    fn chain(text: &str) -> Yaml {
        YamlLoader::load_from_str(text).unwrap().remove(0)
    }

    /// cam0 → cam1: R, T are cam1's T_cn_cnm1; K from the intrinsics.
    ///
    /// Verifies: VTSM-CLI-044
    #[test]
    fn a_kalibr_chain_gives_t_cn_cnm1_as_r_and_t() {
        let c = to_opencv(&chain(CHAIN), "cam0", "cam1").unwrap();
        assert_eq!(c.image_size, [752, 480]);
        assert_eq!(c.t, [-0.11, 0.0005, 0.001]);
        assert_eq!(c.r[1], [0.0, 0.99995, -0.0099998]);
        assert_eq!(
            c.left.k,
            [
                [461.629, 0.0, 362.680],
                [0.0, 460.152, 246.049],
                [0.0, 0.0, 1.0]
            ]
        );
        assert_eq!(c.right.dist, [-0.27, 0.066, 0.0004, -0.0002]);
    }

    /// A chain whose right camera is cam0: the inverse of cam1's transform,
    /// checked by mapping a point both ways.
    ///
    /// Verifies: VTSM-CLI-044
    #[test]
    fn a_chain_read_right_to_left_inverts_t_cn_cnm1() {
        // cam1 is the left camera, 0.11 m to the left of cam0.
        let text = CHAIN.replace("[1.0, 0.0, 0.0, -0.11]", "[1.0, 0.0, 0.0, 0.11]");
        let fwd = to_opencv(&chain(&text), "cam0", "cam1");
        assert!(fwd.unwrap_err().contains("+x axis"), "cam1 is left of cam0");
        let c = to_opencv(&chain(&text), "cam1", "cam0").unwrap();
        // X_cam1 = M · X_cam0 with M = cam1's T_cn_cnm1; X_cam0 = R · X_cam1 + T.
        let m = [
            [1.0, 0.0, 0.0, 0.11],
            [0.0, 0.99995, -0.0099998, 0.0005],
            [0.0, 0.0099998, 0.99995, 0.001],
        ];
        let x0 = [0.3, -0.2, 2.5];
        let x1 = [0, 1, 2].map(|i| (0..3).map(|k| m[i][k] * x0[k]).sum::<f64>() + m[i][3]);
        let back = [0, 1, 2].map(|i| (0..3).map(|k| c.r[i][k] * x1[k]).sum::<f64>() + c.t[i]);
        for i in 0..3 {
            // M's rotation is orthonormal to ~1e-9 as written.
            assert!(
                (back[i] - x0[i]).abs() < 1e-8,
                "{i}: {} vs {}",
                back[i],
                x0[i]
            );
        }
    }

    /// Refusals name the camera and field.
    ///
    /// Verifies: VTSM-CLI-044
    #[test]
    fn bad_chains_are_refused_naming_the_field() {
        for (text, left, right, want) in [
            (
                CHAIN.replace(
                    "camera_model: pinhole\n  intrinsics: [465",
                    "camera_model: omni\n  intrinsics: [465",
                ),
                "cam0",
                "cam1",
                "cam1.camera_model",
            ),
            (
                CHAIN.replacen(
                    "distortion_model: radtan",
                    "distortion_model: equidistant",
                    1,
                ),
                "cam0",
                "cam1",
                "cam0.distortion_model",
            ),
            (
                CHAIN.replacen(
                    "[461.629, 460.152, 362.680, 246.049]",
                    "[461.629, 460.152, 362.680]",
                    1,
                ),
                "cam0",
                "cam1",
                "cam0.`intrinsics` has 3",
            ),
            (
                CHAIN.replacen(
                    "resolution: [752, 480]\ncam1",
                    "resolution: [640, 480]\ncam1",
                    1,
                ),
                "cam0",
                "cam1",
                "different resolutions",
            ),
            (
                CHAIN.replace(
                    "  - [0.0, 0.0, 0.0, 1.0]\n  rostopic: /cam1",
                    "  - [0.0, 0.0, 1.0, 1.0]\n  rostopic: /cam1",
                ),
                "cam0",
                "cam1",
                "last row",
            ),
            (
                CHAIN.replace(
                    "[0.0, 0.99995, -0.0099998, 0.0005]",
                    "[0.0, 0.9, -0.0099998, 0.0005]",
                ),
                "cam0",
                "cam1",
                "T_cn_cnm1 (R)",
            ),
            (CHAIN.to_string(), "cam0", "cam2", "no camera `cam2`"),
            (CHAIN.to_string(), "left", "right", "cam0, cam1"),
        ] {
            let e = to_opencv(&chain(&text), left, right).unwrap_err();
            assert!(e.contains(want), "{want}: {e}");
        }
        let dir = std::env::temp_dir().join(format!("vtsm-kalibr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("chain.yaml"), "- cam0\n").unwrap();
        let calib = dir.join("calib.json");
        for (json, want) in [
            (
                &br#"{"kalibr_camchain": "chain.yaml"}"#[..],
                ["chain.yaml", "one YAML mapping"],
            ),
            (
                &br#"{"kalibr_camchain": "nope.yaml"}"#[..],
                ["nope.yaml", "cannot read"],
            ),
            (
                &br#"{"kalibr_camchain": "chain.yaml", "lft": "cam0"}"#[..],
                ["calib.json", "lft"],
            ),
        ] {
            let e = parse_kalibr_calib(json, &calib).unwrap_err().to_string();
            assert!(want.iter().all(|w| e.contains(w)), "{e}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The example chain of `fsw-docs/interfaces/examples/kalibr/` holds the rig
    /// of `examples/calib-opencv.json` (radtan has no k3: the right camera's
    /// 0.001 is left out) and reads through `calib.json` to its R, T and K.
    ///
    /// Verifies: VTSM-CLI-044
    #[test]
    fn the_example_chain_reads_to_the_opencv_example() {
        use super::super::{read_calib_any, CalibFile};
        let ex = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fsw-docs/interfaces/examples");
        let (CalibFile::OpenCv(want), CalibFile::OpenCv(got)) = (
            read_calib_any(&ex.join("calib-opencv.json")).unwrap(),
            read_calib_any(&ex.join("kalibr/calib.json")).unwrap(),
        ) else {
            panic!("both are physical pairs");
        };
        assert_eq!(
            (got.r, got.t, got.image_size),
            (want.r, want.t, want.image_size)
        );
        assert_eq!((got.left.k, got.right.k), (want.left.k, want.right.k));
        assert_eq!(got.left.dist[..], want.left.dist[..4]);
        assert_eq!(got.right.dist[..], want.right.dist[..4]);
    }
}
