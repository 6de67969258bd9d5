//! The fuzz targets: each takes arbitrary bytes, drives one reader or core
//! entry point, and says whether the input was accepted or with which error
//! it was rejected. A target panics only when the code under test does, or
//! when an invariant the API promises is broken (an accessor of an accepted
//! product failing, a template mask wider than its window, ...).

// A fuzz target reports a broken invariant by panicking, like an assert.
#![allow(clippy::panic)]

use super::{Env, Verdict};
use std::path::Path;
use vtsm_core::config::{Params, MAX_RENDER_PX};
use vtsm_core::geom::{Camera, Pose, StereoRig, Vec3};
use vtsm_core::image::{Gray16View, GrayView, GrayViewMut, Rect};
use vtsm_core::map::{self, MapView};
use vtsm_core::nalgebra::{Quaternion, Unit, UnitQuaternion};
use vtsm_core::ncc::{self, Filter, Run, Scratch, ScratchSizes, Search, SearchConfig};
use vtsm_core::raster::{self, Target};
use vtsm_core::reloc::{Setup, Workspace};
use vtsm_core::rng::Rng;
use vtsm_core::FailureCode;
use vtsm_sim::io;

/// Reads structured values off the front of an input; zeros once it runs out.
pub struct Take<'a> {
    d: &'a [u8],
    i: usize,
}

impl<'a> Take<'a> {
    /// A reader over `d`.
    pub fn new(d: &'a [u8]) -> Self {
        Self { d, i: 0 }
    }
    /// Next byte (0 past the end).
    pub fn u8(&mut self) -> u8 {
        let b = self.d.get(self.i).copied().unwrap_or(0);
        self.i += 1;
        b
    }
    /// Next little-endian u16.
    pub fn u16(&mut self) -> u16 {
        u16::from_le_bytes([self.u8(), self.u8()])
    }
    /// Next little-endian u32.
    pub fn u32(&mut self) -> u32 {
        u32::from_le_bytes([self.u8(), self.u8(), self.u8(), self.u8()])
    }
    /// Next little-endian u64.
    pub fn u64(&mut self) -> u64 {
        u64::from(self.u32()) | (u64::from(self.u32()) << 32)
    }
    /// A value in `lo..=hi` (one byte or two).
    pub fn range(&mut self, lo: u32, hi: u32) -> u32 {
        let span = hi.saturating_sub(lo);
        let v = if span < 256 {
            u32::from(self.u8())
        } else {
            u32::from(self.u16())
        };
        lo + v % (span + 1)
    }
    /// An arbitrary f32: one selector byte, then a special value, the raw bits
    /// of the next four bytes, or a value in `[lo, hi)`.
    pub fn f32(&mut self, lo: f32, hi: f32) -> f32 {
        const SPECIAL: [f32; 10] = [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            -0.0,
            0.0,
            f32::MAX,
            f32::MIN,
            1.0e-40,
            -1.0,
            1.0e20,
        ];
        match self.u8() {
            0..=9 => SPECIAL[usize::from(self.u8()) % SPECIAL.len()],
            10..=19 => f32::from_bits(self.u32()),
            _ => lo + (hi - lo) * (f32::from(self.u16()) / 65536.0),
        }
    }
    /// The bytes not read yet.
    pub fn rest(&self) -> &'a [u8] {
        self.d.get(self.i..).unwrap_or(&[])
    }
}

/// Label of a core failure code.
pub fn code_label(c: FailureCode) -> String {
    format!("0x{:04X} {}", c.code(), c.name())
}

/// Label of a simulator error: its failure code, or the kind of its message:
/// quoted text blanked, every word that is not plain letters (numbers, names,
/// garbage echoed from the input) replaced by `N` (runs of them by one), cut
/// before a `{` or `(` (debug dumps of a decoder's state) and at 8 words, so
/// one kind of error is one label.
pub fn error_label(e: &vtsm_sim::error::Error) -> String {
    let mut msg = String::new();
    let mut quote: Option<char> = None;
    if let Some(c) = e.code {
        return code_label(c);
    }
    for ch in e.msg.chars() {
        match quote {
            Some(q) if ch == q => quote = None,
            Some(_) => {}
            None if ch == '`' || ch == '"' => {
                quote = Some(ch);
                msg.push_str(" N ");
            }
            None => msg.push(ch),
        }
    }
    // serde_json appends the position; the kind is what comes before it.
    if let Some(k) = msg.find(" at line ") {
        msg.truncate(k);
    }
    let mut words: Vec<&str> = Vec::new();
    for w in msg.split_whitespace() {
        if w.starts_with('{') || w.starts_with('(') || words.len() == 8 {
            break;
        }
        let plain = w
            .trim_end_matches([',', '.', ':', ';'])
            .chars()
            .all(|c| c.is_ascii_alphabetic() || c == '-');
        let w = if plain { w } else { "N" };
        if !(w == "N" && words.last() == Some(&"N")) {
            words.push(w);
        }
    }
    words.join(" ")
}

