extern crate std;

mod determinism;
mod focus;
mod integrity;
mod mechanisms;
mod stops;
mod tickets;

use super::*;
use crate::config::{Mechanisms, DEFAULT_T0_M, MAX_T0_M};
use crate::geom::Vec3;
use crate::reloc::AttemptContext;
use crate::reloc::{Budget, PipelineStats};
use crate::reloc::{Focus, Near};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use std::boxed::Box;
use std::vec::Vec;

/// Produces pairs with a unique id in `world.x`; fails when `fail(index, rng)` says so.
type FailFn = Box<dyn FnMut(u32, &mut Rng) -> Option<FailureCode>>;

struct FakeAttempt {
    fail: FailFn,
    next_id: u32,
    contexts: Vec<AttemptContext>,
    /// What `recheck` reports, and how often it was called.
    recheck: Result<(), FailureCode>,
    rechecks: u32,
    /// When set, each pair is a point 2–4 m in front of the camera seen
    /// from this `world_from_left` (a scene), not an arbitrary pair.
    truth: Option<Pose>,
    /// The template variant of pair `id` (Sobel at ℓ unless set); a gray
    /// one is rejected when the context asks for gradient matches only.
    variant: fn(u32) -> u8,
}

impl FakeAttempt {
    fn new(fail: impl FnMut(u32, &mut Rng) -> Option<FailureCode> + 'static) -> Self {
        Self {
            fail: Box::new(fail),
            next_id: 0,
            contexts: Vec::new(),
            recheck: Ok(()),
            rechecks: 0,
            truth: None,
            variant: |_| 1,
        }
    }

    fn seen_from(truth: Pose) -> Self {
        Self {
            truth: Some(truth),
            ..Self::ok()
        }
    }
    fn ok() -> Self {
        Self::new(|_, _| None)
    }
}

impl Attempt for FakeAttempt {
    fn attempt(
        &mut self,
        ctx: &AttemptContext,
        rng: &mut Rng,
        stats: &mut PipelineStats,
    ) -> Result<Correspondence, FailureCode> {
        self.contexts.push(*ctx);
        stats.renders += 2;
        if let Some(code) = (self.fail)(ctx.index, rng) {
            return Err(code);
        }
        let id = self.next_id;
        self.next_id += 1;
        let variant = (self.variant)(id);
        if ctx.gradient_only && !crate::reloc::policy::is_gradient_variant(variant) {
            return Err(FailureCode::NccLowScore);
        }
        if let Some(truth) = self.truth {
            let cam = Vec3::new(
                2.0 * rng.next_f32() - 1.0,
                2.0 * rng.next_f32() - 1.0,
                2.0 + 2.0 * rng.next_f32(),
            );
            return Ok(Correspondence {
                world: truth.transform_point(&cam),
                cam,
                sigma_m: 0.01,
                variant,
                mask_index: id,
            });
        }
        let v = ctx.world_from_viewpoint.translation();
        Ok(Correspondence {
            world: Vec3::new(id as f32, rng.next_f32(), rng.next_f32()),
            // The viewpoint centre travels with the pair so solvers can see it.
            cam: v,
            sigma_m: 0.01,
            variant,
            mask_index: id,
        })
    }

    fn recheck(&mut self) -> Result<(), FailureCode> {
        self.rechecks += 1;
        self.recheck
    }
}

type Script = Box<dyn FnMut(u32, &[Correspondence], &mut [bool]) -> Result<Solution, FailureCode>>;

struct FakeSolver {
    script: Script,
    /// Answers the solves made while the σ scale is above 1, when set.
    wide: Option<Script>,
    scale: f32,
    /// The σ scale of each solve.
    scales: Vec<f32>,
    calls: Vec<Vec<Correspondence>>,
}

impl FakeSolver {
    fn new(
        f: impl FnMut(u32, &[Correspondence], &mut [bool]) -> Result<Solution, FailureCode> + 'static,
    ) -> Self {
        Self {
            script: Box::new(f),
            wide: None,
            scale: 1.0,
            scales: Vec::new(),
            calls: Vec::new(),
        }
    }

