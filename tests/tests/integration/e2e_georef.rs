//! End to end: georeferenced meshes and batches through `vtsm relocalize`'s
//! file path. A scene exported as is and again shifted to UTM-sized
//! coordinates (mesh, mask, prior and truth) relocalizes the same; and a batch
//! of pairs runs against one map load.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use super::scenes;
use std::path::{Path, PathBuf};
use vtsm_core::geom::Pose;
use vtsm_sim::cli::batch;
use vtsm_sim::cli::relocalize::{self, Args, Outcome};
use vtsm_sim::error::EXIT_RELOC_FAILED;
use vtsm_sim::frame::{self, UserPose};
use vtsm_sim::io::json;
use vtsm_sim::job;
use vtsm_sim::scene::export::{pose_json, write_scene, SceneFiles};

const SEED: u64 = 3;
const STOP: u32 = 3;
/// The shift of the georeferenced copy (a UTM easting, northing and height).
const SHIFT: [f64; 3] = [391_234.567_8, 3_784_321.987_6, 312.25];
const SHIFT_ARG: &str = "391234.5678,3784321.9876,312.25";

struct Dirs {
    plain: PathBuf,
    shifted: PathBuf,
}

fn user_pose_json(p: &UserPose) -> String {
    let (t, q) = frame::user_t_q(p);
    serde_json::json!({"world_from_left": {"t": t, "q": q}}).to_string()
}

/// The scene exported twice: as is, and with every coordinate shifted by
/// [`SHIFT`] (vertices written as f64 user coordinates, poses likewise).
fn dirs() -> &'static Dirs {
    static D: std::sync::OnceLock<Dirs> = std::sync::OnceLock::new();
    D.get_or_init(|| {
        let (map, shot) = scenes::flagstone_shot(SEED, STOP);
        let root = scenes::scratch_dir("e2e-georef", SEED);
        let (plain, shifted) = (root.join("plain"), root.join("shifted"));
        let files = shot.files(&map, serde_json::json!({"test": "e2e_georef"}));
        write_scene(&plain, &files, false).unwrap();
        // The same local vertices about origin SHIFT: the exporter writes
        // f64(v) + SHIFT, which is exact for all but tiny coordinates.
        let moved = vtsm_sim::io::mesh::MeshData {
            origin: SHIFT,
            ..map.clone()
        };
        write_scene(
            &shifted,
            &SceneFiles {
                map: &moved,
                ..files
            },
            false,
        )
        .unwrap();
        for (name, p) in [("prior.json", &shot.prior), ("truth.json", &shot.truth)] {
            let user = frame::offset(&frame::to_user(p, [0.0; 3]), SHIFT);
            std::fs::write(shifted.join(name), user_pose_json(&user)).unwrap();
        }
        Dirs { plain, shifted }
    })
}

fn args(dir: &Path, prior: &str, origin: Option<&str>) -> Args {
    Args {
        origin: origin.map(|o| frame::parse_origin(o).unwrap()),
        ..scenes::exported_args(dir, prior, SEED)
    }
}

/// Relocalize; the map's origin, the outcome and the estimate in the user frame.
fn relocalize(a: &Args) -> ([f64; 3], Outcome, UserPose) {
    let o = relocalize::relocalize_one(a).unwrap().outcome;
    let origin = o.origin;
    let r = relocalize::outcome_result(&o);
    let p = r.world_from_left.unwrap().user();
    (origin, o, p)
}

