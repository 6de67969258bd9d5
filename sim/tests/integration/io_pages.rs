//! Meshes whose faces use several texture pages (OBJ `usemtl` / PLY `texnumber`):
//! one atlas, rendered the same as the single-texture original.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, missing_docs)]

use std::path::{Path, PathBuf};
use vtsm_core::geom::{Camera, Pose, Vec3};
use vtsm_core::image::Rect;
use vtsm_core::map::MapView;
use vtsm_core::nalgebra::{Matrix3, Rotation3, UnitQuaternion};
use vtsm_core::raster::{self, Target, DEPTH_NONE};
use vtsm_sim::io::image::{write_png, Gray8};
use vtsm_sim::io::mesh::{self, MeshData};

fn dir(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("io_pages_{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Side of a quadrant page, texels; the original texture is twice as large.
const PAGE: u32 = 64;
/// Mesh cells per quadrant region and side.
const CELLS: usize = 8;

/// A textured pattern with detail at every scale (so a wrong texel shows).
fn original_texture() -> Gray8 {
    let n = 2 * PAGE;
    let mut t = Gray8::filled(n, n, 0);
    for y in 0..n {
        for x in 0..n {
            let v = 128.0
                + 60.0 * ((x as f32) * 0.31).sin() * ((y as f32) * 0.17).cos()
                + 40.0 * (((x * 7 + y * 3) % 23) as f32 / 23.0 - 0.5)
                + if (x / 8 + y / 8) % 2 == 0 {
                    20.0
                } else {
                    -20.0
                };
            t.pixels[(y * n + x) as usize] = v.round().clamp(0.0, 255.0) as u8;
        }
    }
    t
}

/// A 2 m × 2 m undulating ground of 2·CELLS × 2·CELLS quads. Quadrant region
/// (qx, qy) (qx along x, qy = 0 for y ≥ 1 m) takes its texture coordinates from
/// quadrant (qx, qy) of the texture (qy = 0: the top rows), inset by one texel,
/// so no face straddles quadrants and vertices on region borders get a
/// different `vt` on each side. Returns vertices, triangles, per-corner uvs of
/// the original texture and each triangle's quadrant `qy · 2 + qx`.
type Ground = (Vec<[f32; 3]>, Vec<[u32; 3]>, Vec<[[f32; 2]; 3]>, Vec<u32>);

fn ground() -> Ground {
    let n = 2 * CELLS + 1;
    let step = 2.0 / (2 * CELLS) as f32;
    let mut verts = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (i as f32 * step, j as f32 * step);
            let z = 0.05 * (x * 4.0).sin() * (y * 3.0).cos();
            verts.push([x, y, z]);
        }
    }
    let (w, t2) = (PAGE as f32, 2.0 * PAGE as f32);
    let uv = |i: usize, j: usize, qx: usize, qy: usize| -> [f32; 2] {
        // Local position in the region, 0..=1.
        let lx = (i - qx * CELLS) as f32 / CELLS as f32;
        let ly = (j - (1 - qy) * CELLS) as f32 / CELLS as f32;
        // Texel centres qx·W + 0.5 + 1 .. qx·W + W − 1.5 (pixel coordinates), y likewise.
        let px = qx as f32 * w + 1.0 + lx * (w - 2.0);
        let py = qy as f32 * w + 1.0 + (1.0 - ly) * (w - 2.0);
        [px / t2, 1.0 - py / t2]
    };
    let (mut tris, mut uvs, mut quad) = (Vec::new(), Vec::new(), Vec::new());
    for j in 0..2 * CELLS {
        for i in 0..2 * CELLS {
            let (qx, qy) = (i / CELLS, 1 - j / CELLS);
            let id = |a: usize, b: usize| (b * n + a) as u32;
            let c = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)];
            for k in [[0usize, 1, 2], [0, 2, 3]] {
                tris.push(k.map(|m| id(c[m].0, c[m].1)));
                uvs.push(k.map(|m| uv(c[m].0, c[m].1, qx, qy)));
                quad.push((qy * 2 + qx) as u32);
            }
        }
    }
    (verts, tris, uvs, quad)
}

