//! End to end: a simulated scene written by the scene exporter and read back by
//! `vtsm relocalize`'s loader gives the same relocalization, bit for bit, as the
//! in-memory path on the scene's own data; and `vtsm relocalize` exits 0 on
//! success, 1 on a clean relocalization failure, 2 on bad input.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use super::scenes;
use std::path::{Path, PathBuf};
use vtsm_core::geom::{Pose, Vec3};
use vtsm_hal::runner::VerifyChecks;
use vtsm_sim::cli::map_build::DEFAULT_TILE_SIZE_M;
use vtsm_sim::cli::relocalize::{self, outcome_from_core, Args};
use vtsm_sim::error::{EXIT_BAD_INPUT, EXIT_RELOC_FAILED};
use vtsm_sim::io::mesh;
use vtsm_sim::locate::{self, Request};
use vtsm_sim::scene::export::{calib_json, obj_text, pose_json, write_scene};

const SEED: u64 = 3;
const STOP: u32 = 3;

/// One exported test-profile scene plus what the in-memory path needs.
struct Exported {
    dir: PathBuf,
    map_bytes: Vec<u8>,
    rig: vtsm_core::geom::StereoRig,
    left: Vec<u8>,
    right: Vec<u8>,
    prior: Pose,
    truth: Pose,
    map: mesh::MeshData,
}

fn exported() -> &'static Exported {
    static E: std::sync::OnceLock<Exported> = std::sync::OnceLock::new();
    E.get_or_init(|| {
        let (map, shot) = scenes::flagstone_shot(SEED, STOP);
        let dir = scenes::scratch_dir("e2e-file-path", SEED);
        let files = shot.files(&map, serde_json::json!({"test": "e2e_file_path"}));
        write_scene(&dir, &files, false).unwrap();
        let map_bytes = map.encode_map(DEFAULT_TILE_SIZE_M).unwrap();
        Exported {
            dir,
            map_bytes,
            rig: shot.rig,
            left: shot.pair.left,
            right: shot.pair.right,
            prior: shot.prior,
            truth: shot.truth,
            map,
        }
    })
}

fn args(dir: &Path, prior: &str, out: Option<PathBuf>) -> Args {
    Args {
        out,
        // The simulator's frame is the exported files' frame: origin 0 keeps
        // the local vertices those of the in-memory scene, bit for bit (the
        // default, the box centre, moves the local frame by it).
        origin: Some([0.0; 3]),
        ..scenes::exported_args(dir, prior, SEED)
    }
}

fn bits(p: &Pose) -> ([u32; 3], [u32; 4]) {
    (p.t().map(f32::to_bits), p.q().map(f32::to_bits))
}

/// The files read back give exactly the scene's own data: mesh, texture, mask,
/// rig, images and poses.
///
/// Verifies: VTSM-CLI-016
#[test]
fn exported_files_read_back_bit_for_bit() {
    let e = exported();
    let m = mesh::load_mesh_at(&e.dir.join("map.obj"), Some([0.0; 3])).unwrap();
    assert_eq!(m.vertices.len(), e.map.vertices.len());
    for (a, b) in m.vertices.iter().zip(&e.map.vertices) {
        assert_eq!(
            a.map(f32::to_bits),
            b.map(f32::to_bits),
            "vertex {a:?} vs {b:?}"
        );
    }
    assert_eq!(m.triangles, e.map.triangles);
    for (a, b) in m.uvs.iter().zip(&e.map.uvs) {
        assert_eq!(
            a.map(|c| c.map(f32::to_bits)),
            b.map(|c| c.map(f32::to_bits)),
            "uv {a:?} vs {b:?}"
        );
    }
    assert_eq!(m.texture.width, e.map.texture.width);
    assert_eq!(m.texture.height, e.map.texture.height);
    assert!(m.texture.pixels == e.map.texture.pixels, "texture differs");
    // The mask is re-derived from mask.obj by vertex positions.
    relocalize::with_inputs(&args(&e.dir, "prior.json", None), |map, inputs| {
        assert!(map.bytes() == e.map_bytes.as_slice(), "map product differs");
        assert!(inputs.left.pixels == e.left && inputs.right.pixels == e.right);
        let c = inputs.rig.cam();
        let r = e.rig.cam();
        assert_eq!(
            [c.fx(), c.fy(), c.cx(), c.cy(), inputs.rig.baseline_m()].map(f32::to_bits),
            [r.fx(), r.fy(), r.cx(), r.cy(), e.rig.baseline_m()].map(f32::to_bits)
        );
        assert_eq!((c.width(), c.height()), (r.width(), r.height()));
        assert_eq!(bits(&inputs.prior), bits(&e.prior), "prior.json");
        Ok(())
    })
    .unwrap();
    let truth = vtsm_sim::io::json::read_pose(&e.dir.join("truth.json")).unwrap();
    assert_eq!(bits(&truth), bits(&e.truth), "truth.json");
}