/// A scene shifted by (391234.5678, 3784321.9876, 312.25) m, mesh and mask
/// written in f64 user coordinates, with the default origin (the exact
/// bounding-box centre), relocalizes like the unshifted one: both succeed,
/// both within 5 cm of their truths, and the estimates, shifted back, within
/// 1 mm and 0.01° of each other. The default origin is a property of the mesh,
/// so both local frames are the same to the f64 rounding of the shifted
/// coordinates. The same mesh forced to origin 0 (f32 user coordinates,
/// 0.25–0.5 m steps) does not relocalize: that is the failure the origin
/// removes.
///
/// Verifies: VTSM-CLI-035, VTSM-CLI-036
#[test]
fn utm_shifted_scene_relocalizes_like_the_unshifted_one() {
    let d = dirs();
    let (o_plain, plain, p_plain) = relocalize(&args(&d.plain, "prior.json", None));
    let (o_shift, shifted, p_shift) = relocalize(&args(&d.shifted, "prior.json", None));
    for k in 0..3 {
        let moved = o_shift[k] - o_plain[k] - SHIFT[k];
        assert!(moved.abs() < 1e-6, "origins {o_plain:?} and {o_shift:?}");
    }
    assert_eq!(plain.failure, None);
    assert_eq!(shifted.failure, None);
    let back = frame::offset(&p_shift, SHIFT.map(|c| -c));
    let (dt, dr) = frame::error_to(&back, &p_plain);
    eprintln!(
        "shifted vs unshifted: {:.6} mm, {:.6}°; inliers {} vs {}",
        dt * 1e3,
        dr.to_degrees(),
        shifted.inliers,
        plain.inliers
    );
    // Both are right, in their own frames.
    let truth_user = json::read_user_pose(&d.shifted.join("truth.json")).unwrap();
    let (et, _) = frame::error_to(&p_shift, &truth_user);
    let truth_plain = json::read_user_pose(&d.plain.join("truth.json")).unwrap();
    let (et0, _) = frame::error_to(&p_plain, &truth_plain);
    eprintln!(
        "errors to truth: shifted {:.3} mm, unshifted {:.3} mm",
        et * 1e3,
        et0 * 1e3
    );
    assert!(et < 0.05 && et0 < 0.05, "{et} m, {et0} m");

    // Control: the georeferenced mesh without an origin.
    let zero = args(&d.shifted, "prior.json", Some("0,0,0"));
    let bad = relocalize::relocalize_one(&zero).map(|d| {
        let o = d.outcome;
        (o.failure, frame::to_user(&o.pose.unwrap(), [0.0; 3]))
    });
    match bad {
        Err(e) => eprintln!("origin 0: refused: {e}"),
        Ok((Some(code), _)) => eprintln!("origin 0: failed: {}", code.name()),
        Ok((None, p)) => {
            let (t, _) = frame::error_to(&p, &truth_user);
            eprintln!("origin 0: error {:.1} mm", t * 1e3);
            assert!(t > 0.01, "origin 0 gave {t} m: the test cannot tell");
        }
    }
    assert!(dt < 0.001, "{} mm apart", dt * 1e3);
    assert!(dr.to_degrees() < 0.01, "{}° apart", dr.to_degrees());
}

/// With the origin given as the shift itself (`--origin` = the shift) and the
/// unshifted mesh at origin 0, the shifted mesh's local f32 vertices are
/// those of the unshifted mesh bit for
/// bit (f64(v) + shift − shift = v where the sum is exact, i.e. unless a
/// coordinate is within a few mm of 0), so the core sees the same map up to
/// such vertices and gives the same outcome: the estimates, shifted back,
/// agree within 1 µm (well inside 1 mm and 0.01°).
///
/// Verifies: VTSM-CLI-036
#[test]
fn origin_equal_to_the_shift_gives_the_same_local_map_and_outcome() {
    let d = dirs();
    let (args_a, args_b) = (
        args(&d.plain, "prior.json", Some("0,0,0")),
        args(&d.shifted, "prior.json", Some(SHIFT_ARG)),
    );
    relocalize::with_inputs(&args_a, |ma, a| {
        relocalize::with_inputs(&args_b, |mb, b| {
            assert_eq!(mb.origin().map(f64::to_bits), SHIFT.map(f64::to_bits));
            assert_eq!(ma.vertex_count(), mb.vertex_count());
            let differ = (0..ma.vertex_count())
                .filter(|&i| ma.vertex(i) != mb.vertex(i))
                .count();
            let prior_same = a.prior.t().map(f32::to_bits) == b.prior.t().map(f32::to_bits)
                && a.prior.q().map(f32::to_bits) == b.prior.q().map(f32::to_bits);
            eprintln!(
                "{differ} of {} local vertices differ; local prior identical: {prior_same}",
                ma.vertex_count()
            );
            // Only vertices with a coordinate near 0 may round differently.
            for i in 0..ma.vertex_count() {
                let (p, q) = (ma.vertex(i).unwrap(), mb.vertex(i).unwrap());
                if p != q {
                    assert!((p - q).norm() < 1e-8, "vertex {i}: {p:?} vs {q:?}");
                }
            }
            let (oa, ob) = (
                job::run_engine(ma, a)?.outcome,
                job::run_engine(mb, b)?.outcome,
            );
            assert_eq!(oa.failure, None);
            assert_eq!((oa.inliers, oa.iterations), (ob.inliers, ob.iterations));
            if differ == 0 && prior_same {
                // Same core input, same core output, bit for bit.
                assert_eq!(oa.stats, ob.stats);
                assert_eq!(
                    oa.pose.unwrap().t().map(f32::to_bits),
                    ob.pose.unwrap().t().map(f32::to_bits)
                );
            }
            let pa = frame::to_user(&oa.pose.unwrap(), oa.origin);
            let pb = frame::offset(
                &frame::to_user(&ob.pose.unwrap(), ob.origin),
                SHIFT.map(|c| -c),
            );
            let (dt, dr) = frame::error_to(&pb, &pa);
            assert!(dt < 1e-6 && dr < 1e-6, "{dt} m {dr} rad");
            Ok(())
        })
    })
    .unwrap();
}