/// Quadrant `q` of the original texture, and the original uv moved into it.
fn quadrant(tex: &Gray8, q: u32) -> Gray8 {
    let (qx, qy) = (q % 2, q / 2);
    let mut p = Gray8::filled(PAGE, PAGE, 0);
    for y in 0..PAGE {
        for x in 0..PAGE {
            p.pixels[(y * PAGE + x) as usize] = tex.get(qx * PAGE + x, qy * PAGE + y).unwrap();
        }
    }
    p
}

fn to_page(uv: [f32; 2], q: u32) -> [f32; 2] {
    let (qx, qy) = ((q % 2) as f32, (q / 2) as f32);
    [2.0 * uv[0] - qx, 2.0 * uv[1] - 1.0 + qy]
}

/// OBJ text with `vt` per corner and one `usemtl` per run of faces of a page.
fn obj_text(
    verts: &[[f32; 3]],
    tris: &[[u32; 3]],
    uvs: &[[[f32; 2]; 3]],
    page: Option<&[u32]>,
) -> String {
    use std::fmt::Write as _;
    let mut s = String::from("mtllib m.mtl\n");
    if page.is_none() {
        s += "usemtl whole\n";
    }
    for v in verts {
        let _ = writeln!(s, "v {} {} {}", v[0], v[1], v[2]);
    }
    for t in uvs {
        for c in t {
            let _ = writeln!(s, "vt {} {}", c[0], c[1]);
        }
    }
    let mut current = u32::MAX;
    for (k, t) in tris.iter().enumerate() {
        if let Some(p) = page {
            if p[k] != current {
                current = p[k];
                let _ = writeln!(s, "usemtl page{current}");
            }
        }
        let b = 3 * k + 1;
        let _ = writeln!(
            s,
            "f {}/{} {}/{} {}/{}",
            t[0] + 1,
            b,
            t[1] + 1,
            b + 1,
            t[2] + 1,
            b + 2
        );
    }
    s
}

fn write_jpeg(path: &Path, img: &Gray8, quality: u8) {
    // Colour JPEG (R = G = B), as photogrammetry tools write: exercises the luma step.
    let rgb: Vec<u8> = img.pixels.iter().flat_map(|&g| [g, g, g]).collect();
    let f = std::fs::File::create(path).unwrap();
    let mut enc = image::codecs::jpeg::JpegEncoder::new_with_quality(f, quality);
    enc.encode(&rgb, img.width, img.height, image::ExtendedColorType::Rgb8)
        .unwrap();
}

fn write_rgb_png(path: &Path, img: &Gray8) {
    let rgb: Vec<u8> = img.pixels.iter().flat_map(|&g| [g, g, g]).collect();
    image::RgbImage::from_raw(img.width, img.height, rgb)
        .unwrap()
        .save_with_format(path, image::ImageFormat::Png)
        .unwrap();
}

fn write_tiff(path: &Path, img: &Gray8) {
    image::GrayImage::from_raw(img.width, img.height, img.pixels.clone())
        .unwrap()
        .save_with_format(path, image::ImageFormat::Tiff)
        .unwrap();
}

/// Write the single-texture original and its 4-page split (page files named by
/// `page_file`, written by `write_page`); returns (original OBJ, paged OBJ).
fn write_pair(
    d: &Path,
    page_file: &dyn Fn(u32) -> String,
    write_page: &dyn Fn(&Path, &Gray8, u32),
) -> (PathBuf, PathBuf) {
    let tex = original_texture();
    let (verts, tris, uvs, quad) = ground();
    let one = d.join("one");
    let four = d.join("four");
    std::fs::create_dir_all(&one).unwrap();
    std::fs::create_dir_all(four.join("tex")).unwrap();
    write_png(&one.join("whole.png"), &tex, true).unwrap();
    std::fs::write(one.join("m.mtl"), "newmtl whole\nmap_Kd whole.png\n").unwrap();
    std::fs::write(one.join("m.obj"), obj_text(&verts, &tris, &uvs, None)).unwrap();
    let mut mtl = String::new();
    for q in 0..4 {
        let f = page_file(q);
        write_page(&four.join("tex").join(&f), &quadrant(&tex, q), q);
        mtl += &format!("newmtl page{q}\nKd 1 1 1\nmap_Kd tex/{f}\n");
    }
    std::fs::write(four.join("m.mtl"), mtl).unwrap();
    let paged: Vec<[[f32; 2]; 3]> = uvs
        .iter()
        .zip(&quad)
        .map(|(t, &q)| t.map(|c| to_page(c, q)))
        .collect();
    std::fs::write(
        four.join("m.obj"),
        obj_text(&verts, &tris, &paged, Some(&quad)),
    )
    .unwrap();
    (one.join("m.obj"), four.join("m.obj"))
}