/// `relocalize` on the exported files gives the in-memory outcome bit for bit.
///
/// Verifies: VTSM-CLI-016
#[test]
fn file_path_equals_in_memory_path_bit_for_bit() {
    let e = exported();
    let done = relocalize::relocalize_one(&args(&e.dir, "prior.json", None)).unwrap();
    // One check of the map product on the whole file path (the job's; the
    // runner uses its view), and one copy of the pair (into the runner's RAM).
    assert_eq!((done.runner_map_checks, done.pair_copies), (0, 1));
    let from_files = done.outcome;
    let req = Request::new(&e.map_bytes, &e.left, &e.right, e.rig, e.prior).with_seed(SEED);
    let report = locate::relocalize(&req, locate::RunOptions::default()).unwrap();
    let in_memory = relocalize::Outcome {
        prior_uncertainty: Some(report.run.prior_uncertainty),
        ..outcome_from_core(&report.outcome, VerifyChecks::OFF)
    };
    // Without a stated uncertainty the prior gets the paper's (t̃₀, r̃₀).
    assert_eq!(
        from_files.prior_uncertainty,
        Some(vtsm_core::config::PriorUncertainty::PAPER)
    );
    assert_eq!(
        bits(from_files.pose.as_ref().unwrap()),
        bits(in_memory.pose.as_ref().unwrap())
    );
    assert_eq!(from_files, in_memory);
    // The scene is one the engine handles: this comparison is of a real solution.
    assert_eq!(in_memory.failure, None);
    let (t, _) = report.outcome.pose.error_to(&e.truth);
    assert!(t < 0.05, "in-memory error {t} m");
}

/// Shortest-form floats in the exporter's text read back to the same `f32`
/// for awkward values (tiny, huge, negative zero, many digits).
///
/// Verifies: VTSM-CLI-016
#[test]
fn exporter_floats_round_trip() {
    let mut rng = vtsm_core::rng::Rng::new(11);
    let mut values: Vec<f32> = vec![
        0.0,
        -0.0,
        1.0e-7,
        3.4e38,
        -f32::MIN_POSITIVE,
        f32::MAX,
        0.1,
        1.0 / 3.0,
    ];
    values.extend((0..2000).map(|_| f32::from_bits(rng.next_u32() & 0x7f7f_ffff) * 1.0e-30));
    values.extend((0..2000).map(|_| rng.uniform(-50.0, 50.0)));
    let mesh = mesh::MeshData {
        vertices: values.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        triangles: Vec::new(),
        uvs: Vec::new(),
        mask: Vec::new(),
        texture: vtsm_sim::io::image::Gray8 {
            width: 1,
            height: 1,
            pixels: vec![0],
        },
        origin: [0.0; 3],
    };
    let text = obj_text(&mesh, None, false);
    let read: Vec<[f32; 3]> = text
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let v: Vec<f32> = l.split(' ').map(|t| t.parse().unwrap()).collect();
            [v[0], v[1], v[2]]
        })
        .collect();
    assert_eq!(read.len(), mesh.vertices.len());
    for (a, b) in read.iter().zip(&mesh.vertices) {
        assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits));
    }
    // JSON: calibration and pose numbers go through f64 in the reader.
    for w in values
        .chunks_exact(5)
        // Within the calibration reader's range (MAX_FOCAL_PX, MAX_PRINCIPAL_PX).
        .filter(|w| w.iter().all(|v| v.abs() < 1.0e4))
    {
        let cam = vtsm_core::geom::Camera::new(
            100.0 + w[0].abs(),
            100.0 + w[1].abs(),
            w[2],
            w[3],
            64,
            48,
        )
        .unwrap();
        let rig = vtsm_core::geom::StereoRig::new(cam, 0.1 + w[4].abs()).unwrap();
        let c =
            vtsm_sim::io::json::parse_calib(calib_json(&rig).as_bytes(), Path::new("c")).unwrap();
        let back = [c.fx, c.fy, c.cx, c.cy, c.baseline_m].map(|v| (v as f32).to_bits());
        assert_eq!(
            back,
            [cam.fx(), cam.fy(), cam.cx(), cam.cy(), rig.baseline_m()].map(f32::to_bits)
        );
        let p = Pose::from_t_q([w[0], w[1], w[2]], [1.0, 0.0, 0.0, 0.0]).unwrap();
        let q = vtsm_sim::io::json::parse_pose(pose_json(&p).as_bytes(), Path::new("p")).unwrap();
        assert_eq!(bits(&q).0, bits(&p).0);
    }
}

