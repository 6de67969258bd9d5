//! The pipeline's preallocated workspace: left/right templates, depth and
//! mask-depth buffers, template masks, the NCC scratch and the two frame
//! windows (the left and right search windows copied out of the
//! [`FrameSource`](crate::frame::FrameSource)), carved from three caller
//! slices whose lengths are a `const fn` of (ℓ, search side).
//!
//! Nothing here allocates; the paper-scale buffers (several MB) are meant to be
//! static or heap memory of the caller, never a by-value stack object.
//! [`Storage`] is that memory as one typed value whose size is fixed at compile
//! time from a [`WorkspaceSizes`] constant (a `static`, or a stack or heap
//! object of the caller); a caller with run-time sizes borrows three slices
//! into [`Workspace::new`] instead.

use crate::config::{Params, MAX_IMAGE_DIM, MAX_SEARCH_PX, MAX_TEMPLATE_PX};
use crate::failure::FailureCode;
use crate::frame::halo_bytes;
use crate::ncc::{Filter, Run, Scratch, ScratchSizes, Search, SearchConfig};

/// Most bytes the workspace spends on NCC integral tables shared by a whole
/// refinement level (beyond what per-region tables need). Shared tables save
/// 11–16 % of the instructions of a small (32-in-96, 64-in-200) search but
/// about 1 % at ℓ = 128–256, where they would cost 1.5 MB more at paper scale;
/// above this cap the workspace keeps the per-region size and the search
/// builds per-region tables, with the same results
/// (`fsw-docs/budgets/ncc.md`).
pub const NCC_SHARED_TABLES_MAX_BYTES: usize = 1 << 20;

/// Bytes the preflight reads at once from each frame: two rows of the widest
/// image (a sampled row and the one below it).
pub const PREFLIGHT_ROW_BYTES: usize = 2 * MAX_IMAGE_DIM;

/// Integral elements every filter's default search needs at least (per-region tables).
const fn ncc_minimum_integral(t: usize, w: usize, mode: Search) -> usize {
    let g = ScratchSizes::minimum(t, t, w, w, mode, &SearchConfig::for_filter(Filter::Gray));
    let s = ScratchSizes::minimum(t, t, w, w, mode, &SearchConfig::for_filter(Filter::Sobel));
    let l = ScratchSizes::minimum(
        t,
        t,
        w,
        w,
        mode,
        &SearchConfig::for_filter(Filter::Laplacian),
    );
    max(g.integral, max(s.integral, l.integral))
}

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
    /// `u8` elements: left/right intensity and mask (4·ℓ²) + NCC window and
    /// template scratch + the two frame windows (2 · [`Self::frame`]).
    pub bytes: usize,
    /// `u32` elements: left/right depth and mask depth (4·ℓ²) + NCC integral images.
    pub words: usize,
    /// [`Run`] elements.
    pub runs: usize,
    /// Bytes of each frame window: a search window of side W with its
    /// one-pixel ring, (W + 2)², and at least [`PREFLIGHT_ROW_BYTES`].
    pub frame: usize,
    /// The NCC part (covers both ℓ and ℓ/2 templates).
    pub ncc: ScratchSizes,
    /// Integral elements the NCC searches require at least (per-region
    /// tables); `ncc.integral` may be larger (shared whole-level tables).
    pub ncc_min_integral: usize,
}

impl WorkspaceSizes {
    /// Sizes for ℓ = `template_px`, W = `search_px` and search `mode`.
    pub const fn new(template_px: usize, search_px: usize, mode: Search) -> Self {
        let a = ScratchSizes::new(template_px, template_px, search_px, search_px, mode);
        let h = template_px / 2;
        let b = ScratchSizes::new(h, h, search_px, search_px, mode);
        let shared = max(a.integral, b.integral);
        let minimum = max(
            ncc_minimum_integral(template_px, search_px, mode),
            ncc_minimum_integral(h, search_px, mode),
        );
        let integral =
            if shared.saturating_sub(minimum).saturating_mul(4) <= NCC_SHARED_TABLES_MAX_BYTES {
                shared
            } else {
                minimum
            };
        let ncc = ScratchSizes {
            window: max(a.window, b.window),
            template: max(a.template, b.template),
            integral,
            runs: max(a.runs, b.runs),
        };
        // Saturating: sizes beyond any storage are refused when it is checked.
        let t4 = template_px.saturating_mul(template_px).saturating_mul(4);
        let frame = max(halo_bytes(search_px), PREFLIGHT_ROW_BYTES);
        Self {
            template_px,
            search_px,
            bytes: t4
                .saturating_add(ncc.window)
                .saturating_add(ncc.template)
                .saturating_add(frame.saturating_mul(2)),
            words: t4.saturating_add(ncc.integral),
            runs: ncc.runs,
            frame,
            ncc,
            ncc_min_integral: minimum,
        }
    }

