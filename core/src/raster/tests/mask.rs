//! The sampling mask: mask depth, tile culling, the template-mask rule and the
//! depth format.

use super::*;

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
