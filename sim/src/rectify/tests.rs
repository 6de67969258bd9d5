#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use super::*;
use crate::io::calib::model::{OpenCvCalib, OpenCvCamera};
use vtsm_core::rng::Rng;

fn cam(fx: f64, fy: f64, cx: f64, cy: f64, dist: &[f64]) -> OpenCvCamera {
    OpenCvCamera {
        k: [[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]],
        dist: dist.to_vec(),
    }
}

fn arr(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    [
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
    ]
}

/// A physical rig: left at the origin, right camera centre `c_right` (left frame)
/// and `right_from_left` rotation `r`.
fn calib(
    left: OpenCvCamera,
    right: OpenCvCamera,
    r: Matrix3<f64>,
    c_right: Vector3<f64>,
) -> OpenCvCalib {
    let t = -(r * c_right);
    OpenCvCalib {
        image_size: [160, 120],
        left,
        right,
        r: arr(&r),
        t: [t.x, t.y, t.z],
    }
}

fn max_abs(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    (a - b).abs().max()
}

fn test_image(w: u32, h: u32) -> Gray8 {
    let mut rng = Rng::new(5);
    Gray8 {
        width: w,
        height: h,
        pixels: (0..w * h).map(|_| (rng.next_u32() & 0xff) as u8).collect(),
    }
}

/// Identical pinhole cameras, no distortion, the right one translated along +x:
/// the rectification is the identity and the map reproduces the image exactly.
///
/// Verifies: VTSM-SIM-013
#[test]
fn identity_calib_gives_identity_map() {
    let k = cam(100.0, 100.0, 81.0, 58.5, &[0.0; 5]);
    let c = calib(
        k.clone(),
        k,
        Matrix3::identity(),
        Vector3::new(0.3, 0.0, 0.0),
    );
    let r = stereo_rectify(&c).unwrap();
    assert!(max_abs(&r.r1, &Matrix3::identity()) < 1e-15);
    assert!(max_abs(&r.r2, &Matrix3::identity()) < 1e-15);
    assert_eq!(r.f_px, 100.0);
    assert!(
        (r.c_px[0] - 81.0).abs() < 1e-4 && (r.c_px[1] - 58.5).abs() < 1e-4,
        "{:?}",
        r.c_px
    );
    assert!((r.baseline_m - 0.3).abs() < 1e-15);
    assert!((r.p2[0][3] + 30.0).abs() < 1e-12);
    let rect = Rectifier::new(&c).unwrap();
    let (left_map, _) = rect.maps();
    for (i, (&x, &y)) in left_map.map_x.iter().zip(&left_map.map_y).enumerate() {
        let (u, v) = ((i % 160) as f32, (i / 160) as f32);
        assert!(
            (x - u).abs() < 1e-3 && (y - v).abs() < 1e-3,
            "({u},{v}) -> ({x},{y})"
        );
    }
    let img = test_image(160, 120);
    let (l, rr) = rect.rectify_pair(&img, &img);
    // Sub-1e-3 px offsets of the principal point move no 8-bit value by more than 1.
    let diff = l
        .pixels
        .iter()
        .zip(&img.pixels)
        .map(|(a, b)| a.abs_diff(*b))
        .max()
        .unwrap();
    assert!(diff <= 1, "max diff {diff}");
    assert_eq!(l, rr);
    let p = Pose::new(
        UnitQuaternion::from_euler_angles(0.1, 0.2, 0.3),
        Vec3::new(1.0, 2.0, 3.0),
    );
    let q = rect.to_rectified(&p);
    assert!(p.error_to(&q).1 < 1e-6);
}

/// A roll about the baseline: each camera turns by half of it, no further rotation.
///
/// Verifies: VTSM-SIM-013
#[test]
fn roll_about_the_baseline_is_split_in_half() {
    let k = cam(100.0, 100.0, 79.5, 59.5, &[0.0; 5]);
    let theta = 2f64.to_radians();
    let r = Rotation3::from_axis_angle(&Vector3::x_axis(), theta).into_inner();
    let c = calib(k.clone(), k, r, Vector3::new(0.4, 0.0, 0.0));
    let rect = stereo_rectify(&c).unwrap();
    let half = Rotation3::from_axis_angle(&Vector3::x_axis(), theta / 2.0).into_inner();
    assert!(max_abs(&rect.r1, &half) < 1e-14, "{}", rect.r1);
    assert!(max_abs(&rect.r2, &half.transpose()) < 1e-14, "{}", rect.r2);
    assert!((rect.baseline_m - 0.4).abs() < 1e-12);
}

