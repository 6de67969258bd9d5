//! How the reported covariance covers the true error.

use crate::eval::columns::CovarianceColumns;
use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3};
use vtsm_core::geom::Pose;

/// Squared Mahalanobis distances of the world-frame position error
/// `t_est − t_true` (3×3 translation block) and of the world-frame rotation
/// vector `φ` with `R_true = exp([φ]×) R_est` (rotation block), and the 1-σ
/// radii `√tr` of each block (mm, degrees).
pub fn covariance_check(
    est: &Pose,
    truth: &Pose,
    c: &vtsm_core::pose::Covariance,
) -> CovarianceColumns {
    let dt = t64(est) - t64(truth);
    let phi = (q64(truth) * q64(est).inverse()).scaled_axis();
    let block = |o: usize| Matrix3::from_fn(|i, j| f64::from(c.get(o + i, o + j)));
    let d2 = |e: Vector3<f64>, m: Matrix3<f64>| {
        m.try_inverse()
            .map_or(f64::NAN, |inv| (e.transpose() * inv * e)[(0, 0)])
    };
    CovarianceColumns {
        d2_t: d2(dt, block(0)),
        d2_r: d2(phi, block(3)),
        sigma_t_mm: block(0).trace().max(0.0).sqrt() * 1e3,
        sigma_r_deg: block(3).trace().max(0.0).sqrt().to_degrees(),
    }
}

fn q64(p: &Pose) -> UnitQuaternion<f64> {
    let q = p.q();
    UnitQuaternion::from_quaternion(Quaternion::new(
        f64::from(q[0]),
        f64::from(q[1]),
        f64::from(q[2]),
        f64::from(q[3]),
    ))
}

fn t64(p: &Pose) -> Vector3<f64> {
    let t = p.t();
    Vector3::new(f64::from(t[0]), f64::from(t[1]), f64::from(t[2]))
}
