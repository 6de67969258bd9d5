//! The JSON files of design §5: `calib.json` ([`Calib`]), `prior.json` /
//! `truth.json` ([`PoseFile`], with the prior's optional stated uncertainty
//! [`UncertaintyJson`]) and `result.json` ([`ResultFile`]).
//!
//! Readers reject unknown fields (a misspelt key is an error, not a default),
//! non-finite or out-of-range numbers, non-positive sizes, focal lengths,
//! baselines and uncertainties, and quaternions further than
//! [`QUAT_NORM_TOL`] from unit norm. Errors name the file and, where known,
//! the line.

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;
use vtsm_core::config::{PriorUncertainty, MAX_IMAGE_DIM, MAX_R0_DEG, MAX_T0_M};
use vtsm_core::geom::{self, Camera, Pose, StereoRig};
use vtsm_core::reloc::MATCH_VARIANTS;
use vtsm_core::FailureCode;

/// Largest accepted deviation of a quaternion's norm from 1.
pub const QUAT_NORM_TOL: f64 = 1.0e-3;

/// `calib.json`: a rectified stereo pair (both cameras share the intrinsics;
/// the right camera is `baseline_m` along the left camera's +x).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Calib {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels (pixel-centre convention, design §3).
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Stereo baseline, metres.
    pub baseline_m: f64,
}

impl Calib {
    /// The core's checked stereo rig.
    ///
    /// # Errors
    /// The core's failure code if a value is out of range (cannot happen for a
    /// calibration returned by [`read_calib`]).
    pub fn rig(&self) -> std::result::Result<StereoRig, FailureCode> {
        let cam = Camera::new(
            self.fx as f32,
            self.fy as f32,
            self.cx as f32,
            self.cy as f32,
            self.width,
            self.height,
        )?;
        StereoRig::new(cam, self.baseline_m as f32)
    }

    /// Check every field against the ranges of the core's [`Camera::new`]
    /// (width and height in 1..=`MAX_IMAGE_DIM`, focal lengths in
    /// (0, `MAX_FOCAL_PX`], principal point within ±`MAX_PRINCIPAL_PX` pixels) and
    /// a finite positive baseline; returns the name of the bad field and why.
    pub fn validate(&self) -> std::result::Result<(), (&'static str, String)> {
        let dim = |name: &'static str, v: u32| {
            if geom::image_dim_ok(v) {
                Ok(())
            } else {
                Err((name, format!("{v} is outside 1..={MAX_IMAGE_DIM}")))
            }
        };
        dim("width", self.width)?;
        dim("height", self.height)?;
        // The core works in f32: a value is judged as the core will see it.
        let focal = |name: &'static str, v: f64| {
            if geom::focal_px_ok(v as f32) {
                Ok(())
            } else {
                Err((
                    name,
                    format!(
                        "{} px is outside the accepted focal length range (0, {}] px",
                        short_number(v),
                        short_number(f64::from(geom::MAX_FOCAL_PX))
                    ),
                ))
            }
        };
        focal("fx", self.fx)?;
        focal("fy", self.fy)?;
        let principal = |name: &'static str, v: f64| {
            if geom::principal_px_ok(v as f32) {
                Ok(())
            } else {
                Err((
                    name,
                    format!(
                        "{} px is outside the accepted principal point range ±{} px",
                        short_number(v),
                        short_number(f64::from(geom::MAX_PRINCIPAL_PX))
                    ),
                ))
            }
        };
        principal("cx", self.cx)?;
        principal("cy", self.cy)?;
        let b = self.baseline_m;
        if !(b.is_finite() && b > 0.0 && b < f64::from(f32::MAX) && (b as f32) > 0.0) {
            return Err((
                "baseline_m",
                format!("{} must be a finite positive number", short_number(b)),
            ));
        }
        Ok(())
    }
}

