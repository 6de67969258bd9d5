//! SE(3) poses and the rectified pinhole stereo camera (design §3 conventions).
//!
//! * World frame: metres, z up. Camera optical frame: x right, y down, z forward.
//! * [`Pose`] is `target_from_source`: `p_target = R p_source + t`. The rover pose
//!   is `world_from_left`.
//! * Pixels: `(u, v) = (fx X/Z + cx, fy Y/Z + cy)`; integer coordinates are pixel
//!   centres, `(0, 0)` the centre of the top-left pixel.
//! * Rectified stereo: the right camera is the left one translated by `+baseline`
//!   along the left x axis, so `p_right = p_left − (B, 0, 0)` and a point has
//!   disparity `d = u_left − u_right = fx B / Z`.
//!
//! All arithmetic is f32 through nalgebra with libm, so results are identical on
//! every target.

use crate::failure::FailureCode;
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};

/// 3-vector of f32.
pub type Vec3 = Vector3<f32>;

/// Smallest depth (metres) at which a point is considered in front of a camera.
pub const MIN_DEPTH_M: f32 = 1.0e-3;

/// A rigid transform `target_from_source`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// The rigid transform.
    pub iso: Isometry3<f32>,
}

impl Default for Pose {
    fn default() -> Self {
        Self::identity()
    }
}

impl Pose {
    /// The identity transform.
    pub fn identity() -> Self {
        Self {
            iso: Isometry3::identity(),
        }
    }

    /// A pose from a rotation and a translation.
    pub fn new(rotation: UnitQuaternion<f32>, translation: Vec3) -> Self {
        Self {
            iso: Isometry3::from_parts(Translation3::from(translation), rotation),
        }
    }

    /// A pose from translation `t` and quaternion `q = [w, x, y, z]` (JSON convention).
    ///
    /// The quaternion must be finite and within 1e-3 of unit norm; it is then
    /// renormalised. Translation must be finite.
    ///
    /// # Errors
    /// [`FailureCode::PoseNonFinite`] otherwise.
    pub fn from_t_q(t: [f32; 3], q: [f32; 4]) -> Result<Self, FailureCode> {
        if !t.iter().chain(q.iter()).all(|v| v.is_finite()) {
            return Err(FailureCode::PoseNonFinite);
        }
        let quat = Quaternion::new(q[0], q[1], q[2], q[3]);
        let n = libm::sqrtf(q.iter().map(|v| v * v).sum::<f32>());
        if (n - 1.0).abs() > 1.0e-3 {
            return Err(FailureCode::PoseNonFinite);
        }
        Ok(Self::new(
            UnitQuaternion::new_normalize(quat),
            Vec3::new(t[0], t[1], t[2]),
        ))
    }

    /// Translation as an array.
    pub fn t(&self) -> [f32; 3] {
        let v = self.iso.translation.vector;
        [v.x, v.y, v.z]
    }

    /// Rotation as `[w, x, y, z]`.
    pub fn q(&self) -> [f32; 4] {
        let q = self.iso.rotation.quaternion();
        [q.w, q.i, q.j, q.k]
    }

    /// The seven numbers of [`Self::t`] then [`Self::q`] as their bit
    /// patterns: what "bit-identical poses" compares.
    pub fn to_bits(&self) -> [u32; 7] {
        let (t, q) = (self.t(), self.q());
        [t[0], t[1], t[2], q[0], q[1], q[2], q[3]].map(f32::to_bits)
    }

    /// Translation vector.
    pub fn translation(&self) -> Vec3 {
        self.iso.translation.vector
    }

    /// Rotation.
    pub fn rotation(&self) -> UnitQuaternion<f32> {
        self.iso.rotation
    }

    /// `self ∘ other`: if `self` is `a_from_b` and `other` is `b_from_c`, the result is `a_from_c`.
    pub fn compose(&self, other: &Pose) -> Pose {
        Pose {
            iso: self.iso * other.iso,
        }
    }

    /// The inverse transform.
    pub fn inverse(&self) -> Pose {
        Pose {
            iso: self.iso.inverse(),
        }
    }