/// A general physical rig (rotation, vertical offset, different intrinsics and
/// distortion): after rectification every 3-D point lands on the same row in
/// both cameras with disparity f·B/Z, the rectified frames differ by the
/// baseline only, and each map entry is the distorted projection of the ray it
/// stands for.
///
/// Verifies: VTSM-SIM-013
#[test]
fn general_rig_rectifies_to_a_pure_baseline() {
    let l = cam(
        102.0,
        101.0,
        80.3,
        60.2,
        &[-0.1, 0.02, 0.0005, -0.0003, 0.001],
    );
    let rc = cam(99.0, 98.5, 78.9, 59.1, &[-0.09, 0.018, -0.0004, 0.0002]);
    let r = Rotation3::from_scaled_axis(Vector3::new(0.004, -0.007, 0.003)).into_inner();
    let c = calib(l.clone(), rc.clone(), r, Vector3::new(0.4, 0.006, -0.004));
    let rect = stereo_rectify(&c).unwrap();
    for m in [rect.r1, rect.r2] {
        assert!(max_abs(&(m.transpose() * m), &Matrix3::identity()) < 1e-14);
    }
    // Rectified right from rectified left is a pure translation of -B along x.
    let rel = rect.r2 * r * rect.r1.transpose();
    assert!(max_abs(&rel, &Matrix3::identity()) < 1e-12, "{rel}");
    let t = Vector3::new(c.t[0], c.t[1], c.t[2]);
    let t2 = rect.r2 * t;
    assert!(t2.y.abs() < 1e-12 && t2.z.abs() < 1e-12 && (t2.x + rect.baseline_m).abs() < 1e-15);
    let mut rng = Rng::new(9);
    let f = rect.f_px;
    for _ in 0..200 {
        let p = Vector3::new(
            f64::from(rng.uniform(-2.0, 2.0)),
            f64::from(rng.uniform(-1.5, 1.5)),
            f64::from(rng.uniform(1.0, 10.0)),
        );
        let pl = rect.r1 * p;
        let pr = rect.r2 * (r * p + t);
        let vl = f * pl.y / pl.z + rect.c_px[1];
        let vr = f * pr.y / pr.z + rect.c_px[1];
        let ul = f * pl.x / pl.z + rect.c_px[0];
        let ur = f * pr.x / pr.z + rect.c_px[0];
        assert!((vl - vr).abs() < 1e-9, "rows {vl} {vr}");
        assert!((ul - ur - f * rect.baseline_m / pl.z).abs() < 1e-9);
    }
    let full = Rectifier::new(&c).unwrap();
    let pc = PhysicalCamera::from_opencv(&l);
    let (lm, rm) = full.maps();
    // The on-the-fly remap gives the stored maps' pixels.
    let (a, b) = (test_image(160, 120), test_image(160, 120));
    for interp in Interp::ALL {
        let full = full.clone().with_interp(interp);
        assert_eq!(
            full.rectify_pair(&a, &b),
            (lm.remap(&a, interp), rm.remap(&b, interp))
        );
    }
    for (i, (&x, &y)) in lm.map_x.iter().zip(&lm.map_y).enumerate().step_by(37) {
        let (u, v) = ((i % 160) as f64, (i / 160) as f64);
        let ray =
            rect.r1.transpose() * Vector3::new((u - rect.c_px[0]) / f, (v - rect.c_px[1]) / f, 1.0);
        let px = pc.project([ray.x, ray.y, ray.z]).unwrap();
        assert!((px[0] - f64::from(x)).abs() < 1e-3 && (px[1] - f64::from(y)).abs() < 1e-3);
    }
}