/// world_from_cam for an OpenCV camera at `eye` looking at `target`, world z up.
fn look_at(eye: [f32; 3], target: [f32; 3]) -> Pose {
    let eye = Vec3::from(eye);
    let z = (Vec3::from(target) - eye).normalize();
    // Straight down: image "up" towards +y instead of the (parallel) world z.
    let up = if z.z.abs() > 0.99 {
        Vec3::new(0.0, 1.0, 0.0)
    } else {
        Vec3::new(0.0, 0.0, 1.0)
    };
    let x = z.cross(&up).normalize();
    let y = z.cross(&x);
    let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
    Pose::new(UnitQuaternion::from_rotation_matrix(&r), eye)
}

const VIEW: u32 = 96;

/// Intensity, depth and mask depth of one full-camera render.
type Render = (Vec<u8>, Vec<u32>, Vec<u32>);

fn render(map: &MapView, eye: [f32; 3], target: [f32; 3]) -> Render {
    let cam = Camera::new(80.0, 80.0, 47.5, 47.5, VIEW, VIEW).unwrap();
    let n = (VIEW * VIEW) as usize;
    let (mut i, mut d, mut m) = (vec![0u8; n], vec![0u32; n], vec![0u32; n]);
    let mut t = Target {
        intensity: &mut i,
        depth: &mut d,
        mask_depth: &mut m,
    };
    raster::render_window(
        map,
        &cam,
        &look_at(eye, target),
        Rect::new(0, 0, VIEW, VIEW),
        &mut t,
    )
    .unwrap();
    (i, d, m)
}

/// Viewpoints over the ground, several looking at the quadrant borders (x = 1 or y = 1).
const VIEWS: [([f32; 3], [f32; 3]); 6] = [
    ([1.0, -0.2, 1.2], [1.0, 1.0, 0.0]),
    ([1.0, 1.0, 0.9], [1.0, 1.0, 0.0]),
    ([0.3, 0.4, 0.8], [1.0, 0.6, 0.0]),
    ([2.3, 1.8, 1.0], [1.2, 1.0, 0.0]),
    ([1.6, 0.2, 0.5], [1.0, 1.4, 0.0]),
    ([-0.4, 2.4, 1.5], [0.9, 1.1, 0.0]),
];

/// Largest intensity difference over all views (same pixels drawn, same depths,
/// same mask depths asserted), and the number of pixels compared (printed with
/// the number that differ).
fn compare_renders(a: &MeshData, b: &MeshData) -> (u8, usize) {
    let (ba, bb) = (a.encode_map(0.5).unwrap(), b.encode_map(0.5).unwrap());
    let (ma, mb) = (
        MapView::new_checked(&ba).unwrap(),
        MapView::new_checked(&bb).unwrap(),
    );
    let (mut worst, mut pixels, mut differ) = (0u8, 0usize, 0usize);
    for (eye, target) in VIEWS {
        let (ia, da, ka) = render(&ma, eye, target);
        let (ib, db, kb) = render(&mb, eye, target);
        assert_eq!(da, db, "depth differs from {eye:?}");
        assert_eq!(ka, kb, "mask depth differs from {eye:?}");
        for ((x, y), d) in ia.iter().zip(&ib).zip(&da) {
            if *d != DEPTH_NONE {
                worst = worst.max(x.abs_diff(*y));
                pixels += 1;
                differ += usize::from(x != y);
            }
        }
    }
    println!("{differ} of {pixels} drawn pixels differ");
    (worst, pixels)
}

