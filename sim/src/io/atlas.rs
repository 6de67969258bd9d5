//! Texture pages → one gray atlas, for meshes whose faces use several textures
//! (photogrammetry exports: Metashape, RealityCapture, OpenMVS, baked Blender
//! meshes write one texture page per material).
//!
//! A map product holds one texture and the core's rasterizer has one texture
//! fetch path, so the pages are repacked at build time into one atlas and the
//! faces' texture coordinates remapped into it; the map product format and the
//! rasterizer stay as they are.
//!
//! What each page contributes is exactly the texels that its faces can sample,
//! plus a margin. The rasterizer samples bilinearly (no mip levels): a point at
//! texture pixel `x` (centres on integers) reads texels `⌊x⌋` and `⌊x⌋ + 1`, and
//! interpolated coordinates stay inside the triangle's corner coordinates up to
//! 1/32 texel. So for the faces of a page whose corners span `x ∈ [x_min, x_max]`
//! (and likewise in y), the page's rectangle in the atlas covers texels
//! `⌊x_min⌋ − ATLAS_MARGIN_PX ..= ⌊x_max⌋ + 1 + ATLAS_MARGIN_PX`. Texels of that
//! rectangle beyond the page's edges hold the page's edge texels (edge
//! replication), which is what a single texture gives there (the sampler clamps).
//! For faces that use a whole page (corners on its edges, `x` from −0.5 to
//! `W − 0.5`) that is a gutter of 2 replicated texels on every side; a page whose
//! faces use only part of it contributes only that part.
//!
//! Rectangles are placed on shelves (rows), tallest first, at integer texel
//! offsets with the pages' own texel scale, so sampling in the atlas reads the
//! same texels as sampling the page did. The atlas is at most
//! [`MAX_ATLAS_DIM`] texels per side (what a map product's texture view takes);
//! a set of pages that does not fit is refused, never downsampled.
//!
//! Bounds: at most [`MAX_ATLAS_PAGES`] pages; packing is O(pages²), filling
//! O(atlas texels), remapping O(triangles).

use crate::io::image::Gray8;
use crate::io::mesh::raw::CornerUvs;
use vtsm_core::config::{MAX_IMAGE_DIM, MAX_TEXTURE_DIM};

/// Texels of safety margin beyond the bilinear footprint of a page's faces.
pub const ATLAS_MARGIN_PX: i64 = 1;

/// Most texture pages one mesh may use.
pub const MAX_ATLAS_PAGES: usize = 1024;

/// Largest atlas side, texels: a map product's texture must fit both its
/// header's cap (`MAX_TEXTURE_DIM`) and the core's image views (`MAX_IMAGE_DIM`).
pub const MAX_ATLAS_DIM: usize = if MAX_TEXTURE_DIM < MAX_IMAGE_DIM {
    MAX_TEXTURE_DIM
} else {
    MAX_IMAGE_DIM
};

/// One texture page: its gray image and a name for messages (its file).
#[derive(Clone, Debug)]
pub struct Page {
    /// The page, converted to gray.
    pub image: Gray8,
    /// What to call the page in errors (usually its file path).
    pub name: String,
}

/// Where a page's rectangle went in the atlas.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Placement {
    /// Index of the page.
    pub page: usize,
    /// Left column of the rectangle in page texels (negative: a gutter left of the page).
    pub src_x: i64,
    /// Top row of the rectangle in page texels (negative: a gutter above the page).
    pub src_y: i64,
    /// Width of the rectangle, texels.
    pub w: u32,
    /// Height of the rectangle, texels.
    pub h: u32,
    /// Column of the rectangle's left edge in the atlas.
    pub dst_x: u32,
    /// Row of the rectangle's top edge in the atlas.
    pub dst_y: u32,
}

/// A packed atlas.
#[derive(Clone, Debug)]
pub struct Atlas {
    /// The atlas texture (texels outside every rectangle are 0).
    pub texture: Gray8,
    /// One placement per page used by at least one triangle, in page order.
    pub placements: Vec<Placement>,
}

