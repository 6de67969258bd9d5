//! Refused inputs and what any input may do: windows, buffers, poses and
//! cameras out of range, and no write outside a buffer.

use super::*;

/// Verifies: VTSM-RAST-001
#[test]
fn rejects_invalid_windows_buffers_and_poses() {
    let mut s = Scene::new();
    s.tri(
        [[0.0, 0.0, 5.0], [1.0, 0.0, 5.0], [0.0, 1.0, 5.0]],
        [[0.0; 2]; 3],
        false,
    );
    let bytes = s.bytes(10.0);
    let map = MapView::new_checked(&bytes).unwrap();
    let cam = camera(64, 64, 50.0);
    let id = Pose::identity();
    for win in [
        Rect::new(0, 0, 0, 8),
        Rect::new(0, 0, 8, 0),
        Rect::new(0, 0, 257, 8),
        Rect::new(i32::MIN, 0, 8, 8),
    ] {
        assert_eq!(
            render(&map, &cam, &id, win).result,
            Err(FailureCode::RasterWindowInvalid)
        );
    }
    let (mut a, mut b, mut c) = (vec![0u8; 63], vec![0u32; 64], vec![0u32; 64]);
    let mut t = Target {
        intensity: &mut a,
        depth: &mut b,
        mask_depth: &mut c,
    };
    assert_eq!(
        render_window(&map, &cam, &id, Rect::new(0, 0, 8, 8), &mut t),
        Err(FailureCode::RasterBufferTooSmall)
    );
    let bad = Pose::from_t_q([0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]).map(|mut p| {
        p.iso.translation.vector.x = f32::NAN;
        p
    });
    let bad = bad.unwrap();
    assert_eq!(
        render(&map, &cam, &bad, Rect::new(0, 0, 8, 8)).result,
        Err(FailureCode::RasterPoseInvalid)
    );
    // Looking away: nothing visible.
    let away = look_at([0.0, 0.0, 0.0], [1.0, 0.0, -5.0]);
    assert_eq!(
        render(&map, &cam, &away, Rect::new(0, 0, 8, 8)).result,
        Err(FailureCode::RasterNothingVisible)
    );
}

fn coord() -> impl Strategy<Value = f32> {
    prop_oneof![
        -1.0e5f32..1.0e5,
        -20.0f32..20.0,
        -0.2f32..0.2,
        Just(0.0f32),
        Just(crate::raster::RASTER_NEAR_M)
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]
    /// Verifies: VTSM-RAST-002
    #[test]
    fn any_triangle_writes_only_inside_its_buffers(
        p in proptest::array::uniform9(coord()),
        degenerate in 0u8..3,
        wx in -300i32..300, wy in -300i32..300, w in 1u32..=96, h in 1u32..=96,
        yaw in -3.2f32..3.2,
    ) {
        let mut v = [[p[0], p[1], p[2]], [p[3], p[4], p[5]], [p[6], p[7], p[8]]];
        match degenerate {
            1 => v[1] = v[0],
            2 => v[2] = [(v[0][0] + v[1][0]) * 0.5, (v[0][1] + v[1][1]) * 0.5, (v[0][2] + v[1][2]) * 0.5],
            _ => {}
        }
        let mut s = Scene::new();
        s.tri(v, [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], true);
        // A map needs one triangle of non-zero area: this one lies behind the
        // camera, in a tile of its own, which the frustum test culls.
        s.tri(
            [[5.0e6, 0.0, -10.0], [5.0e6 + 1.0, 0.0, -10.0], [5.0e6, 1.0, -10.0]],
            [[0.0; 2]; 3],
            true,
        );
        let bytes = s.bytes(1.0e6);
        let map = MapView::new_checked(&bytes).unwrap();
        let cam = camera(128, 96, 90.0);
        let pose = Pose::new(UnitQuaternion::from_euler_angles(0.0, 0.0, yaw), Vec3::zeros());
        let win = Rect::new(wx, wy, w, h);
        let n = (w * h) as usize;
        const MARGIN: usize = 37;
        let mut inten = vec![0xA5u8; n + 2 * MARGIN];
        let mut depth = vec![0x1234_5678u32; n + 2 * MARGIN];
        let mut mdepth = vec![0x9abc_def0u32; n + 2 * MARGIN];
        let r = {
            let mut t = Target {
                intensity: &mut inten[MARGIN..],
                depth: &mut depth[MARGIN..],
                mask_depth: &mut mdepth[MARGIN..],
            };
            render_window(&map, &cam, &pose, win, &mut t)
        };
        prop_assert!(matches!(r, Ok(_) | Err(FailureCode::RasterNothingVisible)), "{:?}", r);
        for k in (0..MARGIN).chain(MARGIN + n..n + 2 * MARGIN) {
            prop_assert_eq!(inten[k], 0xA5);
            prop_assert_eq!(depth[k], 0x1234_5678);
            prop_assert_eq!(mdepth[k], 0x9abc_def0);
        }
        for k in MARGIN..MARGIN + n {
            // One mask triangle: mask depth equals depth wherever it drew.
            prop_assert_eq!(mdepth[k], depth[k]);
            prop_assert!(depth[k] == DEPTH_NONE || depth[k] <= DEPTH_MAX);
        }
        let cov = coverage(&map, &cam, &pose, win);
        prop_assert!(cov.iter().all(|c| *c <= 1));
        if let Ok(st) = r {
            prop_assert_eq!(st.pixels_written as usize, cov.iter().filter(|c| **c == 1).count());
            prop_assert!(st.triangles_tested <= 1 && st.tiles_visible <= st.tiles_tested);
        }
    }
}

