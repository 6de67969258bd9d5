//! The local-feature relocalizer the paper compares against (§V, "SIFT"
//! baseline), for contrast with VTSM in `vtsm eval --baseline features`.
//!
//! Method, one iteration:
//! 1. render the map's virtual image (intensity and depth) at the current pose
//!    with the core rasterizer ([`locate::render_template`] in tiles of
//!    [`MAX_RENDER_PX`]), so every map pixel with depth has a 3D world point;
//! 2. detect FAST-9 corners (`imageproc`) in the virtual image and in the real
//!    left image, keep the strongest per grid cell, and describe them with
//!    256-bit BRIEF descriptors over fixed, seed-independent test pairs;
//! 3. match every real keypoint to the virtual ones by Hamming distance
//!    (brute force, Lowe ratio test, absolute distance cap, and a pixel gate
//!    around the keypoint as wide as VTSM's search window);
//! 4. triangulate each matched real keypoint with the right image (rectified
//!    stereo: same row, ZNCC disparity search, sub-pixel parabola,
//!    [`stereo::triangulate`]);
//! 5. estimate `world_from_left` from the 3D–3D pairs with the core's
//!    Umeyama + RANSAC ([`pose::ransac`], same gate as VTSM).
//!
//! A second iteration re-renders at the estimate and refines it. The result is
//! a success when the first iteration reaches [`FeatureParams::min_inliers`]
//! RANSAC inliers. Everything is deterministic: no thread-local randomness, the
//! RANSAC stream is seeded from the trial seed.

use crate::error::{Error, Result};
use crate::locate::{self, Request};
use image::GrayImage;
use imageproc::binary_descriptors::brief::{brief, BriefDescriptor, TestPair};
use imageproc::binary_descriptors::BinaryDescriptor;
use imageproc::corners::corners_fast9;
use imageproc::point::Point;
use std::time::{Duration, Instant};
use vtsm_core::config::{MAX_CORR, MAX_RENDER_PX};
use vtsm_core::geom::{Camera, Pose};
use vtsm_core::map::MapView;
use vtsm_core::pose::{self, Correspondence, RansacConfig};
use vtsm_core::raster;
use vtsm_core::rng::Rng;
use vtsm_core::stereo;

/// BRIEF descriptor length, bits.
pub const DESCRIPTOR_BITS: usize = 256;
/// Distance of a keypoint from the image border (BRIEF's 31 px patch needs 17).
pub const BORDER_PX: u32 = 20;
/// Side of the stereo matching patch, pixels (odd).
pub const STEREO_PATCH_PX: usize = 11;
/// Smallest depth the stereo search looks for, metres.
pub const STEREO_MIN_DEPTH_M: f32 = 0.5;

/// Settings of the feature relocalizer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeatureParams {
    /// FAST-9 intensity threshold.
    pub fast_threshold: u8,
    /// Grid cell side, pixels: at most one keypoint (the strongest) per cell.
    pub cell_px: u32,
    /// Lowe ratio: best distance must be below `ratio` × second best.
    pub ratio: f32,
    /// Largest accepted Hamming distance, bits.
    pub max_hamming: u32,
    /// Half side of the square pixel gate around a real keypoint in which its
    /// virtual match must lie (the prior's uncertainty), pixels.
    pub gate_px: f32,
    /// Smallest ZNCC of an accepted stereo match.
    pub min_zncc: f32,
    /// RANSAC inliers needed for success.
    pub min_inliers: u16,
    /// Render–match–fit iterations (the first decides success, later ones refine).
    pub iterations: u8,
}

impl FeatureParams {
    /// Settings for an image width (cells and gate scale with the image).
    pub fn for_width(width: u32) -> Self {
        let l = vtsm_core::config::template_px_for_width(width);
        let search = vtsm_core::config::search_px_for_template(l);
        Self {
            fast_threshold: 12,
            cell_px: (width / 48).max(8),
            ratio: 0.8,
            max_hamming: 80,
            gate_px: f32::from(search) * 0.5,
            min_zncc: 0.8,
            min_inliers: 12,
            iterations: 2,
        }
    }
}

