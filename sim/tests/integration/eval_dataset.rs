//! `vtsm eval --suite dataset --data DIR`: a data set in the documented
//! layout is evaluated pair by pair, its shards merge like any campaign's,
//! a data set that breaks the layout is refused naming the file, and one
//! real photograph pair of `../shared/real/` relocalizes end to end.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, missing_docs)]

use crate::common::{dir, s, vtsm};
use std::path::{Path, PathBuf};

/// Export the test-profile scene of capture `stop` into `out`.
fn export(out: &Path, stop: &str) {
    let o = vtsm(&[
        "scene",
        "export",
        "--terrain",
        "flagstone",
        "--hours",
        "12.5",
        "--profile",
        "test",
        "--stop",
        stop,
        "--out",
        s(out),
    ]);
    assert_eq!(o.status.code(), Some(0), "{o:?}");
}

/// xz-compress `src` into `dst`.
fn xz(src: &Path, dst: &Path) {
    let bytes = std::fs::read(src).unwrap();
    let mut out = Vec::new();
    lzma_rs::xz_compress(&mut std::io::Cursor::new(bytes), &mut out).unwrap();
    std::fs::write(dst, out).unwrap();
}

/// A two-pair data set in the layout of `fsw-docs/interfaces/files.md`,
/// made from two exported captures of one depot: `map/` with the mesh
/// (xz-compressed), its MTL and texture and the mask; `views/s00/` and
/// `views/s07/` with their images, calibration, prior and truth.
fn make_dataset(root: &Path) -> PathBuf {
    let data = root.join("data");
    let map = data.join("map");
    std::fs::create_dir_all(&map).unwrap();
    for stop in ["0", "7"] {
        let e = root.join(format!("export{stop}"));
        export(&e, stop);
        let view = data.join("views").join(format!("s{stop:0>2}"));
        std::fs::create_dir_all(&view).unwrap();
        for f in [
            "left.png",
            "right.png",
            "calib.json",
            "prior.json",
            "truth.json",
        ] {
            std::fs::copy(e.join(f), view.join(f)).unwrap();
        }
        if stop == "0" {
            xz(&e.join("map.obj"), &map.join("map.obj.xz"));
            for f in ["map.mtl", "map_texture.png", "mask.obj"] {
                std::fs::copy(e.join(f), map.join(f)).unwrap();
            }
        }
    }
    data
}

/// The rows of `trials.csv` without its `time_s` column.
fn rows(path: &Path) -> Vec<Vec<String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let t = header.iter().position(|h| *h == "time_s").unwrap();
    text.lines()
        .map(|l| {
            let mut f: Vec<String> = l.split(',').map(str::to_string).collect();
            f.remove(t);
            f
        })
        .collect()
}

/// The value of column `name` in every data row of `trials.csv`.
fn column(path: &Path, name: &str) -> Vec<String> {
    let text = std::fs::read_to_string(path).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let c = header.iter().position(|h| *h == name).unwrap();
    text.lines()
        .skip(1)
        .map(|l| l.split(',').nth(c).unwrap().to_string())
        .collect()
}

fn eval_dataset(data: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "eval",
        "--suite",
        "dataset",
        "--data",
        s(data),
        "--trials",
        "2",
        "--seed",
        "3",
        "--quiet",
        "--out",
        s(out),
    ];
    args.extend_from_slice(extra);
    vtsm(&args)
}

/// Every pair of the data set is a group of `--trials` trials, VTSM and the
/// features baseline on the same trials, every VTSM trial within 5 cm of the
/// truth; the run records the data set's name and fingerprint, and writes
/// a panel per pair on request. Run as two shards and merged, it gives the
/// single run's `trials.csv` but `time_s`.
///
/// Verifies: VTSM-CLI-047
#[test]
fn dataset_suite_runs_every_pair_and_its_shards_merge() {
    let root = dir("eval_dataset", "suite");
    let data = make_dataset(&root);
    let full = root.join("full");
    let o = eval_dataset(&data, &full, &["--baseline", "features", "--panels"]);
    assert_eq!(o.status.code(), Some(0), "{o:?}");
    let csv = full.join("trials.csv");
    let groups = column(&csv, "group");
    assert_eq!(
        groups,
        [
            "s00",
            "s00",
            "s00 · features",
            "s00 · features",
            "s07",
            "s07",
            "s07 · features",
            "s07 · features"
        ]
    );
    let methods = column(&csv, "method");
    let success = column(&csv, "success");
    let err = column(&csv, "final_t_mm");
    for i in 0..groups.len() {
        if methods[i] == "vtsm" {
            assert_eq!(success[i], "true", "row {i}");
            let e: f64 = err[i].parse().unwrap();
            assert!(e < 50.0, "row {i}: {e} mm");
        }
    }
    assert_eq!(
        column(&csv, "pair"),
        ["0.0000", "0.0000", "0.0000", "0.0000", "1.0000", "1.0000", "1.0000", "1.0000"]
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(full.join("summary.json")).unwrap()).unwrap();
    let params = &summary["meta"]["params"];
    assert_eq!(params["data"], "data");
    assert_eq!(params["data_sha256"].as_str().unwrap().len(), 64);
    assert_eq!(params["map"], "map.obj.xz");
    assert_eq!(summary["meta"]["profile"], "data");
    for p in ["s00", "s07"] {
        let png = full.join("panels").join(format!("{p}.png"));
        assert!(std::fs::metadata(&png).unwrap().len() > 1000, "{png:?}");
    }
    assert!(full.join("final_vs_prior_error.png").exists());

    let (p0, p1, merged) = (root.join("p0"), root.join("p1"), root.join("merged"));
    for (k, p) in [("0/2", &p0), ("1/2", &p1)] {
        let o = eval_dataset(&data, p, &["--baseline", "features", "--shard", k]);
        assert_eq!(o.status.code(), Some(0), "{o:?}");
    }
    let o = vtsm(&["eval", "merge", "--out", s(&merged), s(&p1), s(&p0)]);
    assert_eq!(o.status.code(), Some(0), "{o:?}");
    assert_eq!(rows(&merged.join("trials.csv")), rows(&csv));
}

