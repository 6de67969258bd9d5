use super::args::{BaselineArg, LightModelArg, MaskArg};
use super::*;
use crate::cli::demo::MAP_HOURS;
use crate::eval::columns::GroupColumns;
use crate::eval::TrialOutcome;
use crate::io::mesh::MeshData;
use crate::render::LightModel;
use crate::scene::{Profile, Scene, STOPS_PER_CIRCLE};
use crate::terrain::TerrainKind;
use nalgebra::UnitQuaternion;
use vtsm_core::geom::{Camera, Pose, Vec3};

fn small(suite: Suite) -> SuiteConfig {
    SuiteConfig {
        terrains: vec![TerrainKind::Flagstone],
        hours: vec![0.0],
        steps: vec![12],
        seeds_k: 4,
        ..SuiteConfig::new(suite, Profile::Test, 1, 7)
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// Check a run's outcomes, summaries and written files against each other.
fn check_run(run: &SuiteRun, groups: usize, trials: usize, prior_mm: (f64, f64), plots: &[&str]) {
    assert_eq!(run.groups.len(), groups);
    assert_eq!(run.outcomes.len(), groups * trials);
    for o in &run.outcomes {
        assert_eq!(o.success, o.failure.is_none(), "{o:?}");
        assert!(
            o.init_t_mm >= prior_mm.0 - 1e-3 && o.init_t_mm <= prior_mm.1 + 1e-3,
            "{o:?}"
        );
        assert!(o.init_r_deg <= f64::from(PRIOR_MAX_DEG) + 1e-3, "{o:?}");
        assert!(o.final_t_mm.is_finite() && o.final_t_mm >= 0.0);
        let d = o.columns.view.unwrap().dist_m;
        assert!(d.is_finite() && d >= 0.0, "{o:?}");
        if o.success {
            assert!(
                o.iterations > 0 && o.inliers >= 3 && o.time_s > 0.0,
                "{o:?}"
            );
        }
    }
    for g in &run.groups {
        let rows: Vec<&TrialOutcome> = run.outcomes.iter().filter(|o| o.group == g.group).collect();
        let ok: Vec<f64> = rows
            .iter()
            .filter(|o| o.success)
            .map(|o| o.final_t_mm)
            .collect();
        assert_eq!(g.trials, trials);
        assert_eq!(g.successes, ok.len());
        assert!((g.success_pct - 100.0 * ok.len() as f64 / trials as f64).abs() < 1e-9);
        let m = median(ok);
        assert!(m.is_nan() && g.final_t_mm_median.is_nan() || m == g.final_t_mm_median);
    }
    let dir = std::env::temp_dir().join(format!(
        "vtsm-eval-suite-{}-{}",
        run.meta.suite,
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    write_run(&dir, run, false).unwrap();
    // A second write without --force must refuse.
    assert!(write_run(&dir, run, false).is_err());
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(json["meta"]["suite"], run.meta.suite.as_str());
    assert_eq!(json["meta"]["profile"], "test");
    assert_eq!(json["meta"]["seed"], 7);
    assert!(!json["meta"]["git_revision"].as_str().unwrap().is_empty());
    assert!(json["meta"]["params"]["relocalization"]
        .as_str()
        .unwrap()
        .contains("template_px"));
    assert_eq!(json["trials"].as_array().unwrap().len(), run.outcomes.len());
    let csv = std::fs::read_to_string(dir.join("trials.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let (cs, cf, ce) = (col("success"), col("failure"), col("final_t_mm"));
    let rows: Vec<Vec<String>> = lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    assert_eq!(rows.len(), run.outcomes.len());
    for (r, o) in rows.iter().zip(&run.outcomes) {
        assert_eq!(r.len(), header.len());
        assert_eq!(r[cs] == "true", o.success);
        assert_eq!(r[cf].is_empty(), o.success);
        let e: f64 = r[ce].parse().unwrap();
        assert!((e - o.final_t_mm).abs() < 1e-3);
    }
    let table = std::fs::read_to_string(dir.join("table.md")).unwrap();
    for g in &run.groups {
        let row = format!("| {} | {} | {:.0} % |", g.group, g.trials, g.success_pct);
        assert!(table.contains(&row), "{row} not in\n{table}");
    }
    for p in std::iter::once(&"final_error_cdf").chain(plots) {
        let svg = std::fs::read_to_string(dir.join(format!("{p}.svg"))).unwrap();
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        // Every group is in the legend.
        for g in &run.groups {
            assert!(
                svg.contains(&g.group.replace('&', "&amp;")),
                "{p}: {}",
                g.group
            );
        }
        let png = std::fs::read(dir.join(format!("{p}.png"))).unwrap();
        assert!(png.starts_with(b"\x89PNG\r\n\x1a\n"), "{p}.png");
    }
    // The CDF is drawn as lines, one per group with a success.
    let cdf = std::fs::read_to_string(dir.join("final_error_cdf.svg")).unwrap();
    let with_success = run.groups.iter().filter(|g| g.successes > 0).count();
    assert!(cdf.matches("<polyline").count() >= with_success);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Verifies: VTSM-CLI-019
#[test]
fn paper_and_baseline_suites_run_end_to_end_with_consistent_outputs() {
    let cfg = small(Suite::Paper);
    let run = run_suite(&cfg, "test").unwrap();
    check_run(
        &run,
        1,
        1,
        (100.0, 200.0),
        &["final_vs_view_distance", "final_vs_view_angle"],
    );
    // At Δ0 h on flagstone the paper's method converges.
    assert!(run.outcomes[0].success, "{:?}", run.outcomes[0]);
    assert!(run.outcomes[0].final_t_mm < run.outcomes[0].init_t_mm);
    let cfg = small(Suite::Baseline);
    let run = run_suite(&cfg, "test").unwrap();
    check_run(
        &run,
        1,
        1,
        (100.0, 200.0),
        &["final_vs_view_distance", "final_vs_view_angle"],
    );
    assert!(run.groups[0].group.contains("b=0.20m"));
}

/// Verifies: VTSM-CLI-022, VTSM-CLI-023
#[test]
fn feature_baseline_runs_on_the_same_trials_and_is_reported_side_by_side() {
    let cfg = SuiteConfig {
        baseline: Some(Method::Features),
        ..small(Suite::Paper)
    };
    let run = run_suite(&cfg, "test").unwrap();
    check_run(
        &run,
        2,
        1,
        (100.0, 200.0),
        &["final_vs_view_distance", "final_vs_view_angle"],
    );
    let (v, f) = (&run.outcomes[0], &run.outcomes[1]);
    assert_eq!((v.method.as_str(), f.method.as_str()), ("vtsm", "features"));
    assert_eq!(f.group, format!("{} · features", v.group));
    // Paired: same capture, seed and prior.
    assert_eq!(
        (v.seed, v.init_t_mm, v.columns.capture),
        (f.seed, f.init_t_mm, f.columns.capture)
    );
    // A finite result or a clean, named failure.
    assert!(
        f.final_t_mm.is_finite() && f.final_r_deg.is_finite(),
        "{f:?}"
    );
    assert!(f.success || f.failure.as_deref().is_some_and(|c| !c.is_empty()));
    assert!(f.columns.features.unwrap().live_keypoints > 0, "{f:?}");
    // The engine's work counters are recorded with each VTSM trial.
    assert!(v.columns.engine.unwrap().attempts >= 1, "{v:?}");
    assert!(eval::csv(&run.outcomes)
        .lines()
        .next()
        .is_some_and(|h| h.contains(",attempts,")));
    assert!(run.notes.contains("VTSM and the features baseline"));
    assert!(run.notes.contains(&format!("| {} |", v.group)));
    // Deterministic.
    let again = run_suite(&cfg, "test").unwrap();
    assert_eq!(again.outcomes[1].final_t_mm, f.final_t_mm);
    assert_eq!(again.outcomes[1].failure, f.failure);
    // Only with the suites it is defined for, and only known names.
    let mut args = Args {
        seeds_k: 4,
        baseline: Some(BaselineArg::Features),
        ..Args::new(Suite::Uncertainty50)
    };
    assert!(config_from_args(&args).is_err());
    args.suite = Some(Suite::Baseline);
    let parsed = config_from_args(&args).unwrap();
    assert_eq!(parsed.baseline, Some(Method::Features));
    assert_eq!(
        (parsed.light_model, parsed.mask_all),
        (LightModel::Full, false)
    );
    args.light_model = LightModelArg::NoCastShadows;
    args.mask = MaskArg::All;
    let parsed = config_from_args(&args).unwrap();
    assert_eq!(
        (parsed.light_model, parsed.mask_all),
        (LightModel::NoCastShadows, true)
    );
    args.wind = 1.5;
    assert!(config_from_args(&args).is_err());
    args.wind = 0.5;
    assert_eq!(config_from_args(&args).unwrap().wind, 0.5);
    args.map_coarse = 3;
    assert!(config_from_args(&args).is_err());
    args.map_coarse = 4;
    assert_eq!(config_from_args(&args).unwrap().map_coarse, 4);
    // Unknown names are refused by the parser, suite and terrain names in
    // any case.
    let parse = |line: &str| {
        <Cli as clap::Parser>::try_parse_from(
            std::iter::once("eval").chain(line.split_whitespace()),
        )
    };
    for bad in [
        "--suite paper --mask rocks",
        "--suite paper --light-model overcast",
        "--suite paper --baseline sift",
        "--suite everything",
        "--suite paper --terrains flagstone,moon",
    ] {
        assert!(parse(bad).is_err(), "{bad}");
    }
    let cli = parse("--suite PAPER --terrains Cfa2,flagstone --hours 0,3 --profile demo").unwrap();
    let cfg = config_from_args(&cli.args).unwrap();
    assert_eq!(cfg.suite, Suite::Paper);
    assert_eq!(cfg.terrains, [TerrainKind::Cfa2, TerrainKind::Flagstone]);
    assert_eq!((cfg.hours, cfg.profile), (vec![0.0, 3.0], Profile::Demo));
}

/// The command line of `vtsm eval` alone.
#[derive(clap::Parser)]
struct Cli {
    #[command(flatten)]
    args: Args,
}

/// `--wind` changes the live pairs and not the map or the priors (beyond the
/// micrometres the ground under the rover moves); `--mask all` changes the
/// map's mask and `--map-coarse 4` the map's resolution, not the pairs or
/// the priors.
///
/// Verifies: VTSM-SIM-016, VTSM-SIM-017
#[test]
fn wind_and_mask_change_only_what_they_name() {
    let base = SuiteConfig {
        terrains: vec![TerrainKind::Cfa6],
        ..small(Suite::Paper)
    };
    let plain = run_suite(&base, "test").unwrap();
    let windy = run_suite(
        &SuiteConfig {
            wind: 1.0,
            ..base.clone()
        },
        "test",
    )
    .unwrap();
    let masked = run_suite(
        &SuiteConfig {
            mask_all: true,
            ..base.clone()
        },
        "test",
    )
    .unwrap();
    let coarse = run_suite(
        &SuiteConfig {
            map_coarse: 4,
            ..base.clone()
        },
        "test",
    )
    .unwrap();
    for run in [&windy, &masked, &coarse] {
        assert_eq!(run.outcomes.len(), plain.outcomes.len());
        for (a, b) in plain.outcomes.iter().zip(&run.outcomes) {
            // The rover stands on the live ground, which the wind moves by
            // millimetres, so the truth (and the prior drawn about it) may
            // move by a micrometre.
            assert_eq!(a.seed, b.seed);
            assert!((a.init_t_mm - b.init_t_mm).abs() < 1e-2, "{a:?} {b:?}");
        }
    }
    let finals = |r: &SuiteRun| {
        r.outcomes
            .iter()
            .map(|o| (o.final_t_mm, o.inliers))
            .collect::<Vec<_>>()
    };
    assert_ne!(finals(&plain), finals(&windy), "wind changed nothing");
    assert_ne!(finals(&plain), finals(&masked), "the mask changed nothing");
    assert_ne!(
        finals(&plain),
        finals(&coarse),
        "the coarse map changed nothing"
    );
    // The live pairs are the same: the prior errors are equal bit for bit.
    for (a, b) in plain.outcomes.iter().zip(&coarse.outcomes) {
        assert_eq!(a.init_t_mm.to_bits(), b.init_t_mm.to_bits());
    }
    assert_eq!(windy.meta.params["wind"], 1.0);
    assert_eq!(masked.meta.params["mask"], "all");
    assert_eq!(coarse.meta.params["map_coarse"], 4);
    assert_eq!(plain.meta.params["map_coarse"], 1);
}

/// The paper suite with the whole scene offset to UTM-sized coordinates
/// gives the same trials: same successes, seeds, inliers and iterations,
/// errors within 1 µm / 10⁻⁴° (well inside 1 mm / 0.01°): the maps' origin
/// is the offset, so the core's local inputs are the unshifted ones.
///
/// Verifies: VTSM-CLI-037
#[test]
fn origin_offset_leaves_suite_results_unchanged() {
    let cfg = SuiteConfig {
        trials: 2,
        ..small(Suite::Paper)
    };
    let plain = run_suite(&cfg, "test").unwrap();
    let offset = [391_234.567_8, 3_784_321.987_6, 312.25];
    let moved = run_suite(
        &SuiteConfig {
            origin: Some(offset),
            ..cfg.clone()
        },
        "test",
    )
    .unwrap();
    assert_eq!(plain.outcomes.len(), moved.outcomes.len());
    assert!(
        plain.outcomes.iter().any(|o| o.success),
        "nothing to compare"
    );
    for (a, b) in plain.outcomes.iter().zip(&moved.outcomes) {
        assert_eq!(
            (a.seed, a.success, &a.failure),
            (b.seed, b.success, &b.failure)
        );
        assert!((a.init_t_mm - b.init_t_mm).abs() < 1e-3, "{a:?} {b:?}");
        // The core saw the same inputs: only the f64 error arithmetic differs.
        assert_eq!((a.inliers, a.iterations), (b.inliers, b.iterations));
        assert!((a.final_t_mm - b.final_t_mm).abs() < 1e-3, "{a:?} {b:?}");
        assert!((a.final_r_deg - b.final_r_deg).abs() < 1e-4, "{a:?} {b:?}");
        eprintln!(
            "trial {}: final {:.6} mm / {:.6}° vs {:.6} mm / {:.6}° (inliers {} vs {})",
            a.trial, a.final_t_mm, a.final_r_deg, b.final_t_mm, b.final_r_deg, a.inliers, b.inliers
        );
    }
    assert_eq!(moved.meta.params["origin"][0].as_f64(), Some(offset[0]));
    // The offset mesh at the offset's origin has the simulator's vertices
    // (all but coordinates within millimetres of 0 bit for bit); with the
    // default origin, the unshifted mesh's box centre plus the offset.
    let scene = Scene::new(TerrainKind::Flagstone, cfg.seed, cfg.profile);
    let map = scene.map(&scene.lighting(MAP_HOURS));
    let m = offset_mesh(&map, offset, Some(offset)).unwrap();
    let same = m
        .vertices
        .iter()
        .zip(&map.vertices)
        .filter(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits))
        .count();
    eprintln!("{same} of {} vertices bit for bit", map.vertices.len());
    assert!(same * 1000 >= map.vertices.len() * 999);
    for (a, b) in m.vertices.iter().zip(&map.vertices) {
        assert!(a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-8));
    }
    let c = offset_mesh(&map, [0.0; 3], None).unwrap().origin;
    let d = offset_mesh(&map, offset, None).unwrap();
    for ((o, s), c) in d.origin.iter().zip(offset).zip(c) {
        assert!((o - s - c).abs() < 1e-6, "{:?} vs {c}", d.origin);
    }
}

/// (prior_max_m, seeds_k, t0_m, r0_deg) of a trial of a prior group.
fn prior_cols(o: &TrialOutcome) -> (f32, u16, f32, f32) {
    match o.columns.group {
        Some(GroupColumns::Prior {
            prior_max_m,
            seeds_k,
            t0_m,
            r0_deg,
            ..
        }) => (prior_max_m, seeds_k, t0_m, r0_deg),
        g => panic!("not a prior group: {g:?}"),
    }
}

/// Verifies: VTSM-CLI-019, VTSM-CLI-021
#[test]
fn uncertainty_suite_pairs_k0_stating_the_uncertainty_and_k_seeds() {
    let run = run_suite(&small(Suite::Uncertainty50), "test").unwrap();
    check_run(&run, 4, 1, (100.0, 500.0), &["final_vs_initial"]);
    // Groups in order: the 10–20 cm reference, K=0 told the uncertainty,
    // K=0 told nothing, K seeds.
    let [r, a, u, b] = [0, 1, 2, 3].map(|i| &run.outcomes[i]);
    assert!(r.group.contains("ref 10-20cm"), "{}", r.group);
    assert!((100.0..=200.0 + 1e-3).contains(&r.init_t_mm), "{r:?}");
    assert_eq!(prior_cols(r).0, PRIOR_M.1);
    // The reference relocalizes the same capture as the other groups.
    assert_eq!(r.seed, a.seed);
    // Paired: same capture and prior in the 50 cm groups, only what the
    // engine is told and K differ.
    for o in [u, b] {
        assert_eq!((a.seed, a.init_t_mm), (o.seed, o.init_t_mm));
        assert_eq!(prior_cols(o).0, PRIOR_50_M.1);
    }
    assert!(a.init_t_mm >= 250.0 - 1e-3, "{a:?}");
    assert_eq!((prior_cols(a).1, prior_cols(u).1), (0, 0));
    assert_eq!(prior_cols(b).1, 4);
    // The single start is told the priors' real uncertainty, or nothing
    // (the default t̃₀); the multi-seed group keeps the default t̃₀ and
    // spreads its seeds instead.
    assert_eq!((prior_cols(a).2, prior_cols(a).3), (0.5, 1.5));
    for o in [r, u, b] {
        assert!((prior_cols(o).2 - 0.2).abs() < 1e-6, "{:?}", o.columns);
    }
    assert!(a.group.contains("K=0 t0=0.50m"), "{}", a.group);
    assert!(u.group.contains("K=0 untold"), "{}", u.group);
    assert_eq!(run.meta.params["stated_uncertainty"]["t_m"], 0.5);
}

/// Verifies: VTSM-CLI-019, VTSM-CLI-020
#[test]
fn stepsize_suite_reports_range_breakdown() {
    let run = run_suite(&small(Suite::Stepsize), "test").unwrap();
    check_run(&run, 2, 1, (100.0, 200.0), &["final_vs_range"]);
    assert!(run.notes.contains("By range"));
    let binned: usize = run
        .notes
        .lines()
        .filter(|l| l.starts_with("| ") && l.contains('–') || l.starts_with("| ≥"))
        .map(|l| {
            l.split('|')
                .nth(2)
                .unwrap()
                .trim()
                .parse::<usize>()
                .unwrap()
        })
        .sum();
    assert_eq!(binned, run.outcomes.len());
}

/// Verifies: VTSM-CLI-020
#[test]
fn restricted_map_keeps_exactly_the_triangles_a_view_sees() {
    let scene_cam = Camera::new(100.0, 100.0, 49.5, 49.5, 100, 100).unwrap();
    // Camera at (0,0,1) looking straight down (cam z = -world z).
    let down = Pose::new(
        UnitQuaternion::from_axis_angle(&Vec3::x_axis(), std::f32::consts::PI),
        Vec3::new(0.0, 0.0, 1.0),
    );
    // Flat ground triangles centred at x = 0, 0.3, 0.8 (out of the ±0.5 FOV), 5 (out of range).
    let mut mesh = MeshData {
        vertices: Vec::new(),
        triangles: Vec::new(),
        uvs: Vec::new(),
        mask: Vec::new(),
        texture: crate::io::image::Gray8 {
            width: 1,
            height: 1,
            pixels: vec![0],
        },
        origin: [0.0; 3],
    };
    for (i, x) in [0.0f32, 0.3, 0.8, 5.0].iter().enumerate() {
        let n = mesh.vertices.len() as u32;
        mesh.vertices.extend([
            [x - 0.01, -0.01, 0.0],
            [x + 0.01, -0.01, 0.0],
            [*x, 0.01, 0.0],
        ]);
        mesh.triangles.push([n, n + 1, n + 2]);
        mesh.uvs.push([[0.0; 2]; 3]);
        mesh.mask.push(i % 2 == 0);
    }
    let kept = restrict_to_views(&mesh, &scene_cam, &[down]);
    // Reference: pinhole with f = 100 px over a 100 px image sees |x| < 0.5 at 1 m depth.
    assert_eq!(kept.triangles, vec![[0, 1, 2], [3, 4, 5]]);
    assert_eq!(kept.mask, vec![true, false]);
    assert_eq!(kept.vertices, mesh.vertices);
    // A camera below the ground sees nothing (the ground faces up).
    let under = Pose::new(UnitQuaternion::identity(), Vec3::new(0.0, 0.0, -1.0));
    assert!(restrict_to_views(&mesh, &scene_cam, &[under])
        .triangles
        .is_empty());
    // No views, no map.
    assert!(restrict_to_views(&mesh, &scene_cam, &[])
        .triangles
        .is_empty());
}

/// Verifies: VTSM-CLI-021
#[test]
fn priors_and_captures_follow_the_protocol() {
    let truth = Pose::new(
        UnitQuaternion::from_euler_angles(0.1, -0.4, 2.0),
        Vec3::new(1.0, -2.0, 0.7),
    );
    for k in 0..200u64 {
        for (range, lo, hi) in [(PRIOR_M, 0.10, 0.20), (PRIOR_50_M, 0.25, 0.50)] {
            let p = prior_in_range(&truth, trial_seed(3, k as usize), range);
            let dt = (p.translation() - truth.translation()).norm();
            assert!(dt >= lo - 1e-5 && dt <= hi + 1e-5, "{dt}");
            let ang = (p.rotation() * truth.rotation().inverse())
                .angle()
                .to_degrees();
            assert!(ang <= PRIOR_MAX_DEG + 1e-3, "{ang}");
        }
    }
    // Ten trials visit ten distinct stops, spread over both circles.
    let stops: Vec<u32> = (0..10)
        .map(|k| {
            let c = capture_for_trial(k, 10, 0.4);
            c.circle * STOPS_PER_CIRCLE + c.stop
        })
        .collect();
    assert_eq!(stops, vec![0, 3, 6, 9, 12, 15, 18, 21, 24, 27]);
    // Seeds differ per trial and repeat per base seed.
    assert_ne!(trial_seed(1, 0), trial_seed(1, 1));
    assert_eq!(trial_seed(1, 5), trial_seed(1, 5));
    assert_ne!(trial_seed(1, 5), trial_seed(2, 5));
    let near = nearest_view(
        &truth,
        &[
            Pose::new(
                truth.rotation(),
                truth.translation() + Vec3::new(3.0, 0.0, 0.0),
            ),
            Pose::new(
                UnitQuaternion::from_euler_angles(0.0, 0.0, 0.5) * truth.rotation(),
                truth.translation() + Vec3::new(0.0, 0.6, 0.8),
            ),
        ],
    )
    .unwrap();
    assert!((near.0 - 1.0).abs() < 1e-5);
    // A rotation of 0.5 rad about world z: the optical axis turns by at most 0.5 rad.
    assert!(near.1 > 0.0 && near.1 <= 0.5f64.to_degrees() + 1e-3);
}

/// `--change` changes the live depot and `--camera` the live frames, not the
/// maps: the trials differ, the camera leaves the priors bit for bit, and
/// both are recorded.
///
/// Verifies: VTSM-SIM-018, VTSM-SIM-020
#[test]
fn change_and_camera_change_only_the_live_side() {
    let base = SuiteConfig {
        terrains: vec![TerrainKind::Cfa6],
        ..small(Suite::Paper)
    };
    let plain = run_suite(&base, "test").unwrap();
    let changed = run_suite(
        &SuiteConfig {
            change: crate::terrain::DepotChange::parse("tracks=3,rocks=0.5").unwrap(),
            ..base.clone()
        },
        "test",
    )
    .unwrap();
    let camera = run_suite(
        &SuiteConfig {
            camera: crate::effects::CameraEffects::parse("noise=4,jpeg=60").unwrap(),
            ..base.clone()
        },
        "test",
    )
    .unwrap();
    let finals = |r: &SuiteRun| {
        r.outcomes
            .iter()
            .map(|o| (o.final_t_mm.to_bits(), o.inliers))
            .collect::<Vec<_>>()
    };
    assert_ne!(
        finals(&plain),
        finals(&changed),
        "the change changed nothing"
    );
    assert_ne!(
        finals(&plain),
        finals(&camera),
        "the camera changed nothing"
    );
    for (a, b) in plain.outcomes.iter().zip(&camera.outcomes) {
        assert_eq!(a.init_t_mm.to_bits(), b.init_t_mm.to_bits());
    }
    assert_eq!(changed.meta.params["change"], "tracks=3,rocks=0.5");
    assert_eq!(camera.meta.params["camera"], "noise=4,jpeg=60");
    assert_eq!(plain.meta.params["camera"], "none");
}

/// `--suite hard` runs every condition on every terrain, writes the envelope
/// (a row per condition) and its four figures, records each group's
/// condition in its columns, and refuses the flags it sets itself.
///
/// Verifies: VTSM-SIM-019
#[test]
fn the_hard_suite_writes_the_envelope() {
    let cfg = SuiteConfig {
        terrains: vec![TerrainKind::Cfa2],
        ..small(Suite::Hard)
    };
    let run = run_suite(&cfg, "test").unwrap();
    let conditions = super::suites::hard::conditions();
    assert_eq!(run.groups.len(), conditions.len());
    for c in &conditions {
        assert!(
            run.notes.contains(&format!("| {} |", c.name)),
            "no envelope row for {}",
            c.name
        );
    }
    for stem in [
        "envelope_sun",
        "envelope_hours",
        "envelope_rocks",
        "envelope_map",
    ] {
        assert!(run.plots.iter().any(|f| f.stem == stem), "no {stem}");
    }
    for (o, c) in run.outcomes.iter().zip(&conditions) {
        assert_eq!(o.group, format!("cfa2 {}", c.name));
        match o.columns.group {
            Some(GroupColumns::Condition {
                hours,
                sun_el_deg,
                map_coarse,
                tracks,
                camera,
                ..
            }) => {
                assert!((hours - (c.hours - c.map_hours)).abs() < 1e-4, "{}", c.name);
                let el = crate::render::Sun::depot(c.hours).elevation_deg;
                assert!((sun_el_deg - el).abs() < 1e-3, "{}", c.name);
                assert_eq!(map_coarse, c.map_coarse);
                assert_eq!(tracks, c.change.tracks);
                assert_eq!(camera, !c.camera.is_none());
            }
            ref other => panic!("{}: {other:?}", c.name),
        }
    }
    for bad in [
        SuiteConfig {
            map_coarse: 2,
            ..cfg.clone()
        },
        SuiteConfig {
            hours: vec![3.0],
            ..cfg.clone()
        },
        SuiteConfig {
            camera: crate::effects::CameraEffects::parse("jpeg=50").unwrap(),
            ..cfg.clone()
        },
    ] {
        assert!(run_suite(&bad, "test").is_err());
    }
}

/// `--score-deciles` counts every attempt in one decile of the map's
/// scores and changes no outcome; `--map-scores on` ships the scores in a
/// version-3 product the trials draw from.
///
/// Verifies: VTSM-SIM-021
#[test]
fn score_deciles_count_the_attempts_and_change_nothing() {
    let base = SuiteConfig {
        terrains: vec![TerrainKind::Cfa6],
        hours: vec![0.0],
        ..small(Suite::Paper)
    };
    let plain = run_suite(&base, "test").unwrap();
    let counted = run_suite(
        &SuiteConfig {
            score_deciles: true,
            ..base.clone()
        },
        "test",
    )
    .unwrap();
    let finals = |r: &SuiteRun| {
        r.outcomes
            .iter()
            .map(|o| {
                (
                    o.final_t_mm.to_bits(),
                    o.inliers,
                    o.columns.engine.map(|e| e.attempts),
                )
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(finals(&plain), finals(&counted));
    for o in &counted.outcomes {
        let sc = o.columns.scores.expect("decile columns");
        let attempts: u32 = sc.attempts.iter().sum();
        let engine = o.columns.engine.expect("engine columns").attempts;
        // Every attempt that drew a vertex is in one decile (the others
        // found none in view).
        assert!(attempts > 0 && attempts <= engine, "{attempts} of {engine}");
        assert!(sc.correct.iter().zip(&sc.attempts).all(|(c, a)| c <= a));
        assert!(sc.correct.iter().sum::<u32>() > 0);
    }
    assert!(counted
        .notes
        .contains("by decile of the map's sampling scores"));
    assert!(!plain
        .notes
        .contains("by decile of the map's sampling scores"));

    let scored = run_suite(
        &SuiteConfig {
            map_scores: true,
            ..base.clone()
        },
        "test",
    )
    .unwrap();
    assert_ne!(
        finals(&plain),
        finals(&scored),
        "the scores drew nothing else"
    );
    assert!(scored.outcomes.iter().all(|o| o.failure.is_none()));
}
