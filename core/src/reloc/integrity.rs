//! The integrity gates of the final estimate ([`super::Gates`]): closed-form,
//! bounded checks that the answer is the depot seen from near the prior.
//!
//! Inputs: the final pose, the prior and its uncertainty, the final inlier
//! set, the refinement's residual. Output: the code of the first gate that
//! fails, or `None`. Bounds: one pass over at most `MAX_CORR` pairs and a
//! closed-form 3×3 symmetric eigenvalue (no iteration). f64 through `libm`,
//! so every target gives the same bits.

use super::Correspondence;
use crate::failure::FailureCode;
use crate::geom::Pose;

/// RMS spread of the camera points of the pairs flagged in `mask`, across
/// their principal direction: √λ₂ of their scatter matrix about the centroid
/// (λ₁ ≥ λ₂ ≥ λ₃), metres. Points all in one cluster or along one line give
/// ~0: such an inlier set fixes the rotation about that line poorly, whatever
/// its count. 0 for fewer than three flagged pairs.
pub fn spread_m(pairs: &[Correspondence], mask: &[bool]) -> f32 {
    let mut n = 0u32;
    let mut c = [0.0f64; 3];
    for (p, _) in pairs.iter().zip(mask).filter(|(_, m)| **m) {
        // At most `pairs.len()` ≤ MAX_CORR: saturating only keeps the count
        // free of an overflow panic path.
        n = n.saturating_add(1);
        for (k, ck) in c.iter_mut().enumerate() {
            *ck += f64::from(p.cam.get(k).copied().unwrap_or(0.0));
        }
    }
    if n < 3 {
        return 0.0;
    }
    let inv = 1.0 / f64::from(n);
    c.iter_mut().for_each(|v| *v *= inv);
    // Scatter s = [a d e; d b f; e f c] / n.
    let (mut a, mut b, mut cc, mut d, mut e, mut f) = (0.0f64, 0.0, 0.0, 0.0, 0.0, 0.0);
    for (p, _) in pairs.iter().zip(mask).filter(|(_, m)| **m) {
        let x = f64::from(p.cam.x) - c[0];
        let y = f64::from(p.cam.y) - c[1];
        let z = f64::from(p.cam.z) - c[2];
        a += x * x;
        b += y * y;
        cc += z * z;
        d += x * y;
        e += x * z;
        f += y * z;
    }
    let l2 = middle_eigenvalue([a * inv, b * inv, cc * inv, d * inv, e * inv, f * inv]);
    let s = libm::sqrt(l2.max(0.0)) as f32;
    if s.is_finite() {
        s
    } else {
        0.0
    }
}

/// The middle eigenvalue of the symmetric matrix `[a d e; d b f; e f c]`
/// given as `[a, b, c, d, e, f]`, by the trigonometric closed form.
fn middle_eigenvalue([a, b, c, d, e, f]: [f64; 6]) -> f64 {
    let p1 = d * d + e * e + f * f;
    let q = (a + b + c) / 3.0;
    let p2 = (a - q) * (a - q) + (b - q) * (b - q) + (c - q) * (c - q) + 2.0 * p1;
    let p = libm::sqrt(p2 / 6.0);
    if p.is_nan() || p <= 1.0e-30 {
        // A multiple of the identity (or NaN): every eigenvalue is q.
        return q;
    }
    let (ba, bb, bc, bd, be, bf) = ((a - q) / p, (b - q) / p, (c - q) / p, d / p, e / p, f / p);
    let det = ba * (bb * bc - bf * bf) - bd * (bd * bc - bf * be) + be * (bd * bf - bb * be);
    let r = (det / 2.0).clamp(-1.0, 1.0);
    let phi = libm::acos(r) / 3.0;
    let l1 = q + 2.0 * p * libm::cos(phi);
    let l3 = q + 2.0 * p * libm::cos(phi + 2.0 * core::f64::consts::PI / 3.0);
    3.0 * q - l1 - l3
}

/// Translation (metres) and rotation (radians) between `pose` and `prior`.
pub fn distance_to(prior: &Pose, pose: &Pose) -> (f32, f32) {
    let dt = (pose.translation() - prior.translation()).norm();
    let dr = prior.rotation().angle_to(&pose.rotation());
    (dt, dr)
}

/// What the gates are given about the final estimate.
#[derive(Clone, Copy, Debug)]
pub struct Evidence {
    /// Final `world_from_left`.
    pub pose: Pose,
    /// Prior `world_from_left`.
    pub prior: Pose,
    /// Prior uncertainty half-widths (metres, radians).
    pub prior_t_m: f32,
    /// See `prior_t_m`.
    pub prior_r_rad: f32,
    /// [`spread_m`] of the final inliers.
    pub spread_m: f32,
    /// RMS reprojection residual, pixels; `None` when the refinement did not run.
    pub reproj_px: Option<f32>,
}