/// A number for an error message: as written when short, else in scientific
/// notation (so `1e300` is not echoed as 301 digits).
pub fn short_number(v: f64) -> String {
    let plain = format!("{v}");
    if plain.len() <= 16 {
        plain
    } else {
        format!("{v:e}")
    }
}

/// A pose in JSON: `world_from_left`, `p_world = R(q) p_cam + t`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseJson {
    /// Translation, metres.
    pub t: [f64; 3],
    /// Rotation quaternion `[w, x, y, z]`.
    pub q: [f64; 4],
}

impl PoseJson {
    /// From a core pose.
    pub fn from_pose(p: &Pose) -> Self {
        Self {
            t: p.t().map(f64::from),
            q: p.q().map(f64::from),
        }
    }

    /// From a user-frame (f64) pose.
    pub fn from_user(p: &crate::frame::UserPose) -> Self {
        let (t, q) = crate::frame::user_t_q(p);
        Self { t, q }
    }

    /// The user-frame (f64) pose (quaternion renormalised).
    pub fn user(&self) -> crate::frame::UserPose {
        crate::frame::user_pose(self.t, self.q)
    }

    /// The core (local-frame) pose of this pose: `t − origin` in f64, then
    /// `t` and `q` rounded to f32 and `q` renormalised by the core, so at
    /// origin 0 this is exactly the pose an f32 reader would get.
    ///
    /// # Errors
    /// The core's code when the local pose is not finite in f32
    /// ([`Pose::from_t_q`]), e.g. a prior millions of metres from the map.
    pub fn to_local(&self, origin: [f64; 3]) -> std::result::Result<Pose, FailureCode> {
        let t = [0, 1, 2].map(|k| (self.t[k] - origin[k]) as f32);
        Pose::from_t_q(t, self.q.map(|v| v as f32))
    }

    /// The JSON form, in the user frame, of a core (local-frame) pose: the
    /// origin added to `t` in f64, `q` as the core has it.
    pub fn from_local(p: &Pose, origin: [f64; 3]) -> Self {
        let t = p.t();
        Self {
            t: [0, 1, 2].map(|k| f64::from(t[k]) + origin[k]),
            q: p.q().map(f64::from),
        }
    }

    /// Check finiteness and unit norm; returns the reason.
    pub fn validate(&self) -> std::result::Result<(), String> {
        if !self
            .t
            .iter()
            .all(|v| v.is_finite() && v.abs() < f64::from(f32::MAX))
        {
            return Err("translation `t` is not finite".to_string());
        }
        if !self.q.iter().all(|v| v.is_finite()) {
            return Err("quaternion `q` is not finite".to_string());
        }
        let n = self.q.iter().map(|v| v * v).sum::<f64>().sqrt();
        if (n - 1.0).abs() > QUAT_NORM_TOL {
            return Err(format!(
                "quaternion `q` has norm {n:.6}, not within {QUAT_NORM_TOL} of 1"
            ));
        }
        Ok(())
    }

    /// The core pose (quaternion renormalised).
    ///
    /// # Errors
    /// The core's failure code for a non-finite or non-unit pose.
    pub fn pose(&self) -> std::result::Result<Pose, FailureCode> {
        Pose::from_t_q(self.t.map(|v| v as f32), self.q.map(|v| v as f32))
    }
}

/// The stated uncertainty of a prior, `"uncertainty": {"t_m": T, "r_deg": R}`:
/// half-widths of the region the true pose lies in around the prior (the
/// paper's t̃₀, r̃₀). Also echoed in `result.json` as `prior_uncertainty`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UncertaintyJson {
    /// Translation half-width, metres, in (0, [`MAX_T0_M`]].
    pub t_m: f64,
    /// Rotation half-width, degrees, in (0, [`MAX_R0_DEG`]].
    pub r_deg: f64,
}

