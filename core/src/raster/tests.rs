extern crate std;
use super::*;
use crate::config::{TEMPLATE_MASK_JUMP_M, TEMPLATE_MASK_JUMP_REL_DIV, TEMPLATE_MASK_RADIUS_PX};
use crate::image::GrayView;
use crate::map::{encode, encoded_len, MapSource};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion};
use proptest::prelude::*;
use std::vec;
use std::vec::Vec;

/// A mesh in memory for tests (UVs in OBJ convention).
#[derive(Clone, Default)]
struct Scene {
    vertices: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
    uvs: Vec<[[f32; 2]; 3]>,
    mask: Vec<bool>,
    tex: Vec<u8>,
    tw: usize,
    th: usize,
}

impl Scene {
    fn new() -> Self {
        Self {
            tex: vec![128; 4],
            tw: 2,
            th: 2,
            ..Default::default()
        }
    }
    fn tri(&mut self, p: [[f32; 3]; 3], uv: [[f32; 2]; 3], mask: bool) {
        let base = self.vertices.len() as u32;
        self.vertices.extend_from_slice(&p);
        self.triangles.push([base, base + 1, base + 2]);
        self.uvs.push(uv);
        self.mask.push(mask);
    }
    fn bytes(&self, tile_size_m: f32) -> Vec<u8> {
        let src = MapSource {
            vertices: &self.vertices,
            triangles: &self.triangles,
            uvs: &self.uvs,
            mask: &self.mask,
            texture: GrayView::new(&self.tex, self.tw, self.th, self.tw).unwrap(),
            tile_size_m,
            origin: [0.0; 3],
        };
        let mut out = vec![0u8; encoded_len(&src).unwrap()];
        let n = encode(&src, &mut out).unwrap();
        out.truncate(n);
        out
    }
    /// Heightfield grid over [x0, x0+size]² with `n` cells a side, shared vertices.
    fn terrain(n: usize, x0: f32, size: f32, height: impl Fn(f32, f32) -> f32) -> Self {
        let mut s = Self::new();
        for j in 0..=n {
            for i in 0..=n {
                let (x, y) = (
                    x0 + size * i as f32 / n as f32,
                    x0 + size * j as f32 / n as f32,
                );
                s.vertices.push([x, y, height(x, y)]);
            }
        }
        for j in 0..n {
            for i in 0..n {
                let a = (j * (n + 1) + i) as u32;
                let (b, c, d) = (a + 1, a + n as u32 + 1, a + n as u32 + 2);
                let uv = |i: usize, j: usize| [i as f32 / n as f32, j as f32 / n as f32];
                s.triangles.push([a, b, d]);
                s.uvs.push([uv(i, j), uv(i + 1, j), uv(i + 1, j + 1)]);
                s.triangles.push([a, d, c]);
                s.uvs.push([uv(i, j), uv(i + 1, j + 1), uv(i, j + 1)]);
                s.mask.push((i + j) % 3 == 0);
                s.mask.push(i % 4 == 1);
            }
        }
        s.tw = 64;
        s.th = 64;
        s.tex = (0..64 * 64)
            .map(|k| {
                (128.0
                    + 100.0 * libm::sinf((k % 64) as f32 * 0.4) * libm::cosf((k / 64) as f32 * 0.3))
                    as u8
            })
            .collect();
        s
    }
}

fn camera(w: u32, h: u32, f: f32) -> Camera {
    Camera::new(f, f, (w as f32 - 1.0) * 0.5, (h as f32 - 1.0) * 0.5, w, h).unwrap()
}

/// world_from_cam for an OpenCV camera at `eye` looking at `target`, world z up.
fn look_at(eye: [f32; 3], target: [f32; 3]) -> Pose {
    let eye = Vec3::from(eye);
    let z = (Vec3::from(target) - eye).normalize();
    let x = z.cross(&Vec3::new(0.0, 0.0, 1.0)).normalize();
    let y = z.cross(&x);
    let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
    Pose::new(UnitQuaternion::from_rotation_matrix(&r), eye)
}

struct Render {
    intensity: Vec<u8>,
    depth: Vec<u32>,
    mask_depth: Vec<u32>,
    result: Result<RenderStats, FailureCode>,
}