fn write_pairs(dir: &Path, name: &str, lines: &[String]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, lines.join("\n") + "\n").unwrap();
    p
}

/// `args` with the batch `pairs`.
fn with_pairs(args: Args, pairs: &Path) -> Args {
    Args {
        pairs: Some(pairs.to_path_buf()),
        ..args
    }
}

fn batch_args(dir: &Path, out: Option<PathBuf>) -> Args {
    Args {
        left: None,
        right: None,
        prior: None,
        out,
        ..args(dir, "prior.json", None)
    }
}

/// A batch of three pairs relocalizes against one map load: three `ok` lines
/// in order, the first equal to the single-pair result, errors to the truths
/// reported, a pair's own `out` written, exit code 0.
///
/// Verifies: VTSM-CLI-038
#[test]
fn batch_of_pairs_runs_against_one_map_load() {
    let d = dirs();
    let dir = d.plain.join("batch");
    std::fs::create_dir_all(&dir).unwrap();
    let prior = json::read_pose(&d.plain.join("prior.json")).unwrap();
    for (name, dx) in [("prior_b.json", 0.03f32), ("prior_c.json", -0.02)] {
        let p = Pose::new(
            prior.rotation(),
            prior.translation() + vtsm_core::geom::Vec3::new(dx, 0.5 * dx, 0.0),
        );
        std::fs::write(dir.join(name), pose_json(&p)).unwrap();
    }
    let pairs = write_pairs(
        &dir,
        "pairs.jsonl",
        &[
            r#"{"id":"a","left":"../left.png","right":"../right.png","prior":"../prior.json","truth":"../truth.json"}"#.to_string(),
            r#"{"id":"b","left":"../left.png","right":"../right.png","prior":"prior_b.json","truth":"../truth.json","out":"b.json"}"#.to_string(),
            String::new(),
            r#"{"left":"../left.png","right":"../right.png","prior":"prior_c.json","calib":"../calib.json","seed":5}"#.to_string(),
        ],
    );
    let out = dir.join("results.jsonl");
    let s = relocalize::run_batch(&batch_args(&d.plain, Some(out.clone())), &pairs, false).unwrap();
    assert_eq!(s.map_loads, 1);
    // One check of the map product for the whole batch: the job's, whose
    // view the runner uses for every pair.
    assert_eq!(s.map_checks, 1);
    assert_eq!(s.results.len(), 3);
    assert_eq!(s.exit_code(), 0, "{:?}", s.results);
    let ids: Vec<Option<&str>> = s.results.iter().map(|r| r.id.as_deref()).collect();
    assert_eq!(ids, [Some("a"), Some("b"), None]);
    assert!(
        s.results[2].source.ends_with("pairs.jsonl:4"),
        "{}",
        s.results[2].source
    );
    for r in &s.results {
        assert_eq!(r.status, "ok", "{r:?}");
        assert!(r.world_from_left.is_some());
    }
    for r in &s.results[..2] {
        assert!(r.error_t_mm.is_some_and(|e| e < 50.0), "{r:?}");
    }
    assert_eq!(s.results[2].error_t_mm, None);
    // The first pair is exactly the single-pair command's result.
    let single = relocalize::relocalize_one(&args(&d.plain, "prior.json", None))
        .unwrap()
        .outcome;
    let first = s.results[0].world_from_left;
    assert_eq!(first, relocalize::outcome_result(&single).world_from_left);
    // The per-pair result.json of pair b is the batch line's pose.
    let b =
        json::parse_result(&std::fs::read(dir.join("b.json")).unwrap(), Path::new("b")).unwrap();
    assert_eq!(b.world_from_left, s.results[1].world_from_left);
    eprintln!("{}", s.line());
}

