//! Each pixel drawn at most once: grids crossing the near plane, huge triangles
//! clipped to the guard band.

use super::*;

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
