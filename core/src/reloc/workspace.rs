//! The pipeline's preallocated workspace: left/right templates, depth and
//! mask-depth buffers, template masks and the NCC scratch, carved from three
//! caller slices whose lengths are a `const fn` of (ℓ, search side).
//!
//! Nothing here allocates; the paper-scale buffers (several MB) are meant to be
//! static or heap memory of the caller, never a by-value stack object.

use crate::config::{MAX_SEARCH_PX, MAX_TEMPLATE_PX};
use crate::failure::FailureCode;
use crate::ncc::{Run, Scratch, ScratchSizes, Search};

const fn max(a: usize, b: usize) -> usize {
    if a > b {
        a
    } else {
        b
    }
}

/// Element counts of the pipeline's buffers for template side ℓ and search side W.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WorkspaceSizes {
    /// Template side ℓ.
    pub template_px: usize,
    /// Search-window side W.
    pub search_px: usize,
    /// `u8` elements: left/right intensity and mask (4·ℓ²) + NCC window and template scratch.
    pub bytes: usize,
    /// `u32` elements: left/right depth and mask depth (4·ℓ²) + NCC integral images.
    pub words: usize,
    /// [`Run`] elements.
    pub runs: usize,
    /// The NCC part (covers both ℓ and ℓ/2 templates).
    pub ncc: ScratchSizes,
}

impl WorkspaceSizes {
    /// Sizes for ℓ = `template_px`, W = `search_px` and search `mode`.
    pub const fn new(template_px: usize, search_px: usize, mode: Search) -> Self {
        let a = ScratchSizes::new(template_px, template_px, search_px, search_px, mode);
        let h = template_px / 2;
        let b = ScratchSizes::new(h, h, search_px, search_px, mode);
        let ncc = ScratchSizes {
            window: max(a.window, b.window),
            template: max(a.template, b.template),
            integral: max(a.integral, b.integral),
            runs: max(a.runs, b.runs),
        };
        let t2 = template_px * template_px;
        Self {
            template_px,
            search_px,
            bytes: 4 * t2 + ncc.window + ncc.template,
            words: 4 * t2 + ncc.integral,
            runs: ncc.runs,
            ncc,
        }
    }

    /// Total bytes of the three buffers.
    pub const fn total_bytes(&self) -> usize {
        self.bytes + 4 * self.words + self.runs * core::mem::size_of::<Run>()
    }
}

/// Pipeline workspace at paper scale: ℓ = 256, W = `MAX_SEARCH_PX`, coarse-to-fine.
pub const PAPER_WORKSPACE: WorkspaceSizes =
    WorkspaceSizes::new(MAX_TEMPLATE_PX, MAX_SEARCH_PX, Search::CoarseToFine);
/// Bytes of [`PAPER_WORKSPACE`].
pub const PAPER_WORKSPACE_BYTES: usize = PAPER_WORKSPACE.total_bytes();
/// Pipeline workspace at test scale: ℓ = 64, W = 256, coarse-to-fine.
pub const TEST_WORKSPACE: WorkspaceSizes = WorkspaceSizes::new(64, 256, Search::CoarseToFine);
/// Bytes of [`TEST_WORKSPACE`].
pub const TEST_WORKSPACE_BYTES: usize = TEST_WORKSPACE.total_bytes();

/// The pipeline's buffers, carved from three caller slices.
pub struct Workspace<'w> {
    pub(super) sizes: WorkspaceSizes,
    pub(super) inten_l: &'w mut [u8],
    pub(super) inten_r: &'w mut [u8],
    pub(super) mask_l: &'w mut [u8],
    pub(super) mask_r: &'w mut [u8],
    pub(super) depth_l: &'w mut [u32],
    pub(super) depth_r: &'w mut [u32],
    pub(super) mdepth_l: &'w mut [u32],
    pub(super) mdepth_r: &'w mut [u32],
    pub(super) scratch: Scratch<'w>,
}

