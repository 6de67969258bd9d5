#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
use super::*;
use crate::io::calib::{parse_calib_any, read_calib_any, CalibFile};

fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fsw-docs/interfaces/examples")
}

fn opencv(c: CalibFile) -> OpenCvCalib {
    match c {
        CalibFile::OpenCv(c) => *c,
        CalibFile::Rectified(_) => panic!("a physical pair"),
    }
}

/// A scratch directory of this test process.
fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("vtsm-storage-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The files OpenCV 5.1.0's `cv2.FileStorage` wrote for the rig of
/// `calib-opencv.json` (`examples/opencv-storage/write.py`): the two files of
/// the `stereo_calib` sample with `T` in millimetres, and one file with the
/// argument names of `cv2.stereoCalibrate` as YAML and as XML, each read as
/// `--calib` itself, give that calibration (T within 1e-15 m after the
/// millimetre conversion).
///
/// Verifies: VTSM-CLI-045
#[test]
fn the_opencv_written_examples_read_to_the_opencv_example() {
    let ex = examples();
    let want = opencv(read_calib_any(&ex.join("calib-opencv.json")).unwrap());
    for file in [
        "opencv-storage/calib.json",
        "opencv-storage/stereo.yml",
        "opencv-storage/stereo.xml",
    ] {
        let got = opencv(read_calib_any(&ex.join(file)).unwrap());
        assert_eq!(
            (&got.left, &got.right, got.r, got.image_size),
            (&want.left, &want.right, want.r, want.image_size),
            "{file}"
        );
        for (g, w) in got.t.iter().zip(want.t) {
            assert!(
                (g - w).abs() < 1e-15,
                "{file}: T {:?} vs {:?}",
                got.t,
                want.t
            );
        }
    }
}

/// The `%YAML:1.0` header of OpenCV 2–4, block lists, `image_width` with
/// `image_height`, a rotation vector for `R`, 4 and 8 distortion coefficients
/// and plain YAML lists are read.
///
/// Verifies: VTSM-CLI-045
#[test]
fn the_opencv_4_layout_and_other_value_forms_read() {
    let text = "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n\
        K1: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 500., 0., 320.5, 0., 501., 240.,\n       0., 0., 1. ]\n\
        D1: !!opencv-matrix\n   rows: 4\n   cols: 1\n   dt: d\n   data: [ -0.1, 0.01, 0., 0. ]\n\
        K2: [[499., 0., 319.], [0., 500., 241.], [0., 0., 1.]]\n\
        D2:\n  - -0.1\n  - 0.01\n  - 0.\n  - 0.\n  - 0.\n  - 0.001\n  - 0.\n  - 0.\n\
        R: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n   data: [ 0., 0.01, 0. ]\n\
        T: [ -0.12, 0., 0. ]\nrms: 0.21\n";
    let c = opencv(parse_calib_any(text.as_bytes(), Path::new("stereo.yml")).unwrap());
    assert_eq!(c.image_size, [640, 480]);
    assert_eq!(
        c.left.k,
        [[500.0, 0.0, 320.5], [0.0, 501.0, 240.0], [0.0, 0.0, 1.0]]
    );
    assert_eq!(c.left.dist, vec![-0.1, 0.01, 0.0, 0.0]);
    assert_eq!(c.right.k[1], [0.0, 500.0, 241.0]);
    assert_eq!(c.right.dist.len(), 8);
    // A rotation of 0.01 rad about y, as cv2.Rodrigues gives it.
    let (s, co) = 0.01f64.sin_cos();
    let want = [[co, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, co]];
    for (g, w) in c.r.iter().flatten().zip(want.iter().flatten()) {
        assert!((g - w).abs() < 1e-15, "{:?}", c.r);
    }
    assert_eq!(c.t, [-0.12, 0.0, 0.0]);
}

/// Every refusal names the file and the key or field, and says why.
///
/// Verifies: VTSM-CLI-045
#[test]
fn bad_storage_files_are_refused_naming_file_and_key() {
    let dir = scratch("bad");
    let good = std::fs::read_to_string(examples().join("opencv-storage/stereo.yml")).unwrap();
    let intr = std::fs::read_to_string(examples().join("opencv-storage/intrinsics.yml")).unwrap();
    let extr = std::fs::read_to_string(examples().join("opencv-storage/extrinsics.yml")).unwrap();
    std::fs::write(dir.join("intrinsics.yml"), &intr).unwrap();
    std::fs::write(dir.join("extrinsics.yml"), &extr).unwrap();
    let file = |name: &str, text: &str| {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    // --calib a YAML file itself.
    let direct: Vec<(String, Vec<&str>)> = vec![
        (
            good.replace("cameraMatrix2", "cameraMatrixB"),
            vec!["right.K", "`M2`", "`cameraMatrix2`"],
        ),
        (
            good.replace("distCoeffs1", "D1") + "distCoeffs1: [ 0., 0., 0., 0. ]\n",
            vec!["`distCoeffs1`", "`D1`", "differently"],
        ),
        (
            good.replace(
                "rows: 3\n   cols: 3\n   dt: d\n   data: [ 884.2",
                "rows: 2\n   cols: 3\n   dt: d\n   data: [ 884.2",
            ),
            vec!["`cameraMatrix1`", "2 × 3"],
        ),
        (
            good.replace("data: [ 1368, 912 ]", "data: [ 1368, 912, 3 ]"),
            vec!["`image_size`", "3 numbers"],
        ),
        (
            good.replace("image_size", "imagesize"),
            vec!["no image size", "image_size"],
        ),
        (
            good.replace("-0.39994843145470177", "-399.94843145470177"),
            vec!["`T` (T)", "baseline", "T_unit"],
        ),
        (
            good.replace("0.99996466460355093", "1.5"),
            vec!["`R` (R)", "orthonormal"],
        ),
        (
            good.replace(
                "0.02, 0.00059999999999999995",
                ".inf, 0.00059999999999999995",
            ),
            vec!["`distCoeffs1`", "non-finite"],
        ),
        (
            good.replace(
                "0.02, 0.00059999999999999995",
                ".Nan, 0.00059999999999999995",
            ),
            vec!["`distCoeffs1`", "non-finite"],
        ),
        (
            good.replace("data: [ -0.39994843145470177", "data: [ -.Inf"),
            vec!["`T`", "non-finite"],
        ),
        (
            good.replace("data: [ -0.39994843145470177", "data: [ x"),
            vec!["`T`", "not a number"],
        ),
        (
            good.replace("   data: [ 878.", "   dat: [ 878."),
            vec!["`cameraMatrix2`", "without a `data` list"],
        ),
        (format!("{}\n  : :", good), vec!["stereo.yml", "not YAML"]),
    ];
    for (text, want) in direct {
        let p = file("stereo.yml", &text);
        let e = read_calib_any(&p).unwrap_err().to_string();
        assert!(
            e.contains("stereo.yml") && want.iter().all(|w| e.contains(w)),
            "{want:?}: {e}"
        );
    }
    // FileStorage JSON, and XML outside the subset OpenCV writes, named by
    // calib.json.
    let refused = [
        ("x.json", "{\"M1\": 1}", vec!["x.json", "JSON is not read"]),
        (
            "x.xml",
            "<?xml version=\"1.0\"?>\n<storage>\n</storage>\n",
            vec!["x.xml:2", "root is <storage>"],
        ),
        (
            "x.xml",
            "<?xml version=\"1.0\"?>\n<opencv_storage>\n<M1>1 2</M2>\n</opencv_storage>\n",
            vec!["x.xml:3", "</M2> closes <M1>"],
        ),
        (
            "x.xml",
            "<opencv_storage>\n<M1><rows>3</rows>x</M1>\n</opencv_storage>\n",
            vec!["x.xml:2", "mixes text and elements"],
        ),
        (
            "x.xml",
            "<opencv_storage>\n<M1><a><a><a><a><a><a><a><a>1</a></a></a></a></a></a></a></a></M1></opencv_storage>",
            vec!["x.xml:2", "deeper than 8"],
        ),
        ("x.xml", "<opencv_storage>\n<M1>1 2 3", vec!["x.xml", "<M1> is not closed"]),
        (
            "x.xml",
            "<opencv_storage><T>1</T><T>2</T></opencv_storage>",
            vec!["x.xml", "<T> twice"],
        ),
        (
            "x.xml",
            "<opencv_storage><n>&foo;</n></opencv_storage>",
            vec!["x.xml", "entity"],
        ),
        (
            "x.xml",
            "<opencv_storage></opencv_storage> <x/>",
            vec!["x.xml", "content after"],
        ),
    ];
    for (name, text, want) in refused {
        file(name, text);
        let p = file(
            "c.json",
            &format!(r#"{{"opencv_storage": "{name}", "image_size": [640, 480]}}"#),
        );
        let e = read_calib_any(&p).unwrap_err().to_string();
        assert!(want.iter().all(|w| e.contains(w)), "{want:?}: {e}");
    }
    // calib.json of the form.
    for (json, want) in [
        (
            r#"{"opencv_storage": ["intrinsics.yml", "extrinsics.yml"], "image_size": [1368, 912], "T_unit": "inch"}"#,
            vec!["c.json", "`T_unit`", "inch"],
        ),
        (
            r#"{"opencv_storage": ["intrinsics.yml", "extrinsics.yml"], "image_size": [1368, 912]}"#,
            vec!["extrinsics.yml", "`T` (T)", "T_unit"],
        ),
        (
            r#"{"opencv_storage": ["intrinsics.yml"], "image_size": [1368, 912], "T_unit": "mm"}"#,
            vec!["c.json", "no R", "intrinsics.yml"],
        ),
        (
            r#"{"opencv_storage": ["intrinsics.yml", "extrinsics.yml"], "T_unit": "mm"}"#,
            vec!["c.json", "no image size"],
        ),
        (
            r#"{"opencv_storage": [], "image_size": [1368, 912]}"#,
            vec!["c.json", "1 to 8 files, not 0"],
        ),
        (
            r#"{"opencv_storage": "missing.yml", "image_size": [1368, 912]}"#,
            vec!["missing.yml", "cannot read"],
        ),
        (
            r#"{"opencv_storage": "stereo.yml", "image_size": [1368, 913]}"#,
            vec!["c.json", "[1368, 913]", "differs"],
        ),
        (
            r#"{"opencv_storage": "intrinsics.yml", "image_sise": [1, 1]}"#,
            vec!["c.json", "image_sise"],
        ),
    ] {
        std::fs::write(dir.join("stereo.yml"), &good).unwrap();
        let p = file("c.json", json);
        let e = read_calib_any(&p).unwrap_err().to_string();
        assert!(want.iter().all(|w| e.contains(w)), "{want:?}: {e}");
    }
    // One item under two names (or in two files) with the same numbers is
    // read: the left camera matrix also as a plain list.
    let twice = format!("{good}M1: [ 884.2, 0., 691.7, 0., 882.6, 451.9, 0., 0., 1. ]\n");
    let p = file("stereo.yml", &twice);
    assert_eq!(
        opencv(read_calib_any(&p).unwrap()).left.k[0],
        [884.2, 0.0, 691.7]
    );
    // The same two files with the unit given read to the example.
    let p = file(
        "c.json",
        r#"{"opencv_storage": ["intrinsics.yml", "extrinsics.yml"], "image_size": [1368, 912], "T_unit": "mm"}"#,
    );
    assert!(read_calib_any(&p).is_ok());
    let _ = std::fs::remove_dir_all(&dir);
}

use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    /// A FileStorage file cut short, with bytes overwritten, or with lines
    /// dropped is read or refused with an error; it never panics, and a pair
    /// that is read passes the OpenCV form's checks.
    ///
    /// Verifies: VTSM-CLI-045
    #[test]
    fn damaged_storage_files_never_panic(
        cut in 0usize..2400,
        edits in proptest::collection::vec((0usize..2400, any::<u8>()), 0..6),
        drop_line in proptest::option::of(0usize..50),
    ) {
        let text = std::fs::read_to_string(examples().join("opencv-storage/stereo.yml")).unwrap();
        let bytes = crate::io::damaged(&text, cut, &edits, drop_line);
        if let Ok(c) = parse_storage_file(&bytes, Path::new("stereo.yml")) {
            prop_assert!(c.validate().is_ok());
        }
    }

    /// The same for the XML form.
    ///
    /// Verifies: VTSM-CLI-045
    #[test]
    fn damaged_storage_xml_never_panics(
        cut in 0usize..2400,
        edits in proptest::collection::vec((0usize..2400, any::<u8>()), 0..6),
        drop_line in proptest::option::of(0usize..50),
    ) {
        let text = std::fs::read_to_string(examples().join("opencv-storage/stereo.xml")).unwrap();
        let bytes = crate::io::damaged(&text, cut, &edits, drop_line);
        if let Ok(c) = parse_storage_file(&bytes, Path::new("stereo.xml")) {
            prop_assert!(c.validate().is_ok());
        }
    }
}
