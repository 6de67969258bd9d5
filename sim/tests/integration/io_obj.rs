//! OBJ / MTL reader, mask matching and the mesh → map product round trip.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, missing_docs)]

use proptest::prelude::*;
use std::path::{Path, PathBuf};
use vtsm_core::map::MapView;
use vtsm_sim::io::image::{write_png, Gray8};
use vtsm_sim::io::mesh::{self, MeshData};
use vtsm_sim::io::obj;

fn dir(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("io_obj_{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn texture(w: u32, h: u32) -> Gray8 {
    let mut t = Gray8::filled(w, h, 0);
    for y in 0..h {
        for x in 0..w {
            t.pixels[(y * w + x) as usize] = ((x * 13 + y * 7) % 256) as u8;
        }
    }
    t
}

/// A textured depot-like grid written by hand: vertices, per-vertex vt, faces `a/b`.
fn write_grid(d: &Path, nx: usize, ny: usize) -> (PathBuf, Vec<[f32; 3]>, Gray8) {
    let tex = texture(16, 8);
    write_png(&d.join("tex.png"), &tex, true).unwrap();
    std::fs::write(d.join("m.mtl"), "newmtl ground\nKd 1 1 1\nmap_Kd tex.png\n").unwrap();
    let mut s = String::from("# grid\nmtllib m.mtl\nusemtl ground\n");
    let mut verts = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let (x, y) = (i as f32 * 0.25, j as f32 * 0.25);
            let z = 0.1 * (x * 3.0).sin() * (y * 2.0).cos();
            verts.push([x, y, z]);
            s += &format!("v {x} {y} {z}\n");
            s += &format!(
                "vt {} {}\n",
                i as f32 / (nx - 1) as f32,
                j as f32 / (ny - 1) as f32
            );
        }
    }
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let a = j * nx + i + 1;
            let (b, c, dd) = (a + 1, a + nx + 1, a + nx);
            s += &format!("f {a}/{a} {b}/{b} {c}/{c}\nf {a}/{a} {c}/{c} {dd}/{dd}\n");
        }
    }
    let p = d.join("m.obj");
    std::fs::write(&p, s).unwrap();
    (p, verts, tex)
}

/// Verifies: VTSM-CLI-001, VTSM-CLI-002, VTSM-CLI-012
#[test]
fn textured_obj_round_trips_through_the_map_product() {
    let d = dir("roundtrip");
    let (nx, ny) = (6, 5);
    let (p, verts, tex) = write_grid(&d, nx, ny);
    let m = mesh::load_mesh(&p).unwrap();
    // Vertices are local to the map origin (the box centre rounded to metres).
    assert_eq!(m.vertices.len(), verts.len());
    for (a, b) in m.vertices.iter().zip(&verts) {
        let user = [0, 1, 2].map(|k| f64::from(a[k]) + m.origin[k]);
        assert!(
            user.iter()
                .zip(b)
                .all(|(x, y)| (x - f64::from(*y)).abs() <= 1e-6),
            "{user:?} {b:?}"
        );
    }
    assert_eq!(m.triangles.len(), 2 * (nx - 1) * (ny - 1));
    assert_eq!(m.texture, tex);
    assert!(m.mask.iter().all(|&b| b));
    // uv of each corner is the vertex's grid fraction
    for (t, uv) in m.triangles.iter().zip(&m.uvs) {
        for (&v, c) in t.iter().zip(uv) {
            let (i, j) = (v as usize % nx, v as usize / nx);
            assert!((c[0] - i as f32 / (nx - 1) as f32).abs() < 1e-6);
            assert!((c[1] - j as f32 / (ny - 1) as f32).abs() < 1e-6);
        }
    }

    let bytes = m.encode_map(0.5).unwrap();
    let map = MapView::new_checked(&bytes).unwrap();
    assert_eq!(map.vertex_count() as usize, verts.len());
    assert_eq!(map.triangle_count() as usize, m.triangles.len());
    // The product holds the mesh's local vertices and its origin.
    assert_eq!(map.origin(), m.origin);
    for (i, v) in m.vertices.iter().enumerate() {
        let got = map.vertex(i as u32).unwrap();
        assert_eq!([got.x, got.y, got.z], *v);
    }
    // Triangles may be reordered by tile: compare as sets keyed by vertex triple.
    let mut expect: Vec<([u32; 3], [[f32; 2]; 3])> = m
        .triangles
        .iter()
        .zip(&m.uvs)
        .map(|(t, uv)| {
            // map product uv: texture pixels, y down, pixel centres on integers
            (
                *t,
                uv.map(|c| [c[0] * 16.0 - 0.5, (1.0 - c[1]) * 8.0 - 0.5]),
            )
        })
        .collect();
    let mut got: Vec<([u32; 3], [[f32; 2]; 3])> = (0..map.triangle_count())
        .map(|i| {
            let t = map.triangle(i).unwrap();
            assert!(t.mask);
            (t.v, t.uv)
        })
        .collect();
    expect.sort_by_key(|e| e.0);
    got.sort_by_key(|e| e.0);
    for (e, g) in expect.iter().zip(&got) {
        assert_eq!(e.0, g.0);
        for (a, b) in e.1.iter().flatten().zip(g.1.iter().flatten()) {
            assert!((a - b).abs() < 1e-3, "uv {a} vs {b}");
        }
    }
    let t = map.texture();
    for y in 0..8 {
        assert_eq!(t.row(y).unwrap(), &tex.pixels[y * 16..(y + 1) * 16]);
    }
}

