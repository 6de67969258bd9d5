//! `GetTransform` (paper §III-E): the rigid transform between map points and
//! camera points, by a closed-form least-squares fit inside a bounded RANSAC.
//!
//! Inputs: [`Correspondence`]s `{ world, cam, sigma_m }` (at most
//! [`MAX_CORR`]); for RANSAC a [`RansacConfig`] and the core [`Rng`].
//! Outputs: `world_from_cam` as a [`Pose`] (`world = R cam + t`), and for RANSAC
//! an [`Estimate`] with inlier count, RMS residual, work counters and up to
//! [`MAX_POSE_CANDIDATES`] distinct pose candidates for `Distribute`.
//!
//! * Fit ([`umeyama`]): Umeyama's rigid alignment without scale, solved in the
//!   closed form of Horn (1987): the rotation is the unit quaternion that is the
//!   dominant eigenvector of a symmetric 4×4 matrix built from the cross-covariance
//!   of the centred point sets. A unit quaternion is always a proper rotation
//!   (det = +1), so no reflection fix-up is needed. The 4×4 eigenproblem is solved
//!   by cyclic Jacobi rotations capped at [`JACOBI_MAX_SWEEPS`] sweeps of six
//!   rotations each. Points are centred on their centroids before the
//!   cross-covariance is accumulated (f32 precision).
//! * Degeneracy: for the scatter matrix `S` of each centred set, coincident points
//!   have a tiny trace (RMS spread below [`MIN_SPREAD_M`]) and collinear points a
//!   tiny second invariant `m₂ = λ₁λ₂ + λ₁λ₃ + λ₂λ₃` relative to `tr(S)²`
//!   (below [`MIN_PLANARITY`]); since `λ₁λ₂ ≤ m₂ ≤ 3λ₁λ₂` and `tr/3 ≤ λ₁ ≤ tr`,
//!   this bounds `λ₂/λ₁` in closed form, without an eigen-solve.
//! * RANSAC ([`ransac`], resumable as [`Ransac`]): minimal samples of three
//!   distinct pairs drawn with exactly three PRNG draws; a rigid-distance check
//!   and the degeneracy test per sample; an inlier gate in metres, optionally
//!   widened per pair by its depth uncertainty; a hard cap
//!   `min(cfg.iterations, MAX_RANSAC_ITER)`; early exit once
//!   `N = log(1 − p) / log(1 − w³)` samples have been drawn; each new best
//!   hypothesis is refitted on its own inliers (local optimisation); a final
//!   refit on all inliers with recount (at most [`REFIT_ROUNDS`] rounds).
//!
//! Bounds per RANSAC iteration: 3 PRNG draws, one 3-point fit (≤ 16 Jacobi
//! sweeps), `n ≤ MAX_CORR` residuals, ≤ `MAX_POSE_CANDIDATES` candidate
//! comparisons; plus at most `n` local refits per search (each one fit and
//! `3n` residuals), since each needs a strictly larger inlier count. No allocation; f32 through nalgebra and libm, no FMA, so the same
//! seed gives the same bits on every target.

use crate::config::{Params, MAX_CORR, MAX_POSE_CANDIDATES, MAX_RANSAC_ITER};
use crate::failure::FailureCode;
use crate::geom::{Pose, Vec3};
use crate::rng::Rng;
use nalgebra::{Matrix3, Quaternion, UnitQuaternion};

/// Cap on cyclic Jacobi sweeps for the 4×4 eigenproblem. Jacobi converges
/// quadratically; in f32 a 4×4 matrix is diagonal to rounding after 4–6 sweeps.
pub const JACOBI_MAX_SWEEPS: u32 = 16;
/// Point sets whose weighted RMS spread about their centroid is below this
/// (metres) are coincident: the rotation is not determined.
pub const MIN_SPREAD_M: f32 = 1.0e-3;
/// Point sets with `m₂(S) < MIN_PLANARITY · tr(S)²` are collinear
/// (`λ₂/λ₁ ≲ 1e-5`, a width/length ratio below about 0.3–1 %).
pub const MIN_PLANARITY: f32 = 1.0e-5;
/// Default RANSAC confidence `p` of the early-exit rule.
pub const DEFAULT_CONFIDENCE: f32 = 0.999;
/// With `scale_by_sigma`, a pair's gate is `√(inlier_m² + (SIGMA_GATE·σ)²)`.
pub const SIGMA_GATE: f32 = 3.0;
/// Refit-and-recount rounds after the RANSAC search.
pub const REFIT_ROUNDS: u32 = 3;
/// Floor on `sigma_m` when weighting by `1/σ²`, metres.
pub const MIN_SIGMA_M: f32 = 1.0e-4;

/// One map-to-camera point correspondence.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Correspondence {
    /// Map point, world frame, metres.
    pub world: Vec3,
    /// The same point triangulated in the left camera frame, metres.
    pub cam: Vec3,
    /// One-sigma uncertainty of `cam` (the stereo depth sigma), metres, ≥ 0.
    pub sigma_m: f32,
}

impl Correspondence {
    fn is_finite(&self) -> bool {
        self.world
            .iter()
            .chain(self.cam.iter())
            .all(|c| c.is_finite())
            && self.sigma_m.is_finite()
            && self.sigma_m >= 0.0
    }
}

// ---- closed-form fit ------------------------------------------------------

/// Work done by one fit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FitStats {
    /// Pairs that took part (non-zero weight).
    pub points: u16,
    /// Jacobi sweeps used (≤ [`JACOBI_MAX_SWEEPS`]).
    pub jacobi_sweeps: u32,
}

/// Trace and second invariant of a symmetric 3×3 scatter matrix.
fn scatter_invariants(s: &Matrix3<f32>) -> (f32, f32) {
    let (a, b, c) = (s.m11, s.m22, s.m33);
    let tr = a + b + c;
    let m2 = (a * b - s.m12 * s.m21) + (a * c - s.m13 * s.m31) + (b * c - s.m23 * s.m32);
    (tr, m2)
}

fn degenerate(s: &Matrix3<f32>, weight_sum: f32) -> bool {
    let (tr, m2) = scatter_invariants(s);
    // Written so that NaN counts as degenerate.
    let coincident = tr.is_nan() || tr < MIN_SPREAD_M * MIN_SPREAD_M * weight_sum;
    let collinear = m2.is_nan() || m2 < MIN_PLANARITY * tr * tr;
    coincident || collinear
}

const JACOBI_PAIRS: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