    /// Sizes for validated `params` (ℓ = `template_px`, W = `search_px`) and search `mode`.
    pub const fn for_params(params: &Params, mode: Search) -> Self {
        Self::new(params.template_px as usize, params.search_px as usize, mode)
    }

    /// Whether a workspace of these sizes serves every buffer `need` asks for
    /// (NCC integral tables: at least the per-region minimum; the searches use
    /// shared whole-level tables where the buffer holds them, with the same results).
    pub const fn covers(&self, need: &WorkspaceSizes) -> bool {
        self.template_px >= need.template_px
            && self.search_px >= need.search_px
            && self.bytes >= need.bytes
            && self.runs >= need.runs
            && self.frame >= need.frame
            && self.ncc.window >= need.ncc.window
            && self.ncc.template >= need.ncc.template
            && self.ncc.integral >= need.ncc_min_integral
            && self.ncc.runs >= need.ncc.runs
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

/// The engine's working memory as one value of a compile-time size: three
/// arrays of `BYTES` bytes, `WORDS` words and `RUNS` runs. Name it from a
/// [`WorkspaceSizes`] constant, e.g.
/// `Storage<{ SIZES.bytes }, { SIZES.words }, { SIZES.runs }>`, and place it in
/// a `static`, on a large stack, or on the heap; [`Storage::workspace`] carves
/// the [`Workspace`].
///
/// The byte array comes first in a 16-byte-aligned value, so the buffers
/// carved from it at multiples of 16 are 16-byte aligned wherever the value
/// lies; the NCC kernel reads an aligned template as whole vectors (on
/// strict-alignment AArch64 an unaligned one is assembled byte by byte, at
/// about twice the instructions). The results do not depend on it.
#[repr(C, align(16))]
pub struct Storage<const BYTES: usize, const WORDS: usize, const RUNS: usize> {
    bytes: [u8; BYTES],
    words: [u32; WORDS],
    runs: [Run; RUNS],
}

impl<const BYTES: usize, const WORDS: usize, const RUNS: usize> Storage<BYTES, WORDS, RUNS> {
    /// Zeroed storage (usable in a `static` initializer).
    pub const fn new() -> Self {
        Self {
            bytes: [0; BYTES],
            words: [0; WORDS],
            runs: [Run {
                row: 0,
                x0: 0,
                x1: 0,
                rows: 0,
            }; RUNS],
        }
    }

    /// Bytes of this storage.
    pub const fn total_bytes() -> usize {
        core::mem::size_of::<Self>()
    }

    /// The workspace for `sizes`, borrowing this storage.
    ///
    /// # Errors
    /// [`FailureCode::ConfigCapacityTooSmall`] if `sizes` needs more than this storage holds.
    pub fn workspace(&mut self, sizes: WorkspaceSizes) -> Result<Workspace<'_>, FailureCode> {
        Workspace::new(sizes, &mut self.bytes, &mut self.words, &mut self.runs)
    }
}

impl<const BYTES: usize, const WORDS: usize, const RUNS: usize> Default
    for Storage<BYTES, WORDS, RUNS>
{
    fn default() -> Self {
        Self::new()
    }
}

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
    /// The left search window copied from the frame source (and the
    /// preflight's left rows).
    pub(super) frame_l: &'w mut [u8],
    /// The right search window (and the preflight's right rows).
    pub(super) frame_r: &'w mut [u8],
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
    /// The sizes this workspace was carved for.
    pub const fn sizes(&self) -> WorkspaceSizes {
        self.sizes
    }

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
        // Saturating: an impossible size is refused by `take`, not a panic.
        let t2 = sizes.template_px.saturating_mul(sizes.template_px);
        let inten_l = take(&mut bytes, t2)?;
        let inten_r = take(&mut bytes, t2)?;
        let mask_l = take(&mut bytes, t2)?;
        let mask_r = take(&mut bytes, t2)?;
        let window = take(&mut bytes, sizes.ncc.window)?;
        let template = take(&mut bytes, sizes.ncc.template)?;
        let frame_l = take(&mut bytes, sizes.frame)?;
        let frame_r = take(&mut bytes, sizes.frame)?;
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
            frame_l,
            frame_r,
        })
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec;

    /// The NCC buffers carved from a `Storage` are 16-byte aligned wherever
    /// the storage lies (here after one byte, and boxed), so the kernel's
    /// aligned template path is taken on every target.
    ///
    /// Verifies: VTSM-RELOC-016
    #[test]
    fn storage_buffers_are_16_byte_aligned() {
        const S: WorkspaceSizes = WorkspaceSizes::new(32, 96, Search::CoarseToFine);
        type St = Storage<{ S.bytes }, { S.words }, { S.runs }>;
        struct After {
            _byte: u8,
            storage: St,
        }
        let mut a = After {
            _byte: 1,
            storage: St::new(),
        };
        let mut b = std::boxed::Box::new(St::new());
        for st in [&mut a.storage, &mut *b] {
            let ws = st.workspace(S).unwrap();
            assert_eq!(ws.scratch.template.as_ptr() as usize % 16, 0);
            assert_eq!(ws.scratch.window.as_ptr() as usize % 16, 0);
        }
    }

    /// Verifies: VTSM-RELOC-016
    #[test]
    fn sizes_cover_both_template_variants_and_carving_checks_lengths() {
        for (l, w) in [(64usize, 256usize), (128, 512), (256, 1024)] {
            let s = WorkspaceSizes::new(l, w, Search::CoarseToFine);
            for t in [l, l / 2] {
                let n = ScratchSizes::new(t, t, w, w, Search::CoarseToFine);
                assert!(s.ncc.window >= n.window && s.ncc.template >= n.template);
                assert!(s.ncc.runs >= n.runs);
                // At least what every filter's search requires; the shared
                // whole-level tables only while they stay under the cap.
                assert!(s.ncc.integral >= ncc_minimum_integral(t, w, Search::CoarseToFine));
                let extra = n.integral.saturating_sub(s.ncc.integral) * 4;
                assert!(extra == 0 || n.integral * 4 > NCC_SHARED_TABLES_MAX_BYTES);
            }
            assert_eq!(s.frame, ((w + 2) * (w + 2)).max(PREFLIGHT_ROW_BYTES));
            assert_eq!(
                s.bytes,
                4 * l * l + s.ncc.window + s.ncc.template + 2 * s.frame
            );
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
            assert_eq!((ws.frame_l.len(), ws.frame_r.len()), (s.frame, s.frame));
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

    /// Verifies: VTSM-RELOC-016
    #[test]
    fn typed_storage_serves_its_sizes_and_refuses_larger_ones() {
        const S: WorkspaceSizes = WorkspaceSizes::new(32, 128, Search::CoarseToFine);
        type Small = Storage<{ S.bytes }, { S.words }, { S.runs }>;
        let mut st = std::boxed::Box::new(Small::new());
        let ws = st.workspace(S).unwrap();
        assert_eq!(ws.sizes(), S);
        assert!(Small::total_bytes() >= S.total_bytes());
        let bigger = WorkspaceSizes::new(64, 256, Search::CoarseToFine);
        assert!(bigger.covers(&S) && !S.covers(&bigger));
        assert_eq!(
            st.workspace(bigger).err(),
            Some(FailureCode::ConfigCapacityTooSmall)
        );
        let p = Params::paper();
        let paper = WorkspaceSizes::for_params(&p, Search::CoarseToFine);
        assert_eq!(paper.template_px, 256);
        assert_eq!(paper.search_px, usize::from(p.search_px));
        assert!(PAPER_WORKSPACE.covers(&paper));
    }
}