/// What one feature relocalization produced.
#[derive(Clone, Debug)]
pub struct FeatureReport {
    /// Final `world_from_left` (the prior when the first iteration failed).
    pub pose: Pose,
    /// Failure name, `None` on success.
    pub failure: Option<String>,
    /// RANSAC inliers of the last successful iteration.
    pub inliers: u32,
    /// Successful iterations.
    pub iterations: u32,
    /// Keypoints of the virtual image (first iteration).
    pub map_keypoints: usize,
    /// Keypoints of the real left image.
    pub live_keypoints: usize,
    /// Descriptor matches (first iteration).
    pub matches: usize,
    /// Matches with a stereo 3D point (first iteration).
    pub stereo_points: usize,
    /// Wall time, rendering included.
    pub elapsed: Duration,
}

/// The map's virtual image at `world_from_cam`, full frame: intensity and
/// camera-frame depth in metres (`NaN` where nothing is drawn or the template
/// mask drops the pixel). Rendered in tiles with [`locate::render_template`].
pub fn render_virtual(
    map: &MapView<'_>,
    cam: &Camera,
    world_from_cam: &Pose,
) -> (Vec<u8>, Vec<f32>) {
    let (w, h) = (cam.width() as usize, cam.height() as usize);
    let mut inten = vec![0u8; w * h];
    let mut depth = vec![f32::NAN; w * h];
    let l = MAX_RENDER_PX;
    let half = (l / 2) as f32;
    for ty in (0..h).step_by(l) {
        for tx in (0..w).step_by(l) {
            let centre = [tx as f32 + half, ty as f32 + half];
            let Some(t) = locate::render_template(map, cam, world_from_cam, centre, l) else {
                continue;
            };
            for y in 0..l.min(h - ty) {
                for x in 0..l.min(w - tx) {
                    let (s, d) = (y * l + x, (ty + y) * w + tx + x);
                    inten[d] = t.intensity[s];
                    if t.mask[s] == 255 {
                        if let Some(z) = raster::depth_to_m(t.depth[s]) {
                            depth[d] = z;
                        }
                    }
                }
            }
        }
    }
    (inten, depth)
}

/// The fixed BRIEF test pairs: 256 pairs drawn from an isotropic Gaussian
/// (σ = 6.6 px) over the 31×31 patch, from a constant seed.
pub fn test_pairs() -> Vec<TestPair> {
    let mut rng = Rng::new(0x4252_4945_465F_5450);
    let mut pairs = Vec::with_capacity(DESCRIPTOR_BITS);
    let draw = |rng: &mut Rng| {
        let v = 16.0 + 6.6 * rng.normal();
        (0.0..31.0).contains(&v).then_some(v as u32)
    };
    // Bounded: each draw lands in the patch with probability > 0.95.
    for _ in 0..DESCRIPTOR_BITS * 64 {
        if pairs.len() == DESCRIPTOR_BITS {
            break;
        }
        if let (Some(x0), Some(y0), Some(x1), Some(y1)) = (
            draw(&mut rng),
            draw(&mut rng),
            draw(&mut rng),
            draw(&mut rng),
        ) {
            pairs.push(TestPair {
                p0: Point::new(x0, y0),
                p1: Point::new(x1, y1),
            });
        }
    }
    pairs
}

/// FAST-9 corners of `img` where `keep(x, y)`, at least [`BORDER_PX`] from the
/// border, the strongest per `cell_px` grid cell (ties to the first in raster
/// order), in raster order of their cells.
pub fn detect(
    img: &GrayImage,
    p: &FeatureParams,
    keep: impl Fn(u32, u32) -> bool,
) -> Vec<Point<u32>> {
    let (w, h) = img.dimensions();
    if w <= 2 * BORDER_PX || h <= 2 * BORDER_PX {
        return Vec::new();
    }
    let cell = p.cell_px.max(1);
    let (cw, ch) = (w.div_ceil(cell) as usize, h.div_ceil(cell) as usize);
    let mut best: Vec<Option<(f32, Point<u32>)>> = vec![None; cw * ch];
    for c in corners_fast9(img, p.fast_threshold) {
        let inside =
            c.x >= BORDER_PX && c.y >= BORDER_PX && c.x < w - BORDER_PX && c.y < h - BORDER_PX;
        if !inside || !keep(c.x, c.y) {
            continue;
        }
        let k = (c.y / cell) as usize * cw + (c.x / cell) as usize;
        if let Some(slot) = best.get_mut(k) {
            if slot.is_none_or(|(s, _)| c.score > s) {
                *slot = Some((c.score, Point::new(c.x, c.y)));
            }
        }
    }
    best.into_iter().flatten().map(|(_, p)| p).collect()
}

