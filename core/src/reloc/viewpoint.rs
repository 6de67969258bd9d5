//! RandomizeViewpoint (paper §III-B) and the Distribute pick (§III-E).
//!
//! Input: a centre pose `world_from_left`, bounds t̃ (metres) and r̃ (radians),
//! an [`Rng`]. Output: a perturbed pose. Constant work: a fixed number of draws.

use super::Candidate;
use crate::geom::{Pose, Vec3};
use crate::rng::Rng;
use nalgebra::UnitQuaternion;

/// Perturb `center`: a rotation about a uniform random axis by an angle uniform
/// in `[-r_rad, r_rad]` (applied in the camera frame), and a translation of
/// magnitude uniform in `[-t_m, t_m]` along a uniform direction in the world
/// ground plane (`planar`, world x-y, z up) or on the unit sphere.
///
/// Draws exactly 6 values from `rng` in both modes, so the stream position does
/// not depend on the mode.
pub fn randomize(center: &Pose, t_m: f32, r_rad: f32, planar: bool, rng: &mut Rng) -> Pose {
    let axis = rng.unit_vector3();
    let angle = rng.uniform(-r_rad, r_rad);
    let magnitude = rng.uniform(-t_m, t_m);
    let sphere = rng.unit_vector3();
    let dir = if planar {
        // Azimuth from the sphere draw's own longitude keeps the draw count fixed.
        let h = libm::sqrtf(sphere.x * sphere.x + sphere.y * sphere.y);
        if h > 1.0e-6 {
            Vec3::new(sphere.x / h, sphere.y / h, 0.0)
        } else {
            Vec3::new(1.0, 0.0, 0.0)
        }
    } else {
        sphere
    };
    let rot = center.rotation() * UnitQuaternion::from_scaled_axis(axis * angle);
    Pose::new(rot, center.translation() + dir * magnitude)
}

/// Distribute: pick one of `candidates` with probability proportional to its
/// inliers (one draw). Returns `None` when there is no candidate with inliers.
pub fn pick_candidate(candidates: &[Candidate], rng: &mut Rng) -> Option<Pose> {
    let total = candidates
        .iter()
        .fold(0u32, |s, c| s.saturating_add(u32::from(c.inliers)));
    let mut u = rng.below(total);
    if total == 0 {
        return None;
    }
    for c in candidates {
        let w = u32::from(c.inliers);
        if u < w {
            return Some(c.pose);
        }
        u -= w;
    }
    None
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    fn center() -> Pose {
        Pose::new(
            UnitQuaternion::from_euler_angles(0.3, -1.2, 2.0),
            Vec3::new(1.0, -2.0, 0.5),
        )
    }

    /// Verifies: VTSM-RELOC-004
    #[test]
    fn perturbation_stays_within_bounds_planar_then_spherical() {
        let c = center();
        let (t, r) = (0.2f32, 1.5f32.to_radians());
        let mut rng = Rng::new(9);
        let mut max_t = 0.0f32;
        let mut max_r = 0.0f32;
        let mut max_abs_dz_sphere = 0.0f32;
        for i in 0..4000 {
            let planar = i % 2 == 0;
            let before = rng.counter();
            let p = randomize(&c, t, r, planar, &mut rng);
            assert_eq!(rng.counter() - before, 6);
            let d = p.translation() - c.translation();
            let angle = c.rotation().rotation_to(&p.rotation()).angle();
            assert!(d.norm() <= t + 1e-5, "{}", d.norm());
            assert!(angle <= r + 1e-5, "{angle}");
            if planar {
                assert!(d.z.abs() < 1e-6, "planar step left the ground plane: {d:?}");
            } else {
                max_abs_dz_sphere = max_abs_dz_sphere.max(d.z.abs());
            }
            max_t = max_t.max(d.norm());
            max_r = max_r.max(angle);
        }
        // The bounds are actually explored, not just respected.
        assert!(max_t > 0.95 * t && max_r > 0.95 * r);
        assert!(max_abs_dz_sphere > 0.5 * t);
    }

    /// Verifies: VTSM-RELOC-008
    #[test]
    fn distribute_picks_in_proportion_to_inliers() {
        let mk = |x: f32, n: u16| Candidate {
            pose: Pose::new(UnitQuaternion::identity(), Vec3::new(x, 0.0, 0.0)),
            inliers: n,
        };
        let cands = [mk(0.0, 10), mk(1.0, 15), mk(2.0, 25)];
        let mut rng = Rng::new(3);
        let mut hits = [0u32; 3];
        let n = 50_000;
        for _ in 0..n {
            let p = pick_candidate(&cands, &mut rng).unwrap();
            hits[p.translation().x as usize] += 1;
        }
        for (h, expect) in hits.iter().zip([0.2f64, 0.3, 0.5]) {
            let f = f64::from(*h) / f64::from(n);
            assert!((f - expect).abs() < 0.01, "{hits:?}");
        }
        assert!(pick_candidate(&[], &mut rng).is_none());
        assert!(pick_candidate(&[mk(0.0, 0)], &mut rng).is_none());
    }
}
