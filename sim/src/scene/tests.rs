#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use super::*;
use crate::mapping::{ncc, render_mesh};
use crate::render::{radiance, RenderOptions, SKY_AMBIENT};
use crate::terrain::{LABEL_ROCK, LABEL_SAND};
use sha2::{Digest, Sha256};
use std::sync::OnceLock;

fn cfa6_test_scene() -> &'static Scene {
    static S: OnceLock<Scene> = OnceLock::new();
    S.get_or_init(|| Scene::new(TerrainKind::Cfa6, 1, Profile::Test))
}

/// SHA-256 of the left and right images of capture 0 (look at tube 0, 0.40 m) of the
/// CFA6 depot, seed 1, noon, `test` profile.
const GOLDEN_PAIR_SHA256: &str = "f3ffd3446f9cd427f7f31e1b46a6df1a44ca455532166439d978fa3e3f4e6d86";

/// Verifies: VTSM-SIM-007
#[test]
fn same_seed_gives_byte_identical_images_matching_checked_in_hash() {
    let scene = cfa6_test_scene();
    let light = scene.lighting(12.5);
    let cap = Capture::from_index(0, 0, 0.40);
    let (_, _, a) = scene.capture(&light, &cap);
    // Same again on a single thread: rows are independent, so the bytes are too.
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let (_, _, b) = one.install(|| scene.capture(&light, &cap));
    assert_eq!(a, b);
    let mut h = Sha256::new();
    h.update(&a.left);
    h.update(&a.right);
    let hex: String = h.finalize().iter().map(|b| format!("{b:02x}")).collect();
    assert_eq!(hex, GOLDEN_PAIR_SHA256);
    // A different seed gives a different depot and different images.
    let other = Scene::new(TerrainKind::Cfa6, 2, Profile::Test);
    let (_, _, c) = other.capture(&other.lighting(12.5), &cap);
    assert_ne!(a.left, c.left);
}

/// Independent reference for the block test: is ground point (x, y) shadowed by the
/// axis-aligned box [−a, a]² × [0, hgt] under a sun at (elevation, azimuth)?
fn block_shadows(x: f32, y: f32, a: f32, hgt: f32, el_deg: f32, az_deg: f32) -> bool {
    let (el, az) = (el_deg.to_radians(), az_deg.to_radians());
    let reach = hgt / el.tan();
    let (ux, uy) = (az.sin(), az.cos());
    (0..=2000).any(|k| {
        let s = reach * k as f32 / 2000.0;
        let (px, py) = (x + ux * s, y + uy * s);
        px.abs() <= a && py.abs() <= a
    })
}