/// Pack `pages` into one atlas and remap `uvs` (per triangle, normalised, OBJ
/// convention, relative to the triangle's page `tri_page`) into it.
///
/// # Errors
/// A one-line reason: no pages or more than [`MAX_ATLAS_PAGES`], a page index
/// out of range, non-finite coordinates, a page whose faces' coordinates reach
/// beyond [`MAX_ATLAS_DIM`] texels, or rectangles that do not fit one
/// [`MAX_ATLAS_DIM`]² atlas. On error `uvs` is unchanged.
pub fn pack(
    pages: &[Page],
    tri_page: &[u32],
    uvs: &mut [CornerUvs],
) -> std::result::Result<Atlas, String> {
    if pages.is_empty() || pages.len() > MAX_ATLAS_PAGES {
        return Err(format!(
            "{} texture pages; an atlas takes 1..={MAX_ATLAS_PAGES}",
            pages.len()
        ));
    }
    if tri_page.len() != uvs.len() {
        return Err(format!(
            "{} page indices for {} triangles",
            tri_page.len(),
            uvs.len()
        ));
    }
    // Texel reach of each page's faces: min x, min y, max x, max y (page texels).
    let mut reach: Vec<Option<[f64; 4]>> = vec![None; pages.len()];
    for (k, (&p, uv)) in tri_page.iter().zip(uvs.iter()).enumerate() {
        let page = pages.get(p as usize).ok_or_else(|| {
            format!(
                "triangle {} uses texture page {p} but there are {} pages",
                k + 1,
                pages.len()
            )
        })?;
        let (w, h) = (f64::from(page.image.width), f64::from(page.image.height));
        for st in uv {
            if !(st[0].is_finite() && st[1].is_finite()) {
                return Err(format!(
                    "texture coordinates of triangle {} are not finite",
                    k + 1
                ));
            }
            let (x, y) = to_px(*st, w, h);
            let r = reach.get_mut(p as usize).ok_or("page index")?;
            *r = Some(match *r {
                None => [x, y, x, y],
                Some([a, b, c, d]) => [a.min(x), b.min(y), c.max(x), d.max(y)],
            });
        }
    }
    // Rectangles in page texels (inclusive start, size).
    let mut rects: Vec<Rect> = Vec::new();
    for (p, (page, r)) in pages.iter().zip(&reach).enumerate() {
        let Some([x0, y0, x1, y1]) = *r else { continue };
        let span = |lo: f64, hi: f64, what: &str| -> std::result::Result<(i64, u32), String> {
            let first = lo.floor() - ATLAS_MARGIN_PX as f64;
            let last = hi.floor() + 1.0 + ATLAS_MARGIN_PX as f64;
            let n = last - first + 1.0;
            if n > MAX_ATLAS_DIM as f64 {
                return Err(format!(
                    "the faces on texture page `{}` ({}x{}) reach {} texels {what} (coordinates \
                     from {lo:.1} to {hi:.1} texels); an atlas holds at most {MAX_ATLAS_DIM}",
                    page.name,
                    page.image.width,
                    page.image.height,
                    crate::io::json::short_number(n),
                ));
            }
            Ok((first as i64, n as u32))
        };
        let (sx, w) = span(x0, x1, "across")?;
        let (sy, h) = span(y0, y1, "down")?;
        rects.push(Rect {
            page: p,
            x: sx,
            y: sy,
            w,
            h,
        });
    }
    let (aw, ah, spots) = place(&rects).ok_or_else(|| {
        let area: u64 = rects.iter().map(|r| u64::from(r.w) * u64::from(r.h)).sum();
        format!(
            "{} texture pages need {} texels with their gutters, more than fit one \
             {MAX_ATLAS_DIM}x{MAX_ATLAS_DIM} map texture; export fewer or smaller pages",
            rects.len(),
            area
        )
    })?;
    let mut tex = Gray8::filled(aw, ah, 0);
    let mut placements = Vec::with_capacity(rects.len());
    for (r, &(dx, dy)) in rects.iter().zip(&spots) {
        let (p, sx, sy, w, h) = (r.page, r.x, r.y, r.w, r.h);
        let img = &pages.get(p).ok_or("page index")?.image;
        let (pw, ph) = (i64::from(img.width), i64::from(img.height));
        for j in 0..h {
            let src_row = (sy + i64::from(j)).clamp(0, ph - 1) as usize * pw as usize;
            let dst_row = (dy + j) as usize * aw as usize + dx as usize;
            for i in 0..w {
                let sxi = (sx + i64::from(i)).clamp(0, pw - 1) as usize;
                if let (Some(d), Some(&s)) = (
                    tex.pixels.get_mut(dst_row + i as usize),
                    img.pixels.get(src_row + sxi),
                ) {
                    *d = s;
                }
            }
        }
        placements.push(Placement {
            page: p,
            src_x: sx,
            src_y: sy,
            w,
            h,
            dst_x: dx,
            dst_y: dy,
        });
    }
    // Offset of each page: atlas texel = page texel + offset.
    let mut offset: Vec<(f64, f64)> = vec![(0.0, 0.0); pages.len()];
    for pl in &placements {
        if let Some(o) = offset.get_mut(pl.page) {
            *o = (
                f64::from(pl.dst_x) - pl.src_x as f64,
                f64::from(pl.dst_y) - pl.src_y as f64,
            );
        }
    }
    let (awf, ahf) = (f64::from(aw), f64::from(ah));
    for (&p, uv) in tri_page.iter().zip(uvs.iter_mut()) {
        let (Some(page), Some(&(ox, oy))) = (pages.get(p as usize), offset.get(p as usize)) else {
            continue;
        };
        let (w, h) = (f64::from(page.image.width), f64::from(page.image.height));
        for st in uv.iter_mut() {
            let (x, y) = to_px(*st, w, h);
            *st = [
                ((x + ox + 0.5) / awf) as f32,
                (1.0 - (y + oy + 0.5) / ahf) as f32,
            ];
        }
    }
    Ok(Atlas {
        texture: tex,
        placements,
    })
}