/// Largest image area (pixels) described in one piece: imageproc's BRIEF sums
/// two corners of a `u32` integral image, which stays below 2³² only while
/// 2 · area · 255 does (a 5472 × 3648 image does not).
const BRIEF_MAX_AREA_PX: u64 = (u32::MAX as u64) / (2 * 255);

/// Tile side for images larger than [`BRIEF_MAX_AREA_PX`]; each tile is
/// described with a [`BORDER_PX`] apron so every keypoint sees its whole patch.
const BRIEF_TILE_PX: u32 = 1024;

/// BRIEF descriptors of `kps` in `img` with `pairs`, in keypoint order (empty on
/// error). Large images are described tile by tile with the same result as one
/// piece: a descriptor depends only on the keypoint's 31 × 31 patch.
pub fn describe(
    img: &GrayImage,
    kps: &[Point<u32>],
    pairs: &Vec<TestPair>,
) -> Vec<BriefDescriptor> {
    if kps.is_empty() {
        return Vec::new();
    }
    let (w, h) = img.dimensions();
    if u64::from(w) * u64::from(h) <= BRIEF_MAX_AREA_PX {
        return brief(img, kps, DESCRIPTOR_BITS, Some(pairs))
            .map(|(d, _)| d)
            .unwrap_or_default();
    }
    describe_tiled(img, kps, pairs, BRIEF_TILE_PX)
}

/// [`describe`] in tiles of side `t`.
fn describe_tiled(
    img: &GrayImage,
    kps: &[Point<u32>],
    pairs: &Vec<TestPair>,
    t: u32,
) -> Vec<BriefDescriptor> {
    let (w, h) = img.dimensions();
    let mut out: Vec<Option<BriefDescriptor>> = vec![None; kps.len()];
    for ty in 0..h.div_ceil(t) {
        for tx in 0..w.div_ceil(t) {
            let idx: Vec<usize> = (0..kps.len())
                .filter(|&i| kps[i].x / t == tx && kps[i].y / t == ty)
                .collect();
            if idx.is_empty() {
                continue;
            }
            let x0 = (tx * t).saturating_sub(BORDER_PX);
            let y0 = (ty * t).saturating_sub(BORDER_PX);
            let x1 = (tx * t + t + BORDER_PX).min(w);
            let y1 = (ty * t + t + BORDER_PX).min(h);
            let sub = image::imageops::crop_imm(img, x0, y0, x1 - x0, y1 - y0).to_image();
            let local: Vec<Point<u32>> = idx
                .iter()
                .map(|&i| Point::new(kps[i].x - x0, kps[i].y - y0))
                .collect();
            let Ok((descs, _)) = brief(&sub, &local, DESCRIPTOR_BITS, Some(pairs)) else {
                return Vec::new();
            };
            for (&i, mut d) in idx.iter().zip(descs) {
                d.corner.x += x0;
                d.corner.y += y0;
                out[i] = Some(d);
            }
        }
    }
    out.into_iter().flatten().collect()
}

/// For each descriptor of `live`, the index of its match in `map`: nearest by
/// Hamming distance among those within the pixel gate, accepted when below
/// `max_hamming` and below `ratio` × the second nearest. Returns
/// `(live index, map index, distance)`, sorted by distance then live index.
pub fn match_descriptors(
    live: &[BriefDescriptor],
    map: &[BriefDescriptor],
    p: &FeatureParams,
) -> Vec<(usize, usize, u32)> {
    let mut out = Vec::new();
    for (i, a) in live.iter().enumerate() {
        let pa = a.position();
        let (mut best, mut second) = ((u32::MAX, usize::MAX), u32::MAX);
        for (j, b) in map.iter().enumerate() {
            let pb = b.position();
            let dx = (pa.x as f32 - pb.x as f32).abs();
            let dy = (pa.y as f32 - pb.y as f32).abs();
            if dx > p.gate_px || dy > p.gate_px || a.bits.len() != b.bits.len() {
                continue;
            }
            let d = a.hamming_distance(b);
            if d < best.0 {
                second = best.0;
                best = (d, j);
            } else if d < second {
                second = d;
            }
        }
        let ratio_ok = second == u32::MAX || (best.0 as f32) < p.ratio * second as f32;
        if best.1 != usize::MAX && best.0 <= p.max_hamming && ratio_ok {
            out.push((i, best.1, best.0));
        }
    }
    out.sort_by_key(|&(i, _, d)| (d, i));
    out
}