/// Verifies: VTSM-SIM-003
#[test]
fn block_shadow_moves_with_the_sun_as_geometry_predicts() {
    let (a, hgt) = (0.10f32, 0.30f32);
    let t = Terrain::from_fn(TerrainKind::Cfa6, 0, 0.01, |x, y| {
        if x.abs() <= a && y.abs() <= a {
            (hgt, 0.3, LABEL_ROCK)
        } else {
            (0.0, 0.3, LABEL_SAND)
        }
    });
    let mut last_az: Option<f32> = None;
    for (name, hours) in TIMES_H {
        let sun = Sun::depot(hours);
        let light = Lighting::new(&t, sun);
        let reach = hgt / sun.elevation_deg.to_radians().tan();
        let (mut agree, mut total) = (0, 0);
        let (mut sx, mut sy, mut n) = (0.0f32, 0.0f32, 0.0f32);
        let steps = 120;
        for j in 0..steps {
            for i in 0..steps {
                let x = -1.2 + 2.4 * (i as f32 + 0.5) / steps as f32;
                let y = -1.2 + 2.4 * (j as f32 + 0.5) / steps as f32;
                if x.abs() <= a + 0.02 && y.abs() <= a + 0.02 {
                    continue; // on or at the foot of the block
                }
                let truth = block_shadows(x, y, a, hgt, sun.elevation_deg, sun.azimuth_deg);
                // Skip points within 2 cm of the shadow boundary (cell discretisation).
                let near_edge = [(0.02, 0.0), (-0.02, 0.0), (0.0, 0.02), (0.0, -0.02)]
                    .iter()
                    .any(|(dx, dy)| {
                        block_shadows(x + dx, y + dy, a, hgt, sun.elevation_deg, sun.azimuth_deg)
                            != truth
                    });
                let shadowed = light.lit(x, y) < 0.5;
                if shadowed {
                    sx += x;
                    sy += y;
                    n += 1.0;
                }
                if near_edge {
                    continue;
                }
                total += 1;
                if shadowed == truth {
                    agree += 1;
                }
            }
        }
        assert!(n > 20.0, "{name}: no shadow found");
        assert_eq!(
            agree, total,
            "{name}: {agree}/{total} points agree with the analytic shadow"
        );
        // Shadow centroid lies opposite the sun, at about half the shadow length.
        let az = sx.atan2(sy).to_degrees().rem_euclid(360.0);
        let expect = (sun.azimuth_deg + 180.0).rem_euclid(360.0);
        let d_az = ((az - expect + 540.0).rem_euclid(360.0) - 180.0).abs();
        assert!(d_az < 4.0, "{name}: shadow azimuth {az:.1} vs {expect:.1}");
        let dist = (sx * sx + sy * sy).sqrt() / n;
        assert!(
            (dist - 0.5 * (reach + a)).abs() < 0.25 * (reach + a),
            "{name}: centroid distance {dist:.3} for shadow length {reach:.3}"
        );
        if let Some(prev) = last_az {
            let turn = (az - prev).rem_euclid(360.0);
            assert!(
                turn > 5.0 && turn < 180.0,
                "{name}: shadow turns clockwise through the day ({prev:.1} -> {az:.1})"
            );
        }
        last_az = Some(az);
        // Photometry: shadowed ground receives sky light only.
        let p_sh = [
            -(sun.dir[0]) * 0.5 * reach / (1.0 - sun.dir[2] * sun.dir[2]).sqrt(),
            -(sun.dir[1]) * 0.5 * reach / (1.0 - sun.dir[2] * sun.dir[2]).sqrt(),
        ];
        let lit_r = radiance(&t, &light, 1.5, 1.5) / t.albedo(1.5, 1.5);
        let sh_r = radiance(&t, &light, p_sh[0] + a * 0.0, p_sh[1]) / t.albedo(p_sh[0], p_sh[1]);
        assert!(
            (lit_r - (sun.dir[2] + SKY_AMBIENT)).abs() < 0.01,
            "{name}: lit {lit_r}"
        );
        assert!(
            sh_r < SKY_AMBIENT * 1.01 && sh_r > SKY_AMBIENT * 0.3,
            "{name}: shadow {sh_r}"
        );
    }
}

/// Verifies: VTSM-SIM-016
#[test]
fn light_models_take_out_cast_shadows_or_attached_shading_only() {
    use crate::render::LightModel;
    // A block that casts a shadow on flat ground, and a ramp facing west.
    let t = Terrain::from_fn(TerrainKind::Cfa6, 0, 0.01, |x, y| {
        if x.abs() <= 0.1 && y.abs() <= 0.1 {
            (0.3, 0.3, LABEL_ROCK)
        } else if x > 0.5 {
            ((x - 0.5) * 0.577, 0.3, LABEL_SAND)
        } else {
            (0.0, 0.3, LABEL_SAND)
        }
    });
    let sun = Sun::depot(9.5);
    let full = Lighting::new(&t, sun);
    assert_eq!(
        full.irradiance(0.73, 0.31),
        Lighting::with_model(&t, sun, LightModel::Full).irradiance(0.73, 0.31)
    );
    let no_cast = Lighting::with_model(&t, sun, LightModel::NoCastShadows);
    let flat_up = Lighting::with_model(&t, sun, LightModel::NoAttachedShading);
    let flat = Lighting::with_model(&t, sun, LightModel::Flat);
    let (mut shadowed, mut sloped) = (0, 0);
    for j in 0..60 {
        for i in 0..60 {
            let x = -1.0 + 2.0 * (i as f32 + 0.5) / 60.0;
            let y = -1.0 + 2.0 * (j as f32 + 0.5) / 60.0;
            assert_eq!(no_cast.lit(x, y), 1.0, "({x}, {y})");
            assert_eq!(flat.lit(x, y), 1.0, "({x}, {y})");
            let open = sun.dir[2] + SKY_AMBIENT * t.sky_visibility(x, y);
            assert!((flat.irradiance(x, y) - open).abs() < 2e-3, "({x}, {y})");
            assert_eq!(flat_up.lit(x, y), full.lit(x, y), "({x}, {y})");
            let up = sun.dir[2] * full.lit(x, y) + SKY_AMBIENT * t.sky_visibility(x, y);
            assert!(
                (flat_up.irradiance(x, y) - up).abs() < 2e-3,
                "({x}, {y}): {} against {up}",
                flat_up.irradiance(x, y)
            );
            if full.lit(x, y) < 0.5 && x.abs() > 0.12 && y.abs() > 0.12 {
                shadowed += 1;
                assert!(no_cast.irradiance(x, y) > full.irradiance(x, y) + 0.2);
            }
            if x > 0.55 && (x < 0.95) && full.lit(x, y) > 0.99 {
                sloped += 1;
                assert!((full.irradiance(x, y) - up).abs() > 0.05, "({x}, {y})");
            }
        }
    }
    assert!(
        shadowed > 10 && sloped > 100,
        "{shadowed} shadowed, {sloped} on the ramp"
    );
}

