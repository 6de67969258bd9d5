//! `vtsm demo`: build a simulated depot, make its map at one time of day,
//! capture one stereo pair at another, relocalize it from a perturbed prior,
//! print a short report and write `result.json` plus a picture panel like the
//! paper's Fig. 6b (synthetic templates at the random start, the real image,
//! synthetic templates at the final pose).

use crate::cli::eval::protocol::CAMERA_SEED;
use crate::cli::relocalize::{outcome_from_core, outcome_result, Outcome};
use crate::error::{Error, Result, EXIT_RELOC_FAILED};
use crate::io::json;
use crate::locate::{self, Request, RunOptions};
use crate::scene::{perturbed_prior, Capture, Profile, Scene, STOPS_PER_CIRCLE};
use crate::terrain::TerrainKind;
use std::path::{Path, PathBuf};
use std::time::Instant;
use vtsm_core::map::MapView;

/// Hour of the day at which the simulated depot is mapped (the paper's "am").
pub const MAP_HOURS: f32 = 9.5;

/// Arguments of `vtsm demo`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Terrain: flagstone, cfa6 or cfa2.
    #[arg(long, default_value = "flagstone")]
    pub terrain: String,
    /// Hours between mapping (9:30) and relocalization: 0, 3 or 6 (any 0..=8 works).
    #[arg(long, default_value_t = 0.0)]
    pub hours: f32,
    /// Seed of the depot, the capture noise, the prior perturbation and the relocalization.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Map from imagery K times coarser: 1, 2, 4 or 8 (vertex spacing and
    /// texel size × K); the stereo pair is unchanged.
    #[arg(long, value_name = "K", default_value_t = 1)]
    pub map_coarse: u32,
    /// `--change SPEC` and `--camera SPEC`: the depot changed since mapping
    /// and a camera that is not ideal.
    #[command(flatten)]
    pub conditions: super::ConditionsArg,
    /// Capture stop on the paper's grid (0..30).
    #[arg(long, default_value_t = 3)]
    pub stop: u32,
    /// Image profile: demo (1368×912), test (480×320) or paper (5472×3648).
    #[arg(long, default_value = "demo")]
    pub profile: String,
    /// `--verify [repeat,map]`: the engine's upset checks.
    #[command(flatten)]
    pub verify: super::VerifyArg,
    /// `--accuracy T_MM,R_DEG`: end the rounds once the stated uncertainty
    /// meets it.
    #[command(flatten)]
    pub accuracy: super::AccuracyArg,
    /// `--final-pairs N`: correspondences of the last round.
    #[command(flatten)]
    pub final_pairs: super::FinalPairsArg,
    /// `--revisit on|off`, `--near on|off`: the search mechanisms.
    #[command(flatten)]
    pub search: super::SearchArgs,
    /// `--threads N`: the threads the attempts run on (same result).
    #[command(flatten)]
    pub threads: super::ThreadsArg,
    /// `--map-scores on|off`: the map with sampling scores.
    #[command(flatten)]
    pub map_scores: super::MapScoresArg,
    /// Relight the map from the 9:30 sun to the sun of the pair before
    /// matching (`on`; [`crate::relight`]), or match it as made (`off`).
    #[arg(long, value_enum, ignore_case = true, default_value_t = super::OnOff::Off)]
    pub relight: super::OnOff,
    /// Output directory (default: the first free `vtsm-demo/run-N`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Overwrite existing outputs in `--out`.
    #[arg(long)]
    pub force: bool,
}

fn default_out() -> PathBuf {
    (1..)
        .map(|k| PathBuf::from(format!("vtsm-demo/run-{k}")))
        .find(|p| !p.exists())
        .unwrap_or_else(|| PathBuf::from("vtsm-demo/run"))
}

