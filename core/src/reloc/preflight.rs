//! Preflight: the fast "no fix". Before any template is rendered, decide from
//! cheap evidence whether a relocalization can possibly succeed, so a hopeless
//! input ends in a specific failure code after a bounded pass over the inputs
//! instead of minutes of Stall and Reseed.
//!
//! The frames are read through their [`FrameSource`], two rows at a time into
//! two caller buffers of at least two image rows each (the workspace's frame
//! windows); a read that fails ends the preflight with
//! [`FailureCode::RelocFrameReadFailed`].
//!
//! Checks (each bounded by the inputs' sizes, which `config` caps):
//! * each image shows texture on at least [`MIN_TEXTURE_PERMILLE`] ‰ of the
//!   pixels of [`PREFLIGHT_ROWS`] evenly spaced rows (black, saturated and flat
//!   frames fail with [`FailureCode::RelocFrameNoTexture`]);
//! * the two images differ on at least one sampled row
//!   ([`FailureCode::RelocStereoIdentical`]: one sensor delivered twice);
//! * the images are larger than a template, and at least one mask vertex
//!   projects in front of the prior's left camera inside its image
//!   ([`FailureCode::RelocNoVisibleMaskVertex`]: facing the sky, far away,
//!   wrong intrinsics).

use crate::failure::FailureCode;
use crate::frame::{Eye, FrameSource};
use crate::geom::{Pose, StereoRig};
#[cfg(test)]
use crate::image::GrayView;
use crate::image::Rect;
use crate::map::MapView;

/// Rows of each image sampled by the texture and identity checks.
pub const PREFLIGHT_ROWS: usize = 64;
/// Smallest share of textured pixels (‰) a usable image shows on the sampled rows.
pub const MIN_TEXTURE_PERMILLE: u32 = 20;
/// A pixel is textured when it is not 0 or 255 and differs from its right or
/// lower neighbour by at least this many gray levels.
pub const TEXTURE_STEP: u8 = 2;

/// What the preflight measured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Preflight {
    /// Textured share of the sampled pixels of the left image, ‰.
    pub left_texture_permille: u32,
    /// Textured share of the sampled pixels of the right image, ‰.
    pub right_texture_permille: u32,
    /// Mask vertices found in front of the prior's left camera and inside its
    /// image: 0 or 1, since the scan stops at the first one.
    pub visible_mask_vertices: u32,
    /// Pixels and vertices read (the work of the preflight).
    pub reads: u64,
}

/// Evenly spaced row indices `0..h` (at most [`PREFLIGHT_ROWS`], each once).
fn sampled_rows(h: usize) -> impl Iterator<Item = usize> {
    let n = h.min(PREFLIGHT_ROWS);
    // k < n ≤ PREFLIGHT_ROWS and h ≤ MAX_IMAGE_DIM: the product fits; the
    // wrapping forms keep the arithmetic total.
    (0..n).map(move |k| {
        k.wrapping_mul(h.saturating_sub(1))
            .checked_div(n.saturating_sub(1))
            .unwrap_or(0)
    })
}

/// Textured pixels of `row` (its lower neighbour row `below`, the row itself
/// on the last row of the image).
fn textured_pixels(row: &[u8], below: &[u8]) -> u64 {
    let mut textured = 0u64;
    // A range, not `enumerate`: its counter carries an overflow check.
    for (x, &p) in (0..row.len()).zip(row) {
        if p == 0 || p == 255 {
            continue;
        }
        let right = row.get(x.wrapping_add(1)).copied().unwrap_or(p);
        let down = below.get(x).copied().unwrap_or(p);
        if p.abs_diff(right) >= TEXTURE_STEP || p.abs_diff(down) >= TEXTURE_STEP {
            textured = textured.saturating_add(1);
        }
    }
    textured
}