impl UncertaintyJson {
    /// Check both values against the ranges of the core's
    /// [`PriorUncertainty::validate`] (finite, `t_m` in (0, [`MAX_T0_M`]] m,
    /// `r_deg` in (0, [`MAX_R0_DEG`]]°), judged as the f32 the core will see;
    /// returns the name of the bad field (`t_m` or `r_deg`) and why.
    pub fn validate(&self) -> std::result::Result<(), (&'static str, String)> {
        let one = |name: &'static str, v: f64, max: f32, unit: &str| {
            let f = v as f32;
            if v.is_finite() && f.is_finite() && f > 0.0 && f <= max {
                Ok(())
            } else {
                Err((
                    name,
                    format!(
                        "{} {unit} is outside the accepted range (0, {}] {unit}",
                        short_number(v),
                        short_number(f64::from(max))
                    ),
                ))
            }
        };
        one("t_m", self.t_m, MAX_T0_M, "m")?;
        one("r_deg", self.r_deg, MAX_R0_DEG, "deg")
    }

    /// The core's form (f32; checked by [`UncertaintyJson::validate`]).
    pub fn core(&self) -> PriorUncertainty {
        PriorUncertainty {
            t_m: self.t_m as f32,
            r_deg: self.r_deg as f32,
        }
    }

    /// From the core's form, each f32 as the shortest decimal that reads
    /// back to it (so 0.2 is echoed as 0.2, not 0.20000000298023224).
    pub fn from_core(u: &PriorUncertainty) -> Self {
        let short = |v: f32| v.to_string().parse::<f64>().unwrap_or(f64::from(v));
        Self {
            t_m: short(u.t_m),
            r_deg: short(u.r_deg),
        }
    }
}

/// `prior.json` / `truth.json`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseFile {
    /// Pose of the left camera in the world.
    pub world_from_left: PoseJson,
    /// The prior's stated uncertainty; absent: the engine's t̃₀, r̃₀ (the
    /// paper's 0.20 m, 1.5°). Read but not used in `truth.json`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<UncertaintyJson>,
    /// The sun at capture time, in the map's frame (`azimuth_deg` clockwise
    /// from `+y`, `elevation_deg` above the `xy` plane); absent: the map is
    /// matched as made. With the map's own sun (`--map-sun`) the map is
    /// relit to it ([`crate::relight`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sun: Option<crate::relight::SunAngles>,
}

/// `result.json`, written by `vtsm relocalize` and `vtsm demo`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResultFile {
    /// `"ok"` or `"failed"`.
    pub status: String,
    /// Failure code name (e.g. `"RELOC_..."`) or `null`.
    pub failure: Option<String>,
    /// Final estimate (the last estimate when failed), or `null` if none.
    pub world_from_left: Option<PoseJson>,
    /// RANSAC inliers of the final estimate.
    pub inliers: u32,
    /// Successful iterations.
    pub iterations: u32,
    /// Work counters of the engine ([`WorkStats`]).
    pub stats: WorkStats,
    /// 6×6 covariance of `world_from_left`, row-major (36 numbers): world-frame
    /// camera position in metres, then a world-frame rotation vector in
    /// radians (`fsw-docs/interfaces/files.md`); `null` when not estimated.
    #[serde(default)]
    pub covariance: Option<Vec<f64>>,
    /// The upset checks that ran on this result (`--verify`); both false when
    /// absent (files written before the field).
    #[serde(default)]
    pub verified: Verified,
    /// The prior uncertainty (t̃₀, r̃₀) the engine ran with: the prior's
    /// stated `uncertainty`, else the default; `null` (or absent) when not
    /// known (results written before the field existed).
    #[serde(default)]
    pub prior_uncertainty: Option<UncertaintyJson>,
}