fn sim_verdict<T>(r: &vtsm_sim::error::Result<T>) -> Verdict {
    match r {
        Ok(_) => Verdict::Accepted,
        Err(e) => Verdict::Rejected(error_label(e)),
    }
}

fn core_verdict<T>(r: &Result<T, FailureCode>) -> Verdict {
    match r {
        Ok(_) => Verdict::Accepted,
        Err(c) => Verdict::Rejected(code_label(*c)),
    }
}

// ---------------------------------------------------------------- map product

/// Walk every accessor of an accepted product (bounded), checking that each
/// in-range index answers.
fn walk_map(m: &MapView) -> u64 {
    let mut acc = 0u64;
    let cap = 1 << 14;
    for i in 0..m.vertex_count().min(cap) {
        let v = m.vertex(i);
        assert!(v.is_some(), "vertex {i} of an accepted map is missing");
        acc = acc.wrapping_add(v.map_or(0, |v| v.x.to_bits() as u64));
    }
    for i in 0..m.triangle_count().min(cap) {
        let t = m.triangle(i);
        assert!(t.is_some(), "triangle {i} of an accepted map is missing");
        assert!(
            m.triangle_vertices(i).is_some(),
            "triangle {i} of an accepted map has a missing vertex"
        );
    }
    for i in 0..m.tile_count().min(cap) {
        assert!(
            m.tile(i).is_some(),
            "tile {i} of an accepted map is missing"
        );
    }
    for k in 0..m.mask_vertex_count().min(cap) {
        let v = m.mask_vertex(k);
        assert!(
            v.is_some_and(|v| v < m.vertex_count()),
            "mask vertex {k} of an accepted map is missing or out of range"
        );
    }
    let _ = m.vertex(m.vertex_count());
    let _ = m.triangle(m.triangle_count());
    let _ = m.tile(m.tile_count());
    let _ = m.mask_vertex(m.mask_vertex_count());
    let _ = (m.bounds(), m.origin(), m.tile_grid(), m.version());
    let tex = m.texture();
    acc = acc.wrapping_add(u64::from(tex.get(0, 0).unwrap_or(0)));
    acc = acc.wrapping_add(u64::from(
        tex.get(
            tex.width().saturating_sub(1),
            tex.height().saturating_sub(1),
        )
        .unwrap_or(0),
    ));
    acc
}

/// `MapView::new_checked` on the bytes as given, then on the bytes with every
/// CRC recomputed (`map::reseal`), so that mutations reach the structural
/// checks behind the CRCs. The verdict is that of the resealed product.
pub fn map_product(_env: &Env, d: &[u8]) -> Verdict {
    let raw = MapView::new_checked(d);
    if let Ok(m) = &raw {
        walk_map(m);
    }
    let mut copy = d.to_vec();
    if map::reseal(&mut copy).is_err() {
        return core_verdict(&raw);
    }
    let sealed = MapView::new_checked(&copy);
    if raw.is_ok() {
        assert!(
            sealed.is_ok(),
            "an accepted product is rejected after reseal"
        );
    }
    if let Ok(m) = &sealed {
        walk_map(m);
    }
    core_verdict(&sealed)
}

// ---------------------------------------------------------------- sim readers

/// OBJ geometry (`obj::parse` without appearance), then `MeshData::from_raw`.
pub fn obj(env: &Env, d: &[u8]) -> Verdict {
    let path = env.dir.join("g.obj");
    let raw = io::obj::parse(d, &path, false);
    match raw {
        Ok(raw) => {
            let r = io::mesh::MeshData::from_raw(raw, &path);
            sim_verdict(&r)
        }
        Err(e) => Verdict::Rejected(error_label(&e)),
    }
}

/// Separator between the OBJ and the MTL part of an `obj_mtl` input.
pub const MTL_SEPARATOR: &[u8] = b"\n#%%MTL%%\n";

