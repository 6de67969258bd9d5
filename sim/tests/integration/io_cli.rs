//! `vtsm map build` and `vtsm relocalize` input handling, and the upset
//! checks of `--verify` end to end (`vtsm relocalize` on an exported
//! test-profile scene, `vtsm demo`, `vtsm eval`), through the binary.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, missing_docs)]

use std::path::{Path, PathBuf};
use vtsm_core::map::MapView;
use vtsm_sim::io::image::{write_png, Gray8};

use crate::common::{s, vtsm};

fn dir(name: &str) -> PathBuf {
    crate::common::dir("io_cli", name)
}

/// A 3x3-vertex textured patch and a mask holding two of its eight triangles.
fn scene(d: &Path) -> (PathBuf, PathBuf) {
    let tex = Gray8 {
        width: 4,
        height: 4,
        pixels: (0..16).map(|v| v * 16).collect(),
    };
    write_png(&d.join("t.png"), &tex, true).unwrap();
    std::fs::write(d.join("m.mtl"), "newmtl g\nmap_Kd t.png\n").unwrap();
    let mut obj = String::from("mtllib m.mtl\nusemtl g\n");
    for j in 0..3 {
        for i in 0..3 {
            obj += &format!(
                "v {} {} {}\nvt {} {}\n",
                i,
                j,
                (i * j) as f32 * 0.1,
                i as f32 / 2.0,
                j as f32 / 2.0
            );
        }
    }
    for j in 0..2 {
        for i in 0..2 {
            let a = j * 3 + i + 1;
            obj += &format!(
                "f {a}/{a} {b}/{b} {c}/{c}\nf {a}/{a} {c}/{c} {d}/{d}\n",
                b = a + 1,
                c = a + 4,
                d = a + 3
            );
        }
    }
    let mesh = d.join("m.obj");
    std::fs::write(&mesh, obj).unwrap();
    // mask: triangles (1,2,5) and (5,6,9) of the mesh, written with other numbering
    let mask = d.join("k.obj");
    std::fs::write(
        &mask,
        "v 1 1 0.1\nv 0 0 0\nv 1 0 0\nv 2 1 0.2\nv 2 2 0.4\nf 3 1 2\nf 1 4 5\n",
    )
    .unwrap();
    (mesh, mask)
}

fn no_temp_files(d: &Path) -> bool {
    std::fs::read_dir(d)
        .unwrap()
        .all(|e| !e.unwrap().file_name().to_string_lossy().contains(".tmp."))
}

