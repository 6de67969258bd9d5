//! Bounded fuzzing in CI: every target of `vtsm_tests::fuzz` for a fixed,
//! small number of executions (the recorded long run is
//! `fsw-docs/verification/fuzz.md`), plus checks that the harness itself works:
//! known-bad inputs get their codes, runs are deterministic, and a panic is
//! caught with its input written.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;
use std::time::Instant;
use vtsm_tests::fuzz::{self, corpus, Env, FuzzTarget, Kind, Limits, Stats, Verdict};
use vtsm_tests::workspace_root;

/// Executions per target in CI (seed corpus included). Chosen so that the
/// whole file stays well under a minute in the test profile on 2 cores.
fn ci_iters(t: &FuzzTarget) -> u64 {
    match t.name {
        "reloc" => 60,
        "render" | "ncc" => 1_500,
        "obj_mtl" | "ply" | "image" => 5_000,
        _ => 10_000,
    }
}

fn crash_dir() -> PathBuf {
    workspace_root().join("target/fuzz-crashes")
}

fn run(t: &FuzzTarget, env: &Env, seed: u64, iters: u64) -> Stats {
    let root = workspace_root();
    let seeds = corpus::load(t, &root.join("tests/fuzz/corpus"), &root);
    assert!(!seeds.is_empty(), "{}: no seed corpus", t.name);
    fuzz::run(
        t,
        &seeds,
        env,
        seed,
        Limits { iters, time: None },
        &crash_dir(),
    )
}

/// Every target runs its CI budget without a crash, and exercises what it
/// drives: parsers both accept and reject inputs (with several error kinds),
/// stages reach more than one outcome.
///
/// Verifies: VTSM-ROB-001, VTSM-ROB-002, VTSM-ROB-003, VTSM-ROB-004
#[test]
fn every_target_runs_its_budget_without_a_crash() {
    let env = Env::new("smoke").unwrap();
    let t0 = Instant::now();
    let mut report = Vec::new();
    for t in fuzz::TARGETS {
        let s = run(t, &env, 1, ci_iters(t));
        report.push(format!(
            "{:<11} {:>6} execs {:>8.0}/s accepted {:>5} rejected {:>5} errors {:>3}",
            t.name,
            s.execs,
            s.rate(),
            s.accepted,
            s.rejected,
            s.distinct_errors()
        ));
        assert!(
            s.crashes.is_empty(),
            "{}: crash at iteration {}: {} (input {})",
            t.name,
            s.crashes[0].iter,
            s.crashes[0].message,
            s.crashes[0].file.display()
        );
        assert_eq!(s.execs, ci_iters(t), "{}: stopped early", t.name);
        assert!(
            s.outcomes.len() >= 2,
            "{}: one outcome only ({:?}): the mutator does not reach the code",
            t.name,
            s.outcomes
        );
        if t.kind == Kind::Parser {
            assert!(
                s.accepted > 0 && s.rejected > 0 && s.distinct_errors() >= 3,
                "{}: accepted {}, rejected {}, error kinds {:?}",
                t.name,
                s.accepted,
                s.rejected,
                s.outcomes
            );
        }
    }
    println!("{}", report.join("\n"));
    println!("fuzz smoke: {:.1} s", t0.elapsed().as_secs_f64());
}

fn verdict(name: &str, env: &Env, input: &[u8]) -> Verdict {
    let t = fuzz::target(name).unwrap();
    fuzz::execute(t, env, input).unwrap_or_else(|m| panic!("{name}: crash: {m}"))
}

fn rejected_with(v: &Verdict, what: &str) -> bool {
    matches!(v, Verdict::Rejected(l) if l.contains(what))
}