/// Verifies: VTSM-SIM-004
#[test]
fn known_point_appears_at_predicted_pixels_in_both_images() {
    // Dark flat ground with three bright 4 cm squares at known positions.
    let markers = [[0.3f32, 1.8, 0.0], [-0.5, 2.4, 0.0], [0.9, 2.9, 0.0]];
    let half = 0.02;
    let t = Terrain::from_fn(TerrainKind::Cfa2, 0, 0.005, |x, y| {
        let on = markers
            .iter()
            .any(|m| (x - m[0]).abs() <= half && (y - m[1]).abs() <= half);
        (0.0, if on { 0.9 } else { 0.08 }, LABEL_SAND)
    });
    let scene = Scene {
        terrain: t,
        profile: Profile::Test,
        seed: 0,
        map_coarse: 1,
    };
    let light = scene.lighting(12.5);
    for baseline in BASELINES_M {
        let rig = scene.rig(baseline);
        let pose = look_pose([0.1, 0.0, 1.0], [0.2, 2.0, 0.0], 25f32.to_radians());
        let pair = scene.render_pair(&light, &rig, &pose, &RenderOptions::clean(4));
        let w = rig.cam().width() as usize;
        for m in markers {
            let p_left = pose.inverse().transform_point(&Vec3::new(m[0], m[1], m[2]));
            let (pl, pr) = rig.project_stereo(&p_left).unwrap();
            let centroid = |img: &[u8], c: [f32; 2]| {
                let (mut su, mut sv, mut sw) = (0.0f64, 0.0f64, 0.0f64);
                let (v0, u0) = (c[1] as usize - 12, c[0] as usize - 12);
                let win = |v: usize, u: usize| f64::from(img[v * w + u]);
                let (mut lo, mut hi) = (255.0f64, 0.0f64);
                for v in v0..v0 + 25 {
                    for u in u0..u0 + 25 {
                        lo = lo.min(win(v, u));
                        hi = hi.max(win(v, u));
                    }
                }
                let thr = 0.5 * (lo + hi);
                for v in v0..v0 + 25 {
                    for u in u0..u0 + 25 {
                        let wgt = (win(v, u) - thr).max(0.0);
                        su += wgt * u as f64;
                        sv += wgt * v as f64;
                        sw += wgt;
                    }
                }
                assert!(sw > 0.0);
                [(su / sw) as f32, (sv / sw) as f32]
            };
            let cl = centroid(&pair.left, pl);
            let cr = centroid(&pair.right, pr);
            for (c, p) in [(cl, pl), (cr, pr)] {
                assert!(
                    (c[0] - p[0]).abs() < 0.35 && (c[1] - p[1]).abs() < 0.35,
                    "B={baseline} marker {m:?}: found {c:?}, predicted {p:?}"
                );
            }
            // Rectified: same row; disparity fx·B/Z.
            assert!((cl[1] - cr[1]).abs() < 0.2);
            let disp = rig.cam().fx() * baseline / p_left.z;
            assert!(
                ((cl[0] - cr[0]) - disp).abs() < 0.4,
                "disparity {} vs {disp}",
                cl[0] - cr[0]
            );
        }
    }
}