/// Cyclic Jacobi eigen-decomposition of a symmetric 4×4 matrix. Returns the
/// eigenvector (column of `V`) of the largest eigenvalue and the sweeps used.
// Indexing: `p`, `q` come from JACOBI_PAIRS (all < 4) and `k`, `i`, `j` range
// over 0..4, so every index into the [[f32; 4]; 4] arrays is in bounds.
#[allow(clippy::indexing_slicing)]
fn jacobi4_dominant(mut a: [[f32; 4]; 4]) -> ([f32; 4], u32) {
    let mut v = [[0.0f32; 4]; 4];
    for (i, row) in v.iter_mut().enumerate() {
        if let Some(x) = row.get_mut(i) {
            *x = 1.0;
        }
    }
    let mut sweeps = 0;
    while sweeps < JACOBI_MAX_SWEEPS {
        let mut off = 0.0f32;
        let mut total = 0.0f32;
        for (i, row) in a.iter().enumerate() {
            for (j, x) in row.iter().enumerate() {
                let e = x * x;
                total += e;
                if i != j {
                    off += e;
                }
            }
        }
        // Off-diagonal mass at the rounding level of the whole matrix: done.
        if off <= 1.0e-14 * total {
            break;
        }
        sweeps += 1;
        for (p, q) in JACOBI_PAIRS {
            let apq = a[p][q];
            if apq == 0.0 {
                continue;
            }
            // Numerical Recipes §11.1: the smaller root keeps the rotation below 45°.
            let theta = (a[q][q] - a[p][p]) / (2.0 * apq);
            let sign = if theta >= 0.0 { 1.0 } else { -1.0 };
            let t = sign / (theta.abs() + libm::sqrtf(theta * theta + 1.0));
            let c = 1.0 / libm::sqrtf(t * t + 1.0);
            let s = t * c;
            // A ← Pᵀ A P: first the columns p, q, then the rows p, q.
            for row in a.iter_mut() {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (rp, rq) = (a[p], a[q]);
            a[p] = core::array::from_fn(|k| c * rp[k] - s * rq[k]);
            a[q] = core::array::from_fn(|k| s * rp[k] + c * rq[k]);
            a[p][q] = 0.0;
            a[q][p] = 0.0;
            for row in v.iter_mut() {
                let (vkp, vkq) = (row[p], row[q]);
                row[p] = c * vkp - s * vkq;
                row[q] = s * vkp + c * vkq;
            }
        }
    }
    let mut best = 0;
    for j in 1..4 {
        if a[j][j] > a[best][best] {
            best = j;
        }
    }
    ([v[0][best], v[1][best], v[2][best], v[3][best]], sweeps)
}

/// Weighted rigid fit of `world ≈ R cam + t`. `weight(i, pair)` ≥ 0; pairs with
/// weight 0 do not take part. Inputs are assumed finite (checked by callers).
fn fit<W>(pairs: &[Correspondence], weight: W) -> Result<(Pose, FitStats), FailureCode>
where
    W: Fn(usize, &Correspondence) -> f32,
{
    let mut wsum = 0.0f32;
    let mut used = 0u16;
    let mut cw = Vec3::zeros();
    let mut cc = Vec3::zeros();
    for (i, p) in pairs.iter().enumerate() {
        let w = weight(i, p);
        if w > 0.0 {
            wsum += w;
            used = used.saturating_add(1);
            cw += p.world * w;
            cc += p.cam * w;
        }
    }
    if used < 3 {
        return Err(FailureCode::PoseTooFewPoints);
    }
    if !(wsum.is_finite() && wsum > 0.0) {
        return Err(FailureCode::PoseNonFinite);
    }
    cw /= wsum;
    cc /= wsum;
    // Centred accumulation: H = Σ w a bᵀ with a = cam − c̄, b = world − w̄.
    let mut h = Matrix3::<f32>::zeros();
    let mut sa = Matrix3::<f32>::zeros();
    let mut sb = Matrix3::<f32>::zeros();
    for (i, p) in pairs.iter().enumerate() {
        let w = weight(i, p);
        if w > 0.0 {
            let a = p.cam - cc;
            let b = p.world - cw;
            let aw = a * w;
            h += aw * b.transpose();
            sa += aw * a.transpose();
            sb += (b * w) * b.transpose();
        }
    }
    if degenerate(&sa, wsum) || degenerate(&sb, wsum) {
        return Err(FailureCode::PoseDegenerate);
    }
    // Scale H to O(1): eigenvectors do not change, f32 range is safe.
    let scale = 1.0 / libm::sqrtf(sa.trace() * sb.trace());
    let h = h * scale;
    let (sxx, sxy, sxz) = (h.m11, h.m12, h.m13);
    let (syx, syy, syz) = (h.m21, h.m22, h.m23);
    let (szx, szy, szz) = (h.m31, h.m32, h.m33);
    // Horn (1987), eq. for N with S_ij = Σ a_i b_j; quaternion order (w, x, y, z).
    let n = [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ];
    let ([qw, qx, qy, qz], sweeps) = jacobi4_dominant(n);
    // Canonical sign (w ≥ 0) so equal rotations have equal bits.
    let sgn = if qw < 0.0 { -1.0 } else { 1.0 };
    let quat = Quaternion::new(qw * sgn, qx * sgn, qy * sgn, qz * sgn);
    let norm = quat.norm();
    if !(norm.is_finite() && norm > 0.5) {
        return Err(FailureCode::PoseNonFinite);
    }
    let rot = UnitQuaternion::from_quaternion(quat);
    let t = cw - rot * cc;
    let pose = Pose::new(rot, t);
    if !pose.is_finite() {
        return Err(FailureCode::PoseNonFinite);
    }
    Ok((
        pose,
        FitStats {
            points: used,
            jacobi_sweeps: sweeps,
        },
    ))
}

fn check_pairs(pairs: &[Correspondence]) -> Result<(), FailureCode> {
    if pairs.len() < 3 {
        return Err(FailureCode::PoseTooFewPoints);
    }
    if pairs.len() > MAX_CORR {
        return Err(FailureCode::ConfigParamOutOfRange);
    }
    if !pairs.iter().all(Correspondence::is_finite) {
        return Err(FailureCode::PoseNonFinite);
    }
    Ok(())
}

fn inverse_variance(p: &Correspondence) -> f32 {
    let s = p.sigma_m.max(MIN_SIGMA_M);
    1.0 / (s * s)
}

/// Least-squares rigid transform `world_from_cam` (`world = R cam + t`, no scale)
/// of all pairs, equally weighted.
///
/// # Errors
/// * [`FailureCode::PoseTooFewPoints`]: fewer than 3 pairs.
/// * [`FailureCode::ConfigParamOutOfRange`]: more than [`MAX_CORR`] pairs.
/// * [`FailureCode::PoseNonFinite`]: a point or sigma is NaN/infinite (or sigma < 0).
/// * [`FailureCode::PoseDegenerate`]: the world or camera points are coincident or collinear.
pub fn umeyama(pairs: &[Correspondence]) -> Result<Pose, FailureCode> {
    umeyama_with_stats(pairs).map(|(p, _)| p)
}

/// [`umeyama`] with its work counters.
///
/// # Errors
/// As [`umeyama`].
pub fn umeyama_with_stats(pairs: &[Correspondence]) -> Result<(Pose, FitStats), FailureCode> {
    check_pairs(pairs)?;
    fit(pairs, |_, _| 1.0)
}

/// As [`umeyama`] but each pair weighted by `1/σ²` (σ = `sigma_m`, floored at
/// [`MIN_SIGMA_M`]): far points with large depth uncertainty count less.
///
/// # Errors
/// As [`umeyama`].
pub fn umeyama_weighted(pairs: &[Correspondence]) -> Result<Pose, FailureCode> {
    check_pairs(pairs)?;
    fit(pairs, |_, p| inverse_variance(p)).map(|(p, _)| p)
}

// ---- RANSAC ----------------------------------------------------------------

/// RANSAC settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RansacConfig {
    /// Iteration cap, 1..=[`MAX_RANSAC_ITER`].
    pub iterations: u16,
    /// Inlier gate on the 3D residual `|world − (R cam + t)|`, metres, > 0.
    pub inlier_m: f32,
    /// Early-exit confidence `p`, in (0, 1).
    pub confidence: f32,
    /// Widen each pair's gate to `√(inlier_m² + (SIGMA_GATE·sigma_m)²)`.
    pub scale_by_sigma: bool,
}

impl RansacConfig {
    /// Settings from validated [`Params`] (`ransac_iter`, `inlier_m`), with
    /// [`DEFAULT_CONFIDENCE`] and the gate scaled by sigma.
    pub fn from_params(p: &Params) -> Self {
        Self {
            iterations: p.ransac_iter,
            inlier_m: p.inlier_m,
            confidence: DEFAULT_CONFIDENCE,
            scale_by_sigma: true,
        }
    }