/// OBJ with appearance: the input is `OBJ text`, [`MTL_SEPARATOR`], `MTL text`;
/// the MTL part is written to `m.mtl` beside the OBJ (in the target's own
/// directory, which also holds the textures `rock.png`, `sand.png`, `tex.png`),
/// then `obj::parse` reads materials and textures and `MeshData::from_raw`
/// builds the mesh; a mesh that passes is encoded to a map product, which
/// must be accepted by `MapView::new_checked`.
pub fn obj_mtl(env: &Env, d: &[u8]) -> Verdict {
    let (obj, mtl) = match d
        .windows(MTL_SEPARATOR.len())
        .position(|w| w == MTL_SEPARATOR)
    {
        Some(k) => (&d[..k], &d[k + MTL_SEPARATOR.len()..]),
        None => (d, &[][..]),
    };
    let mtl_path = env.dir.join("m.mtl");
    if std::fs::write(&mtl_path, mtl).is_err() {
        return Verdict::Rejected("harness: cannot write m.mtl".to_string());
    }
    let path = env.dir.join("m.obj");
    let raw = match io::obj::parse(obj, &path, true) {
        Ok(r) => r,
        Err(e) => return Verdict::Rejected(error_label(&e)),
    };
    mesh_to_map(raw, &path)
}

fn mesh_to_map(raw: io::mesh::RawMesh, path: &Path) -> Verdict {
    let mesh = match io::mesh::MeshData::from_raw(raw, path) {
        Ok(m) => m,
        Err(e) => return Verdict::Rejected(error_label(&e)),
    };
    // Large meshes are accepted by the reader; only small ones are encoded (time).
    if mesh.triangles.len() > 4096 || mesh.texture.pixels.len() > 1 << 20 {
        return Verdict::Accepted;
    }
    match mesh.encode_map(1.0) {
        Ok(bytes) => {
            let m = MapView::new_checked(&bytes);
            assert!(
                m.is_ok(),
                "a map encoded from a parsed mesh is rejected: {:?}",
                m.err()
            );
            Verdict::Accepted
        }
        Err(e) => Verdict::Rejected(format!("encode: {}", error_label(&e))),
    }
}

/// PLY (ascii and binary) with appearance (`comment TextureFile` names
/// resolve in the target's directory), then the mesh and map as [`obj_mtl`].
pub fn ply(env: &Env, d: &[u8]) -> Verdict {
    let path = env.dir.join("m.ply");
    match io::ply::parse(d, &path, true) {
        Ok(raw) => mesh_to_map(raw, &path),
        Err(e) => Verdict::Rejected(error_label(&e)),
    }
}

/// `calib.json` in either form (`calib::parse_calib_any`); an accepted
/// rectified calibration must give a rig (`Calib::rig`).
pub fn calib(env: &Env, d: &[u8]) -> Verdict {
    let path = env.dir.join("calib.json");
    match io::calib::parse_calib_any(d, &path) {
        Ok(io::calib::CalibFile::Rectified(c)) => {
            let rig = c.rig();
            assert!(
                rig.is_ok(),
                "an accepted calib.json gives no rig: {:?}",
                rig.err()
            );
            Verdict::Accepted
        }
        Ok(io::calib::CalibFile::OpenCv(c)) => {
            let (w, h) = c.size();
            assert!(w > 0 && h > 0, "accepted OpenCV calibration of size 0");
            let _ = (c.left.intrinsics(), c.right.dist8());
            Verdict::Accepted
        }
        Err(e) => Verdict::Rejected(error_label(&e)),
    }
}

/// `prior.json` / `truth.json` (`json::parse_pose_json`); an accepted pose
/// must convert to a core pose.
pub fn prior(env: &Env, d: &[u8]) -> Verdict {
    let path = env.dir.join("prior.json");
    match io::json::parse_pose_json(d, &path) {
        Ok(p) => {
            let _ = p.user();
            let _ = p.pose();
            Verdict::Accepted
        }
        Err(e) => Verdict::Rejected(error_label(&e)),
    }
}

/// `result.json` (`json::parse_result`).
pub fn result(env: &Env, d: &[u8]) -> Verdict {
    let path = env.dir.join("result.json");
    sim_verdict(&io::json::parse_result(d, &path))
}

/// `pairs.jsonl`: UTF-8 text, one `PairSpec` object per non-blank line, as
/// `vtsm relocalize --pairs` reads it. Accepted when every line parses.
pub fn pairs(_env: &Env, d: &[u8]) -> Verdict {
    let Ok(text) = std::str::from_utf8(d) else {
        return Verdict::Rejected("pairs file is not UTF-8 text".to_string());
    };
    let mut n = 0usize;
    for line in text.lines() {
        if line.trim().is_empty() {
            continue;
        }
        n += 1;
        if let Err(e) = serde_json::from_str::<vtsm_sim::cli::batch::PairSpec>(line) {
            let msg = vtsm_sim::error::Error::msg(format!("invalid pair: {e}"));
            return Verdict::Rejected(error_label(&msg));
        }
    }
    if n == 0 {
        return Verdict::Rejected("no pairs".to_string());
    }
    Verdict::Accepted
}

