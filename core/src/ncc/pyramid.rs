//! Pyramid levels: how many, the scratch they need, and building the template
//! and window levels.

use super::filter::{downsample, filter_region};
use super::Scratch;
use super::{
    Filter, Run, ScratchSizes, Search, SearchConfig, MAX_LEVELS, MAX_REFINE_RADIUS_PX,
    MIN_COARSE_PX, MIN_MASK_PX, WIDE_WINDOW_RATIO,
};
use crate::config::{MAX_SEARCH_PX, MAX_TEMPLATE_PX};
use crate::failure::FailureCode;
use crate::fmt::present;
use crate::image::{GrayView, Rect};

/// Pyramid levels the coarse-to-fine search uses for a `tw × th` template:
/// halve while the shorter side stays at least [`MIN_COARSE_PX`], at most [`MAX_LEVELS`].
pub const fn pyramid_levels(tw: usize, th: usize) -> usize {
    pyramid_levels_min(tw, th, MIN_COARSE_PX)
}

/// Pyramid levels for a `tw × th` template when the coarsest template side should
/// stay at least `min_coarse_px`: halve while it does, but always halve once when
/// the shorter side is at least `2·MIN_COARSE_PX` (never more than [`pyramid_levels`]).
#[allow(
    clippy::arithmetic_side_effects,
    reason = "levels < MAX_LEVELS in the loop"
)]
pub const fn pyramid_levels_min(tw: usize, th: usize, min_coarse_px: usize) -> usize {
    let m = if tw < th { tw } else { th };
    let min = if min_coarse_px > MIN_COARSE_PX {
        min_coarse_px
    } else {
        MIN_COARSE_PX
    };
    let mut levels = 1;
    while levels < MAX_LEVELS && (m >> levels) >= min {
        levels += 1;
    }
    if levels == 1 && (m >> 1) >= MIN_COARSE_PX && MAX_LEVELS > 1 {
        levels = 2;
    }
    levels
}

/// Pyramid levels the coarse-to-fine search with `cfg` uses for a `tw × th`
/// template in a `ww × wh` window.
#[allow(
    clippy::arithmetic_side_effects,
    reason = "WIDE_WINDOW_RATIO · t for template sides ≤ MAX_TEMPLATE_PX"
)]
pub const fn search_levels(
    tw: usize,
    th: usize,
    ww: usize,
    wh: usize,
    cfg: &SearchConfig,
) -> usize {
    let c = *cfg;
    let t = if tw < th { tw } else { th };
    let w = if ww < wh { ww } else { wh };
    // Saturating: no panic path for sizes only known at run time.
    let min = if w > WIDE_WINDOW_RATIO.saturating_mul(t) {
        c.wide_min_coarse_px
    } else {
        c.min_coarse_px
    };
    pyramid_levels_min(tw, th, min)
}

/// Radius (full-resolution pixels, Chebyshev) of the main peak's neighbourhood,
/// outside which the runner-up is sought: an eighth of the shorter template side, at least 2.
pub const fn peak_radius_px(tw: usize, th: usize) -> usize {
    let m = if tw < th { tw } else { th };
    if m / 8 > 2 {
        m / 8
    } else {
        2
    }
}

pub(super) const fn max_usize(a: usize, b: usize) -> usize {
    if a > b {
        a
    } else {
        b
    }
}

/// Refinement radius and number of candidates refined at level `k` below the
/// coarsest level `lc` (`k < lc`) with the configuration `c`.
pub(super) const fn refine_plan(
    tw: usize,
    th: usize,
    k: usize,
    lc: usize,
    c: &SearchConfig,
) -> (usize, usize) {
    let (r, keep) = if k == 0 {
        let m = if tw < th { tw } else { th };
        let n = if m < c.verify_all_below_px {
            c.candidates
        } else {
            c.final_candidates
        };
        (c.final_refine_radius_px, n)
    } else {
        (c.refine_radius_px, c.candidates)
    };
    let r = if k.saturating_add(1) == lc {
        max_usize(r, c.first_refine_radius_px)
    } else {
        r
    };
    (r, keep)
}

