//! The per-trial columns of `trials.csv` beyond the fixed ones, typed.
//!
//! Each part is set by whoever knows it: the group's settings by the suite,
//! the capture and the nearest mapping view by the trial, the work counters,
//! the covariance check and the upset checks by the VTSM relocalization, the
//! keypoint counts by the feature baseline. A part that was not set writes no
//! column; the columns of a file are those set in any of its trials, sorted
//! by name, each written as an `f64` with four decimals.

use serde::ser::{Serialize, SerializeMap, Serializer};

/// What a group of the suite set for its trials.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GroupColumns {
    /// Terrain × lighting change groups (`paper`, `baseline`, `uncertainty50`).
    Prior {
        /// Time difference between mapping and capture, hours.
        hours: f32,
        /// Largest prior translation of the group, metres.
        prior_max_m: f32,
        /// Pose seeds K of the multi-seed mode (0: single start).
        seeds_k: u16,
        /// Translation uncertainty t̃₀ the engine runs with, metres.
        t0_m: f32,
        /// Rotation uncertainty r̃₀ the engine runs with, degrees.
        r0_deg: f32,
    },
    /// Inputs that must not give a confident answer (`wrongplace`).
    WrongPlace {
        /// Time difference between mapping and capture, hours.
        hours: f32,
        /// The frames come from another depot: every success is wrong.
        other_depot: bool,
    },
    /// Maps restricted to a sub-sampled mapping path (`stepsize`).
    Step {
        /// Time difference between mapping and capture, hours.
        hours: f32,
        /// Mapping step size.
        step: usize,
        /// The forward path (else the wave path).
        forward: bool,
    },
    /// One condition of the operating envelope (`hard`): the light, the
    /// depot, the map and the camera of the group.
    Condition {
        /// Time difference between mapping and capture, hours.
        hours: f32,
        /// Sun elevation at capture, degrees.
        sun_el_deg: f32,
        /// Sun elevation at mapping, degrees.
        map_sun_el_deg: f32,
        /// Map coarsening factor (1: the profile's map).
        map_coarse: u32,
        /// Wheel-track passes across the depot since mapping.
        tracks: u32,
        /// Fraction of the rocks moved or taken away since mapping.
        rocks_moved: f32,
        /// Dust cover since mapping.
        dust: f32,
        /// The live camera is not ideal (the group label says how).
        camera: bool,
    },
    /// The stereo pairs of a data set on disk (`dataset`).
    Dataset {
        /// The pair's index in the data set (its `views/` directories in
        /// name order).
        pair: u32,
        /// Translation uncertainty t̃₀ the engine runs with, metres.
        t0_m: f32,
        /// Rotation uncertainty r̃₀ the engine runs with, degrees.
        r0_deg: f32,
    },
}

impl GroupColumns {
    /// The time difference between mapping and capture, hours (`None` for
    /// a data set's pairs, whose light is their own).
    pub fn hours(&self) -> Option<f32> {
        match *self {
            Self::Prior { hours, .. }
            | Self::WrongPlace { hours, .. }
            | Self::Step { hours, .. }
            | Self::Condition { hours, .. } => Some(hours),
            Self::Dataset { .. } => None,
        }
    }

