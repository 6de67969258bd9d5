//! Upset injection (feature `upset-injection`, never in a flight build): flip
//! one bit of the engine's memory between two steps, so a simulator can run
//! single-event-upset campaigns on the same engine the runner drives.
//!
//! The memory is split into [`UpsetRegion`]s: the caller-owned workspace
//! (templates, depths, NCC scratch) and the engine's own state (the
//! correspondences of the current round, the estimate and viewpoint centre,
//! the search bounds, the Distribute candidates). [`Relocalizer::upset_bits`]
//! says how many bits a region holds now; [`Relocalizer::flip_bit`] flips one.
//! Both are O(1) and cannot panic.
//!
//! The map product is not a region: the engine only borrows it, read-only.
//! [`Relocalizer::upset_map`] stands in for an upset of the memory holding it
//! after its check at load: from then on the engine reads the product through
//! a view of the same layout over other bytes
//! ([`MapView::with_changed_bytes`]), e.g. a copy with one bit flipped.

use super::Relocalizer;
use crate::geom::Pose;
use crate::map::MapView;
use crate::reloc::pipeline::Pipeline;
use crate::reloc::solver::RansacSolver;

/// A region of the engine's memory an upset can hit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UpsetRegion {
    /// Left and right template intensities and masks (workspace bytes, 4·ℓ²).
    Templates,
    /// Left and right template depths and mask depths (workspace words, 4·ℓ²).
    TemplateDepths,
    /// NCC window and template pixels (workspace bytes).
    NccPixels,
    /// NCC integral images (workspace words).
    NccIntegrals,
    /// NCC runs of kept template pixels (workspace, 3 × u16 each).
    NccRuns,
    /// The correspondences of the current round (7 × f32 each: map point,
    /// triangulated point, sigma); only the ones collected so far.
    Correspondences,
    /// The current estimate and the viewpoint centre (2 poses × 7 × f32).
    Estimate,
    /// The search bounds t̃ and r̃ (2 × f32).
    SearchBounds,
    /// The Distribute candidates (7 × f32 pose each); only the current ones.
    Candidates,
}

impl UpsetRegion {
    /// Every region, workspace first.
    pub const ALL: [UpsetRegion; 9] = [
        UpsetRegion::Templates,
        UpsetRegion::TemplateDepths,
        UpsetRegion::NccPixels,
        UpsetRegion::NccIntegrals,
        UpsetRegion::NccRuns,
        UpsetRegion::Correspondences,
        UpsetRegion::Estimate,
        UpsetRegion::SearchBounds,
        UpsetRegion::Candidates,
    ];

    /// Short lowercase name for reports.
    pub const fn name(self) -> &'static str {
        match self {
            UpsetRegion::Templates => "templates",
            UpsetRegion::TemplateDepths => "template depths",
            UpsetRegion::NccPixels => "ncc pixels",
            UpsetRegion::NccIntegrals => "ncc integrals",
            UpsetRegion::NccRuns => "ncc runs",
            UpsetRegion::Correspondences => "correspondences",
            UpsetRegion::Estimate => "estimate",
            UpsetRegion::SearchBounds => "search bounds",
            UpsetRegion::Candidates => "candidates",
        }
    }

    /// Whether the region is caller-owned workspace (else engine state).
    pub const fn is_workspace(self) -> bool {
        matches!(
            self,
            UpsetRegion::Templates
                | UpsetRegion::TemplateDepths
                | UpsetRegion::NccPixels
                | UpsetRegion::NccIntegrals
                | UpsetRegion::NccRuns
        )
    }
}

fn flip_u8(parts: [&mut [u8]; 4], bit: u64) -> bool {
    let mut at = bit;
    for p in parts {
        let n = p.len() as u64 * 8;
        if at < n {
            return p
                .get_mut((at / 8) as usize)
                .map(|b| *b ^= 1 << (at % 8))
                .is_some();
        }
        at -= n;
    }
    false
}

fn flip_u32(parts: [&mut [u32]; 4], bit: u64) -> bool {
    let mut at = bit;
    for p in parts {
        let n = p.len() as u64 * 32;
        if at < n {
            return p
                .get_mut((at / 32) as usize)
                .map(|w| *w ^= 1 << (at % 32))
                .is_some();
        }
        at -= n;
    }
    false
}

fn flip_f32(v: &mut f32, bit: u64) {
    *v = f32::from_bits(v.to_bits() ^ (1 << (bit % 32)));
}

/// Flip bit `bit` (< 7·32) of a pose's translation (3 f32) then quaternion
/// (4 f32, `[x, y, z, w]` as stored), without renormalizing.
fn flip_pose(p: &mut Pose, bit: u64) {
    let k = (bit / 32) as usize;
    if k < 3 {
        if let Some(v) = p.iso.translation.vector.get_mut(k) {
            flip_f32(v, bit);
        }
    } else if let Some(v) = p.iso.rotation.as_mut_unchecked().coords.get_mut(k - 3) {
        flip_f32(v, bit);
    }
}