/// The engine's work counters as `result.json` writes them (`stats`): the
/// core's [`vtsm_core::reloc::Stats`] with its pipeline counters; the NCC
/// matches and acceptances both summed over the match variants and per
/// variant. Fields in
/// name order, the order of the file. A reader takes a missing counter as 0
/// and ignores one it does not know (files of other versions).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct WorkStats {
    /// Refinements run to check the caller's accuracy (`--accuracy`).
    pub accuracy_checks: u64,
    /// Correspondence attempts (one template synthesized and matched).
    pub attempts: u64,
    /// Correspondences collected.
    pub correspondences: u64,
    /// Rounds run with the focused search.
    pub focused_rounds: u64,
    /// Rounds run in the gradient domain.
    pub gradient_rounds: u64,
    /// NCC matches accepted, over every variant.
    pub ncc_accepted: u64,
    /// NCC matches accepted per variant, in the order of the core's
    /// `Variant::index`: gray, Sobel, Laplacian at ℓ, then the same at ℓ/2.
    pub ncc_accepted_by_variant: [u64; MATCH_VARIANTS],
    /// NCC multiply-accumulates.
    pub ncc_macs: u64,
    /// NCC matches made, over every variant.
    pub ncc_matches: u64,
    /// NCC matches made per variant (left and right searches), in the
    /// order of `ncc_accepted_by_variant`.
    pub ncc_matches_by_variant: [u64; MATCH_VARIANTS],
    /// NCC positions scored.
    pub ncc_positions: u64,
    /// Attempts whose vertex was drawn near an agreeing one (VTSM-RELOC-047).
    pub near_drawn: u64,
    /// Of those, the ones that gave a correspondence (VTSM-RELOC-047).
    pub near_pairs: u64,
    /// RANSAC iterations.
    pub ransac_iterations: u64,
    /// Refinement steps accepted.
    pub refine_accepted: u64,
    /// Refinement iterations.
    pub refine_iterations: u64,
    /// Pixels rendered.
    pub render_pixels: u64,
    /// Templates rendered.
    pub renders: u64,
    /// Reseeds.
    pub reseeds: u64,
    /// Correspondences reused from the previous round.
    pub reused: u64,
    /// Revisit attempts that gave a correspondence (VTSM-RELOC-046).
    pub revisit_pairs: u64,
    /// Attempts that measured their revisit vertex (VTSM-RELOC-046).
    pub revisited: u64,
    /// Rounds.
    pub rounds: u64,
    /// Pose updates not made because the caller's accuracy (`--accuracy`)
    /// was met first.
    pub rounds_saved: u64,
    /// Sampled points occluded.
    pub samples_occluded: u64,
    /// Sampled points out of view.
    pub samples_out_of_view: u64,
    /// Pose seeds tried (multi-seed mode).
    pub seeds_tried: u64,
    /// Pose solves.
    pub solves: u64,
    /// Stalls.
    pub stalls: u64,
    /// Stereo triangulations.
    pub triangulations: u64,
    /// Work units of the upset checks.
    pub verify_units: u64,
    /// Solves with a widened threshold.
    pub widened_solves: u64,
    /// Work units.
    pub work_units: u64,
}

impl From<&vtsm_core::reloc::Stats> for WorkStats {
    fn from(s: &vtsm_core::reloc::Stats) -> Self {
        let p = &s.pipeline;
        let sum = |v: &[u32]| v.iter().map(|&m| u64::from(m)).sum();
        Self {
            accuracy_checks: s.accuracy_checks.into(),
            attempts: s.attempts.into(),
            correspondences: s.correspondences.into(),
            focused_rounds: s.focused_rounds.into(),
            gradient_rounds: s.gradient_rounds.into(),
            ncc_accepted: sum(&p.accepted),
            ncc_accepted_by_variant: p.accepted.map(u64::from),
            ncc_macs: p.ncc_macs,
            ncc_matches: sum(&p.matches),
            ncc_matches_by_variant: p.matches.map(u64::from),
            ncc_positions: p.ncc_positions,
            near_drawn: p.near_drawn.into(),
            near_pairs: p.near_pairs.into(),
            ransac_iterations: s.ransac_iterations.into(),
            refine_accepted: s.refine.accepted.into(),
            refine_iterations: s.refine.iterations.into(),
            render_pixels: p.render_pixels,
            renders: p.renders.into(),
            reseeds: s.reseeds.into(),
            reused: s.reused.into(),
            revisit_pairs: p.revisit_pairs.into(),
            revisited: p.revisited.into(),
            rounds: s.rounds.into(),
            rounds_saved: s.rounds_saved.into(),
            samples_occluded: p.occluded.into(),
            samples_out_of_view: p.out_of_view.into(),
            seeds_tried: s.seeds_tried.into(),
            solves: s.solves.into(),
            stalls: s.stalls.into(),
            triangulations: p.triangulations.into(),
            verify_units: s.verify_units.into(),
            widened_solves: s.widened_solves.into(),
            work_units: s.work_units.into(),
        }
    }
}

