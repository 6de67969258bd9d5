//! The final estimate of a relocalization and how sure it is: after the last
//! RANSAC, (a) a rigid fit of the inliers weighted by their depth uncertainty,
//! then (b) a bounded Levenberg–Marquardt refinement of the 6-DoF pose on the
//! reprojection error of every inlier in both rectified images, and (c) the
//! pose covariance from the normal equations.
//!
//! Why: the RANSAC refit weighs every inlier alike in 3D, although the depth of
//! a stereo point is known to `σ_Z = Z² σ_d / (f B)` along its ray and to about
//! a pixel's footprint `Z σ_px / f` across it. The pixel residual is where the
//! matcher's noise lives (roughly isotropic, a fraction of a pixel in each
//! image), so least squares there weighs near and far points as the geometry
//! says.
//!
//! Model. A pair is `{ world, cam }`; its observations are the projections of
//! `cam` (which the triangulation reproduces exactly): `u_l = f_x X/Z + c_x`,
//! `u_r = f_x (X − B)/Z + c_x` and the mean row `v = f_y Y/Z + c_y`, the last
//! used in both images (so it carries weight 2, the variance of a mean of two
//! rows). The prediction of `world` under `world_from_left = (R, t)` is
//! `q = Rᵀ (world − t)` projected the same way. Parameters: a world-frame
//! translation `δt` of the camera position and a world-frame rotation vector
//! `φ`, `R ← exp([φ]×) R`, `t ← t + δt`; so `∂q/∂δt = −Rᵀ` and
//! `∂q/∂φ = Rᵀ [world − t]×`. The 6×6 covariance is in the same order and frame
//! (translation in metres, then rotation in radians, both in the world frame):
//! `Σ₀ = s² (JᵀJ)⁻¹` with the a-posteriori pixel variance `s² = cost / (3n − 6)`.
//!
//! Shared errors. `Σ₀` holds only if the pixel errors of different matches are
//! independent. A template peak moved by the content of the template (shadows
//! cast at another time of day, texture and geometry of the map) moves the
//! same way in the left and the right image, and such shifts are correlated
//! across matches, which the pose absorbs and the residuals do not show. The
//! left/right part is observable: `ρ` is the correlation of the left and right
//! column residuals over the inliers, less its `2/√n` noise level under
//! independent errors and clamped to 0..=1. A correlation `c·ρ` between
//! matches makes the variance of the estimate `1 + (n − 1)·c·ρ` times larger
//! (Kish's design effect: it stops shrinking with `n`), so the reported
//! covariance is `Σ = D Σ₀ D` with `D = diag(√κ_t I₃, √κ_r I₃)`,
//! `κ = 1 + (n − 1)·c·ρ`, `c` = [`SHARED_T`] for the translation and
//! [`SHARED_R`] for the rotation block (the cross block scales by
//! `√(κ_t κ_r)`). With independent pixel noise `ρ` is 0 (in about 98 % of
//! cases) and `Σ = Σ₀`. The two constants are fitted on simulated depots
//! (`fsw-docs/eval/covariance.md`).
//!
//! Safeguard. The refined pose replaces the RANSAC pose only if its cost is
//! strictly lower and it moved by at most [`RefineConfig::max_step_m`] and
//! [`RefineConfig::max_step_rad`]; otherwise the RANSAC pose is kept and the
//! covariance is evaluated there.
//!
//! Bounds: one weighted fit (≤ [`JACOBI_MAX_SWEEPS`](super::JACOBI_MAX_SWEEPS)
//! sweeps), then at most `2 + max_iterations` passes over the `n ≤ MAX_CORR`
//! pairs, each a fixed amount of f64 arithmetic, and one 6×6 Cholesky solve per
//! iteration. No allocation: fixed-size nalgebra matrices on the stack. f64
//! through nalgebra with `libm` (no FMA), so every target gives the same bits.

use super::fit::{check_pairs, fit, inverse_variance};
use super::Correspondence;
use crate::config::MAX_REFINE_ITER;
use crate::failure::FailureCode;
use crate::geom::{Pose, StereoRig, Vec3};
use nalgebra::{Matrix3, Matrix6, Quaternion, SMatrix, UnitQuaternion, Vector3, Vector6};

type V3 = Vector3<f64>;
type M3 = Matrix3<f64>;
type V6 = Vector6<f64>;
type M6 = Matrix6<f64>;

/// Default bound on the rotation the refinement may apply, radians (about
/// 1.1°): far beyond what a consistent inlier set moves a RANSAC pose, far
/// below a different solution.
pub const DEFAULT_MAX_STEP_RAD: f32 = 0.02;
/// Predicted points nearer than this (metres) make a pose invalid for the cost.
const MIN_Z_M: f64 = 1.0e-3;
/// Correlation between the pixel errors of two matches per unit of the
/// left/right residual correlation `ρ`, translation block (see the module
/// documentation). Fitted so that 95 % of the true translation errors of the
/// `paper` suite (demo profile, `--seed 1`, 54 trials) fall inside the 95 %
/// ellipsoid (`fsw-docs/eval/covariance.md`).
pub const SHARED_T: f64 = 0.12;
/// As [`SHARED_T`], rotation block.
pub const SHARED_R: f64 = 0.07;
/// Damping start and bounds (Marquardt scaling by the diagonal).
const LAMBDA_START: f64 = 1.0e-4;
const LAMBDA_MIN: f64 = 1.0e-12;
const LAMBDA_MAX: f64 = 1.0e8;