/// Whether refinement level `k` (`k < lc`) builds the integral tables of its whole
/// window once and serves every refinement region (and, at level 0, the sub-pixel
/// probe) from them: when the whole level has no more table entries than its
/// refinement regions would have (one region per refined candidate, re-centring
/// steps not counted). Otherwise each region takes its own window sums: running
/// column sums for an unmasked template, its own tables for a masked one
/// ([`super::integral::Tables::sums`]). Either way the window sums are the same
/// integers.
pub(super) const fn whole_level_tables(
    tw: usize,
    th: usize,
    ww: usize,
    wh: usize,
    k: usize,
    lc: usize,
    c: &SearchConfig,
) -> bool {
    let (r, keep) = refine_plan(tw, th, k, lc, c);
    // Saturating: sizes beyond any scratch compare the same way or are refused
    // when the scratch is sized.
    let whole = table_len(shr(ww, k), shr(wh, k));
    let side = r.saturating_mul(2);
    let region = table_len(
        shr(tw, k).saturating_add(side),
        shr(th, k).saturating_add(side),
    );
    whole <= keep.saturating_mul(region)
}

/// `v >> k`, 0 for a shift of the whole width or more (a level index is below
/// MAX_LEVELS; this keeps the shift free of its overflow panic path).
pub(super) const fn shr(v: usize, k: usize) -> usize {
    if k < usize::BITS as usize {
        v >> k
    } else {
        0
    }
}

/// Entries of one integral table of a `w × h` region: `(w + 1) · (h + 1)`, saturating.
const fn table_len(w: usize, h: usize) -> usize {
    w.saturating_add(1).saturating_mul(h.saturating_add(1))
}

impl ScratchSizes {
    /// Sizes for a `tw × th` template in a `ww × wh` window with `mode` and the
    /// default [`SearchConfig`] of any filter (the largest of their sizes; the
    /// derivative domains refine more candidates, so they may share whole-level
    /// integral tables where gray does not).
    pub const fn new(tw: usize, th: usize, ww: usize, wh: usize, mode: Search) -> Self {
        const GRAY: SearchConfig = SearchConfig::for_filter(Filter::Gray);
        const SOBEL: SearchConfig = SearchConfig::for_filter(Filter::Sobel);
        const LAPLACIAN: SearchConfig = SearchConfig::for_filter(Filter::Laplacian);
        let g = Self::with_config(tw, th, ww, wh, mode, &GRAY);
        let s = Self::with_config(tw, th, ww, wh, mode, &SOBEL);
        let l = Self::with_config(tw, th, ww, wh, mode, &LAPLACIAN);
        Self {
            window: max_usize(g.window, max_usize(s.window, l.window)),
            template: max_usize(g.template, max_usize(s.template, l.template)),
            integral: max_usize(g.integral, max_usize(s.integral, l.integral)),
            runs: max_usize(g.runs, max_usize(s.runs, l.runs)),
        }
    }

    /// Sizes for a `tw × th` template in a `ww × wh` window with `mode` and `cfg`.
    ///
    /// The integral buffer includes the whole-level tables of the refinement
    /// levels that share them; a search whose buffer is shorter (down to
    /// [`ScratchSizes::minimum`]) builds per-region tables there instead, with the
    /// same results.
    pub const fn with_config(
        tw: usize,
        th: usize,
        ww: usize,
        wh: usize,
        mode: Search,
        cfg: &SearchConfig,
    ) -> Self {
        Self::sized(tw, th, ww, wh, mode, cfg, true)
    }

    /// The smallest scratch a search with `cfg` accepts: as
    /// [`ScratchSizes::with_config`] without the whole-level integral tables of
    /// the refinement levels (each refinement region then builds its own).
    pub const fn minimum(
        tw: usize,
        th: usize,
        ww: usize,
        wh: usize,
        mode: Search,
        cfg: &SearchConfig,
    ) -> Self {
        Self::sized(tw, th, ww, wh, mode, cfg, false)
    }

