//! The evaluation protocol shared by every suite: the paper's constants,
//! which capture and seed trial `k` uses, how its prior is drawn, and the
//! nearest mapping view to a pose.

use crate::scene::{perturbed_prior, Capture, STOPS_PER_CIRCLE};
use nalgebra::UnitQuaternion;
use vtsm_core::config::PriorUncertainty;
use vtsm_core::geom::{Pose, Vec3};
use vtsm_core::rng::Rng;

/// Stereo baseline of the paper's main results, metres.
pub const MAIN_BASELINE_M: f32 = 0.40;
/// Stereo baseline of the `baseline` suite, metres.
pub const SHORT_BASELINE_M: f32 = 0.20;
/// Prior translation range of `paper`, `baseline` and `stepsize`, metres.
pub const PRIOR_M: (f32, f32) = (0.10, 0.20);
/// Prior translation range of `uncertainty50`, metres.
pub const PRIOR_50_M: (f32, f32) = (0.25, 0.50);
/// The uncertainty the `uncertainty50` priors state in the single-start
/// group: the half-widths they are drawn within (0.50 m, 1.5°).
pub const UNCERTAINTY_50: PriorUncertainty = PriorUncertainty {
    t_m: PRIOR_50_M.1,
    r_deg: PRIOR_MAX_DEG,
};
/// A success whose true translation error exceeds this is confident wrong, mm:
/// the smallest displacement of the evaluation priors, so such an answer is
/// no better than the prior it started from.
pub const WRONG_T_MM: f64 = 100.0;
/// A success whose true rotation error exceeds this is confident wrong,
/// degrees: the largest rotation of the evaluation priors.
pub const WRONG_R_DEG: f64 = 1.5;
/// Shift of the "right" image of the `wrongplace` suite, pixels (test
/// profile; scaled with the image width).
pub const SHIFT_PX: u32 = 4;

/// Fork of a scene's seed that seeds its `--wind`.
pub const WIND_SEED: u64 = 0x5749_4E44_4556;

/// Fork of a trial's seed that seeds its live camera's effects (`hard`).
pub const CAMERA_SEED: u64 = 0x4341_4D45_5241;

/// Largest prior rotation, degrees (all suites).
pub const PRIOR_MAX_DEG: f32 = 1.5;
/// A map triangle counts as seen by a mapping view when its centroid is within
/// this range of the view (and in its field of view, facing it).
pub const MAP_VIEW_RANGE_M: f32 = 3.0;
/// Map tile size used for every map product, metres (as `vtsm demo`).
pub const TILE_M: f32 = 0.5;

/// Capture `k` of `n`: stops spread evenly over the 30 (then cycling), the
/// looked-at tube alternating.
pub fn capture_for_trial(k: usize, n: usize, baseline_m: f32) -> Capture {
    let stops = (2 * STOPS_PER_CIRCLE) as usize;
    let stop = if n <= stops {
        k * stops / n.max(1)
    } else {
        k % stops
    };
    let look_at = (k + k / stops) % 2;
    Capture::from_index(stop as u32, look_at as u32, baseline_m)
}

/// Seed of trial `k` (the same in every group of a run).
pub fn trial_seed(base: u64, k: usize) -> u64 {
    Rng::new(base)
        .fork(0x4556_414C ^ ((k as u64) << 32))
        .next_u64()
}

/// A prior: truth displaced by `lo..hi` metres in a random direction and rotated
/// by up to [`PRIOR_MAX_DEG`] about a random axis. The paper's 10–20 cm range is
/// exactly [`perturbed_prior`].
pub fn prior_in_range(truth: &Pose, seed: u64, (lo, hi): (f32, f32)) -> Pose {
    if (lo, hi) == PRIOR_M {
        return perturbed_prior(truth, seed);
    }
    let mut rng = Rng::new(seed).fork(0x0050_5249_4F52_3530);
    let dt = rng.unit_vector3() * rng.uniform(lo, hi);
    let axis = rng.unit_vector3();
    let angle = rng.uniform(-PRIOR_MAX_DEG, PRIOR_MAX_DEG).to_radians();
    let dq = UnitQuaternion::from_scaled_axis(axis * angle);
    Pose::new(dq * truth.rotation(), truth.translation() + dt)
}

/// Distance (m) to the nearest of `views` (by camera centre) and the angle (°)
/// between its optical axis and that of `pose`. `None` without views.
pub fn nearest_view(pose: &Pose, views: &[Pose]) -> Option<(f64, f64)> {
    let c = pose.translation();
    let v = views.iter().min_by(|a, b| {
        (a.translation() - c)
            .norm()
            .total_cmp(&(b.translation() - c).norm())
    })?;
    let z = Vec3::z();
    let (a, b) = (pose.rotation() * z, v.rotation() * z);
    let angle = f64::from(a.dot(&b).clamp(-1.0, 1.0)).acos().to_degrees();
    Some((f64::from((v.translation() - c).norm()), angle))
}

/// The label of a time difference, e.g. `Δ3h`.
pub fn hours_label(h: f32) -> String {
    format!("Δ{}h", h)
}
