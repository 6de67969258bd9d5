//! The user frame and the map's local frame (design §5, `core::map` module doc).
//!
//! A mesh, its priors, truths and results are in the mesh's own frame (the
//! *user* frame), which may be georeferenced (UTM eastings ~4·10⁵ m, northings
//! ~4·10⁶ m, where one f32 step is 0.25–0.5 m). A map product keeps an f64
//! origin and stores its vertices as f32 relative to it; the core sees only
//! that *local* frame. The tools convert here, in f64: user → local on the way
//! into the core ([`to_local`]), local → user on the way out ([`to_user`]).
//! Rotations are the same in both frames (the axes are parallel).
//!
//! [`default_origin`] is the origin `vtsm map build` chooses when none is
//! given: the exact centre of the mesh's bounding box. It is a property of the
//! mesh, not of the frame it is written in: the same mesh written in local
//! coordinates or shifted to UTM gets the same local vertices (to ~10⁻⁹ m, the
//! f64 rounding of the shifted coordinates), so the core sees the same map and
//! gives the same answer. A rounded origin would leave the fraction of the
//! shift in the local frame and change the f32 rounding of every vertex.

use crate::error::{Error, Result};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use vtsm_core::geom::Pose;
use vtsm_core::FailureCode;

/// A pose `world_from_left` in the user frame, f64.
pub type UserPose = Isometry3<f64>;

/// The user-frame pose of a JSON pose (quaternion `[w, x, y, z]` renormalised).
pub fn user_pose(t: [f64; 3], q: [f64; 4]) -> UserPose {
    let q = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
    Isometry3::from_parts(Translation3::new(t[0], t[1], t[2]), q)
}

/// Translation and quaternion `[w, x, y, z]` of a user-frame pose.
pub fn user_t_q(p: &UserPose) -> ([f64; 3], [f64; 4]) {
    let t = p.translation.vector;
    let q = p.rotation.quaternion();
    ([t.x, t.y, t.z], [q.w, q.i, q.j, q.k])
}

/// The core (local-frame, f32) pose of a user-frame pose: the origin is
/// subtracted in f64 before the translation is rounded to f32.
///
/// # Errors
/// The core's code when the local pose is not finite in f32
/// ([`Pose::from_t_q`]), e.g. a prior millions of metres from the map.
pub fn to_local(p: &UserPose, origin: [f64; 3]) -> std::result::Result<Pose, FailureCode> {
    let (t, q) = user_t_q(p);
    let local = [t[0] - origin[0], t[1] - origin[1], t[2] - origin[2]];
    Pose::from_t_q(local.map(|v| v as f32), q.map(|v| v as f32))
}

/// The user-frame pose of a core (local-frame) pose: the origin is added in f64.
pub fn to_user(p: &Pose, origin: [f64; 3]) -> UserPose {
    let (t, q) = (p.t(), p.q());
    user_pose(
        [
            f64::from(t[0]) + origin[0],
            f64::from(t[1]) + origin[1],
            f64::from(t[2]) + origin[2],
        ],
        q.map(f64::from),
    )
}

/// `p` moved by `offset` (the same pose of a scene offset by `offset`).
pub fn offset(p: &UserPose, offset: [f64; 3]) -> UserPose {
    Isometry3::from_parts(
        Translation3::from(p.translation.vector + Vector3::from(offset)),
        p.rotation,
    )
}

/// Error of `est` against `truth` (design §3: `(T_true)⁻¹ · T_est`):
/// translation norm, metres, and rotation angle, radians, in f64.
pub fn error_to(est: &UserPose, truth: &UserPose) -> (f64, f64) {
    let d = truth.inverse() * est;
    (d.translation.vector.norm(), d.rotation.angle())
}

/// The default origin of a mesh's map: the centre of the bounding box of
/// `vertices` (user frame), not rounded (`[0, 0, 0]` when empty): see the
/// module doc. The local vertices are then centred, which also gives them the
/// finest f32 steps the mesh allows. `-0` is normalised to `0`, so
/// subtracting the origin never flips the sign of a zero coordinate.
pub fn default_origin(vertices: &[[f64; 3]]) -> [f64; 3] {
    let Some(first) = vertices.first() else {
        return [0.0; 3];
    };
    let (mut lo, mut hi) = (*first, *first);
    for v in vertices {
        for k in 0..3 {
            lo[k] = lo[k].min(v[k]);
            hi[k] = hi[k].max(v[k]);
        }
    }
    [0, 1, 2].map(|k| (0.5 * lo[k] + 0.5 * hi[k]) + 0.0)
}

