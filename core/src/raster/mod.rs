//! Scanline rasterizer for virtual templates (paper §III-C, `Synthesize`).
//!
//! Renders a window (pixel rectangle) of a virtual pinhole camera placed at
//! `world_from_cam` over a [`MapView`], into caller buffers: 8-bit intensity
//! (bilinear texture sample with perspective-correct UVs), depth, and the depth of
//! the mask sub-mesh M̂ where M̂ is the visible surface. [`template_mask`] turns the
//! two depth buffers into the template mask.
//!
//! Pipeline per call: tiles whose box lies outside the window frustum (four side
//! planes and the near plane) are skipped; each remaining triangle is rejected
//! if all corners lie outside one window side plane (world frame), moved to the
//! camera frame, rejected if all corners lie in front of the near plane,
//! clipped in camera space against the near plane and, only when a corner lies
//! outside it, against the guard band ([`RASTER_GUARD_PX`](crate::config::RASTER_GUARD_PX) beyond the window);
//! the clipped convex polygon is snapped to 28.4 fixed point in absolute image
//! pixels and filled span by span as one polygon (never fanned, so snapping
//! cannot make pieces of one triangle overlap). Coverage is decided exactly on
//! integers with a top-left style tie rule (a pixel centre on an edge belongs to
//! the polygon that holds the centre moved by (ε, ε²)), so triangles sharing an
//! edge cover each pixel exactly once. Back faces are drawn (photogrammetry meshes
//! have arbitrary winding). A triangle of small depth range (at most 1/32 of its
//! depth, and small enough that texture coordinates move by at most 1/32 texel;
//! see `Affine`) that needs no clipping gets depth and UVs linear in the image,
//! as an exact integer plane stepped once per pixel along each span. Any other
//! triangle gets them from its unclipped plane (1/Z, u/Z, v/Z linear in the
//! image), evaluated exactly at every 8th absolute pixel column and stepped
//! linearly in fixed point in between when depth changes by at most 1/64 over
//! the 8 pixels (exactly at every pixel otherwise). Nothing that decides a pixel
//! depends on the window, so a window render equals the same crop of a full
//! render bit for bit.
//!
//! Depth format: `u32` camera-frame Z (along the optical axis) in units of
//! 2⁻¹⁶ m ([`DEPTH_FRAC_BITS`]), [`DEPTH_NONE`] where nothing was drawn; see
//! `fsw-docs/budgets/numeric.md`.
//!
//! Bounds: window ≤ [`MAX_RENDER_PX`]² pixels; tiles ≤ `MAX_MAP_TILES`, triangles
//! ≤ `MAX_MAP_TRIANGLES` per call (each visited at most once); a clipped polygon has
//! at most [`MAX_CLIP_VERTS`] corners; each polygon's rows and spans are
//! clipped to the window. [`RenderStats`] reports the work.

//!
//! Files, one step each, imported one way (top to bottom):
//! - `mod.rs` (this file): the entry points [`render_window`] and
//!   `rasterize` (tile and triangle culling, then one triangle at a time);
//! - `fill.rs`: a clipped polygon's rows and spans;
//! - `edge.rs`: edge functions walked row by row;
//! - `interp.rs`: depth and texture-coordinate interpolation per triangle;
//! - `frame.rs`: per-call window geometry, clipping, projection and snapping;
//! - `target.rs`: the caller's buffers, the depth test, [`RenderStats`];
//! - `texture.rs`: bilinear texture sampling;
//! - `depth.rs`: the depth format;
//! - `mask.rs`: [`template_mask`], which reads a finished render.

mod depth;
mod edge;
mod fill;
mod frame;
mod interp;
mod mask;
mod target;
mod texture;

pub use depth::{depth_from_m, depth_to_m, DEPTH_FRAC_BITS, DEPTH_MAX, DEPTH_NONE};
pub use frame::{MAX_CLIP_VERTS, SUBPIXEL_BITS};
pub use mask::template_mask;
pub use target::{RenderStats, Target};