    /// Map a point from the source frame to the target frame.
    pub fn transform_point(&self, p: &Vec3) -> Vec3 {
        self.iso.rotation * p + self.iso.translation.vector
    }

    /// Rotate a direction (no translation).
    pub fn transform_vector(&self, v: &Vec3) -> Vec3 {
        self.iso.rotation * v
    }

    /// Whether all components are finite.
    pub fn is_finite(&self) -> bool {
        self.t()
            .iter()
            .chain(self.q().iter())
            .all(|v| v.is_finite())
    }

    /// Error of `self` (estimate) against `truth` (paper §V-A): `truth⁻¹ · self`,
    /// as (translation norm in metres, rotation angle in radians).
    pub fn error_to(&self, truth: &Pose) -> (f32, f32) {
        let d = truth.inverse().compose(self);
        (d.translation().norm(), d.rotation().angle())
    }
}

/// A pinhole camera with image size (rectified, no distortion).
///
/// Checked type: the fields are private to the core and the only constructors
/// are [`Camera::new`] and [`Camera::from_hfov`], so every camera a caller holds
/// passed their checks; the stages that use it do not check it again.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Camera {
    pub(crate) fx: f32,
    pub(crate) fy: f32,
    pub(crate) cx: f32,
    pub(crate) cy: f32,
    pub(crate) width: u32,
    pub(crate) height: u32,
}

/// Largest accepted focal length, pixels (a 1° horizontal field of view at
/// `MAX_IMAGE_DIM` pixels needs about 4.7·10⁵).
pub const MAX_FOCAL_PX: f32 = 1.0e6;
/// Largest accepted distance of the principal point from pixel (0, 0) along
/// either axis, pixels (the render-window origin bound, 2·`MAX_IMAGE_DIM`).
pub const MAX_PRINCIPAL_PX: f32 = 2.0 * crate::config::MAX_IMAGE_DIM as f32;

/// Whether `f` is an accepted focal length: finite, positive, at most [`MAX_FOCAL_PX`].
pub fn focal_px_ok(f: f32) -> bool {
    // NaN fails both comparisons.
    f > 0.0 && f <= MAX_FOCAL_PX
}

/// Whether `c` is an accepted principal-point coordinate: within ±[`MAX_PRINCIPAL_PX`].
pub fn principal_px_ok(c: f32) -> bool {
    // NaN fails the comparison.
    c.abs() <= MAX_PRINCIPAL_PX
}

/// Whether `d` is an accepted image width or height: `1..=MAX_IMAGE_DIM`.
pub fn image_dim_ok(d: u32) -> bool {
    d > 0 && d as usize <= crate::config::MAX_IMAGE_DIM
}

impl Camera {
    /// A checked camera: focal lengths accepted by [`focal_px_ok`], a
    /// principal point by [`principal_px_ok`], image sides by [`image_dim_ok`].
    ///
    /// # Errors
    /// [`FailureCode::StereoRigInvalid`].
    pub fn new(
        fx: f32,
        fy: f32,
        cx: f32,
        cy: f32,
        width: u32,
        height: u32,
    ) -> Result<Self, FailureCode> {
        let cam = Self {
            fx,
            fy,
            cx,
            cy,
            width,
            height,
        };
        cam.check()?;
        Ok(cam)
    }

    /// The checks of [`Camera::new`]: focal lengths in (0, [`MAX_FOCAL_PX`]], principal
    /// point within ±[`MAX_PRINCIPAL_PX`], width and height in `1..=MAX_IMAGE_DIM`
    /// ([`focal_px_ok`], [`principal_px_ok`], [`image_dim_ok`]). Every value then
    /// is finite, and pixel coordinates of the image fit the rasterizer's
    /// fixed-point range.
    ///
    /// # Errors
    /// [`FailureCode::StereoRigInvalid`].
    pub(crate) fn check(&self) -> Result<(), FailureCode> {
        let ok = focal_px_ok(self.fx)
            && focal_px_ok(self.fy)
            && principal_px_ok(self.cx)
            && principal_px_ok(self.cy)
            && image_dim_ok(self.width)
            && image_dim_ok(self.height);
        if ok {
            Ok(())
        } else {
            Err(FailureCode::StereoRigInvalid)
        }
    }