/// Known-bad inputs are rejected with the expected code or message, and the
/// seeds are accepted, so the targets drive the real checks.
///
/// Verifies: VTSM-ROB-001, VTSM-ROB-002, VTSM-ROB-003, VTSM-ROB-004
#[test]
fn known_bad_inputs_get_their_codes() {
    let env = Env::new("codes").unwrap();
    let map = corpus::tiny_map();
    assert_eq!(verdict("map", &env, &map), Verdict::Accepted);
    assert!(rejected_with(
        &verdict("map", &env, &map[..40]),
        "MAP_TRUNCATED"
    ));
    let mut bad = map.clone();
    bad[0] ^= 0xff;
    assert!(rejected_with(&verdict("map", &env, &bad), "MAP_BAD_MAGIC"));
    let mut trailing = map.clone();
    trailing.extend_from_slice(&[0; 8]);
    assert!(matches!(
        verdict("map", &env, &trailing),
        Verdict::Rejected(_)
    ));

    assert!(rejected_with(
        &verdict("obj", &env, b"v 1 2\nf 1 1 1\n"),
        "vertex needs"
    ));
    assert!(rejected_with(
        &verdict("obj", &env, b"v 0 0 0\n"),
        "no faces"
    ));
    assert!(rejected_with(
        &verdict("obj", &env, b"v 0 0 NaN\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
        "not finite"
    ));
    assert!(matches!(
        verdict(
            "ply",
            &env,
            b"ply\nformat ascii 1.0\nelement vertex 99999999\nend_header\n"
        ),
        Verdict::Rejected(_)
    ));
    assert!(rejected_with(
        &verdict("calib", &env, b"{}"),
        "missing field"
    ));
    let fx = br#"{"width": 640, "height": 480, "fx": 1e300, "fy": 457, "cx": 319.5, "cy": 239.5, "baseline_m": 0.3}"#;
    assert!(matches!(verdict("calib", &env, fx), Verdict::Rejected(_)));
    let e = vtsm_sim::io::calib::parse_calib_any(fx, std::path::Path::new("c.json"))
        .err()
        .unwrap();
    assert!(e.msg.contains("fx"), "{e}");
    assert!(matches!(
        verdict(
            "prior",
            &env,
            br#"{"world_from_left": {"t": [0,0,0], "q": [2,0,0,0]}}"#
        ),
        Verdict::Rejected(_)
    ));
    assert!(rejected_with(&verdict("pairs", &env, b"\n \n"), "no pairs"));
    assert!(rejected_with(
        &verdict("pairs", &env, b"{\"left\": 1}\n"),
        "invalid pair"
    ));
    assert!(matches!(
        verdict("image", &env, b"P5\n99999 99999\n255\n\x00"),
        Verdict::Rejected(_)
    ));
    assert!(matches!(
        verdict("image", &env, b"GIF89a"),
        Verdict::Rejected(_)
    ));

    // Stages: a template side of 15 px, a NaN focal length, a NaN prior.
    let mut ncc_in = vec![0u8; 128];
    ncc_in[0] = 1; // image sized from the template
    ncc_in[1] = 1; // side selector 1: fixed sides
    ncc_in[2] = 1; // 15 px wide
    ncc_in[3] = 2; // height drawn from 16..=40
    assert!(rejected_with(
        &verdict("ncc", &env, &ncc_in),
        "NCC_TEMPLATE_SIZE_INVALID"
    ));
    let mut render_in = vec![0u8; 64];
    render_in[0] = 16; // camera values and pose from the input, window in the image
    render_in[1] = 0; // fx: special value ...
    render_in[2] = 0; // ... NaN
    assert!(rejected_with(
        &verdict("render", &env, &render_in),
        "STEREO_RIG_INVALID"
    ));
    let mut reloc_in = vec![0u8; 96];
    reloc_in[0] = 3; // rendered frames, arbitrary prior (mode / 8 % 4 == 0)
    reloc_in[1] = 0; // first run count: no overwrites
    reloc_in[2] = 0; // quaternion w: special value ...
    reloc_in[3] = 0; // ... NaN
    assert!(rejected_with(
        &verdict("reloc", &env, &reloc_in),
        "RELOC_PRIOR_INVALID"
    ));
}

/// The same seed and counts give the same outcomes; another seed other inputs.
///
/// Verifies: VTSM-ROB-006
#[test]
fn runs_are_deterministic() {
    let env = Env::new("det").unwrap();
    let t = fuzz::target("obj").unwrap();
    let a = run(t, &env, 7, 600);
    let b = run(t, &env, 7, 600);
    let c = run(t, &env, 8, 600);
    assert_eq!(a.outcomes, b.outcomes);
    assert_eq!(a.pool, b.pool);
    assert_ne!(a.outcomes, c.outcomes);
}

fn panics_on_mutated(_env: &Env, d: &[u8]) -> Verdict {
    if d != b"seed" {
        let v: Vec<u8> = Vec::new();
        // An out-of-bounds index, as a bug in a reader would have.
        let _ = v[d.len()];
    }
    Verdict::Accepted
}

/// A panicking target is caught: the run stops with one crash naming the
/// iteration, and the input that crashed is written for replay.
///
/// Verifies: VTSM-ROB-006
#[test]
fn a_panic_is_caught_and_its_input_written() {
    let env = Env::new("panic").unwrap();
    let t = FuzzTarget {
        name: "selftest",
        kind: Kind::Parser,
        about: "panics on any mutated input",
        text: false,
        dict: &[],
        max_len: 64,
        extra_seeds: &[],
        run: panics_on_mutated,
    };
    let dir = std::env::temp_dir().join(format!("vtsm-fuzz-selftest-{}", std::process::id()));
    let s = fuzz::run(
        &t,
        &[b"seed".to_vec()],
        &env,
        3,
        Limits {
            iters: 100,
            time: None,
        },
        &dir,
    );
    assert_eq!(s.crashes.len(), 1);
    let c = &s.crashes[0];
    assert_eq!(c.iter, 1, "the seed runs first, the first mutation crashes");
    assert!(c.message.contains("index out of bounds"), "{}", c.message);
    let saved = std::fs::read(&c.file).unwrap();
    assert_ne!(saved, b"seed");
    assert_eq!(fuzz::execute(&t, &env, &saved).err().map(|_| ()), Some(()));
    let _ = std::fs::remove_dir_all(&dir);
}
