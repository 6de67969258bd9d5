//! `flight_bundle SCENE OUT`: the inputs of the flight-profile firmware run.
//!
//! `SCENE` is a directory written by `vtsm scene export` with the map product
//! `map.vmap` built from it by `vtsm map build`. The bundle holds what a rover
//! would carry into the relocalization:
//!
//! - `map.vmap`: the map product cropped to the part of the depot that can be
//!   in view from the prior region (every triangle with a corner that projects
//!   into the image widened by [`MARGIN`] on each side, in front of the
//!   camera and nearer than [`MAX_DEPTH_M`], from the prior and from the
//!   prior moved by ±t₀ along each axis), with its texture cropped to the
//!   texels those triangles use (plus a border of [`TEXEL_BORDER`]);
//! - `left.gray`, `right.gray`: the stereo pair, 8-bit, row-major;
//! - `scene.rs`: the calibration, prior, truth, seed and the digest of the
//!   host's relocalization on exactly these inputs, as Rust constants.
//!
//! The host digest comes from [`vtsm_sim::locate::relocalize`], the desktop
//! runner path, folded the way the firmware folds its outcome
//! ([`vtsm_tests::outcome_digest`]); the firmware image built with
//! `VTSM_FLIGHT_BUNDLE=OUT` prints its own, which must be equal. The tool
//! also relocalizes on the full map and prints both results: the crop changes
//! the mask vertices the engine draws its samples from, so the two runs
//! differ in their draws, not in what the cameras can see.
#![allow(clippy::print_stdout, clippy::print_stderr)]

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use vtsm_core::geom::{Pose, Vec3};
use vtsm_core::image::GrayView;
use vtsm_core::map::{MapSource, MapView};
use vtsm_sim::io::{image::read_gray_sized, json, read_file, write_atomic};
use vtsm_sim::locate::{self, MapIn, Request, RunOptions};

/// Image widening for the crop, fraction of the image size on each side.
const MARGIN: f32 = 0.15;
/// Depth beyond which a triangle is dropped, metres.
const MAX_DEPTH_M: f32 = 6.0;
/// Texels kept around the used part of the texture.
const TEXEL_BORDER: i64 = 8;
/// Seed of the relocalization (the `vtsm relocalize` default).
const SEED: u64 = 1;

fn main() -> ExitCode {
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    let [scene, out] = args.as_slice() else {
        eprintln!("usage: flight_bundle SCENE_DIR OUT_DIR");
        return ExitCode::from(2);
    };
    match run(scene, out) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("flight_bundle: {e}");
            ExitCode::from(2)
        }
    }
}