    fn push(&self, out: &mut Vec<(&'static str, f64)>) {
        match *self {
            Self::Prior {
                hours,
                prior_max_m,
                seeds_k,
                t0_m,
                r0_deg,
            } => out.extend([
                ("hours", f64::from(hours)),
                ("prior_max_m", f64::from(prior_max_m)),
                ("seeds_k", f64::from(seeds_k)),
                ("t0_m", f64::from(t0_m)),
                ("r0_deg", f64::from(r0_deg)),
            ]),
            Self::WrongPlace { hours, other_depot } => out.extend([
                ("hours", f64::from(hours)),
                ("wrong_place", f64::from(u8::from(other_depot))),
            ]),
            Self::Step {
                hours,
                step,
                forward,
            } => out.extend([
                ("hours", f64::from(hours)),
                ("step", step as f64),
                ("forward", f64::from(u8::from(forward))),
            ]),
            Self::Condition {
                hours,
                sun_el_deg,
                map_sun_el_deg,
                map_coarse,
                tracks,
                rocks_moved,
                dust,
                camera,
            } => out.extend([
                ("hours", f64::from(hours)),
                ("sun_el_deg", f64::from(sun_el_deg)),
                ("map_sun_el_deg", f64::from(map_sun_el_deg)),
                ("map_coarse", f64::from(map_coarse)),
                ("tracks", f64::from(tracks)),
                ("rocks_moved", f64::from(rocks_moved)),
                ("dust", f64::from(dust)),
                ("camera_effects", f64::from(u8::from(camera))),
            ]),
            Self::Dataset { pair, t0_m, r0_deg } => out.extend([
                ("pair", f64::from(pair)),
                ("t0_m", f64::from(t0_m)),
                ("r0_deg", f64::from(r0_deg)),
            ]),
        }
    }
}

/// Where the trial's capture was taken.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CaptureColumns {
    /// Grid stop, 0..30 over both circles.
    pub stop: u32,
    /// Tube looked at.
    pub look_at: u32,
}

/// The nearest mapping view to the truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewColumns {
    /// Distance between camera centres, metres.
    pub dist_m: f64,
    /// Angle between the optical axes, degrees.
    pub angle_deg: f64,
}

/// The engine's work counters and what its integrity gates saw.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EngineColumns {
    /// Correspondence attempts.
    pub attempts: u32,
    /// Correspondences collected.
    pub pairs: u32,
    /// Attempts that measured their revisit vertex (VTSM-RELOC-046).
    pub revisited: u32,
    /// Of those, the ones that gave a correspondence.
    pub revisit_pairs: u32,
    /// Attempts whose vertex was drawn near an agreeing one (VTSM-RELOC-047).
    pub near_drawn: u32,
    /// Of those, the ones that gave a correspondence.
    pub near_pairs: u32,
    /// Stalled iterations.
    pub stalls: u16,
    /// Reseeds.
    pub reseeds: u16,
    /// Focused rounds.
    pub focused_rounds: u16,
    /// Gradient rounds.
    pub gradient_rounds: u16,
    /// Refinement steps accepted.
    pub refine_accepted: u32,
    /// Spread of the inliers, metres.
    pub spread_m: f32,
    /// Reprojection RMS of the inliers, pixels.
    pub reproj_px: f32,
    /// Distance of the estimate to the prior, metres.
    pub prior_dt_m: f32,
    /// Angle of the estimate to the prior, degrees.
    pub prior_dr_deg: f32,
}

/// Attempts and correct matches per decile of the map's sampling scores
/// (`--score-deciles`): decile 0 holds the mask's lowest-scored tenth.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ScoreColumns {
    /// Attempts whose SamplePoint drew a vertex of the decile.
    pub attempts: [u32; 10],
    /// Of those, attempts whose correspondence lies within
    /// `max(3σ, 1 cm)` of the vertex's true position in the camera.
    pub correct: [u32; 10],
}

/// Column names of [`ScoreColumns`]: attempts of decile k, then correct.
const SCORE_NAMES: [[&str; 2]; 10] = [
    ["score_d0_attempts", "score_d0_correct"],
    ["score_d1_attempts", "score_d1_correct"],
    ["score_d2_attempts", "score_d2_correct"],
    ["score_d3_attempts", "score_d3_correct"],
    ["score_d4_attempts", "score_d4_correct"],
    ["score_d5_attempts", "score_d5_correct"],
    ["score_d6_attempts", "score_d6_correct"],
    ["score_d7_attempts", "score_d7_correct"],
    ["score_d8_attempts", "score_d8_correct"],
    ["score_d9_attempts", "score_d9_correct"],
];

/// Matches per template variant (`--variant-counts`), in the order of the
/// engine's `ncc_matches_by_variant`: gray, Sobel, Laplacian at ℓ, then the
/// same at ℓ/2.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct VariantColumns {
    /// Template searches of the variant (the engine's count).
    pub matches: [u32; VARIANTS],
    /// Attempts whose correspondence came from the variant.
    pub accepted: [u32; VARIANTS],
    /// Of those, the ones within `max(3σ, 1 cm)` of the vertex's true
    /// position in the camera.
    pub correct: [u32; VARIANTS],
}

