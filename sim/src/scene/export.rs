//! Writers for the design §5 scene files: `map.obj` + `map.mtl` + `map_texture.png`,
//! `mask.obj`, `calib.json`, `left.png`, `right.png`, `prior.json`, `truth.json`, and a
//! `scene.json` describing how the scene was made.
//!
//! Small, dependency-light writers (the readers live in `io`). Every float (OBJ vertices
//! and texture coordinates, calibration, poses) is written in the shortest decimal form
//! that reads back to the same `f32`, so `vtsm relocalize` on the exported files sees
//! bit for bit the data of the in-memory scene. Faces reference per-corner `vt` entries;
//! the mask OBJ repeats the same vertex list and holds only the masked faces.

use crate::error::{Error, Result};
use crate::io::mesh::MeshData;
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};
use vtsm_core::geom::{Pose, StereoRig};

/// Names of the files a scene export writes, in writing order.
pub const FILES: [&str; 10] = [
    "map.obj",
    "map.mtl",
    "map_texture.png",
    "mask.obj",
    "calib.json",
    "left.png",
    "right.png",
    "prior.json",
    "truth.json",
    "scene.json",
];

fn io_err(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::file(path, format!("cannot write: {e}"))
}

/// Write an 8-bit gray PNG.
pub fn write_png_gray(path: &Path, width: u32, height: u32, data: &[u8]) -> Result<()> {
    let img = image::GrayImage::from_raw(width, height, data.to_vec())
        .ok_or_else(|| Error::file(path, "image buffer does not match its size"))?;
    img.save_with_format(path, image::ImageFormat::Png)
        .map_err(|e| io_err(path, e))
}

/// The OBJ text of `mesh` (all faces, or only masked ones), referencing `mtl` if given.
pub fn obj_text(mesh: &MeshData, mtl: Option<&str>, masked_only: bool) -> String {
    let mut s = String::with_capacity(mesh.vertices.len() * 40 + mesh.triangles.len() * 120);
    if let Some(m) = mtl {
        let _ = writeln!(s, "mtllib {m}\nusemtl depot");
    }
    if mesh.origin == [0.0; 3] {
        for v in &mesh.vertices {
            let _ = writeln!(s, "v {} {} {}", v[0], v[1], v[2]);
        }
    } else {
        // Georeferenced: the user-frame coordinates, in f64.
        let o = mesh.origin;
        for v in &mesh.vertices {
            let u = [0, 1, 2].map(|k| f64::from(v[k]) + o[k]);
            let _ = writeln!(s, "v {} {} {}", u[0], u[1], u[2]);
        }
    }
    let mut vt = 0usize;
    for (k, tri) in mesh.triangles.iter().enumerate() {
        if masked_only && !mesh.mask.get(k).copied().unwrap_or(false) {
            continue;
        }
        if !masked_only {
            if let Some(uv) = mesh.uvs.get(k) {
                for c in uv {
                    let _ = writeln!(s, "vt {} {}", c[0], c[1]);
                }
            }
            let _ = writeln!(
                s,
                "f {}/{} {}/{} {}/{}",
                tri[0] + 1,
                vt + 1,
                tri[1] + 1,
                vt + 2,
                tri[2] + 1,
                vt + 3
            );
            vt += 3;
        } else {
            let _ = writeln!(s, "f {} {} {}", tri[0] + 1, tri[1] + 1, tri[2] + 1);
        }
    }
    s
}

fn write_text(path: &Path, text: &str) -> Result<()> {
    fs::write(path, text).map_err(|e| io_err(path, e))
}

/// An f32 as the f64 with the same shortest decimal form (0.4 stays 0.4 in JSON).
fn short(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(f64::from(x))
}

/// `{"world_from_left":{"t":[..],"q":[w,x,y,z]}}`.
pub fn pose_json(pose: &Pose) -> String {
    prior_json(pose, None)
}

