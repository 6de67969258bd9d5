//! The closed-form rigid fit: Horn's quaternion solution of Umeyama's
//! alignment (no scale), the bounded Jacobi eigen-solver and the degeneracy
//! checks. See the [module documentation](super) for the method.

use super::Correspondence;
use crate::config::MAX_CORR;
use crate::failure::FailureCode;
use crate::geom::{Pose, Vec3};
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
/// Floor on `sigma_m` when weighting by `1/σ²`, metres.
pub const MIN_SIGMA_M: f32 = 1.0e-4;

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
        sweeps = u32::saturating_add(sweeps, 1);
        for (p, q) in JACOBI_PAIRS {
            // No-op masks (every pair is < 4) that let the optimizer drop the
            // bounds checks where it does not unroll this loop.
            let (p, q) = (p & 3, q & 3);
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
    for j in 1..4usize {
        if a[j][j] > a[best & 3][best & 3] {
            best = j;
        }
    }
    let best = best & 3;
    ([v[0][best], v[1][best], v[2][best], v[3][best]], sweeps)
}

/// Weighted rigid fit of `world ≈ R cam + t`. `weight(i, pair)` ≥ 0; pairs with
/// weight 0 do not take part. Inputs are assumed finite (checked by callers).
pub(super) fn fit<W>(pairs: &[Correspondence], weight: W) -> Result<(Pose, FitStats), FailureCode>
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

pub(super) fn check_pairs(pairs: &[Correspondence]) -> Result<(), FailureCode> {
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

pub(super) fn inverse_variance(p: &Correspondence) -> f32 {
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

#[cfg(test)]
#[allow(clippy::needless_range_loop)] // the f64 reference mirrors the textbook index notation
mod tests {
    extern crate std;
    use super::super::test_pairs::{add_noise, exact_pairs, random_cam_point};
    use super::*;
    use crate::rng::Rng;
    use nalgebra::{Matrix3 as M3, Vector3 as V3};
    use proptest::prelude::*;
    use std::vec::Vec;

    use crate::testkit::random_pose;

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
                    variant: crate::pose::VARIANT_UNKNOWN,
                    mask_index: crate::pose::MASK_INDEX_UNKNOWN,
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
                        variant: crate::pose::VARIANT_UNKNOWN,
                        mask_index: crate::pose::MASK_INDEX_UNKNOWN,
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
}
