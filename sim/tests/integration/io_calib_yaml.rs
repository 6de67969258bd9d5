//! The ROS and Kalibr forms of `calib.json` through `vtsm relocalize`: a bad
//! pair is refused before anything else is read, with one line naming the file
//! and what is wrong, exit code 2, and nothing written.
#![allow(clippy::unwrap_used, missing_docs)]

use std::path::{Path, PathBuf};
use std::process::Command;

fn examples(form: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fsw-docs/interfaces/examples")
        .join(form)
}

/// Run `vtsm relocalize` with `calib` (the map, images and prior do not exist:
/// the calibration is checked first); exit code, stderr, whether `--out` exists.
fn relocalize(d: &Path, calib: &Path) -> (Option<i32>, String, bool) {
    let out = d.join("result.json");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let o = Command::new(env!("CARGO_BIN_EXE_vtsm"))
        .args(["relocalize", "--map", &s(&d.join("none.vmap"))])
        .args(["--calib", &s(calib)])
        .args([
            "--left",
            &s(&d.join("l.png")),
            "--right",
            &s(&d.join("r.png")),
        ])
        .args(["--prior", &s(&d.join("prior.json")), "--out", &s(&out)])
        .output()
        .unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).trim().to_string(),
        out.exists(),
    )
}

/// Verifies: VTSM-CLI-043
#[test]
fn relocalize_refuses_a_bad_ros_pair() {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("io_calib_ros_cli");
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let left = std::fs::read_to_string(examples("ros").join("left.yaml")).unwrap();
    let right = std::fs::read_to_string(examples("ros").join("right.yaml")).unwrap();
    std::fs::write(d.join("left.yaml"), &left).unwrap();
    // The right camera's projection moved off the row: a vertical pair.
    let vertical = right.replacen("454.94644927978516, 0.0,", "454.94644927978516, 12.5,", 1);
    assert_ne!(vertical, right);
    std::fs::write(d.join("vertical.yaml"), vertical).unwrap();
    // A right file with the camera matrix cut to 8 numbers.
    let short = right.replacen("data: [878.0, 0.0, ", "data: [878.0, ", 1);
    assert_ne!(short, right);
    std::fs::write(d.join("short.yaml"), short).unwrap();
    for (right, want) in [
        ("vertical.yaml", ["calib.json", "vertical"]),
        ("short.yaml", ["short.yaml", "camera_matrix.data"]),
        ("missing.yaml", ["missing.yaml", "cannot read"]),
    ] {
        let calib = d.join("calib.json");
        std::fs::write(
            &calib,
            format!(r#"{{"ros_camera_info": {{"left": "left.yaml", "right": "{right}"}}}}"#),
        )
        .unwrap();
        let (code, err, wrote) = relocalize(&d, &calib);
        assert_eq!(code, Some(2), "{right}: {err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(want.iter().all(|w| err.contains(w)), "{right}: {err}");
        assert!(!wrote);
    }
}

/// Verifies: VTSM-CLI-044
#[test]
fn relocalize_refuses_a_bad_kalibr_chain() {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("io_calib_kalibr_cli");
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let chain = std::fs::read_to_string(examples("kalibr").join("camchain.yaml")).unwrap();
    let fisheye = chain.replacen(
        "distortion_model: radtan",
        "distortion_model: equidistant",
        2,
    );
    assert_ne!(fisheye, chain);
    std::fs::write(d.join("fisheye.yaml"), fisheye).unwrap();
    std::fs::write(d.join("good.yaml"), &chain).unwrap();
    for (json, want) in [
        (
            r#"{"kalibr_camchain": "fisheye.yaml"}"#,
            ["fisheye.yaml", "cam0.distortion_model"],
        ),
        (
            r#"{"kalibr_camchain": "good.yaml", "left": "cam0", "right": "cam2"}"#,
            ["good.yaml", "no camera `cam2`"],
        ),
        (
            r#"{"kalibr_camchain": "good.yaml", "left": "cam1", "right": "cam0"}"#,
            ["good.yaml", "+x axis"],
        ),
    ] {
        let calib = d.join("calib.json");
        std::fs::write(&calib, json).unwrap();
        let (code, err, wrote) = relocalize(&d, &calib);
        assert_eq!(code, Some(2), "{json}: {err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(want.iter().all(|w| err.contains(w)), "{json}: {err}");
        assert!(!wrote);
    }
}
