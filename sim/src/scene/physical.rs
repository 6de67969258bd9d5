//! Physical (unrectified, distorted) stereo captures, as a real rig calibrated
//! with OpenCV would deliver them.
//!
//! [`physical_calib`] derives a fixed, plausible physical rig from the ideal
//! rectified one of a profile: slightly different intrinsics per camera
//! (focal lengths within ±0.5 %, principal points off centre by up to 0.6 % of
//! the image), barrel distortion (`k1 ≈ -0.1`, `k2 ≈ 0.02`, tangential terms of a
//! few 1e-4) and a relative rotation of 0.5° with a baseline a little off the
//! x axis. [`capture_physical`] renders a capture of the grid through these
//! cameras: every supersample ray is the exact undistorted ray of its
//! (distorted) pixel position ([`crate::rectify::PhysicalCamera::ray`]) cast
//! into the terrain by [`crate::render::render_rays`], so distortion costs no
//! resampling. The physical left camera stands where the ideal left camera of
//! the capture does (the truth pose); the right camera follows from `R`, `T`.

use super::{capture_pose, Capture, Scene, StereoPair};
use crate::io::calib::model::{OpenCvCalib, OpenCvCamera};
use crate::rectify::PhysicalCamera;
use crate::render::{render_rays, Lighting, RenderOptions};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use vtsm_core::geom::{Pose, StereoRig, Vec3};
use vtsm_core::rng::Rng;

/// Relative rotation of the physical pair (right from left), degrees.
pub const RELATIVE_ROTATION_DEG: f64 = 0.5;
/// Distortion `k1,k2,p1,p2,k3` of the left camera.
pub const LEFT_DIST: [f64; 5] = [-0.10, 0.02, 0.0006, -0.0004, 0.0];
/// Distortion `k1,k2,p1,p2,k3` of the right camera.
pub const RIGHT_DIST: [f64; 5] = [-0.095, 0.018, -0.0005, 0.0003, 0.001];

/// The physical rig standing in for `rig` (same image size and baseline length
/// scale): see the module documentation for the values.
pub fn physical_calib(rig: &StereoRig) -> OpenCvCalib {
    let c = rig.cam();
    let (f, w, h) = (
        f64::from(c.fx()),
        f64::from(c.width()),
        f64::from(c.height()),
    );
    let (cx, cy) = (f64::from(c.cx()), f64::from(c.cy()));
    let k = |sx: f64, sy: f64, dx: f64, dy: f64| {
        [
            [f * sx, 0.0, cx + dx * w],
            [0.0, f * sy, cy + dy * h],
            [0.0, 0.0, 1.0],
        ]
    };
    let axis = Vector3::new(0.3, 1.0, 0.4).normalize();
    let r = Rotation3::from_scaled_axis(axis * RELATIVE_ROTATION_DEG.to_radians()).into_inner();
    let b = f64::from(rig.baseline_m());
    let c_right = Vector3::new(b, 0.01 * b, -0.008 * b);
    let t = -(r * c_right);
    OpenCvCalib {
        image_size: [c.width(), c.height()],
        left: OpenCvCamera {
            k: k(1.004, 1.002, 0.006, -0.004),
            dist: LEFT_DIST.to_vec(),
        },
        right: OpenCvCamera {
            k: k(0.997, 0.995, -0.005, 0.003),
            dist: RIGHT_DIST.to_vec(),
        },
        r: [
            [r[(0, 0)], r[(0, 1)], r[(0, 2)]],
            [r[(1, 0)], r[(1, 1)], r[(1, 2)]],
            [r[(2, 0)], r[(2, 1)], r[(2, 2)]],
        ],
        t: [t.x, t.y, t.z],
    }
}

/// `left_from_right` of a physical calibration (`X_left = Rᵀ (X_right - T)`), as
/// a core pose.
pub fn left_from_right(c: &OpenCvCalib) -> Pose {
    let r = Matrix3::from_fn(|i, j| c.r[i][j]);
    let t = Vector3::new(c.t[0], c.t[1], c.t[2]);
    let rt = Rotation3::from_matrix_eps(&r.transpose(), 1e-15, 100, Rotation3::identity());
    let centre = -(r.transpose() * t);
    let q = UnitQuaternion::from_rotation_matrix(&rt).cast::<f32>();
    Pose::new(
        UnitQuaternion::new_normalize(q.into_inner()),
        Vec3::new(centre.x as f32, centre.y as f32, centre.z as f32),
    )
}

/// Render one physical camera.
fn render_physical(
    scene: &Scene,
    light: &Lighting,
    cam: &PhysicalCamera,
    size: (u32, u32),
    world_from_cam: &Pose,
    opts: &RenderOptions,
) -> Vec<u8> {
    render_rays(
        &scene.terrain,
        light,
        size,
        [cam.cx as f32, cam.cy as f32],
        world_from_cam,
        opts,
        |u, v| {
            cam.ray(f64::from(u), f64::from(v))
                .map(|(x, y)| Vec3::new(x as f32, y as f32, 1.0))
        },
    )
}

/// A capture of the grid through the physical rig of [`physical_calib`]:
/// calibration, truth `world_from_left` of the physical left camera and the
/// distorted pair (sensor noise seeded as [`Scene::capture`] seeds it).
pub fn capture_physical(
    scene: &Scene,
    light: &Lighting,
    c: &Capture,
) -> (OpenCvCalib, Pose, StereoPair) {
    let rig = scene.rig(c.baseline_m);
    let calib = physical_calib(&rig);
    let truth = capture_pose(&scene.terrain, c);
    let noise_seed = Rng::new(scene.seed)
        .fork(
            u64::from(c.circle * 100 + c.stop * 2 + c.look_at)
                ^ (u64::from(c.baseline_m.to_bits()) << 20),
        )
        .next_u64();
    let opts = scene.render_options(noise_seed);
    let ropts = RenderOptions {
        noise_seed: Rng::new(noise_seed).fork(0x0052_4947_4854).next_u64(),
        ..opts
    };
    let size = calib.size();
    let left = render_physical(
        scene,
        light,
        &PhysicalCamera::from_opencv(&calib.left),
        size,
        &truth,
        &opts,
    );
    let right = render_physical(
        scene,
        light,
        &PhysicalCamera::from_opencv(&calib.right),
        size,
        &truth.compose(&left_from_right(&calib)),
        &ropts,
    );
    (
        calib,
        truth,
        StereoPair {
            width: size.0,
            height: size.1,
            left,
            right,
        },
    )
}