/// Normalised OBJ coordinates → texture pixels (x right, y down, centres on integers).
fn to_px(st: [f32; 2], w: f64, h: f64) -> (f64, f64) {
    (
        f64::from(st[0]) * w - 0.5,
        (1.0 - f64::from(st[1])) * h - 0.5,
    )
}

/// A page's rectangle in page texels: top-left texel and size.
struct Rect {
    page: usize,
    x: i64,
    y: i64,
    w: u32,
    h: u32,
}

/// Atlas width, height and each rectangle's top-left corner.
type Layout = (u32, u32, Vec<(u32, u32)>);

/// Shelf packing of `rects`: tallest first (ties by page
/// order), rows filled left to right up to a row width limit. Every limit from
/// the widest rectangle up to [`MAX_ATLAS_DIM`] that changes the rows is tried
/// (the sums of consecutive widths in packing order), and the smallest atlas
/// area wins (ties: the smaller longer side, then the narrower). Returns the
/// atlas size and each rectangle's top-left corner, in the order of `rects`.
fn place(rects: &[Rect]) -> Option<Layout> {
    let mut order: Vec<usize> = (0..rects.len()).collect();
    order.sort_by_key(|&i| (std::cmp::Reverse(rects.get(i).map_or(0, |r| r.h)), i));
    let widths: Vec<u64> = order
        .iter()
        .map(|&i| rects.get(i).map_or(0, |r| u64::from(r.w)))
        .collect();
    let widest = widths.iter().copied().max().unwrap_or(1);
    let mut limits: Vec<u64> = vec![widest];
    for start in 0..widths.len() {
        let mut sum = 0u64;
        for w in widths.iter().skip(start) {
            sum += w;
            if sum > MAX_ATLAS_DIM as u64 {
                break;
            }
            if sum >= widest {
                limits.push(sum);
            }
        }
    }
    limits.sort_unstable();
    limits.dedup();
    // (area, longer side, width) and the corners.
    type Spots = Vec<(u32, u32)>;
    let mut best: Option<([u64; 3], Spots)> = None;
    for &limit in &limits {
        let (mut x, mut y, mut row_h, mut width) = (0u64, 0u64, 0u64, 0u64);
        let mut spots = vec![(0u32, 0u32); rects.len()];
        for &i in &order {
            let Some(r) = rects.get(i) else { continue };
            let (w, h) = (u64::from(r.w), u64::from(r.h));
            if x > 0 && x + w > limit {
                y += row_h;
                x = 0;
                row_h = 0;
            }
            if let Some(s) = spots.get_mut(i) {
                *s = (x as u32, y as u32);
            }
            x += w;
            row_h = row_h.max(h);
            width = width.max(x);
        }
        let height = y + row_h;
        if width > MAX_ATLAS_DIM as u64 || height > MAX_ATLAS_DIM as u64 {
            continue;
        }
        let key = [width * height, width.max(height), width];
        if best.as_ref().is_none_or(|b| key < b.0) {
            best = Some((key, spots));
        }
    }
    best.map(|(key, spots)| {
        let h = rects
            .iter()
            .zip(&spots)
            .map(|(r, s)| s.1 + r.h)
            .max()
            .unwrap_or(1);
        (key[2] as u32, h, spots)
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    fn page(w: u32, h: u32, v: u8) -> Page {
        Page {
            image: Gray8::filled(w, h, v),
            name: format!("p{v}"),
        }
    }

    /// Verifies: VTSM-CLI-026
    #[test]
    fn full_pages_get_two_texel_gutters_and_keep_their_texel_scale() {
        let pages = [page(8, 4, 10), page(8, 4, 200)];
        // One triangle per page, corners on the page's corners.
        let full: CornerUvs = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        let mut uvs = vec![full, full];
        let a = pack(&pages, &[0, 1], &mut uvs).unwrap();
        assert_eq!(a.placements.len(), 2);
        for pl in &a.placements {
            assert_eq!((pl.src_x, pl.src_y, pl.w, pl.h), (-2, -2, 12, 8));
        }
        let (aw, ah) = (a.texture.width as f32, a.texture.height as f32);
        for (pl, uv) in a.placements.iter().zip(&uvs) {
            // Corner (0, 0) of the page (texel −0.5, 3.5) sits 2 texels into its rectangle.
            let x = uv[0][0] * aw - 0.5;
            let y = (1.0 - uv[0][1]) * ah - 0.5;
            assert!((x - (pl.dst_x as f32 + 1.5)).abs() < 1e-4, "{x}");
            assert!((y - (pl.dst_y as f32 + 5.5)).abs() < 1e-4, "{y}");
            // Texel scale unchanged: u from 0 to 1 spans 8 atlas texels.
            assert!(((uv[1][0] - uv[0][0]) * aw - 8.0).abs() < 1e-4);
            // Every texel of the rectangle holds the page's (constant) gray.
            let g = pages[pl.page].image.pixels[0];
            for j in 0..pl.h {
                for i in 0..pl.w {
                    assert_eq!(a.texture.get(pl.dst_x + i, pl.dst_y + j), Some(g));
                }
            }
        }
    }

    /// Verifies: VTSM-CLI-030
    #[test]
    fn refuses_pages_that_do_not_fit_and_leaves_uvs_alone() {
        let big = MAX_ATLAS_DIM as u32;
        let pages = [page(big / 2, big / 2, 1), page(big / 2, big / 2, 2)];
        let full: CornerUvs = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        // Four full half-size pages would fit a 2 x 2 grid only without their gutters.
        let mut uvs = vec![full; 4];
        let before = uvs.clone();
        let pages4 = [
            pages[0].clone(),
            pages[1].clone(),
            page(big / 2, big / 2, 3),
            page(big / 2, big / 2, 4),
        ];
        let e = pack(&pages4, &[0, 1, 2, 3], &mut uvs).unwrap_err();
        assert!(e.contains("more than fit one"), "{e}");
        assert_eq!(uvs, before);
        // Coordinates far beyond a page.
        let mut far = vec![[[0.0, 0.0], [5000.0, 0.0], [0.0, 1.0]]];
        let e = pack(&[page(4, 4, 1)], &[0], &mut far).unwrap_err();
        assert!(e.contains("reach") && e.contains("`p1`"), "{e}");
        let e = pack(&pages, &[0, 2], &mut [full; 2]).unwrap_err();
        assert!(e.contains("page 2"), "{e}");
    }

    /// Bilinear sample at texture pixel (x, y), clamped to the edge texels (the
    /// core sampler's rule, in f64).
    fn bilinear(img: &Gray8, x: f64, y: f64) -> f64 {
        let (w, h) = (i64::from(img.width), i64::from(img.height));
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let g = |i: i64, j: i64| {
            let (i, j) = (i.clamp(0, w - 1), j.clamp(0, h - 1));
            f64::from(img.pixels[(j * w + i) as usize])
        };
        let (i, j) = (x0 as i64, y0 as i64);
        let top = g(i, j) * (1.0 - fx) + g(i + 1, j) * fx;
        let bot = g(i, j + 1) * (1.0 - fx) + g(i + 1, j + 1) * fx;
        top * (1.0 - fy) + bot * fy
    }

    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Sampling the atlas anywhere within half a texel of a triangle's corners
        /// reads what sampling its own page reads: nothing from another page.
        ///
        /// Verifies: VTSM-CLI-026
        #[test]
        fn atlas_samples_equal_page_samples(
            sizes in proptest::collection::vec((1u32..40, 1u32..40), 1..6),
            tris in proptest::collection::vec(
                (0usize..6, proptest::array::uniform6(-0.2f32..1.2)), 1..12),
            probes in proptest::collection::vec((0f64..1.0, 0f64..1.0, -0.5f64..0.5, -0.5f64..0.5), 8),
            seed in 0u32..1000,
        ) {
            let pages: Vec<Page> = sizes.iter().enumerate().map(|(k, &(w, h))| {
                let mut img = Gray8::filled(w, h, 0);
                for (n, p) in img.pixels.iter_mut().enumerate() {
                    *p = ((n as u32 * 37 + k as u32 * 91 + seed) % 251) as u8;
                }
                Page { image: img, name: format!("p{k}") }
            }).collect();
            let tri_page: Vec<u32> = tris.iter().map(|t| (t.0 % pages.len()) as u32).collect();
            let before: Vec<CornerUvs> = tris.iter().map(|t| {
                let c = t.1;
                [[c[0], c[1]], [c[2], c[3]], [c[4], c[5]]]
            }).collect();
            let mut uvs = before.clone();
            let a = pack(&pages, &tri_page, &mut uvs).unwrap();
            let (aw, ah) = (f64::from(a.texture.width), f64::from(a.texture.height));
            for ((p, b), u) in tri_page.iter().zip(&before).zip(&uvs) {
                let img = &pages[*p as usize].image;
                let (w, h) = (f64::from(img.width), f64::from(img.height));
                for &(s, t, dx, dy) in &probes {
                    // A point of the triangle (or just beyond it by up to half a texel).
                    let (s, t) = if s + t > 1.0 { (1.0 - s, 1.0 - t) } else { (s, t) };
                    let mix = |c: &CornerUvs, k: usize| {
                        f64::from(c[0][k]) * (1.0 - s - t) + f64::from(c[1][k]) * s + f64::from(c[2][k]) * t
                    };
                    let (px, py) = (mix(b, 0) * w - 0.5 + dx, (1.0 - mix(b, 1)) * h - 0.5 + dy);
                    let (qx, qy) = (mix(u, 0) * aw - 0.5 + dx, (1.0 - mix(u, 1)) * ah - 0.5 + dy);
                    let (gp, ga) = (bilinear(img, px, py), bilinear(&a.texture, qx, qy));
                    prop_assert!((gp - ga).abs() < 0.05, "page {gp} atlas {ga}");
                }
            }
        }
    }
}