/// Distort then undistort (and the reverse) returns the point, over the field of
/// a 77° camera, for the 5- and 8-coefficient models.
///
/// Verifies: VTSM-SIM-013
#[test]
fn distortion_round_trips() {
    let models = [
        Distortion([-0.1, 0.02, 0.0005, -0.0003, 0.001, 0.0, 0.0, 0.0]),
        Distortion([-0.28, 0.07, 0.001, 0.0008, -0.008, 0.01, -0.02, 0.003]),
        Distortion::NONE,
    ];
    let mut rng = Rng::new(3);
    for d in models {
        for _ in 0..2000 {
            let (x, y) = (
                f64::from(rng.uniform(-0.8, 0.8)),
                f64::from(rng.uniform(-0.55, 0.55)),
            );
            let (xd, yd) = d.distort(x, y);
            let (xu, yu) = d.undistort(xd, yd).unwrap();
            assert!(
                (xu - x).abs() < 1e-10 && (yu - y).abs() < 1e-10,
                "{d:?} ({x},{y})"
            );
            let (xu, yu) = d.undistort(x, y).unwrap();
            let (xr, yr) = d.distort(xu, yu);
            assert!((xr - x).abs() < 1e-11 && (yr - y).abs() < 1e-11);
        }
    }
    // OpenCV's fixed point iteration approaches the exact inverse.
    let d = models[0];
    let (xd, yd) = d.distort(0.7, -0.5);
    let (x, y) = d.undistort_opencv(xd, yd, 20);
    assert!(
        (x - 0.7).abs() < 1e-6 && (y + 0.5).abs() < 1e-6,
        "({x},{y})"
    );
}

/// Physical-left and rectified-left poses convert both ways, and the rectified
/// camera sees a world point along `R1` of the physical camera's ray.
///
/// Verifies: VTSM-SIM-013
#[test]
fn pose_conversion_round_trips() {
    let l = cam(102.0, 101.0, 80.3, 60.2, &[-0.1, 0.02, 0.0, 0.0, 0.0]);
    let r = Rotation3::from_scaled_axis(Vector3::new(0.01, 0.006, -0.004)).into_inner();
    let c = calib(l.clone(), l, r, Vector3::new(0.4, 0.01, 0.02));
    let rect = Rectifier::new(&c).unwrap();
    let phys = Pose::new(
        UnitQuaternion::from_euler_angles(-1.2, 0.3, 2.0),
        Vec3::new(3.0, -1.0, 1.0),
    );
    let rl = rect.to_rectified(&phys);
    let back = rect.to_physical(&rl);
    let (dt, dr) = back.error_to(&phys);
    assert!(dt < 1e-6 && dr < 1e-6);
    let pw = Vec3::new(4.0, 2.0, -1.0);
    let in_phys = phys.inverse().transform_point(&pw).cast::<f64>();
    let in_rect = rl.inverse().transform_point(&pw).cast::<f64>();
    let want = rect.rect.r1 * in_phys;
    assert!(
        (want - in_rect).norm() < 1e-5 * want.norm(),
        "{want} {in_rect}"
    );
}

/// Every kernel's weights sum to one; at a whole pixel each is the unit impulse
/// (the identity remap reproduces the image); Lanczos-4 agrees with the
/// textbook `sinc(d)·sinc(d/4)` normalised in f64.
///
/// Verifies: VTSM-SIM-013
#[test]
fn kernel_weights_are_normalised_and_interpolating() {
    for k in 0..=64 {
        let x = k as f32 / 64.0 * 0.999;
        let c = cubic_weights(x);
        let l = lanczos4_weights(x);
        assert!(
            (c.iter().sum::<f32>() - 1.0).abs() < 1e-6,
            "cubic {x}: {c:?}"
        );
        assert!(
            (l.iter().sum::<f32>() - 1.0).abs() < 1e-6,
            "lanczos4 {x}: {l:?}"
        );
        let sinc = |d: f64| {
            if d == 0.0 {
                1.0
            } else {
                (std::f64::consts::PI * d).sin() / (std::f64::consts::PI * d)
            }
        };
        let reference: Vec<f64> = (0..8)
            .map(|i| {
                let d = f64::from(x) + 3.0 - f64::from(i);
                sinc(d) * sinc(d / 4.0)
            })
            .collect();
        let total: f64 = reference.iter().sum();
        for (w, r) in l.iter().zip(&reference) {
            assert!(
                (f64::from(*w) - r / total).abs() < 1e-6,
                "lanczos4 {x}: {l:?}"
            );
        }
    }
    assert_eq!(cubic_weights(0.0), [0.0, 1.0, 0.0, 0.0]);
    assert_eq!(
        lanczos4_weights(0.0),
        [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0]
    );
    // Keys' kernel at the half pixel: (−0.09375, 0.59375, 0.59375, −0.09375).
    let h = cubic_weights(0.5);
    for (w, r) in h.iter().zip([-0.09375f32, 0.59375, 0.59375, -0.09375]) {
        assert!((w - r).abs() < 1e-7, "{h:?}");
    }
    let img = test_image(40, 30);
    for interp in Interp::ALL {
        for y in 0..30 {
            for x in 0..40 {
                let v = sample(&img, x as f32, y as f32, interp);
                assert_eq!(v, img.pixels[y * 40 + x], "{interp:?} at ({x},{y})");
            }
        }
    }
}