    /// Focal length along x, pixels.
    pub const fn fx(&self) -> f32 {
        self.fx
    }

    /// Focal length along y, pixels.
    pub const fn fy(&self) -> f32 {
        self.fy
    }

    /// Principal point x, pixels.
    pub const fn cx(&self) -> f32 {
        self.cx
    }

    /// Principal point y, pixels.
    pub const fn cy(&self) -> f32 {
        self.cy
    }

    /// Image width, pixels.
    pub const fn width(&self) -> u32 {
        self.width
    }

    /// Image height, pixels.
    pub const fn height(&self) -> u32 {
        self.height
    }

    /// A camera with square pixels and the principal point at the image centre,
    /// from a horizontal field of view in degrees.
    ///
    /// # Errors
    /// [`FailureCode::StereoRigInvalid`] for a non-finite or out-of-range FOV or size.
    pub fn from_hfov(width: u32, height: u32, hfov_deg: f32) -> Result<Self, FailureCode> {
        if !(hfov_deg.is_finite() && hfov_deg > 1.0 && hfov_deg < 179.0) {
            return Err(FailureCode::StereoRigInvalid);
        }
        let f = (width as f32 * 0.5) / libm::tanf(hfov_deg.to_radians() * 0.5);
        Self::new(
            f,
            f,
            (width as f32 - 1.0) * 0.5,
            (height as f32 - 1.0) * 0.5,
            width,
            height,
        )
    }

    /// Project a camera-frame point; `None` if it is not in front of the camera
    /// (`Z < MIN_DEPTH_M`) or not finite. The pixel may lie outside the image.
    #[inline]
    pub fn project(&self, p: &Vec3) -> Option<[f32; 2]> {
        let in_front = p.z.is_finite() && p.z >= MIN_DEPTH_M;
        if !in_front || !p.x.is_finite() || !p.y.is_finite() {
            return None;
        }
        let inv = 1.0 / p.z;
        Some([self.fx * p.x * inv + self.cx, self.fy * p.y * inv + self.cy])
    }

    /// Back-project pixel `(u, v)` at depth `z` into the camera frame.
    #[inline]
    pub fn back_project(&self, u: f32, v: f32, z: f32) -> Vec3 {
        Vec3::new((u - self.cx) * z / self.fx, (v - self.cy) * z / self.fy, z)
    }

    /// Whether pixel `(u, v)` lies inside the image, `margin` pixels from the border.
    pub fn contains(&self, u: f32, v: f32, margin: f32) -> bool {
        u >= margin
            && v >= margin
            && u <= self.width as f32 - 1.0 - margin
            && v <= self.height as f32 - 1.0 - margin
    }
}

/// A rectified stereo rig: two identical cameras, the right one `baseline_m`
/// along the left camera's +x axis. Checked type, like [`Camera`]: built only
/// by [`StereoRig::new`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StereoRig {
    pub(crate) cam: Camera,
    pub(crate) baseline_m: f32,
}

impl StereoRig {
    /// A checked rig.
    ///
    /// # Errors
    /// [`FailureCode::StereoRigInvalid`] for a non-finite or non-positive baseline.
    pub fn new(cam: Camera, baseline_m: f32) -> Result<Self, FailureCode> {
        if !(baseline_m.is_finite() && baseline_m > 0.0) {
            return Err(FailureCode::StereoRigInvalid);
        }
        Ok(Self { cam, baseline_m })
    }

    /// Intrinsics shared by both cameras.
    pub const fn cam(&self) -> Camera {
        self.cam
    }

    /// Baseline, metres (> 0).
    pub const fn baseline_m(&self) -> f32 {
        self.baseline_m
    }

    /// `left_from_right`: translation by `+baseline` along x.
    pub fn left_from_right(&self) -> Pose {
        Pose::new(
            UnitQuaternion::identity(),
            Vec3::new(self.baseline_m, 0.0, 0.0),
        )
    }

    /// `world_from_right` for a given `world_from_left`.
    pub fn world_from_right(&self, world_from_left: &Pose) -> Pose {
        world_from_left.compose(&self.left_from_right())
    }