/// Exit codes of `vtsm relocalize`: 0 success, 1 clean failure (featureless
/// images; `result.json` written with status `failed`), 2 bad input (nothing
/// written). A prior 1 m off gives 1, or 0 only with a pose within 5 cm.
///
/// Verifies: VTSM-CLI-017, VTSM-CLI-009
#[test]
fn relocalize_exit_codes() {
    let e = exported();
    let out_dir = e.dir.join("runs");
    std::fs::create_dir_all(&out_dir).unwrap();

    let ok = out_dir.join("ok.json");
    assert_eq!(
        relocalize::run(&args(&e.dir, "prior.json", Some(ok.clone()))).unwrap(),
        0
    );
    let text = std::fs::read_to_string(&ok).unwrap();
    assert!(text.contains("\"ok\""), "{text}");

    // A prior 1 m off, written as a pose file like any other.
    let far = Pose::new(
        e.prior.rotation(),
        e.prior.translation() + Vec3::new(0.8, -0.6, 0.0),
    );
    std::fs::write(e.dir.join("prior_far.json"), pose_json(&far)).unwrap();
    let failed = out_dir.join("failed.json");
    let code = relocalize::run(&args(&e.dir, "prior_far.json", Some(failed.clone()))).unwrap();
    let text = std::fs::read_to_string(&failed).unwrap();
    if code == 0 {
        // Success is only acceptable if it is right.
        let r: serde_json::Value = serde_json::from_str(&text).unwrap();
        let t = &r["world_from_left"]["t"];
        let tt = e.truth.t();
        let d: f64 = (0..3)
            .map(|k| (t[k].as_f64().unwrap() - f64::from(tt[k])).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(d < 0.05, "claimed success {d} m from the truth");
    } else {
        assert_eq!(code, EXIT_RELOC_FAILED);
        assert!(text.contains("\"failed\""), "{text}");
    }

    // Featureless images (uniform gray) of the right size: nothing to match,
    // so the relocalization must fail cleanly with exit code 1.
    let (w, h) = (e.rig.cam().width(), e.rig.cam().height());
    let gray = vec![128u8; (w * h) as usize];
    vtsm_sim::scene::export::write_png_gray(&e.dir.join("blank.png"), w, h, &gray).unwrap();
    let mut blank = args(&e.dir, "prior.json", Some(out_dir.join("blank.json")));
    blank.left = Some(e.dir.join("blank.png"));
    blank.right = Some(e.dir.join("blank.png"));
    assert_eq!(relocalize::run(&blank).unwrap(), EXIT_RELOC_FAILED);
    let text = std::fs::read_to_string(out_dir.join("blank.json")).unwrap();
    assert!(text.contains("\"failed\""), "{text}");

    // Bad input: a prior that is not a unit quaternion.
    std::fs::write(
        e.dir.join("prior_bad.json"),
        r#"{"world_from_left":{"t":[0,0,0],"q":[2,0,0,0]}}"#,
    )
    .unwrap();
    let bad_out = out_dir.join("bad.json");
    let err = relocalize::run(&args(&e.dir, "prior_bad.json", Some(bad_out.clone())))
        .expect_err("a non-unit quaternion must be refused");
    assert_eq!(vtsm_sim::cli::report(&err), EXIT_BAD_INPUT);
    assert!(err.to_string().contains("prior_bad.json"), "{err}");
    assert!(!bad_out.exists());

    // Bad input: the output exists and --force is not given.
    let err = relocalize::run(&args(&e.dir, "prior.json", Some(ok))).expect_err("no overwrite");
    assert_eq!(vtsm_sim::cli::report(&err), EXIT_BAD_INPUT);
}
