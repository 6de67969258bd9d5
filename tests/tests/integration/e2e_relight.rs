//! End to end: relighting through `vtsm relocalize`'s file path. A CFA6
//! test-profile depot mapped at 9:30 is captured at 15:30; `prior.json`
//! states the capture-time sun and `--map-sun` the mapping sun. The map is
//! then relit before matching; without either, the run is today's, bit for
//! bit.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use super::scenes;
use std::path::{Path, PathBuf};
use vtsm_core::geom::Pose;
use vtsm_sim::cli::relocalize::{self, Args};
use vtsm_sim::io::json;
use vtsm_sim::relight::SunAngles;
use vtsm_sim::scene::export::{pose_json, write_scene, SceneFiles};
use vtsm_sim::scene::{perturbed_prior, Capture, Profile, Scene};
use vtsm_sim::terrain::TerrainKind;

const SEED: u64 = 2;
const STOP: u32 = 3;
const CAPTURE_HOURS: f32 = 15.5;

struct Scenario {
    dir: PathBuf,
    truth: Pose,
    map_sun: SunAngles,
}

fn angles(sun: &vtsm_sim::render::Sun) -> SunAngles {
    SunAngles::from(sun)
}

/// The scene written with the capture sun in `prior.json`, and the same
/// prior without it as `prior_nosun.json`.
fn scenario() -> &'static Scenario {
    static S: std::sync::OnceLock<Scenario> = std::sync::OnceLock::new();
    S.get_or_init(|| {
        let scene = Scene::new(TerrainKind::Cfa6, SEED, Profile::Test);
        let map_light = scene.lighting(scenes::MAP_HOURS);
        let map = scene.map(&map_light);
        let light = scene.lighting(CAPTURE_HOURS);
        let (rig, truth, pair) = scene.capture(&light, &Capture::from_index(STOP, 0, 0.40));
        let prior = perturbed_prior(&truth, SEED);
        let dir = scenes::scratch_dir("e2e-relight", SEED);
        let files = SceneFiles {
            map: &map,
            rig: &rig,
            left: &pair.left,
            right: &pair.right,
            prior: &prior,
            truth: &truth,
            meta: serde_json::json!({"test": "e2e_relight"}),
            sun: Some(angles(&light.sun)),
        };
        write_scene(&dir, &files, false).unwrap();
        std::fs::write(dir.join("prior_nosun.json"), pose_json(&prior)).unwrap();
        Scenario {
            dir,
            truth,
            map_sun: angles(&map_light.sun),
        }
    })
}

fn args(dir: &Path, prior: &str, map_sun: Option<SunAngles>, out: PathBuf) -> Args {
    Args {
        out: Some(out),
        map_sun,
        ..scenes::exported_args(dir, prior, SEED)
    }
}

fn run(name: &str, prior: &str, map_sun: Option<SunAngles>) -> (Vec<u8>, json::ResultFile) {
    let s = scenario();
    let out = s.dir.join(name);
    relocalize::run(&args(&s.dir, prior, map_sun, out.clone())).unwrap();
    let bytes = std::fs::read(&out).unwrap();
    let r = json::parse_result(&bytes, &out).unwrap();
    (bytes, r)
}

/// With both suns the map is relit: the run succeeds within 5 cm and is not
/// the unrelit run. With only one of them (no `--map-sun`, or a prior without
/// a sun) the run is today's, byte for byte.
///
/// Verifies: VTSM-SIM-022
#[test]
fn a_stated_sun_relights_the_map_and_no_sun_changes_nothing() {
    let s = scenario();
    let (plain, r0) = run("result_plain.json", "prior.json", None);
    let (nosun, _) = run("result_nosun.json", "prior_nosun.json", Some(s.map_sun));
    assert_eq!(plain, nosun, "a prior without a sun must give today's run");
    let (_, r1) = run("result_relit.json", "prior.json", Some(s.map_sun));
    assert_eq!(r1.status, "ok", "{r1:?}");
    let e = scenes::error_mm(&r1, &s.truth);
    eprintln!(
        "relit: {e:.1} mm, {} attempts; as made: {:.1} mm, {} attempts",
        r1.stats.attempts,
        scenes::error_mm(&r0, &s.truth),
        r0.stats.attempts
    );
    assert!(e < 50.0, "relit final error {e} mm");
    assert_ne!(
        (r1.stats.attempts, r1.world_from_left),
        (r0.stats.attempts, r0.world_from_left),
        "the relit run is the unrelit one"
    );
}