/// Every kernel against a direct f64 sum over its 2-D taps (border 0) at
/// random positions inside, across and outside the image: within one gray
/// level (f32 weights and accumulation); a constant image stays constant
/// away from the border; positions that are not finite give 0.
///
/// Verifies: VTSM-SIM-013
#[test]
fn kernels_match_a_direct_f64_sum() {
    let (w, h) = (37u32, 23u32);
    let img = test_image(w, h);
    let at = |x: i64, y: i64| -> f64 {
        if x < 0 || y < 0 || x >= i64::from(w) || y >= i64::from(h) {
            0.0
        } else {
            f64::from(img.pixels[(y * i64::from(w) + x) as usize])
        }
    };
    let mut rng = Rng::new(21);
    for _ in 0..4000 {
        let (sx, sy) = (
            rng.uniform(-6.0, w as f32 + 6.0),
            rng.uniform(-6.0, h as f32 + 6.0),
        );
        let (fx, fy) = (sx.floor(), sy.floor());
        let (ax, ay) = (sx - fx, sy - fy);
        for interp in Interp::ALL {
            let (wx, wy, first): (Vec<f32>, Vec<f32>, i64) = match interp {
                Interp::Linear => (vec![1.0 - ax, ax], vec![1.0 - ay, ay], 0),
                Interp::Cubic => (cubic_weights(ax).to_vec(), cubic_weights(ay).to_vec(), -1),
                Interp::Lanczos4 => (
                    lanczos4_weights(ax).to_vec(),
                    lanczos4_weights(ay).to_vec(),
                    -3,
                ),
            };
            let mut v = 0.0f64;
            for (j, &b) in wy.iter().enumerate() {
                for (i, &a) in wx.iter().enumerate() {
                    let (x, y) = (fx as i64 + first + i as i64, fy as i64 + first + j as i64);
                    v += f64::from(a) * f64::from(b) * at(x, y);
                }
            }
            let want = v.round().clamp(0.0, 255.0);
            let got = f64::from(sample(&img, sx, sy, interp));
            assert!(
                (got - want).abs() <= 1.0,
                "{interp:?} at ({sx},{sy}): {got} vs {want}"
            );
        }
    }
    let flat = Gray8 {
        width: w,
        height: h,
        pixels: vec![137; (w * h) as usize],
    };
    for interp in Interp::ALL {
        assert_eq!(sample(&flat, 10.37, 11.81, interp), 137, "{interp:?}");
        assert_eq!(sample(&flat, f32::NAN, 3.0, interp), 0);
        assert_eq!(sample(&flat, 1e30, 3.0, interp), 0);
        assert_eq!(sample(&flat, -1e30, -1e30, interp), 0);
    }
}

/// Names round-trip; an unknown name is refused with the accepted ones.
///
/// Verifies: VTSM-SIM-013
#[test]
fn interp_names_round_trip() {
    for i in Interp::ALL {
        assert_eq!(Interp::parse(i.name()), Ok(i));
    }
    let e = Interp::parse("nearest").unwrap_err();
    assert!(e.contains("linear, cubic or lanczos4"), "{e}");
    assert_eq!(Interp::default(), Interp::Lanczos4);
}