/// Bad pairs fail on their own line (malformed JSON, a missing image, an
/// unknown field) and make the exit code 1 without stopping the batch, `--out`
/// holding one line per pair; bad
/// input of the batch itself (missing pairs file, no pairs, an existing
/// --out) is an error (exit code 2) and writes nothing.
///
/// Verifies: VTSM-CLI-038
#[test]
fn bad_pairs_fail_alone_and_bad_batches_are_refused() {
    let d = dirs();
    let dir = d.plain.join("batch_bad");
    std::fs::create_dir_all(&dir).unwrap();
    let pairs = write_pairs(
        &dir,
        "pairs.jsonl",
        &[
            r#"{"left":"../left.png","right":"../right.png""#.to_string(),
            r#"{"left":"../missing.png","right":"../right.png","prior":"../prior.json"}"#
                .to_string(),
            r#"{"left":"../left.png","right":"../right.png","prior":"../prior.json","colour":1}"#
                .to_string(),
            r#"{"left":"../left.png","right":"../right.png","prior":"../prior.json"}"#.to_string(),
        ],
    );
    let s = relocalize::run_batch(&batch_args(&d.plain, None), &pairs, false).unwrap();
    let status: Vec<&str> = s.results.iter().map(|r| r.status.as_str()).collect();
    assert_eq!(status, ["error", "error", "error", "ok"], "{:?}", s.results);
    assert_eq!(s.exit_code(), EXIT_RELOC_FAILED);
    assert!(s.results[0]
        .message
        .as_deref()
        .unwrap()
        .contains("invalid pair"));
    assert!(s.results[1]
        .message
        .as_deref()
        .unwrap()
        .contains("missing.png"));
    assert!(s.results[2].message.as_deref().unwrap().contains("colour"));
    assert_eq!(s.map_loads, 1);

    // `run` writes one line per pair to --out and exits 1 (some pair failed).
    let out = dir.join("results.jsonl");
    assert_eq!(
        relocalize::run(&with_pairs(batch_args(&d.plain, Some(out.clone())), &pairs)).unwrap(),
        EXIT_RELOC_FAILED
    );
    let lines: Vec<batch::PairResult> = std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 4);
    assert_eq!(lines[3].world_from_left, s.results[3].world_from_left);
    std::fs::remove_file(&out).unwrap();
    let missing = relocalize::run(&with_pairs(
        batch_args(&d.plain, Some(out.clone())),
        &dir.join("nope.jsonl"),
    ));
    assert_eq!(vtsm_sim::cli::report(&missing.unwrap_err()), 2);
    let empty = write_pairs(&dir, "empty.jsonl", &[String::new()]);
    let e =
        relocalize::run(&with_pairs(batch_args(&d.plain, Some(out.clone())), &empty)).unwrap_err();
    assert!(e.to_string().contains("no pairs"), "{e}");
    assert!(!out.exists(), "nothing is written for a bad batch");
    std::fs::write(&out, "keep\n").unwrap();
    let e =
        relocalize::run(&with_pairs(batch_args(&d.plain, Some(out.clone())), &pairs)).unwrap_err();
    assert!(e.to_string().contains("exists"), "{e}");
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "keep\n");
}
