//! Span filling of one clipped, snapped convex polygon: exact integer
//! coverage with the owner rule, then each row's span handed to the pixel sink
//! as a linear run (affine triangles) or perspective-correct segments.
//!
//! Input: at most [`MAX_CLIP_VERTS`] corners in 28.4 fixed point, the window
//! [`Frame`], a lazily built [`Attr`]; output: the covered pixels of the window,
//! each once, to the sink, and the counts in [`RenderStats`]. Rows and spans
//! are clipped to the window.

use super::depth::DEPTH_MAX;
use super::edge::{ceil_div, floor_div, EdgeWalk, Side};
use super::frame::{Frame, ScreenVert, MAX_CLIP_VERTS, SUBPIXEL_BITS};
use super::interp::{exact_at, Affine, Attr, Interp, LINEAR_MAX_DZ_INV, SEG, SEG_SHIFT};
use super::target::{Frag, PixelSink, RenderStats, RUN_SHIFT};

/// Fill one clipped, snapped convex polygon (`v[..n]`, n ≤ [`MAX_CLIP_VERTS`]).
/// Coverage is exact integer arithmetic on 28.4 coordinates (magnitudes < 2^18,
/// edge terms < 2^40 in i64): a pixel is covered when it is inside every edge's
/// half-plane, so one polygon covers a pixel at most once even when snapping
/// made it slightly non-convex (a reflex corner then only trims a sliver). The
/// sink is called once per covered pixel inside the window.
#[allow(
    clippy::cast_possible_truncation,
    reason = "row offsets inside the window (≤ MAX_RENDER_PX²), formed with wrapping arithmetic on coordinates bounded by the guard band"
)]
pub(super) fn fill_polygon<S: PixelSink>(
    v: &[ScreenVert; MAX_CLIP_VERTS],
    n: usize,
    make_attr: impl FnOnce() -> Option<Attr>,
    mask: bool,
    frame: &Frame,
    stats: &mut RenderStats,
    sink: &mut S,
) {
    let n = n.min(MAX_CLIP_VERTS);
    if n < 3 {
        return;
    }
    let Some((area, [x_lo, x_hi, y_lo, y_hi])) = pixel_box(v, n, frame) else {
        return;
    };
    // Attribute setup only for polygons that reach a pixel centre of the window.
    let Some(attr) = make_attr() else {
        return;
    };
    let attr = &attr;
    stats.triangles_drawn = stats.triangles_drawn.saturating_add(1);
    if matches!(attr, Attr::Affine(_)) {
        stats.triangles_linear = stats.triangles_linear.saturating_add(1);
    }
    let mut walks = [EdgeWalk::default(); MAX_CLIP_VERTS];
    // `edge_walks` never counts past the array; were it to, an empty edge list
    // would fill the whole bounding box, so draw nothing instead.
    let ne = edge_walks(v, n, area, y_lo, &mut walks);
    let Some(walks) = walks.get_mut(..ne) else {
        return;
    };
    let (wx, wy, w) = (frame.wx, frame.wy, frame.w);
    for py in y_lo..=y_hi {
        let Some((xl, xr)) = row_span(walks, x_lo, x_hi) else {
            continue;
        };
        stats.spans = stats.spans.saturating_add(1);
        let row = py.wrapping_sub(wy).wrapping_mul(w).wrapping_sub(wx) as usize;
        match attr {
            Attr::Affine(af) => fill_span_affine(af, py, xl, xr, row, mask, sink),
            Attr::Perspective(it) => fill_span_perspective(it, frame, py, xl, xr, row, mask, sink),
        }
    }
}

/// Corner pairs (v0, v1), (v1, v2), …, (v[n−1], v0) of the polygon `v[..n]`.
fn corner_pairs(
    v: &[ScreenVert; MAX_CLIP_VERTS],
    n: usize,
) -> impl Iterator<Item = (&ScreenVert, &ScreenVert)> {
    v.iter().take(n).zip(v.iter().take(n).cycle().skip(1))
}

