//! PLY reader: ascii and both binary byte orders, colour, texture coordinates, errors.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, missing_docs)]

use proptest::prelude::*;
use std::path::{Path, PathBuf};
use vtsm_sim::io::image::{write_png, Gray8};
use vtsm_sim::io::mesh::{self, MeshData};
use vtsm_sim::io::ply;

fn dir(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("io_ply_{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

const VERTS: [[f32; 3]; 5] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.25],
    [1.0, 1.0, -0.5],
    [0.0, 1.0, 1.5],
    [0.5, 1.5, 2.0],
];
const RGB: [[u8; 3]; 5] = [
    [255, 0, 0],
    [0, 255, 0],
    [0, 0, 255],
    [10, 20, 30],
    [200, 100, 50],
];

/// The same mesh (a quad + a triangle, with a `quality` property and an extra
/// `edge` element to skip) in each format, written by hand.
fn ply_bytes(format: &str) -> Vec<u8> {
    let mut out = format!(
        "ply\nformat {format} 1.0\ncomment made by the test\n\
         element vertex 5\nproperty float x\nproperty float y\nproperty float z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\nproperty double quality\n\
         element face 2\nproperty list uchar int vertex_indices\n\
         element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n"
    )
    .into_bytes();
    let faces: [&[i32]; 2] = [&[0, 1, 2, 3], &[3, 2, 4]];
    if format == "ascii" {
        for (v, c) in VERTS.iter().zip(RGB) {
            out.extend(
                format!(
                    "{} {} {} {} {} {} 0.5\n",
                    v[0], v[1], v[2], c[0], c[1], c[2]
                )
                .bytes(),
            );
        }
        for f in faces {
            let idx: Vec<String> = f.iter().map(|i| i.to_string()).collect();
            out.extend(format!("{} {}\n", f.len(), idx.join(" ")).bytes());
        }
        out.extend(b"0 1\n");
    } else {
        let be = format == "binary_big_endian";
        let f32b = |v: f32| if be { v.to_be_bytes() } else { v.to_le_bytes() };
        let i32b = |v: i32| if be { v.to_be_bytes() } else { v.to_le_bytes() };
        for (v, c) in VERTS.iter().zip(RGB) {
            for x in v {
                out.extend(f32b(*x));
            }
            out.extend(c);
            out.extend(if be {
                0.5f64.to_be_bytes()
            } else {
                0.5f64.to_le_bytes()
            });
        }
        for f in faces {
            out.push(f.len() as u8);
            for i in f {
                out.extend(i32b(*i));
            }
        }
        out.extend(i32b(0));
        out.extend(i32b(1));
    }
    out
}

fn luma_ref(c: [u8; 3]) -> u8 {
    (0.299 * f64::from(c[0]) + 0.587 * f64::from(c[1]) + 0.114 * f64::from(c[2])).round() as u8
}

/// Verifies: VTSM-CLI-003, VTSM-CLI-004
#[test]
fn ascii_and_both_binary_orders_read_the_same_mesh() {
    let p = Path::new("/nonexistent/m.ply");
    let meshes: Vec<_> = ["ascii", "binary_little_endian", "binary_big_endian"]
        .iter()
        .map(|f| ply::parse(&ply_bytes(f), p, true).unwrap())
        .collect();
    for m in &meshes {
        let want: Vec<[f64; 3]> = VERTS.iter().map(|v| v.map(f64::from)).collect();
        assert_eq!(m.vertices, want);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [3, 2, 4]]);
        let expect: Vec<u8> = RGB.iter().map(|c| luma_ref(*c)).collect();
        assert_eq!(m.vertex_gray.as_deref(), Some(&expect[..]));
        assert!(m.texture.is_none() && m.uvs.is_none());
    }
    assert_eq!(meshes[0], meshes[1]);
    assert_eq!(meshes[1], meshes[2]);
    // Colour only → the map gets a synthesized atlas.
    let m = MeshData::from_raw(meshes[0].clone(), p).unwrap();
    let gray = meshes[0].vertex_gray.clone().unwrap();
    for (t, uv) in m.triangles.iter().zip(&m.uvs) {
        for (&v, c) in t.iter().zip(uv) {
            let x = (c[0] * m.texture.width as f32 - 0.5).round() as u32;
            let y = ((1.0 - c[1]) * m.texture.height as f32 - 0.5).round() as u32;
            assert_eq!(m.texture.get(x, y), Some(gray[v as usize]));
        }
    }
}