/// Verifies: VTSM-SIM-006
#[test]
fn baked_map_matches_mapping_image_and_differs_six_hours_later() {
    for kind in [TerrainKind::Flagstone, TerrainKind::Cfa6] {
        let scene = Scene::new(kind, 5, Profile::Test);
        let map_light = scene.lighting(9.5);
        let mesh = scene.map(&map_light);
        let poses = mapping_trajectory(&scene.terrain, Trajectory::Forward, 1);
        let pose = poses[25];
        let cam = scene.camera();
        let (baked, cover) = render_mesh(&mesh, &cam, &pose);
        let same = render(
            &scene.terrain,
            &map_light,
            &cam,
            &pose,
            &RenderOptions::clean(2),
        );
        let later = render(
            &scene.terrain,
            &scene.lighting(15.5),
            &cam,
            &pose,
            &RenderOptions::clean(2),
        );
        let covered = cover.iter().filter(|&&c| c).count();
        assert!(covered > cover.len() / 2, "mesh covers {covered} px");
        let n_same = ncc(&baked, &same, &cover);
        let n_later = ncc(&baked, &later, &cover);
        println!("{kind:?}: NCC(map render, mapping image) = {n_same:.3}, at +6 h = {n_later:.3}");
        assert!(n_same > 0.85, "{kind:?}: same-time NCC {n_same}");
        assert!(
            n_later < n_same - 0.2,
            "{kind:?}: +6 h NCC {n_later} vs {n_same}"
        );
    }
}

/// Verifies: VTSM-SIM-008
#[test]
fn capture_grid_follows_the_paper_layout() {
    let scene = cfa6_test_scene();
    let grid = capture_grid();
    assert_eq!(grid.len(), 120);
    let rig = scene.rig(0.40);
    let hfov = 2.0 * ((rig.cam().width() as f32 * 0.5) / rig.cam().fx()).atan();
    assert!((hfov.to_degrees() - HFOV_DEG).abs() < 1e-3);
    for c in &grid {
        let pose = capture_pose(&scene.terrain, c);
        let r = pose.rotation().to_rotation_matrix();
        let m = r.matrix();
        // Camera y (down) points down in the world, x (right) is horizontal (no roll).
        assert!(m[(2, 1)] < -0.5 && m[(2, 0)].abs() < 1e-5);
        // Rig centre on the 1.5 m circle around its tube, 1 m above the ground.
        let mid = pose.transform_point(&Vec3::new(0.5 * c.baseline_m, 0.0, 0.0));
        let tube = TUBE_XY_M[c.circle as usize];
        let rad = ((mid.x - tube[0]).powi(2) + (mid.y - tube[1]).powi(2)).sqrt();
        assert!((rad - CIRCLE_RADIUS_M).abs() < 1e-4);
        assert!((mid.z - scene.terrain.height(mid.x, mid.y) - CAMERA_HEIGHT_M).abs() < 1e-4);
        // The tube looked at lies on the rig's vertical centre line, in the image.
        let target = scene.terrain.tube_centre(c.look_at as usize);
        let p = pose
            .inverse()
            .transform_point(&Vec3::new(target[0], target[1], target[2]));
        let rig = scene.rig(c.baseline_m);
        let (l, rpx) = rig.project_stereo(&p).unwrap();
        let mid_u = 0.5 * (l[0] + rpx[0]);
        assert!(
            (mid_u - rig.cam().cx()).abs() < 0.05,
            "{c:?}: tube at u = {mid_u}, centre {}",
            rig.cam().cx()
        );
        assert!(rig.cam().contains(l[0], l[1], 0.0));
    }
    for kind in [Trajectory::Wave, Trajectory::Forward] {
        assert_eq!(mapping_trajectory(&scene.terrain, kind, 1).len(), 60);
        assert_eq!(mapping_trajectory(&scene.terrain, kind, 6).len(), 10);
    }
}