/// Raw values for camera fields, windows and poses: anything, including NaN,
/// infinities and sizes far above `MAX_IMAGE_DIM` (cameras are then brought
/// into `Camera::new`'s range).
fn any_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        any::<f32>(),
        -1.0e30f32..1.0e30,
        -2.0e4f32..2.0e4,
        1.0e-30f32..2.0e6,
        Just(f32::NAN),
        Just(f32::INFINITY),
        Just(f32::MAX),
        Just(f32::MIN_POSITIVE),
    ]
}

fn any_dim() -> impl Strategy<Value = u32> {
    prop_oneof![
        any::<u32>(),
        1u32..=MAX_IMAGE_DIM as u32,
        Just(u32::MAX),
        Just(MAX_IMAGE_DIM as u32 + 1)
    ]
}

/// The two panics of arbitrary cameras (a size above `MAX_IMAGE_DIM`, a NaN or
/// huge focal length) came from struct literals that skipped `Camera::new`. The
/// fields are now private to the core: every such camera is refused where it
/// would be built, and the extreme cameras that pass render without panicking.
/// Verifies: VTSM-RAST-001
#[test]
fn cameras_beyond_the_checks_cannot_be_built_and_extreme_valid_ones_render() {
    let s = Scene::terrain(8, -4.0, 8.0, |_, _| 0.0);
    let bytes = s.bytes(1.0);
    let map = MapView::new_checked(&bytes).unwrap();
    let pose = look_at([0.0, -3.0, 4.0], [0.0, 0.0, 0.0]);
    for (fx, fy, cx, cy, w, h) in [
        (50.0, 50.0, 32.0, 32.0, u32::MAX, 64),
        (50.0, 50.0, 32.0, 32.0, 64, u32::MAX),
        (50.0, 50.0, 32.0, 32.0, 1 << 20, 1 << 20),
        (50.0, 50.0, 32.0, 32.0, MAX_IMAGE_DIM as u32 + 1, 64),
        (50.0, 50.0, 32.0, 32.0, 0, 64),
        (f32::NAN, 50.0, 32.0, 32.0, 64, 64),
        (50.0, -1.0, 32.0, 32.0, 64, 64),
        (1.0e30, 50.0, 32.0, 32.0, 64, 64),
        (50.0, 50.0, f32::INFINITY, 32.0, 64, 64),
        (50.0, 50.0, 32.0, -1.0e30, 64, 64),
    ] {
        assert_eq!(
            Camera::new(fx, fy, cx, cy, w, h),
            Err(FailureCode::StereoRigInvalid),
            "{fx} {fy} {cx} {cy} {w} {h}"
        );
    }
    let m = MAX_IMAGE_DIM as u32;
    let p = crate::geom::MAX_PRINCIPAL_PX;
    for cam in [
        Camera::new(
            crate::geom::MAX_FOCAL_PX,
            crate::geom::MAX_FOCAL_PX,
            p,
            -p,
            m,
            m,
        ),
        Camera::new(f32::MIN_POSITIVE, f32::MIN_POSITIVE, -p, p, m, 1),
        Camera::new(50.0, 50.0, 32.0, 32.0, m, m),
    ] {
        let cam = cam.unwrap();
        let r = render(&map, &cam, &pose, Rect::new(0, 0, 64, 64)).result;
        assert!(
            matches!(r, Ok(_) | Err(FailureCode::RasterNothingVisible)),
            "{cam:?}: {r:?}"
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]
    /// Arbitrary (valid, extreme) cameras, windows and poses (huge, tiny,
    /// non-finite): no panic (the test profile has overflow checks on), a bad
    /// window or pose is rejected with its code, and nothing is written past
    /// the window.
    /// Verifies: VTSM-RAST-001, VTSM-RAST-002
    #[test]
    fn any_camera_window_and_pose_renders_or_fails_without_panic(
        f in proptest::array::uniform4(any_f32()),
        dims in proptest::array::uniform2(any_dim()),
        win in (any::<i32>(), any::<i32>(), any::<u32>(), any::<u32>()),
        small_win in (-20_000i32..20_000, -20_000i32..20_000, 1u32..=MAX_RENDER_PX as u32, 1u32..=MAX_RENDER_PX as u32),
        use_small in any::<bool>(),
        t in proptest::array::uniform3(any_f32()),
        q in proptest::array::uniform4(-1.0f32..1.0),
    ) {
        let s = Scene::terrain(6, -3.0, 6.0, |x, y| 0.3 * libm::sinf(x) * libm::cosf(y));
        let bytes = s.bytes(1.0);
        let map = MapView::new_checked(&bytes).unwrap();
        // Arbitrary values brought into Camera::new's range (the only way to
        // build a camera): extreme but valid.
        let fit = |v: f32, lo: f32, hi: f32| if v.is_nan() { hi } else { v.clamp(lo, hi) };
        let c = crate::geom::MAX_PRINCIPAL_PX;
        let cam = Camera::new(
            fit(f[0], f32::MIN_POSITIVE, crate::geom::MAX_FOCAL_PX),
            fit(f[1], f32::MIN_POSITIVE, crate::geom::MAX_FOCAL_PX),
            fit(f[2], -c, c),
            fit(f[3], -c, c),
            dims[0].clamp(1, MAX_IMAGE_DIM as u32),
            dims[1].clamp(1, MAX_IMAGE_DIM as u32),
        );
        prop_assert!(cam.is_ok(), "{:?}", cam);
        let cam = cam.unwrap();
        let win = if use_small {
            Rect::new(small_win.0, small_win.1, small_win.2, small_win.3)
        } else {
            Rect::new(win.0, win.1, win.2, win.3)
        };
        let rot = nalgebra::Quaternion::new(q[0], q[1], q[2], q[3] + 1.0e-3);
        let pose = Pose::new(UnitQuaternion::new_normalize(rot), Vec3::new(t[0], t[1], t[2]));
        const N: usize = MAX_RENDER_PX * MAX_RENDER_PX;
        const MARGIN: usize = 11;
        let mut inten = vec![0xA5u8; N + MARGIN];
        let mut depth = vec![0x1234_5678u32; N + MARGIN];
        let mut mdepth = vec![0x9abc_def0u32; N + MARGIN];
        let r = {
            let mut t = Target {
                intensity: &mut inten,
                depth: &mut depth,
                mask_depth: &mut mdepth,
            };
            render_window(&map, &cam, &pose, win, &mut t)
        };
        prop_assert!(
            matches!(
                r,
                Ok(_)
                    | Err(FailureCode::RasterNothingVisible)
                    | Err(FailureCode::RasterPoseInvalid)
                    | Err(FailureCode::RasterWindowInvalid)
            ),
            "{:?}",
            r
        );
        let n = if r.is_ok() || r == Err(FailureCode::RasterNothingVisible) {
            win.w as usize * win.h as usize
        } else {
            0
        };
        for k in n..N + MARGIN {
            prop_assert_eq!(inten[k], 0xA5);
            prop_assert_eq!(depth[k], 0x1234_5678);
            prop_assert_eq!(mdepth[k], 0x9abc_def0);
        }
        for d in &depth[..n] {
            prop_assert!(*d == DEPTH_NONE || *d <= DEPTH_MAX);
        }
    }
}