/// [`pose_json`] with the capture-time sun as `prior.json`'s `sun` when
/// given.
pub fn prior_json(pose: &Pose, sun: Option<crate::relight::SunAngles>) -> String {
    let t = pose.t().map(short);
    let q = pose.q().map(short);
    match sun {
        None => serde_json::json!({"world_from_left": {"t": t, "q": q}}).to_string(),
        Some(s) => serde_json::json!({
            "world_from_left": {"t": t, "q": q},
            "sun": {"azimuth_deg": short(s.azimuth_deg), "elevation_deg": short(s.elevation_deg)}
        })
        .to_string(),
    }
}

/// `{"width":W,"height":H,"fx":..,"fy":..,"cx":..,"cy":..,"baseline_m":B}`.
pub fn calib_json(rig: &StereoRig) -> String {
    let c = rig.cam();
    serde_json::json!({
        "width": c.width(), "height": c.height(), "fx": short(c.fx()), "fy": short(c.fy()),
        "cx": short(c.cx()), "cy": short(c.cy()), "baseline_m": short(rig.baseline_m())
    })
    .to_string()
}

/// Everything a scene export writes.
#[derive(Clone, Debug)]
pub struct SceneFiles<'a> {
    /// The map product.
    pub map: &'a MeshData,
    /// The rig.
    pub rig: &'a StereoRig,
    /// Left image.
    pub left: &'a [u8],
    /// Right image.
    pub right: &'a [u8],
    /// Prior `world_from_left`.
    pub prior: &'a Pose,
    /// Truth `world_from_left`.
    pub truth: &'a Pose,
    /// Free-form description written to `scene.json`.
    pub meta: serde_json::Value,
    /// The capture-time sun, written into `prior.json` as its `sun` (`None`:
    /// a prior without one).
    pub sun: Option<crate::relight::SunAngles>,
}

/// Files of [`FILES`] that already exist in `dir`.
pub fn existing(dir: &Path) -> Vec<PathBuf> {
    FILES
        .iter()
        .map(|f| dir.join(f))
        .filter(|p| p.exists())
        .collect()
}

/// Write all scene files into `dir` (created if missing). Refuses, writing nothing, if
/// any of them exists and `force` is false.
pub fn write_scene(dir: &Path, files: &SceneFiles<'_>, force: bool) -> Result<()> {
    write_scene_with_calib(dir, files, &calib_json(files.rig), force)
}

/// [`write_scene`] with `calib.json` given as text (the OpenCV form of a
/// physical pair, whose images are `files.rig`'s size).
pub fn write_scene_with_calib(
    dir: &Path,
    files: &SceneFiles<'_>,
    calib_text: &str,
    force: bool,
) -> Result<()> {
    if !force {
        if let Some(p) = existing(dir).first() {
            return Err(Error::file(p, "already exists (use --force to overwrite)"));
        }
    }
    fs::create_dir_all(dir).map_err(|e| io_err(dir, e))?;
    let (w, h) = (files.rig.cam().width(), files.rig.cam().height());
    write_text(
        &dir.join("map.obj"),
        &obj_text(files.map, Some("map.mtl"), false),
    )?;
    write_text(
        &dir.join("map.mtl"),
        "newmtl depot\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nillum 1\nmap_Kd map_texture.png\n",
    )?;
    let tex = &files.map.texture;
    write_png_gray(
        &dir.join("map_texture.png"),
        tex.width,
        tex.height,
        &tex.pixels,
    )?;
    write_text(&dir.join("mask.obj"), &obj_text(files.map, None, true))?;
    write_text(&dir.join("calib.json"), calib_text)?;
    write_png_gray(&dir.join("left.png"), w, h, files.left)?;
    write_png_gray(&dir.join("right.png"), w, h, files.right)?;
    write_text(&dir.join("prior.json"), &prior_json(files.prior, files.sun))?;
    write_text(&dir.join("truth.json"), &pose_json(files.truth))?;
    write_text(&dir.join("scene.json"), &files.meta.to_string())?;
    Ok(())
}