/// Read row `y` of `eye` and the row below it (if any) into `buf`: the row
/// and its lower neighbour (the row itself on the last row).
fn read_rows<'b, F: FrameSource + ?Sized>(
    frames: &mut F,
    eye: Eye,
    y: usize,
    buf: &'b mut [u8],
) -> Result<(&'b [u8], &'b [u8]), FailureCode> {
    let (w, h) = frames.size();
    let rows = if y.saturating_add(1) < h { 2 } else { 1 };
    let to_i32 = |v: usize| i32::try_from(v).map_err(|_| FailureCode::RelocFrameReadFailed);
    let to_u32 = |v: usize| u32::try_from(v).map_err(|_| FailureCode::RelocFrameReadFailed);
    let rect = Rect::new(0, to_i32(y)?, to_u32(w)?, to_u32(rows)?);
    let out = buf
        .get_mut(..w.saturating_mul(rows))
        .ok_or(FailureCode::RelocFrameReadFailed)?;
    frames
        .read_window(eye, rect, out)
        .map_err(|_| FailureCode::RelocFrameReadFailed)?;
    let out: &'b [u8] = out;
    let (row, rest) = out.split_at(w.min(out.len()));
    Ok((row, if rest.is_empty() { row } else { rest }))
}

/// Textured share (‰) of `textured` of `total` sampled pixels.
fn permille(textured: u64, total: u64) -> u32 {
    textured
        .saturating_mul(1000)
        .checked_div(total)
        .unwrap_or(0) as u32
}