/// Verifies: VTSM-CLI-026, VTSM-CLI-027
#[test]
fn four_png_pages_render_like_the_single_texture_original() {
    let d = dir("png");
    // Mixed page files: gray PNG, colour PNG, TIFF, gray PNG again.
    let name = |q: u32| match q {
        2 => format!("page{q}.tif"),
        _ => format!("page{q}.png"),
    };
    let write = |p: &Path, img: &Gray8, q: u32| match q {
        1 => write_rgb_png(p, img),
        2 => write_tiff(p, img),
        _ => write_png(p, img, true).unwrap(),
    };
    let (one, four) = write_pair(&d, &name, &write);
    let a = mesh::load_mesh_at(&one, Some([0.0; 3])).unwrap();
    let b = mesh::load_mesh_at(&four, Some([0.0; 3])).unwrap();
    assert_eq!(a.vertices, b.vertices);
    assert_eq!(a.triangles, b.triangles);
    // The faces' corners lie at page texels 0.5..=62.5, so bilinear sampling reads
    // texels 0..=63; with the margin of one texel, 66² rectangles, 2 × 2.
    assert_eq!((b.texture.width, b.texture.height), (132, 132));
    // Every corner samples the same texel of the atlas as of the original.
    for (ua, ub) in a.uvs.iter().zip(&b.uvs) {
        for (ca, cb) in ua.iter().zip(ub) {
            let sa = a.sample_texture(ca[0], ca[1]);
            let sb = b.sample_texture(cb[0], cb[1]);
            assert!((sa - sb).abs() < 0.01, "{sa} vs {sb}");
        }
    }
    let (worst, pixels) = compare_renders(&a, &b);
    println!("png pages: {pixels} pixels compared, max |difference| {worst} gray levels");
    assert!(pixels > 20_000, "{pixels}");
    assert!(worst <= 1, "max difference {worst}");
}

/// Verifies: VTSM-CLI-026
#[test]
fn four_jpeg_pages_render_like_the_original_up_to_jpeg_loss() {
    let d = dir("jpeg");
    let (one, four) = write_pair(&d, &|q| format!("page{q}.jpg"), &|p, img, _| {
        write_jpeg(p, img, 95)
    });
    let a = mesh::load_mesh_at(&one, Some([0.0; 3])).unwrap();
    let b = mesh::load_mesh_at(&four, Some([0.0; 3])).unwrap();
    let (worst, pixels) = compare_renders(&a, &b);
    println!("jpeg q95 pages: {pixels} pixels compared, max |difference| {worst} gray levels");
    assert!(pixels > 20_000, "{pixels}");
    // JPEG loses a little; a wrong page or a shifted texel would cost tens of levels.
    assert!(worst <= 12, "max difference {worst}");
    assert!(
        worst > 0,
        "JPEG is lossy: identical renders mean the pages were not used"
    );
}

/// The same mask mesh marks the same triangles of the original and of the paged
/// mesh (matching is by position; the pages and their seams do not matter).
///
/// Verifies: VTSM-CLI-027
#[test]
fn mask_matching_is_unchanged_by_pages_and_per_corner_uvs() {
    let d = dir("mask");
    let (one, four) = write_pair(&d, &|q| format!("page{q}.png"), &|p, img, _| {
        write_png(p, img, true).unwrap()
    });
    let (verts, tris, _, quad) = ground();
    // Mask: the triangles of quadrant 3, renumbered vertices, rotated corners.
    let mut s = String::new();
    let mut nv = 0;
    for (t, q) in tris.iter().zip(&quad) {
        if *q != 3 {
            continue;
        }
        for k in [1usize, 2, 0] {
            let v = verts[t[k] as usize];
            s += &format!("v {} {} {}\n", v[0], v[1], v[2]);
        }
        s += &format!("f {} {} {}\n", nv + 1, nv + 2, nv + 3);
        nv += 3;
    }
    let k = d.join("mask.obj");
    std::fs::write(&k, s).unwrap();
    let geo = mesh::load_geometry(&k).unwrap();
    let mut a = mesh::load_mesh_at(&one, Some([0.0; 3])).unwrap();
    let mut b = mesh::load_mesh_at(&four, Some([0.0; 3])).unwrap();
    let sa = a.apply_mask(&geo, &k).unwrap();
    let sb = b.apply_mask(&geo, &k).unwrap();
    assert_eq!(sa, sb);
    assert_eq!(sb.marked, 2 * CELLS * CELLS);
    assert_eq!(a.mask, b.mask);
    for (m, q) in b.mask.iter().zip(&quad) {
        assert_eq!(*m, *q == 3);
    }
    // Renders agree including the mask depth (asserted inside).
    let (worst, _) = compare_renders(&a, &b);
    assert!(worst <= 1);
}