    #[allow(
        clippy::arithmetic_side_effects,
        reason = "k < levels ≤ MAX_LEVELS in both loops"
    )]
    const fn sized(
        tw: usize,
        th: usize,
        ww: usize,
        wh: usize,
        mode: Search,
        cfg: &SearchConfig,
        whole_levels: bool,
    ) -> Self {
        let levels = match mode {
            Search::Exhaustive => 1,
            Search::CoarseToFine => search_levels(tw, th, ww, wh, cfg),
        };
        let (mut window, mut template, mut runs) = (0, 0, 0);
        let mut k = 0;
        // Saturating throughout: a size no buffer can have is refused when the
        // scratch is checked against it. `k < levels ≤ MAX_LEVELS`.
        while k < levels {
            window = usize::saturating_add(window, shr(ww, k).saturating_mul(shr(wh, k)));
            template = usize::saturating_add(
                template,
                shr(tw, k).saturating_mul(shr(th, k)).saturating_mul(2),
            );
            runs = usize::saturating_add(runs, shr(th, k).saturating_mul(shr(tw, k).div_ceil(2)));
            k += 1;
        }
        let lc = levels.saturating_sub(1);
        let coarse = table_len(shr(ww, lc), shr(wh, lc));
        let pad = 2 * MAX_REFINE_RADIUS_PX;
        let refine = table_len(tw.saturating_add(pad), th.saturating_add(pad));
        let mut tables = max_usize(coarse, refine);
        let c = *cfg;
        let mut k = 0;
        while k < lc {
            if whole_levels && whole_level_tables(tw, th, ww, wh, k, lc, &c) {
                tables = max_usize(tables, table_len(shr(ww, k), shr(wh, k)));
            }
            k += 1;
        }
        Self {
            window,
            template,
            integral: tables.saturating_mul(2),
            runs,
        }
    }

    /// Sizes for the largest template and window of `config` in `mode`.
    pub const fn max(mode: Search) -> Self {
        Self::new(
            MAX_TEMPLATE_PX,
            MAX_TEMPLATE_PX,
            MAX_SEARCH_PX,
            MAX_SEARCH_PX,
            mode,
        )
    }

    /// Whether every buffer of `s` is at least this large.
    pub fn fits(&self, s: &Scratch) -> bool {
        s.window.len() >= self.window
            && s.template.len() >= self.template
            && s.integral.len() >= self.integral
            && s.runs.len() >= self.runs
    }
}

/// One pyramid level of the template.
#[derive(Clone, Copy, Debug)]
pub(super) struct Tpl<'s> {
    /// Pixels, zero where the mask drops them, row-major, [`TPL_BYTES_PER_PX`]
    /// bytes each (little-endian i16 on the vector targets, bytes elsewhere).
    pub(super) px: &'s [u8],
    /// Runs of kept pixels; `None` for an unmasked template.
    pub(super) runs: Option<&'s [Run]>,
    pub(super) w: usize,
    pub(super) h: usize,
    pub(super) n: i64,
    pub(super) st: i64,
    pub(super) var_t: i64,
}

/// One pyramid level of the window.
#[derive(Clone, Copy, Debug)]
pub(super) struct Win<'s> {
    /// Pixels, row-major with `stride` pixels per row (at least
    /// `(h − 1)·stride + w` of them).
    pub(super) px: &'s [u8],
    pub(super) w: usize,
    pub(super) h: usize,
    pub(super) stride: usize,
}

impl<'s> Win<'s> {
    /// Last valid top-left column and row for a `tw × th` template.
    pub(super) fn last_pos(&self, tw: usize, th: usize) -> (usize, usize) {
        (self.w.saturating_sub(tw), self.h.saturating_sub(th))
    }

    /// `len` pixels of row `y` from column `x`, or `None` where they would
    /// leave the buffer: checked offsets, no panic path.
    #[inline]
    pub(super) fn span(&self, x: usize, y: usize, len: usize) -> Option<&'s [u8]> {
        let start = y.checked_mul(self.stride)?.checked_add(x)?;
        self.px.get(start..start.checked_add(len)?)
    }
}

/// Template bytes per pixel in [`Tpl::px`]: 2 (little-endian i16) where the
/// vector kernel runs (x86-64, AArch64), 1 elsewhere.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
pub(super) const TPL_BYTES_PER_PX: usize = 2;
/// Template bytes per pixel in [`Tpl::px`] (the portable kernel's bytes).
#[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
pub(super) const TPL_BYTES_PER_PX: usize = 1;

/// Rewrite the first `n` bytes of `region` (pixels), in place, as `n`
/// little-endian i16 over the first `2n` bytes (the level's pixel and mask
/// bytes, the mask no longer being needed). Pixel `i` moves to `2i`, at or
/// after where it was, so a descending pass reads each pixel before it is
/// overwritten.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
fn widen_in_place(region: &mut [u8], n: usize) {
    for i in (0..n).rev() {
        let v = region.get(i).copied().unwrap_or(0);
        if let Some(pair) = region
            .get_mut(i.saturating_mul(2)..)
            .and_then(|r| r.first_chunk_mut::<2>())
        {
            *pair = [v, 0];
        }
    }
}