/// Settings of the final refinement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefineConfig {
    /// Levenberg–Marquardt iteration cap, 0..=[`MAX_REFINE_ITER`] (0: no
    /// weighted fit and no iteration; only the covariance of the given pose).
    pub max_iterations: u8,
    /// Largest translation change accepted against the RANSAC pose, metres, > 0.
    pub max_step_m: f32,
    /// Largest rotation change accepted against the RANSAC pose, radians, > 0.
    pub max_step_rad: f32,
}

impl RefineConfig {
    /// `refine_iter` iterations, steps bounded by twice the RANSAC gate
    /// `inlier_m` (a pose change that large moves every near point out of the
    /// gate) and [`DEFAULT_MAX_STEP_RAD`].
    pub fn from_params(p: &crate::config::Params) -> Self {
        Self {
            max_iterations: p.refine_iter,
            max_step_m: 2.0 * p.inlier_m,
            max_step_rad: DEFAULT_MAX_STEP_RAD,
        }
    }

    /// Check the ranges documented on each field.
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`].
    pub fn validate(&self) -> Result<(), FailureCode> {
        let pos = |v: f32| v.is_finite() && v > 0.0;
        if usize::from(self.max_iterations) <= MAX_REFINE_ITER
            && pos(self.max_step_m)
            && pos(self.max_step_rad)
        {
            Ok(())
        } else {
            Err(FailureCode::ConfigParamOutOfRange)
        }
    }
}

/// Work counters of one refinement.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RefineStats {
    /// Levenberg–Marquardt iterations run (≤ the cap).
    pub iterations: u8,
    /// Iterations whose step lowered the cost.
    pub steps_taken: u8,
    /// Inlier pairs that took part.
    pub points: u16,
    /// Pair residual evaluations (each one point in both images).
    pub residuals_evaluated: u32,
    /// The weighted fit had a lower cost than the RANSAC pose and started the iterations.
    pub weighted_start: bool,
    /// The refined pose passed the safeguard and replaced the RANSAC pose.
    pub accepted: bool,
}

/// A 6×6 pose covariance, row-major: translation of the camera position in the
/// world frame (metres), then a world-frame rotation vector (radians), i.e.
/// `R_true = exp([φ]×) R_est`, `t_true = t_est + δt`, `Cov[(δt, φ)]`. From
/// [`refine`]: `D s² (JᵀJ)⁻¹ D`, with the shared-error factors `D` of the
/// module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Covariance {
    /// Row-major entries.
    pub m: [f32; 36],
}

impl Covariance {
    /// Entry `(row, col)`, `0.0` outside 0..6.
    pub fn get(&self, row: usize, col: usize) -> f32 {
        if row < 6 && col < 6 {
            self.m.get(row * 6 + col).copied().unwrap_or(0.0)
        } else {
            0.0
        }
    }

    /// One-sigma translation along world x, y, z, metres.
    pub fn sigma_t_m(&self) -> [f32; 3] {
        core::array::from_fn(|i| libm::sqrtf(self.get(i, i).max(0.0)))
    }

    /// One-sigma rotation about world x, y, z, radians.
    pub fn sigma_r_rad(&self) -> [f32; 3] {
        core::array::from_fn(|i| libm::sqrtf(self.get(i + 3, i + 3).max(0.0)))
    }
}

/// Result of [`refine`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refined {
    /// The final `world_from_left`: refined if accepted, else the given pose.
    pub pose: Pose,
    /// Covariance of `pose`.
    pub covariance: Covariance,
    /// Reprojection cost of the given pose, Σ of squared pixel residuals.
    pub initial_cost_px2: f32,
    /// Reprojection cost of `pose`.
    pub final_cost_px2: f32,
    /// RMS pixel residual of `pose` per observation (`√(cost / 3n)`).
    pub rms_px: f32,
    /// Correlation of the left and right column residuals of `pose` over the
    /// inliers, −1..=1 (0 if either is all zero).
    pub lr_correlation: f32,
    /// Variance factors `(κ_t, κ_r)` ≥ 1 applied to the translation and
    /// rotation blocks of `s² (JᵀJ)⁻¹` for errors shared between matches.
    pub inflation: [f32; 2],
    /// Work counters.
    pub stats: RefineStats,
}

/// Pose in f64 during the iterations.
#[derive(Clone, Copy)]
struct State {
    q: UnitQuaternion<f64>,
    t: V3,
}

impl State {
    fn from_pose(p: &Pose) -> Self {
        let q = p.rotation();
        let tr = p.translation();
        Self {
            q: UnitQuaternion::new_normalize(Quaternion::new(
                f64::from(q.w),
                f64::from(q.i),
                f64::from(q.j),
                f64::from(q.k),
            )),
            t: V3::new(f64::from(tr.x), f64::from(tr.y), f64::from(tr.z)),
        }
    }

    fn to_pose(self) -> Pose {
        let q = self.q.quaternion();
        // Canonical sign (w ≥ 0), as the fit, so equal rotations have equal bits.
        let s = if q.w < 0.0 { -1.0 } else { 1.0 };
        let qf = Quaternion::new(
            (q.w * s) as f32,
            (q.i * s) as f32,
            (q.j * s) as f32,
            (q.k * s) as f32,
        );
        Pose::new(
            UnitQuaternion::new_normalize(qf),
            Vec3::new(self.t.x as f32, self.t.y as f32, self.t.z as f32),
        )
    }

    /// `R ← exp([φ]×) R`, `t ← t + δt`, `x = (δt, φ)`.
    fn step(&self, x: &V6) -> Self {
        let phi = V3::new(x[3], x[4], x[5]);
        Self {
            q: UnitQuaternion::from_scaled_axis(phi) * self.q,
            t: self.t + V3::new(x[0], x[1], x[2]),
        }
    }
}

/// Camera constants in f64.
#[derive(Clone, Copy)]
struct Cam {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    b: f64,
}

impl Cam {
    fn new(rig: &StereoRig) -> Self {
        Self {
            fx: f64::from(rig.cam.fx),
            fy: f64::from(rig.cam.fy),
            cx: f64::from(rig.cam.cx),
            cy: f64::from(rig.cam.cy),
            b: f64::from(rig.baseline_m),
        }
    }

    /// `(u_l, v, u_r)` of a left-camera point; `None` behind or at the camera.
    fn project(&self, p: &V3) -> Option<[f64; 3]> {
        if p.z.is_nan() || p.z < MIN_Z_M {
            return None;
        }
        let iz = 1.0 / p.z;
        Some([
            self.fx * p.x * iz + self.cx,
            self.fy * p.y * iz + self.cy,
            self.fx * (p.x - self.b) * iz + self.cx,
        ])
    }
}

fn v64(v: &Vec3) -> V3 {
    V3::new(f64::from(v.x), f64::from(v.y), f64::from(v.z))
}

fn skew(a: &V3) -> M3 {
    M3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

/// Cost and, optionally, normal equations `JᵀJ`, `Jᵀr` and the left/right
/// column residual moments `(Σ r_l², Σ r_r², Σ r_l r_r)` at `s`.
#[derive(Clone, Copy)]
struct Eval {
    cost: f64,
    jtj: M6,
    jtr: V6,
    lr: [f64; 3],
}

/// One pass over the inliers. `None` if a point is behind a camera, an input
/// does not project, or the cost is not finite.
fn evaluate(
    pairs: &[Correspondence],
    mask: &[bool],
    cam: &Cam,
    s: &State,
    normal: bool,
    stats: &mut RefineStats,
) -> Option<Eval> {
    let rt = s.q.to_rotation_matrix().into_inner().transpose();
    let mut e = Eval {
        cost: 0.0,
        jtj: M6::zeros(),
        jtr: V6::zeros(),
        lr: [0.0; 3],
    };
    for (p, _) in pairs.iter().zip(mask.iter()).filter(|(_, m)| **m) {
        stats.residuals_evaluated = stats.residuals_evaluated.saturating_add(1);
        let obs = cam.project(&v64(&p.cam))?;
        let d = v64(&p.world) - s.t;
        let q = rt * d;
        let pred = cam.project(&q)?;
        // Residuals: u_l, v (left), u_r, v (right); the two rows coincide.
        let r = [
            pred[0] - obs[0],
            pred[1] - obs[1],
            pred[2] - obs[2],
            pred[1] - obs[1],
        ];
        e.cost += r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3];
        if normal {
            let iz = 1.0 / q.z;
            let iz2 = iz * iz;
            let dproj = SMatrix::<f64, 4, 3>::new(
                cam.fx * iz,
                0.0,
                -cam.fx * q.x * iz2,
                0.0,
                cam.fy * iz,
                -cam.fy * q.y * iz2,
                cam.fx * iz,
                0.0,
                -cam.fx * (q.x - cam.b) * iz2,
                0.0,
                cam.fy * iz,
                -cam.fy * q.y * iz2,
            );
            let mut dq = SMatrix::<f64, 3, 6>::zeros();
            dq.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-rt));
            dq.fixed_view_mut::<3, 3>(0, 3).copy_from(&(rt * skew(&d)));
            let j = dproj * dq;
            let rv = nalgebra::Vector4::new(r[0], r[1], r[2], r[3]);
            e.jtj += j.transpose() * j;
            e.jtr += j.transpose() * rv;
            e.lr[0] += r[0] * r[0];
            e.lr[1] += r[2] * r[2];
            e.lr[2] += r[0] * r[2];
        }
    }
    e.cost.is_finite().then_some(e)
}

/// Correlation of the left and right column residuals, `0.0` when either
/// sum of squares is zero or the ratio is not finite.
fn lr_correlation(e: &Eval) -> f64 {
    let den = libm::sqrt(e.lr[0] * e.lr[1]);
    let c = e.lr[2] / den;
    if den > 0.0 && c.is_finite() {
        c.clamp(-1.0, 1.0)
    } else {
        0.0
    }
}

/// Variance factors `(κ_t, κ_r) = 1 + (n − 1)·c·ρ` for a left/right residual
/// correlation `corr` over `n` inliers, with `ρ = clamp(corr − 2/√n, 0, 1)`.
fn inflation(corr: f64, n: u16) -> (f64, f64) {
    let nf = f64::from(n);
    let rho = if nf > 0.0 {
        (corr - 2.0 / libm::sqrt(nf)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let m = (nf - 1.0).max(0.0) * rho;
    (1.0 + SHARED_T * m, 1.0 + SHARED_R * m)
}

/// `Σ = D s² (JᵀJ)⁻¹ D` with `s² = cost / (3n − 6)` and
/// `D = diag(√κ_t I₃, √κ_r I₃)` from [`inflation`]; also `(κ_t, κ_r)`.
fn covariance(e: &Eval, n: u16) -> Option<(Covariance, [f32; 2])> {
    let dof = 3.0 * f64::from(n) - 6.0;
    if dof <= 0.0 {
        return None;
    }
    let s2 = e.cost / dof;
    let (kt, kr) = inflation(lr_correlation(e), n);
    let d = V6::new(
        libm::sqrt(kt),
        libm::sqrt(kt),
        libm::sqrt(kt),
        libm::sqrt(kr),
        libm::sqrt(kr),
        libm::sqrt(kr),
    );
    let inv = e.jtj.cholesky()?.inverse() * s2;
    let dm = M6::from_diagonal(&d);
    let scaled = dm * inv * dm;
    let mut m = [0.0f32; 36];
    // nalgebra iterates column-major: the transpose's order is the row-major order.
    for (v, x) in m.iter_mut().zip(scaled.transpose().iter()) {
        *v = *x as f32;
    }
    m.iter()
        .all(|v| v.is_finite())
        .then_some((Covariance { m }, [kt as f32, kr as f32]))
}

/// (a) The depth-weighted fit of the inliers, as the start of the descent
/// when its cost is lower than that of `(cur, e)`; `(cur, e)` otherwise.
fn weighted_start(
    pairs: &[Correspondence],
    mask: &[bool],
    cam: &Cam,
    (cur, e): (State, Eval),
    stats: &mut RefineStats,
) -> (State, Eval) {
    let weighted = fit(pairs, |i, p| match mask.get(i) {
        Some(true) => inverse_variance(p),
        _ => 0.0,
    });
    if let Ok((wp, _)) = weighted {
        let ws = State::from_pose(&wp);
        if let Some(we) = evaluate(pairs, mask, cam, &ws, true, stats) {
            if we.cost < e.cost {
                stats.weighted_start = true;
                return (ws, we);
            }
        }
    }
    (cur, e)
}

/// (b) Levenberg–Marquardt with Marquardt's diagonal scaling from `(cur, e)`,
/// at most `max_iterations` iterations; returns the last accepted state.
fn descend(
    pairs: &[Correspondence],
    mask: &[bool],
    cam: &Cam,
    (mut cur, mut e): (State, Eval),
    max_iterations: u8,
    stats: &mut RefineStats,
) -> (State, Eval) {
    let mut lambda = LAMBDA_START;
    for _ in 0..max_iterations {
        stats.iterations = stats.iterations.saturating_add(1);
        let damp = e.jtj.diagonal().map(|d| lambda * d.max(f64::MIN_POSITIVE));
        let a = e.jtj + M6::from_diagonal(&damp);
        let Some(ch) = a.cholesky() else {
            lambda *= 10.0;
            if lambda > LAMBDA_MAX {
                break;
            }
            continue;
        };
        let x = -ch.solve(&e.jtr);
        if !x.iter().all(|v| v.is_finite()) {
            break;
        }
        let next = cur.step(&x);
        match evaluate(pairs, mask, cam, &next, true, stats) {
            Some(ne) if ne.cost < e.cost => {
                stats.steps_taken = stats.steps_taken.saturating_add(1);
                let gain = e.cost - ne.cost;
                cur = next;
                e = ne;
                lambda = (lambda * 0.1).max(LAMBDA_MIN);
                // Converged: the cost no longer changes at f64 precision.
                if gain <= 1.0e-12 * e.cost {
                    break;
                }
            }
            _ => {
                lambda *= 10.0;
                if lambda > LAMBDA_MAX {
                    break;
                }
            }
        }
    }
    (cur, e)
}

/// Refine `pose` (`world_from_left`, from RANSAC) on the pairs flagged in
/// `inlier_mask` and report its covariance. The result is the refined pose
/// only if it passes the safeguard (lower cost, bounded change); otherwise
/// `pose` itself with its covariance.
///
/// # Errors
/// * [`FailureCode::ConfigParamOutOfRange`]: bad `cfg`, more than
///   [`MAX_CORR`](crate::config::MAX_CORR) pairs, or `inlier_mask` shorter than `pairs`.
/// * [`FailureCode::PoseTooFewPoints`]: fewer than 3 inliers.
/// * [`FailureCode::PoseNonFinite`]: a non-finite pair, or `pose` puts an
///   inlier behind the camera.
/// * [`FailureCode::PoseDegenerate`]: the normal equations are singular (the
///   covariance does not exist).
pub fn refine(
    pairs: &[Correspondence],
    inlier_mask: &[bool],
    rig: &StereoRig,
    pose: &Pose,
    cfg: &RefineConfig,
) -> Result<Refined, FailureCode> {
    cfg.validate()?;
    let Some(mask) = inlier_mask.get(..pairs.len()) else {
        return Err(FailureCode::ConfigParamOutOfRange);
    };
    check_pairs(pairs)?;
    // A fold rather than `filter().count()`, whose sum is overflow-checked.
    let n = mask
        .iter()
        .fold(0usize, |n, &m| n.wrapping_add(usize::from(m)));
    if n < 3 {
        return Err(FailureCode::PoseTooFewPoints);
    }
    let cam = Cam::new(rig);
    let mut stats = RefineStats {
        points: u16::try_from(n).unwrap_or(u16::MAX),
        ..RefineStats::default()
    };
    let start = State::from_pose(pose);
    let e0 =
        evaluate(pairs, mask, &cam, &start, true, &mut stats).ok_or(FailureCode::PoseNonFinite)?;
    let mut best = (start, e0.cost);
    let mut cur = start;
    let mut e = e0;
    if cfg.max_iterations > 0 {
        (cur, e) = weighted_start(pairs, mask, &cam, (cur, e), &mut stats);
        (cur, e) = descend(pairs, mask, &cam, (cur, e), cfg.max_iterations, &mut stats);
        // Safeguard: lower cost and a bounded change against the RANSAC pose.
        let dt = (cur.t - start.t).norm();
        let dr = cur.q.angle_to(&start.q);
        let bounded = dt <= f64::from(cfg.max_step_m) && dr <= f64::from(cfg.max_step_rad);
        if e.cost < e0.cost && bounded {
            stats.accepted = true;
            best = (cur, e.cost);
        }
    }
    let (fin, cost) = best;
    let final_eval = if stats.accepted { e } else { e0 };
    let (cov, inflation) =
        covariance(&final_eval, stats.points).ok_or(FailureCode::PoseDegenerate)?;
    let pose_out = if stats.accepted { fin.to_pose() } else { *pose };
    if !pose_out.is_finite() {
        return Err(FailureCode::PoseNonFinite);
    }
    Ok(Refined {
        pose: pose_out,
        covariance: cov,
        initial_cost_px2: e0.cost as f32,
        final_cost_px2: cost as f32,
        rms_px: libm::sqrt(cost / (3.0 * n as f64)) as f32,
        lr_correlation: lr_correlation(&final_eval) as f32,
        inflation,
        stats,
    })
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::geom::Camera;
    use crate::rng::Rng;
    use crate::stereo::triangulate;
    use crate::testkit::random_pose;
    use std::vec::Vec;

    const SIGMA_PX: f32 = 0.3;

    fn rig() -> StereoRig {
        StereoRig::new(Camera::from_hfov(1368, 912, 77.0).unwrap(), 0.4).unwrap()
    }

    /// Steps bounded far beyond the unweighted fit's errors on these scenes
    /// (the safeguard has its own test).
    fn cfg(iter: u8) -> RefineConfig {
        RefineConfig {
            max_iterations: iter,
            max_step_m: 0.5,
            max_step_rad: DEFAULT_MAX_STEP_RAD,
        }
    }

    /// `n` map points 2–15 m ahead under `truth`, observed in both images with
    /// independent pixel noise `sigma_px` on every coordinate and triangulated
    /// as the pipeline does (`σ_d = √2 σ_px`).
    fn stereo_pairs(rng: &mut Rng, truth: &Pose, n: usize, sigma_px: f32) -> Vec<Correspondence> {
        stereo_pairs_shared(rng, truth, n, sigma_px, 0.0, [0.0; 2])
    }

    /// As [`stereo_pairs`], plus errors a template shift makes: a shift of
    /// each match drawn with `match_px` per axis and applied to its left and
    /// right observation alike, and `common` added to every match.
    fn stereo_pairs_shared(
        rng: &mut Rng,
        truth: &Pose,
        n: usize,
        sigma_px: f32,
        match_px: f32,
        common: [f32; 2],
    ) -> Vec<Correspondence> {
        let rig = rig();
        let mut out = Vec::new();
        while out.len() < n {
            let p = Vec3::new(
                rng.uniform(-4.0, 4.0),
                rng.uniform(-0.5, 1.5),
                rng.uniform(2.0, 15.0),
            );
            let Some((l, r)) = rig.project_stereo(&p) else {
                continue;
            };
            if !(rig.cam.contains(l[0], l[1], 0.0) && rig.cam.contains(r[0], r[1], 0.0)) {
                continue;
            }
            let shift = if match_px > 0.0 {
                [
                    common[0] + match_px * rng.normal(),
                    common[1] + match_px * rng.normal(),
                ]
            } else {
                common
            };
            let mut noisy = |x: [f32; 2]| {
                [
                    x[0] + shift[0] + sigma_px * rng.normal(),
                    x[1] + shift[1] + sigma_px * rng.normal(),
                ]
            };
            let (l, r) = (noisy(l), noisy(r));
            let Ok(pt) = triangulate(&rig, l, r, 8.0, sigma_px * core::f32::consts::SQRT_2, 0.5)
            else {
                continue;
            };
            out.push(Correspondence {
                world: truth.transform_point(&p),
                cam: pt.p_cam,
                sigma_m: pt.sigma_z_m,
                variant: crate::pose::VARIANT_UNKNOWN,
                mask_index: crate::pose::MASK_INDEX_UNKNOWN,
            });
        }
        out
    }

    fn v(p: &Vec3) -> nalgebra::Vector3<f64> {
        v64(p)
    }

    /// World-frame errors `(t_est − t_true, φ)` with `R_true = exp([φ]×) R_est`.
    fn error_vec(est: &Pose, truth: &Pose) -> (nalgebra::Vector3<f64>, nalgebra::Vector3<f64>) {
        let se = State::from_pose(est);
        let st = State::from_pose(truth);
        ((se.t - st.t), (st.q * se.q.inverse()).scaled_axis())
    }

    /// The reference: the same residuals in plain f64, a numeric (central
    /// difference) Jacobian, and undamped Gauss–Newton solved by LU on the
    /// dense normal equations, iterated to convergence.
    fn dense_reference(pairs: &[Correspondence], rig: &StereoRig, start: &Pose) -> (State, M6) {
        let cam = Cam::new(rig);
        let residuals = |s: &State| -> Vec<f64> {
            let rt = s.q.to_rotation_matrix().into_inner().transpose();
            let mut r = Vec::new();
            for p in pairs {
                let o = cam.project(&v(&p.cam)).unwrap();
                let q = cam.project(&(rt * (v(&p.world) - s.t))).unwrap();
                r.extend([q[0] - o[0], q[1] - o[1], q[2] - o[2], q[1] - o[1]]);
            }
            r
        };
        let mut s = State::from_pose(start);
        let mut jtj = M6::zeros();
        for _ in 0..30 {
            let r0 = residuals(&s);
            let mut cols: Vec<Vec<f64>> = Vec::new();
            for k in 0..6 {
                let h = if k < 3 { 1e-6 } else { 1e-8 };
                let mut x = V6::zeros();
                x[k] = h;
                let rp = residuals(&s.step(&x));
                x[k] = -h;
                let rm = residuals(&s.step(&x));
                cols.push(
                    rp.iter()
                        .zip(&rm)
                        .map(|(a, b)| (a - b) / (2.0 * h))
                        .collect(),
                );
            }
            let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
            jtj = M6::from_fn(|i, j| dot(&cols[i], &cols[j]));
            let jtr = V6::from_fn(|i, _| dot(&cols[i], &r0));
            let dx = -jtj.lu().solve(&jtr).unwrap();
            s = s.step(&dx);
            if dx.norm() < 1e-13 {
                break;
            }
        }
        let r = residuals(&s);
        let dof = r.len() as f64 * 0.75 - 6.0;
        let cost: f64 = r.iter().map(|x| x * x).sum();
        (s, jtj.try_inverse().unwrap() * (cost / dof))
    }

    /// Verifies: VTSM-POSE-015
    #[test]
    fn agrees_with_dense_f64_reference_solve() {
        let rig = rig();
        let mut rng = Rng::new(21);
        for case in 0..20 {
            let truth = random_pose(&mut rng);
            let pairs = stereo_pairs(&mut rng, &truth, 20 + case * 4, SIGMA_PX);
            let mask = [true; 100];
            let start = umeyama_start(&pairs);
            let got = refine(&pairs, &mask, &rig, &start, &cfg(20)).unwrap();
            assert!(got.stats.accepted, "case {case}: {:?}", got.stats);
            let (rs, rcov) = dense_reference(&pairs, &rig, &start);
            let (dt, _) = error_vec(&got.pose, &rs.to_pose());
            let dr = State::from_pose(&got.pose).q.angle_to(&rs.q);
            // f32 output: |t| ≤ ~9 m carries ~1e-6 m of rounding.
            assert!(
                dt.norm() < 5e-6 && dr < 1e-6,
                "case {case}: {} m {dr} rad",
                dt.norm()
            );
            // `s² (JᵀJ)⁻¹` times the shared-error factor of its block.
            for i in 0..6 {
                let k = f64::from(got.inflation[i / 3]);
                let (a, b) = (f64::from(got.covariance.get(i, i)), k * rcov[(i, i)]);
                assert!(
                    (a / b - 1.0).abs() < 1e-3,
                    "case {case} diag {i}: {a:e} vs {b:e}"
                );
            }
        }
    }

    fn umeyama_start(pairs: &[Correspondence]) -> Pose {
        super::super::umeyama(pairs).unwrap()
    }

    /// Verifies: VTSM-POSE-015
    #[test]
    fn refined_pose_beats_unweighted_umeyama_on_noisy_stereo() {
        let rig = rig();
        let mut rng = Rng::new(22);
        let trials = 300;
        let (mut ut, mut ur, mut rt, mut rr) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let mut accepted = 0;
        for _ in 0..trials {
            let truth = random_pose(&mut rng);
            let pairs = stereo_pairs(&mut rng, &truth, 60, SIGMA_PX);
            let mask = [true; 60];
            let start = umeyama_start(&pairs);
            let got = refine(&pairs, &mask, &rig, &start, &cfg(10)).unwrap();
            accepted += usize::from(got.stats.accepted);
            assert!(got.stats.iterations <= 10);
            assert!(got.final_cost_px2 <= got.initial_cost_px2);
            let (a, b) = start.error_to(&truth);
            let (c, d) = got.pose.error_to(&truth);
            ut += f64::from(a);
            ur += f64::from(b);
            rt += f64::from(c);
            rr += f64::from(d);
        }
        let n = trials as f64;
        std::println!(
            "mean error over {trials}: umeyama {:.2} mm {:.4}°, refined {:.2} mm {:.4}°; accepted {accepted}",
            ut / n * 1e3,
            (ur / n).to_degrees(),
            rt / n * 1e3,
            (rr / n).to_degrees()
        );
        assert!(accepted == trials, "{accepted}");
        assert!(rt < 0.7 * ut, "translation {rt} vs {ut}");
        assert!(rr < 0.9 * ur, "rotation {rr} vs {ur}");
    }

    /// Verifies: VTSM-POSE-016
    #[test]
    fn covariance_bounds_hold_at_95_percent_on_synthetic_noise() {
        let rig = rig();
        let mut rng = Rng::new(23);
        let trials = 1000;
        let (mut in_t, mut in_r, mut inflated) = (0, 0, 0);
        for _ in 0..trials {
            let truth = random_pose(&mut rng);
            let pairs = stereo_pairs(&mut rng, &truth, 60, SIGMA_PX);
            let mask = [true; 60];
            let got = refine(&pairs, &mask, &rig, &umeyama_start(&pairs), &cfg(10)).unwrap();
            let (et, er) = error_vec(&got.pose, &truth);
            let block = |o: usize| {
                nalgebra::Matrix3::<f64>::from_fn(|i, j| {
                    f64::from(got.covariance.get(o + i, o + j))
                })
            };
            let d2 = |e: nalgebra::Vector3<f64>, c: nalgebra::Matrix3<f64>| {
                (e.transpose() * c.try_inverse().unwrap() * e)[(0, 0)]
            };
            in_t += usize::from(d2(et, block(0)) <= 7.81);
            in_r += usize::from(d2(er, block(3)) <= 7.81);
            inflated += usize::from(got.inflation != [1.0, 1.0]);
        }
        let (ft, fr) = (in_t as f64 / trials as f64, in_r as f64 / trials as f64);
        std::println!(
            "within chi2(3, 0.95): translation {ft:.3}, rotation {fr:.3}; shared-error factor > 1 in {inflated} of {trials}"
        );
        // Independent noise: the left/right correlation stays under its 2/√n
        // noise level (about 98 % of the time) and the covariance is s² (JᵀJ)⁻¹.
        assert!(inflated <= trials / 20, "{inflated}");
        // Binomial σ at 95 % over 1000 trials ≈ 0.7 %.
        assert!((0.92..=0.98).contains(&ft), "{ft}");
        assert!((0.92..=0.98).contains(&fr), "{fr}");
    }

    /// Verifies: VTSM-POSE-016
    #[test]
    fn errors_shared_by_left_and_right_inflate_the_covariance() {
        let rig = rig();
        let mut rng = Rng::new(26);
        let trials = 300;
        let n = 80;
        let (mut in0, mut in1) = ([0usize; 2], [0usize; 2]);
        for case in 0..trials {
            let truth = random_pose(&mut rng);
            // Each match shifted alike in both images (0.6 px per axis), a
            // shift shared by all matches of the scene (0.25 px), 0.1 px of
            // independent noise.
            let common = [0.25 * rng.normal(), 0.25 * rng.normal()];
            let pairs = stereo_pairs_shared(&mut rng, &truth, n, 0.1, 0.6, common);
            let mask = [true; 80];
            let start = umeyama_start(&pairs);
            let got = refine(&pairs, &mask, &rig, &start, &cfg(10)).unwrap();
            // The left and right residuals move together; the factors follow
            // from their correlation and n alone.
            let corr = f64::from(got.lr_correlation);
            assert!(corr > 0.8, "case {case}: {corr}");
            let rho = (corr - 2.0 / libm::sqrt(n as f64)).clamp(0.0, 1.0);
            let want = [
                1.0 + SHARED_T * (n as f64 - 1.0) * rho,
                1.0 + SHARED_R * (n as f64 - 1.0) * rho,
            ];
            for (k, w) in got.inflation.iter().zip(want) {
                assert!((f64::from(*k) / w - 1.0).abs() < 1e-6, "{k} vs {w}");
            }
            // Σ = D Σ₀ D against the dense reference: blocks scaled by κ_t,
            // κ_r and the cross block by √(κ_t κ_r).
            let (_, rcov) = dense_reference(&pairs, &rig, &start);
            if case < 10 {
                for i in 0..6 {
                    for j in 0..6 {
                        let k = libm::sqrt(want[i / 3] * want[j / 3]);
                        let (a, b) = (f64::from(got.covariance.get(i, j)), k * rcov[(i, j)]);
                        let scale = libm::sqrt(k * k * rcov[(i, i)] * rcov[(j, j)]);
                        assert!((a - b).abs() < 1e-3 * scale, "({i}, {j}): {a:e} vs {b:e}");
                    }
                }
            }
            let (et, er) = error_vec(&got.pose, &truth);
            let d2 = |e: nalgebra::Vector3<f64>, o: usize, k: f64| {
                let c = nalgebra::Matrix3::<f64>::from_fn(|i, j| {
                    f64::from(got.covariance.get(o + i, o + j))
                }) / k;
                (e.transpose() * c.try_inverse().unwrap() * e)[(0, 0)]
            };
            let k = [f64::from(got.inflation[0]), f64::from(got.inflation[1])];
            for (b, (e, o)) in [(et, 0), (er, 3)].into_iter().enumerate() {
                in0[b] += usize::from(d2(e, o, k[b]) <= 7.81);
                in1[b] += usize::from(d2(e, o, 1.0) <= 7.81);
            }
        }
        let f = |x: usize| x as f64 / trials as f64;
        std::println!(
            "within chi2(3, 0.95), s² (JᵀJ)⁻¹: t {:.3} r {:.3}; reported: t {:.3} r {:.3}",
            f(in0[0]),
            f(in0[1]),
            f(in1[0]),
            f(in1[1])
        );
        // Without the factor the shared shifts fall far outside; with it
        // most of them are inside.
        for b in 0..2 {
            assert!(f(in0[b]) < 0.85 && f(in1[b]) > 0.9, "{in0:?} {in1:?}");
        }
    }

    /// Verifies: VTSM-POSE-017
    #[test]
    fn safeguard_keeps_the_ransac_pose_and_bounds_the_work() {
        let rig = rig();
        let mut rng = Rng::new(24);
        let truth = random_pose(&mut rng);
        let pairs = stereo_pairs(&mut rng, &truth, 50, SIGMA_PX);
        let mask = [true; 50];
        // A RANSAC pose 8 mm off: the refinement moves it by about that much.
        let start = Pose::new(
            truth.rotation(),
            truth.translation() + Vec3::new(0.008, 0.0, 0.0),
        );
        let free = refine(&pairs, &mask, &rig, &start, &cfg(10)).unwrap();
        assert!(free.stats.accepted && free.final_cost_px2 < free.initial_cost_px2);
        assert!(free.pose.error_to(&truth).0 < start.error_to(&truth).0);
        // Same data with a 1 mm step bound: the RANSAC pose is kept, bit for bit,
        // with its own covariance and cost.
        let tight = RefineConfig {
            max_step_m: 0.001,
            ..cfg(10)
        };
        let kept = refine(&pairs, &mask, &rig, &start, &tight).unwrap();
        assert!(!kept.stats.accepted);
        assert_eq!(kept.pose, start);
        assert_eq!(kept.final_cost_px2, kept.initial_cost_px2);
        // No iterations: no fit, the given pose and its covariance.
        let none = refine(&pairs, &mask, &rig, &start, &cfg(0)).unwrap();
        assert_eq!(none.pose, start);
        assert_eq!(none.covariance, kept.covariance);
        assert_eq!(none.stats.iterations, 0);
        assert_eq!(u32::from(none.stats.points), none.stats.residuals_evaluated);
        // Iterations and pair evaluations stay under the cap: ≤ (2 + cap) passes.
        for cap in 1..=MAX_REFINE_ITER as u8 {
            let r = refine(&pairs, &mask, &rig, &start, &cfg(cap)).unwrap();
            assert!(r.stats.iterations <= cap && r.stats.steps_taken <= r.stats.iterations);
            assert!(r.stats.residuals_evaluated <= (2 + u32::from(cap)) * 50);
            // Same inputs, same bits.
            assert_eq!(r, refine(&pairs, &mask, &rig, &start, &cfg(cap)).unwrap());
        }
        // Only masked pairs take part: a gross outlier outside the mask changes nothing.
        let mut with_outlier = pairs.clone();
        with_outlier[7].world += Vec3::new(1.0, 0.0, 0.0);
        let mut m2 = mask;
        m2[7] = false;
        let a = refine(&with_outlier, &m2, &rig, &start, &cfg(10)).unwrap();
        let mut m3 = m2;
        m3[7] = true;
        let b = refine(&with_outlier, &m3, &rig, &start, &cfg(10)).unwrap();
        assert_eq!(a.stats.points, 49);
        assert!(
            a.rms_px < 0.5 && b.rms_px > 4.0 * a.rms_px,
            "{} {}",
            a.rms_px,
            b.rms_px
        );
    }

    /// Verifies: VTSM-POSE-017
    #[test]
    fn refine_rejects_bad_inputs_with_codes() {
        let rig = rig();
        let mut rng = Rng::new(25);
        let truth = random_pose(&mut rng);
        let pairs = stereo_pairs(&mut rng, &truth, 10, SIGMA_PX);
        let mask = [true; 10];
        let mut two = [false; 10];
        two[0] = true;
        two[1] = true;
        let c = cfg(5);
        assert_eq!(
            refine(&pairs, &two, &rig, &truth, &c).err(),
            Some(FailureCode::PoseTooFewPoints)
        );
        assert_eq!(
            refine(&pairs, &mask[..9], &rig, &truth, &c).err(),
            Some(FailureCode::ConfigParamOutOfRange)
        );
        for bad in [
            cfg(MAX_REFINE_ITER as u8 + 1),
            RefineConfig {
                max_step_m: 0.0,
                ..c
            },
            RefineConfig {
                max_step_rad: f32::NAN,
                ..c
            },
        ] {
            assert_eq!(
                refine(&pairs, &mask, &rig, &truth, &bad).err(),
                Some(FailureCode::ConfigParamOutOfRange)
            );
        }
        let mut nan = pairs.clone();
        nan[2].cam.x = f32::NAN;
        assert_eq!(
            refine(&nan, &mask, &rig, &truth, &c).err(),
            Some(FailureCode::PoseNonFinite)
        );
        // A pose that puts the points behind the camera.
        let flipped = truth.compose(&Pose::new(
            UnitQuaternion::from_scaled_axis(Vec3::new(0.0, core::f32::consts::PI, 0.0)),
            Vec3::zeros(),
        ));
        assert_eq!(
            refine(&pairs, &mask, &rig, &flipped, &c).err(),
            Some(FailureCode::PoseNonFinite)
        );
    }
}