/// Local f32 vertices of user-frame `vertices` about `origin`: each coordinate
/// is `(v − origin) as f32`, the subtraction in f64.
///
/// # Errors
/// A message naming the first vertex (1-based) whose local coordinates are not
/// finite in f32, or an origin that is not usable (`vtsm_core::map::origin_ok`).
pub fn local_vertices(
    vertices: &[[f64; 3]],
    origin: [f64; 3],
) -> std::result::Result<Vec<[f32; 3]>, String> {
    if !vtsm_core::map::origin_ok(&origin) {
        return Err(format!(
            "map origin ({}, {}, {}) is not finite or beyond ±{} m",
            origin[0],
            origin[1],
            origin[2],
            vtsm_core::config::MAX_MAP_ORIGIN_M
        ));
    }
    vertices
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let l = [0, 1, 2].map(|k| (v[k] - origin[k]) as f32);
            if l.iter().all(|c| c.is_finite()) {
                Ok(l)
            } else {
                Err(format!(
                    "vertex {} at ({}, {}, {}) is out of f32 range about the map origin",
                    i + 1,
                    v[0],
                    v[1],
                    v[2]
                ))
            }
        })
        .collect()
}

/// [`parse_origin`] as a command-line value parser (`--origin X,Y,Z`).
///
/// # Errors
/// As [`parse_origin`], as text.
pub fn origin_arg(s: &str) -> std::result::Result<[f64; 3], String> {
    parse_origin(s).map_err(|e| e.to_string())
}

/// Parse `X,Y,Z` (metres) for an `--origin` option.
///
/// # Errors
/// Not three comma-separated numbers, or an origin that is not usable
/// (`vtsm_core::map::origin_ok`), with [`FailureCode::MapOriginOutOfRange`].
pub fn parse_origin(s: &str) -> Result<[f64; 3]> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let bad = || Error::msg(format!("--origin `{s}`: expected X,Y,Z in metres"));
    if parts.len() != 3 {
        return Err(bad());
    }
    let mut o = [0.0f64; 3];
    for (slot, p) in o.iter_mut().zip(&parts) {
        *slot = p.parse().map_err(|_| bad())?;
    }
    if !vtsm_core::map::origin_ok(&o) {
        return Err(Error::msg(format!(
            "--origin `{s}`: each coordinate must be finite and within ±{} m",
            vtsm_core::config::MAX_MAP_ORIGIN_M
        ))
        .with_code(FailureCode::MapOriginOutOfRange));
    }
    Ok(o)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// User → local → user is exact to f32 rounding of the local translation,
    /// and the local translation is small for a UTM-sized pose.
    ///
    /// Verifies: VTSM-CLI-035
    #[test]
    fn utm_pose_survives_the_local_frame() {
        let origin = [391_235.0, 3_784_322.0, 312.0];
        let p = user_pose(
            [391_236.123_456, 3_784_320.654_321, 313.5],
            [1.0, 0.0, 0.0, 0.0],
        );
        let local = to_local(&p, origin).unwrap();
        assert!((local.t()[0] - 1.123_456).abs() < 1e-6, "{:?}", local.t());
        let back = to_user(&local, origin);
        let (t, r) = error_to(&back, &p);
        assert!(t < 1e-6 && r < 1e-6, "{t} m {r} rad");
        // Without the origin the same pose in f32 is off by up to 0.25 m.
        let direct = to_local(&p, [0.0; 3]).unwrap();
        let (t, _) = error_to(&to_user(&direct, [0.0; 3]), &p);
        assert!(t > 1e-3, "{t}");
    }

    /// The default origin is the box centre, never -0.
    ///
    /// Verifies: VTSM-CLI-035
    #[test]
    fn default_origin_is_the_box_centre() {
        let v = [
            [391_230.5, 3_784_300.0, 300.0],
            [391_240.0, 3_784_341.5, 325.0],
        ];
        assert_eq!(default_origin(&v), [391_235.25, 3_784_320.75, 312.5]);
        let o = default_origin(&[[-0.5, -4.0, -0.25], [0.5, 4.0, 0.25]]);
        assert_eq!(o.map(f64::to_bits), [0.0f64; 3].map(f64::to_bits));
        assert!(parse_origin("1,2").is_err());
        assert!(parse_origin("1,2,nan").is_err());
        assert_eq!(parse_origin(" 1.5, -2 ,3e2").unwrap(), [1.5, -2.0, 300.0]);
    }
}
