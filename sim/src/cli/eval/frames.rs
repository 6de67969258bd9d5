//! The frames of a trial: the capture as the rig delivers it, and the other
//! frames `wrongplace` gives the relocalizer instead.

use super::depot::Depot;
use super::group::{Frames, Group};
use super::protocol::prior_in_range;
use crate::io::calib::model::OpenCvCalib;
use crate::render::Lighting;
use crate::scene::physical::capture_physical;
use crate::scene::{Capture, Scene, StereoPair, STOPS_PER_CIRCLE};
use vtsm_core::geom::{Pose, StereoRig};

/// What a trial relocalizes: the rig, the frames, the prior and where the
/// frames were really taken.
pub struct LiveFrames {
    /// The core's rig of the trial's capture.
    pub rig: StereoRig,
    /// Where the frames were taken (`world_from_left`); errors are measured to it.
    pub truth: Pose,
    /// The frames.
    pub pair: StereoPair,
    /// The rig's OpenCV calibration when the frames are physical (distorted,
    /// unrectified).
    pub calib: Option<OpenCvCalib>,
    /// The prior given to the relocalizer.
    pub prior: Pose,
}

/// The frames of group `g` at `capture`, and a prior drawn about the
/// capture's truth with `seed` (the same in every group).
pub fn live_frames(
    physical: bool,
    g: &Group,
    depot: &Depot,
    capture: &Capture,
    seed: u64,
) -> LiveFrames {
    let (scene, light) = (depot.live_of(g.light), &depot.lights[g.light]);
    let (rig, here, mut pair, calib) = shoot(physical, scene, light, capture);
    let mut prior = prior_in_range(&here, seed, g.prior_m);
    let truth = match g.frames {
        Frames::Truth => here,
        Frames::ShiftedRight(d) => {
            pair.right = shifted_left(&pair.left, pair.width as usize, d as usize);
            prior = here;
            here
        }
        Frames::OtherSpot => {
            let (_, there, p, _) = shoot(physical, scene, light, &other_spot(capture));
            pair = p;
            there
        }
        Frames::OtherDepot(o) => {
            let hour = g.light % depot.live_hours.len().max(1);
            let other = depot.light_of(o, hour);
            let (_, there, p, _) = shoot(
                physical,
                depot.live_of(other),
                &depot.lights[other],
                capture,
            );
            pair = p;
            there
        }
    };
    LiveFrames {
        rig,
        truth,
        pair,
        calib,
        prior,
    }
}

/// The capture at the stop half the grid away from `capture`'s.
fn other_spot(capture: &Capture) -> Capture {
    let stops = 2 * STOPS_PER_CIRCLE;
    let k = capture.circle * STOPS_PER_CIRCLE + capture.stop;
    Capture {
        circle: ((k + stops / 2) % stops) / STOPS_PER_CIRCLE,
        stop: ((k + stops / 2) % stops) % STOPS_PER_CIRCLE,
        ..*capture
    }
}

/// One capture as the rig delivers it: the core's rig, the truth
/// `world_from_left`, the pair and, in the physical form
/// ([`capture_physical`], as `vtsm scene export --physical` writes it; same
/// truth and sensor-noise seeds as [`Scene::capture`]), the rig's OpenCV
/// calibration (the images are then distorted and unrectified).
fn shoot(
    physical: bool,
    scene: &Scene,
    light: &Lighting,
    c: &Capture,
) -> (StereoRig, Pose, StereoPair, Option<OpenCvCalib>) {
    if physical {
        let (calib, truth, pair) = capture_physical(scene, light, c);
        (scene.rig(c.baseline_m), truth, pair, Some(calib))
    } else {
        let (rig, truth, pair) = scene.capture(light, c);
        (rig, truth, pair, None)
    }
}

/// `img` (`width` wide) shifted left by `d` pixels, the last columns
/// repeating the edge: every pixel at disparity `d`.
fn shifted_left(img: &[u8], width: usize, d: usize) -> Vec<u8> {
    img.chunks(width.max(1))
        .flat_map(|row| (0..row.len()).map(move |x| row[(x + d).min(row.len() - 1)]))
        .collect()
}