fn render(map: &MapView, cam: &Camera, pose: &Pose, win: Rect) -> Render {
    let n = (win.w * win.h) as usize;
    let (mut intensity, mut depth, mut mask_depth) = (vec![0u8; n], vec![0u32; n], vec![0u32; n]);
    let mut t = Target {
        intensity: &mut intensity,
        depth: &mut depth,
        mask_depth: &mut mask_depth,
    };
    let result = render_window(map, cam, pose, win, &mut t);
    Render {
        intensity,
        depth,
        mask_depth,
        result,
    }
}

/// Coverage count per window pixel (test-only use of the pixel sink).
fn coverage(map: &MapView, cam: &Camera, pose: &Pose, win: Rect) -> Vec<u32> {
    let n = (win.w * win.h) as usize;
    let mut count = vec![0u32; n];
    let mut outside = 0usize;
    rasterize(
        map,
        cam,
        pose,
        win,
        &mut |f: Frag| match count.get_mut(f.idx) {
            Some(c) => *c += 1,
            None => outside += 1,
        },
    )
    .unwrap();
    assert_eq!(outside, 0, "fragment outside the window");
    count
}

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
        Just(super::RASTER_NEAR_M)
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

/// A jittered, warped grid on the plane Z = 4 + a·X + b·Y (camera frame = world),
/// reaching far beyond the guard band and, when tilted, behind the camera.
fn jittered_plane(n: usize, a: f32, b: f32, seed: u32, flip: bool) -> Scene {
    let mut rng = crate::rng::Rng::new(u64::from(seed));
    let mut s = Scene::new();
    let coord = |k: usize| {
        let t = 2.0 * k as f32 / n as f32 - 1.0;
        40.0 * t * libm::fabsf(t)
    };
    for j in 0..=n {
        for i in 0..=n {
            let (mut x, mut y) = (coord(i), coord(j));
            if i > 0 && i < n && j > 0 && j < n {
                // Jitter by under a third of the smaller neighbouring spacing: no fold-overs.
                let sx = (coord(i + 1) - coord(i)).min(coord(i) - coord(i - 1));
                let sy = (coord(j + 1) - coord(j)).min(coord(j) - coord(j - 1));
                x += (rng.next_f32() - 0.5) * 0.6 * sx;
                y += (rng.next_f32() - 0.5) * 0.6 * sy;
            }
            s.vertices.push([x, y, 4.0 + a * x + b * y]);
        }
    }
    for j in 0..n {
        for i in 0..n {
            let a0 = (j * (n + 1) + i) as u32;
            let (b0, c0, d0) = (a0 + 1, a0 + n as u32 + 1, a0 + n as u32 + 2);
            let diag = rng.next_u32() % 2 == 0;
            let (t1, t2) = if diag {
                ([a0, b0, d0], [a0, d0, c0])
            } else {
                ([a0, b0, c0], [b0, d0, c0])
            };
            for t in [t1, t2] {
                let t = if flip && rng.next_u32() % 2 == 0 {
                    [t[0], t[2], t[1]]
                } else {
                    t
                };
                s.triangles.push(t);
                s.uvs.push([[0.0; 2]; 3]);
                s.mask.push(false);
            }
        }
    }
    s
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]
    /// Verifies: VTSM-RAST-003
    #[test]
    fn shared_edges_cover_each_pixel_exactly_once(
        a in -0.3f32..0.3, b in -0.3f32..0.3, seed in 0u32..10_000,
        wx in 0i32..120, wy in 0i32..100, w in 1u32..=80, h in 1u32..=60,
    ) {
        let s = jittered_plane(26, a, b, seed, true);
        let bytes = s.bytes(7.0);
        let map = MapView::new_checked(&bytes).unwrap();
        let cam = camera(200, 160, 150.0);
        let cov = coverage(&map, &cam, &Pose::identity(), Rect::new(wx, wy, w, h));
        for (k, c) in cov.iter().enumerate() {
            prop_assert_eq!(*c, 1, "pixel {} of {}x{} at ({},{})", k, w, h, wx, wy);
        }
    }
}