    /// Check the ranges documented on each field.
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`].
    pub fn validate(&self) -> Result<(), FailureCode> {
        let ok = (1..=MAX_RANSAC_ITER as u16).contains(&self.iterations)
            && self.inlier_m.is_finite()
            && self.inlier_m > 0.0
            && self.confidence.is_finite()
            && self.confidence > 0.0
            && self.confidence < 1.0;
        if ok {
            Ok(())
        } else {
            Err(FailureCode::ConfigParamOutOfRange)
        }
    }
}

/// A pose hypothesis and its inlier count.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    /// `world_from_cam`.
    pub pose: Pose,
    /// Pairs within the inlier gate.
    pub inliers: u16,
}

/// RANSAC work counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RansacStats {
    /// Samples drawn (≤ the cap).
    pub iterations: u16,
    /// Samples rejected because the three pairwise distances disagree between
    /// the world and camera points (no rigid transform can fit them).
    pub distance_rejects: u16,
    /// Samples rejected as coincident or collinear.
    pub degenerate_samples: u16,
    /// Hypotheses whose inliers were counted.
    pub hypotheses_scored: u16,
    /// Point residuals evaluated (search and refit).
    pub residuals_evaluated: u32,
    /// Jacobi sweeps over all fits.
    pub jacobi_sweeps: u32,
    /// Local refits of new best hypotheses during the search.
    pub local_refits: u16,
    /// Refits accepted after the search.
    pub refits: u8,
    /// Whether the confidence rule stopped the search before the cap.
    pub early_exit: bool,
}

/// RANSAC result.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    /// Maximum-inlier `world_from_cam`, refitted on its inliers.
    pub pose: Pose,
    /// Inliers of `pose`.
    pub inliers: u16,
    /// RMS residual of the inliers under `pose`, metres.
    pub rms_m: f32,
    /// Samples drawn (same as `stats.iterations`).
    pub iterations: u16,
    /// Distinct hypotheses, pairwise farther apart than the inlier gate in the
    /// sense of `|Δt| + θ·(mean camera-point range)`: first `pose`, then the
    /// others by inlier count, most first.
    pub candidates: heapless::Vec<Candidate, MAX_POSE_CANDIDATES>,
    /// Work counters.
    pub stats: RansacStats,
}

/// Samples needed for confidence `p` when a fraction `w` of pairs are inliers:
/// `⌈log(1 − p) / log(1 − w³)⌉`, saturating at `u32::MAX`.
pub fn required_iterations(inliers: u16, n: usize, confidence: f32) -> u32 {
    if n == 0 || inliers == 0 {
        return u32::MAX;
    }
    let w = (f32::from(inliers) / n as f32).min(1.0);
    let w3 = w * w * w;
    let denom = libm::log1pf(-w3);
    if denom == f32::NEG_INFINITY {
        return 1;
    }
    if denom.is_nan() || denom >= 0.0 {
        return u32::MAX;
    }
    let k = libm::log1pf(-confidence) / denom;
    if k.is_nan() || k >= u32::MAX as f32 {
        return u32::MAX;
    }
    (libm::ceilf(k) as u32).max(1)
}

/// Three distinct indices in `0..n` (`n ≥ 3`) from exactly three draws.
fn sample3(rng: &mut Rng, n: usize) -> [usize; 3] {
    let n = n as u32;
    let i0 = rng.below(n);
    let mut i1 = rng.below(n - 1);
    if i1 >= i0 {
        i1 += 1;
    }
    let (lo, hi) = if i0 < i1 { (i0, i1) } else { (i1, i0) };
    let mut i2 = rng.below(n - 2);
    if i2 >= lo {
        i2 += 1;
    }
    if i2 >= hi {
        i2 += 1;
    }
    [i0 as usize, i1 as usize, i2 as usize]
}

fn gate_sq(cfg: &RansacConfig, p: &Correspondence) -> f32 {
    let base = cfg.inlier_m * cfg.inlier_m;
    if cfg.scale_by_sigma {
        let s = SIGMA_GATE * p.sigma_m;
        base + s * s
    } else {
        base
    }
}

/// Upper bound (metres) on how far two `world_from_cam` poses move a camera
/// point at range `lever_m`: `|Δt| + θ·lever_m`.
fn pose_distance(a: &Pose, b: &Pose, lever_m: f32) -> f32 {
    (a.translation() - b.translation()).norm() + a.rotation().angle_to(&b.rotation()) * lever_m
}

/// Count inliers of `pose`; optionally write the inlier mask. Returns
/// `(inliers, sum of squared inlier residuals, whether any mask entry changed)`.
fn score(
    pairs: &[Correspondence],
    cfg: &RansacConfig,
    pose: &Pose,
    mut mask: Option<&mut [bool]>,
) -> (u16, f32, bool) {
    let r: Matrix3<f32> = pose.rotation().to_rotation_matrix().into_inner();
    let t = pose.translation();
    let mut count = 0u16;
    let mut sum_sq = 0.0f32;
    let mut changed = false;
    for (i, p) in pairs.iter().enumerate() {
        let e2 = (p.world - (r * p.cam + t)).norm_squared();
        let inlier = e2 <= gate_sq(cfg, p);
        if inlier {
            count = count.saturating_add(1);
            sum_sq += e2;
        }
        if let Some(m) = mask.as_deref_mut().and_then(|m| m.get_mut(i)) {
            changed |= *m != inlier;
            *m = inlier;
        }
    }
    (count, sum_sq, changed)
}

/// Insert `c` into the list kept sorted by inliers (descending) with entries
/// pairwise farther apart than `sep_m`. `c` is dropped if a close entry has at
/// least as many inliers; otherwise every close entry (all with fewer inliers)
/// is removed, so the invariant holds after every call.
fn insert_candidate(
    list: &mut heapless::Vec<Candidate, MAX_POSE_CANDIDATES>,
    c: Candidate,
    lever_m: f32,
    sep_m: f32,
) {
    let close = |e: &Candidate| pose_distance(&e.pose, &c.pose, lever_m) <= sep_m;
    if list.iter().any(|e| close(e) && e.inliers >= c.inliers) {
        return;
    }
    list.retain(|e| !close(e));
    let pos = list
        .iter()
        .position(|e| e.inliers < c.inliers)
        .unwrap_or(list.len());
    if list.is_full() {
        if pos >= list.len() {
            return;
        }
        list.pop();
    }
    // Cannot fail: there is room, and pos ≤ len.
    let _ = list.insert(pos, c);
}

/// Resumable RANSAC state: call [`Ransac::run_chunk`] until it reports done (or
/// whenever the caller's step budget allows), then [`Ransac::finish`]. Holds no
/// borrow, so an engine can keep it beside the correspondence buffer; the same
/// pairs must be passed to every call.
#[derive(Clone, Debug)]
pub struct Ransac {
    cfg: RansacConfig,
    n: usize,
    cap: u16,
    rng: Rng,
    needed: u32,
    best: Option<Candidate>,
    candidates: heapless::Vec<Candidate, MAX_POSE_CANDIDATES>,
    lever_m: f32,
    weighted_refit: bool,
    local_refit: bool,
    stats: RansacStats,
}

impl Ransac {
    /// Check the inputs and prepare a search that draws from `rng`.
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] for a bad config or more than
    /// [`MAX_CORR`] pairs; [`FailureCode::PoseTooFewPoints`],
    /// [`FailureCode::PoseNonFinite`] for bad pairs.
    pub fn new(
        pairs: &[Correspondence],
        cfg: &RansacConfig,
        rng: Rng,
    ) -> Result<Self, FailureCode> {
        cfg.validate()?;
        check_pairs(pairs)?;
        let lever_m = pairs.iter().map(|p| p.cam.norm()).sum::<f32>() / pairs.len() as f32;
        Ok(Self {
            cfg: *cfg,
            n: pairs.len(),
            cap: cfg.iterations.min(MAX_RANSAC_ITER as u16),
            rng,
            needed: u32::MAX,
            best: None,
            candidates: heapless::Vec::new(),
            lever_m,
            weighted_refit: false,
            local_refit: true,
            stats: RansacStats::default(),
        })
    }

    /// Refit on the inliers weighted by `1/σ²` instead of equally.
    pub fn with_weighted_refit(mut self, on: bool) -> Self {
        self.weighted_refit = on;
        self
    }

    /// Refit each new best hypothesis on its inliers during the search
    /// (default on).
    pub fn with_local_refit(mut self, on: bool) -> Self {
        self.local_refit = on;
        self
    }

    /// Whether the search is over (cap reached or confidence met).
    pub fn is_done(&self) -> bool {
        let it = u32::from(self.stats.iterations);
        self.stats.iterations >= self.cap || it >= self.needed
    }

    /// Samples drawn so far.
    pub fn iterations(&self) -> u16 {
        self.stats.iterations
    }

    /// Work counters so far.
    pub fn stats(&self) -> RansacStats {
        self.stats
    }

    /// The generator, advanced past every draw made so far.
    pub fn rng(&self) -> Rng {
        self.rng
    }

    /// Best hypothesis so far (before the refit).
    pub fn best(&self) -> Option<Candidate> {
        self.best
    }

    /// Draw and score at most `max_iterations` samples; `Ok(true)` once done.
    ///
    /// # Errors
    /// [`FailureCode::ConfigParamOutOfRange`] if `pairs` is not the slice given to [`Ransac::new`]
    /// (length differs).
    pub fn run_chunk(
        &mut self,
        pairs: &[Correspondence],
        max_iterations: u16,
    ) -> Result<bool, FailureCode> {
        if pairs.len() != self.n {
            return Err(FailureCode::ConfigParamOutOfRange);
        }
        for _ in 0..max_iterations {
            if self.is_done() {
                break;
            }
            self.iterate(pairs);
        }
        let done = self.is_done();
        self.stats.early_exit = done && self.stats.iterations < self.cap;
        Ok(done)
    }

    fn iterate(&mut self, pairs: &[Correspondence]) {
        self.stats.iterations += 1;
        let [i0, i1, i2] = sample3(&mut self.rng, self.n);
        let (Some(a), Some(b), Some(c)) = (pairs.get(i0), pairs.get(i1), pairs.get(i2)) else {
            return;
        };
        let s = [*a, *b, *c];
        // A rigid transform preserves distances: if |d_world − d_cam| exceeds the
        // sum of the two gates, no pose can make both pairs inliers.
        let gate = |p: &Correspondence| libm::sqrtf(gate_sq(&self.cfg, p));
        for (x, y) in [(a, b), (a, c), (b, c)] {
            let dw = (x.world - y.world).norm();
            let dc = (x.cam - y.cam).norm();
            if (dw - dc).abs() > gate(x) + gate(y) {
                self.stats.distance_rejects += 1;
                return;
            }
        }
        let (pose, fs) = match fit(&s, |_, _| 1.0) {
            Ok(v) => v,
            Err(_) => {
                self.stats.degenerate_samples += 1;
                return;
            }
        };
        self.stats.jacobi_sweeps = self.stats.jacobi_sweeps.saturating_add(fs.jacobi_sweeps);
        let (inliers, _, _) = score(pairs, &self.cfg, &pose, None);
        self.stats.hypotheses_scored += 1;
        self.stats.residuals_evaluated =
            self.stats.residuals_evaluated.saturating_add(self.n as u32);
        let mut cand = Candidate { pose, inliers };
        if self.best.is_none_or(|b| inliers > b.inliers) {
            if self.local_refit {
                cand = self.refine(pairs, cand);
            }
            self.best = Some(cand);
            self.needed = required_iterations(cand.inliers, self.n, self.cfg.confidence);
        }
        insert_candidate(&mut self.candidates, cand, self.lever_m, self.cfg.inlier_m);
    }

    /// Local optimisation (LO-RANSAC, Chum et al. 2003): refit a new best
    /// hypothesis on its own inliers and keep the refit if it has at least as
    /// many. Runs only when the best count strictly grows, so at most `n` times
    /// per search.
    fn refine(&mut self, pairs: &[Correspondence], c: Candidate) -> Candidate {
        let r: Matrix3<f32> = c.pose.rotation().to_rotation_matrix().into_inner();
        let t = c.pose.translation();
        let cfg = self.cfg;
        let inlier =
            |p: &Correspondence| (p.world - (r * p.cam + t)).norm_squared() <= gate_sq(&cfg, p);
        self.stats.local_refits += 1;
        self.stats.residuals_evaluated = self
            .stats
            .residuals_evaluated
            .saturating_add(3 * self.n as u32);
        let Ok((pose, fs)) = fit(pairs, |_, p| if inlier(p) { 1.0 } else { 0.0 }) else {
            return c;
        };
        self.stats.jacobi_sweeps = self.stats.jacobi_sweeps.saturating_add(fs.jacobi_sweeps);
        let (inliers, _, _) = score(pairs, &self.cfg, &pose, None);
        if inliers >= c.inliers {
            Candidate { pose, inliers }
        } else {
            c
        }
    }

    /// Refit the best hypothesis on its inliers (recounting after each refit,
    /// at most [`REFIT_ROUNDS`] times) and report. Writes the inlier flags of the
    /// final pose into the first `pairs.len()` entries of `inlier_mask`.
    ///
    /// # Errors
    /// * [`FailureCode::ConfigParamOutOfRange`]: `pairs` differs in length from [`Ransac::new`].
    /// * [`FailureCode::ConfigCapacityTooSmall`]: `inlier_mask` is shorter than `pairs`.
    /// * [`FailureCode::PoseRansacNoConsensus`]: no sample gave a hypothesis with 3 inliers.
    pub fn finish(
        &mut self,
        pairs: &[Correspondence],
        inlier_mask: &mut [bool],
    ) -> Result<Estimate, FailureCode> {
        if pairs.len() != self.n {
            return Err(FailureCode::ConfigParamOutOfRange);
        }
        let Some(mask) = inlier_mask.get_mut(..self.n) else {
            return Err(FailureCode::ConfigCapacityTooSmall);
        };
        let best = match self.best {
            Some(b) if b.inliers >= 3 => b,
            _ => {
                mask.fill(false);
                return Err(FailureCode::PoseRansacNoConsensus);
            }
        };
        let (mut pose, mut inliers) = (best.pose, best.inliers);
        let (_, mut sum_sq, _) = score(pairs, &self.cfg, &pose, Some(&mut *mask));
        self.stats.residuals_evaluated =
            self.stats.residuals_evaluated.saturating_add(self.n as u32);
        // Refit on the inliers and recount until the inlier set is stable. The
        // refit is kept even if it has fewer inliers than the 3-point hypothesis:
        // a least-squares fit on the consensus set is the better estimate, and a
        // wrong hypothesis can collect more pairs than the truth by including
        // outliers near the gate.
        for _ in 0..REFIT_ROUNDS {
            let weighted = self.weighted_refit;
            let m: &[bool] = mask;
            let refit = fit(pairs, |i, p| match m.get(i) {
                Some(true) if weighted => inverse_variance(p),
                Some(true) => 1.0,
                _ => 0.0,
            });
            let Ok((new_pose, fs)) = refit else { break };
            self.stats.jacobi_sweeps = self.stats.jacobi_sweeps.saturating_add(fs.jacobi_sweeps);
            let (new_inliers, new_sum, changed) =
                score(pairs, &self.cfg, &new_pose, Some(&mut *mask));
            self.stats.residuals_evaluated =
                self.stats.residuals_evaluated.saturating_add(self.n as u32);
            if new_inliers < 3 {
                // Consensus lost: keep the previous pose and restore its mask.
                score(pairs, &self.cfg, &pose, Some(&mut *mask));
                break;
            }
            pose = new_pose;
            inliers = new_inliers;
            sum_sq = new_sum;
            self.stats.refits += 1;
            if !changed {
                break;
            }
        }
        let rms_m = libm::sqrtf(sum_sq / f32::from(inliers.max(1)));
        let mut candidates = self.candidates.clone();
        let fin = Candidate { pose, inliers };
        // The refined pose leads the list (even if the refit lost a few inliers
        // against its 3-point hypothesis); entries it duplicates are dropped.
        candidates.retain(|c| pose_distance(&c.pose, &pose, self.lever_m) > self.cfg.inlier_m);
        if candidates.is_full() {
            candidates.pop();
        }
        if candidates.insert(0, fin).is_err() {
            // Unreachable: one slot was freed above.
            return Err(FailureCode::ConfigCapacityTooSmall);
        }
        Ok(Estimate {
            pose,
            inliers,
            rms_m,
            iterations: self.stats.iterations,
            candidates,
            stats: self.stats,
        })
    }
}

/// RANSAC over `pairs` with minimal 3-point samples, then refit on the inliers.
/// Draws from `rng` (advanced past every draw); writes the final inlier flags
/// into the first `pairs.len()` entries of `inlier_mask`. Equivalent to
/// [`Ransac::new`], [`Ransac::run_chunk`] until done, [`Ransac::finish`].
///
/// # Errors
/// As [`Ransac::new`] and [`Ransac::finish`].
pub fn ransac(
    pairs: &[Correspondence],
    cfg: &RansacConfig,
    rng: &mut Rng,
    inlier_mask: &mut [bool],
) -> Result<Estimate, FailureCode> {
    let mut r = Ransac::new(pairs, cfg, *rng)?;
    r.run_chunk(pairs, MAX_RANSAC_ITER as u16)?;
    *rng = r.rng();
    r.finish(pairs, inlier_mask)
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)] // the f64 reference mirrors the textbook index notation
mod tests {
    extern crate std;
    use super::*;
    use crate::rng::Rng;
    use nalgebra::{Matrix3 as M3, Vector3 as V3};
    use proptest::prelude::*;
    use std::vec::Vec;

    use crate::testkit::random_pose;

    /// A rover-like scene: points 2–10 m ahead of the left camera.
    fn random_cam_point(rng: &mut Rng) -> Vec3 {
        Vec3::new(
            rng.uniform(-3.0, 3.0),
            rng.uniform(-1.0, 1.5),
            rng.uniform(2.0, 10.0),
        )
    }

    fn exact_pairs(rng: &mut Rng, pose: &Pose, n: usize) -> Vec<Correspondence> {
        (0..n)
            .map(|_| {
                let cam = random_cam_point(rng);
                Correspondence {
                    world: pose.transform_point(&cam),
                    cam,
                    sigma_m: 0.01,
                }
            })
            .collect()
    }

    fn rot64(p: &Pose) -> M3<f64> {
        p.rotation().to_rotation_matrix().into_inner().cast::<f64>()
    }

    fn v64(v: &Vec3) -> V3<f64> {
        v.cast::<f64>()
    }

    /// Rotation angle of `a bᵀ` in radians, accurate for small angles.
    fn angle_between(a: &M3<f64>, b: &M3<f64>) -> f64 {
        let d = a * b.transpose();
        let s = V3::new(
            d[(2, 1)] - d[(1, 2)],
            d[(0, 2)] - d[(2, 0)],
            d[(1, 0)] - d[(0, 1)],
        )
        .norm()
            * 0.5;
        let c = (d.trace() - 1.0) * 0.5;
        s.atan2(c)
    }

    // ---- independent f64 reference: Horn's quaternion method with classical
    // (largest-pivot) Jacobi and atan2 rotation angles -------------------------

    fn horn_f64(pairs: &[Correspondence]) -> (M3<f64>, V3<f64>) {
        let n = pairs.len() as f64;
        let cw = pairs.iter().map(|p| v64(&p.world)).sum::<V3<f64>>() / n;
        let cc = pairs.iter().map(|p| v64(&p.cam)).sum::<V3<f64>>() / n;
        let mut s = [[0.0f64; 3]; 3];
        for p in pairs {
            let a = v64(&p.cam) - cc;
            let b = v64(&p.world) - cw;
            for i in 0..3 {
                for j in 0..3 {
                    s[i][j] += a[i] * b[j];
                }
            }
        }
        let [[xx, xy, xz], [yx, yy, yz], [zx, zy, zz]] = s;
        let mut m = [
            [xx + yy + zz, yz - zy, zx - xz, xy - yx],
            [yz - zy, xx - yy - zz, xy + yx, zx + xz],
            [zx - xz, xy + yx, -xx + yy - zz, yz + zy],
            [xy - yx, zx + xz, yz + zy, -xx - yy + zz],
        ];
        let mut v = [[0.0f64; 4]; 4];
        for (i, row) in v.iter_mut().enumerate() {
            row[i] = 1.0;
        }
        for _ in 0..200 {
            let (mut p, mut q, mut big) = (0, 1, 0.0);
            for i in 0..4 {
                for j in i + 1..4 {
                    if m[i][j].abs() > big {
                        (p, q, big) = (i, j, m[i][j].abs());
                    }
                }
            }
            if big < 1e-300 {
                break;
            }
            let phi = 0.5 * (2.0 * m[p][q]).atan2(m[q][q] - m[p][p]);
            let (sn, cs) = phi.sin_cos();
            // G = rotation in the (p, q) plane; M ← Gᵀ M G, V ← V G.
            let mut g = [[0.0f64; 4]; 4];
            for (i, row) in g.iter_mut().enumerate() {
                row[i] = 1.0;
            }
            g[p][p] = cs;
            g[q][q] = cs;
            g[p][q] = sn;
            g[q][p] = -sn;
            let mul = |a: &[[f64; 4]; 4], b: &[[f64; 4]; 4]| {
                let mut r = [[0.0f64; 4]; 4];
                for i in 0..4 {
                    for j in 0..4 {
                        r[i][j] = (0..4).map(|k| a[i][k] * b[k][j]).sum();
                    }
                }
                r
            };
            let mut gt = g;
            for i in 0..4 {
                for j in 0..4 {
                    gt[i][j] = g[j][i];
                }
            }
            m = mul(&gt, &mul(&m, &g));
            v = mul(&v, &g);
        }
        let k = (0..4)
            .max_by(|&a, &b| m[a][a].partial_cmp(&m[b][b]).unwrap())
            .unwrap();
        let (w, x, y, z) = (v[0][k], v[1][k], v[2][k], v[3][k]);
        let nq = (w * w + x * x + y * y + z * z).sqrt();
        let (w, x, y, z) = (w / nq, x / nq, y / nq, z / nq);
        let r = M3::new(
            w * w + x * x - y * y - z * z,
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
            2.0 * (x * y + w * z),
            w * w - x * x + y * y - z * z,
            2.0 * (y * z - w * x),
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            w * w - x * x - y * y + z * z,
        );
        (r, cw - r * cc)
    }

    /// Second reference: Kabsch by f64 SVD with the reflection fix.
    fn kabsch_f64(pairs: &[Correspondence]) -> (M3<f64>, V3<f64>) {
        let n = pairs.len() as f64;
        let cw = pairs.iter().map(|p| v64(&p.world)).sum::<V3<f64>>() / n;
        let cc = pairs.iter().map(|p| v64(&p.cam)).sum::<V3<f64>>() / n;
        let mut h = M3::<f64>::zeros();
        for p in pairs {
            h += (v64(&p.world) - cw) * (v64(&p.cam) - cc).transpose();
        }
        let svd = h.svd(true, true);
        let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
        let d = (u * vt).determinant().signum();
        let r = u * M3::from_diagonal(&V3::new(1.0, 1.0, d)) * vt;
        (r, cw - r * cc)
    }

    fn add_noise(pairs: &mut [Correspondence], rng: &mut Rng, sigma: f32) {
        for p in pairs {
            p.world += Vec3::new(rng.normal(), rng.normal(), rng.normal()) * sigma;
        }
    }

    // ---- Umeyama ----------------------------------------------------------

    /// Tolerances for a noise-free fit at f32 precision: (angle, residual).
    ///
    /// * Data: the world points are computed in f32, so each coordinate carries
    ///   an error up to u ≈ 2 ulp(max |coordinate|). To first order that moves the
    ///   exact fit's rotation by u·√tr(J⁻¹) (J = Σ |a|²I − aaᵀ over the centred
    ///   camera points, as in the noise test) and the centroid by u.
    /// * Solver: the cross-covariance and Horn's 4×4 matrix are formed in f32,
    ///   a perturbation of ε‖N‖ against an eigen-gap that shrinks with the second
    ///   scatter eigenvalue λ₂, so δθ ≈ c·ε·λ₁/λ₂ (c ≤ 5.2 measured against the
    ///   f64 reference over 200,000 random 3–7 point sets).
    ///
    /// Both with a margin (8 on the data term, 16 on the solver term).
    fn rounding_tolerance(pairs: &[Correspondence]) -> (f64, f64) {
        let max_c = pairs
            .iter()
            .flat_map(|p| p.world.iter().chain(p.cam.iter()))
            .fold(0.0f32, |m, c| m.max(c.abs()));
        let eps = f64::from(f32::EPSILON);
        let u = 2.0 * f64::from(max_c) * eps;
        let n = pairs.len() as f64;
        let cc = pairs.iter().map(|p| v64(&p.cam)).sum::<V3<f64>>() / n;
        let mut j = M3::<f64>::zeros();
        let mut sc = M3::<f64>::zeros();
        let mut reach = 0.0f64;
        for p in pairs {
            let a = v64(&p.cam) - cc;
            j += M3::identity() * a.norm_squared() - a * a.transpose();
            sc += a * a.transpose();
            reach = reach.max(a.norm());
        }
        let mut ev: Vec<f64> = sc.symmetric_eigenvalues().iter().copied().collect();
        ev.sort_by(|a, b| b.partial_cmp(a).unwrap());
        let ang = 8.0 * u * j.try_inverse().unwrap().trace().sqrt() + 16.0 * eps * ev[0] / ev[1];
        (ang, 8.0 * u + ang * reach)
    }

    /// Verifies: VTSM-POSE-001
    #[test]
    fn recovers_random_rigid_transforms_noise_free() {
        let mut rng = Rng::new(1);
        let mut worst = (0.0f64, 0.0f64);
        for case in 0..2000 {
            let truth = random_pose(&mut rng);
            let n = 3 + (case % 98);
            let pairs = exact_pairs(&mut rng, &truth, n);
            let est = umeyama(&pairs).unwrap();
            let ang = angle_between(&rot64(&est), &rot64(&truth));
            let max_res = pairs
                .iter()
                .map(|p| f64::from((est.transform_point(&p.cam) - p.world).norm()))
                .fold(0.0, f64::max);
            let (tol_ang, tol_t) = rounding_tolerance(&pairs);
            worst = (worst.0.max(ang / tol_ang), worst.1.max(max_res / tol_t));
            assert!(ang < tol_ang, "case {case}: angle {ang} > {tol_ang}");
            assert!(max_res < tol_t, "case {case}: residual {max_res} > {tol_t}");
            // With enough points the tolerance itself is at f32 level.
            if n >= 20 {
                assert!(ang < 1e-5 && max_res < 2e-5, "case {case}: {ang} {max_res}");
            }
        }
        std::println!(
            "noise-free worst / tolerance: angle {:.2}, residual {:.2}",
            worst.0,
            worst.1
        );
    }

    /// Verifies: VTSM-POSE-002
    #[test]
    fn noise_error_matches_first_order_expectation() {
        // world_i = R a_i + c + n_i, n_i ~ N(0, σ² I). To first order the fit error
        // at the camera-point centroid is the mean noise (E|e|² = 3σ²/N) and the
        // rotation error δθ has covariance σ² J⁻¹ with J = Σ(|a|² I − a aᵀ) over the
        // centred points (E|δθ|² = σ² tr J⁻¹).
        let mut rng = Rng::new(2);
        let n = 50;
        let sigma = 0.01f32;
        let truth = random_pose(&mut rng);
        let clean = exact_pairs(&mut rng, &truth, n);
        let cc = clean.iter().map(|p| v64(&p.cam)).sum::<V3<f64>>() / n as f64;
        let mut j = M3::<f64>::zeros();
        for p in &clean {
            let a = v64(&p.cam) - cc;
            j += M3::identity() * a.norm_squared() - a * a.transpose();
        }
        let s2 = f64::from(sigma).powi(2);
        let expect_c = 3.0 * s2 / n as f64;
        let expect_r = s2 * j.try_inverse().unwrap().trace();
        let rt = rot64(&truth);
        let truth_c = rt * cc + v64(&truth.translation());
        let trials = 2000;
        let (mut sum_c, mut sum_r) = (0.0f64, 0.0f64);
        for _ in 0..trials {
            let mut pairs = clean.clone();
            add_noise(&mut pairs, &mut rng, sigma);
            let est = umeyama(&pairs).unwrap();
            let re = rot64(&est);
            let est_c = re * cc + v64(&est.translation());
            sum_c += (est_c - truth_c).norm_squared();
            let d = re * rt.transpose();
            let dth = V3::new(
                d[(2, 1)] - d[(1, 2)],
                d[(0, 2)] - d[(2, 0)],
                d[(1, 0)] - d[(0, 1)],
            ) * 0.5;
            sum_r += dth.norm_squared();
        }
        let (mc_c, mc_r) = (sum_c / trials as f64, sum_r / trials as f64);
        std::println!(
            "centroid MSE {mc_c:.3e} vs {expect_c:.3e}; rotation MSE {mc_r:.3e} vs {expect_r:.3e}"
        );
        // Monte-Carlo standard error of each mean is ~2 %; allow 10 %.
        assert!((mc_c / expect_c - 1.0).abs() < 0.10, "{mc_c} vs {expect_c}");
        assert!((mc_r / expect_r - 1.0).abs() < 0.10, "{mc_r} vs {expect_r}");
    }

    /// Verifies: VTSM-POSE-005
    #[test]
    fn agrees_with_independent_f64_references() {
        let mut rng = Rng::new(3);
        let mut worst = (0.0f64, 0.0f64);
        for case in 0..500 {
            let truth = random_pose(&mut rng);
            let n = 3 + (case % 60);
            let mut pairs = exact_pairs(&mut rng, &truth, n);
            add_noise(&mut pairs, &mut rng, 0.02);
            let est = umeyama(&pairs).unwrap();
            let (rh, th) = horn_f64(&pairs);
            let (rk, tk) = kabsch_f64(&pairs);
            // The two f64 references agree with each other to rounding.
            assert!(angle_between(&rh, &rk) < 1e-9 && (th - tk).norm() < 1e-8);
            let ang = angle_between(&rot64(&est), &rh);
            let dt = (v64(&est.translation()) - th).norm();
            worst = (worst.0.max(ang), worst.1.max(dt));
            assert!(
                ang < 1e-5 && dt < 1e-5,
                "case {case}: {ang:e} rad, {dt:e} m"
            );
        }
        std::println!("vs f64 Horn: worst {:.2e} rad, {:.2e} m", worst.0, worst.1);
    }

    /// Verifies: VTSM-POSE-003
    #[test]
    fn too_few_coincident_and_collinear_points_return_codes() {
        let mut rng = Rng::new(4);
        let truth = random_pose(&mut rng);
        let pairs = exact_pairs(&mut rng, &truth, 10);
        for k in 0..3 {
            assert_eq!(umeyama(&pairs[..k]), Err(FailureCode::PoseTooFewPoints));
        }
        assert!(umeyama(&pairs[..3]).is_ok());
        // Coincident: all points within 0.1 mm of each other.
        let base = random_cam_point(&mut rng);
        let coincident: Vec<_> = (0..8)
            .map(|_| {
                let cam = base + Vec3::new(rng.uniform(-1e-4, 1e-4), 0.0, rng.uniform(-1e-4, 1e-4));
                Correspondence {
                    world: truth.transform_point(&cam),
                    cam,
                    sigma_m: 0.0,
                }
            })
            .collect();
        assert_eq!(umeyama(&coincident), Err(FailureCode::PoseDegenerate));
        // Collinear, exactly and with f32 rounding; then a thin but valid strip.
        let dir = rng.unit_vector3();
        let side = dir.cross(&Vec3::new(0.3, 0.5, 0.8)).normalize();
        let line = |width: f32, rng: &mut Rng| -> Vec<Correspondence> {
            (0..12)
                .map(|_| {
                    let cam =
                        base + dir * rng.uniform(-2.0, 2.0) + side * rng.uniform(-width, width);
                    Correspondence {
                        world: truth.transform_point(&cam),
                        cam,
                        sigma_m: 0.0,
                    }
                })
                .collect()
        };
        assert_eq!(
            umeyama(&line(0.0, &mut rng)),
            Err(FailureCode::PoseDegenerate)
        );
        assert_eq!(
            umeyama(&line(1e-4, &mut rng)),
            Err(FailureCode::PoseDegenerate)
        );
        let strip = line(0.1, &mut rng);
        let est = umeyama(&strip).unwrap();
        assert!(angle_between(&rot64(&est), &rot64(&truth)) < 1e-4);
        // Degenerate world side only (map points collapsed) is also caught.
        let mut bad_world = pairs.clone();
        for p in &mut bad_world {
            p.world = Vec3::new(1.0, 2.0, 3.0);
        }
        assert_eq!(umeyama(&bad_world), Err(FailureCode::PoseDegenerate));
        // Non-finite input.
        let mut nan = pairs.clone();
        nan[4].cam.y = f32::NAN;
        assert_eq!(umeyama(&nan), Err(FailureCode::PoseNonFinite));
        let mut neg = pairs.clone();
        neg[1].sigma_m = -1.0;
        assert_eq!(umeyama(&neg), Err(FailureCode::PoseNonFinite));
        // Above the correspondence cap.
        let big = exact_pairs(&mut rng, &truth, MAX_CORR + 1);
        assert_eq!(umeyama(&big), Err(FailureCode::ConfigParamOutOfRange));
        assert!(umeyama(&big[..MAX_CORR]).is_ok());
    }

    /// Verifies: VTSM-POSE-004
    #[test]
    fn jacobi_sweeps_stay_under_cap() {
        let mut rng = Rng::new(5);
        let mut max_sweeps = 0;
        for case in 0..2000 {
            let truth = random_pose(&mut rng);
            let mut pairs = exact_pairs(&mut rng, &truth, 3 + case % 40);
            add_noise(&mut pairs, &mut rng, [0.0, 0.01, 0.5, 5.0][case % 4]);
            if let Ok((_, st)) = umeyama_with_stats(&pairs) {
                max_sweeps = max_sweeps.max(st.jacobi_sweeps);
                assert_eq!(usize::from(st.points), pairs.len());
            }
        }
        std::println!("max Jacobi sweeps {max_sweeps}");
        // Converged well before the cap: the cap is a bound, not the stopping rule.
        assert!(max_sweeps < JACOBI_MAX_SWEEPS, "{max_sweeps}");
    }

    /// Verifies: VTSM-POSE-011
    #[test]
    fn weighted_fit_discounts_uncertain_pairs() {
        let mut rng = Rng::new(6);
        let truth = random_pose(&mut rng);
        let mut pairs = exact_pairs(&mut rng, &truth, 20);
        // Equal sigmas: same as the unweighted fit.
        let a = umeyama(&pairs).unwrap();
        let b = umeyama_weighted(&pairs).unwrap();
        assert!(angle_between(&rot64(&a), &rot64(&b)) < 1e-5);
        assert!((a.translation() - b.translation()).norm() < 1e-5);
        // One pair off by 1 m but declared 100× less certain.
        pairs[0].cam += Vec3::new(0.0, 0.0, 1.0);
        pairs[0].sigma_m = 1.0;
        let (eu, _) = umeyama(&pairs).unwrap().error_to(&truth);
        let (ew, _) = umeyama_weighted(&pairs).unwrap().error_to(&truth);
        assert!(eu > 0.02, "{eu}");
        assert!(ew < eu * 0.01, "{ew} vs {eu}");
    }

    proptest! {
        /// Verifies: VTSM-POSE-004
        #[test]
        fn rotation_is_always_proper(seed in any::<u64>(), n in 3usize..40, noise in 0.0f32..3.0) {
            // Arbitrary (even unrelated) point sets: whatever comes back is a rotation.
            let mut rng = Rng::new(seed);
            let truth = random_pose(&mut rng);
            let mut pairs = exact_pairs(&mut rng, &truth, n);
            add_noise(&mut pairs, &mut rng, noise);
            if seed % 3 == 0 {
                for p in &mut pairs {
                    p.world = -p.world; // a reflection of the true configuration
                }
            }
            if let Ok(est) = umeyama(&pairs) {
                let r = rot64(&est);
                prop_assert!((r.determinant() - 1.0).abs() < 1e-5, "det {}", r.determinant());
                prop_assert!((r.transpose() * r - M3::identity()).norm() < 1e-5);
                prop_assert!(est.is_finite());
            }
        }

        /// Verifies: VTSM-POSE-001
        #[test]
        fn recovers_any_rigid_transform(seed in any::<u64>(), n in 3usize..60) {
            let mut rng = Rng::new(seed);
            let truth = random_pose(&mut rng);
            let pairs = exact_pairs(&mut rng, &truth, n);
            let est = umeyama(&pairs).unwrap();
            let (tol_ang, tol_t) = rounding_tolerance(&pairs);
            prop_assert!(angle_between(&rot64(&est), &rot64(&truth)) < tol_ang);
            let cc = pairs.iter().map(|p| p.cam).sum::<Vec3>() / n as f32;
            let moved = (est.transform_point(&cc) - truth.transform_point(&cc)).norm();
            prop_assert!(f64::from(moved) < tol_t, "{moved} > {tol_t}");
        }
    }

    // ---- RANSAC ------------------------------------------------------------

    /// `n_in` pairs under `truth` with `noise` m, `n_out` gross outliers.
    fn contaminated(
        rng: &mut Rng,
        truth: &Pose,
        n_in: usize,
        n_out: usize,
        noise: f32,
    ) -> Vec<Correspondence> {
        let mut v = exact_pairs(rng, truth, n_in);
        add_noise(&mut v, rng, noise);
        for _ in 0..n_out {
            let cam = random_cam_point(rng);
            let other = random_cam_point(rng);
            v.push(Correspondence {
                world: truth.transform_point(&other),
                cam,
                sigma_m: 0.01,
            });
        }
        // Shuffle (Fisher–Yates) so inliers are not a prefix.
        for i in (1..v.len()).rev() {
            let j = rng.below(i as u32 + 1) as usize;
            v.swap(i, j);
        }
        v
    }

    fn cfg(iterations: u16) -> RansacConfig {
        RansacConfig {
            iterations,
            inlier_m: 0.05,
            confidence: 0.999,
            scale_by_sigma: false,
        }
    }

    /// Verifies: VTSM-POSE-006, VTSM-POSE-007
    #[test]
    fn ransac_finds_transform_with_60_percent_outliers_in_999_of_10000() {
        let c = cfg(1000);
        let (mut ok, mut max_iter, mut sum_iter) = (0u32, 0u16, 0u64);
        let mut fails = Vec::new();
        for seed in 0..10_000u64 {
            let mut rng = Rng::new(seed);
            let truth = random_pose(&mut rng);
            let n = 30 + (seed % 71) as usize; // 30..=100 pairs
            let n_out = (n * 3) / 5; // 60 % outliers
            let pairs = contaminated(&mut rng, &truth, n - n_out, n_out, 0.005);
            let mut mask = [false; MAX_CORR];
            let mut r = rng.fork(7);
            let est = ransac(&pairs, &c, &mut r, &mut mask);
            if let Ok(e) = &est {
                assert!(e.iterations <= c.iterations, "seed {seed}: cap exceeded");
                max_iter = max_iter.max(e.iterations);
                sum_iter += u64::from(e.iterations);
                let (dt, dr) = e.pose.error_to(&truth);
                if dt < 0.02 && dr < 0.01 && usize::from(e.inliers) >= n - n_out - 2 {
                    ok += 1;
                    continue;
                }
            }
            match &est {
                Ok(e) => std::println!(
                    "seed {seed}: n {n}, error {:?}, inliers {}, {:?}",
                    e.pose.error_to(&truth),
                    e.inliers,
                    e.stats
                ),
                Err(code) => std::println!("seed {seed}: n {n}, {code:?}"),
            }
            fails.push(seed);
        }
        std::println!(
            "ransac 60% outliers: {ok}/10000 ok, max iterations {max_iter}, mean {:.1}, failing seeds {:?}",
            sum_iter as f64 / 10_000.0,
            &fails[..fails.len().min(10)]
        );
        assert!(ok >= 9990, "{ok} / 10000; failing seeds {fails:?}");
    }

    /// Verifies: VTSM-POSE-007
    #[test]
    fn iteration_cap_is_never_exceeded() {
        // Pure outliers: the confidence rule never fires, so the search runs to its cap.
        let mut rng = Rng::new(8);
        let truth = random_pose(&mut rng);
        let pairs = contaminated(&mut rng, &truth, 0, 60, 0.0);
        let mut mask = [false; 60];
        for cap in [1u16, 2, 7, 100, 1000, MAX_RANSAC_ITER as u16] {
            let mut r = Rng::new(u64::from(cap));
            let mut s = Ransac::new(&pairs, &cfg(cap), r).unwrap();
            assert!(s.run_chunk(&pairs, u16::MAX).unwrap());
            assert_eq!(s.iterations(), cap);
            assert!(!s.stats().early_exit);
            // Further chunks do no work.
            assert!(s.run_chunk(&pairs, 50).unwrap());
            assert_eq!(s.iterations(), cap);
            let st = s.stats();
            assert_eq!(
                st.distance_rejects + st.degenerate_samples + st.hypotheses_scored,
                cap
            );
            match ransac(&pairs, &cfg(cap), &mut r, &mut mask) {
                Ok(e) => assert!(e.iterations <= cap && e.stats.iterations == e.iterations),
                Err(code) => assert_eq!(code, FailureCode::PoseRansacNoConsensus),
            }
        }
        // Caps above the configured maximum are refused, not clamped silently.
        let too_many = cfg(MAX_RANSAC_ITER as u16 + 1);
        assert_eq!(
            Ransac::new(&pairs, &too_many, Rng::new(0)).err(),
            Some(FailureCode::ConfigParamOutOfRange)
        );
    }

    /// Verifies: VTSM-POSE-010
    #[test]
    fn chunked_run_is_bit_identical_to_one_shot() {
        for seed in 0..40u64 {
            let mut rng = Rng::new(seed);
            let truth = random_pose(&mut rng);
            let pairs = contaminated(&mut rng, &truth, 25, 25, 0.01);
            let c = RansacConfig {
                scale_by_sigma: seed % 2 == 0,
                ..cfg(300)
            };
            let mut m1 = [false; 50];
            let mut r1 = Rng::new(seed ^ 99);
            let one = ransac(&pairs, &c, &mut r1, &mut m1).unwrap();
            for chunk in [1u16, 7, 64] {
                let mut s = Ransac::new(&pairs, &c, Rng::new(seed ^ 99)).unwrap();
                let mut calls = 0;
                while !s.run_chunk(&pairs, chunk).unwrap() {
                    calls += 1;
                    assert!(calls <= 300 / usize::from(chunk) + 1);
                }
                let mut m2 = [false; 50];
                let two = s.finish(&pairs, &mut m2).unwrap();
                assert_eq!(one, two);
                assert_eq!(m1, m2);
                assert_eq!(s.rng(), r1);
            }
            // Same seed, same bits; another seed draws other samples.
            let mut r3 = Rng::new(seed ^ 99);
            assert_eq!(ransac(&pairs, &c, &mut r3, &mut m1).unwrap(), one);
        }
    }

    /// Verifies: VTSM-POSE-013, VTSM-POSE-014
    #[test]
    fn early_exit_follows_confidence_formula() {
        for (p, w) in [(0.99f32, 0.5f32), (0.999, 0.4), (0.9999, 0.3), (0.5, 0.9)] {
            let n = 100;
            let inl = (w * n as f32) as u16;
            let reference = ((1.0 - f64::from(p)).ln() / (1.0 - f64::from(w).powi(3)).ln()).ceil();
            let got = f64::from(required_iterations(inl, n, p));
            assert!(
                (got - reference).abs() <= 1.0,
                "p {p} w {w}: {got} vs {reference}"
            );
        }
        assert_eq!(required_iterations(10, 10, 0.999), 1);
        assert_eq!(required_iterations(0, 10, 0.999), u32::MAX);
        // Clean data: the first good sample gives w = 1 and the search stops.
        let mut rng = Rng::new(10);
        let truth = random_pose(&mut rng);
        let pairs = contaminated(&mut rng, &truth, 40, 0, 0.001);
        let mut mask = [false; 40];
        let e = ransac(&pairs, &cfg(1000), &mut rng, &mut mask).unwrap();
        assert!(e.stats.early_exit && e.iterations <= 3, "{:?}", e.stats);
        assert_eq!(e.inliers, 40);
        assert!(mask.iter().all(|&m| m));
        // rms is the RMS of the inlier residuals.
        let rms = (pairs
            .iter()
            .map(|p| f64::from((e.pose.transform_point(&p.cam) - p.world).norm_squared()))
            .sum::<f64>()
            / 40.0)
            .sqrt();
        assert!(
            (f64::from(e.rms_m) - rms).abs() < 1e-5,
            "{} vs {rms}",
            e.rms_m
        );
    }

    /// Verifies: VTSM-POSE-014
    #[test]
    fn local_refit_raises_inlier_estimate_and_shortens_search() {
        // Refitting a new best hypothesis on its inliers can only keep or raise
        // its count, so the confidence rule is met sooner on average.
        let (mut with_lo, mut without_lo) = (0u32, 0u32);
        for seed in 0..300u64 {
            let mut rng = Rng::new(seed);
            let truth = random_pose(&mut rng);
            let pairs = contaminated(&mut rng, &truth, 24, 36, 0.01);
            for (lo, total) in [(true, &mut with_lo), (false, &mut without_lo)] {
                let mut s = Ransac::new(&pairs, &cfg(1000), Rng::new(seed))
                    .unwrap()
                    .with_local_refit(lo);
                s.run_chunk(&pairs, u16::MAX).unwrap();
                assert_eq!(s.stats().local_refits > 0, lo);
                *total += u32::from(s.iterations());
                let mut mask = [false; 60];
                let e = s.finish(&pairs, &mut mask).unwrap();
                let (dt, dr) = e.pose.error_to(&truth);
                assert!(dt < 0.02 && dr < 0.01, "seed {seed} lo {lo}: {dt} {dr}");
                // The mask is exactly the gate applied to the returned pose.
                for (p, m) in pairs.iter().zip(mask.iter()) {
                    let r = (e.pose.transform_point(&p.cam) - p.world).norm();
                    assert_eq!(*m, r <= 0.05, "seed {seed}: residual {r}");
                }
            }
        }
        std::println!("iterations over 300 runs: {with_lo} with local refit, {without_lo} without");
        assert!(with_lo < without_lo, "{with_lo} vs {without_lo}");
    }

    /// Verifies: VTSM-POSE-009
    #[test]
    fn candidate_list_keeps_invariants_under_any_insertions() {
        let mut rng = Rng::new(14);
        for _ in 0..200 {
            let centres: Vec<Pose> = (0..12).map(|_| random_pose(&mut rng)).collect();
            let mut list = heapless::Vec::<Candidate, MAX_POSE_CANDIDATES>::new();
            let mut best_seen = 0u16;
            for _ in 0..300 {
                // Hypotheses scattered a few centimetres around a few centres, so
                // many are within the 5 cm separation of each other.
                let c = centres[rng.below(12) as usize];
                let jitter = Pose::new(
                    UnitQuaternion::from_scaled_axis(rng.unit_vector3() * rng.uniform(0.0, 0.01)),
                    rng.unit_vector3() * rng.uniform(0.0, 0.05),
                );
                let cand = Candidate {
                    pose: c.compose(&jitter),
                    inliers: rng.below(60) as u16,
                };
                best_seen = best_seen.max(cand.inliers);
                insert_candidate(&mut list, cand, 3.0, 0.05);
                for (i, x) in list.iter().enumerate() {
                    for y in &list[i + 1..] {
                        assert!(x.inliers >= y.inliers);
                        assert!(pose_distance(&x.pose, &y.pose, 3.0) > 0.05);
                    }
                }
                assert_eq!(list[0].inliers, best_seen);
            }
            assert!(list.len() >= 2);
        }
    }

    /// Verifies: VTSM-POSE-009
    #[test]
    fn candidates_are_distinct_sorted_and_find_second_structure() {
        let mut found_b = 0;
        for seed in 0..50u64 {
            let mut rng = Rng::new(seed);
            let a = random_pose(&mut rng);
            let b = random_pose(&mut rng);
            let mut pairs = contaminated(&mut rng, &a, 24, 10, 0.005);
            pairs.extend(exact_pairs(&mut rng, &b, 16));
            let c = RansacConfig {
                confidence: 0.99999,
                ..cfg(2000)
            };
            let mut mask = [false; 50];
            let e = ransac(&pairs, &c, &mut rng, &mut mask).unwrap();
            let (dt, dr) = e.pose.error_to(&a);
            assert!(dt < 0.02 && dr < 0.01);
            assert_eq!(e.candidates[0].pose, e.pose);
            assert_eq!(e.candidates[0].inliers, e.inliers);
            let lever = pairs.iter().map(|p| p.cam.norm()).sum::<f32>() / 50.0;
            for (i, x) in e.candidates.iter().enumerate() {
                for y in &e.candidates[i + 1..] {
                    assert!(i == 0 || x.inliers >= y.inliers);
                    assert!(pose_distance(&x.pose, &y.pose, lever) > c.inlier_m);
                }
            }
            if e.candidates.iter().any(|k| {
                let (t, r) = k.pose.error_to(&b);
                t < 0.05 && r < 0.02 && k.inliers >= 16
            }) {
                found_b += 1;
            }
        }
        // The second structure needs a clean sample of its 16 pairs, probability
        // C(16,3)/C(50,3) ≈ 0.029 per draw, within the ≈ 99 draws the confidence
        // rule allows once A (w = 0.48) is found: 1 − 0.971⁹⁹ ≈ 0.94 per run,
        // 47 of 50 expected (binomial σ ≈ 1.7).
        assert!(found_b >= 40, "{found_b}/50");
    }

    /// Verifies: VTSM-POSE-008
    #[test]
    fn inlier_gate_scales_with_sigma() {
        let mut rng = Rng::new(11);
        let truth = random_pose(&mut rng);
        let mut pairs = exact_pairs(&mut rng, &truth, 20);
        for p in &mut pairs {
            p.sigma_m = 0.0;
        }
        // Pair 0 is 0.1 m off along z with σ = 0.05 m: gate √(0.05² + 0.15²) ≈ 0.158 m.
        pairs[0].cam.z += 0.1;
        pairs[0].sigma_m = 0.05;
        let mut mask = [false; 20];
        let plain = ransac(&pairs, &cfg(200), &mut rng.fork(1), &mut mask).unwrap();
        assert!(!mask[0] && plain.inliers == 19);
        let scaled = RansacConfig {
            scale_by_sigma: true,
            ..cfg(200)
        };
        let wide = ransac(&pairs, &scaled, &mut rng.fork(1), &mut mask).unwrap();
        assert!(mask[0] && wide.inliers == 20);
    }

    /// Verifies: VTSM-POSE-012
    #[test]
    fn ransac_rejects_bad_inputs_with_codes() {
        let mut rng = Rng::new(12);
        let truth = random_pose(&mut rng);
        let pairs = exact_pairs(&mut rng, &truth, 20);
        let mut mask = [false; 20];
        let c = cfg(100);
        assert_eq!(
            ransac(&pairs[..2], &c, &mut rng, &mut mask).err(),
            Some(FailureCode::PoseTooFewPoints)
        );
        assert_eq!(
            ransac(&pairs, &c, &mut rng, &mut mask[..19]).err(),
            Some(FailureCode::ConfigCapacityTooSmall)
        );
        for bad in [
            RansacConfig { iterations: 0, ..c },
            RansacConfig { inlier_m: 0.0, ..c },
            RansacConfig {
                inlier_m: f32::NAN,
                ..c
            },
            RansacConfig {
                confidence: 1.0,
                ..c
            },
            RansacConfig {
                confidence: 0.0,
                ..c
            },
        ] {
            assert_eq!(
                ransac(&pairs, &bad, &mut rng, &mut mask).err(),
                Some(FailureCode::ConfigParamOutOfRange)
            );
        }
        let mut nan = pairs.clone();
        nan[3].world.x = f32::INFINITY;
        assert_eq!(
            ransac(&nan, &c, &mut rng, &mut mask).err(),
            Some(FailureCode::PoseNonFinite)
        );
        let mut s = Ransac::new(&pairs, &c, Rng::new(1)).unwrap();
        assert_eq!(
            s.run_chunk(&pairs[..10], 5),
            Err(FailureCode::ConfigParamOutOfRange)
        );
        // All pairs collinear: every sample is degenerate, no consensus.
        let line: Vec<_> = (0..20)
            .map(|i| {
                let cam = Vec3::new(0.1 * i as f32, 0.0, 5.0);
                Correspondence {
                    world: truth.transform_point(&cam),
                    cam,
                    sigma_m: 0.0,
                }
            })
            .collect();
        let e = ransac(&line, &c, &mut rng, &mut mask);
        assert_eq!(e.err(), Some(FailureCode::PoseRansacNoConsensus));
        assert!(mask.iter().all(|&m| !m));
        // Params defaults map onto a valid config.
        assert_eq!(
            RansacConfig::from_params(&Params::paper()).validate(),
            Ok(())
        );
    }

    /// Verifies: VTSM-POSE-006
    #[test]
    fn samples_are_distinct_and_uniform() {
        let mut rng = Rng::new(13);
        let mut hits = [0u32; 7];
        for _ in 0..70_000 {
            let [a, b, c] = sample3(&mut rng, 7);
            assert!(a != b && a != c && b != c && a < 7 && b < 7 && c < 7);
            hits[a] += 1;
            hits[b] += 1;
            hits[c] += 1;
        }
        // Each index appears in 3/7 of samples: 30,000 expected, σ ≈ 130.
        for h in hits {
            assert!((h as i32 - 30_000).abs() < 800, "{hits:?}");
        }
        assert_eq!(rng.counter(), 210_000);
        let [a, b, c] = sample3(&mut Rng::new(1), 3);
        let mut s = [a, b, c];
        s.sort();
        assert_eq!(s, [0, 1, 2]);
    }
}