use crate::config::{MAX_IMAGE_DIM, MAX_RENDER_PX, RASTER_NEAR_M};
use crate::failure::FailureCode;
use crate::geom::{Camera, Pose, Vec3};
use crate::image::Rect;
use crate::map::MapView;
use fill::fill_polygon;
use frame::{clip_poly, project, snap, Frame, ScreenVert};
use interp::attributes;
use target::{PixelSink, ZBuffer};

#[cfg(test)]
use target::Frag;

/// Clip and fill one triangle given in the camera frame (not rejected against
/// the window frustum by `rasterize`).
fn draw_triangle<S: PixelSink>(
    frame: &Frame,
    p: [Vec3; 3],
    uv: &[[f32; 2]; 3],
    mask: bool,
    stats: &mut RenderStats,
    sink: &mut S,
) {
    let mut screen = [ScreenVert::default(); MAX_CLIP_VERTS];
    let clip = frame
        .clip_planes
        .iter()
        .any(|pl| p.iter().any(|c| pl.dist(c) < 0.0));
    if clip {
        let mut poly = [Vec3::zeros(); MAX_CLIP_VERTS];
        let mut tmp = [Vec3::zeros(); MAX_CLIP_VERTS];
        poly[..3].copy_from_slice(&p);
        let mut n = 3;
        for pl in &frame.clip_planes {
            if poly.iter().take(n).any(|c| pl.dist(c) < 0.0) {
                n = clip_poly(&poly, n, pl, &mut tmp);
                poly = tmp;
                if n < 3 {
                    return;
                }
            }
        }
        for (sv, c) in screen.iter_mut().zip(poly.iter().take(n)) {
            *sv = snap(frame, project(frame, c));
        }
        // The choice of interpolation depends on the triangle only (a triangle
        // inside the image's guard band is clipped only by rounding), so it is the
        // same whatever window, and hence guard band, the call uses.
        let make = || attributes(frame, &p, &p.map(|c| project(frame, &c)), uv);
        fill_polygon(&screen, n, make, mask, frame, stats, sink);
    } else {
        let s = p.map(|c| project(frame, &c));
        for (sv, c) in screen.iter_mut().zip(s) {
            *sv = snap(frame, c);
        }
        fill_polygon(
            &screen,
            3,
            || attributes(frame, &p, &s, uv),
            mask,
            frame,
            stats,
            sink,
        );
    }
}

#[allow(
    clippy::arithmetic_side_effects,
    clippy::cast_possible_truncation,
    reason = "2·MAX_IMAGE_DIM and MAX_RENDER_PX are small constants that fit i32 and u32"
)]
fn check_inputs(world_from_cam: &Pose, window: Rect) -> Result<(), FailureCode> {
    let lim = 2 * MAX_IMAGE_DIM as i32;
    let window_ok = (1..=MAX_RENDER_PX as u32).contains(&window.w)
        && (1..=MAX_RENDER_PX as u32).contains(&window.h)
        && (-lim..=lim).contains(&window.x)
        && (-lim..=lim).contains(&window.y);
    if !window_ok {
        return Err(FailureCode::RasterWindowInvalid);
    }
    // `Camera` is a checked type (built only by `Camera::new`), so its image size
    // and intrinsics are within the bounds that `Frame` turns into fixed-point
    // limits (see `fill_polygon`'s overflow budget); no per-call re-check.
    if !world_from_cam.is_finite() {
        return Err(FailureCode::RasterPoseInvalid);
    }
    Ok(())
}