/// Run the preflight on the stereo pair of `frames` (of `rig`'s size), the
/// map and the prior; `left_rows` and `right_rows` hold at least two image
/// rows each.
///
/// # Errors
/// [`FailureCode::RelocFrameNoTexture`], [`FailureCode::RelocStereoIdentical`]
/// or [`FailureCode::RelocNoVisibleMaskVertex`], as described in the module
/// docs; [`FailureCode::RelocFrameReadFailed`] when a row cannot be read.
pub fn check<F: FrameSource + ?Sized>(
    map: &MapView,
    frames: &mut F,
    (left_rows, right_rows): (&mut [u8], &mut [u8]),
    rig: &StereoRig,
    prior: &Pose,
    template_px: usize,
) -> Result<Preflight, FailureCode> {
    let mut out = Preflight::default();
    let (w, h) = frames.size();
    let (mut tl, mut tr, mut total) = (0u64, 0u64, 0u64);
    let mut identical = true;
    for y in sampled_rows(h) {
        let (lrow, lbelow) = read_rows(frames, Eye::Left, y, left_rows)?;
        let (rrow, rbelow) = read_rows(frames, Eye::Right, y, right_rows)?;
        tl = tl.saturating_add(textured_pixels(lrow, lbelow));
        tr = tr.saturating_add(textured_pixels(rrow, rbelow));
        total = total.saturating_add(w as u64);
        identical &= lrow == rrow;
    }
    let (tl, tr) = (permille(tl, total), permille(tr, total));
    out.left_texture_permille = tl;
    out.right_texture_permille = tr;
    out.reads = total.saturating_mul(4);
    if tl < MIN_TEXTURE_PERMILLE || tr < MIN_TEXTURE_PERMILLE {
        return Err(FailureCode::RelocFrameNoTexture);
    }
    if identical {
        return Err(FailureCode::RelocStereoIdentical);
    }
    let cam = &rig.cam;
    if (cam.width as usize) <= template_px || (cam.height as usize) <= template_px {
        return Err(FailureCode::RelocNoVisibleMaskVertex);
    }
    let cam_from_world = prior.inverse();
    for k in 0..map.mask_vertex_count() {
        let Some(world) = map.mask_vertex(k).and_then(|i| map.vertex(i)) else {
            continue;
        };
        out.reads = out.reads.saturating_add(1);
        let p = cam_from_world.transform_point(&world);
        if let Some((l, _)) = rig.project_stereo(&p) {
            if cam.contains(l[0], l[1], 0.0) {
                out.visible_mask_vertices = out.visible_mask_vertices.saturating_add(1);
                // One is enough to know the run can start.
                break;
            }
        }
    }
    if out.visible_mask_vertices == 0 {
        return Err(FailureCode::RelocNoVisibleMaskVertex);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::frame::StereoPair;
    use crate::geom::Vec3;
    use crate::rng::Rng;
    use crate::testkit::{build_map, camera_pose, render_full, rig};
    use nalgebra::UnitQuaternion;
    use std::vec;

    /// The preflight over two in-memory views.
    fn run(
        map: &MapView,
        left: &GrayView,
        right: &GrayView,
        rig: &StereoRig,
        prior: &Pose,
        template_px: usize,
    ) -> Result<Preflight, FailureCode> {
        let mut pair = StereoPair::new(*left, *right);
        let (mut a, mut b) = (vec![0u8; 2 * left.width()], vec![0u8; 2 * left.width()]);
        check(map, &mut pair, (&mut a, &mut b), rig, prior, template_px)
    }

    /// A source that serves `good` reads, then fails.
    struct Failing<'a> {
        pair: StereoPair<'a>,
        good: u32,
    }

    impl FrameSource for Failing<'_> {
        fn size(&self) -> (usize, usize) {
            self.pair.size()
        }
        fn read_window(&mut self, eye: Eye, r: Rect, out: &mut [u8]) -> Result<(), FailureCode> {
            if self.good == 0 {
                return Err(FailureCode::HalFrameStoreRead);
            }
            self.good -= 1;
            self.pair.read_window(eye, r, out)
        }
    }

    /// Verifies: VTSM-RELOC-021, VTSM-RELOC-037
    #[test]
    fn hopeless_inputs_get_their_own_code_and_good_ones_pass() {
        let bytes = build_map(1);
        let map = MapView::new_checked(&bytes).unwrap();
        let rig = rig();
        let truth = camera_pose(0.6, 0.2);
        let left = render_full(&map, &rig.cam, &truth, 0.85, 20.0);
        let right = render_full(&map, &rig.cam, &rig.world_from_right(&truth), 0.85, 20.0);
        fn view(b: &[u8]) -> GrayView<'_> {
            GrayView::new(b, 640, 480, 640).unwrap()
        }
        let (lv, rv) = (view(&left), view(&right));
        let ok = run(&map, &lv, &rv, &rig, &truth, 64).unwrap();
        assert!(ok.left_texture_permille > 500, "{ok:?}");
        assert!(ok.visible_mask_vertices > 0 && ok.reads > 0);

        let black = vec![0u8; 640 * 480];
        let white = vec![255u8; 640 * 480];
        let flat = vec![117u8; 640 * 480];
        for bad in [&black, &white, &flat] {
            let e = run(&map, &view(bad), &rv, &rig, &truth, 64).err();
            assert_eq!(e, Some(FailureCode::RelocFrameNoTexture));
            let e = run(&map, &lv, &view(bad), &rig, &truth, 64).err();
            assert_eq!(e, Some(FailureCode::RelocFrameNoTexture));
        }
        // Pure noise is textured: it passes here and is left to the engine.
        let mut rng = Rng::new(5);
        let noise: std::vec::Vec<u8> = (0..640 * 480).map(|_| rng.below(256) as u8).collect();
        assert!(run(&map, &view(&noise), &rv, &rig, &truth, 64).is_ok());

        let e = run(&map, &lv, &lv, &rig, &truth, 64).err();
        assert_eq!(e, Some(FailureCode::RelocStereoIdentical));

        let sky = Pose::new(
            UnitQuaternion::from_axis_angle(&Vec3::x_axis(), core::f32::consts::PI)
                * truth.rotation(),
            truth.translation(),
        );
        let far = Pose::new(
            truth.rotation(),
            truth.translation() + Vec3::new(100.0, 0.0, 0.0),
        );
        for prior in [sky, far] {
            let e = run(&map, &lv, &rv, &rig, &prior, 64).err();
            assert_eq!(e, Some(FailureCode::RelocNoVisibleMaskVertex));
        }
        // A frame source that fails part-way: the preflight ends with the
        // read failure, whatever it had read before.
        for good in [0, 1, 17] {
            let mut src = Failing {
                pair: StereoPair::new(lv, rv),
                good,
            };
            let (mut a, mut b) = (vec![0u8; 1280], vec![0u8; 1280]);
            let e = check(&map, &mut src, (&mut a, &mut b), &rig, &truth, 64).err();
            assert_eq!(e, Some(FailureCode::RelocFrameReadFailed));
        }
        // Buffers shorter than two rows cannot hold a read.
        let mut pair = StereoPair::new(lv, rv);
        let (mut a, mut b) = (vec![0u8; 1279], vec![0u8; 1280]);
        let e = check(&map, &mut pair, (&mut a, &mut b), &rig, &truth, 64).err();
        assert_eq!(e, Some(FailureCode::RelocFrameReadFailed));
        // Templates as large as the image can never be placed.
        let e = run(&map, &lv, &rv, &rig, &truth, 480).err();
        assert_eq!(e, Some(FailureCode::RelocNoVisibleMaskVertex));
    }
}
