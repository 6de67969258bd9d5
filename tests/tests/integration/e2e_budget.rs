//! `vtsm budget`: the workspace and engine sizes it prints are the core's, and
//! its measured row is the work of a real test-profile relocalization.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::mem::size_of;
use vtsm_core::config as cfg;
use vtsm_core::ncc::Run;
use vtsm_core::reloc::workspace::{PAPER_WORKSPACE_BYTES, TEST_WORKSPACE_BYTES};
use vtsm_core::reloc::{Outcome, Pipeline, RansacSolver, Relocalizer};
use vtsm_sim::cli::budget::{measured_rows, rows, Row, MEASURED_SCENE};
use vtsm_sim::locate::{self, Request};
use vtsm_sim::scene::{perturbed_prior, Capture, Profile, Scene};

fn value(rows: &[Row], item: &str) -> u64 {
    rows.iter()
        .find(|r| r.item == item)
        .unwrap_or_else(|| panic!("no row `{item}`"))
        .value
}

/// Verifies: VTSM-CLI-018
#[test]
fn budget_prints_workspace_and_engine_sizes() {
    let r = rows();
    let paper = value(
        &r,
        "pipeline workspace, paper (ℓ 256, W 1024, coarse-to-fine)",
    );
    let test = value(&r, "pipeline workspace, test (ℓ 64, W 256, coarse-to-fine)");
    assert_eq!(paper, PAPER_WORKSPACE_BYTES as u64);
    assert_eq!(test, TEST_WORKSPACE_BYTES as u64);
    // Independent lower bound: four ℓ² u8 planes (templates and masks) plus four
    // ℓ² u32 planes (depths) are in the workspace, besides the NCC scratch.
    for (bytes, l) in [(paper, cfg::MAX_TEMPLATE_PX as u64), (test, 64)] {
        assert!(bytes > 4 * l * l + 16 * l * l, "{bytes} for ℓ {l}");
    }
    assert!(size_of::<Run>() > 0);
    assert_eq!(
        value(&r, "core::reloc::Relocalizer<(), ()> (engine state)"),
        size_of::<Relocalizer<(), ()>>() as u64
    );
    assert_eq!(
        value(&r, "core::reloc::Relocalizer<Pipeline, RansacSolver>"),
        size_of::<Relocalizer<Pipeline<'static, 'static>, RansacSolver>>() as u64
    );
    assert_eq!(
        value(&r, "core::reloc::Outcome"),
        size_of::<Outcome>() as u64
    );
}

/// The measured rows are the counters of the same relocalization run here
/// independently (the engine is deterministic), and stay within the caps.
///
/// Verifies: VTSM-CLI-018
#[test]
fn budget_measured_rows_are_a_real_run() {
    let seed = 1;
    let m = measured_rows(seed).unwrap();
    let v = |item: &str| value(&m, &format!("test-profile relocalization: {item}"));

    let (kind, hours, stop) = MEASURED_SCENE;
    let scene = Scene::new(kind, seed, Profile::Test);
    let light = scene.lighting(hours);
    let map = scene.map(&light);
    let bytes = map.encode_map(0.5).unwrap();
    let (rig, truth, pair) = scene.capture(&light, &Capture::from_index(stop, 0, 0.40));
    let prior = perturbed_prior(&truth, seed);
    let view = vtsm_core::map::MapView::new_checked(&bytes).unwrap();
    let req = Request::new(view, &pair.left, &pair.right, rig, prior).with_seed(seed);
    let report = locate::relocalize(&req, locate::RunOptions::default()).unwrap();
    let o = &report.outcome;
    let s = &o.stats;
    assert_eq!(v("image width"), u64::from(rig.cam().width()));
    assert_eq!(v("failure code (0 = success)"), 0, "{:?}", o.failure);
    assert_eq!(v("attempts"), u64::from(s.attempts));
    assert_eq!(v("renders"), u64::from(s.pipeline.renders));
    assert_eq!(v("NCC MACs"), s.pipeline.ncc_macs);
    assert_eq!(v("RANSAC iterations"), u64::from(s.ransac_iterations));
    assert_eq!(v("inliers"), u64::from(o.quality.inliers));
    assert_eq!(v("refinement iterations"), u64::from(s.refine.iterations));
    assert!(
        v("refinement iterations")
            <= u64::from(locate::params_for_width(rig.cam().width()).refine_iter)
    );
    assert!(
        v("refinement pair evaluations")
            <= (2 + v("refinement iterations")) * u64::from(o.quality.inliers)
    );
    let (t1, _) = o.pose.error_to(&truth);
    assert!(
        v("final error") < 50_000,
        "final error row {} µm",
        v("final error")
    );
    assert!((v("final error") as f64 - f64::from(t1) * 1e6).abs() <= 1.0);
    // Work happened and stayed within the caps.
    assert!(v("renders") > 0 && v("NCC MACs") > v("NCC positions scored"));
    assert!(v("RANSAC iterations") <= u64::from(s.solves) * cfg::MAX_RANSAC_ITER as u64);
    assert!(v("attempts") <= u64::from(s.rounds) * cfg::MAX_ATTEMPTS_PER_ITER as u64);
    assert!(v("engine wall time (one thread)") > 0);
}

/// The checked-in budget snapshot (`fsw-docs/budgets/budget.snapshot.json`,
/// written by `vtsm budget --write fsw-docs/budgets/`) must agree with the
/// code: every row present on both sides, static sizes and bounds exactly,
/// measured counters within their stated tolerance. A change that moves memory
/// or work fails here until the snapshot is renewed on purpose.
///
/// Verifies: VTSM-CLI-025
#[test]
fn budget_snapshot_matches_the_code() {
    use vtsm_sim::cli::budget::{in_snapshot, profile_rows, tolerance};
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../fsw-docs/budgets/budget.snapshot.json"
    );
    let text = std::fs::read_to_string(path).unwrap();
    let snap: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let mut now = rows();
    now.extend(profile_rows());
    now.extend(measured_rows(1).unwrap());
    let now: Vec<&Row> = now.iter().filter(|r| in_snapshot(r)).collect();
    let key = |s: &str, i: &str| format!("{s} / {i}");
    let mut problems = Vec::new();
    for r in &now {
        let old = snap
            .iter()
            .find(|v| v["section"] == r.section && v["item"] == r.item.as_str());
        match old.and_then(|v| v["value"].as_u64()) {
            None => problems.push(format!("new row {}", key(r.section, &r.item))),
            Some(old) => {
                let tol = tolerance(r) * old as f64;
                if (r.value as f64 - old as f64).abs() > tol {
                    problems.push(format!(
                        "{}: {} in the code, {old} in the snapshot (tolerance {:.0} %)",
                        key(r.section, &r.item),
                        r.value,
                        tolerance(r) * 100.0
                    ));
                }
            }
        }
    }
    for v in &snap {
        let (s, i) = (v["section"].as_str().unwrap(), v["item"].as_str().unwrap());
        if !now.iter().any(|r| r.section == s && r.item == i) {
            problems.push(format!("row gone from the code: {}", key(s, i)));
        }
    }
    assert!(
        problems.is_empty(),
        "budget snapshot out of date (renew with `vtsm budget --write fsw-docs/budgets/`):\n{}",
        problems.join("\n")
    );
}