/// Walk the visible tiles and triangles, calling `sink` for every covered pixel.
#[allow(
    clippy::arithmetic_side_effects,
    reason = "f32 vector arithmetic (nalgebra); no integer operation"
)]
pub(crate) fn rasterize<S: PixelSink>(
    map: &MapView,
    cam: &Camera,
    world_from_cam: &Pose,
    window: Rect,
    sink: &mut S,
) -> Result<RenderStats, FailureCode> {
    check_inputs(world_from_cam, window)?;
    let frame = Frame::new(cam, world_from_cam, window);
    let mut stats = RenderStats::default();
    let to_cam = |p: Vec3| frame.rot * p + frame.trans;
    for k in 0..map.tile_count() {
        let Some(tile) = map.tile(k) else { break };
        if tile.triangle_count == 0 {
            continue;
        }
        stats.tiles_tested = stats.tiles_tested.saturating_add(1);
        if !frame.box_visible(&tile.min, &tile.max) {
            continue;
        }
        stats.tiles_visible = stats.tiles_visible.saturating_add(1);
        let end = tile.first_triangle.saturating_add(tile.triangle_count);
        for i in tile.first_triangle..end.min(map.triangle_count()) {
            stats.triangles_tested = stats.triangles_tested.saturating_add(1);
            let Some(w) = map.triangle_vertices(i) else {
                break;
            };
            // Reject triangles with all corners beyond one side plane of the window
            // (tested in the world frame, before the transform) or all in front of
            // the near plane. The side planes lie half a pixel outside the window's
            // outer pixel centres, far beyond rounding, so no covered pixel is lost.
            if frame
                .world_planes
                .iter()
                .skip(1)
                .any(|pl| w.iter().all(|c| pl.dist(c) < 0.0))
            {
                continue;
            }
            let p = w.map(to_cam);
            if p.iter().all(|c| c.z < RASTER_NEAR_M) {
                continue;
            }
            let Some(t) = map.triangle(i) else { break };
            draw_triangle(&frame, p, &t.uv, t.mask, &mut stats, sink);
        }
    }
    Ok(stats)
}

/// Render `window` (a pixel rectangle of the full virtual image of `cam`) of the
/// map seen from `world_from_cam` into `target`.
///
/// The three buffers are cleared over `w·h` (intensity 0, depths [`DEPTH_NONE`])
/// and then filled with a strict-less depth test; ties keep the first surface
/// drawn (deterministic map order).
///
/// # Errors
/// [`FailureCode::RasterWindowInvalid`] (empty, above [`MAX_RENDER_PX`], origin
/// beyond ±2·`MAX_IMAGE_DIM`), [`FailureCode::RasterBufferTooSmall`],
/// [`FailureCode::RasterPoseInvalid`] (non-finite pose),
/// [`FailureCode::RasterNothingVisible`] (no pixel written; buffers are cleared).
pub fn render_window(
    map: &MapView,
    cam: &Camera,
    world_from_cam: &Pose,
    window: Rect,
    target: &mut Target,
) -> Result<RenderStats, FailureCode> {
    check_inputs(world_from_cam, window)?;
    let n = (window.w as usize).saturating_mul(window.h as usize);
    let (Some(inten), Some(depth), Some(mdepth)) = (
        target.intensity.get_mut(..n),
        target.depth.get_mut(..n),
        target.mask_depth.get_mut(..n),
    ) else {
        return Err(FailureCode::RasterBufferTooSmall);
    };
    inten.fill(0);
    depth.fill(DEPTH_NONE);
    mdepth.fill(DEPTH_NONE);
    let tex = map.texture();
    let (tw, th) = (tex.width(), tex.height());
    let mut sink = ZBuffer {
        intensity: inten,
        depth,
        mask_depth: mdepth,
        tex: map.texture_bytes(),
        tw,
        th,
        written: 0,
    };
    let mut stats = rasterize(map, cam, world_from_cam, window, &mut sink)?;
    let written = sink.written;
    stats.pixels_written = written;
    if written == 0 {
        return Err(FailureCode::RasterNothingVisible);
    }
    Ok(stats)
}

#[cfg(test)]
mod tests;