/// The upset checks that ran on a relocalization (`result.json` `verified`).
/// A check that ran and failed ended the run with its failure code.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Verified {
    /// The final solve was repeated from a second random stream and compared
    /// with the final estimate (`--verify repeat`; `RELOC_VERIFY_DISAGREE`).
    pub repeat_solve: bool,
    /// The map product was re-checked before the result was returned
    /// (`--verify map`; `RELOC_MAP_CHANGED`).
    pub recheck_map: bool,
}

/// The 1-based line on which `"key"` first appears in `text`, if it does.
fn key_line(text: &str, key: &str) -> Option<usize> {
    let needle = format!("\"{key}\"");
    text.lines()
        .position(|l| l.contains(&needle))
        .map(|i| i + 1)
}

pub(crate) fn parse_json<T: for<'de> Deserialize<'de>>(bytes: &[u8], path: &Path) -> Result<T> {
    serde_json::from_slice(bytes).map_err(|e| {
        let msg = format!("invalid JSON: {e}");
        // serde_json appends " at line L column C"; the line goes in front instead.
        let msg = match msg.rfind(" at line ") {
            Some(i) => msg.get(..i).unwrap_or(&msg).to_string(),
            None => msg,
        };
        if e.line() > 0 {
            Error::at(path, e.line(), msg)
        } else {
            Error::file(path, msg)
        }
    })
}

pub(crate) fn field_error(bytes: &[u8], path: &Path, key: &str, why: String) -> Error {
    let text = String::from_utf8_lossy(bytes);
    let msg = format!("`{key}`: {why}");
    match key_line(&text, key) {
        Some(l) => Error::at(path, l, msg),
        None => Error::file(path, msg),
    }
}

/// Parse and validate `calib.json` bytes.
///
/// # Errors
/// Malformed JSON, a missing or unknown field, or a value out of range.
pub fn parse_calib(bytes: &[u8], path: &Path) -> Result<Calib> {
    let c: Calib = parse_json(bytes, path)?;
    c.validate()
        .map_err(|(k, why)| field_error(bytes, path, k, why))?;
    Ok(c)
}

/// Read and validate `calib.json`.
///
/// # Errors
/// As [`parse_calib`], plus I/O errors.
pub fn read_calib(path: &Path) -> Result<Calib> {
    parse_calib(&super::read_file(path)?, path)
}

/// Parse and validate `prior.json` / `truth.json` bytes into a core pose.
///
/// # Errors
/// Malformed JSON, a missing or unknown field, non-finite numbers, or a
/// quaternion not within [`QUAT_NORM_TOL`] of unit norm.
pub fn parse_pose(bytes: &[u8], path: &Path) -> Result<Pose> {
    parse_pose_json(bytes, path)?
        .pose()
        .map_err(|c| Error::file(path, format!("pose rejected: {}", c.name())).with_code(c))
}

/// Parse and validate `prior.json` / `truth.json` bytes, keeping the f64
/// numbers as written (user frame; see [`crate::frame`]).
///
/// # Errors
/// As [`parse_prior`].
pub fn parse_pose_json(bytes: &[u8], path: &Path) -> Result<PoseJson> {
    Ok(parse_prior(bytes, path)?.world_from_left)
}

