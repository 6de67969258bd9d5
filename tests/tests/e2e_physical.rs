//! End to end: a physical (distorted, unrectified) capture written by
//! `scene export --physical` relocalizes through `vtsm relocalize`'s loader and
//! engine call to about the accuracy of the ideal rectified capture of the same
//! scene, and the pose reported is the physical left camera's.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use vtsm_core::geom::Pose;
use vtsm_sim::cli::map_build::DEFAULT_TILE_SIZE_M;
use vtsm_sim::cli::relocalize::{load_inputs, run_engine, Args};
use vtsm_sim::io::calib_opencv::opencv_calib_text;
use vtsm_sim::scene::export::{write_scene, write_scene_with_calib, SceneFiles};
use vtsm_sim::scene::physical::capture_physical;
use vtsm_sim::scene::{perturbed_prior, Capture, Profile, Scene};
use vtsm_sim::terrain::TerrainKind;

const SEED: u64 = 3;
const HOURS: f32 = 9.5;

fn args(dir: &Path) -> Args {
    Args {
        mesh: Some(dir.join("map.obj")),
        mask: Some(dir.join("mask.obj")),
        map: None,
        calib: dir.join("calib.json"),
        left: Some(dir.join("left.png")),
        right: Some(dir.join("right.png")),
        prior: Some(dir.join("prior.json")),
        pairs: None,
        seed: SEED,
        verify: Default::default(),
        out: None,
        force: false,
        tile_size_m: DEFAULT_TILE_SIZE_M,
        origin: None,
    }
}

/// Relocalize the files in `dir`; (translation error m, rotation error deg) of
/// the reported pose against `truth`, and the pose.
fn relocalize(dir: &Path, truth: &Pose) -> (f32, f32, Pose) {
    let inputs = load_inputs(&args(dir)).unwrap();
    let out = run_engine(&inputs).unwrap();
    assert_eq!(out.failure, None, "{}", dir.display());
    // The outcome is in the map's local frame; the truth in the mesh's.
    let local = out.pose.unwrap();
    let o = out.origin;
    let pose = Pose::new(
        local.rotation(),
        local.translation() + vtsm_core::geom::Vec3::new(o[0] as f32, o[1] as f32, o[2] as f32),
    );
    let (t, r) = pose.error_to(truth);
    (t, r.to_degrees(), pose)
}

/// Same scene, stop and prior perturbation: the physical pair's error is within
/// 3 cm and 0.3° of the rectified pair's (and under 5 cm, 0.5° absolute), and
/// the reported pose is nearer the physical left camera than the rectified one.
///
/// Verifies: VTSM-CLI-033, VTSM-SIM-014
#[test]
fn physical_pair_relocalizes_like_the_rectified_one() {
    let scene = Scene::new(TerrainKind::Flagstone, SEED, Profile::Test);
    let light = scene.lighting(HOURS);
    let map = scene.map(&light);
    let root = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("e2e-physical-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let mut rows = Vec::new();
    for stop in [3u32, 20] {
        let cap = Capture::from_index(stop, 0, 0.40);
        let (rig, truth, pair) = scene.capture(&light, &cap);
        let prior = perturbed_prior(&truth, SEED + u64::from(stop));
        let rect_dir = root.join(format!("rect-{stop}"));
        let files = SceneFiles {
            map: &map,
            rig: &rig,
            left: &pair.left,
            right: &pair.right,
            prior: &prior,
            truth: &truth,
            meta: serde_json::json!({}),
        };
        write_scene(&rect_dir, &files, false).unwrap();
        let (calib, ptruth, ppair) = capture_physical(&scene, &light, &cap);
        assert_eq!(
            ptruth, truth,
            "the physical left camera stands where the ideal one does"
        );
        // The distorted images are not the ideal ones.
        assert!(ppair.left != pair.left && ppair.right != pair.right);
        let phys_dir = root.join(format!("phys-{stop}"));
        let files = SceneFiles {
            left: &ppair.left,
            right: &ppair.right,
            ..files
        };
        write_scene_with_calib(&phys_dir, &files, &opencv_calib_text(&calib), false).unwrap();
        let (rt, rr, _) = relocalize(&rect_dir, &truth);
        let (pt, pr, pose) = relocalize(&phys_dir, &truth);
        // The rectified left camera is turned from the physical one by R1; an
        // estimate that were left rectified would be off by that rotation.
        let inputs = load_inputs(&args(&phys_dir)).unwrap();
        let rect = inputs.physical.as_ref().unwrap();
        let (_, to_rect) = pose.error_to(&rect.to_rectified(&truth));
        println!(
            "stop {stop}: rectified {:.1} mm {rr:.3}°, physical {:.1} mm {pr:.3}° \
             (vs the rectified-left truth {:.3}°)",
            rt * 1e3,
            pt * 1e3,
            to_rect.to_degrees()
        );
        assert!(pt < 0.05 && pr < 0.5, "physical error {pt} m {pr}°");
        assert!((pt - rt).abs() < 0.03 && (pr - rr).abs() < 0.3);
        assert!(
            pr < to_rect.to_degrees(),
            "pose is not the physical camera's"
        );
        rows.push((rt, pt));
    }
    let _ = std::fs::remove_dir_all(&root);
    assert_eq!(rows.len(), 2);
}