/// What a built template level knows besides its pixels.
#[derive(Clone, Copy)]
struct LevelTerms<'s> {
    runs: Option<&'s [Run]>,
    w: usize,
    h: usize,
    n: i64,
    st: i64,
    var_t: i64,
}

/// Build the template pyramid; returns the number of usable levels.
///
/// Each level takes `2·w·h` bytes of `tbuf`: its pixels (dropped ones zeroed)
/// and its mask while the pyramid is built; once every level is built, the
/// vector targets rewrite each level's two halves as i16 pixels
/// ([`TPL_BYTES_PER_PX`]), the kernel's operand.
#[allow(
    clippy::cast_possible_truncation,
    reason = "Σt ≤ MAX_TEMPLATE_PX²·255 and Σt² fit i64 (numeric.md)"
)]
pub(super) fn build_template_levels<'s>(
    template: &GrayView,
    mask: Option<&GrayView>,
    filter: Filter,
    want: usize,
    mut tbuf: &'s mut [u8],
    mut rbuf: &'s mut [Run],
    levels: &mut [Option<Tpl<'s>>; MAX_LEVELS],
) -> Result<usize, FailureCode> {
    let (tw, th) = (template.width(), template.height());
    // Each level's `2·w·h` bytes (pixels, then mask) and its terms.
    let mut regions: [Option<(&'s mut [u8], LevelTerms<'s>)>; MAX_LEVELS] =
        [const { None }; MAX_LEVELS];
    let mut used = 0;
    for k in 0..want.min(MAX_LEVELS) {
        let (w, h) = (shr(tw, k), shr(th, k));
        let n_px = w.saturating_mul(h);
        let (region, rest) = core::mem::take(&mut tbuf)
            .split_at_mut_checked(n_px.saturating_mul(2))
            .ok_or(FailureCode::NccScratchTooSmall)?;
        tbuf = rest;
        // The level above: its pixels and mask (k ≥ 1).
        let prev = k
            .checked_sub(1)
            .and_then(|p| regions.get(p))
            .and_then(|r| r.as_ref())
            .and_then(|(r, _)| r.split_at_checked(r.len() / 2));
        let (px, mk) = region
            .split_at_mut_checked(n_px)
            .ok_or(FailureCode::NccScratchTooSmall)?;
        match prev {
            None => first_level(template, mask, filter, (w, h), px, mk)?,
            Some((ppx, pmk)) => halve_level((ppx, pmk), (w, h), px, mk)?,
        }
        let (n, st, stt) = zero_dropped(px, mk);
        if n < MIN_MASK_PX {
            if k == 0 {
                return Err(FailureCode::NccMaskEmpty);
            }
            break;
        }
        let (n, st) = (i64::from(n), st as i64);
        // < 2⁴⁸ for any template within the caps (numeric.md).
        let var_t = n.wrapping_mul(stt as i64).wrapping_sub(st.wrapping_mul(st));
        if var_t <= 0 {
            if k == 0 {
                return Err(FailureCode::NccTemplateFlat);
            }
            break;
        }
        let runs = if mask.is_some() {
            let count = mask_runs(mk, (w, h), rbuf)?;
            let (mine, rest) = core::mem::take(&mut rbuf)
                .split_at_mut_checked(count)
                .ok_or(FailureCode::NccScratchTooSmall)?;
            rbuf = rest;
            Some(&*mine)
        } else {
            None
        };
        if let Some(slot) = regions.get_mut(k) {
            *slot = Some((
                region,
                LevelTerms {
                    runs,
                    w,
                    h,
                    n,
                    st,
                    var_t,
                },
            ));
        }
        used = k.saturating_add(1);
    }
    for (slot, region) in levels.iter_mut().zip(regions) {
        let Some((region, lt)) = region else {
            break;
        };
        let n_px = lt.w.saturating_mul(lt.h);
        #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
        widen_in_place(region, n_px);
        let px: &'s [u8] = present(region.get(..n_px.saturating_mul(TPL_BYTES_PER_PX)));
        *slot = Some(Tpl {
            px,
            runs: lt.runs,
            w: lt.w,
            h: lt.h,
            n: lt.n,
            st: lt.st,
            var_t: lt.var_t,
        });
    }
    Ok(used)
}

