//! The bounded RANSAC around the fit: settings, the resumable [`Ransac`]
//! state, 3-point hypothesis sampling, the inlier gate, local and final refits
//! and the candidate list. See the [module documentation](super) for the method.

use super::fit::{check_pairs, fit, inverse_variance};
use super::{Candidate, Correspondence, Estimate};
use crate::config::{Params, MAX_POSE_CANDIDATES, MAX_RANSAC_ITER};
use crate::failure::FailureCode;
use crate::geom::Pose;
use crate::rng::Rng;
use nalgebra::Matrix3;

/// Default RANSAC confidence `p` of the early-exit rule.
pub const DEFAULT_CONFIDENCE: f32 = 0.999;
/// Default [`RansacConfig::sigma_gate`]: a pair's gate is `√(inlier_m² + (SIGMA_GATE·σ)²)`.
pub const SIGMA_GATE: f32 = 3.0;
/// Refit-and-recount rounds after the RANSAC search.
pub const REFIT_ROUNDS: u32 = 3;

/// RANSAC settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RansacConfig {
    /// Iteration cap, 1..=[`MAX_RANSAC_ITER`].
    pub iterations: u16,
    /// Inlier gate on the 3D residual `|world − (R cam + t)|`, metres, > 0.
    pub inlier_m: f32,
    /// Early-exit confidence `p`, in (0, 1).
    pub confidence: f32,
    /// Widen each pair's gate to `√(inlier_m² + (sigma_gate·sigma_m)²)`
    /// (0: the fixed gate `inlier_m`), finite, ≥ 0.
    pub sigma_gate: f32,
}

impl RansacConfig {
    /// Settings from validated [`Params`] (`ransac_iter`, `inlier_m`), with
    /// [`DEFAULT_CONFIDENCE`] and the gate scaled by sigma.
    pub fn from_params(p: &Params) -> Self {
        Self {
            iterations: p.ransac_iter,
            inlier_m: p.inlier_m,
            confidence: DEFAULT_CONFIDENCE,
            sigma_gate: SIGMA_GATE,
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
            && self.sigma_gate.is_finite()
            && self.sigma_gate >= 0.0
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
    // Each draw is below n − 1 or n − 2 and is raised at most by one per index
    // it passes, so it stays below n: the increments cannot wrap.
    let i0 = rng.below(n);
    let mut i1 = rng.below(n.saturating_sub(1));
    if i1 >= i0 {
        i1 = i1.wrapping_add(1);
    }
    let (lo, hi) = if i0 < i1 { (i0, i1) } else { (i1, i0) };
    let mut i2 = rng.below(n.saturating_sub(2));
    if i2 >= lo {
        i2 = i2.wrapping_add(1);
    }
    if i2 >= hi {
        i2 = i2.wrapping_add(1);
    }
    [i0 as usize, i1 as usize, i2 as usize]
}

fn gate_sq(cfg: &RansacConfig, p: &Correspondence) -> f32 {
    let base = cfg.inlier_m * cfg.inlier_m;
    let s = cfg.sigma_gate * p.sigma_m;
    base + s * s
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
    retain_where(list, |e| !close(e));
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
    insert_at(list, pos, c);
}

/// `heapless::Vec::retain` without its panic paths (an overflow-checked
/// subtraction in its drop guard): keeps the entries `keep` accepts, in order.
fn retain_where<const N: usize>(
    list: &mut heapless::Vec<Candidate, N>,
    keep: impl Fn(&Candidate) -> bool,
) {
    let mut n = 0usize;
    for i in 0..list.len() {
        if let Some(e) = list.get(i).copied() {
            if keep(&e) {
                if let Some(d) = list.get_mut(n) {
                    *d = e;
                }
                // n ≤ i < len: cannot wrap.
                n = n.wrapping_add(1);
            }
        }
    }
    list.truncate(n);
}

/// Insert `c` at `pos` (clamped to the length), shifting the tail; returns
/// `false`, changing nothing, when the list is full. `heapless::Vec::insert`
/// panics for `pos > len`; this has no panic path.
fn insert_at<const N: usize>(
    list: &mut heapless::Vec<Candidate, N>,
    pos: usize,
    c: Candidate,
) -> bool {
    let pos = pos.min(list.len());
    if list.push(c).is_err() {
        return false;
    }
    // Shift `pos..len − 1` one place right (the push made room), then place `c`.
    let mut i = list.len().saturating_sub(1);
    while i > pos {
        let prev = i.wrapping_sub(1);
        if let Some(e) = list.get(prev).copied() {
            if let Some(d) = list.get_mut(i) {
                *d = e;
            }
        }
        i = prev;
    }
    if let Some(d) = list.get_mut(pos) {
        *d = c;
    }
    true
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
    /// [`MAX_CORR`](crate::config::MAX_CORR) pairs; [`FailureCode::PoseTooFewPoints`],
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
        self.stats.iterations = self.stats.iterations.saturating_add(1);
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
                self.stats.distance_rejects = self.stats.distance_rejects.saturating_add(1);
                return;
            }
        }
        let (pose, fs) = match fit(&s, |_, _| 1.0) {
            Ok(v) => v,
            Err(_) => {
                self.stats.degenerate_samples = self.stats.degenerate_samples.saturating_add(1);
                return;
            }
        };
        self.stats.jacobi_sweeps = self.stats.jacobi_sweeps.saturating_add(fs.jacobi_sweeps);
        let (inliers, _, _) = score(pairs, &self.cfg, &pose, None);
        self.stats.hypotheses_scored = self.stats.hypotheses_scored.saturating_add(1);
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
        self.stats.local_refits = self.stats.local_refits.saturating_add(1);
        self.stats.residuals_evaluated = self
            .stats
            .residuals_evaluated
            .saturating_add((self.n as u32).saturating_mul(3));
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
            self.stats.refits = self.stats.refits.saturating_add(1);
            if !changed {
                break;
            }
        }
        let rms_m = libm::sqrtf(sum_sq / f32::from(inliers.max(1)));
        let mut candidates = self.candidates.clone();
        let fin = Candidate { pose, inliers };
        // The refined pose leads the list (even if the refit lost a few inliers
        // against its 3-point hypothesis); entries it duplicates are dropped.
        retain_where(&mut candidates, |c| {
            pose_distance(&c.pose, &pose, self.lever_m) > self.cfg.inlier_m
        });
        if candidates.is_full() {
            candidates.pop();
        }
        if !insert_at(&mut candidates, 0, fin) {
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
mod tests {
    extern crate std;
    use super::super::test_pairs::{add_noise, exact_pairs, random_cam_point};
    use super::*;
    use crate::config::MAX_CORR;
    use crate::geom::Vec3;
    use nalgebra::UnitQuaternion;
    use std::vec::Vec;

    use crate::testkit::random_pose;

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
                variant: crate::pose::VARIANT_UNKNOWN,
                mask_index: crate::pose::MASK_INDEX_UNKNOWN,
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
            sigma_gate: 0.0,
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
                sigma_gate: if seed % 2 == 0 { SIGMA_GATE } else { 0.0 },
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
            sigma_gate: SIGMA_GATE,
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
            RansacConfig {
                sigma_gate: -1.0,
                ..c
            },
            RansacConfig {
                sigma_gate: f32::INFINITY,
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
                    variant: crate::pose::VARIANT_UNKNOWN,
                    mask_index: crate::pose::MASK_INDEX_UNKNOWN,
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
