//! The one constructor of the relocalization engine.
//!
//! [`Setup`] gathers everything one relocalization needs — the checked map,
//! the real stereo pair (a [`FrameSource`]: the in-memory [`StereoPair`] by
//! default, or a frame store the engine reads search windows from), the rig, validated [`Params`], the Match policy, the
//! engine [`Options`], the prior and the seed — and [`Setup::build`] checks it
//! all once and wires the real [`Pipeline`], the [`RansacSolver`] and the
//! [`Relocalizer`] over a caller-owned [`Workspace`] (carved from a typed
//! [`Storage`](super::Storage) or from three caller slices) whose size is
//! [`Setup::sizes`], a `const fn` of the parameters.
//!
//! The desktop tools, the tests, the benches and the firmware image all build
//! the engine here, so there is one wiring to audit (custom [`super::Attempt`]
//! or [`super::Solver`] implementations, the core's own test fakes, are
//! wired inside the crate).

use super::pipeline::Pipeline;
use super::policy::MatchPolicy;
use super::solver::RansacSolver;
use super::workspace::{Workspace, WorkspaceSizes};
use super::{Options, Relocalizer};
use crate::config::Params;
use crate::failure::FailureCode;
use crate::frame::{FrameSource, StereoPair};
use crate::geom::{Pose, StereoRig};
use crate::image::GrayView;
use crate::map::MapView;

/// The engine as built by [`Setup::build`]: the real pipeline over the frame
/// source `F` (the in-memory pair by default) and RANSAC.
pub type Engine<'a, 'w, F = StereoPair<'a>> = Relocalizer<Pipeline<'a, 'w, F>, RansacSolver>;

/// The inputs of one relocalization. Fill it with [`Setup::new`] (defaults for
/// the policy and options from the params), change the policy or options with
/// [`Setup::with_policy`], [`Setup::with_options`] or
/// [`Setup::with_upset_checks`] if needed, size the workspace with
/// [`Setup::sizes`] and call [`Setup::build`]. Values are read through
/// accessors of the fields' names.
#[derive(Clone, Copy, Debug)]
pub struct Setup<'a, F = StereoPair<'a>> {
    pub(super) map: &'a MapView<'a>,
    pub(super) frames: F,
    pub(super) rig: StereoRig,
    pub(super) params: Params,
    pub(super) policy: MatchPolicy,
    pub(super) options: Options,
    pub(super) prior: Pose,
    pub(super) seed: u64,
}

impl<'a> Setup<'a> {
    /// A setup over the in-memory pair `left`, `right` with the default policy
    /// ([`MatchPolicy::for_params`]) and options ([`Options::for_params`]) for
    /// `params`. Nothing is checked yet.
    pub fn new(
        map: &'a MapView<'a>,
        left: GrayView<'a>,
        right: GrayView<'a>,
        rig: &StereoRig,
        params: &Params,
        prior: &Pose,
        seed: u64,
    ) -> Self {
        Self::with_frames(map, StereoPair::new(left, right), rig, params, prior, seed)
    }
}

impl<'a, F: FrameSource> Setup<'a, F> {
    /// [`Setup::new`] over any frame source: the engine reads each search
    /// window from `frames` when it needs it.
    pub fn with_frames(
        map: &'a MapView<'a>,
        frames: F,
        rig: &StereoRig,
        params: &Params,
        prior: &Pose,
        seed: u64,
    ) -> Self {
        Self {
            map,
            frames,
            rig: *rig,
            params: *params,
            policy: MatchPolicy::for_params(params),
            options: Options::for_params(params),
            prior: *prior,
            seed,
        }
    }

    /// The checked map product.
    pub fn map(&self) -> &'a MapView<'a> {
        self.map
    }

    /// The rectified pair, `rig.cam` sized: where the engine reads its
    /// search windows and preflight rows from.
    pub fn frames(&self) -> &F {
        &self.frames
    }

    /// Calibrated rectified rig.
    pub fn rig(&self) -> &StereoRig {
        &self.rig
    }

    /// Relocalization parameters.
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// Match policy (variants, acceptance).
    pub fn policy(&self) -> &MatchPolicy {
        &self.policy
    }

    /// Engine options (acceptance, budget, multi-seed spread).
    pub fn options(&self) -> &Options {
        &self.options
    }

    /// Prior `world_from_left`.
    pub fn prior(&self) -> &Pose {
        &self.prior
    }