/// Verifies: VTSM-CLI-001
#[test]
fn all_face_index_forms_and_polygons_are_read() {
    let d = dir("forms");
    let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 1.5 0\n\
                vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n\
                f 1 2 3\n\
                f 1/1 2/2 3/3\n\
                f 1/1/1 2/2/1 3/3/1\n\
                f 1//1 2//1 3//1\n\
                f -5 -4 -3\n\
                f 1 2 3 4 5\n";
    let p = d.join("forms.obj");
    let raw = obj::parse(text.as_bytes(), &p, false).unwrap();
    let mut expect = vec![[0, 1, 2]; 5];
    // pentagon fan around its first corner
    expect.extend([[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
    assert_eq!(raw.triangles, expect);
    // Not every face has vt, so the mesh has no per-corner uvs.
    assert!(raw.uvs.is_none());
    let text2 = "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nf 1/-3 2/-2 3/-1\n";
    let raw2 = obj::parse(text2.as_bytes(), &p, false).unwrap();
    assert_eq!(
        raw2.uvs.unwrap(),
        vec![[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]]
    );
}

fn obj_err(text: &str, appearance: bool) -> vtsm_sim::Error {
    obj::parse(
        text.as_bytes(),
        Path::new("/nonexistent/bad.obj"),
        appearance,
    )
    .unwrap_err()
}

/// Verifies: VTSM-CLI-008
#[test]
fn malformed_obj_gives_file_line_and_reason() {
    let cases: &[(&str, usize, &str)] = &[
        ("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 4\n", 4, "out of range"),
        ("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 -4\n", 4, "out of range"),
        ("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 0 1 2\n", 4, "index 0"),
        ("v 0 0 0\nv nan 0 0\n", 2, "not finite"),
        ("v 0 0 0\nv inf 0 0\n", 2, "not finite"),
        ("v 0 0\n", 1, "3 coordinates"),
        ("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2\n", 4, "at least 3"),
        ("v 0 0 0\nv 1 0 x\n", 2, "not a number"),
        ("v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2 3\n", 5, "mixes"),
        (
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1/2 2 3\n",
            4,
            "texture coordinate index",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1/a 2 3\n",
            4,
            "not an integer",
        ),
        ("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1/1/1/1 2 3\n", 4, "too many"),
        (
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\nusemtl stone\n",
            5,
            "not defined",
        ),
        ("v 0 0 0\nmtllib missing.mtl\n", 2, "material library"),
    ];
    for (text, line, what) in cases {
        let e = obj_err(text, true);
        assert_eq!(
            e.file.as_deref(),
            Some(Path::new("/nonexistent/bad.obj")),
            "{text:?}"
        );
        assert_eq!(e.line, Some(*line), "{text:?}: {e}");
        assert!(e.msg.contains(what), "{text:?}: {e}");
        assert_eq!(e.to_string().lines().count(), 1);
    }
    let e = obj::parse(
        b"v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n\xff\n",
        Path::new("x.obj"),
        true,
    )
    .unwrap_err();
    assert_eq!((e.line, e.msg.contains("UTF-8")), (Some(5), true), "{e}");
    // No faces at all: truncated before the first `f`.
    let e = obj_err("v 0 0 0\nv 1 0 0\n", true);
    assert!(e.msg.contains("no faces"), "{e}");
}

/// Verifies: VTSM-CLI-002, VTSM-CLI-008
#[test]
fn bad_mtl_and_missing_texture_name_the_right_file() {
    let d = dir("mtl");
    let obj_text = "mtllib m.mtl\nusemtl a\nv 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nf 1/1 2/2 3/3\n";
    let p = d.join("m.obj");
    std::fs::write(&p, obj_text).unwrap();

    std::fs::write(d.join("m.mtl"), "newmtl a\nmap_Kd missing.png\n").unwrap();
    let e = mesh::load_mesh(&p).unwrap_err();
    assert_eq!(e.file.as_deref(), Some(d.join("m.mtl").as_path()));
    assert_eq!(e.line, Some(2));
    assert!(e.msg.contains("not found"), "{e}");

    std::fs::write(d.join("m.mtl"), "map_Kd tex.png\nnewmtl a\n").unwrap();
    let e = mesh::load_mesh(&p).unwrap_err();
    assert_eq!(
        (e.line, e.msg.contains("before any newmtl")),
        (Some(1), true),
        "{e}"
    );

    std::fs::write(d.join("m.mtl"), "newmtl a\nmap_Kd -s 1 1 1 -clamp on\n").unwrap();
    let e = mesh::load_mesh(&p).unwrap_err();
    assert!(e.msg.contains("no texture file"), "{e}");

    // A texture that is not an image names the texture file.
    std::fs::write(d.join("tex.png"), b"not a png at all").unwrap();
    std::fs::write(d.join("m.mtl"), "newmtl a\nmap_Kd -s 1 1 1 tex.png\n").unwrap();
    let e = mesh::load_mesh(&p).unwrap_err();
    assert_eq!(e.file.as_deref(), Some(d.join("tex.png").as_path()), "{e}");

    // With options before the file name, and the texture in a subfolder of the MTL's folder.
    std::fs::create_dir_all(d.join("mat/img")).unwrap();
    write_png(&d.join("mat/img/t.png"), &texture(4, 4), true).unwrap();
    std::fs::write(
        d.join("mat/m.mtl"),
        "newmtl a\nmap_Kd -o 0 0 -bm 1 img/t.png\n",
    )
    .unwrap();
    std::fs::write(&p, obj_text.replace("mtllib m.mtl", "mtllib mat/m.mtl")).unwrap();
    let m = mesh::load_mesh(&p).unwrap();
    assert_eq!(m.texture, texture(4, 4));

    // Textured but a face lacks vt.
    std::fs::write(
        &p,
        "mtllib mat/m.mtl\nusemtl a\nv 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let e = mesh::load_mesh(&p).unwrap_err();
    assert_eq!(e.line, Some(6), "{e}");

    // Neither texture nor colour.
    std::fs::write(&p, "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n").unwrap();
    let e = mesh::load_mesh(&p).unwrap_err();
    assert!(e.msg.contains("neither a texture"), "{e}");
}

/// Verifies: VTSM-CLI-011
#[test]
fn mask_matches_triangles_in_any_corner_order_and_vertex_numbering() {
    let d = dir("mask");
    let (p, verts, _) = write_grid(&d, 5, 4);
    let mut m = mesh::load_mesh(&p).unwrap();
    // Mask: every third mesh triangle, corners rotated, vertices renumbered (reversed),
    // coordinates perturbed by far less than the tolerance.
    let chosen: Vec<usize> = (0..m.triangles.len()).step_by(3).collect();
    let n = verts.len() as u32;
    let mask_vertices: Vec<[f64; 3]> = verts
        .iter()
        .rev()
        .map(|v| {
            [
                f64::from(v[0]) + 1e-6,
                f64::from(v[1]) - 1e-6,
                f64::from(v[2]),
            ]
        })
        .collect();
    let mut mask_tris = Vec::new();
    for &k in chosen.iter().rev() {
        let t = m.triangles[k];
        mask_tris.push([n - 1 - t[1], n - 1 - t[2], n - 1 - t[0]]);
    }
    let mut raw = mesh::RawMesh {
        vertices: mask_vertices,
        triangles: mask_tris,
        ..Default::default()
    };
    let stats = m.apply_mask(&raw, Path::new("k.obj")).unwrap();
    assert_eq!(stats.mask_triangles, chosen.len());
    assert_eq!(stats.matched, chosen.len());
    assert_eq!(stats.marked, chosen.len());
    for (k, &flag) in m.mask.iter().enumerate() {
        assert_eq!(flag, k % 3 == 0, "triangle {k}");
    }
    // Plus one triangle that is not in the mesh (its vertices are): refused,
    // naming the mask file and the triangle, and the mesh's mask is unchanged.
    raw.triangles.push([0, 1, n - 1]);
    let before = m.mask.clone();
    let e = m.apply_mask(&raw, Path::new("k.obj")).unwrap_err();
    assert_eq!(e.file.as_deref(), Some(Path::new("k.obj")));
    let want = format!("mask triangle {} ", chosen.len() + 1);
    assert!(
        e.msg.contains(&want) && e.msg.contains("not a triangle of the mesh"),
        "{e}"
    );
    assert_eq!(m.mask, before);
    // A mask with no triangle of the mesh is an error naming the mask file.
    let far = mesh::RawMesh {
        vertices: vec![[9.0, 9.0, 9.0], [9.5, 9.0, 9.0], [9.0, 9.5, 9.0]],
        triangles: vec![[0, 1, 2]],
        ..Default::default()
    };
    let e = m.apply_mask(&far, Path::new("k.obj")).unwrap_err();
    assert_eq!(e.file.as_deref(), Some(Path::new("k.obj")));
}

/// Verifies: VTSM-CLI-004
#[test]
fn vertex_coloured_obj_gets_an_atlas_that_reproduces_the_colours() {
    let text = "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 1 1 0 0 0 1\nv 0 1 0 1 1 1\nf 1 2 3 4\n";
    let p = Path::new("/nonexistent/c.obj");
    let raw = obj::parse(text.as_bytes(), p, true).unwrap();
    // BT.601 of pure red, green, blue, white (reference weights 0.299, 0.587, 0.114)
    let expect = [76u8, 150, 29, 255];
    assert_eq!(raw.vertex_gray.as_deref(), Some(&expect[..]));
    let m = MeshData::from_raw(raw, p).unwrap();
    check_atlas(&m, &expect);
}

/// Each corner's uv lands on a texel holding that vertex's gray, and the texel at
/// the cell's centroid holds about the mean of the three.
pub fn check_atlas(m: &MeshData, gray: &[u8]) {
    let (w, h) = (m.texture.width as f32, m.texture.height as f32);
    for (t, uv) in m.triangles.iter().zip(&m.uvs) {
        let mut px = [[0f32; 2]; 3];
        for ((&v, c), p) in t.iter().zip(uv).zip(px.iter_mut()) {
            let (x, y) = (c[0] * w - 0.5, (1.0 - c[1]) * h - 0.5);
            assert!((x - x.round()).abs() < 1e-3 && (y - y.round()).abs() < 1e-3);
            let g = m.texture.get(x.round() as u32, y.round() as u32).unwrap();
            assert_eq!(g, gray[v as usize]);
            *p = [x, y];
        }
        // The texels between the corners interpolate: check the midpoint of edge 0-1
        // against the mean of the two end grays (cell side 4 → midpoint between texels 1 and 2).
        let g0 = f32::from(gray[t[0] as usize]);
        let g1 = f32::from(gray[t[1] as usize]);
        let (x1, y0) = (px[0][0] as u32 + 1, px[0][1] as u32);
        let a = f32::from(m.texture.get(x1, y0).unwrap());
        let b = f32::from(m.texture.get(x1 + 1, y0).unwrap());
        assert!(
            ((a + b) / 2.0 - (g0 + g1) / 2.0).abs() <= 1.0,
            "{a} {b} {g0} {g1}"
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// Verifies: VTSM-CLI-008
    #[test]
    fn obj_reader_never_panics_on_arbitrary_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        let _ = obj::parse(&bytes, Path::new("/nonexistent/fuzz.obj"), true);
    }

    /// Verifies: VTSM-CLI-008
    #[test]
    fn obj_reader_never_panics_on_obj_like_text(
        lines in proptest::collection::vec(
            proptest::collection::vec(
                prop_oneof![
                    Just("v"), Just("vt"), Just("vn"), Just("f"), Just("usemtl"), Just("mtllib"),
                    Just("0"), Just("1"), Just("-1"), Just("2"), Just("-3"), Just("0.5"), Just("nan"),
                    Just("1e39"), Just("1/1"), Just("1//1"), Just("-1/-1/-1"), Just("2/0"), Just("/"),
                    Just("4294967296"), Just("-9223372036854775808"), Just("#"),
                ],
                0..8),
            0..24)
    ) {
        let text: String = lines.iter().map(|l| l.join(" ") + "\n").collect();
        let r = obj::parse(text.as_bytes(), Path::new("/nonexistent/fuzz.obj"), true);
        if let Ok(raw) = r {
            let nv = raw.vertices.len() as u32;
            prop_assert!(raw.triangles.iter().flatten().all(|&i| i < nv));
            prop_assert!(raw.vertices.iter().flatten().all(|c| c.is_finite()));
        }
    }
}

/// Verifies: VTSM-CLI-001, VTSM-CLI-011
#[test]
fn scene_export_obj_files_read_back_as_the_simulated_map() {
    use vtsm_sim::scene::export::obj_text;
    let d = dir("export");
    let verts: Vec<[f32; 3]> = (0..12)
        .map(|k| {
            [
                (k % 4) as f32 * 0.3 + 0.012_345,
                (k / 4) as f32 * 0.3 - 1.5,
                0.01 * k as f32,
            ]
        })
        .collect();
    let mut tris = Vec::new();
    for j in 0..2u32 {
        for i in 0..3u32 {
            let a = j * 4 + i;
            tris.push([a, a + 1, a + 5]);
            tris.push([a, a + 5, a + 4]);
        }
    }
    let uvs: Vec<[[f32; 2]; 3]> = tris
        .iter()
        .map(|t| t.map(|k| [(k % 4) as f32 / 3.0, (k / 4) as f32 / 2.0]))
        .collect();
    let mask: Vec<bool> = (0..tris.len()).map(|k| k % 2 == 1).collect();
    let tex = texture(8, 8);
    let sim = MeshData {
        vertices: verts.clone(),
        triangles: tris.clone(),
        uvs: uvs.clone(),
        mask: mask.clone(),
        texture: tex.clone(),
        origin: [0.0; 3],
    };

    write_png(&d.join("map_texture.png"), &tex, true).unwrap();
    std::fs::write(d.join("map.mtl"), "newmtl depot\nmap_Kd map_texture.png\n").unwrap();
    std::fs::write(d.join("map.obj"), obj_text(&sim, Some("map.mtl"), false)).unwrap();
    std::fs::write(d.join("mask.obj"), obj_text(&sim, None, true)).unwrap();
    let mut back = mesh::load_mesh(&d.join("map.obj")).unwrap();
    let geo = mesh::load_geometry(&d.join("mask.obj")).unwrap();
    back.apply_mask(&geo, &d.join("mask.obj")).unwrap();
    assert_eq!(back.triangles, tris);
    assert_eq!(back.mask, mask);
    assert_eq!(back.texture, tex);
    // The exporter rounds positions to 1e-5 m and uvs to 1e-6.
    for (a, b) in back.vertices.iter().zip(&verts) {
        let user = [0, 1, 2].map(|k| f64::from(a[k]) + back.origin[k]);
        assert!(
            user.iter()
                .zip(b)
                .all(|(x, y)| (x - f64::from(*y)).abs() <= 7e-6),
            "{user:?} {b:?}"
        );
    }
    for (a, b) in back.uvs.iter().zip(&uvs) {
        assert!(a
            .iter()
            .flatten()
            .zip(b.iter().flatten())
            .all(|(x, y)| (x - y).abs() <= 1e-6));
    }
}