/// Verifies: VTSM-CLI-010, VTSM-CLI-011, VTSM-CLI-012, VTSM-SIM-021
#[test]
fn map_build_writes_a_valid_product_and_refuses_to_overwrite() {
    let d = dir("build");
    let (mesh, mask) = scene(&d);
    let out = d.join("d.vmap");
    let o = vtsm(&[
        "map",
        "build",
        "--mesh",
        s(&mesh),
        "--mask",
        s(&mask),
        "--out",
        s(&out),
    ]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let bytes = std::fs::read(&out).unwrap();
    let map = MapView::new_checked(&bytes).unwrap();
    assert_eq!((map.vertex_count(), map.triangle_count()), (9, 8));
    let masked: Vec<[u32; 3]> = (0..8)
        .map(|i| map.triangle(i).unwrap())
        .filter(|t| t.mask)
        .map(|t| {
            let mut v = t.v;
            v.sort_unstable();
            v
        })
        .collect();
    let mut masked = masked;
    masked.sort_unstable();
    assert_eq!(masked, vec![[0, 1, 4], [4, 5, 8]]);

    // Second run without --force: exit 2, one line on stderr, file untouched.
    std::fs::write(&out, b"keep me").unwrap();
    let o = vtsm(&["map", "build", "--mesh", s(&mesh), "--out", s(&out)]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("--force") && err.contains("d.vmap"), "{err}");
    assert_eq!(std::fs::read(&out).unwrap(), b"keep me");
    let o = vtsm(&[
        "map",
        "build",
        "--mesh",
        s(&mesh),
        "--out",
        s(&out),
        "--force",
    ]);
    assert_eq!(o.status.code(), Some(0));
    let unscored = std::fs::read(&out).unwrap();
    let v2 = MapView::new_checked(&unscored).unwrap();
    assert_eq!((v2.version(), v2.scored()), (2, false));

    // With scores: a version-3 product with the same content, one score per
    // mask vertex, each drawable (the floor is 1).
    let o = vtsm(&[
        "map",
        "build",
        "--mesh",
        s(&mesh),
        "--out",
        s(&out),
        "--force",
        "--map-scores",
        "on",
    ]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(String::from_utf8_lossy(&o.stdout).contains("scored"));
    let scored = std::fs::read(&out).unwrap();
    let v3 = MapView::new_checked(&scored).unwrap();
    assert_eq!((v3.version(), v3.scored()), (3, true));
    assert_eq!(v3.mask_vertex_count(), v2.mask_vertex_count());
    assert_eq!(v3.texture_bytes(), v2.texture_bytes());
    for k in 0..v3.mask_vertex_count() {
        assert_eq!(v3.mask_vertex(k), v2.mask_vertex(k));
        assert!(v3.mask_score(k).is_some_and(|s| s >= 1), "mask vertex {k}");
    }
    assert!(no_temp_files(&d));
}

/// Verifies: VTSM-CLI-009, VTSM-CLI-008
#[test]
fn map_build_bad_input_exits_2_and_writes_nothing() {
    let d = dir("bad");
    let (mesh, _) = scene(&d);
    let good = std::fs::read_to_string(&mesh).unwrap();
    let out = d.join("d.vmap");
    let bad = d.join("bad.obj");
    let cases: Vec<(String, &str)> = vec![
        (good.replacen("v 1 0 0", "v 1 nan 0", 1), "bad.obj:5:"),
        (
            good.replacen("f 1/1 2/2 5/5", "f 1/1 2/2 50/5", 1),
            "bad.obj:21:",
        ),
        (good.replace("m.mtl", "gone.mtl"), "bad.obj:1:"),
        (good.replace("usemtl g", "usemtl h"), "bad.obj:2:"),
    ];
    for (text, want) in cases {
        std::fs::write(&bad, text).unwrap();
        let o = vtsm(&["map", "build", "--mesh", s(&bad), "--out", s(&out)]);
        assert_eq!(o.status.code(), Some(2));
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.contains(want), "{want}: {err}");
        assert!(!out.exists());
    }
    for args in [
        vec!["--mesh", s(&mesh), "--mask", "/nonexistent/k.obj"],
        vec!["--mesh", s(&mesh), "--tile-size-m", "0"],
        vec!["--mesh", "/nonexistent/m.stl"],
    ] {
        let mut a = vec!["map", "build", "--out", s(&out)];
        a.extend(args);
        let o = vtsm(&a);
        assert_eq!(o.status.code(), Some(2), "{a:?}");
        assert!(!out.exists());
    }
    assert!(no_temp_files(&d));
}

/// Run `vtsm map build` with `extra` arguments: exit 2, one stderr line holding
/// every string of `want`, no output and no temporary file.
fn build_refused(d: &Path, mesh: &Path, extra: &[&str], want: &[&str]) {
    let out = d.join("d.vmap");
    let mut a = vec!["map", "build", "--mesh", s(mesh), "--out", s(&out)];
    a.extend_from_slice(extra);
    let o = vtsm(&a);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{a:?}: {err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    for w in want {
        assert!(err.contains(w), "{w}: {err}");
    }
    assert!(!out.exists());
    assert!(no_temp_files(d));
}

/// Verifies: VTSM-CLI-024, VTSM-CLI-011
#[test]
fn map_build_refuses_flat_meshes_stray_mask_triangles_and_tiny_tiles() {
    let d = dir("refuse");
    let (mesh, mask) = scene(&d);
    // Every vertex on one line: all eight triangles have zero area.
    let good = std::fs::read_to_string(&mesh).unwrap();
    let mut flat = String::new();
    let mut k = 0;
    for line in good.lines() {
        if line.starts_with("v ") {
            flat += &format!("v {k} 0 0\n");
            k += 1;
        } else {
            flat += line;
            flat += "\n";
        }
    }
    let flat_obj = d.join("flat.obj");
    std::fs::write(&flat_obj, flat).unwrap();
    build_refused(
        &d,
        &flat_obj,
        &[],
        &["flat.obj", "zero area", "MAP_NO_SURFACE"],
    );
    // A mask triangle that is not in the mesh: the third one, (1,1)-(2,1)-(0,2)
    // uses mesh vertices but is not a mesh triangle; the fourth has a vertex the
    // mesh lacks.
    let stray = d.join("stray.obj");
    let text = std::fs::read_to_string(&mask).unwrap();
    std::fs::write(&stray, format!("{text}v 0 2 0\nf 1 4 6\n")).unwrap();
    build_refused(
        &d,
        &mesh,
        &["--mask", s(&stray)],
        &["stray.obj", "mask triangle 3", "not a triangle of the mesh"],
    );
    let stray2 = d.join("stray2.obj");
    std::fs::write(&stray2, format!("{text}v 7 7 7\nf 1 4 6\n")).unwrap();
    build_refused(
        &d,
        &mesh,
        &["--mask", s(&stray2)],
        &["stray2.obj", "mask triangle 3", "vertex 6 at (7, 7, 7)"],
    );
    // A tile size so small that the grid is above MAX_MAP_TILES: named, with its code.
    build_refused(
        &d,
        &mesh,
        &["--tile-size-m", "1e-9"],
        &[
            "tile size 0.000000001 m",
            "MAP_TILE_SIZE_OUT_OF_RANGE",
            "--tile-size-m",
        ],
    );
    // The unchanged mask and a normal tile size still build.
    let out = d.join("d.vmap");
    let o = vtsm(&[
        "map",
        "build",
        "--mesh",
        s(&mesh),
        "--mask",
        s(&mask),
        "--out",
        s(&out),
    ]);
    assert_eq!(o.status.code(), Some(0));
}

/// Verifies: VTSM-CLI-009, VTSM-CLI-013, VTSM-CLI-024, VTSM-CLI-041
#[test]
fn relocalize_rejects_bad_inputs_before_writing_anything() {
    let d = dir("reloc");
    let (mesh, _) = scene(&d);
    let map = d.join("d.vmap");
    assert_eq!(
        vtsm(&["map", "build", "--mesh", s(&mesh), "--out", s(&map)])
            .status
            .code(),
        Some(0)
    );
    let calib = d.join("calib.json");
    std::fs::write(
        &calib,
        r#"{"width":32,"height":24,"fx":30,"fy":30,"cx":15.5,"cy":11.5,"baseline_m":0.4}"#,
    )
    .unwrap();
    let prior = d.join("prior.json");
    std::fs::write(&prior, r#"{"world_from_left":{"t":[1,1,2],"q":[1,0,0,0]}}"#).unwrap();
    let left = d.join("l.png");
    let right = d.join("r.png");
    write_png(&left, &Gray8::filled(32, 24, 100), true).unwrap();
    write_png(&right, &Gray8::filled(32, 24, 100), true).unwrap();
    let small = d.join("small.png");
    write_png(&small, &Gray8::filled(32, 23, 100), true).unwrap();
    let tilted = d.join("tilted.json");
    std::fs::write(
        &tilted,
        r#"{"world_from_left":{"t":[1,1,2],"q":[1,0.1,0,0]}}"#,
    )
    .unwrap();
    let wide = d.join("wide.json");
    std::fs::write(
        &wide,
        r#"{"world_from_left":{"t":[1,1,2],"q":[1,0,0,0]},"uncertainty":{"t_m":0.5,"r_deg":45}}"#,
    )
    .unwrap();
    let extra_key = d.join("extra_key.json");
    std::fs::write(
        &extra_key,
        r#"{"world_from_left":{"t":[1,1,2],"q":[1,0,0,0]},"uncertainty":{"t_m":0.5,"r_deg":1.5,"sigma":1}}"#,
    )
    .unwrap();
    let huge_fx = d.join("huge_fx.json");
    std::fs::write(
        &huge_fx,
        r#"{"width":32,"height":24,"fx":1e300,"fy":30,"cx":15.5,"cy":11.5,"baseline_m":0.4}"#,
    )
    .unwrap();
    // A product edited on purpose and resealed (valid CRCs) with a UV of 1e30.
    let mut far_uv = std::fs::read(&map).unwrap();
    let uv_off = u32::from_le_bytes(far_uv[76 + 36..76 + 40].try_into().unwrap()) as usize;
    far_uv[uv_off + 4..uv_off + 8].copy_from_slice(&1.0e30f32.to_le_bytes());
    vtsm_core::map::reseal(&mut far_uv).unwrap();
    let far_uv_map = d.join("far_uv.vmap");
    std::fs::write(&far_uv_map, far_uv).unwrap();
    let mut corrupt = std::fs::read(&map).unwrap();
    let last = corrupt.len() - 1;
    corrupt[last] ^= 0x55;
    let bad_map = d.join("bad.vmap");
    std::fs::write(&bad_map, corrupt).unwrap();
    let out = d.join("result.json");

    let base = |l: &Path, r: &Path, p: &Path, m: &Path| -> Vec<String> {
        [
            "relocalize",
            "--map",
            s(m),
            "--calib",
            s(&calib),
            "--left",
            s(l),
            "--right",
            s(r),
            "--prior",
            s(p),
            "--out",
            s(&out),
        ]
        .iter()
        .map(|a| a.to_string())
        .collect()
    };
    let with_calib = |c: &Path| -> Vec<String> {
        let mut a = base(&left, &right, &prior, &map);
        a[4] = s(c).to_string();
        a
    };
    let with_mask = {
        let mut a = base(&left, &right, &prior, &map);
        a.extend(["--mask".to_string(), s(&mesh).to_string()]);
        a
    };
    let with_scores = {
        let mut a = base(&left, &right, &prior, &map);
        a.extend(["--map-scores".to_string(), "on".to_string()]);
        a
    };
    let cases = [
        (base(&left, &small, &prior, &map), "small.png", "32x23"),
        (with_calib(&huge_fx), "huge_fx.json", "`fx`: 1e300 px"),
        (with_mask, "m.obj", "--mask needs --mesh"),
        (with_scores, "--map-scores on", "needs --mesh"),
        (
            base(&left, &right, &prior, &far_uv_map),
            "far_uv.vmap",
            "MAP_UV_OUT_OF_RANGE",
        ),
        (base(&left, &right, &tilted, &map), "tilted.json", "norm"),
        (
            base(&left, &right, &wide, &map),
            "wide.json:1",
            "`uncertainty.r_deg`: 45 deg is outside the accepted range (0, 20] deg",
        ),
        (
            base(&left, &right, &extra_key, &map),
            "extra_key.json:1",
            "unknown field `sigma`, expected `t_m` or `r_deg`",
        ),
        (
            base(&left, &right, &prior, &bad_map),
            "bad.vmap",
            "MAP_CRC_MISMATCH",
        ),
        (
            base(&left, Path::new("/nonexistent/r.png"), &prior, &map),
            "r.png",
            "no such file",
        ),
    ];
    for (args, file, what) in cases {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = vtsm(&a);
        assert_eq!(o.status.code(), Some(2));
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(
            err.contains(file) && err.contains(what),
            "{file} {what}: {err}"
        );
        assert!(!out.exists());
    }
    // --mesh and --map together is a usage error (clap's exit code is 2 as well).
    let o = vtsm(&[
        "relocalize",
        "--mesh",
        s(&mesh),
        "--map",
        s(&map),
        "--calib",
        s(&calib),
        "--left",
        s(&left),
        "--right",
        s(&right),
        "--prior",
        s(&prior),
    ]);
    assert_eq!(o.status.code(), Some(2));
}

/// Verifies: VTSM-CLI-014
#[test]
fn budget_prints_the_config_capacities() {
    let o = vtsm(&["budget", "--json"]);
    assert_eq!(o.status.code(), Some(0));
    let text = String::from_utf8_lossy(&o.stdout);
    let rows: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let get = |item: &str| {
        rows.iter()
            .find(|r| r["item"] == item)
            .map(|r| r["value"].as_u64().unwrap())
    };
    use vtsm_core::config as c;
    assert_eq!(get("MAX_TEMPLATE_PX"), Some(c::MAX_TEMPLATE_PX as u64));
    assert_eq!(get("MAX_SEARCH_PX"), Some(c::MAX_SEARCH_PX as u64));
    assert_eq!(get("MAX_CORR"), Some(c::MAX_CORR as u64));
    assert_eq!(
        get("template, MAX_TEMPLATE_PX² u8"),
        Some((c::MAX_TEMPLATE_PX * c::MAX_TEMPLATE_PX) as u64)
    );
}

// ---- --verify ------------------------------------------------------------------

/// A test-profile Flagstone scene (the one of `tests/tests/integration/e2e_file_path.rs`)
/// written by `vtsm scene export`, and its map product built by
/// `vtsm map build`, in the test directory `name`.
fn exported(name: &str) -> PathBuf {
    let dir = dir(name);
    let run = |args: &[&str]| {
        let o = vtsm(args);
        assert_eq!(o.status.code(), Some(0), "{args:?}: {o:?}");
    };
    run(&[
        "scene",
        "export",
        "--terrain",
        "flagstone",
        "--hours",
        "am",
        "--profile",
        "test",
        "--seed",
        "3",
        "--stop",
        "3",
        "--out",
        s(&dir),
    ]);
    run(&[
        "map",
        "build",
        "--mesh",
        s(&dir.join("map.obj")),
        "--mask",
        s(&dir.join("mask.obj")),
        "--out",
        s(&dir.join("d.vmap")),
    ]);
    dir
}

/// The arguments of `vtsm relocalize` on the exported scene, writing `out`.
fn relocalize_args(dir: &Path, out: &Path) -> Vec<String> {
    let file = |name: &str| dir.join(name).display().to_string();
    [
        "relocalize",
        "--map",
        &file("d.vmap"),
        "--calib",
        &file("calib.json"),
        "--left",
        &file("left.png"),
        "--right",
        &file("right.png"),
        "--prior",
        &file("prior.json"),
        "--seed",
        "3",
        "--out",
        s(out),
    ]
    .map(str::to_string)
    .to_vec()
}

/// `vtsm relocalize` on the exported scene with `extra` arguments, writing
/// `out`; the exit code and the parsed result.
fn relocalize(dir: &Path, out: &Path, extra: &[&str]) -> (Option<i32>, serde_json::Value) {
    let mut args = relocalize_args(dir, out);
    args.extend(extra.iter().map(|a| a.to_string()));
    let o = vtsm(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let text = std::fs::read_to_string(out)
        .unwrap_or_else(|e| panic!("{} not written ({e}): {o:?}", out.display()));
    (o.status.code(), serde_json::from_str(&text).unwrap())
}

fn verified(r: &serde_json::Value) -> (bool, bool) {
    let v = &r["verified"];
    (
        v["repeat_solve"].as_bool().unwrap(),
        v["recheck_map"].as_bool().unwrap(),
    )
}

/// `vtsm relocalize --verify` succeeds on a scene it relocalizes and says in
/// `result.json` that both checks ran; `--verify map` runs the re-check
/// alone; without `--verify` neither runs; the pose is the same in all three.
/// An unknown check is bad input: exit 2, nothing written.
///
/// Verifies: VTSM-CLI-039
#[test]
fn relocalize_verify_runs_the_checks_and_says_so() {
    let dir = exported("verify_scene");
    let (code, both) = relocalize(&dir, &dir.join("both.json"), &["--verify"]);
    println!("{both}");
    assert_eq!(code, Some(0));
    assert_eq!(both["status"], "ok");
    assert!(both["failure"].is_null());
    assert_eq!(verified(&both), (true, true));
    assert!(both["stats"]["verify_units"].as_u64().unwrap() >= 1);

    let (code, map_only) = relocalize(&dir, &dir.join("map.json"), &["--verify", "map"]);
    assert_eq!(code, Some(0));
    assert_eq!(verified(&map_only), (false, true));

    let (code, plain) = relocalize(&dir, &dir.join("plain.json"), &[]);
    assert_eq!(code, Some(0));
    assert_eq!(verified(&plain), (false, false));
    assert_eq!(plain["stats"]["verify_units"], 0);
    for r in [&map_only, &plain] {
        assert_eq!(r["world_from_left"], both["world_from_left"]);
        assert_eq!(r["inliers"], both["inliers"]);
    }

    let bad = dir.join("bad.json");
    let mut args = relocalize_args(&dir, &bad);
    args.extend(["--verify".to_string(), "repeat,crc".to_string()]);
    let o = vtsm(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("unknown check `crc`"), "{err}");
    assert!(!bad.exists());
}

/// `vtsm demo --verify` relocalizes its test-profile scene, reports the
/// checks and writes a `result.json` that says both ran.
///
/// Verifies: VTSM-CLI-039
#[test]
fn demo_verify_echoes_the_checks() {
    let out = dir("verify_demo");
    let o = vtsm(&[
        "demo",
        "--profile",
        "test",
        "--seed",
        "3",
        "--verify",
        "--out",
        s(&out),
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    println!("{stdout}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("result.json")).unwrap()).unwrap();
    assert_eq!(o.status.code(), Some(0), "{stdout}");
    assert_eq!(r["status"], "ok");
    assert_eq!(verified(&r), (true, true));
    assert!(r["stats"]["verify_units"].as_u64().unwrap() >= 1, "{r}");
    assert!(
        stdout.contains("upset checks: repeated solve ran"),
        "{stdout}"
    );
}

/// `vtsm eval --verify` runs every VTSM trial with both checks, records them
/// in `summary.json`'s parameters and says per trial which ran; without it
/// the trials carry no such columns.
///
/// Verifies: VTSM-CLI-039
#[test]
fn eval_verify_records_the_checks_per_trial() {
    let run = |name: &str, extra: &[&str]| -> serde_json::Value {
        let out = dir(name);
        let mut args = vec![
            "eval",
            "--suite",
            "paper",
            "--profile",
            "test",
            "--trials",
            "1",
            "--terrains",
            "flagstone",
            "--hours",
            "0",
            "--quiet",
            "--out",
            s(&out),
        ];
        args.extend_from_slice(extra);
        let o = vtsm(&args);
        assert_eq!(o.status.code(), Some(0), "{o:?}");
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
    };
    let checked = run("verify_eval", &["--verify"]);
    let v = &checked["meta"]["params"]["verify"];
    assert_eq!(
        (v["repeat_solve"].as_bool(), v["recheck_map"].as_bool()),
        (Some(true), Some(true))
    );
    let t = &checked["trials"][0];
    assert_eq!(t["success"], true, "{t}");
    assert_eq!(t["extra"]["verify_repeat_solve"], 1.0);
    assert_eq!(t["extra"]["verify_recheck_map"], 1.0);

    let plain = run("verify_eval_plain", &[]);
    let v = &plain["meta"]["params"]["verify"];
    assert_eq!(
        (v["repeat_solve"].as_bool(), v["recheck_map"].as_bool()),
        (Some(false), Some(false))
    );
    assert!(plain["trials"][0]["extra"]
        .get("verify_repeat_solve")
        .is_none());
    assert_eq!(plain["trials"][0]["final_t_mm"], t["final_t_mm"]);
}

// ---- --pairs with every calibration form ------------------------------------

/// `vtsm relocalize --pairs` reads `--calib` with the same reader as a single
/// pair: in every form (rectified, OpenCV, ROS camera_info, Kalibr, the
/// FileStorage form and a FileStorage YAML or XML file given itself) the batch
/// is accepted and its one pair fails alone, on its missing image (exit 1, an
/// `"error"` line naming the image), not the batch on its calibration (exit 2).
///
/// Verifies: VTSM-CLI-038, VTSM-CLI-043, VTSM-CLI-044, VTSM-CLI-045
#[test]
fn pairs_batch_accepts_every_calibration_form() {
    let d = dir("pairs_calib");
    let (mesh, _) = scene(&d);
    let rectified = d.join("calib.json");
    std::fs::write(
        &rectified,
        r#"{"width":32,"height":24,"fx":30,"fy":30,"cx":15.5,"cy":11.5,"baseline_m":0.4}"#,
    )
    .unwrap();
    std::fs::write(
        d.join("prior.json"),
        r#"{"world_from_left":{"t":[1,1,2],"q":[1,0,0,0]}}"#,
    )
    .unwrap();
    let pairs = d.join("pairs.jsonl");
    std::fs::write(
        &pairs,
        "{\"left\": \"missing.png\", \"right\": \"missing.png\", \"prior\": \"prior.json\"}\n",
    )
    .unwrap();
    let ex = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fsw-docs/interfaces/examples");
    let forms = [
        rectified,
        ex.join("calib-opencv.json"),
        ex.join("ros/calib.json"),
        ex.join("kalibr/calib.json"),
        ex.join("opencv-storage/calib.json"),
        ex.join("opencv-storage/stereo.yml"),
        ex.join("opencv-storage/stereo.xml"),
    ];
    for calib in &forms {
        let o = vtsm(&[
            "relocalize",
            "--mesh",
            s(&mesh),
            "--calib",
            s(calib),
            "--pairs",
            s(&pairs),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{}: {err}", calib.display());
        let stdout = String::from_utf8(o.stdout).unwrap();
        let lines: Vec<serde_json::Value> = stdout
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(lines.len(), 1, "{}: {stdout}", calib.display());
        assert_eq!(lines[0]["status"], "error", "{}", calib.display());
        let message = lines[0]["message"].as_str().unwrap();
        assert!(
            message.contains("missing.png"),
            "{}: {message}",
            calib.display()
        );
    }
}

/// `--threads N` changes nothing in `result.json`: `vtsm relocalize` on 1,
/// 2 and 3 threads and with the default (here `RAYON_NUM_THREADS=2`) writes
/// the same bytes; `vtsm demo` says how many threads it used. `--threads 0`
/// is bad input: exit 2, nothing written.
///
/// Verifies: VTSM-CLI-049
#[test]
fn threads_give_the_same_result_bytes() {
    let dir = exported("threads_scene");
    let read = |p: &Path| std::fs::read(p).unwrap();
    let (code, one) = relocalize(&dir, &dir.join("t1.json"), &["--threads", "1"]);
    assert_eq!(code, Some(0));
    assert_eq!(one["status"], "ok");
    for n in ["2", "3"] {
        let out = dir.join(format!("t{n}.json"));
        let (code, _) = relocalize(&dir, &out, &["--threads", n]);
        assert_eq!(code, Some(0));
        assert_eq!(read(&out), read(&dir.join("t1.json")), "{n} threads");
    }
    let env = dir.join("tenv.json");
    let args = relocalize_args(&dir, &env);
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_vtsm"))
        .args(&args)
        .env("RAYON_NUM_THREADS", "2")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{o:?}");
    assert_eq!(read(&env), read(&dir.join("t1.json")));

    let bad = dir.join("t0.json");
    let mut args = relocalize_args(&dir, &bad);
    args.extend(["--threads".to_string(), "0".to_string()]);
    let o = vtsm(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(2));
    assert!(!bad.exists());

    let out = dir.join("demo-threads");
    let o = vtsm(&[
        "demo",
        "--profile",
        "test",
        "--seed",
        "3",
        "--threads",
        "2",
        "--out",
        s(&out),
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{stdout}");
    assert!(
        stdout.contains("(2 threads, ") && stdout.contains(" attempts dropped as stale)"),
        "{stdout}"
    );
}

// ---- --change and --camera ---------------------------------------------------

/// `vtsm scene export --change ... --camera ...` writes what it was asked for
/// into `scene.json`, images that differ from the unchanged export and the
/// same map; a spec out of range exits 2 and writes nothing.
///
/// Verifies: VTSM-SIM-018, VTSM-SIM-020
#[test]
fn scene_export_writes_a_changed_depot_through_another_camera() {
    let export = |name: &str, extra: &[&str]| {
        let d = dir(name);
        let mut args = vec![
            "scene",
            "export",
            "--terrain",
            "cfa6",
            "--hours",
            "am",
            "--profile",
            "test",
            "--seed",
            "3",
            "--out",
            s(&d),
        ];
        args.extend_from_slice(extra);
        (d.clone(), vtsm(&args))
    };
    let (plain, o) = export("export_plain", &[]);
    assert_eq!(o.status.code(), Some(0), "{o:?}");
    let (changed, o) = export(
        "export_changed",
        &[
            "--change",
            "tracks=2,rocks=0.3",
            "--camera",
            "noise=4,jpeg=60",
        ],
    );
    assert_eq!(o.status.code(), Some(0), "{o:?}");
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(changed.join("scene.json")).unwrap()).unwrap();
    assert_eq!(meta["change"], "tracks=2,rocks=0.3");
    assert_eq!(meta["camera"], "noise=4,jpeg=60");
    let read = |d: &Path, f: &str| std::fs::read(d.join(f)).unwrap();
    assert_ne!(read(&plain, "left.png"), read(&changed, "left.png"));
    assert_eq!(read(&plain, "map.obj"), read(&changed, "map.obj"));
    for (flag, bad) in [("--change", "rocks=2"), ("--camera", "jpeg=101")] {
        let (d, o) = export("export_bad", &[flag, bad]);
        assert_eq!(o.status.code(), Some(2), "{flag} {bad}: {o:?}");
        assert!(!d.join("left.png").exists());
    }
}
