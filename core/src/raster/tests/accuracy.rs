//! Rendered depth and texture against references: f64 ray casting, the analytic
//! projection of a textured quad, window renders against crops of a full
//! render.

use super::*;

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