/// Two flat quads side by side, each using the whole of its page (corners on the
/// page edges: the worst case for bleeding), pages of constant, very different gray.
///
/// Verifies: VTSM-CLI-026
#[test]
fn no_gray_bleeds_across_page_borders() {
    let d = dir("bleed");
    let (dark, light) = (20u8, 230u8);
    write_png(&d.join("dark.png"), &Gray8::filled(16, 16, dark), true).unwrap();
    write_png(&d.join("light.png"), &Gray8::filled(16, 16, light), true).unwrap();
    std::fs::write(
        d.join("m.mtl"),
        "newmtl dark\nmap_Kd dark.png\nnewmtl light\nmap_Kd light.png\n",
    )
    .unwrap();
    let obj = "mtllib m.mtl\n\
        v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\n\
        vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
        usemtl dark\nf 1/1 2/2 3/3 4/4\n\
        usemtl light\nf 2/1 5/2 6/3 3/4\n";
    let p = d.join("m.obj");
    std::fs::write(&p, obj).unwrap();
    let m = mesh::load_mesh_at(&p, Some([0.0; 3])).unwrap();
    // Both 16² pages are in the atlas, each in a 20² rectangle (2 gutter texels a
    // side), the two rectangles touching.
    let (w, h) = (m.texture.width, m.texture.height);
    assert_eq!((w * h, w.max(h)), (800, 40));
    let bytes = m.encode_map(0.5).unwrap();
    let map = MapView::new_checked(&bytes).unwrap();
    let mut seen = [0usize; 2];
    for (eye, target) in [
        ([1.0, 0.5, 0.6], [1.0, 0.5, 0.0]),
        ([1.0, -0.5, 0.8], [1.0, 0.5, 0.0]),
        ([0.2, 1.3, 0.5], [1.0, 0.0, 0.0]),
        ([1.05, 0.5, 0.15], [1.0, 0.5, 0.0]),
    ] {
        let (i, dep, _) = render(&map, eye, target);
        for (v, z) in i.iter().zip(&dep) {
            if *z == DEPTH_NONE {
                continue;
            }
            assert!(*v == dark || *v == light, "gray {v} from {eye:?}");
            seen[usize::from(*v == light)] += 1;
        }
    }
    assert!(seen[0] > 1000 && seen[1] > 1000, "{seen:?}");
}