/// Verifies: VTSM-RAST-003
#[test]
fn grid_crossing_the_near_plane_is_drawn_at_most_once() {
    // Camera looking along a ground plane that passes beside and behind it.
    let s = jittered_plane(30, 0.0, 0.0, 7, true);
    let bytes = s.bytes(5.0);
    let map = MapView::new_checked(&bytes).unwrap();
    let cam = camera(200, 160, 150.0);
    for (k, pose) in [
        look_at([0.0, 0.0, 4.3], [0.0, 10.0, 3.8]),
        look_at([0.0, -3.0, 3.0], [0.0, 30.0, 4.0]),
    ]
    .iter()
    .enumerate()
    {
        let cov = coverage(&map, &cam, pose, Rect::new(0, 0, 200, 160));
        assert!(cov.iter().all(|c| *c <= 1), "pose {k}");
        // Every pixel whose ray meets the plane (Z = 4) at least 2·near in front and
        // inside the grid is covered.
        let r = pose.rotation();
        let eye = pose.translation();
        let mut expected_hits = 0;
        for (i, c) in cov.iter().enumerate() {
            let (u, v) = ((i % 200) as f64, (i / 200) as f64);
            let d = r * Vec3::new(
                ((u - 99.5) / 150.0) as f32,
                ((v - 79.5) / 150.0) as f32,
                1.0,
            );
            let t = (4.0 - f64::from(eye.z)) / f64::from(d.z);
            let hit = [
                f64::from(eye.x) + t * f64::from(d.x),
                f64::from(eye.y) + t * f64::from(d.y),
            ];
            if t > 2.0 * f64::from(RASTER_NEAR_M) + 0.01
                && hit[0].abs() < 39.0
                && hit[1].abs() < 39.0
                && t < 1e4
            {
                expected_hits += 1;
                assert_eq!(*c, 1, "pose {k} pixel {i} t {t}");
            }
        }
        assert!(expected_hits > 1000, "pose {k}: {expected_hits}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]
    /// Verifies: VTSM-RAST-003
    #[test]
    fn square_split_in_two_covers_its_pixel_count(
        x0 in 0i32..150 * 16, y0 in 0i32..150 * 16, sw in 1i32..80 * 16, sh in 1i32..80 * 16,
        integer in any::<bool>(), diag in any::<bool>(), flip in any::<bool>(),
    ) {
        // Corners in 1/16 px; with `integer`, on pixel centres.
        let (x0, y0, sw, sh) = if integer {
            (x0 / 16 * 16, y0 / 16 * 16, (sw / 16).max(1) * 16, (sh / 16).max(1) * 16)
        } else {
            (x0 / 16 * 16 + 1 + x0 % 15, y0 / 16 * 16 + 1 + y0 % 15, sw, sh)
        };
        let (x1, y1) = (x0 + sw, y0 + sh);
        // Camera with f = 64 and principal point 0: pixel u = 32·X at Z = 2, exact in binary.
        let cam = Camera::new(64.0, 64.0, 0.0, 0.0, 256, 256).unwrap();
        let p = |x: i32, y: i32| [x as f32 / 16.0 / 32.0, y as f32 / 16.0 / 32.0, 2.0];
        let q = [p(x0, y0), p(x1, y0), p(x1, y1), p(x0, y1)];
        let mut s = Scene::new();
        let (t1, t2) = if diag { ([0, 1, 2], [0, 2, 3]) } else { ([0, 1, 3], [1, 2, 3]) };
        for t in [t1, t2] {
            let t = if flip { [t[0], t[2], t[1]] } else { t };
            s.tri([q[t[0]], q[t[1]], q[t[2]]], [[0.0; 2]; 3], false);
        }
        let bytes = s.bytes(1.0);
        let map = MapView::new_checked(&bytes).unwrap();
        let win = Rect::new(0, 0, 256, 256);
        let cov = coverage(&map, &cam, &Pose::identity(), win);
        prop_assert!(cov.iter().all(|c| *c <= 1));
        let count = cov.iter().filter(|c| **c == 1).count() as i32;
        // Pixel centres k·16; with no centre on the boundary, the count is the number of
        // integers strictly inside; on-boundary squares are half-open in each axis.
        let inside = |a: i32, b: i32| {
            if integer { (b - a) / 16 } else { b.div_euclid(16) - a.div_euclid(16) - i32::from(b % 16 == 0) }
        };
        let expected = inside(x0, x1).max(0) * inside(y0, y1).max(0);
        prop_assert_eq!(count, expected);
        if expected > 0 {
            let r = render(&map, &cam, &Pose::identity(), win);
            prop_assert_eq!(r.result.unwrap().pixels_written as i32, expected);
        }
    }
}

/// Möller–Trumbore in f64: distance along `d` to the nearest triangle of `s`.
fn ray_cast(s: &Scene, o: [f64; 3], d: [f64; 3]) -> Option<(f64, usize)> {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let v = |i: u32| s.vertices[i as usize].map(f64::from);
    let mut best: Option<(f64, usize)> = None;
    for (k, t) in s.triangles.iter().enumerate() {
        let (p0, p1, p2) = (v(t[0]), v(t[1]), v(t[2]));
        let (e1, e2) = (sub(p1, p0), sub(p2, p0));
        let pv = cross(d, e2);
        let det = dot(e1, pv);
        if det.abs() < 1e-15 {
            continue;
        }
        let tv = sub(o, p0);
        let u = dot(tv, pv) / det;
        let qv = cross(tv, e1);
        let w = dot(d, qv) / det;
        let dist = dot(e2, qv) / det;
        if u >= 0.0 && w >= 0.0 && u + w <= 1.0 && dist > 0.0 && best.is_none_or(|b| dist < b.0) {
            best = Some((dist, k));
        }
    }
    best
}

/// Verifies: VTSM-RAST-004
#[test]
fn terrain_depth_matches_f64_ray_casting() {
    // A coarse mesh (mostly perspective-correct triangles) and a fine one (mostly
    // triangles of small depth range, interpolated linearly in the image).
    for (cells, linear_share) in [(24, 0.0), (72, 0.5)] {
        check_terrain_depth(cells, linear_share);
    }
}

fn check_terrain_depth(cells: usize, linear_share: f64) {
    let s = Scene::terrain(cells, 0.0, 6.0, |x, y| {
        0.35 * libm::sinf(x * 1.1) * libm::cosf(y * 0.8) + 0.05 * x
    });
    let bytes = s.bytes(1.0);
    let map = MapView::new_checked(&bytes).unwrap();
    let cam = camera(160, 120, 140.0);
    let pose = look_at([3.0, -2.5, 3.0], [3.0, 3.0, 0.0]);
    let r = render(&map, &cam, &pose, Rect::new(0, 0, 160, 120));
    let stats = r.result.unwrap();
    assert!(
        f64::from(stats.triangles_linear) >= linear_share * f64::from(stats.triangles_drawn),
        "{stats:?}"
    );
    let rot = pose.rotation();
    let eye = pose.translation().map(f64::from);
    let (mut both, mut only_one, mut worst) = (0, 0, 0.0f64);
    for i in 0..160 * 120 {
        let (u, v) = ((i % 160) as f64, (i / 160) as f64);
        // Ray with camera-frame z = 1, so the hit distance is camera Z.
        let dc = Vec3::new(
            ((u - 79.5) / 140.0) as f32,
            ((v - 59.5) / 140.0) as f32,
            1.0,
        );
        let dw = (rot * dc).map(f64::from);
        let hit = ray_cast(&s, [eye.x, eye.y, eye.z], [dw.x, dw.y, dw.z]);
        match (hit, depth_to_m(r.depth[i])) {
            (Some((z_ref, _)), Some(z)) => {
                both += 1;
                let err = (f64::from(z) - z_ref).abs() / z_ref;
                worst = worst.max(err);
                // Documented tolerance: 0.1 % of depth plus one depth LSB.
                assert!(
                    (f64::from(z) - z_ref).abs() <= 1e-3 * z_ref + 1.0 / 65536.0,
                    "pixel {i}: {z} vs {z_ref}"
                );
            }
            (None, None) => {}
            _ => only_one += 1,
        }
    }
    assert!(both > 8000, "{both}");
    // Coverage differs only at the mesh border (snapping to 1/16 px).
    assert!(only_one * 100 < both, "{only_one} of {both}");
    std::println!(
        "terrain depth, {cells} cells: {both} px, worst relative error {worst:e}, {only_one} border px differ; {stats:?}"
    );
}

/// Verifies: VTSM-RAST-005
#[test]
fn textured_quad_at_an_angle_matches_analytic_projection() {
    // Quad O + s·U + t·V, s, t ∈ [0, 1], receding from Z = 3 to Z = 5 across s.
    let o = [-1.2f64, -0.9, 3.0];
    let uu = [2.4f64, 0.0, 2.0];
    let vv = [0.0f64, 1.8, 0.3];
    let at = |s: f64, t: f64| {
        [
            (o[0] + s * uu[0] + t * vv[0]) as f32,
            (o[1] + s * uu[1] + t * vv[1]) as f32,
            (o[2] + s * uu[2] + t * vv[2]) as f32,
        ]
    };
    let mut sc = Scene::new();
    sc.tw = 48;
    sc.th = 40;
    sc.tex = (0..48 * 40)
        .map(|k| {
            let (x, y) = ((k % 48) as f64, (k / 48) as f64);
            (128.0 + 90.0 * (0.45 * x).sin() * (0.33 * y).cos()).round() as u8
        })
        .collect();
    // OBJ uv of a corner = (s, t).
    sc.tri(
        [at(0.0, 0.0), at(1.0, 0.0), at(1.0, 1.0)],
        [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]],
        false,
    );
    sc.tri(
        [at(0.0, 0.0), at(1.0, 1.0), at(0.0, 1.0)],
        [[0.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
        false,
    );
    let bytes = sc.bytes(1.0);
    let map = MapView::new_checked(&bytes).unwrap();
    // Wide view (perspective division at every pixel) and a narrow, paper-like view
    // (8-pixel segments with linear steps), each a 200×150 window.
    for (cam, win) in [
        (camera(200, 150, 160.0), Rect::new(0, 0, 200, 150)),
        (camera(2000, 1500, 1600.0), Rect::new(880, 620, 200, 150)),
    ] {
        let stats = check_quad_window(&sc, &map, &cam, win, o, uu, vv);
        assert_eq!(stats.triangles_linear, 0);
    }
    // A far quad with a depth range of 0.15 % (below 1/8 texel over its 48 texels):
    // both triangles are interpolated linearly in the image and must still match
    // the analytic projection.
    let o = [-1.2f64, -0.9, 20.0];
    let uu = [2.4f64, 0.0, 0.02];
    let vv = [0.0f64, 1.8, 0.01];
    let at = |s: f64, t: f64| {
        [
            (o[0] + s * uu[0] + t * vv[0]) as f32,
            (o[1] + s * uu[1] + t * vv[1]) as f32,
            (o[2] + s * uu[2] + t * vv[2]) as f32,
        ]
    };
    let mut far = sc.clone();
    far.vertices.clear();
    far.triangles.clear();
    far.uvs.clear();
    far.mask.clear();
    far.tri(
        [at(0.0, 0.0), at(1.0, 0.0), at(1.0, 1.0)],
        [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]],
        false,
    );
    far.tri(
        [at(0.0, 0.0), at(1.0, 1.0), at(0.0, 1.0)],
        [[0.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
        false,
    );
    let bytes = far.bytes(1.0);
    let map = MapView::new_checked(&bytes).unwrap();
    let cam = camera(2000, 1500, 1600.0);
    let win = Rect::new(880, 620, 200, 150);
    let stats = check_quad_window(&far, &map, &cam, win, o, uu, vv);
    assert_eq!(stats.triangles_linear, 2);
}

fn check_quad_window(
    sc: &Scene,
    map: &MapView,
    cam: &Camera,
    win: Rect,
    o: [f64; 3],
    uu: [f64; 3],
    vv: [f64; 3],
) -> RenderStats {
    let r = render(map, cam, &Pose::identity(), win);
    let stats = r.result.unwrap();
    let tex = |x: i64, y: i64| f64::from(sc.tex[(y.clamp(0, 39) * 48 + x.clamp(0, 47)) as usize]);
    let (mut checked, mut worst, mut depth_err) = (0, 0.0f64, 0.0f64);
    // Normal of the quad plane for the ray intersection.
    let n = [
        uu[1] * vv[2] - uu[2] * vv[1],
        uu[2] * vv[0] - uu[0] * vv[2],
        uu[0] * vv[1] - uu[1] * vv[0],
    ];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    for i in 0..(win.w * win.h) as usize {
        let (u, v) = (
            (i % win.w as usize) as f64 + f64::from(win.x),
            (i / win.w as usize) as f64 + f64::from(win.y),
        );
        let d = [
            (u - f64::from(cam.cx)) / f64::from(cam.fx),
            (v - f64::from(cam.cy)) / f64::from(cam.fy),
            1.0,
        ];
        let z = dot(n, o) / dot(n, d);
        let p = [d[0] * z - o[0], d[1] * z - o[1], d[2] * z - o[2]];
        // Solve p = s·U + t·V (least squares on the 2×2 normal equations).
        let (a11, a12, a22) = (dot(uu, uu), dot(uu, vv), dot(vv, vv));
        let (b1, b2) = (dot(p, uu), dot(p, vv));
        let det = a11 * a22 - a12 * a12;
        let s = (b1 * a22 - b2 * a12) / det;
        let t = (a11 * b2 - a12 * b1) / det;
        if !(0.02..=0.98).contains(&s) || !(0.02..=0.98).contains(&t) {
            continue;
        }
        // OBJ (s, t) → texture pixel (x right, y down, centres on integers), bilinear.
        let (x, y) = (s * 48.0 - 0.5, (1.0 - t) * 40.0 - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let want = (tex(x0, y0) * (1.0 - fx) + tex(x0 + 1, y0) * fx) * (1.0 - fy)
            + (tex(x0, y0 + 1) * (1.0 - fx) + tex(x0 + 1, y0 + 1) * fx) * fy;
        let got = f64::from(r.intensity[i]);
        worst = worst.max((got - want).abs());
        checked += 1;
        assert!(
            (got - want).abs() <= 2.0,
            "pixel ({u},{v}): {got} vs {want:.2}"
        );
        let z_d = depth_to_m(r.depth[i]).unwrap();
        depth_err += (f64::from(z_d) - z).abs();
    }
    assert!(checked > 5000, "{checked}");
    assert!(depth_err / f64::from(checked) < 1e-4);
    std::println!(
        "textured quad, f = {}: {checked} px, worst |error| {worst:.2} gray levels; {stats:?}",
        cam.fx
    );
    stats
}

/// Verifies: VTSM-RAST-006
#[test]
fn window_render_equals_crop_of_full_render() {
    // Coarse and fine meshes: perspective-correct and linear triangles.
    for cells in [30, 120] {
        check_window_crops(cells);
    }
}

fn check_window_crops(cells: usize) {
    let s = Scene::terrain(cells, -4.0, 14.0, |x, y| {
        0.4 * libm::sinf(x * 0.9) * libm::cosf(y * 1.3)
    });
    let bytes = s.bytes(1.5);
    let map = MapView::new_checked(&bytes).unwrap();
    let cam = camera(220, 170, 130.0);
    let mut rng = crate::rng::Rng::new(99);
    for pose in [
        look_at([3.0, -3.0, 2.0], [3.0, 4.0, 0.0]),
        look_at([0.0, 0.0, 0.6], [5.0, 5.0, 0.2]),
    ] {
        let full = render(&map, &cam, &pose, Rect::new(0, 0, 220, 170));
        let stats = full.result.unwrap();
        if cells > 100 {
            assert!(stats.triangles_linear > 100, "{stats:?}");
        }
        for _ in 0..40 {
            let w = 1 + rng.below(128);
            let h = 1 + rng.below(128);
            let x = rng.below(220 - w + 1) as i32;
            let y = rng.below(170 - h + 1) as i32;
            let win = render(&map, &cam, &pose, Rect::new(x, y, w, h));
            for yy in 0..h as usize {
                for xx in 0..w as usize {
                    let (i, j) = (
                        yy * w as usize + xx,
                        (y as usize + yy) * 220 + x as usize + xx,
                    );
                    assert_eq!(
                        win.intensity[i], full.intensity[j],
                        "window {x},{y},{w},{h} at {xx},{yy}"
                    );
                    assert_eq!(win.depth[i], full.depth[j]);
                    assert_eq!(win.mask_depth[i], full.mask_depth[j]);
                }
            }
        }
    }
}

/// Verifies: VTSM-RAST-007
#[test]
fn mask_depth_is_set_only_where_the_mask_is_the_visible_surface() {
    let mut s = Scene::new();
    let quad = |s: &mut Scene, x0: f32, x1: f32, z: f32, mask: bool| {
        s.tri(
            [[x0, -1.0, z], [x1, -1.0, z], [x1, 1.0, z]],
            [[0.0; 2]; 3],
            mask,
        );
        s.tri(
            [[x0, -1.0, z], [x1, 1.0, z], [x0, 1.0, z]],
            [[0.0; 2]; 3],
            mask,
        );
    };
    quad(&mut s, -1.0, 1.0, 5.0, true); // mask plane behind
    quad(&mut s, -0.2, 0.3, 3.0, false); // occluder in front
    let bytes = s.bytes(0.5);
    let map = MapView::new_checked(&bytes).unwrap();
    let cam = camera(100, 100, 80.0);
    let r = render(&map, &cam, &Pose::identity(), Rect::new(0, 0, 100, 100));
    r.result.unwrap();
    let (mut masked, mut occluded) = (0, 0);
    for i in 0..100 * 100 {
        let u = (i % 100) as f32;
        let x_at = |z: f32| (u - 49.5) / 80.0 * z;
        match depth_to_m(r.depth[i]) {
            Some(z) if (z - 3.0).abs() < 1e-3 => {
                assert_eq!(r.mask_depth[i], DEPTH_NONE);
                assert!(x_at(3.0) > -0.21 && x_at(3.0) < 0.31);
                occluded += 1;
            }
            Some(z) => {
                assert!((z - 5.0).abs() < 1e-3);
                assert_eq!(r.mask_depth[i], r.depth[i]);
                masked += 1;
            }
            None => assert_eq!(r.mask_depth[i], DEPTH_NONE),
        }
    }
    assert!(masked > 400 && occluded > 100, "{masked} {occluded}");
}

/// Verifies: VTSM-RAST-008
#[test]
fn tile_culling_skips_work_without_changing_the_image() {
    let s = Scene::terrain(60, -15.0, 30.0, |x, y| 0.2 * libm::sinf(x) * libm::cosf(y));
    let tiled = s.bytes(2.0);
    let single = s.bytes(1000.0);
    let (mt, ms) = (
        MapView::new_checked(&tiled).unwrap(),
        MapView::new_checked(&single).unwrap(),
    );
    assert!(mt.tile_count() > 100 && ms.tile_count() == 1);
    let cam = camera(256, 256, 400.0);
    let pose = look_at([0.0, -3.0, 2.0], [1.0, 2.0, 0.0]);
    for win in [Rect::new(0, 0, 256, 256), Rect::new(100, 120, 64, 48)] {
        let (a, b) = (render(&mt, &cam, &pose, win), render(&ms, &cam, &pose, win));
        let (sa, sb) = (a.result.unwrap(), b.result.unwrap());
        assert_eq!(a.intensity, b.intensity);
        assert_eq!(a.depth, b.depth);
        assert_eq!(a.mask_depth, b.mask_depth);
        assert!(sa.tiles_visible < sa.tiles_tested / 2, "{sa:?}");
        assert!(
            sa.triangles_tested * 2 < sb.triangles_tested,
            "{sa:?} {sb:?}"
        );
        assert!(sa.triangles_tested <= mt.triangle_count());
    }
}

/// Brute-force reference of the template-mask rule.
fn template_mask_reference(depth: &[u32], mdepth: &[u32], w: usize, h: usize) -> Vec<u8> {
    let r = TEMPLATE_MASK_RADIUS_PX as i64;
    let mut out = vec![0u8; w * h];
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            let i = (y * w as i64 + x) as usize;
            let mut keep = mdepth[i] != DEPTH_NONE;
            let d = if depth[i] == DEPTH_NONE {
                f64::INFINITY
            } else {
                f64::from(depth[i]) / 65536.0
            };
            for yy in (y - r).max(0)..=(y + r).min(h as i64 - 1) {
                for xx in (x - r).max(0)..=(x + r).min(w as i64 - 1) {
                    let m = mdepth[(yy * w as i64 + xx) as usize];
                    if m != DEPTH_NONE {
                        let zm = f64::from(m) / 65536.0;
                        let jump = f64::from(TEMPLATE_MASK_JUMP_M)
                            + zm / f64::from(TEMPLATE_MASK_JUMP_REL_DIV);
                        // Exact real threshold; the fixed-point one rounds each term
                        // down, so it lies at most 2 LSB below this (see the caller).
                        if d > zm + jump {
                            keep = true;
                        }
                    }
                }
            }
            out[i] = if keep { 255 } else { 0 };
        }
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]
    /// Verifies: VTSM-RAST-009
    #[test]
    fn template_mask_keeps_mask_and_background_beyond_silhouettes(
        w in 1usize..40, h in 1usize..40, seed in 0u64..1_000_000,
    ) {
        let mut rng = crate::rng::Rng::new(seed);
        let n = w * h;
        let mut depth = vec![DEPTH_NONE; n];
        let mut mdepth = vec![DEPTH_NONE; n];
        // A "rock" disc (mask, near) on a ground (not mask, far or close behind).
        let (cx, cy, rad) = (rng.below(w as u32) as f32, rng.below(h as u32) as f32, 1.0 + rng.next_f32() * 8.0);
        for i in 0..n {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let rock = (x - cx) * (x - cx) + (y - cy) * (y - cy) <= rad * rad;
            let z = if rock { 2.0 + rng.next_f32() * 0.1 } else {
                match rng.below(4) { 0 => f32::INFINITY, 1 => 2.0 + rng.next_f32() * 0.1, _ => 2.0 + rng.next_f32() * 6.0 }
            };
            if z.is_finite() { depth[i] = depth_from_m(z); }
            if rock { mdepth[i] = depth[i]; }
        }
        let mut out = vec![7u8; n + 5];
        let kept = template_mask(&depth, &mdepth, w, h, &mut out);
        let want = template_mask_reference(&depth, &mdepth, w, h);
        // Pixels within 2 LSB of the threshold may go either way; everything else must agree.
        for i in 0..n {
            if out[i] != want[i] {
                let ambiguous = (0..n).any(|q| mdepth[q] != DEPTH_NONE && depth[i] != DEPTH_NONE && {
                    let m = mdepth[q];
                    let thr = m + (TEMPLATE_MASK_JUMP_M * 65536.0) as u32 + m / TEMPLATE_MASK_JUMP_REL_DIV;
                    depth[i].abs_diff(thr) <= 2
                });
                prop_assert!(ambiguous, "pixel {} got {} want {}", i, out[i], want[i]);
            }
            prop_assert!(mdepth[i] == DEPTH_NONE || out[i] == 255);
        }
        prop_assert_eq!(kept as usize, out[..n].iter().filter(|v| **v == 255).count());
        prop_assert_eq!(&out[n..], &[7u8; 5][..]);
    }
}

/// Verifies: VTSM-RAST-009
#[test]
fn template_mask_rejects_bad_sizes() {
    let d = vec![0u32; 16];
    let mut out = vec![9u8; 16];
    assert_eq!(template_mask(&d, &d, 0, 4, &mut out), 0);
    assert_eq!(template_mask(&d, &d, 5, 4, &mut out), 0);
    assert_eq!(template_mask(&d, &d[..15], 4, 4, &mut out), 0);
    assert_eq!(template_mask(&d, &d, 257, 1, &mut out), 0);
    // Sizes whose product overflows usize (any target) are refused, not multiplied.
    for (w, h) in [
        (usize::MAX, 2),
        (2, usize::MAX),
        (usize::MAX, usize::MAX),
        (1 << (usize::BITS / 2), 1 << (usize::BITS / 2)),
    ] {
        assert_eq!(template_mask(&d, &d, w, h, &mut out), 0);
    }
    assert!(out.iter().all(|v| *v == 9));
    // All-mask input keeps everything.
    assert_eq!(template_mask(&d, &d, 4, 4, &mut out), 16);
}

#[test]
fn depth_format_round_trips_and_saturates() {
    assert_eq!(depth_from_m(1.0), 65536);
    assert_eq!(depth_from_m(0.0), 0);
    assert_eq!(depth_from_m(-3.0), 0);
    assert_eq!(depth_from_m(f32::NAN), 0);
    assert_eq!(depth_from_m(1.0e9), DEPTH_MAX);
    assert_eq!(depth_to_m(DEPTH_NONE), None);
    for z in [0.05f32, 0.5, 3.25, 100.0, 4000.0] {
        let back = depth_to_m(depth_from_m(z)).unwrap();
        assert!((back - z).abs() <= z * 1e-6 + 1.0 / 131072.0, "{z} {back}");
    }
}

/// Huge triangles clipped to the guard band: snapping the clipped polygon can make
/// it slightly non-convex; it must still cover every pixel at most once
/// (two inputs once found by `any_triangle_writes_only_inside_its_buffers`).
/// Verifies: VTSM-RAST-002
#[test]
fn huge_clipped_triangle_covers_each_pixel_at_most_once() {
    let cases: [([f32; 9], Rect, f32); 2] = [
        (
            [
                0.0,
                -39528.03,
                0.0,
                0.05,
                -0.072_075_08,
                9.159_459,
                -1.113_300_9,
                31757.678,
                0.0,
            ],
            Rect::new(59, -41, 62, 28),
            2.392_923,
        ),
        (
            [
                0.0,
                0.0,
                -16997.273,
                0.05,
                -0.168_959_96,
                0.067_933_105,
                2.181_255_3,
                0.0,
                40057.3,
            ],
            Rect::new(129, -27, 2, 1),
            -0.440_998_73,
        ),
    ];
    for (p, win, yaw) in cases {
        let mut s = Scene::new();
        s.tri(
            [[p[0], p[1], p[2]], [p[3], p[4], p[5]], [p[6], p[7], p[8]]],
            [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
            true,
        );
        let bytes = s.bytes(1.0e6);
        let map = MapView::new_checked(&bytes).unwrap();
        let cam = camera(128, 96, 90.0);
        let pose = Pose::new(
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
            Vec3::zeros(),
        );
        let cov = coverage(&map, &cam, &pose, win);
        assert!(cov.iter().all(|c| *c <= 1), "{p:?} {win:?}: {cov:?}");
    }
}