    /// Seed of the relocalization's random streams.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// With the Match policy `policy`.
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] for a policy out of range.
    pub fn with_policy(self, policy: MatchPolicy) -> Result<Self, FailureCode> {
        policy.validate()?;
        Ok(Self { policy, ..self })
    }

    /// With the engine options `options`, checked against the parameters.
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] for options out of range, for
    /// these parameters.
    pub fn with_options(self, options: Options) -> Result<Self, FailureCode> {
        options.validate(&self.params)?;
        Ok(Self { options, ..self })
    }

    /// With the two upset checks ([`Options::with_upset_checks`]) switched on
    /// or off.
    pub fn with_upset_checks(self, repeat_solve: bool, recheck_map: bool) -> Self {
        Self {
            options: self.options.with_upset_checks(repeat_solve, recheck_map),
            ..self
        }
    }

    /// Workspace sizes this setup needs (template side and search window of
    /// the params, search mode of the policy).
    pub const fn sizes(&self) -> WorkspaceSizes {
        WorkspaceSizes::for_params(&self.params, self.policy.search)
    }

    /// Check every input once: params, policy, options, prior, image sizes
    /// against the rig, and that the map has a sampling mask.
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] (params, policy or options),
    /// [`FailureCode::RelocPriorInvalid`], [`FailureCode::ImageSizeMismatch`],
    /// [`FailureCode::RelocNoVisibleMaskVertex`] (empty mask).
    pub fn validate(&self) -> Result<(), FailureCode> {
        self.params.validate()?;
        self.policy.validate()?;
        self.options.validate(&self.params)?;
        if !super::engine::pose_is_valid(&self.prior) {
            return Err(FailureCode::RelocPriorInvalid);
        }
        let (w, h) = (self.rig.cam.width as usize, self.rig.cam.height as usize);
        if self.frames.size() != (w, h) {
            return Err(FailureCode::ImageSizeMismatch);
        }
        if self.map.mask_vertex_count() == 0 {
            return Err(FailureCode::RelocNoVisibleMaskVertex);
        }
        Ok(())
    }

    /// The [`preflight`](super::preflight) of these inputs: texture in both
    /// images, two different images, a mask vertex in view from the prior;
    /// the rows are read into `ws`'s frame windows.
    ///
    /// # Errors
    /// [`FailureCode::RelocFrameNoTexture`], [`FailureCode::RelocStereoIdentical`],
    /// [`FailureCode::RelocNoVisibleMaskVertex`], [`FailureCode::RelocFrameReadFailed`].
    pub fn preflight(
        &mut self,
        ws: &mut Workspace<'_>,
    ) -> Result<super::preflight::Preflight, FailureCode> {
        super::preflight::check(
            self.map,
            &mut self.frames,
            (&mut *ws.frame_l, &mut *ws.frame_r),
            &self.rig,
            &self.prior,
            usize::from(self.params.template_px),
        )
    }

    /// Validate (as [`Setup::validate`]) and build the engine over `ws`. When
    /// the [`Setup::preflight`] fails, the engine is already done: its first
    /// step returns the outcome with the preflight's code and no work.
    ///
    /// # Errors
    /// As [`Setup::validate`], and [`FailureCode::ConfigCapacityTooSmall`] if
    /// `ws` was carved for smaller sizes than [`Setup::sizes`].
    pub fn build<'w>(mut self, mut ws: Workspace<'w>) -> Result<Engine<'a, 'w, F>, FailureCode> {
        self.validate()?;
        if !ws.sizes().covers(&self.sizes()) {
            return Err(FailureCode::ConfigCapacityTooSmall);
        }
        let preflight = self.preflight(&mut ws);
        let pipeline = Pipeline::from_checked(
            self.map,
            self.frames,
            &self.rig,
            &self.params,
            &self.policy,
            ws,
        );
        let mut engine = Relocalizer::from_checked(
            pipeline,
            RansacSolver::from_params(&self.params).with_refinement(
                &self.rig,
                crate::pose::RefineConfig::from_params(&self.params),
            ),
            &self.params,
            &self.options,
            &self.prior,
            self.seed,
        );
        // A hopeless frame is a relocalization that fails (an outcome with its
        // code, after no work), not bad input.
        if let Err(code) = preflight {
            engine.end_early(code);
        }
        Ok(engine)
    }
}