/// Template variants counted by [`VariantColumns`].
pub const VARIANTS: usize = vtsm_core::reloc::MATCH_VARIANTS;

/// Column names of [`VariantColumns`]: matches, accepted, correct of
/// variant k.
pub const VARIANT_NAMES: [[&str; 3]; VARIANTS] = [
    [
        "variant_0_matches",
        "variant_0_accepted",
        "variant_0_correct",
    ],
    [
        "variant_1_matches",
        "variant_1_accepted",
        "variant_1_correct",
    ],
    [
        "variant_2_matches",
        "variant_2_accepted",
        "variant_2_correct",
    ],
    [
        "variant_3_matches",
        "variant_3_accepted",
        "variant_3_correct",
    ],
    [
        "variant_4_matches",
        "variant_4_accepted",
        "variant_4_correct",
    ],
    [
        "variant_5_matches",
        "variant_5_accepted",
        "variant_5_correct",
    ],
];

/// What a caller's accuracy (`--accuracy`) saved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AccuracyColumns {
    /// Pose updates not made because the accuracy was met first.
    pub rounds_saved: u16,
    /// Refinements run to check the accuracy.
    pub accuracy_checks: u16,
}

/// How the reported covariance covers the true error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CovarianceColumns {
    /// Squared Mahalanobis distance of the translation error.
    pub d2_t: f64,
    /// Squared Mahalanobis distance of the rotation error.
    pub d2_r: f64,
    /// 1-σ radius of the translation block, mm.
    pub sigma_t_mm: f64,
    /// 1-σ radius of the rotation block, degrees.
    pub sigma_r_deg: f64,
}

/// Which of the asked upset checks ran.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VerifyColumns {
    /// The final solve was repeated from a second random stream.
    pub repeat_solve: bool,
    /// The map product was re-checked before the success.
    pub recheck_map: bool,
}

/// The feature baseline's counts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FeatureColumns {
    /// Keypoints of the virtual image (first iteration).
    pub map_keypoints: usize,
    /// Keypoints of the real left image.
    pub live_keypoints: usize,
    /// Descriptor matches (first iteration).
    pub matches: usize,
    /// Matches with a stereo 3D point (first iteration).
    pub stereo_points: usize,
}

/// Every column a trial may set beyond the fixed ones.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TrialColumns {
    /// Set by the group.
    pub group: Option<GroupColumns>,
    /// Set by the trial.
    pub capture: Option<CaptureColumns>,
    /// Set when the map has mapping views.
    pub view: Option<ViewColumns>,
    /// Set by a VTSM relocalization.
    pub engine: Option<EngineColumns>,
    /// Set when the engine reported a covariance.
    pub covariance: Option<CovarianceColumns>,
    /// Set by a VTSM relocalization given an accuracy (`--accuracy`).
    pub accuracy: Option<AccuracyColumns>,
    /// Set when upset checks were asked for.
    pub verify: Option<VerifyColumns>,
    /// Set by a VTSM relocalization under `--score-deciles`.
    pub scores: Option<ScoreColumns>,
    /// Set by a VTSM relocalization under `--variant-counts`.
    pub variants: Option<VariantColumns>,
    /// Set by the feature baseline.
    pub features: Option<FeatureColumns>,
}