fn run(scene: &Path, out: &Path) -> Result<(), String> {
    let s = |e: vtsm_sim::Error| e.to_string();
    let calib = json::read_calib(&scene.join("calib.json")).map_err(s)?;
    let rig = calib.rig().map_err(|c| format!("calib.json: {c:?}"))?;
    let prior = json::read_pose(&scene.join("prior.json")).map_err(s)?;
    let truth = json::read_pose(&scene.join("truth.json")).map_err(s)?;
    let (w, h) = (calib.width, calib.height);
    let left = read_gray_sized(&scene.join("left.png"), w, h).map_err(s)?;
    let right = read_gray_sized(&scene.join("right.png"), w, h).map_err(s)?;
    let full_bytes = read_file(&scene.join("map.vmap")).map_err(s)?;
    let map = MapView::new_checked(&full_bytes).map_err(|c| format!("map.vmap: {c:?}"))?;
    let params = locate::params_for_width(w);

    let cropped = crop(&map, &rig, &prior, params.t0_m)?;
    let request = |map| {
        Request::new(MapIn::Bytes(map), &left.pixels, &right.pixels, rig, prior)
            .with_params(params)
            .with_seed(SEED)
    };
    let full = locate::relocalize(&request(&full_bytes), RunOptions::default())
        .map_err(s)?
        .outcome;
    let (f1, fr1) = full.pose.error_to(&truth);
    println!(
        "host, full map: failure {:?}, final error {:.1} mm ({:.3}°), {} attempts",
        full.failure,
        f1 * 1e3,
        fr1.to_degrees(),
        full.stats.attempts
    );
    let report = locate::relocalize(&request(&cropped), RunOptions::default()).map_err(s)?;
    let o = &report.outcome;
    let digest = vtsm_tests::outcome_digest(o);
    let (e0, _) = prior.error_to(&truth);
    let (e1, r1) = o.pose.error_to(&truth);
    println!(
        "host, cropped map {} -> {} bytes: failure {:?}, error {:.1} mm -> {:.1} mm ({:.3}°), {} attempts, digest {digest:016x}",
        full_bytes.len(),
        cropped.len(),
        o.failure,
        e0 * 1e3,
        e1 * 1e3,
        r1.to_degrees(),
        o.stats.attempts
    );

    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let wr = |name: &str, bytes: &[u8]| write_atomic(&out.join(name), bytes, true).map_err(s);
    wr("map.vmap", &cropped)?;
    wr("left.gray", &left.pixels)?;
    wr("right.gray", &right.pixels)?;
    let pose = |p: &Pose| {
        let (t, q) = (p.t(), p.q());
        format!(
            "([{:?}, {:?}, {:?}], [{:?}, {:?}, {:?}, {:?}])",
            t[0], t[1], t[2], q[0], q[1], q[2], q[3]
        )
    };
    let c = rig.cam();
    let text = format!(
        "// Generated by `cargo run -p vtsm-tests --bin flight_bundle -- {} {}`.\n\
         pub const WIDTH: usize = {w};\npub const HEIGHT: usize = {h};\n\
         pub const CAMERA: (f32, f32, f32, f32) = ({:?}, {:?}, {:?}, {:?});\n\
         pub const BASELINE_M: f32 = {:?};\n\
         /// (translation, quaternion [w, x, y, z]) of `world_from_left`.\n\
         pub const PRIOR: ([f32; 3], [f32; 4]) = {};\n\
         pub const TRUTH: ([f32; 3], [f32; 4]) = {};\n\
         pub const SEED: u64 = {SEED};\npub const MAP_LEN: usize = {};\n\
         pub const HOST_DIGEST: u64 = 0x{digest:016x};\n\
         pub const HOST_ATTEMPTS: u32 = {};\n",
        scene.display(),
        out.display(),
        c.fx(),
        c.fy(),
        c.cx(),
        c.cy(),
        rig.baseline_m(),
        pose(&prior),
        pose(&truth),
        cropped.len(),
        o.stats.attempts,
    );
    wr("scene.rs", text.as_bytes())?;
    println!("wrote {}", out.display());
    Ok(())
}