/// Recompute the chunk CRCs of a PNG (so mutations reach the decoder).
fn fix_png_crcs(d: &mut [u8]) {
    let mut at = 8usize;
    while at + 12 <= d.len() {
        let len = u32::from_be_bytes([d[at], d[at + 1], d[at + 2], d[at + 3]]) as usize;
        let Some(end) = (at + 8).checked_add(len) else {
            return;
        };
        if end + 4 > d.len() {
            return;
        }
        let crc = map::crc32(&d[at + 4..end]);
        d[end..end + 4].copy_from_slice(&crc.to_be_bytes());
        at = end + 4;
    }
}

/// Images (`image::decode_gray`: PNG, JPEG, TIFF, PGM/PPM); PNG chunk CRCs are
/// recomputed first. An accepted image must give a checked view of its size.
pub fn image(env: &Env, d: &[u8]) -> Verdict {
    let path = env.dir.join("image.png");
    let mut bytes = d.to_vec();
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        fix_png_crcs(&mut bytes);
    }
    match io::image::decode_gray(&bytes, &path) {
        Ok(g) => {
            assert_eq!(
                g.pixels.len(),
                g.width as usize * g.height as usize,
                "decoded image has the wrong pixel count"
            );
            let v = g.view();
            assert!(v.is_ok(), "decoded image gives no view: {:?}", v.err());
            Verdict::Accepted
        }
        Err(e) => Verdict::Rejected(error_label(&e)),
    }
}

// ---------------------------------------------------------------- core views and stages

/// `ImageView::new` / `ImageViewMut::new` with arbitrary size, stride and
/// buffer length, then every accessor with arbitrary coordinates and rectangles.
pub fn image_view(_env: &Env, d: &[u8]) -> Verdict {
    let mut t = Take::new(d);
    let pick = |t: &mut Take| -> usize {
        match t.u8() % 8 {
            0 => t.u32() as usize,
            1 => [0usize, 1, 8191, 8192, 8193, 16384, 16385, usize::MAX][usize::from(t.u8() % 8)],
            _ => usize::from(t.u8()),
        }
    };
    let (w, h, s) = (pick(&mut t), pick(&mut t), pick(&mut t));
    let len = (t.u16() as usize).min(1 << 16);
    let buf: Vec<u8> = (0..len).map(|i| (i * 31 % 251) as u8).collect();
    let v = match GrayView::new(&buf, w, h, s) {
        Ok(v) => v,
        Err(c) => {
            // Same verdict for the 16-bit and mutable views.
            let b16 = vec![0u16; len];
            assert_eq!(Gray16View::new(&b16, w, h, s).err(), Some(c));
            let mut bm = buf.clone();
            assert_eq!(GrayViewMut::new(&mut bm, w, h, s).err(), Some(c));
            return Verdict::Rejected(code_label(c));
        }
    };
    for _ in 0..8 {
        let (x, y) = (pick(&mut t), pick(&mut t));
        let got = v.get(x, y);
        assert_eq!(got.is_some(), x < w && y < h, "get({x}, {y}) on {w}x{h}");
        assert_eq!(v.row(y).is_some_and(|r| r.len() == w), y < h);
        let r = Rect::new(t.u32() as i32, t.u32() as i32, t.u32(), t.u32());
        let r = if t.u8() % 2 == 0 {
            Rect::new(
                (r.x as u8).into(),
                (r.y as u8).into(),
                (r.w as u8).into(),
                (r.h as u8).into(),
            )
        } else {
            r
        };
        if let Some(sv) = v.sub(r) {
            assert!(v.rect().contains(&r), "sub {r:?} outside {w}x{h}");
            assert_eq!((sv.width(), sv.height()), (r.w as usize, r.h as usize));
            if r.w > 0 && r.h > 0 {
                assert_eq!(sv.get(0, 0), v.get(r.x as usize, r.y as usize));
            }
        }
        let o = Rect::new(t.u32() as i32, t.u32() as i32, t.u32(), t.u32());
        if let Some(i) = r.intersect(&o) {
            assert!(r.contains(&i) && o.contains(&i), "{r:?} ∩ {o:?} = {i:?}");
        }
    }
    let mut bm = buf.clone();
    let mut m = GrayViewMut::new(&mut bm, w, h, s).unwrap_or_else(|c| {
        panic!("a mutable view is rejected ({c:?}) where the view is accepted")
    });
    let (x, y) = (pick(&mut t), pick(&mut t));
    assert_eq!(m.set(x, y, 7), x < w && y < h);
    if let Some(r) = m.row_mut(y) {
        r.fill(3);
    }
    m.fill(9);
    Verdict::Accepted
}