/// Level 0 of the template pyramid: `template` after `filter` into `px`, and
/// its mask (1 kept, 0 dropped; all kept without `mask`) into `mk`.
fn first_level(
    template: &GrayView,
    mask: Option<&GrayView>,
    filter: Filter,
    (w, h): (usize, usize),
    px: &mut [u8],
    mk: &mut [u8],
) -> Result<(), FailureCode> {
    filter_region(template, template.rect(), filter, px)?;
    match mask {
        Some(m) => {
            for (y, mrow) in (0..h).zip(mk.chunks_exact_mut(w.max(1))) {
                let src = present(m.row(y));
                for (d, &s) in mrow.iter_mut().zip(src) {
                    *d = u8::from(s != 0);
                }
            }
        }
        None => mk.fill(1),
    }
    Ok(())
}

/// Level k ≥ 1 of the template pyramid, `w × h`, from the pixels and mask of
/// level k − 1: the 2× box downsample into `px`, and into `mk` a coarse pixel
/// kept only when all four children are kept.
fn halve_level(
    (ppx, pmk): (&[u8], &[u8]),
    (w, h): (usize, usize),
    px: &mut [u8],
    mk: &mut [u8],
) -> Result<(), FailureCode> {
    // Level k is half of level k − 1 (≤ MAX_TEMPLATE_PX), so the
    // doubled sizes fit; saturating keeps the arithmetic total.
    let w2 = w.saturating_mul(2);
    downsample(&GrayView::new(ppx, w2, h.saturating_mul(2), w2)?, px);
    for (y, mrow) in (0..h).zip(mk.chunks_exact_mut(w.max(1))) {
        let row0 = y.saturating_mul(2).saturating_mul(w2);
        let r0 = present(pmk.get(row0..).and_then(|r| r.get(..w2)));
        let r1 = present(pmk.get(row0.saturating_add(w2)..).and_then(|r| r.get(..w2)));
        for ((d, a), b) in mrow
            .iter_mut()
            .zip(r0.chunks_exact(2))
            .zip(r1.chunks_exact(2))
        {
            *d = u8::from(a.iter().chain(b.iter()).all(|&v| v != 0));
        }
    }
    Ok(())
}

/// Zero the pixels of `px` that `mk` drops, so the plain dot product is the
/// masked Σ t·f; returns the kept pixels' count, Σt and Σt².
#[allow(clippy::arithmetic_side_effects, reason = "255² fits u64")]
fn zero_dropped(px: &mut [u8], mk: &[u8]) -> (u32, u64, u64) {
    let (mut n, mut st, mut stt) = (0u32, 0u64, 0u64);
    for (p, &m) in px.iter_mut().zip(mk.iter()) {
        if m == 0 {
            *p = 0;
        } else {
            // At most MAX_TEMPLATE_PX² pixels of ≤ 255: far below the u32
            // and u64 limits (numeric.md), so wrapping never happens.
            n = n.wrapping_add(1);
            st = st.wrapping_add(u64::from(*p));
            stt = stt.wrapping_add(u64::from(*p) * u64::from(*p));
        }
    }
    (n, st, stt)
}

/// Encode the kept pixels of the `w × h` mask `mk` as [`Run`]s into the front
/// of `rbuf`, a row's only run merged into the rectangle of the previous
/// row's only run when it repeats it; returns how many runs it wrote.
///
/// # Errors
/// [`FailureCode::NccScratchTooSmall`] when `rbuf` is too short.
#[allow(
    clippy::cast_possible_truncation,
    reason = "template sides ≤ MAX_TEMPLATE_PX < 2^16 fit the u16 run fields"
)]
fn mask_runs(mk: &[u8], (w, h): (usize, usize), rbuf: &mut [Run]) -> Result<usize, FailureCode> {
    let mut count = 0usize;
    // The row whose only run ends the list (it may grow downwards).
    let mut prev_single_row: Option<usize> = None;
    for (y, mrow) in (0..h).zip(mk.chunks_exact(w.max(1))) {
        let mut first_of_row = true;
        if prev_single_row != Some(y.wrapping_sub(1)) {
            prev_single_row = None;
        }
        let mut x = 0usize;
        // `x < w` bounds both loops, so the increments cannot wrap.
        while x < w {
            if mrow.get(x).copied().unwrap_or(0) == 0 {
                x = x.wrapping_add(1);
                continue;
            }
            let x0 = x;
            while x < w && mrow.get(x).copied().unwrap_or(0) != 0 {
                x = x.wrapping_add(1);
            }
            let (row, x0, x1) = (y as u16, x0 as u16, x as u16);
            // A row whose only run repeats the previous row's only run
            // extends that rectangle (rows < h ≤ MAX_TEMPLATE_PX).
            let single = x >= w || !mrow.iter().skip(x).any(|&v| v != 0);
            let extend = single
                && first_of_row
                && count > 0
                && prev_single_row == Some(y.wrapping_sub(1))
                && rbuf
                    .get(count.wrapping_sub(1))
                    .is_some_and(|p| (p.x0, p.x1) == (x0, x1));
            if extend {
                if let Some(p) = rbuf.get_mut(count.wrapping_sub(1)) {
                    p.rows = p.rows.wrapping_add(1);
                }
            } else {
                let r = rbuf.get_mut(count).ok_or(FailureCode::NccScratchTooSmall)?;
                *r = Run {
                    row,
                    x0,
                    x1,
                    rows: 1,
                };
                // `rbuf.get_mut(count)` succeeded, so count < rbuf.len().
                count = count.wrapping_add(1);
            }
            // Only a run that was the first of its row and is the row's
            // only run may be extended by the next row.
            prev_single_row = (single && first_of_row).then_some(y);
            first_of_row = false;
        }
    }
    Ok(count)
}