/// ZNCC of the `STEREO_PATCH_PX` patches centred at `(xl, y)` in `left` and
/// `(xr, y)` in `right` (row-major, width `w`); callers keep both in the image.
fn zncc(left: &[u8], right: &[u8], w: usize, xl: usize, xr: usize, y: usize) -> f32 {
    let r = STEREO_PATCH_PX / 2;
    let (mut sa, mut sb, mut saa, mut sbb, mut sab) = (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for dy in 0..STEREO_PATCH_PX {
        let row = (y + dy - r) * w;
        for dx in 0..STEREO_PATCH_PX {
            let a = f64::from(left.get(row + xl + dx - r).copied().unwrap_or(0));
            let b = f64::from(right.get(row + xr + dx - r).copied().unwrap_or(0));
            sa += a;
            sb += b;
            saa += a * a;
            sbb += b * b;
            sab += a * b;
        }
    }
    let n = (STEREO_PATCH_PX * STEREO_PATCH_PX) as f64;
    let va = saa - sa * sa / n;
    let vb = sbb - sb * sb / n;
    if va <= 1e-9 || vb <= 1e-9 {
        return -1.0;
    }
    ((sab - sa * sb / n) / (va * vb).sqrt()) as f32
}

/// Disparity of left pixel `(x, y)` of `w×h` images along the same row of `right`: the ZNCC
/// peak over `1..=max_d`, refined by a parabola; `None` when the peak is below
/// `min_zncc`, at the search edge, or the patch leaves the image.
pub fn disparity(
    left: &[u8],
    right: &[u8],
    (w, h): (usize, usize),
    (x, y): (usize, usize),
    max_d: usize,
    min_zncc: f32,
) -> Option<f32> {
    let r = STEREO_PATCH_PX / 2;
    if y < r || y + r >= h || x + r >= w || x < r + 1 || left.len() < w * h || right.len() < w * h {
        return None;
    }
    let max_d = max_d.min(x - r);
    let scores: Vec<f32> = (1..=max_d)
        .map(|d| zncc(left, right, w, x, x - d, y))
        .collect();
    let (k, &best) = scores
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1).then(b.0.cmp(&a.0)))?;
    if best < min_zncc || k == 0 || k + 1 >= scores.len() {
        return None;
    }
    let (a, c) = (scores[k - 1], scores[k + 1]);
    let den = a - 2.0 * best + c;
    let off = if den < 0.0 { 0.5 * (a - c) / den } else { 0.0 };
    Some((k + 1) as f32 + off.clamp(-0.5, 0.5))
}

struct Step {
    pose: Pose,
    inliers: u16,
    map_keypoints: usize,
    matches: usize,
    stereo_points: usize,
}