/// Twice the polygon's signed area (shoelace, for the orientation) and the
/// pixel centres it may cover inside the window (`[x_lo, x_hi, y_lo, y_hi]`);
/// `None` for a polygon of zero area or one that reaches no pixel centre of the
/// window.
fn pixel_box(v: &[ScreenVert; MAX_CLIP_VERTS], n: usize, frame: &Frame) -> Option<(i64, [i64; 4])> {
    let mut area = 0i64;
    let (mut minx, mut maxx, mut miny, mut maxy) = (i64::MAX, i64::MIN, i64::MAX, i64::MIN);
    // Wrapping arithmetic in the polygon setup: snapped coordinates lie within
    // the frame's guard band (|x|, |y| < 2^18 in 28.4), so products stay below
    // 2^40 and nothing wraps; the wrapping forms only remove the panic paths.
    for (&p, &q) in corner_pairs(v, n) {
        area = area.wrapping_add(p.x.wrapping_mul(q.y).wrapping_sub(q.x.wrapping_mul(p.y)));
        minx = minx.min(p.x);
        maxx = maxx.max(p.x);
        miny = miny.min(p.y);
        maxy = maxy.max(p.y);
    }
    if area == 0 {
        return None;
    }
    let s = i64::from(1u32 << SUBPIXEL_BITS);
    let x_lo = ceil_div(minx, s).max(frame.wx);
    let x_hi = floor_div(maxx, s).min(frame.wx.wrapping_add(frame.w).wrapping_sub(1));
    let y_lo = ceil_div(miny, s).max(frame.wy);
    let y_hi = floor_div(maxy, s).min(frame.wy.wrapping_add(frame.h).wrapping_sub(1));
    if x_lo > x_hi || y_lo > y_hi {
        return None;
    }
    Some((area, [x_lo, x_hi, y_lo, y_hi]))
}

/// The polygon's non-degenerate edges as walks started at row `y_lo`, into
/// `walks`; returns how many (≤ [`MAX_CLIP_VERTS`]).
fn edge_walks(
    v: &[ScreenVert; MAX_CLIP_VERTS],
    n: usize,
    area: i64,
    y_lo: i64,
    walks: &mut [EdgeWalk; MAX_CLIP_VERTS],
) -> usize {
    let s = i64::from(1u32 << SUBPIXEL_BITS);
    // Edge (p→q), walked counter-clockwise in the image (area > 0):
    // E(px,py) = A·px + B·py + C, positive inside.
    let mut ne = 0;
    for (&p, &q) in corner_pairs(v, n) {
        let (mut p, mut q) = (p, q);
        if area < 0 {
            core::mem::swap(&mut p, &mut q);
        }
        if p.x == q.x && p.y == q.y {
            continue;
        }
        let (dx, dy) = (q.x.wrapping_sub(p.x), q.y.wrapping_sub(p.y));
        let a = s.wrapping_mul(dy).wrapping_neg();
        let b = s.wrapping_mul(dx);
        let c = dy.wrapping_mul(p.x).wrapping_sub(dx.wrapping_mul(p.y));
        // Owner rule: a pixel centre on the edge is inside iff the centre moved by
        // (ε, ε²) is, i.e. A > 0 or (A == 0 and B > 0). Exactly one of two
        // polygons sharing the edge (opposite directions) owns it.
        let t = if a > 0 || (a == 0 && b > 0) { 0 } else { 1 };
        if let Some(wk) = walks.get_mut(ne) {
            *wk = EdgeWalk::new((a, b, c, t), y_lo);
            // `get_mut` succeeded: ne < MAX_CLIP_VERTS.
            ne = usize::wrapping_add(ne, 1);
        }
    }
    ne
}

/// The covered columns `xl..=xr` of the current row within `x_lo..=x_hi`
/// (`None` when the row is empty); steps every walk on to the next row.
fn row_span(walks: &mut [EdgeWalk], x_lo: i64, x_hi: i64) -> Option<(i64, i64)> {
    let mut xl = x_lo;
    let mut xr = x_hi;
    let mut empty = false;
    for wk in walks.iter_mut() {
        match wk.side {
            Side::Left => xl = xl.max(wk.q),
            Side::Right => xr = xr.min(wk.q),
            Side::Flat => empty |= wk.m < 0,
        }
        wk.step();
    }
    (!empty && xl <= xr).then_some((xl, xr))
}

/// Fill pixels `xl..=xr` of row `py` from the exact integer plane `af`, as one run.
#[inline]
#[allow(
    clippy::cast_possible_truncation,
    reason = "span lengths and column offsets inside the window (≤ MAX_RENDER_PX)"
)]
fn fill_span_affine<S: PixelSink>(
    af: &Affine,
    py: i64,
    xl: i64,
    xr: i64,
    row: usize,
    mask: bool,
    sink: &mut S,
) {
    // Exact integer plane: the value at pixel x is the same whichever
    // pixel the span starts at. Bounds: |base| ≤ 2^53, |gradient| ≤ 2^40,
    // pixel offsets < 2^15, so every accumulator stays below 2^57.
    let (dx, dy) = (xl.wrapping_sub(af.ax), py.wrapping_sub(af.ay));
    let mut acc = af.base;
    for ((a, gx), gy) in acc.iter_mut().zip(af.gx).zip(af.gy) {
        *a = a
            .wrapping_add(gx.wrapping_mul(dx))
            .wrapping_add(gy.wrapping_mul(dy));
    }
    sink.put_run(
        row.wrapping_add(xl as usize),
        xr.wrapping_sub(xl).wrapping_add(1) as usize,
        acc,
        af.gx,
        mask,
    );
}

