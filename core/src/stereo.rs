//! `Valid` and `Stereo` (paper §III-D): from a left and a right template peak to
//! a 3D point in the left camera frame, with its depth uncertainty.
//!
//! Inputs: the rectified [`StereoRig`] of [`crate::geom`], the sub-pixel peak
//! `(u, v)` in each image, the epipolar tolerance ε (pixels), the disparity
//! uncertainty σ_d (pixels) and the smallest plausible disparity (pixels).
//! Output: [`Point`] `{ p_cam, sigma_z_m }` or a failure code.
//!
//! * `Valid`: the pair is kept only if `|v_l − v_r| ≤ ε`
//!   ([`FailureCode::StereoEpipolarViolation`] otherwise).
//! * `Stereo`: with `d = u_l − u_r` and the mean row `v = (v_l + v_r)/2`,
//!   `Z = f_x B / d`, `X = (u_l − c_x) Z / f_x`, `Y = (v − c_y) Z / f_y`.
//!   A non-positive disparity or one below the plausible minimum is rejected
//!   ([`FailureCode::StereoDisparityInvalid`]).
//! * Depth uncertainty by first-order propagation of σ_d through `Z = f_x B / d`:
//!   `σ_Z = Z² σ_d / (f_x B)`.
//!
//! Bounds: constant work per call (no loop), no allocation, f32 only.

use crate::failure::FailureCode;
use crate::geom::{StereoRig, Vec3};

/// A triangulated point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// Position in the left camera frame (x right, y down, z forward), metres.
    pub p_cam: Vec3,
    /// One-sigma depth (Z) uncertainty, metres, from the disparity uncertainty.
    pub sigma_z_m: f32,
}

/// The `Valid` step: whether the rows of the left and right peaks differ by at
/// most `epsilon_px`. Non-finite rows or tolerance are never valid.
#[inline]
pub fn epipolar_ok(left: [f32; 2], right: [f32; 2], epsilon_px: f32) -> bool {
    // `<=` on NaN is false, so any NaN rejects.
    (left[1] - right[1]).abs() <= epsilon_px
}

/// One-sigma depth uncertainty `Z² σ_d / (f_x B)` of a point at depth `z_m`.
#[inline]
pub fn depth_sigma_m(rig: &StereoRig, z_m: f32, sigma_d_px: f32) -> f32 {
    z_m * z_m * sigma_d_px / (rig.cam.fx * rig.baseline_m)
}