    /// Project a left-camera-frame point into both images: `(left_px, right_px)`.
    pub fn project_stereo(&self, p_left: &Vec3) -> Option<([f32; 2], [f32; 2])> {
        let l = self.cam.project(p_left)?;
        let r = self
            .cam
            .project(&(p_left - Vec3::new(self.baseline_m, 0.0, 0.0)))?;
        Some((l, r))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    use crate::testkit::random_pose;

    /// Verifies: VTSM-GEOM-001
    #[test]
    fn composition_and_inversion_round_trip() {
        let mut rng = Rng::new(11);
        for _ in 0..1000 {
            let a = random_pose(&mut rng);
            let b = random_pose(&mut rng);
            let p = Vec3::new(
                rng.uniform(-3.0, 3.0),
                rng.uniform(-3.0, 3.0),
                rng.uniform(-3.0, 3.0),
            );
            let ab = a.compose(&b);
            assert!(
                (ab.transform_point(&p) - a.transform_point(&b.transform_point(&p))).norm() < 1e-4
            );
            let id = a.compose(&a.inverse());
            assert!(id.translation().norm() < 1e-5);
            assert!(id.rotation().angle() < 1e-3);
            assert!((a.inverse().transform_point(&a.transform_point(&p)) - p).norm() < 1e-4);
            let (et, er) = a.error_to(&a);
            assert!(et < 1e-5 && er < 1e-3);
        }
    }

    /// Verifies: VTSM-GEOM-002
    #[test]
    fn projection_round_trips_and_stereo_disparity_matches_depth() {
        let cam = Camera::from_hfov(640, 480, 77.0).unwrap();
        let rig = StereoRig::new(cam, 0.4).unwrap();
        let mut rng = Rng::new(5);
        for _ in 0..1000 {
            let p = Vec3::new(
                rng.uniform(-2.0, 2.0),
                rng.uniform(-2.0, 2.0),
                rng.uniform(0.5, 10.0),
            );
            let [u, v] = cam.project(&p).unwrap();
            assert!((cam.back_project(u, v, p.z) - p).norm() < 1e-4 * p.z);
            let (l, r) = rig.project_stereo(&p).unwrap();
            assert!((l[1] - r[1]).abs() < 1e-3);
            let d = l[0] - r[0];
            assert!((d - cam.fx * 0.4 / p.z).abs() < 1e-2);
        }
        assert!(cam.project(&Vec3::new(0.0, 0.0, -1.0)).is_none());
        assert!(cam.project(&Vec3::new(f32::NAN, 0.0, 1.0)).is_none());
    }

    /// Verifies: VTSM-GEOM-003
    #[test]
    fn rejects_bad_cameras_and_poses() {
        assert!(Camera::new(0.0, 1.0, 0.0, 0.0, 10, 10).is_err());
        assert!(Camera::new(1.0, f32::NAN, 0.0, 0.0, 10, 10).is_err());
        assert!(Camera::new(1.0, 1.0, 0.0, 0.0, 0, 10).is_err());
        assert!(Camera::new(1.0e7, 1.0, 0.0, 0.0, 10, 10).is_err());
        assert!(Camera::new(1.0, 1.0, 0.0, 1.0e5, 10, 10).is_err());
        assert!(Camera::new(1.0, 1.0, 0.0, 0.0, 10, 8193).is_err());
        assert!(Camera::new(MAX_FOCAL_PX, 1.0, -MAX_PRINCIPAL_PX, 0.0, 8192, 1).is_ok());
        let mut lit = Camera::new(500.0, 500.0, 320.0, 240.0, 640, 480).unwrap();
        assert!(lit.check().is_ok());
        lit.width = u32::MAX;
        assert_eq!(lit.check(), Err(FailureCode::StereoRigInvalid));
        assert!(StereoRig::new(Camera::from_hfov(10, 10, 60.0).unwrap(), 0.0).is_err());
        assert!(Pose::from_t_q([0.0; 3], [1.0, 0.0, 0.0, 0.0]).is_ok());
        assert!(Pose::from_t_q([f32::NAN, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]).is_err());
        assert!(Pose::from_t_q([0.0; 3], [2.0, 0.0, 0.0, 0.0]).is_err());
    }
}