/// A data set that breaks the layout, or holds a bad file, is refused before
/// any trial runs: exit 2, one line naming the directory or file, and no
/// output directory left behind.
///
/// Verifies: VTSM-CLI-047
#[test]
fn a_bad_data_set_is_refused_naming_the_file() {
    let root = dir("eval_dataset", "bad");
    let good = make_dataset(&root);
    let copy = |name: &str| -> PathBuf {
        let d = root.join(name);
        let o = std::process::Command::new("cp")
            .args(["-r", s(&good), s(&d)])
            .output()
            .unwrap();
        assert!(o.status.success());
        d
    };
    type Break = (&'static str, fn(&Path), &'static str);
    let cases: [Break; 6] = [
        (
            "nomap",
            |d| std::fs::remove_file(d.join("map/map.obj.xz")).unwrap(),
            "holds no map",
        ),
        (
            "twomeshes",
            |d| {
                std::fs::copy(d.join("map/mask.obj"), d.join("map/other.obj"))
                    .map(|_| ())
                    .unwrap()
            },
            "holds 2 mesh files",
        ),
        (
            "noprior",
            |d| std::fs::remove_file(d.join("views/s07/prior.json")).unwrap(),
            "has no prior file",
        ),
        (
            "badcalib",
            |d| std::fs::write(d.join("views/s00/calib.json"), "{ \"fx\": ").unwrap(),
            "calib.json",
        ),
        (
            "smallimage",
            |d| {
                let img = image::GrayImage::new(64, 32);
                img.save(d.join("views/s07/right.png")).unwrap();
            },
            "is 64×32; its calibration",
        ),
        (
            "badxz",
            |d| std::fs::write(d.join("map/map.obj.xz"), b"not xz at all").unwrap(),
            "not a valid xz file",
        ),
    ];
    for (name, brk, why) in cases {
        let d = copy(name);
        brk(&d);
        let out = root.join(format!("out_{name}"));
        let o = eval_dataset(&d, &out, &[]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{name}: {err}");
        assert_eq!(err.lines().count(), 1, "{name}: {err}");
        assert!(err.contains(why), "{name}: {err}");
        assert!(!out.exists(), "{name}: output directory left behind");
    }
}

/// The real-photograph data set of `../shared/real/` (or `$VTSM_REAL_DATA`),
/// when present.
fn real_data() -> Option<PathBuf> {
    let d = std::env::var_os("VTSM_REAL_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/real/herz-jesus-p8")
        });
    d.join("views").is_dir().then_some(d)
}

/// One real stereo pair (two photographs of a church facade never seen by
/// the map, an OpenCV calibration, a prior 35–50 cm off stating its
/// uncertainty) against a photogrammetry map (an xz-compressed OBJ of 1.5 M
/// triangles, frame with its vertical axis down), through the data-set
/// suite end to end: within 5 cm of the ground truth. Skipped, with a
/// message, where the data set is not there (a clone without `../shared`).
///
/// Verifies: VTSM-CLI-047
#[test]
fn one_real_photograph_pair_relocalizes_within_5_cm() {
    let Some(real) = real_data() else {
        eprintln!(
            "skipped: no real data set at ../shared/real/herz-jesus-p8 (set VTSM_REAL_DATA to one in the same layout)"
        );
        return;
    };
    let root = dir("eval_dataset", "real");
    // The data set with one pair: its map and that pair's files, linked.
    let data = root.join("one-pair");
    let link = |from: &Path, to: &Path| std::os::unix::fs::symlink(from, to).unwrap();
    std::fs::create_dir_all(data.join("views")).unwrap();
    link(&real.join("map").canonicalize().unwrap(), &data.join("map"));
    let view = real.join("views/L03-R05_far").canonicalize().unwrap();
    link(&view, &data.join("views/L03-R05_far"));
    let out = root.join("out");
    let o = vtsm(&[
        "eval",
        "--suite",
        "dataset",
        "--data",
        s(&data),
        "--trials",
        "1",
        "--quiet",
        "--out",
        s(&out),
    ]);
    assert_eq!(o.status.code(), Some(0), "{o:?}");
    let csv = out.join("trials.csv");
    assert_eq!(column(&csv, "success"), ["true"]);
    let e: f64 = column(&csv, "final_t_mm")[0].parse().unwrap();
    let e0: f64 = column(&csv, "init_t_mm")[0].parse().unwrap();
    assert!(e < 50.0, "final error {e} mm");
    assert!(e0 > 300.0, "the far prior is {e0} mm off");
}