/// The tiny map of the environment, or the input's map bytes after reseal
/// when those pass `new_checked`.
fn parse_or_default<'a>(env: &'a Env, rest: &[u8], buf: &'a mut Vec<u8>) -> (MapView<'a>, bool) {
    if !rest.is_empty() {
        buf.clear();
        buf.extend_from_slice(rest);
        if map::reseal(buf).is_ok() {
            if let Ok(m) = MapView::new_checked(buf) {
                return (m, true);
            }
        }
    }
    match MapView::new_checked(&env.map) {
        Ok(m) => (m, false),
        Err(c) => panic!("harness: the environment's map is rejected: {c:?}"),
    }
}

fn arbitrary_pose(t: &mut Take) -> Pose {
    let q = Quaternion::new(
        t.f32(-1.0, 1.0),
        t.f32(-1.0, 1.0),
        t.f32(-1.0, 1.0),
        t.f32(-1.0, 1.0),
    );
    let rot = if t.u8() % 2 == 0 {
        Unit::new_unchecked(q)
    } else {
        UnitQuaternion::from_quaternion(q)
    };
    Pose::new(
        rot,
        Vec3::new(t.f32(-10.0, 10.0), t.f32(-10.0, 10.0), t.f32(-10.0, 10.0)),
    )
}

/// A pose near `base`: translation within ±`t_m`, rotation within ±`r_rad`.
fn near_pose(t: &mut Take, base: &Pose, t_m: f32, r_rad: f32) -> Pose {
    let mut u = |s: f32| (f32::from(t.u8()) / 255.0 * 2.0 - 1.0) * s;
    let axis = Vec3::new(u(1.0), u(1.0), u(1.0));
    let rot = UnitQuaternion::from_scaled_axis(axis * r_rad);
    let d = Vec3::new(u(t_m), u(t_m), u(t_m));
    Pose::new(base.rotation() * rot, base.translation() + d)
}

/// Bytes of a `render` input before its own map product.
pub const RENDER_HEADER: usize = 64;

/// `raster::render_window` of a parsed map (the environment's tiny map, or the
/// input's own after reseal) from an arbitrary camera (any values, through
/// `Camera::new`), pose (NaN and non-unit quaternions included) and window, into
/// buffers of arbitrary size; then `raster::template_mask` with arbitrary
/// sizes over those buffers.
pub fn render(env: &Env, d: &[u8]) -> Verdict {
    let (head, own_map) = d.split_at(d.len().min(RENDER_HEADER));
    let mut t = Take::new(head);
    let mode = t.u8();
    let cam = if mode % 4 == 0 {
        // Any values: `Camera::new` is the only way to a camera, so values
        // outside its ranges end here with its code.
        let (fx, fy) = (t.f32(-10.0, 2000.0), t.f32(-10.0, 2000.0));
        let (cx, cy) = (t.f32(-20000.0, 20000.0), t.f32(-20000.0, 20000.0));
        let width = if t.u8() % 2 == 0 {
            t.u32()
        } else {
            t.range(0, 400)
        };
        let height = if t.u8() % 2 == 0 {
            t.u32()
        } else {
            t.range(0, 400)
        };
        match Camera::new(fx, fy, cx, cy, width, height) {
            Ok(c) => c,
            Err(c) => return Verdict::Rejected(code_label(c)),
        }
    } else {
        env.rig.cam()
    };
    let pose = if mode / 4 % 4 == 0 {
        arbitrary_pose(&mut t)
    } else {
        near_pose(&mut t, &env.truth, 0.5, 0.3)
    };
    let window = if mode / 16 % 4 == 0 {
        Rect::new(
            t.u32() as i32,
            t.u32() as i32,
            t.range(0, 300),
            t.range(0, 300),
        )
    } else {
        let w = t.range(1, 64);
        let h = t.range(1, 64);
        Rect::new(
            t.range(0, cam.width().min(1000)) as i32 - 16,
            t.range(0, cam.height().min(1000)) as i32 - 16,
            w,
            h,
        )
    };
    let n = window.w as usize * window.h as usize;
    let n = n.min(MAX_RENDER_PX * MAX_RENDER_PX);
    let short = if t.u8() % 8 == 0 {
        usize::from(t.u8())
    } else {
        0
    };
    let len = n.saturating_sub(short);
    let (mut inten, mut depth, mut md) = (vec![0u8; len], vec![0u32; len], vec![0u32; len]);
    let mut mapbuf = Vec::new();
    let (m, own) = parse_or_default(env, own_map, &mut mapbuf);
    let mut target = Target {
        intensity: &mut inten,
        depth: &mut depth,
        mask_depth: &mut md,
    };
    let r = raster::render_window(&m, &cam, &pose, window, &mut target);
    if let Ok(s) = &r {
        assert!(s.pixels_written > 0);
        assert!(s.triangles_drawn <= s.triangles_tested);
    }
    // Template mask over the window's buffers, sometimes with other sizes.
    let (mw, mh) = if mode >= 128 {
        (t.u16() as usize, t.u16() as usize)
    } else {
        (window.w as usize, window.h as usize)
    };
    let mut out = vec![0u8; len];
    let kept = raster::template_mask(&depth, &md, mw, mh, &mut out);
    assert!(kept as usize <= len, "template_mask kept {kept} of {len}");
    assert!(out.iter().all(|&v| v == 0 || v == 255));
    let label = match r {
        Ok(_) => Verdict::Accepted,
        Err(c) => Verdict::Rejected(code_label(c)),
    };
    match (label, own) {
        (Verdict::Accepted, true) => Verdict::Rejected("own map: drawn".to_string()),
        (v, _) => v,
    }
}

