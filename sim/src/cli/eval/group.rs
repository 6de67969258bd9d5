//! A group: one row of the table, the trials of one setting.

use super::config::Method;
use super::protocol::{MAIN_BASELINE_M, PRIOR_M};
use crate::effects::CameraEffects;
use crate::eval::columns::GroupColumns;
use vtsm_core::config::PriorUncertainty;

/// What the relocalizer is given as frames (`wrongplace` varies them).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Frames {
    /// The capture of the trial.
    Truth,
    /// The left image of the capture as both images, the right one shifted
    /// left by this many pixels; the prior is the truth.
    ShiftedRight(u32),
    /// The capture at the stop half the grid away, prior from this stop.
    OtherSpot,
    /// The capture at this stop in the depot of terrain index `.0`.
    OtherDepot(usize),
}

/// One row of the table.
#[derive(Clone, Debug)]
pub struct Group {
    /// Label of the row.
    pub label: String,
    /// Terrain index (into `--terrains`).
    pub terrain: usize,
    /// Index of the map product.
    pub map: usize,
    /// Index of the live lighting.
    pub light: usize,
    /// Stereo baseline of the live pairs, metres.
    pub baseline_m: f32,
    /// Prior translation range, metres.
    pub prior_m: (f32, f32),
    /// Pose seeds K of the multi-seed mode (0: single start).
    pub seeds: u16,
    /// The uncertainty the priors state (`None`: the engine's t̃₀, r̃₀).
    pub uncertainty: Option<PriorUncertainty>,
    /// The relocalizer.
    pub method: Method,
    /// The group's settings, written with every trial.
    pub columns: GroupColumns,
    /// What the relocalizer is given as frames.
    pub frames: Frames,
    /// Small parameters (N_corr 27, N_iter 1, reseed cap 3).
    pub small: bool,
    /// What the live camera adds to the frames ([`CameraEffects::NONE`]:
    /// the ideal one).
    pub camera: CameraEffects,
}

impl Group {
    /// A group of the paper's protocol on terrain `terrain` (its own map) under
    /// lighting `light`: the true frames, 0.40 m baseline, 10–20 cm priors, a
    /// single start told nothing, VTSM; the builders below change one thing.
    pub fn new(label: String, terrain: usize, light: usize, columns: GroupColumns) -> Self {
        Self {
            label,
            terrain,
            map: terrain,
            light,
            baseline_m: MAIN_BASELINE_M,
            prior_m: PRIOR_M,
            seeds: 0,
            uncertainty: None,
            method: Method::Vtsm,
            columns,
            frames: Frames::Truth,
            small: false,
            camera: CameraEffects::NONE,
        }
    }

    /// The same group with another stereo baseline.
    pub fn with_baseline(self, baseline_m: f32) -> Self {
        Self { baseline_m, ..self }
    }

    /// The same group with another prior range, multi-seed K and stated
    /// uncertainty.
    pub fn with_prior(
        self,
        prior_m: (f32, f32),
        seeds: u16,
        uncertainty: Option<PriorUncertainty>,
    ) -> Self {
        Self {
            prior_m,
            seeds,
            uncertainty,
            ..self
        }
    }

    /// The same group relocalizing other frames, with small parameters or not.
    pub fn with_frames(self, frames: Frames, small: bool) -> Self {
        Self {
            frames,
            small,
            ..self
        }
    }

    /// The same group seen through a camera with `camera`'s effects.
    pub fn with_camera(self, camera: CameraEffects) -> Self {
        Self { camera, ..self }
    }

    /// The same group on map product `map`.
    pub fn on_map(self, map: usize) -> Self {
        Self { map, ..self }
    }

    /// The same trials relocalized by `method`, labelled `"<label> · <method>"`.
    pub fn by(&self, method: Method) -> Self {
        Self {
            label: format!("{} · {}", self.label, method.name()),
            method,
            ..self.clone()
        }
    }
}

/// Every group followed by the same group relocalized by `baseline`, if any.
pub fn with_baseline_groups(groups: Vec<Group>, baseline: Option<Method>) -> Vec<Group> {
    match baseline {
        None => groups,
        Some(m) => groups
            .into_iter()
            .flat_map(|g| {
                let b = g.by(m);
                [g, b]
            })
            .collect(),
    }
}