fn take<'w, T>(s: &mut &'w mut [T], n: usize) -> Result<&'w mut [T], FailureCode> {
    let all = core::mem::take(s);
    let (head, tail) = all
        .split_at_mut_checked(n)
        .ok_or(FailureCode::ConfigCapacityTooSmall)?;
    *s = tail;
    Ok(head)
}

impl<'w> Workspace<'w> {
    /// Carve the buffers for `sizes` out of `bytes`, `words` and `runs`.
    ///
    /// # Errors
    /// [`FailureCode::ConfigCapacityTooSmall`] if a slice is shorter than `sizes` says.
    pub fn new(
        sizes: WorkspaceSizes,
        mut bytes: &'w mut [u8],
        mut words: &'w mut [u32],
        runs: &'w mut [Run],
    ) -> Result<Self, FailureCode> {
        let t2 = sizes.template_px * sizes.template_px;
        let inten_l = take(&mut bytes, t2)?;
        let inten_r = take(&mut bytes, t2)?;
        let mask_l = take(&mut bytes, t2)?;
        let mask_r = take(&mut bytes, t2)?;
        let window = take(&mut bytes, sizes.ncc.window)?;
        let template = take(&mut bytes, sizes.ncc.template)?;
        let depth_l = take(&mut words, t2)?;
        let depth_r = take(&mut words, t2)?;
        let mdepth_l = take(&mut words, t2)?;
        let mdepth_r = take(&mut words, t2)?;
        let integral = take(&mut words, sizes.ncc.integral)?;
        let mut runs = runs;
        let runs = take(&mut runs, sizes.ncc.runs)?;
        Ok(Self {
            sizes,
            inten_l,
            inten_r,
            mask_l,
            mask_r,
            depth_l,
            depth_r,
            mdepth_l,
            mdepth_r,
            scratch: Scratch {
                window,
                template,
                integral,
                runs,
            },
        })
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec;

    /// Verifies: VTSM-RELOC-016
    #[test]
    fn sizes_cover_both_template_variants_and_carving_checks_lengths() {
        for (l, w) in [(64usize, 256usize), (128, 512), (256, 1024)] {
            let s = WorkspaceSizes::new(l, w, Search::CoarseToFine);
            for t in [l, l / 2] {
                let n = ScratchSizes::new(t, t, w, w, Search::CoarseToFine);
                assert!(s.ncc.window >= n.window && s.ncc.template >= n.template);
                assert!(s.ncc.integral >= n.integral && s.ncc.runs >= n.runs);
            }
            assert_eq!(s.bytes, 4 * l * l + s.ncc.window + s.ncc.template);
            assert_eq!(s.words, 4 * l * l + s.ncc.integral);
            let total = s.bytes + 4 * s.words + s.runs * core::mem::size_of::<Run>();
            assert_eq!(s.total_bytes(), total);
            let (mut b, mut wd, mut r) = (
                vec![0u8; s.bytes],
                vec![0u32; s.words],
                vec![Run::default(); s.runs],
            );
            let ws = Workspace::new(s, &mut b, &mut wd, &mut r).unwrap();
            assert_eq!(ws.inten_l.len(), l * l);
            assert_eq!(ws.mdepth_r.len(), l * l);
            assert!(s.ncc.fits(&ws.scratch));
            let short = Workspace::new(s, &mut b[1..], &mut wd, &mut r).err();
            assert_eq!(short, Some(FailureCode::ConfigCapacityTooSmall));
            let short = Workspace::new(s, &mut b, &mut wd[1..], &mut r).err();
            assert_eq!(short, Some(FailureCode::ConfigCapacityTooSmall));
            if s.runs > 0 {
                let short = Workspace::new(s, &mut b, &mut wd, &mut r[1..]).err();
                assert_eq!(short, Some(FailureCode::ConfigCapacityTooSmall));
            }
        }
        assert_eq!(PAPER_WORKSPACE_BYTES, PAPER_WORKSPACE.total_bytes());
    }
}