const POSE_BITS: u64 = 7 * 32;

impl<'a, 'w> Relocalizer<Pipeline<'a, 'w>, RansacSolver> {
    /// Bits `region` holds now (0 when it is empty, e.g. no correspondence yet).
    pub fn upset_bits(&self, region: UpsetRegion) -> u64 {
        let ws = self.attempt.workspace();
        let b = |s: &[u8]| s.len() as u64 * 8;
        let w = |s: &[u32]| s.len() as u64 * 32;
        match region {
            UpsetRegion::Templates => b(ws.inten_l) + b(ws.inten_r) + b(ws.mask_l) + b(ws.mask_r),
            UpsetRegion::TemplateDepths => {
                w(ws.depth_l) + w(ws.depth_r) + w(ws.mdepth_l) + w(ws.mdepth_r)
            }
            UpsetRegion::NccPixels => b(ws.scratch.window) + b(ws.scratch.template),
            UpsetRegion::NccIntegrals => w(ws.scratch.integral),
            UpsetRegion::NccRuns => ws.scratch.runs.len() as u64 * 48,
            UpsetRegion::Correspondences => self.pairs.len() as u64 * 7 * 32,
            UpsetRegion::Estimate => 2 * POSE_BITS,
            UpsetRegion::SearchBounds => 2 * 32,
            UpsetRegion::Candidates => self.candidates.len() as u64 * POSE_BITS,
        }
    }

    /// From now on read the map product through `changed`: the memory that
    /// held the product checked at load now holds `changed`'s bytes (a view
    /// from [`MapView::with_changed_bytes`]). Nothing else notices; with
    /// [`crate::reloc::Verify::recheck_map`] the re-check before a success
    /// does.
    pub fn upset_map(&mut self, changed: &'a MapView<'a>) {
        self.attempt.set_map(changed);
    }

    /// Flip bit `bit` of `region` (as counted by [`Self::upset_bits`]);
    /// `false`, and nothing changed, when `bit` is beyond the region.
    pub fn flip_bit(&mut self, region: UpsetRegion, bit: u64) -> bool {
        if bit >= self.upset_bits(region) {
            return false;
        }
        let ws = self.attempt.workspace_mut();
        match region {
            UpsetRegion::Templates => flip_u8(
                [
                    &mut *ws.inten_l,
                    &mut *ws.inten_r,
                    &mut *ws.mask_l,
                    &mut *ws.mask_r,
                ],
                bit,
            ),
            UpsetRegion::TemplateDepths => flip_u32(
                [
                    &mut *ws.depth_l,
                    &mut *ws.depth_r,
                    &mut *ws.mdepth_l,
                    &mut *ws.mdepth_r,
                ],
                bit,
            ),
            UpsetRegion::NccPixels => flip_u8(
                [
                    &mut *ws.scratch.window,
                    &mut *ws.scratch.template,
                    &mut [],
                    &mut [],
                ],
                bit,
            ),
            UpsetRegion::NccIntegrals => {
                flip_u32([&mut *ws.scratch.integral, &mut [], &mut [], &mut []], bit)
            }
            UpsetRegion::NccRuns => {
                let Some(run) = ws.scratch.runs.get_mut((bit / 48) as usize) else {
                    return false;
                };
                let field = match (bit % 48) / 16 {
                    0 => &mut run.row,
                    1 => &mut run.x0,
                    _ => &mut run.x1,
                };
                *field ^= 1 << (bit % 16);
                true
            }
            UpsetRegion::Correspondences => {
                let Some(c) = self.pairs.get_mut((bit / (7 * 32)) as usize) else {
                    return false;
                };
                let k = ((bit / 32) % 7) as usize;
                let v = match k {
                    0..=2 => c.world.get_mut(k),
                    3..=5 => c.cam.get_mut(k - 3),
                    _ => Some(&mut c.sigma_m),
                };
                v.map(|v| flip_f32(v, bit)).is_some()
            }
            UpsetRegion::Estimate => {
                if bit < POSE_BITS {
                    flip_pose(&mut self.anchor, bit);
                } else {
                    flip_pose(&mut self.center, bit - POSE_BITS);
                }
                true
            }
            UpsetRegion::SearchBounds => {
                if bit < 32 {
                    flip_f32(&mut self.t_m, bit);
                } else {
                    flip_f32(&mut self.r_rad, bit);
                }
                true
            }
            UpsetRegion::Candidates => {
                let Some(c) = self.candidates.get_mut((bit / POSE_BITS) as usize) else {
                    return false;
                };
                flip_pose(&mut c.pose, bit % POSE_BITS);
                true
            }
        }
    }
}