/// Build the window pyramid of `levels` levels: level 0 is `wr` of `image` after
/// `filter` (for the gray domain, `wr` of `image` itself: no copy), each further
/// level the 2× box downsample of the one above.
pub(super) fn build_window_levels<'s>(
    image: &GrayView<'s>,
    wr: Rect,
    filter: Filter,
    levels: usize,
    window: &'s mut [u8],
    wins: &mut [Option<Win<'s>>; MAX_LEVELS],
) -> Result<(), FailureCode> {
    let (ww, wh) = (wr.w as usize, wr.h as usize);
    let mut wbuf: &mut [u8] = window;
    let mut prev: Option<Win> = None;
    for (k, slot) in wins.iter_mut().enumerate().take(levels) {
        let (w, h) = (shr(ww, k), shr(wh, k));
        let (px, rest) = core::mem::take(&mut wbuf)
            .split_at_mut_checked(w.saturating_mul(h))
            .ok_or(FailureCode::NccScratchTooSmall)?;
        wbuf = rest;
        let win = match prev {
            None if filter == Filter::Gray => {
                let v = image.sub(wr).ok_or(FailureCode::NccWindowOutsideImage)?;
                Win {
                    px: v.data(),
                    w,
                    h,
                    stride: v.stride(),
                }
            }
            None => {
                filter_region(image, wr, filter, px)?;
                Win {
                    px,
                    w,
                    h,
                    stride: w,
                }
            }
            Some(p) => {
                downsample(&GrayView::new(p.px, p.w, p.h, p.stride)?, px);
                Win {
                    px,
                    w,
                    h,
                    stride: w,
                }
            }
        };
        *slot = Some(win);
        prev = Some(win);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::*;

    /// `ScratchSizes::new` covers every filter's default search, and the minimum
    /// a search accepts never exceeds the recommended size.
    #[test]
    fn scratch_sizes_cover_every_default_and_exceed_the_minimum() {
        for (tw, ww) in [
            (32usize, 96usize),
            (64, 200),
            (64, 1024),
            (128, 800),
            (256, 800),
            (256, 1024),
        ] {
            for mode in [Search::CoarseToFine, Search::Exhaustive] {
                let n = ScratchSizes::new(tw, tw, ww, ww, mode);
                for f in [Filter::Gray, Filter::Sobel, Filter::Laplacian] {
                    let cfg = SearchConfig::for_filter(f);
                    let s = ScratchSizes::with_config(tw, tw, ww, ww, mode, &cfg);
                    let m = ScratchSizes::minimum(tw, tw, ww, ww, mode, &cfg);
                    assert!(n.integral >= s.integral && s.integral >= m.integral);
                    assert_eq!(
                        (n.window, n.template, n.runs),
                        (s.window, s.template, s.runs)
                    );
                    assert_eq!(
                        (m.window, m.template, m.runs),
                        (s.window, s.template, s.runs)
                    );
                }
            }
        }
        assert_eq!(pyramid_levels(32, 32), 2);
        assert_eq!(pyramid_levels(256, 256), 4);
        assert_eq!(pyramid_levels_min(32, 32, 32), 2);
        assert_eq!(pyramid_levels_min(31, 64, 32), 1);
    }
}