/// One render–match–fit iteration from `current`.
fn step(
    map: &MapView<'_>,
    req: &Request<'_>,
    p: &FeatureParams,
    pairs: &Vec<TestPair>,
    live: &[BriefDescriptor],
    current: &Pose,
    rng: &mut Rng,
) -> std::result::Result<Step, (String, usize, usize, usize)> {
    let cam = req.rig.cam();
    let (w, h) = (cam.width() as usize, cam.height() as usize);
    let (inten, depth) = render_virtual(map, &cam, current);
    let Some(vimg) = GrayImage::from_raw(cam.width(), cam.height(), inten) else {
        return Err(("FEATURES_BAD_IMAGE".into(), 0, 0, 0));
    };
    let kps = detect(&vimg, p, |x, y| {
        depth
            .get(y as usize * w + x as usize)
            .is_some_and(|z| z.is_finite())
    });
    let mdesc = describe(&vimg, &kps, pairs);
    let nk = mdesc.len();
    let matches = match_descriptors(live, &mdesc, p);
    let nm = matches.len();
    let max_d = ((cam.fx() * req.rig.baseline_m() / STEREO_MIN_DEPTH_M) as usize).min(w / 2);
    let mut corr: Vec<Correspondence> = Vec::new();
    for &(i, j, _) in &matches {
        if corr.len() == MAX_CORR {
            break;
        }
        let (Some(a), Some(b)) = (live.get(i), mdesc.get(j)) else {
            continue;
        };
        let (pa, pb) = (a.position(), b.position());
        let Some(z) = depth.get(pb.y as usize * w + pb.x as usize).copied() else {
            continue;
        };
        let world = current.transform_point(&cam.back_project(pb.x as f32, pb.y as f32, z));
        let Some(d) = disparity(
            req.left,
            req.right,
            (w, h),
            (pa.x as usize, pa.y as usize),
            max_d,
            p.min_zncc,
        ) else {
            continue;
        };
        let (u, v) = (pa.x as f32, pa.y as f32);
        let Ok(pt) = stereo::triangulate(&req.rig, [u, v], [u - d, v], 0.5, 0.5, 1.0) else {
            continue;
        };
        corr.push(Correspondence {
            world,
            cam: pt.p_cam,
            sigma_m: pt.sigma_z_m,
            variant: vtsm_core::pose::VARIANT_UNKNOWN,
            mask_index: vtsm_core::pose::MASK_INDEX_UNKNOWN,
        });
    }
    let ns = corr.len();
    let fail = |s: &str| Err((s.to_string(), nk, nm, ns));
    if ns < 3 {
        return fail("FEATURES_TOO_FEW_MATCHES");
    }
    let mut mask = vec![false; ns];
    let est = match pose::ransac(
        &corr,
        &RansacConfig::from_params(&req.params),
        rng,
        &mut mask,
    ) {
        Ok(e) => e,
        Err(c) => return fail(c.name()),
    };
    if est.inliers < p.min_inliers {
        return fail("FEATURES_TOO_FEW_INLIERS");
    }
    Ok(Step {
        pose: est.pose,
        inliers: est.inliers,
        map_keypoints: nk,
        matches: nm,
        stereo_points: ns,
    })
}