/// `Valid` + `Stereo`: check the epipolar constraint, then triangulate from the
/// mean row and the disparity.
///
/// `left`, `right` are `[u, v]` peak positions in pixels (sub-pixel allowed);
/// `epsilon_px` is the row tolerance (> 0), `sigma_d_px` the one-sigma disparity
/// uncertainty (≥ 0), `min_disparity_px` the smallest plausible disparity (≥ 0;
/// the disparity must also be strictly positive).
///
/// # Errors
/// * [`FailureCode::ConfigParamOutOfRange`]: a tolerance argument is negative or not finite.
/// * [`FailureCode::StereoPixelNonFinite`]: a peak coordinate is NaN or infinite.
/// * [`FailureCode::StereoEpipolarViolation`]: `|v_l − v_r| > epsilon_px`.
/// * [`FailureCode::StereoDisparityInvalid`]: `d ≤ 0`, `d < min_disparity_px`, or the
///   point would not be finite.
pub fn triangulate(
    rig: &StereoRig,
    left: [f32; 2],
    right: [f32; 2],
    epsilon_px: f32,
    sigma_d_px: f32,
    min_disparity_px: f32,
) -> Result<Point, FailureCode> {
    let args_ok = epsilon_px.is_finite()
        && epsilon_px > 0.0
        && sigma_d_px.is_finite()
        && sigma_d_px >= 0.0
        && min_disparity_px.is_finite()
        && min_disparity_px >= 0.0;
    if !args_ok {
        return Err(FailureCode::ConfigParamOutOfRange);
    }
    // The rig is a checked type (`StereoRig::new`, `Camera::new`): positive
    // finite baseline and focal lengths, finite principal point; no re-check.
    let cam = &rig.cam;
    if !left.iter().chain(right.iter()).all(|c| c.is_finite()) {
        return Err(FailureCode::StereoPixelNonFinite);
    }
    if !epipolar_ok(left, right, epsilon_px) {
        return Err(FailureCode::StereoEpipolarViolation);
    }
    let d = left[0] - right[0];
    if !(d > 0.0 && d >= min_disparity_px) {
        return Err(FailureCode::StereoDisparityInvalid);
    }
    let z = cam.fx * rig.baseline_m / d;
    let v = 0.5 * (left[1] + right[1]);
    let p_cam = cam.back_project(left[0], v, z);
    let sigma_z_m = depth_sigma_m(rig, z, sigma_d_px);
    // A tiny positive disparity with a huge baseline can overflow to infinity.
    if !(p_cam.iter().all(|c| c.is_finite()) && sigma_z_m.is_finite()) {
        return Err(FailureCode::StereoDisparityInvalid);
    }
    Ok(Point { p_cam, sigma_z_m })
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::geom::Camera;
    use crate::rng::Rng;
    use proptest::prelude::*;

    fn rig() -> StereoRig {
        StereoRig::new(Camera::from_hfov(1280, 960, 77.0).unwrap(), 0.4).unwrap()
    }

    /// Verifies: VTSM-STER-002, VTSM-STER-003
    #[test]
    fn triangulation_round_trips_projected_points() {
        let rig = rig();
        let mut rng = Rng::new(3);
        let mut n = 0;
        for _ in 0..10_000 {
            let p = Vec3::new(
                rng.uniform(-3.0, 3.0),
                rng.uniform(-2.0, 2.0),
                rng.uniform(0.8, 15.0),
            );
            let (l, r) = rig.project_stereo(&p).unwrap();
            let q = triangulate(&rig, l, r, 8.0, 0.0, 0.5).unwrap();
            // f32 pixel coordinates carry ~1e-7 relative error; depth error grows
            // with Z² (the disparity is a difference of two ~1e3 px numbers).
            let d = rig.cam.fx * rig.baseline_m / p.z;
            let tol = 1e-4 * p.z * (1.0 + 1e3 / d);
            assert!((q.p_cam - p).norm() < tol, "{p:?} -> {:?}", q.p_cam);
            n += 1;
        }
        assert_eq!(n, 10_000);
    }

    /// Verifies: VTSM-STER-002
    #[test]
    fn triangulation_uses_mean_row() {
        let rig = rig();
        let p = Vec3::new(0.3, -0.2, 4.0);
        let (l, r) = rig.project_stereo(&p).unwrap();
        // Shift the rows symmetrically: the mean row, hence Y, is unchanged.
        let a = triangulate(&rig, [l[0], l[1] + 2.5], [r[0], r[1] - 2.5], 8.0, 0.0, 0.0).unwrap();
        assert!((a.p_cam - p).norm() < 1e-4);
        // Shift only the left row by 2 px: Y moves by Z·1/fy.
        let b = triangulate(&rig, [l[0], l[1] + 2.0], r, 8.0, 0.0, 0.0).unwrap();
        let expect_dy = 1.0 * p.z / rig.cam.fy;
        assert!((b.p_cam.y - p.y - expect_dy).abs() < 1e-4);
    }

    /// Verifies: VTSM-STER-001
    #[test]
    fn epipolar_check_rejects_exactly_pairs_beyond_epsilon() {
        let rig = rig();
        let mut rng = Rng::new(9);
        let eps = 8.0f32;
        let (mut kept, mut rejected) = (0, 0);
        for _ in 0..20_000 {
            let l = [rng.uniform(700.0, 900.0), rng.uniform(0.0, 959.0)];
            let r = [
                l[0] - rng.uniform(20.0, 200.0),
                l[1] + rng.uniform(-16.0, 16.0),
            ];
            // Independent reference in f64.
            let beyond = (f64::from(l[1]) - f64::from(r[1])).abs() > f64::from(eps);
            let res = triangulate(&rig, l, r, eps, 0.1, 1.0);
            if beyond {
                assert_eq!(
                    res,
                    Err(FailureCode::StereoEpipolarViolation),
                    "{l:?} {r:?}"
                );
                rejected += 1;
            } else {
                assert!(res.is_ok(), "{l:?} {r:?}");
                kept += 1;
            }
        }
        assert!(kept > 5_000 && rejected > 5_000);
        // Exactly at the tolerance is kept, one ulp beyond is rejected.
        let l = [800.0, 100.0];
        assert!(triangulate(&rig, l, [700.0, 108.0], eps, 0.0, 0.0).is_ok());
        let beyond = f32::from_bits(108.0f32.to_bits() + 1);
        assert_eq!(
            triangulate(&rig, l, [700.0, beyond], eps, 0.0, 0.0),
            Err(FailureCode::StereoEpipolarViolation)
        );
    }

    /// Verifies: VTSM-STER-003
    #[test]
    fn rejects_non_positive_and_implausibly_small_disparity() {
        let rig = rig();
        let bad = FailureCode::StereoDisparityInvalid;
        assert_eq!(
            triangulate(&rig, [500.0, 10.0], [500.0, 10.0], 8.0, 0.1, 0.0),
            Err(bad)
        );
        assert_eq!(
            triangulate(&rig, [500.0, 10.0], [510.0, 10.0], 8.0, 0.1, 0.0),
            Err(bad)
        );
        assert_eq!(
            triangulate(&rig, [500.0, 10.0], [499.5, 10.0], 8.0, 0.1, 1.0),
            Err(bad)
        );
        assert!(triangulate(&rig, [500.0, 10.0], [499.0, 10.0], 8.0, 0.1, 1.0).is_ok());
        // Non-finite peaks, bad tolerances and bad rigs have their own codes.
        assert_eq!(
            triangulate(&rig, [f32::NAN, 10.0], [499.0, 10.0], 8.0, 0.1, 1.0),
            Err(FailureCode::StereoPixelNonFinite)
        );
        assert_eq!(
            triangulate(&rig, [500.0, 10.0], [499.0, f32::INFINITY], 8.0, 0.1, 1.0),
            Err(FailureCode::StereoPixelNonFinite)
        );
        for (e, s, m) in [(0.0, 0.1, 1.0), (8.0, -0.1, 1.0), (8.0, 0.1, f32::NAN)] {
            assert_eq!(
                triangulate(&rig, [500.0, 10.0], [499.0, 10.0], e, s, m),
                Err(FailureCode::ConfigParamOutOfRange)
            );
        }
        // A rig with a zero baseline cannot be built, so none reaches triangulate.
        assert_eq!(
            StereoRig::new(rig.cam(), 0.0),
            Err(FailureCode::StereoRigInvalid)
        );
        // A disparity so small that Z overflows f32 is rejected, not returned as inf.
        let wide = StereoRig::new(rig.cam(), 1.0e37).unwrap();
        assert_eq!(
            triangulate(&wide, [500.0, 10.0], [499.0, 10.0], 8.0, 0.1, 0.0),
            Err(bad)
        );
    }

    /// Verifies: VTSM-STER-004
    #[test]
    fn depth_sigma_matches_monte_carlo_spread() {
        // Perturb the right peak by Gaussian disparity noise and compare the
        // empirical depth spread with σ_Z = Z² σ_d / (f B).
        let rig = rig();
        let mut rng = Rng::new(21);
        let sigma_d = 0.25f32;
        for z in [2.0f32, 5.0, 10.0] {
            let p = Vec3::new(0.2, 0.1, z);
            let (l, r) = rig.project_stereo(&p).unwrap();
            let pred = triangulate(&rig, l, r, 8.0, sigma_d, 0.0)
                .unwrap()
                .sigma_z_m;
            let expect = z * z * sigma_d / (rig.cam.fx * 0.4);
            assert!((pred - expect).abs() <= 1e-3 * expect);
            let n = 20_000;
            let mut sum2 = 0.0f64;
            for _ in 0..n {
                let rr = [r[0] + sigma_d * rng.normal(), r[1]];
                let q = triangulate(&rig, l, rr, 8.0, sigma_d, 0.0).unwrap();
                sum2 += f64::from(q.p_cam.z - z).powi(2);
            }
            let emp = (sum2 / f64::from(n)).sqrt() as f32;
            // First order is accurate while σ_d ≪ d (d ≥ 20 px here); MC error ~1 %.
            assert!(
                (emp / pred - 1.0).abs() < 0.05,
                "z={z} emp={emp} pred={pred}"
            );
        }
    }

    proptest! {
        /// Verifies: VTSM-STER-005
        #[test]
        fn any_input_gives_finite_point_or_code(
            ul in -1e6f32..1e6, vl in -1e6f32..1e6, ur in -1e6f32..1e6, vr in -1e6f32..1e6,
            eps in 0.01f32..64.0, md in 0.0f32..10.0,
        ) {
            match triangulate(&rig(), [ul, vl], [ur, vr], eps, 0.2, md) {
                Ok(p) => {
                    prop_assert!(p.p_cam.iter().all(|c| c.is_finite()));
                    prop_assert!(p.p_cam.z > 0.0 && p.sigma_z_m >= 0.0);
                    prop_assert!((vl - vr).abs() <= eps && ul - ur >= md);
                }
                Err(c) => prop_assert!(matches!(
                    c,
                    FailureCode::StereoEpipolarViolation | FailureCode::StereoDisparityInvalid
                )),
            }
        }
    }
}