/// `ncc::match_template_with` with arbitrary template, mask, image and search
/// sizes, pixel contents, filter, search mode, coarse-to-fine configuration
/// and scratch sizes (the minimum, or shorter).
pub fn ncc(_env: &Env, d: &[u8]) -> Verdict {
    let mut t = Take::new(d);
    let mode = t.u8();
    let side = |t: &mut Take| -> usize {
        match t.u8() % 16 {
            0 => t.u16() as usize,
            1 => [0usize, 15, 16, 256, 257][usize::from(t.u8() % 5)],
            _ => t.range(16, 40) as usize,
        }
    };
    let (tw, th) = (side(&mut t).max(1), side(&mut t).max(1));
    let (iw, ih) = if mode % 16 == 0 {
        (t.range(1, 1100) as usize, t.range(1, 1100) as usize)
    } else {
        (
            tw.min(300) + t.range(0, 48) as usize,
            th.min(300) + t.range(0, 48) as usize,
        )
    };
    let stride = iw
        + if t.u8() % 4 == 0 {
            usize::from(t.u8())
        } else {
            0
        };
    let seed = t.u64();
    let content = t.u8() % 8;
    let mut rng = Rng::new(seed);
    let len = (ih.max(1) - 1) * stride + iw;
    let img: Vec<u8> = match content {
        0 => vec![t.u8(); len],
        1 => (0..len)
            .map(|i| ((i % stride) * 7 + (i / stride) * 3) as u8)
            .collect(),
        _ => (0..len).map(|_| rng.next_u32() as u8).collect(),
    };
    let Ok(image) = GrayView::new(&img, iw, ih, stride) else {
        return Verdict::Rejected("harness: image view rejected".to_string());
    };
    // Template: a crop of the image at an offset (a true match), or noise, or flat.
    let (ox, oy) = (t.range(0, 64) as usize, t.range(0, 64) as usize);
    let tl = tw.min(300) * th.min(300);
    let tpl: Vec<u8> = match t.u8() % 4 {
        0 => vec![t.u8(); tl],
        1 => (0..tl).map(|_| rng.next_u32() as u8).collect(),
        _ => (0..tl)
            .map(|i| {
                let (x, y) = (i % tw.min(300) + ox, i / tw.min(300) + oy);
                image.get(x, y).unwrap_or(0)
            })
            .collect(),
    };
    let Ok(template) = GrayView::new(&tpl, tw.min(300), th.min(300), tw.min(300)) else {
        return Verdict::Rejected("harness: template view rejected".to_string());
    };
    let mask_kind = t.u8() % 8;
    let (mw, mh) = if mask_kind == 7 {
        (side(&mut t).clamp(1, 300), side(&mut t).clamp(1, 300))
    } else {
        (template.width(), template.height())
    };
    let mbytes: Vec<u8> = match mask_kind {
        0 => vec![0; mw * mh],
        1 => vec![255; mw * mh],
        2 => (0..mw * mh).map(|_| rng.next_u32() as u8).collect(),
        3 => (0..mw * mh)
            .map(|i| if (i % mw.max(1)) < mw / 3 { 0 } else { 255 })
            .collect(),
        4 => (0..mw * mh).map(|i| if i == 0 { 255 } else { 0 }).collect(),
        _ => (0..mw * mh)
            .map(|_| (rng.next_u32() & 1) as u8 * 255)
            .collect(),
    };
    let mask = if mask_kind < 5 || mask_kind == 7 {
        GrayView::new(&mbytes, mw, mh, mw).ok()
    } else {
        None
    };
    let search = if t.u8() % 4 == 0 {
        Rect::new(t.u32() as i32, t.u32() as i32, t.u32(), t.u32())
    } else {
        Rect::new(
            t.range(0, 40) as i32 - 20,
            t.range(0, 40) as i32 - 20,
            t.range(0, 400),
            t.range(0, 400),
        )
    };
    let filter = [Filter::Gray, Filter::Sobel, Filter::Laplacian][usize::from(t.u8() % 3)];
    let smode = if t.u8() % 4 == 0 {
        Search::Exhaustive
    } else {
        Search::CoarseToFine
    };
    let mut cfg = SearchConfig::for_filter(filter);
    if t.u8() % 2 == 0 {
        let f = |t: &mut Take| -> usize {
            match t.u8() % 8 {
                0 => usize::MAX,
                1 => t.u32() as usize,
                _ => usize::from(t.u8() % 40),
            }
        };
        let (c, fc) = (f(&mut t), f(&mut t));
        let verify_all = f(&mut t);
        let radii = (f(&mut t), f(&mut t), f(&mut t));
        let nms = f(&mut t);
        let coarse = (f(&mut t), f(&mut t));
        // A value out of range is refused with its code, never clamped.
        let checked = cfg
            .with_candidates(c, fc)
            .and_then(|cfg| cfg.with_refine_radii_px(radii.0, radii.1, radii.2))
            .and_then(|cfg| cfg.with_coarse_px(coarse.0, coarse.1))
            .map(|cfg| cfg.with_nms_and_verify_px(nms, verify_all));
        match checked {
            Ok(c) => cfg = c,
            Err(code) => assert_eq!(
                code,
                FailureCode::ConfigParamOutOfRange,
                "SearchConfig refused with another code"
            ),
        }
    }
    // Scratch: the minimum for the clipped window (capped), sometimes short.
    let wr = image.rect().intersect(&search);
    let (ww, wh) = wr.map_or((0, 0), |r| (r.w as usize, r.h as usize));
    let need = ScratchSizes::minimum(
        template.width(),
        template.height(),
        ww.min(1100),
        wh.min(1100),
        smode,
        &cfg,
    );
    let cut = if t.u8() % 8 == 0 {
        usize::from(t.u8()) + 1
    } else {
        0
    };
    let cap = 1 << 24;
    let (mut sw, mut st, mut si, mut sr) = (
        vec![0u8; need.window.min(cap).saturating_sub(cut)],
        vec![0u8; need.template.min(cap)],
        vec![0u32; need.integral.min(cap)],
        vec![Run::default(); need.runs.min(cap)],
    );
    let mut scratch = Scratch {
        window: &mut sw,
        template: &mut st,
        integral: &mut si,
        runs: &mut sr,
    };
    let r = ncc::match_template_with(
        template,
        mask,
        image,
        search,
        filter,
        smode,
        &cfg,
        &mut scratch,
    );
    if let Ok((m, _)) = &r {
        assert!(
            (-1.0..=1.0).contains(&m.score),
            "NCC score {} outside [-1, 1]",
            m.score
        );
        assert!(m.x >= 0 && m.y >= 0, "match at ({}, {})", m.x, m.y);
        assert!(
            m.x as usize + template.width() <= iw && m.y as usize + template.height() <= ih,
            "match at ({}, {}) puts the template outside the image",
            m.x,
            m.y
        );
    }
    core_verdict(&r)
}

