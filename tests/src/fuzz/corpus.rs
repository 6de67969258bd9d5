//! Seed corpora and fixed inputs of the fuzz targets.
//!
//! The seed files under `tests/fuzz/corpus/<target>/` are written by
//! [`generate`] (`fuzz --make-corpus tests/fuzz/corpus`) from the builders
//! here, so they can be remade; crash regressions are added there by hand
//! and are never overwritten. [`load`] reads a target's directory plus the
//! interface examples the target names (`fsw-docs/interfaces/examples/`).

use super::targets::MTL_SEPARATOR;
use super::FuzzTarget;
use crate::testkit::{self, GridMesh};
use std::path::Path;
use vtsm_core::geom::{Pose, StereoRig};
use vtsm_core::image::{GrayView, Rect};
use vtsm_core::map::{MapSource, MapView};
use vtsm_core::raster::{self, Target};
use vtsm_core::rng::Rng;

/// Texture pages of the interface example (`two-pages`), and a third one.
pub fn textures() -> Vec<(&'static str, Vec<u8>)> {
    vec![
        (
            "rock.png",
            include_bytes!("../../../fsw-docs/interfaces/examples/two-pages/rock.png").to_vec(),
        ),
        (
            "sand.png",
            include_bytes!("../../../fsw-docs/interfaces/examples/two-pages/sand.png").to_vec(),
        ),
        ("tex.png", png(&noise_image(16, 16, 5))),
    ]
}

fn noise_image(w: u32, h: u32, seed: u64) -> vtsm_sim::io::image::Gray8 {
    let mut rng = Rng::new(seed);
    vtsm_sim::io::image::Gray8 {
        width: w,
        height: h,
        pixels: (0..w * h).map(|_| rng.next_u32() as u8).collect(),
    }
}

fn png(img: &vtsm_sim::io::image::Gray8) -> Vec<u8> {
    vtsm_sim::io::image::encode_png(img).unwrap_or_default()
}

/// A small map product: a 9×9-vertex bumpy heightfield over [0, 4] × [-2, 2] m
/// (the test kit's [`testkit::grid_mesh`]; 128 triangles, all in M̂; the last
/// row of triangles outside it in variants 1 and 2), a 64×64 noise texture
/// (16×16 in variants 1 and 2), 1 m tiles; variant 2 carries sampling
/// scores (version 3).
pub fn tiny_map_variant(variant: u32) -> Vec<u8> {
    let n = 9usize;
    let GridMesh {
        vertices,
        triangles,
        uvs,
    } = testkit::grid_mesh(n, 4.0, |x, y| {
        0.08 * libm::sinf(2.1 * x) * libm::cosf(1.7 * y)
    });
    let mask: Vec<bool> = (0..triangles.len())
        .map(|k| variant == 0 || k < triangles.len() - 2 * (n - 1))
        .collect();
    let tex_side = if variant == 0 { 64 } else { 16 };
    let mut rng = Rng::new(11 + u64::from(variant));
    // Blocky noise: 4×4-texel cells, so templates have structure at image scale.
    let cells: Vec<u8> = (0..tex_side * tex_side / 16)
        .map(|_| rng.next_u32() as u8)
        .collect();
    let texture: Vec<u8> = (0..tex_side * tex_side)
        .map(|k| {
            let (x, y) = (k % tex_side / 4, k / tex_side / 4);
            cells[y * (tex_side / 4) + x]
        })
        .collect();
    let Ok(tex) = GrayView::new(&texture, tex_side, tex_side, tex_side) else {
        return Vec::new();
    };
    // Variant 2: variant 1 with sampling scores (a version-3 product),
    // zero on every fifth vertex.
    let scores: Vec<u8> = (0..vertices.len()).map(|k| (k % 5) as u8 * 60).collect();
    let src = MapSource {
        vertices: &vertices,
        triangles: &triangles,
        uvs: &uvs,
        mask: &mask,
        texture: tex,
        tile_size_m: 1.0,
        origin: [0.0; 3],
        vertex_scores: (variant == 2).then_some(scores.as_slice()),
    };
    let Ok(len) = vtsm_core::map::encoded_len(&src) else {
        return Vec::new();
    };
    let mut out = vec![0u8; len];
    match vtsm_core::map::encode(&src, &mut out) {
        Ok(n) => {
            out.truncate(n);
            out
        }
        Err(_) => Vec::new(),
    }
}

/// [`tiny_map_variant`] 0.
pub fn tiny_map() -> Vec<u8> {
    tiny_map_variant(0)
}

fn render_full(map: &MapView, rig: &StereoRig, pose: &Pose) -> Vec<u8> {
    let (w, h) = (rig.cam().width() as usize, rig.cam().height() as usize);
    let (mut inten, mut depth, mut md) = (vec![0u8; w * h], vec![0u32; w * h], vec![0u32; w * h]);
    let mut t = Target {
        intensity: &mut inten,
        depth: &mut depth,
        mask_depth: &mut md,
    };
    let _ = raster::render_window(
        map,
        &rig.cam(),
        pose,
        Rect::new(0, 0, w as u32, h as u32),
        &mut t,
    );
    inten
}

