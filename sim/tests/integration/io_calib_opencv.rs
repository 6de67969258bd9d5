//! The OpenCV form of `calib.json`: accepted as OpenCV writes it, refused with a
//! one-line error naming the file, line and field when a value cannot be used.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, missing_docs)]

use std::path::{Path, PathBuf};
use std::process::Command;
use vtsm_sim::io::calib::{parse_calib_any, CalibFile};

const GOOD: &str = r#"{"image_size": [640, 480],
 "left":  {"K": [[500.0, 0, 320.5], [0, 501.0, 240.2], [0, 0, 1]],
           "dist": [-0.1, 0.02, 0.0005, -0.0003, 0.0]},
 "right": {"K": [[499.0, 0, 318.0], [0, 498.0, 241.0], [0, 0, 1]],
           "dist": [-0.09, 0.018, -0.0004, 0.0002, 0.001]},
 "R": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
 "T": [-0.4, 0.002, -0.001]}
"#;

fn p() -> &'static Path {
    Path::new("calib.json")
}

/// The example of the interface document and the form written by OpenCV parse
/// and rectify; 4 and 8 distortion coefficients are accepted too.
///
/// Verifies: VTSM-CLI-032
#[test]
fn opencv_form_is_detected_and_rectifies() {
    let c = match parse_calib_any(GOOD.as_bytes(), p()).unwrap() {
        CalibFile::OpenCv(c) => c,
        CalibFile::Rectified(_) => panic!("not detected"),
    };
    assert_eq!(c.size(), (640, 480));
    assert_eq!(c.left.dist8()[0], -0.1);
    let r = vtsm_sim::rectify::Rectifier::new(&c).unwrap();
    assert!((r.rig.baseline_m() - 0.4).abs() < 1e-3);
    assert_eq!(r.rig.cam().fx(), 499.5);
    let example = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fsw-docs/interfaces/examples/calib-opencv.json");
    let bytes = std::fs::read(&example).unwrap();
    assert!(matches!(
        parse_calib_any(&bytes, &example).unwrap(),
        CalibFile::OpenCv(_)
    ));
    for dist in [
        "[-0.1, 0.02, 0.0005, -0.0003]",
        "[-0.1, 0.02, 0, 0, 0.001, 0.01, 0.002, 0.0]",
    ] {
        let text = GOOD.replacen("[-0.1, 0.02, 0.0005, -0.0003, 0.0]", dist, 1);
        assert!(parse_calib_any(text.as_bytes(), p()).is_ok(), "{dist}");
    }
    // The rectified form is still read as before.
    let rect = br#"{"width":4,"height":3,"fx":2,"fy":2,"cx":1.5,"cy":1,"baseline_m":0.4}"#;
    assert!(matches!(
        parse_calib_any(rect, p()).unwrap(),
        CalibFile::Rectified(_)
    ));
}

/// Each unusable value is refused with the file, the line and the field.
///
/// Verifies: VTSM-CLI-032
#[test]
fn bad_opencv_values_are_rejected_with_field_and_line() {
    let cases: [(&str, &str, &str, usize); 12] = [
        ("[640, 480]", "[0, 480]", "`image_size`", 1),
        ("[640, 480]", "[640, 100000]", "`image_size`", 1),
        ("[[500.0, 0, 320.5]", "[[-500.0, 0, 320.5]", "`left.K`", 2),
        ("[0, 498.0, 241.0]", "[0, 0.0, 241.0]", "`right.K`", 4),
        ("[[500.0, 0, 320.5]", "[[500.0, 3, 320.5]", "`left.K`", 2),
        ("[0, 0, 1]]", "[0, 0, 2]]", "`left.K`", 2),
        ("0.0005, -0.0003, 0.0]", "0.0005]", "`left.dist`", 3),
        ("[-0.09, 0.018", "[1e300, 0.018", "`right.dist`", 5),
        (
            "[[1, 0, 0], [0, 1, 0]",
            "[[1, 0.01, 0], [0, 1, 0]",
            "`R`",
            6,
        ),
        (
            "[[1, 0, 0], [0, 1, 0], [0, 0, 1]]",
            "[[1, 0, 0], [0, 1, 0], [0, 0, -1]]",
            "`R`",
            6,
        ),
        ("[-0.4, 0.002, -0.001]", "[0.0, 0.0, 0.0]", "`T`", 7),
        ("[-0.4, 0.002, -0.001]", "[0.0, -0.4, 0.0]", "`T`", 7),
    ];
    for (from, to, field, line) in cases {
        assert!(GOOD.contains(from), "{from}");
        let text = GOOD.replacen(from, to, 1);
        let e = parse_calib_any(text.as_bytes(), p()).unwrap_err();
        let msg = e.to_string();
        assert!(msg.starts_with("calib.json:"), "{msg}");
        assert!(msg.contains(field), "{to}: {msg}");
        assert_eq!(e.line, Some(line), "{to}: {msg}");
        assert!(!msg.contains('\n'), "{msg}");
    }
    // The right camera on the left of the left camera.
    let text = GOOD.replacen("[-0.4, 0.002, -0.001]", "[0.4, 0.0, 0.0]", 1);
    let msg = parse_calib_any(text.as_bytes(), p())
        .unwrap_err()
        .to_string();
    assert!(msg.contains("`T`") && msg.contains("+x"), "{msg}");
    // An unknown key is an error, not ignored.
    let text = GOOD.replacen("\"T\"", "\"t\"", 1);
    assert!(parse_calib_any(text.as_bytes(), p()).is_err());
    let text = GOOD.replacen("\"dist\"", "\"D\"", 1);
    assert!(parse_calib_any(text.as_bytes(), p()).is_err());
}

/// `vtsm relocalize` with a bad OpenCV calibration: exit 2, one line naming the
/// file and field, nothing written.
///
/// Verifies: VTSM-CLI-032
#[test]
fn relocalize_refuses_a_bad_opencv_calib() {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("io_calib_opencv_cli");
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let calib = d.join("calib.json");
    std::fs::write(
        &calib,
        GOOD.replacen("[[1, 0, 0], [0, 1, 0]", "[[1, 0.2, 0], [0, 1, 0]", 1),
    )
    .unwrap();
    let out = d.join("result.json");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let o = Command::new(env!("CARGO_BIN_EXE_vtsm"))
        .args([
            "relocalize",
            "--map",
            &s(&d.join("none.vmap")),
            "--calib",
            &s(&calib),
        ])
        .args([
            "--left",
            &s(&d.join("l.png")),
            "--right",
            &s(&d.join("r.png")),
        ])
        .args(["--prior", &s(&d.join("prior.json")), "--out", &s(&out)])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.contains("calib.json:6:") && err.contains("`R`"),
        "{err}"
    );
    assert!(!out.exists());
}