/// Fill pixels `xl..=xr` of row `py` with perspective-correct values: exact at
/// every `SEG`-th absolute column, linear in between where depth changes little.
#[allow(clippy::too_many_arguments)]
#[inline]
#[allow(
    clippy::cast_possible_truncation,
    reason = "pixel offsets inside the window (≤ MAX_RENDER_PX²); depth clamped to 0..=DEPTH_MAX before the cast"
)]
pub(super) fn fill_span_perspective<S: PixelSink>(
    it: &Interp,
    frame: &Frame,
    py: i64,
    xl: i64,
    xr: i64,
    row: usize,
    mask: bool,
    sink: &mut S,
) {
    let yn = (py as f32 - frame.cy) * frame.inv_fy;
    let row_w = it.inv_z.y * yn + it.inv_z.z;
    let row_u = it.u_over_z.y * yn + it.u_over_z.z;
    let row_v = it.v_over_z.y * yn + it.v_over_z.z;
    let at = |x: i64| {
        exact_at(
            (x as f32 - frame.cx) * frame.inv_fx,
            row_w,
            row_u,
            row_v,
            it,
        )
    };
    let mut px = xl;
    // The exact values at the end of one segment are those at the start of the
    // next (same column, same arithmetic): evaluated once per boundary.
    let mut next: Option<(i64, Option<[i64; 3]>)> = None;
    // Bounded: each pass advances px to the next segment boundary (at most
    // w / SEG + 2 passes per span).
    while px <= xr {
        let s0 = px & !(SEG - 1);
        let s1 = s0.saturating_add(SEG);
        let end = xr.min(s1.saturating_sub(1));
        let e0 = match next {
            Some((col, e)) if col == s0 => e,
            _ => at(s0),
        };
        let e1 = at(s1);
        next = Some((s1, e1));
        match (e0, e1) {
            // Linear depth and UVs deviate from perspective-correct values by about
            // δ²/4 of depth with δ the relative change of depth over the segment;
            // segments with δ > 1/64 are evaluated exactly at every pixel instead.
            (Some(a), Some(b))
                if a[0] >= 0
                    && b[0]
                        .wrapping_sub(a[0])
                        .unsigned_abs()
                        .saturating_mul(LINEAR_MAX_DZ_INV as u64)
                        <= a[0] as u64 =>
            {
                // Bounded as documented below: the wrapping forms never wrap.
                let d = [
                    b[0].wrapping_sub(a[0]),
                    b[1].wrapping_sub(a[1]),
                    b[2].wrapping_sub(a[2]),
                ];
                let k = px.wrapping_sub(s0);
                // acc / SEG is the linear interpolation between the segment ends,
                // rescaled to RUN_SHIFT fractional bits (|a| ≤ 2^37, |d| ≤ 2^38:
                // below 2^54 after the shift).
                let sh = RUN_SHIFT - SEG_SHIFT;
                let lin =
                    |a: i64, d: i64| a.wrapping_mul(SEG).wrapping_add(d.wrapping_mul(k)) << sh;
                let acc = [lin(a[0], d[0]), lin(a[1], d[1]), lin(a[2], d[2])];
                sink.put_run(
                    row.wrapping_add(px as usize),
                    end.wrapping_sub(px).wrapping_add(1) as usize,
                    acc,
                    [d[0] << sh, d[1] << sh, d[2] << sh],
                    mask,
                );
            }
            _ => {
                for x in px..=end {
                    let e = at(x).unwrap_or([i64::from(DEPTH_MAX), 0, 0]);
                    sink.put(Frag {
                        idx: row.wrapping_add(x as usize),
                        depth: e[0].clamp(0, i64::from(DEPTH_MAX)) as u32,
                        u_q16: e[1],
                        v_q16: e[2],
                        mask,
                    });
                }
            }
        }
        let Some(next_px) = end.checked_add(1) else {
            break;
        };
        px = next_px;
    }
}