/// The stereo pair of `map` seen by `rig` from `truth` (left, right); blank
/// images if the map is rejected.
pub fn render_pair(map: &[u8], rig: &StereoRig, truth: &Pose) -> (Vec<u8>, Vec<u8>) {
    let n = rig.cam().width() as usize * rig.cam().height() as usize;
    let Ok(m) = MapView::new_checked(map) else {
        return (vec![0; n], vec![0; n]);
    };
    (
        render_full(&m, rig, truth),
        render_full(&m, rig, &rig.world_from_right(truth)),
    )
}

fn pgm(img: &vtsm_sim::io::image::Gray8, binary: bool) -> Vec<u8> {
    let mut s = format!(
        "{}\n# seed\n{} {}\n255\n",
        if binary { "P5" } else { "P2" },
        img.width,
        img.height
    )
    .into_bytes();
    if binary {
        s.extend_from_slice(&img.pixels);
    } else {
        for row in img.pixels.chunks(img.width as usize) {
            let line: Vec<String> = row.iter().map(|v| v.to_string()).collect();
            s.extend_from_slice(line.join(" ").as_bytes());
            s.push(b'\n');
        }
    }
    s
}

fn encode_with(img: &vtsm_sim::io::image::Gray8, fmt: image::ImageFormat) -> Vec<u8> {
    let Some(buf) = image::GrayImage::from_raw(img.width, img.height, img.pixels.clone()) else {
        return Vec::new();
    };
    let mut out = std::io::Cursor::new(Vec::new());
    if buf.write_to(&mut out, fmt).is_err() {
        return Vec::new();
    }
    out.into_inner()
}

const OBJ_TRI: &str = "# two triangles and a quad, positive and negative indices\n\
v 0 0 0\nv 1 0 0\nv 1 1 0.1\nv 0 1 0\nv 2 0 0 0.5 0.5 0.5\n\
vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n\
o patch\ng g1\ns off\n\
f 1/1/1 2/2/1 3/3/1\nf -4/-4 -2/-2 -1/-1\nf 2/2 5/1 3/3 4/4\n";

const OBJ_COLOUR: &str = "v 0 0 0 1 0 0\nv 1 0 0 0 255 0\nv 1 1 0 0 0 1\nv 0 1 0.2 0.5 0.5 0.5\n\
f 1 2 3\nf 1//1 3//1 4//1\n";

const OBJ_TEX: &str = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0.05\nv 0 1 0\n\
vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl tex\nf 1/1 2/2 3/3 4/4\n";

const MTL_TEX: &str =
    "# one textured material\nnewmtl tex\nKd 1 1 1\nmap_Kd -s 1 1 1 -o 0 0 -clamp on tex.png\nnewmtl plain\n";

const PLY_ASCII: &str = "ply\nformat ascii 1.0\ncomment TextureFile tex.png\n\
element vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
property float u\nproperty float v\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
element face 2\nproperty list uchar int vertex_indices\nend_header\n\
0 0 0 0 0 255 0 0\n1 0 0 1 0 0 255 0\n1 1 0.1 1 1 0 0 255\n0 1 0 0 1 128 128 128\n\
3 0 1 2\n3 0 2 3\n";

fn ply_binary(big: bool) -> Vec<u8> {
    let fmt = if big {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    let mut out = format!(
        "ply\nformat {fmt} 1.0\ncomment TextureFile rock.png\ncomment TextureFile sand.png\n\
         element vertex 4\nproperty float x\nproperty float y\nproperty double z\n\
         element face 2\nproperty list uchar uint vertex_indices\nproperty list uchar float texcoord\n\
         property int texnumber\nelement extra 1\nproperty short k\nend_header\n"
    )
    .into_bytes();
    let f = |out: &mut Vec<u8>, v: f32| {
        out.extend_from_slice(&if big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        })
    };
    for (x, y, z) in [
        (0.0f32, 0.0f32, 0.0f32),
        (1.0, 0.0, 0.0),
        (1.0, 1.0, 0.1),
        (0.0, 1.0, 0.0),
    ] {
        f(&mut out, x);
        f(&mut out, y);
        let z = f64::from(z);
        out.extend_from_slice(&if big {
            z.to_be_bytes()
        } else {
            z.to_le_bytes()
        });
    }
    for (k, tri) in [[0u32, 1, 2], [0, 2, 3]].iter().enumerate() {
        out.push(3);
        for i in tri {
            out.extend_from_slice(&if big {
                i.to_be_bytes()
            } else {
                i.to_le_bytes()
            });
        }
        out.push(6);
        for v in [0.0f32, 0.0, 1.0, 0.0, 1.0, 1.0] {
            f(&mut out, v);
        }
        let page = k as i32;
        out.extend_from_slice(&if big {
            page.to_be_bytes()
        } else {
            page.to_le_bytes()
        });
    }
    out.extend_from_slice(&[0, 7]);
    out
}