/// The first gate of `gates` that `ev` fails, in the order prior, spread,
/// residual; `None` if it passes them all (a gate at 0 is off).
pub fn check(gates: &super::Gates, ev: &Evidence) -> Option<FailureCode> {
    if gates.prior_factor > 0.0 {
        let (dt, dr) = distance_to(&ev.prior, &ev.pose);
        // NaN is never within a bound.
        let far = |d: f32, bound: f32| d.is_nan() || d > gates.prior_factor * bound;
        if far(dt, ev.prior_t_m) || far(dr, ev.prior_r_rad) {
            return Some(FailureCode::RelocPoseOutsidePrior);
        }
    }
    if gates.min_spread_m > 0.0 && (ev.spread_m.is_nan() || ev.spread_m < gates.min_spread_m) {
        return Some(FailureCode::RelocInliersDegenerate);
    }
    if let Some(px) = ev.reproj_px {
        if gates.max_reproj_px > 0.0 && (px.is_nan() || px > gates.max_reproj_px) {
            return Some(FailureCode::RelocResidualHigh);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::geom::Vec3;
    use crate::rng::Rng;
    use std::vec::Vec;

    fn pair(cam: Vec3) -> Correspondence {
        Correspondence {
            world: cam,
            cam,
            sigma_m: 0.01,
            variant: crate::pose::VARIANT_UNKNOWN,
            mask_index: crate::pose::MASK_INDEX_UNKNOWN,
        }
    }

    /// Verifies: VTSM-RELOC-031
    #[test]
    fn spread_is_the_second_principal_rms_of_the_inliers() {
        let mut rng = Rng::new(3);
        // Uniform in a box of half-widths (3, 1, 0.01) m, rotated: √λ₂ = 1/√3.
        let rot = nalgebra::UnitQuaternion::from_euler_angles(0.3f32, -0.7, 1.1);
        let pts: Vec<Correspondence> = (0..4000)
            .map(|_| {
                let v = Vec3::new(
                    rng.uniform(-3.0, 3.0),
                    rng.uniform(-1.0, 1.0),
                    rng.uniform(-0.01, 0.01),
                );
                pair(rot * v + Vec3::new(1.0, -2.0, 6.0))
            })
            .collect();
        let all = std::vec![true; pts.len()];
        let s = spread_m(&pts, &all);
        assert!((s - 1.0 / 3.0f32.sqrt()).abs() < 0.02, "{s}");
        // Collinear points (a line of length 6 m) have no spread across it.
        let line: Vec<Correspondence> = (0..50)
            .map(|i| pair(Vec3::new(0.1 * i as f32, 0.05 * i as f32, 5.0)))
            .collect();
        assert!(spread_m(&line, &all[..50]) < 1e-3);
        // Only the flagged pairs count; fewer than three give 0.
        let mut mask = std::vec![false; pts.len()];
        mask[0] = true;
        mask[1] = true;
        assert_eq!(spread_m(&pts, &mask), 0.0);
        // Non-finite input never yields a spread that passes a gate.
        let bad = [pair(Vec3::new(f32::NAN, 0.0, 1.0)); 5];
        assert_eq!(spread_m(&bad, &[true; 5]), 0.0);
    }

    /// Verifies: VTSM-RELOC-031
    #[test]
    fn each_gate_fails_with_its_own_code_and_zero_turns_it_off() {
        let prior = Pose::new(nalgebra::UnitQuaternion::identity(), Vec3::zeros());
        let at = |x: f32, deg: f32| {
            Pose::new(
                nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, deg.to_radians()),
                Vec3::new(x, 0.0, 0.0),
            )
        };
        let gates = super::super::Gates {
            prior_factor: 3.0,
            min_spread_m: 0.5,
            max_reproj_px: 2.0,
        };
        let ev = |pose, spread_m, reproj_px| Evidence {
            pose,
            prior,
            prior_t_m: 0.2,
            prior_r_rad: 1.5f32.to_radians(),
            spread_m,
            reproj_px,
        };
        assert_eq!(check(&gates, &ev(at(0.59, 4.4), 0.6, Some(1.0))), None);
        for (e, code) in [
            (
                ev(at(0.61, 0.0), 0.6, Some(1.0)),
                FailureCode::RelocPoseOutsidePrior,
            ),
            (
                ev(at(0.0, 4.6), 0.6, Some(1.0)),
                FailureCode::RelocPoseOutsidePrior,
            ),
            (
                ev(at(f32::NAN, 0.0), 0.6, Some(1.0)),
                FailureCode::RelocPoseOutsidePrior,
            ),
            (
                ev(at(0.0, 0.0), 0.4, Some(1.0)),
                FailureCode::RelocInliersDegenerate,
            ),
            (
                ev(at(0.0, 0.0), f32::NAN, Some(1.0)),
                FailureCode::RelocInliersDegenerate,
            ),
            (
                ev(at(0.0, 0.0), 0.6, Some(2.5)),
                FailureCode::RelocResidualHigh,
            ),
        ] {
            assert_eq!(check(&gates, &e), Some(code));
            assert_eq!(check(&super::super::Gates::OFF, &e), None);
        }
        // No refinement: the residual gate has nothing to check.
        assert_eq!(check(&gates, &ev(at(0.0, 0.0), 0.6, None)), None);
    }
}