/// The relocalizer through `vtsm_core::reloc::Setup`: the environment's tiny
/// map and rig, frames rendered at the truth pose and corrupted by the input,
/// or noise, flat or identical frames; a prior near the truth, far from it or
/// arbitrary (NaN included); parameters from a small profile with fields
/// replaced by arbitrary values. Runs to completion (every loop is bounded).
pub fn reloc(env: &Env, d: &[u8]) -> Verdict {
    let mut t = Take::new(d);
    let mode = t.u8();
    let (w, h) = (
        env.rig.cam().width() as usize,
        env.rig.cam().height() as usize,
    );
    let mut left = env.left.clone();
    let mut right = env.right.clone();
    match mode % 8 {
        0 => {
            let mut rng = Rng::new(t.u64());
            left.iter_mut().for_each(|p| *p = rng.next_u32() as u8);
            right.iter_mut().for_each(|p| *p = rng.next_u32() as u8);
        }
        1 => {
            left.fill(t.u8());
            right.fill(t.u8());
        }
        2 => right.clone_from(&left),
        _ => {
            // Overwrite runs of pixels with input bytes.
            for _ in 0..t.range(0, 16) {
                let at = t.u32() as usize % (w * h);
                let n = t.range(0, 4000) as usize;
                let v = t.u8();
                let img = if t.u8() % 2 == 0 {
                    &mut left
                } else {
                    &mut right
                };
                let end = (at + n).min(img.len());
                img[at..end].fill(v);
            }
        }
    }
    let prior = match mode / 8 % 4 {
        0 => arbitrary_pose(&mut t),
        1 => near_pose(&mut t, &env.truth, 2.0, 0.5),
        _ => near_pose(&mut t, &env.truth, 0.2, 0.026),
    };
    let mut p = env.params;
    if mode / 32 % 2 == 1 {
        for _ in 0..t.range(1, 4) {
            match t.u8() % 12 {
                0 => p.n_corr = t.u16() % 64,
                1 => p.n_iter = t.u8() % 8,
                2 => p.t0_m = t.f32(0.0, 3.0),
                3 => p.r0_deg = t.f32(0.0, 30.0),
                4 => p.template_px = t.u16() % 80,
                5 => p.search_px = t.u16() % 300,
                6 => p.epsilon_px = t.f32(0.0, 80.0),
                7 => p.ransac_iter = t.u16() % 200,
                8 => p.inlier_m = t.f32(0.0, 1.5),
                9 => p.min_score = t.f32(-0.5, 1.5),
                10 => p.seeds = t.u16() % 6,
                _ => p.attempts_per_iter = t.u32() % 200,
            }
        }
    }
    let (lw, lh) = if mode / 64 == 3 && t.u8() % 2 == 0 {
        (w - 1, h)
    } else {
        (w, h)
    };
    let Ok(lv) = GrayView::new(&left, lw, lh, w) else {
        return Verdict::Rejected("harness: left view rejected".to_string());
    };
    let Ok(rv) = GrayView::new(&right, w, h, w) else {
        return Verdict::Rejected("harness: right view rejected".to_string());
    };
    let Ok(m) = MapView::new_checked(&env.map) else {
        panic!("harness: the environment's map is rejected");
    };
    let setup = Setup::new(&m, lv, rv, &env.rig, &p, &prior, t.u64());
    if let Err(c) = setup.validate() {
        return Verdict::Rejected(code_label(c));
    }
    let sizes = setup.sizes();
    let (mut b, mut wds, mut runs) = (
        vec![0u8; sizes.bytes],
        vec![0u32; sizes.words],
        vec![Run::default(); sizes.runs],
    );
    let ws = match Workspace::new(sizes, &mut b, &mut wds, &mut runs) {
        Ok(ws) => ws,
        Err(c) => return Verdict::Rejected(code_label(c)),
    };
    let mut engine = match setup.build(ws) {
        Ok(e) => e,
        Err(c) => return Verdict::Rejected(code_label(c)),
    };
    let out = engine.run_to_completion(0);
    match out.failure {
        None => {
            assert!(
                out.pose.is_finite(),
                "a successful relocalization gives a non-finite pose"
            );
            Verdict::Accepted
        }
        Some(c) => Verdict::Rejected(format!("outcome {}", code_label(c))),
    }
}

/// The small relocalization profile of the `reloc` target.
pub fn reloc_params() -> Params {
    Params {
        template_px: 32,
        search_px: 96,
        n_corr: 12,
        n_iter: 2,
        attempts_per_iter: 60,
        ransac_iter: 60,
        max_reseed: 2,
        max_stall: 2,
        seeds: 0,
        ..Params::paper()
    }
}

/// A camera `StereoRig` for the environment (160×120, 70° field of view, 0.3 m).
pub fn small_rig() -> StereoRig {
    let cam = Camera::from_hfov(160, 120, 70.0);
    match cam.and_then(|c| StereoRig::new(c, 0.3)) {
        Ok(r) => r,
        Err(c) => panic!("harness: small rig rejected: {c:?}"),
    }
}