/// Structured seeds of a stage target: zeros, ones and a few random strings.
fn stage_seeds(n: usize, count: u64, salt: u64) -> Vec<Vec<u8>> {
    let mut v = vec![vec![0u8; n], vec![0xffu8; n]];
    for s in 0..count {
        let mut rng = Rng::new(salt + s);
        v.push((0..n).map(|_| rng.next_u32() as u8).collect());
    }
    v
}

/// The generated seed files of every target: (target, file name, bytes).
pub fn seeds() -> Vec<(&'static str, String, Vec<u8>)> {
    let mut out: Vec<(&'static str, String, Vec<u8>)> = Vec::new();
    let mut add =
        |t: &'static str, name: &str, bytes: Vec<u8>| out.push((t, name.to_string(), bytes));
    add("map", "tiny.vmap", tiny_map());
    add("map", "tiny-masked.vmap", tiny_map_variant(1));
    add("map", "tiny-scored.vmap", tiny_map_variant(2));
    add("obj", "patch.obj", OBJ_TRI.as_bytes().to_vec());
    add("obj", "colour.obj", OBJ_COLOUR.as_bytes().to_vec());
    let join = |a: &[u8], b: &[u8]| [a, MTL_SEPARATOR, b].concat();
    add(
        "obj_mtl",
        "tex.objmtl",
        join(OBJ_TEX.as_bytes(), MTL_TEX.as_bytes()),
    );
    add(
        "obj_mtl",
        "two-pages.objmtl",
        join(
            include_bytes!("../../../fsw-docs/interfaces/examples/two-pages/m.obj"),
            include_bytes!("../../../fsw-docs/interfaces/examples/two-pages/m.mtl"),
        ),
    );
    add("ply", "ascii.ply", PLY_ASCII.as_bytes().to_vec());
    add("ply", "le.ply", ply_binary(false));
    add("ply", "be.ply", ply_binary(true));
    add(
        "calib",
        "rectified.json",
        b"{\"width\": 640, \"height\": 480, \"fx\": 457.0, \"fy\": 457.0, \"cx\": 319.5, \"cy\": 239.5, \"baseline_m\": 0.3}\n".to_vec(),
    );
    add(
        "prior",
        "prior.json",
        b"{\"world_from_left\": {\"t\": [1.20, -0.35, 1.10], \"q\": [0.70711, 0.0, 0.0, 0.70711]}}\n"
            .to_vec(),
    );
    add(
        "result",
        "result.json",
        b"{\"status\": \"ok\", \"failure\": null,\n \"world_from_left\": {\"t\": [1.2, -0.35, 1.1], \"q\": [1, 0, 0, 0]},\n \"inliers\": 87, \"iterations\": 5, \"stats\": {\"attempts\": 123, \"renders\": 7},\n \"covariance\": null}\n"
            .to_vec(),
    );
    add(
        "pairs",
        "one.jsonl",
        b"{\"left\": \"l.png\", \"right\": \"r.png\", \"prior\": \"p.json\", \"seed\": 18446744073709551615}\n\n"
            .to_vec(),
    );
    let img = noise_image(12, 9, 3);
    add("image", "noise.png", png(&img));
    add("image", "noise.pgm", pgm(&img, true));
    add("image", "noise-ascii.pgm", pgm(&img, false));
    add(
        "image",
        "noise.jpg",
        encode_with(&img, image::ImageFormat::Jpeg),
    );
    add(
        "image",
        "noise.tif",
        encode_with(&img, image::ImageFormat::Tiff),
    );
    for (k, s) in stage_seeds(64, 4, 100).into_iter().enumerate() {
        add("image_view", &format!("s{k}.bin"), s);
    }
    for (k, s) in stage_seeds(128, 6, 200).into_iter().enumerate() {
        add("ncc", &format!("s{k}.bin"), s);
    }
    for (k, s) in stage_seeds(96, 6, 300).into_iter().enumerate() {
        add("reloc", &format!("s{k}.bin"), s);
    }
    for (k, mut s) in stage_seeds(64, 4, 400).into_iter().enumerate() {
        if k % 2 == 1 {
            s.extend_from_slice(&tiny_map_variant(1));
        }
        add("render", &format!("s{k}.bin"), s);
    }
    out
}

/// Write the generated seeds under `dir/<target>/` (existing files of other
/// names, such as crash regressions, are kept).
///
/// # Errors
/// A directory or file cannot be written.
pub fn generate(dir: &Path) -> std::io::Result<usize> {
    let seeds = seeds();
    for (t, name, bytes) in &seeds {
        let d = dir.join(t);
        std::fs::create_dir_all(&d)?;
        std::fs::write(d.join(name), bytes)?;
    }
    Ok(seeds.len())
}

/// The seed inputs of `t`: every file of `dir/<t.name>/` (sorted by name),
/// then its extra seeds (relative to `root`).
pub fn load(t: &FuzzTarget, dir: &Path, root: &Path) -> Vec<Vec<u8>> {
    let mut files: Vec<_> = std::fs::read_dir(dir.join(t.name))
        .map(|rd| {
            rd.flatten()
                .map(|e| e.path())
                .filter(|p| p.is_file())
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    files.extend(t.extra_seeds.iter().map(|p| root.join(p)));
    files.iter().filter_map(|p| std::fs::read(p).ok()).collect()
}