/// Verifies: VTSM-CLI-003
#[test]
fn texture_file_with_face_or_vertex_texcoords() {
    let d = dir("tex");
    let tex = Gray8 {
        width: 2,
        height: 2,
        pixels: vec![0, 50, 100, 150],
    };
    write_png(&d.join("t.png"), &tex, true).unwrap();
    let face_tc = "ply\nformat ascii 1.0\ncomment TextureFile t.png\nelement vertex 3\n\
        property float x\nproperty float y\nproperty float z\nelement face 1\n\
        property list uchar int vertex_indices\nproperty list uchar float texcoord\nend_header\n\
        0 0 0\n1 0 0\n0 1 0\n3 0 1 2 6 0.1 0.2 0.3 0.4 0.5 0.6\n";
    let p = d.join("f.ply");
    std::fs::write(&p, face_tc).unwrap();
    let m = mesh::load_mesh(&p).unwrap();
    assert_eq!(m.texture, tex);
    assert_eq!(m.uvs, vec![[[0.1, 0.2], [0.3, 0.4], [0.5, 0.6]]]);

    let vert_tc = "ply\nformat ascii 1.0\ncomment TextureFile t.png\nelement vertex 3\n\
        property float x\nproperty float y\nproperty float z\nproperty float s\nproperty float t\n\
        element face 1\nproperty list uchar uint vertex_index\nend_header\n\
        0 0 0 0.0 0.1\n1 0 0 0.9 0.1\n0 1 0 0.0 0.8\n3 2 1 0\n";
    let p = d.join("v.ply");
    std::fs::write(&p, vert_tc).unwrap();
    let m = mesh::load_mesh(&p).unwrap();
    assert_eq!(m.triangles, vec![[2, 1, 0]]);
    assert_eq!(m.uvs, vec![[[0.0, 0.8], [0.9, 0.1], [0.0, 0.1]]]);

    // Missing texture file: error at the header line naming it.
    std::fs::write(&p, vert_tc.replace("t.png", "gone.png")).unwrap();
    let e = mesh::load_mesh(&p).unwrap_err();
    assert_eq!(
        (e.line, e.msg.contains("not found")),
        (Some(3), true),
        "{e}"
    );
}

fn ply_err(bytes: &[u8]) -> vtsm_sim::Error {
    ply::parse(bytes, Path::new("/nonexistent/bad.ply"), true).unwrap_err()
}

/// Verifies: VTSM-CLI-008, VTSM-CLI-015
#[test]
fn malformed_ply_gives_file_location_and_reason() {
    let good = String::from_utf8(ply_bytes("ascii")).unwrap();
    let cases: Vec<(String, Option<usize>, &str)> = vec![
        (good.replacen("ply\n", "plx\n", 1), Some(1), "magic"),
        (
            good.replace("format ascii", "format utf16"),
            Some(2),
            "unknown format",
        ),
        (good.replace(" 1.0\n", " 2.0\n"), Some(2), "version"),
        (
            good.replace("property float y", "property half y"),
            Some(6),
            "unknown property type",
        ),
        (good[..60].to_string(), None, "end_header"),
        (
            good.replace("end_header\n", ""),
            Some(17),
            "unrecognised header line",
        ),
        (good.replace("0.25", "nan"), Some(19), "not finite"),
        (good.replace("3 3 2 4", "3 3 2 5"), Some(24), "out of range"),
        (
            good.replace("3 3 2 4", "3 3 2 -1"),
            Some(24),
            "out of range",
        ),
        (good.replace("3 3 2 4", "2 3 2"), Some(24), "at least 3"),
        (
            good.replace("3 3 2 4", "3 3 2 4 7"),
            Some(24),
            "values on the line",
        ),
        (
            good.replace("element vertex 5", "element vertex 5000000000"),
            None,
            "too short",
        ),
        (good[..good.len() - 4].to_string(), Some(24), "truncated"),
        (
            good[..good.len() - 10].to_string(),
            Some(24),
            "too few values",
        ),
    ];
    for (text, line, what) in &cases {
        let e = ply_err(text.as_bytes());
        assert_eq!(e.file.as_deref(), Some(Path::new("/nonexistent/bad.ply")));
        assert_eq!(e.line, *line, "{what}: {e}");
        assert!(e.msg.contains(what), "{what}: {e}");
        assert_eq!(e.to_string().lines().count(), 1);
    }
    // Binary: truncation and NaN report the byte offset.
    let bin = ply_bytes("binary_little_endian");
    let e = ply_err(&bin[..bin.len() - 3]);
    assert!(
        e.msg.contains("at byte") && e.msg.contains("truncated"),
        "{e}"
    );
    let hdr = bin.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let mut nan = bin.clone();
    nan[hdr..hdr + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    let e = ply_err(&nan);
    assert!(
        e.msg.contains(&format!("at byte {}", hdr + 4)) && e.msg.contains("finite"),
        "{e}"
    );
    let mut extra = bin.clone();
    extra.push(0);
    assert!(ply_err(&extra).msg.contains("after the last element"));
    // A forged face list length cannot allocate beyond the file.
    let mut forged = bin.clone();
    let face0 = hdr + 5 * (12 + 3 + 8);
    forged[face0] = 255;
    let e = ply_err(&forged);
    assert!(e.msg.contains("longer than the file"), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Verifies: VTSM-CLI-008
    #[test]
    fn ply_reader_never_panics_on_corrupted_files(
        fmt in 0usize..3, pos in any::<prop::sample::Index>(), byte in any::<u8>(), cut in any::<prop::sample::Index>()
    ) {
        let f = ["ascii", "binary_little_endian", "binary_big_endian"][fmt];
        let mut b = ply_bytes(f);
        let i = pos.index(b.len());
        b[i] = byte;
        let _ = ply::parse(&b, Path::new("/nonexistent/fuzz.ply"), true);
        let n = cut.index(b.len());
        let _ = ply::parse(&b[..n], Path::new("/nonexistent/fuzz.ply"), true);
    }
}