impl TrialColumns {
    /// The columns that are set, as `(name, value)`, sorted by name.
    pub fn entries(&self) -> Vec<(&'static str, f64)> {
        let mut out = Vec::new();
        if let Some(g) = &self.group {
            g.push(&mut out);
        }
        if let Some(c) = &self.capture {
            out.extend([
                ("stop", f64::from(c.stop)),
                ("look_at", f64::from(c.look_at)),
            ]);
        }
        if let Some(v) = &self.view {
            out.extend([("view_dist_m", v.dist_m), ("view_angle_deg", v.angle_deg)]);
        }
        if let Some(e) = &self.engine {
            out.extend([
                ("attempts", f64::from(e.attempts)),
                ("pairs", f64::from(e.pairs)),
                ("revisited", f64::from(e.revisited)),
                ("revisit_pairs", f64::from(e.revisit_pairs)),
                ("near_drawn", f64::from(e.near_drawn)),
                ("near_pairs", f64::from(e.near_pairs)),
                ("stalls", f64::from(e.stalls)),
                ("reseeds", f64::from(e.reseeds)),
                ("focused_rounds", f64::from(e.focused_rounds)),
                ("gradient_rounds", f64::from(e.gradient_rounds)),
                ("refine_accepted", f64::from(e.refine_accepted)),
                ("spread_m", f64::from(e.spread_m)),
                ("reproj_px", f64::from(e.reproj_px)),
                ("prior_dt_m", f64::from(e.prior_dt_m)),
                ("prior_dr_deg", f64::from(e.prior_dr_deg)),
            ]);
        }
        if let Some(c) = &self.covariance {
            out.extend([
                ("cov_d2_t", c.d2_t),
                ("cov_d2_r", c.d2_r),
                ("sigma_t_mm", c.sigma_t_mm),
                ("sigma_r_deg", c.sigma_r_deg),
            ]);
        }
        if let Some(a) = &self.accuracy {
            out.extend([
                ("rounds_saved", f64::from(a.rounds_saved)),
                ("accuracy_checks", f64::from(a.accuracy_checks)),
            ]);
        }
        if let Some(v) = &self.verify {
            out.extend([
                ("verify_repeat_solve", f64::from(u8::from(v.repeat_solve))),
                ("verify_recheck_map", f64::from(u8::from(v.recheck_map))),
            ]);
        }
        if let Some(v) = &self.variants {
            for (k, [m, a, c]) in VARIANT_NAMES.iter().enumerate() {
                out.extend([
                    (*m, f64::from(v.matches[k])),
                    (*a, f64::from(v.accepted[k])),
                    (*c, f64::from(v.correct[k])),
                ]);
            }
        }
        if let Some(sc) = &self.scores {
            for (k, [a, c]) in SCORE_NAMES.iter().enumerate() {
                out.extend([
                    (*a, f64::from(sc.attempts[k])),
                    (*c, f64::from(sc.correct[k])),
                ]);
            }
        }
        if let Some(f) = &self.features {
            out.extend([
                ("map_keypoints", f.map_keypoints as f64),
                ("live_keypoints", f.live_keypoints as f64),
                ("matches", f.matches as f64),
                ("stereo_points", f.stereo_points as f64),
            ]);
        }
        out.sort_by(|a, b| a.0.cmp(b.0));
        out
    }

    /// The time difference of the trial's group, hours (`None` if unset).
    pub fn hours(&self) -> Option<f32> {
        self.group.as_ref().and_then(GroupColumns::hours)
    }

    /// Whether the frames came from another depot.
    pub fn other_depot(&self) -> bool {
        matches!(
            self.group,
            Some(GroupColumns::WrongPlace {
                other_depot: true,
                ..
            })
        )
    }
}

/// A map of the set columns, sorted by name.
impl Serialize for TrialColumns {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let entries = self.entries();
        let mut map = s.serialize_map(Some(entries.len()))?;
        for (k, v) in &entries {
            map.serialize_entry(k, v)?;
        }
        map.end()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unset_parts_write_no_column_and_names_come_sorted() {
        assert!(TrialColumns::default().entries().is_empty());
        let c = TrialColumns {
            group: Some(GroupColumns::Step {
                hours: 3.0,
                step: 6,
                forward: true,
            }),
            capture: Some(CaptureColumns {
                stop: 4,
                look_at: 1,
            }),
            ..TrialColumns::default()
        };
        let names: Vec<&str> = c.entries().iter().map(|e| e.0).collect();
        assert_eq!(names, ["forward", "hours", "look_at", "step", "stop"]);
        assert_eq!(c.hours(), Some(3.0));
        assert!(!c.other_depot());
        let json = serde_json::to_string(&c).unwrap();
        assert_eq!(
            json,
            r#"{"forward":1.0,"hours":3.0,"look_at":1.0,"step":6.0,"stop":4.0}"#
        );
    }
}