/// Verifies: VTSM-CLI-028
#[test]
fn ply_texnumber_pages_build_the_same_map_as_the_obj() {
    let d = dir("ply");
    let (_, four) = write_pair(&d, &|q| format!("page{q}.png"), &|p, img, _| {
        write_png(p, img, true).unwrap()
    });
    let (verts, tris, uvs, quad) = ground();
    let mut s = String::from("ply\nformat ascii 1.0\ncomment made by a test\n");
    // Pages listed in the order the OBJ's faces first use them (its page order),
    // so both files describe the same atlas.
    let order = [2u32, 3, 0, 1];
    for q in order {
        s += &format!("comment TextureFile tex/page{q}.png\n");
    }
    s += &format!(
        "element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         element face {}\nproperty list uchar int vertex_indices\n\
         property list uchar float texcoord\nproperty int texnumber\nend_header\n",
        verts.len(),
        tris.len()
    );
    for v in &verts {
        s += &format!("{} {} {}\n", v[0], v[1], v[2]);
    }
    for ((t, uv), q) in tris.iter().zip(&uvs).zip(&quad) {
        let c = uv.map(|c| to_page(c, *q));
        let tn = order.iter().position(|o| o == q).unwrap();
        s += &format!(
            "3 {} {} {} 6 {} {} {} {} {} {} {tn}\n",
            t[0], t[1], t[2], c[0][0], c[0][1], c[1][0], c[1][1], c[2][0], c[2][1]
        );
    }
    let ply = four.parent().unwrap().join("m.ply");
    std::fs::write(&ply, &s).unwrap();
    let a = mesh::load_mesh_at(&four, Some([0.0; 3])).unwrap();
    let b = mesh::load_mesh_at(&ply, Some([0.0; 3])).unwrap();
    assert_eq!(a.vertices, b.vertices);
    assert_eq!(a.triangles, b.triangles);
    assert_eq!(a.texture, b.texture);
    assert_eq!(a.uvs, b.uvs);
    let (ea, eb) = (a.encode_map(0.5).unwrap(), b.encode_map(0.5).unwrap());
    assert!(
        ea == eb,
        "PLY and OBJ map products differ ({} vs {} bytes)",
        ea.len(),
        eb.len()
    );

    // Several textures but no texnumber; a texnumber beyond the textures.
    let no_tn = s
        .replace("property int texnumber\n", "")
        .lines()
        .map(|l| {
            if l.starts_with("3 ") {
                l.rsplit_once(' ').unwrap().0.to_string()
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
        + "\n";
    std::fs::write(&ply, no_tn).unwrap();
    let e = mesh::load_mesh_at(&ply, Some([0.0; 3])).unwrap_err();
    assert!(e.msg.contains("no `texnumber`"), "{e}");
    let bad = s.replacen(" 3\n", " 4\n", 1);
    let first_bad = bad
        .lines()
        .position(|l| l.starts_with("3 ") && l.ends_with(" 4"))
        .unwrap();
    std::fs::write(&ply, bad).unwrap();
    let e = mesh::load_mesh_at(&ply, Some([0.0; 3])).unwrap_err();
    assert!(e.msg.contains("texnumber 4 out of range"), "{e}");
    assert_eq!(e.line, Some(first_bad + 1), "{e}");
}

/// Verifies: VTSM-CLI-029
#[test]
fn map_kd_scale_and_offset_are_applied_and_unsupported_options_refused() {
    let d = dir("options");
    write_png(&d.join("t.png"), &Gray8::filled(4, 4, 9), true).unwrap();
    let obj = "mtllib m.mtl\nusemtl a\nv 0 0 0\nv 1 0 0\nv 1 1 0\n\
               vt 0 0\nvt 1 0\nvt 1 1\nf 1/1 2/2 3/3\n";
    let p = d.join("m.obj");
    std::fs::write(&p, obj).unwrap();
    std::fs::write(
        d.join("m.mtl"),
        "newmtl a\nmap_Kd -s 0.5 0.25 1 -o 0.25 0.5 t.png\n",
    )
    .unwrap();
    let m = mesh::load_mesh_at(&p, Some([0.0; 3])).unwrap();
    assert_eq!(m.uvs[0], [[0.25, 0.5], [0.75, 0.5], [0.75, 0.75]]);
    for (opt, why) in [("-mm 0 1", "gray levels"), ("-imfchan r", "channel")] {
        std::fs::write(d.join("m.mtl"), format!("newmtl a\n\nmap_Kd {opt} t.png\n")).unwrap();
        let e = mesh::load_mesh_at(&p, Some([0.0; 3])).unwrap_err();
        assert_eq!(e.file.as_deref(), Some(d.join("m.mtl").as_path()), "{e}");
        assert_eq!(e.line, Some(3), "{e}");
        assert!(
            e.msg.contains("not supported") && e.msg.contains(why),
            "{e}"
        );
    }
}

/// Verifies: VTSM-CLI-026
#[test]
fn multi_page_obj_refuses_untextured_faces() {
    let d = dir("untextured");
    write_png(&d.join("a.png"), &Gray8::filled(4, 4, 1), true).unwrap();
    write_png(&d.join("b.png"), &Gray8::filled(4, 4, 2), true).unwrap();
    std::fs::write(
        d.join("m.mtl"),
        "newmtl a\nmap_Kd a.png\nnewmtl b\nmap_Kd b.png\nnewmtl plain\nKd 1 1 1\n",
    )
    .unwrap();
    let head = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\n";
    let p = d.join("m.obj");
    std::fs::write(
        &p,
        format!(
            "{head}usemtl a\nf 1/1 2/2 3/3\nusemtl plain\nf 1/1 2/2 3/3\nusemtl b\nf 1/1 2/2 3/3\n"
        ),
    )
    .unwrap();
    let e = mesh::load_mesh_at(&p, Some([0.0; 3])).unwrap_err();
    assert_eq!(e.line, Some(11), "{e}");
    assert!(
        e.msg.contains("without map_Kd") && e.msg.contains("2 texture pages"),
        "{e}"
    );
    // Without usemtl, two textured materials cannot be assigned to faces.
    std::fs::write(&p, format!("{head}f 1/1 2/2 3/3\n")).unwrap();
    let e = mesh::load_mesh_at(&p, Some([0.0; 3])).unwrap_err();
    assert!(e.msg.contains("no face selects one"), "{e}");
}

/// Verifies: VTSM-CLI-031
#[test]
fn meshes_above_the_product_capacity_are_refused_with_a_code() {
    use vtsm_core::config::{MAX_MAP_TRIANGLES, MAX_MAP_VERTICES};
    let p = Path::new("big.obj");
    assert!(mesh::check_capacity(p, MAX_MAP_VERTICES, MAX_MAP_TRIANGLES).is_ok());
    let e = mesh::check_capacity(p, 3, MAX_MAP_TRIANGLES + 1).unwrap_err();
    assert_eq!(e.code, Some(vtsm_core::FailureCode::MapCountOutOfRange));
    assert_eq!(e.file.as_deref(), Some(p));
    assert!(
        e.msg
            .contains(&format!("{} triangles", MAX_MAP_TRIANGLES + 1))
            && e.msg.contains("MAX_MAP_TRIANGLES")
            && e.msg.contains("0x0305"),
        "{e}"
    );
    let e = mesh::check_capacity(p, MAX_MAP_VERTICES + 1, 1).unwrap_err();
    assert!(e.msg.contains("MAX_MAP_VERTICES"), "{e}");
}

/// The example in the ICD builds, with both pages in the atlas.
///
/// Verifies: VTSM-CLI-026
#[test]
fn icd_two_page_example_builds_a_map() {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fsw-docs/interfaces/examples/two-pages/m.obj");
    let m = mesh::load_mesh_at(&p, Some([0.0; 3])).unwrap();
    assert_eq!(m.triangles.len(), 4);
    // Two 8² pages used to their edges: two 12² rectangles.
    let (w, h) = (m.texture.width, m.texture.height);
    assert_eq!((w * h, w.max(h)), (288, 24));
    let bytes = m.encode_map(0.5).unwrap();
    let map = MapView::new_checked(&bytes).unwrap();
    // Rock faces sample the dark page (40..=50), sand faces the light one (200..=205).
    for i in 0..map.triangle_count() {
        let t = map.triangle(i).unwrap();
        let rock = (0..3).all(|k| map.vertex(t.v[k]).unwrap().x <= 1.0);
        let c =
            t.uv.iter()
                .fold([0f32; 2], |a, c| [a[0] + c[0] / 3.0, a[1] + c[1] / 3.0]);
        let g = map
            .texture()
            .get(c[0].round() as usize, c[1].round() as usize)
            .unwrap();
        assert!(
            if rock {
                (40..=50).contains(&g)
            } else {
                (200..=205).contains(&g)
            },
            "{g}"
        );
    }
}

/// Through the binary: the two-page example builds (exit 0, one summary line on
/// stdout), and with stderr not a terminal no progress is drawn there.
///
/// Verifies: VTSM-CLI-026, VTSM-CLI-031
#[test]
fn map_build_cli_builds_the_two_page_example_quietly() {
    let d = dir("cli");
    let mesh = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fsw-docs/interfaces/examples/two-pages/m.obj");
    let out = d.join("two.vmap");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_vtsm"))
        .args(["map", "build", "--mesh"])
        .arg(&mesh)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    assert_eq!(o.status.code(), Some(0), "{stderr}");
    assert!(stderr.is_empty(), "{stderr}");
    assert_eq!(stdout.lines().count(), 1, "{stdout}");
    assert!(stdout.contains("4 triangles"), "{stdout}");
    let bytes = std::fs::read(&out).unwrap();
    assert!(MapView::new_checked(&bytes).is_ok());
}