/// Parse and validate `prior.json` bytes: the pose (f64, user frame) and the
/// stated uncertainty, if any.
///
/// # Errors
/// Malformed JSON, a missing or unknown field (also inside `uncertainty`),
/// non-finite numbers, a quaternion not within [`QUAT_NORM_TOL`] of unit
/// norm, or an uncertainty out of range ([`UncertaintyJson::validate`]; that
/// error carries [`FailureCode::HalPriorInvalid`], the code the flight path
/// gives the same prior).
pub fn parse_prior(bytes: &[u8], path: &Path) -> Result<PoseFile> {
    let f: PoseFile = parse_json(bytes, path)?;
    let text = || String::from_utf8_lossy(bytes);
    f.world_from_left.validate().map_err(|why| {
        let key = if why.contains("`t`") { "t" } else { "q" };
        match key_line(&text(), key) {
            Some(l) => Error::at(path, l, why),
            None => Error::file(path, why),
        }
    })?;
    if let Some(u) = &f.uncertainty {
        u.validate().map_err(|(key, why)| {
            let msg = format!("`uncertainty.{key}`: {why}");
            match key_line(&text(), key) {
                Some(l) => Error::at(path, l, msg),
                None => Error::file(path, msg),
            }
            .with_code(FailureCode::HalPriorInvalid)
        })?;
    }
    if let Some(s) = &f.sun {
        s.check().map_err(|why| {
            let msg = format!("`sun`: {why}");
            match key_line(&text(), "sun") {
                Some(l) => Error::at(path, l, msg),
                None => Error::file(path, msg),
            }
            .with_code(FailureCode::HalPriorInvalid)
        })?;
    }
    Ok(f)
}

/// Read and validate `prior.json` (see [`parse_prior`]).
///
/// # Errors
/// As [`parse_prior`], plus I/O errors.
pub fn read_prior(path: &Path) -> Result<PoseFile> {
    parse_prior(&super::read_file(path)?, path)
}

/// Read and validate `prior.json` / `truth.json` as a user-frame (f64) pose.
///
/// # Errors
/// As [`parse_pose`], plus I/O errors.
pub fn read_user_pose(path: &Path) -> Result<crate::frame::UserPose> {
    Ok(parse_pose_json(&super::read_file(path)?, path)?.user())
}

/// Read and validate `prior.json` / `truth.json`.
///
/// # Errors
/// As [`parse_pose`], plus I/O errors.
pub fn read_pose(path: &Path) -> Result<Pose> {
    parse_pose(&super::read_file(path)?, path)
}

/// Serialise a pose file (`prior.json` / `truth.json`), pretty-printed.
pub fn pose_file_text(pose: &Pose) -> String {
    let f = PoseFile {
        world_from_left: PoseJson::from_pose(pose),
        uncertainty: None,
        sun: None,
    };
    serde_json::to_string_pretty(&f).unwrap_or_default() + "\n"
}

/// Serialise a calibration, pretty-printed.
pub fn calib_text(c: &Calib) -> String {
    serde_json::to_string_pretty(c).unwrap_or_default() + "\n"
}

/// Serialise `result.json`, pretty-printed.
pub fn result_text(r: &ResultFile) -> String {
    serde_json::to_string_pretty(r).unwrap_or_default() + "\n"
}

/// Write `result.json` atomically (see [`super::write_atomic`]).
///
/// # Errors
/// I/O errors, or an existing file without `force`.
pub fn write_result(path: &Path, r: &ResultFile, force: bool) -> Result<()> {
    super::write_atomic(path, result_text(r).as_bytes(), force)
}

/// Parse `result.json` bytes (for tools and tests that read results back).
///
/// # Errors
/// Malformed JSON or a missing/unknown field.
pub fn parse_result(bytes: &[u8], path: &Path) -> Result<ResultFile> {
    parse_json(bytes, path)
}