/// Run the command; returns the exit code.
pub fn run(args: &Args) -> Result<u8> {
    let kind = TerrainKind::parse(&args.terrain).ok_or_else(|| {
        Error::msg(format!(
            "unknown --terrain `{}` (flagstone, cfa6, cfa2)",
            args.terrain
        ))
    })?;
    let profile = Profile::parse(&args.profile).ok_or_else(|| {
        Error::msg(format!(
            "unknown --profile `{}` (demo, test, paper)",
            args.profile
        ))
    })?;
    if !(args.hours.is_finite() && (0.0..=8.0).contains(&args.hours)) {
        return Err(Error::msg("--hours must be between 0 and 8"));
    }
    if args.stop >= 2 * STOPS_PER_CIRCLE {
        return Err(Error::msg("--stop must be 0..30"));
    }
    Scene::check_map_coarse(args.map_coarse)?;
    let out = args.out.clone().unwrap_or_else(default_out);
    let result_path = out.join("result.json");
    let panel_path = out.join("panel.png");
    std::fs::create_dir_all(&out)
        .map_err(|e| Error::file(&out, format!("cannot create directory: {e}")))?;
    for p in [&result_path, &panel_path] {
        crate::io::check_output(p, args.force)?;
    }

    let t_all = Instant::now();
    println!(
        "vtsm demo: terrain {}, map at {:.1} h, images at {:.1} h (Δ{} h), profile {}, seed {}",
        kind.name(),
        MAP_HOURS,
        MAP_HOURS + args.hours,
        args.hours,
        profile.name(),
        args.seed
    );
    let (change, camera) = (args.conditions.change, args.conditions.camera);
    if !change.is_none() || !camera.is_none() {
        println!(
            "  depot changed since mapping: {}; camera: {}",
            change.label(),
            camera.label()
        );
    }
    let t0 = Instant::now();
    let scene = Scene::new(kind, args.seed, profile).with_map_coarse(args.map_coarse);
    let map_light = scene.lighting(MAP_HOURS);
    let map_mesh = scene.map(&map_light);
    let capture = Capture::from_index(args.stop, 0, 0.40);
    let live = scene.live(0.0, &change, args.seed);
    let live_light = live.lighting(MAP_HOURS + args.hours);
    let map_mesh = if args.relight == super::OnOff::On {
        let (relit, stats) = crate::relight::relit_mesh(
            &map_mesh,
            (&map_light.sun).into(),
            (&live_light.sun).into(),
            &crate::relight::RelightOptions::default(),
        )?;
        println!(
            "  map relit from the {:.1}° sun to the {:.1}° sun: {} texels, {:.1} % in cast shadow then, {:.1} % now",
            map_light.sun.elevation_deg,
            live_light.sun.elevation_deg,
            stats.texels_relit,
            100.0 * stats.shadowed[0],
            100.0 * stats.shadowed[1]
        );
        relit
    } else {
        map_mesh
    };
    let map_bytes = crate::mapscore::encode(&map_mesh, 0.5, args.map_scores.on())?;
    let (rig, truth, pair) = live.capture(&live_light, &capture);
    let pair = camera.apply(&pair, args.seed ^ CAMERA_SEED)?;
    let prior = perturbed_prior(&truth, args.seed);
    println!(
        "  depot and map: {} triangles ({} in the sampling mask), texture {}×{}; stereo pair {}×{}, baseline {:.2} m  [{:.1} s]",
        map_mesh.triangles.len(),
        map_mesh.mask_count(),
        map_mesh.texture.width,
        map_mesh.texture.height,
        pair.width,
        pair.height,
        rig.baseline_m(),
        t0.elapsed().as_secs_f64()
    );

    // The map product is checked once; the runner and the panel use the view.
    let map = MapView::new_checked(&map_bytes)?;
    let req = Request::new(map, &pair.left, &pair.right, rig, prior)
        .with_seed(args.seed)
        .with_verify(args.verify.checks())
        .with_accuracy(args.accuracy.accuracy)
        .with_final_pairs(args.final_pairs.final_pairs)
        .with_search(args.search.search())
        .with_threads(args.threads.threads());
    let report = locate::relocalize(&req, RunOptions::default())?;
    let o = &report.outcome;
    let (t0_m, r0) = prior.error_to(&truth);
    let (t1_m, r1) = o.pose.error_to(&truth);
    let status = match o.failure {
        None => "SUCCESS".to_string(),
        Some(c) => format!(
            "FAILED {} (0x{:04x}): {}",
            c.name(),
            c.code(),
            c.description()
        ),
    };
    println!(
        "  initial error: {:7.1} mm  {:6.3}°",
        t0_m * 1e3,
        r0.to_degrees()
    );
    println!(
        "  final error:   {:7.1} mm  {:6.3}°",
        t1_m * 1e3,
        r1.to_degrees()
    );
    println!(
        "  inliers {} (ratio {:.2}, RMS {:.1} mm), iterations {}, attempts {}, stalls {}, reseeds {}, templates ℓ = {} px",
        o.quality.inliers,
        o.quality.inlier_ratio,
        o.quality.rms_m * 1e3,
        o.stats.successes,
        o.stats.attempts,
        o.stats.stalls,
        o.stats.reseeds,
        report.template_px
    );
    if let Some(c) = &o.quality.covariance {
        let (st, sr) = (c.sigma_t_m(), c.sigma_r_rad());
        println!(
            "  1-σ (world x, y, z): {:.1} {:.1} {:.1} mm, {:.3} {:.3} {:.3}°; reprojection RMS {:.2} px, refined {}",
            st[0] * 1e3,
            st[1] * 1e3,
            st[2] * 1e3,
            sr[0].to_degrees(),
            sr[1].to_degrees(),
            sr[2].to_degrees(),
            o.quality.reproj_rms_px,
            if o.stats.refine.accepted { "yes" } else { "no" }
        );
    }
    let result = outcome_result(&Outcome {
        prior_uncertainty: Some(report.run.prior_uncertainty),
        ..outcome_from_core(o, req.verify)
    });
    if req.verify.any() {
        let v = result.verified;
        let ran = |asked: bool, ran: bool| match (asked, ran) {
            (false, _) => "off",
            (true, false) => "not reached",
            (true, true) => "ran",
        };
        let diff = o.quality.verify_diff.map_or(String::new(), |(dt, dr)| {
            format!(
                " (the two solves {:.1} mm, {:.3}° apart)",
                dt * 1e3,
                dr.to_degrees()
            )
        });
        println!(
            "  upset checks: repeated solve {}{diff}, map re-check {}",
            ran(req.verify.repeat_solve, v.repeat_solve),
            ran(req.verify.recheck_map, v.recheck_map)
        );
    }
    println!(
        "  relocalization time {:.2} s ({}), workspace {:.1} MB",
        report.elapsed.as_secs_f64(),
        match report.attempts_worked {
            None => "1 thread".to_string(),
            Some(w) => format!(
                "{} threads, {} attempts dropped as stale",
                req.threads,
                w.saturating_sub(o.stats.attempts)
            ),
        },
        report.workspace_bytes as f64 / 1e6
    );
    println!("  status: {status}");

    let canvas = crate::panel::result_panel(
        &map,
        &rig.cam(),
        &pair.left,
        &prior,
        &o.pose,
        &truth,
        report.template_px,
        args.seed,
    );
    std::fs::create_dir_all(&out)
        .map_err(|e| Error::file(&out, format!("cannot create directory: {e}")))?;
    canvas.save_png(&panel_path, args.force)?;
    json::write_result(&result_path, &result, args.force)?;
    println!(
        "  wrote {} and {}  [total {:.1} s]",
        show(&result_path),
        show(&panel_path),
        t_all.elapsed().as_secs_f64()
    );
    Ok(if o.failure.is_none() {
        0
    } else {
        EXIT_RELOC_FAILED
    })
}

fn show(p: &Path) -> String {
    p.display().to_string()
}