/// Relocalize `req` with local features (see the module documentation). A
/// relocalization that fails cleanly is a report with a failure name.
///
/// # Errors
/// A bad map product or images whose size disagrees with the rig.
pub fn relocalize_features(req: &Request<'_>, p: &FeatureParams) -> Result<FeatureReport> {
    let map = match req.map {
        crate::locate::MapIn::Checked(v) => v,
        crate::locate::MapIn::Bytes(b) => MapView::new_checked(b)?,
    };
    let cam = req.rig.cam();
    let (w, h) = (cam.width(), cam.height());
    let n = w as usize * h as usize;
    if req.left.len() != n || req.right.len() != n {
        return Err(Error::from(vtsm_core::FailureCode::ImageSizeMismatch));
    }
    let t0 = Instant::now();
    let pairs = test_pairs();
    let limg = GrayImage::from_raw(w, h, req.left.to_vec())
        .ok_or_else(|| Error::from(vtsm_core::FailureCode::ImageSizeMismatch))?;
    let lkps = detect(&limg, p, |_, _| true);
    let live = describe(&limg, &lkps, &pairs);
    let mut rng = Rng::new(req.seed).fork(0x4645_4154);
    let mut report = FeatureReport {
        pose: req.prior,
        failure: None,
        inliers: 0,
        iterations: 0,
        map_keypoints: 0,
        live_keypoints: live.len(),
        matches: 0,
        stereo_points: 0,
        elapsed: Duration::ZERO,
    };
    let mut current = req.prior;
    for it in 0..p.iterations.max(1) {
        match step(&map, req, p, &pairs, &live, &current, &mut rng) {
            Ok(s) => {
                if it == 0 {
                    report.map_keypoints = s.map_keypoints;
                    report.matches = s.matches;
                    report.stereo_points = s.stereo_points;
                }
                current = s.pose;
                report.pose = s.pose;
                report.inliers = u32::from(s.inliers);
                report.iterations += 1;
            }
            Err((code, nk, nm, ns)) => {
                if it == 0 {
                    report.failure = Some(code);
                    report.map_keypoints = nk;
                    report.matches = nm;
                    report.stereo_points = ns;
                }
                break;
            }
        }
    }
    report.elapsed = t0.elapsed();
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A textured image: smooth random blobs, deterministic.
    fn texture(w: usize, h: usize, seed: u64) -> Vec<u8> {
        let mut rng = Rng::new(seed);
        let blobs: Vec<(f32, f32, f32, f32)> = (0..200)
            .map(|_| {
                (
                    rng.uniform(0.0, w as f32),
                    rng.uniform(0.0, h as f32),
                    rng.uniform(3.0, 9.0),
                    rng.uniform(-120.0, 120.0),
                )
            })
            .collect();
        let mut img = vec![0u8; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut v = 128.0f32;
                for &(bx, by, r, a) in &blobs {
                    let d2 = ((x as f32 - bx).powi(2) + (y as f32 - by).powi(2)) / (r * r);
                    v += a * (-d2).exp();
                }
                img[y * w + x] = v.clamp(0.0, 255.0) as u8;
            }
        }
        img
    }

    /// Tiled description equals one-piece description, and a paper-profile image
    /// (whose one-piece integral image would overflow `u32`) is described without
    /// a panic.
    /// Verifies: VTSM-CLI-023
    #[test]
    fn large_images_are_described_in_tiles_with_the_one_piece_result() {
        let (w, h) = (300u32, 200u32);
        let img = GrayImage::from_raw(w, h, texture(w as usize, h as usize, 5)).unwrap();
        let pairs = test_pairs();
        let mut fp = FeatureParams::for_width(w);
        fp.cell_px = 16;
        let kps = detect(&img, &fp, |_, _| true);
        assert!(kps.len() > 10, "{} keypoints", kps.len());
        let one = describe(&img, &kps, &pairs);
        let tiled = describe_tiled(&img, &kps, &pairs, 64);
        assert_eq!(one.len(), kps.len());
        assert!(one == tiled);
        let big = GrayImage::from_pixel(5472, 3648, image::Luma([255u8]));
        let corner = [Point::new(5472 - BORDER_PX - 1, 3648 - BORDER_PX - 1)];
        let d = describe(&big, &corner, &pairs);
        assert_eq!(d.len(), 1);
        assert_eq!((d[0].corner.x, d[0].corner.y), (corner[0].x, corner[0].y));
    }

    /// Verifies: VTSM-CLI-023
    #[test]
    fn test_pairs_are_fixed_and_inside_the_patch() {
        let a = test_pairs();
        assert_eq!(a.len(), DESCRIPTOR_BITS);
        assert_eq!(a, test_pairs());
        assert!(a
            .iter()
            .all(|t| t.p0.x < 31 && t.p0.y < 31 && t.p1.x < 31 && t.p1.y < 31));
    }

    /// Verifies: VTSM-CLI-023
    #[test]
    fn stereo_search_recovers_a_known_shift_and_matching_finds_shifted_keypoints() {
        let (w, h) = (200usize, 120usize);
        let left = texture(w, h, 3);
        // right(x) = left(x + 17): disparity 17.
        let right: Vec<u8> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                left[y * w + (x + 17).min(w - 1)]
            })
            .collect();
        let d = disparity(&left, &right, (w, h), (120, 60), 60, 0.8).unwrap();
        assert!((d - 17.0).abs() < 0.25, "{d}");
        // Too far left for any disparity: clean refusal.
        assert!(disparity(&left, &right, (w, h), (3, 60), 60, 0.8).is_none());
        // Flat image: no match.
        let flat = vec![7u8; w * h];
        assert!(disparity(&flat, &flat, (w, h), (120, 60), 60, 0.8).is_none());

        let p = FeatureParams {
            cell_px: 10,
            ..FeatureParams::for_width(w as u32)
        };
        let pairs = test_pairs();
        let a = GrayImage::from_raw(w as u32, h as u32, left).unwrap();
        let b = GrayImage::from_raw(w as u32, h as u32, right).unwrap();
        let (ka, kb) = (detect(&a, &p, |_, _| true), detect(&b, &p, |_, _| true));
        assert!(ka.len() >= 10, "{}", ka.len());
        assert!(ka
            .iter()
            .all(|k| k.x >= BORDER_PX && k.y >= BORDER_PX && k.x < w as u32 - BORDER_PX));
        let (da, db) = (describe(&a, &ka, &pairs), describe(&b, &kb, &pairs));
        let m = match_descriptors(&db, &da, &p);
        assert!(m.len() >= 5, "{}", m.len());
        let good = m
            .iter()
            .filter(|&&(i, j, _)| {
                let (pb, pa) = (db[i].position(), da[j].position());
                pa.y.abs_diff(pb.y) <= 1 && pa.x.abs_diff(pb.x + 17) <= 1
            })
            .count();
        assert!(good * 10 >= m.len() * 7, "{good} of {}", m.len());
        // Sorted by distance.
        assert!(m.windows(2).all(|w| w[0].2 <= w[1].2));
    }
}