    fn with_wide(
        mut self,
        f: impl FnMut(u32, &[Correspondence], &mut [bool]) -> Result<Solution, FailureCode> + 'static,
    ) -> Self {
        self.wide = Some(Box::new(f));
        self
    }
}

impl Solver for FakeSolver {
    fn solve(
        &mut self,
        pairs: &[Correspondence],
        rng: &mut Rng,
        mask: &mut [bool],
    ) -> Result<Solution, FailureCode> {
        let _ = rng.next_u32();
        let call = self.calls.len() as u32;
        self.calls.push(pairs.to_vec());
        self.scales.push(self.scale);
        match self.wide.as_mut() {
            Some(wide) if self.scale > 1.0 => wide(call, pairs, mask),
            _ => (self.script)(call, pairs, mask),
        }
    }

    fn set_sigma_scale(&mut self, scale: f32) {
        self.scale = scale;
    }
}

fn at_x(x: f32) -> Pose {
    Pose::new(UnitQuaternion::identity(), Vec3::new(x, 0.0, 0.0))
}

/// A solution at `pose` whose inliers are the pairs with an even id.
fn even_inliers(pose: Pose, pairs: &[Correspondence], mask: &mut [bool]) -> Solution {
    let mut n = 0u16;
    for (p, m) in pairs.iter().zip(mask.iter_mut()) {
        *m = (p.world.x as u32) % 2 == 0;
        n += u16::from(*m);
    }
    Solution {
        pose,
        inliers: n,
        rms_m: 0.01,
        iterations: 10,
        candidates: heapless::Vec::new(),
    }
}

fn small_params() -> Params {
    Params {
        n_corr: 20,
        n_iter: 5,
        attempts_per_iter: 50,
        max_stall: 3,
        max_reseed: 4,
        template_px: 64,
        ..Params::paper()
    }
}

/// Options of the search tests: the fakes' poses and points are not a
/// scene, so the integrity gates (tested on their own) are off.
fn opts(p: &Params) -> Options {
    Options {
        min_inliers: 5,
        gates: crate::reloc::Gates::OFF,
        first_fix_rounds: 0,
        ..Options::for_params(p)
    }
}

/// Verifies: VTSM-RELOC-002
#[test]
fn invalid_prior_params_or_options_are_refused() {
    let p = small_params();
    let o = opts(&p);
    let mk = |prior: &Pose, p: &Params, o: &Options| {
        Relocalizer::new(
            FakeAttempt::ok(),
            FakeSolver::new(|_, _, _| Err(FailureCode::PoseDegenerate)),
            p,
            o,
            prior,
            1,
        )
        .err()
    };
    assert_eq!(
        mk(&at_x(f32::NAN), &p, &o),
        Some(FailureCode::RelocPriorInvalid)
    );
    let non_unit = Pose {
        iso: Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 0.0),
            UnitQuaternion::new_unchecked(Quaternion::new(1.5, 0.0, 0.0, 0.0)),
        ),
    };
    assert_eq!(mk(&non_unit, &p, &o), Some(FailureCode::RelocPriorInvalid));
    let bad = Params { n_corr: 1, ..p };
    assert_eq!(
        mk(&at_x(0.0), &bad, &o),
        Some(FailureCode::ConfigParamOutOfRange)
    );
    let bad_o = Options {
        min_inliers: p.n_corr + 1,
        ..o
    };
    assert_eq!(
        mk(&at_x(0.0), &p, &bad_o),
        Some(FailureCode::ConfigParamOutOfRange)
    );
    let bad_o = Options {
        seed_t_m: f32::NAN,
        ..o
    };
    assert_eq!(
        mk(&at_x(0.0), &p, &bad_o),
        Some(FailureCode::ConfigParamOutOfRange)
    );
    assert_eq!(mk(&at_x(0.0), &p, &o), None);
}