/// The map product re-encoded with only the triangles that can be in view
/// from the prior region, and the texture cropped to what they use.
fn crop(
    map: &MapView<'_>,
    rig: &vtsm_core::geom::StereoRig,
    prior: &Pose,
    t0: f32,
) -> Result<Vec<u8>, String> {
    let cam = rig.cam();
    let (wf, hf) = (cam.width() as f32, cam.height() as f32);
    let mut poses = vec![*prior];
    for axis in [Vec3::x(), Vec3::y(), Vec3::z()] {
        for sgn in [-1.0f32, 1.0] {
            poses.push(Pose::new(
                prior.rotation(),
                prior.translation() + axis * (sgn * t0),
            ));
        }
    }
    let cams: Vec<Pose> = poses.iter().map(Pose::inverse).collect();
    let in_view = |p: Vec3| {
        cams.iter().any(|c_from_w| {
            let q = c_from_w.transform_point(&p);
            if q.z <= 0.05 || q.z > MAX_DEPTH_M {
                return false;
            }
            let u = cam.fx() * q.x / q.z + cam.cx();
            let v = cam.fy() * q.y / q.z + cam.cy();
            (-MARGIN * wf..=(1.0 + MARGIN) * wf).contains(&u)
                && (-MARGIN * hf..=(1.0 + MARGIN) * hf).contains(&v)
        })
    };
    let n = map.triangle_count();
    let mut keep = Vec::new();
    for i in 0..n {
        let t = map.triangle(i).ok_or("triangle out of range")?;
        let v = map.triangle_vertices(i).ok_or("triangle out of range")?;
        if v.iter().any(|p| in_view(*p)) {
            keep.push(t);
        }
    }
    eprintln!("crop: {} of {n} triangles", keep.len());
    if keep.is_empty() {
        return Err("no triangle of the map is in view from the prior".into());
    }
    // Texture: the bounding box of the kept UVs (texel coordinates).
    let tex = map.texture();
    let (tw, th) = (tex.width() as i64, tex.height() as i64);
    let (mut x0, mut y0, mut x1, mut y1) = (i64::MAX, i64::MAX, i64::MIN, i64::MIN);
    for t in &keep {
        for c in t.uv {
            x0 = x0.min(c[0].floor() as i64);
            y0 = y0.min(c[1].floor() as i64);
            x1 = x1.max(c[0].ceil() as i64);
            y1 = y1.max(c[1].ceil() as i64);
        }
    }
    let (x0, y0) = ((x0 - TEXEL_BORDER).max(0), (y0 - TEXEL_BORDER).max(0));
    let (x1, y1) = (
        (x1 + TEXEL_BORDER).min(tw - 1),
        (y1 + TEXEL_BORDER).min(th - 1),
    );
    let (cw, ch) = ((x1 - x0 + 1) as usize, (y1 - y0 + 1) as usize);
    eprintln!("crop: texture {cw}x{ch} of {tw}x{th}");
    let mut texels = vec![0u8; cw * ch];
    for (y, row) in texels.chunks_exact_mut(cw).enumerate() {
        let src = tex.row(y0 as usize + y).ok_or("texture row out of range")?;
        row.copy_from_slice(&src[x0 as usize..x0 as usize + cw]);
    }
    // Vertices: only those the kept triangles use, renumbered.
    let mut remap = vec![u32::MAX; map.vertex_count() as usize];
    let mut vertices = Vec::new();
    let mut triangles = Vec::with_capacity(keep.len());
    let mut uvs = Vec::with_capacity(keep.len());
    let mut mask = Vec::with_capacity(keep.len());
    for t in &keep {
        let mut tri = [0u32; 3];
        for (k, &vi) in t.v.iter().enumerate() {
            let slot = &mut remap[vi as usize];
            if *slot == u32::MAX {
                let p = map.vertex(vi).ok_or("vertex out of range")?;
                *slot = vertices.len() as u32;
                vertices.push([p.x, p.y, p.z]);
            }
            tri[k] = *slot;
        }
        triangles.push(tri);
        // Stored texel coordinates back to the encoder's normalized UVs, in
        // the cropped texture.
        uvs.push(t.uv.map(|c| {
            [
                (c[0] - x0 as f32 + 0.5) / cw as f32,
                1.0 - (c[1] - y0 as f32 + 0.5) / ch as f32,
            ]
        }));
        mask.push(t.mask);
    }
    let texture = GrayView::new(&texels, cw, ch, cw).map_err(|c| format!("texture: {c:?}"))?;
    let src = MapSource {
        vertices: &vertices,
        triangles: &triangles,
        uvs: &uvs,
        mask: &mask,
        texture,
        tile_size_m: map.tile_grid().2,
        origin: map.origin(),
        vertex_scores: None,
    };
    let mut bytes = vec![0u8; vtsm_core::map::encoded_len(&src).map_err(|c| format!("{c:?}"))?];
    let n = vtsm_core::map::encode(&src, &mut bytes).map_err(|c| format!("encode: {c:?}"))?;
    bytes.truncate(n);
    Ok(bytes)
}