/// Verifies: VTSM-SIM-009
#[test]
fn export_writes_design_files_and_refuses_to_overwrite() {
    let scene = cfa6_test_scene();
    let light = scene.lighting(9.5);
    let mesh = scene.map(&light);
    assert!(mesh.triangles.len() <= 400_000);
    assert_eq!(mesh.uvs.len(), mesh.triangles.len());
    assert_eq!(mesh.mask.len(), mesh.triangles.len());
    let masked = mesh.mask.iter().filter(|&&m| m).count();
    assert!(
        masked > 0 && masked < mesh.triangles.len() / 3,
        "cfa6 mask keeps rocks only: {masked}"
    );
    let cap = Capture::from_index(3, 1, 0.20);
    let (rig, truth, pair) = scene.capture(&light, &cap);
    let prior = perturbed_prior(&truth, 9);
    let (dt, dr) = prior.error_to(&truth);
    assert!(
        (0.099..=0.201).contains(&dt) && dr.to_degrees() <= 1.5 + 1e-3,
        "{dt} {dr}"
    );
    let dir = std::env::temp_dir().join(format!("vtsm_scene_export_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let files = export::SceneFiles {
        map: &mesh,
        rig: &rig,
        left: &pair.left,
        right: &pair.right,
        prior: &prior,
        truth: &truth,
        meta: serde_json::json!({"terrain": "cfa6"}),
        sun: None,
    };
    export::write_scene(&dir, &files, false).unwrap();
    for f in export::FILES {
        assert!(dir.join(f).exists(), "{f} missing");
    }
    let obj = std::fs::read_to_string(dir.join("map.obj")).unwrap();
    assert_eq!(
        obj.lines().filter(|l| l.starts_with("f ")).count(),
        mesh.triangles.len()
    );
    assert_eq!(
        obj.lines().filter(|l| l.starts_with("v ")).count(),
        mesh.vertices.len()
    );
    let mask = std::fs::read_to_string(dir.join("mask.obj")).unwrap();
    assert_eq!(mask.lines().filter(|l| l.starts_with("f ")).count(), masked);
    let calib: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("calib.json")).unwrap()).unwrap();
    assert_eq!(calib["width"], 480);
    assert!((calib["baseline_m"].as_f64().unwrap() - 0.2).abs() < 1e-6);
    let left = image::open(dir.join("left.png")).unwrap().to_luma8();
    assert_eq!(left.as_raw(), &pair.left);
    let before = std::fs::read(dir.join("truth.json")).unwrap();
    let again = export::write_scene(&dir, &files, false);
    assert!(again.is_err());
    assert_eq!(std::fs::read(dir.join("truth.json")).unwrap(), before);
    export::write_scene(&dir, &files, true).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

/// Every profile's camera and both paper baselines pass the core's checks
/// (`Scene::camera` and `Scene::rig` rely on it).
/// Verifies: VTSM-SIM-001
#[test]
fn every_profile_has_a_valid_rig() {
    for profile in [Profile::Paper, Profile::Demo, Profile::Test] {
        let (w, h) = profile.image_size();
        let f = (w as f32 * 0.5) / (HFOV_DEG.to_radians() * 0.5).tan();
        let cam = Camera::new(f, f, (w as f32 - 1.0) * 0.5, (h as f32 - 1.0) * 0.5, w, h).unwrap();
        for b in [0.20, 0.40] {
            assert_eq!(StereoRig::new(cam, b).unwrap().baseline_m(), b);
        }
    }
}

/// A map from imagery 4× coarser has 1/16 the texels and about 1/16 the
/// vertices, each texel the mean over its footprint (the mean brightness is
/// kept), and `map_coarse` 1 is the profile's map bit for bit.
///
/// Verifies: VTSM-SIM-017
#[test]
fn a_coarse_map_has_fewer_texels_and_vertices_and_the_same_brightness() {
    let scene = cfa6_test_scene();
    let light = scene.lighting(9.5);
    let fine = scene.map(&light);
    let same = scene.clone().with_map_coarse(1).map(&light);
    assert_eq!(fine.texture.pixels, same.texture.pixels);
    assert_eq!(fine.vertices, same.vertices);
    let coarse = scene.clone().with_map_coarse(4).map(&light);
    let texels = |m: &MeshData| m.texture.pixels.len() as f64;
    let ratio = texels(&fine) / texels(&coarse);
    assert!((15.0..=17.0).contains(&ratio), "texel ratio {ratio}");
    let ratio = fine.vertices.len() as f64 / coarse.vertices.len() as f64;
    assert!((13.0..=17.0).contains(&ratio), "vertex ratio {ratio}");
    let mean =
        |m: &MeshData| m.texture.pixels.iter().map(|&p| f64::from(p)).sum::<f64>() / texels(m);
    let (a, b) = (mean(&fine), mean(&coarse));
    assert!((a - b).abs() < 3.0, "mean {a:.1} vs {b:.1}");
    // Coarser means smoother: less texel-to-texel contrast per texel.
    let contrast = |m: &MeshData| {
        let w = m.texture.width as usize;
        m.texture
            .pixels
            .windows(2)
            .enumerate()
            .filter(|(i, _)| (i + 1) % w != 0)
            .map(|(_, p)| (f64::from(p[0]) - f64::from(p[1])).abs())
            .sum::<f64>()
            / texels(m)
    };
    assert!(contrast(&coarse) > 0.0 && contrast(&fine) > 0.0);
    assert!(
        coarse.mask.iter().any(|&m| m),
        "the coarse map keeps a mask"
    );
}
