//! `vtsm scene export`: render one capture of a simulated depot and write the files
//! `vtsm relocalize` reads (design §5), plus `scene.json` describing the scene.

use crate::cli::eval::protocol::CAMERA_SEED;
use crate::error::{Error, Result};
use crate::io::calib::opencv::opencv_calib_text;
use crate::scene::export::{existing, write_scene, write_scene_with_calib, SceneFiles};
use crate::scene::physical::capture_physical;
use crate::scene::{parse_hours, perturbed_prior, Capture, Profile, Scene, STOPS_PER_CIRCLE};
use crate::terrain::TerrainKind;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `vtsm scene export`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Terrain: flagstone, cfa6 or cfa2.
    #[arg(long)]
    pub terrain: String,
    /// Capture time of the stereo pair: am, noon, pm or local solar hours (e.g. 15.5).
    #[arg(long)]
    pub hours: String,
    /// Time of the mapping images baked into the map texture (default am = 9.5 h).
    #[arg(long, default_value = "am")]
    pub map_hours: String,
    /// Output directory (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Seed of the depot, map noise, sensor noise and prior.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Profile: paper, demo or test.
    #[arg(long, default_value = "demo")]
    pub profile: String,
    /// Stop of the capture grid, 0..30 (0..15 around tube 0, 15..30 around tube 1).
    #[arg(long, default_value_t = 0)]
    pub stop: u32,
    /// Tube the cameras look at: 0 or 1.
    #[arg(long, default_value_t = 0)]
    pub look_at: u32,
    /// Stereo baseline in metres: 0.40 or 0.20.
    #[arg(long, default_value_t = 0.40)]
    pub baseline: f32,
    /// Wind between mapping and capture, 0..1 (sand moved, dust deposited); 0 = none.
    #[arg(long, default_value_t = 0.0)]
    pub wind: f32,
    /// Map from imagery K times coarser: 1, 2, 4 or 8 (vertex spacing and
    /// texel size × K); the pair is unchanged.
    #[arg(long, value_name = "K", default_value_t = 1)]
    pub map_coarse: u32,
    /// `--change SPEC` and `--camera SPEC`: the depot changed since mapping
    /// (after the wind) and a camera that is not ideal.
    #[command(flatten)]
    pub conditions: super::ConditionsArg,
    /// Overwrite files already in DIR.
    #[arg(long)]
    pub force: bool,
    /// Write a physical pair instead of an ideal rectified one: distorted images
    /// of two slightly rotated cameras with different intrinsics, `calib.json`
    /// in the OpenCV form, and poses of the physical left camera.
    #[arg(long)]
    pub physical: bool,
}

/// Run the command; returns the exit code.
pub fn run(args: &Args) -> Result<u8> {
    let kind = TerrainKind::parse(&args.terrain).ok_or_else(|| {
        Error::msg(format!(
            "unknown terrain `{}` (flagstone, cfa6, cfa2)",
            args.terrain
        ))
    })?;
    let hours = parse_hours(&args.hours).ok_or_else(|| {
        Error::msg(format!(
            "bad --hours `{}` (am, noon, pm or 0..24)",
            args.hours
        ))
    })?;
    let map_hours = parse_hours(&args.map_hours).ok_or_else(|| {
        Error::msg(format!(
            "bad --map-hours `{}` (am, noon, pm or 0..24)",
            args.map_hours
        ))
    })?;
    let profile = Profile::parse(&args.profile).ok_or_else(|| {
        Error::msg(format!(
            "unknown profile `{}` (paper, demo, test)",
            args.profile
        ))
    })?;
    if args.stop >= 2 * STOPS_PER_CIRCLE || args.look_at > 1 {
        return Err(Error::msg("--stop must be 0..30 and --look-at 0 or 1"));
    }
    if !(args.wind.is_finite() && (0.0..=1.0).contains(&args.wind)) {
        return Err(Error::msg("--wind must be in [0, 1]"));
    }
    Scene::check_map_coarse(args.map_coarse)?;
    if !(args.baseline.is_finite() && args.baseline > 0.0 && args.baseline < 2.0) {
        return Err(Error::msg("--baseline must be in (0, 2) metres"));
    }
    if !args.force {
        if let Some(p) = existing(&args.out).first() {
            return Err(Error::file(p, "already exists (use --force to overwrite)"));
        }
    }
    let t0 = Instant::now();
    let map_scene = Scene::new(kind, args.seed, profile).with_map_coarse(args.map_coarse);
    let (change, camera) = (args.conditions.change, args.conditions.camera);
    let scene = map_scene.live(args.wind, &change, args.seed);
    let terrain_s = t0.elapsed().as_secs_f64();
    let cap = Capture::from_index(args.stop, args.look_at, args.baseline);
    let t1 = Instant::now();
    let light = scene.lighting(hours);
    let shadow_s = t1.elapsed().as_secs_f64();
    let t2 = Instant::now();
    let cpu2 = process_cpu_s();
    let (rig, truth, pair, calib_text) = if args.physical {
        let (calib, truth, pair) = capture_physical(&scene, &light, &cap);
        (
            scene.rig(cap.baseline_m),
            truth,
            pair,
            Some(opencv_calib_text(&calib)),
        )
    } else {
        let (rig, truth, pair) = scene.capture(&light, &cap);
        (rig, truth, pair, None)
    };
    let pair = camera.apply(&pair, args.seed ^ CAMERA_SEED)?;
    let pair_s = t2.elapsed().as_secs_f64();
    let pair_cpu_s = process_cpu_s().zip(cpu2).map(|(b, a)| b - a);
    let t3 = Instant::now();
    let map_light = if (map_hours - hours).abs() < 1e-6 && args.wind <= 0.0 && change.is_none() {
        light.clone()
    } else {
        map_scene.lighting(map_hours)
    };
    let map = map_scene.map(&map_light);
    let map_s = t3.elapsed().as_secs_f64();
    let prior = perturbed_prior(&truth, args.seed);
    let meta = serde_json::json!({
        "terrain": kind.name(), "seed": args.seed, "profile": profile.name(),
        "hours": hours, "map_hours": map_hours, "stop": args.stop, "look_at": args.look_at,
        "baseline_m": args.baseline, "wind": args.wind, "map_coarse": args.map_coarse,
        "change": change.label(), "camera": camera.label(), "sun_elevation_deg": light.sun.elevation_deg,
        "sun_azimuth_deg": light.sun.azimuth_deg, "triangles": map.triangles.len(),
        "map_sun_elevation_deg": map_light.sun.elevation_deg,
        "map_sun_azimuth_deg": map_light.sun.azimuth_deg,
        "masked_triangles": map.mask.iter().filter(|&&m| m).count(),
        "physical": args.physical,
    });
    let files = SceneFiles {
        map: &map,
        rig: &rig,
        left: &pair.left,
        right: &pair.right,
        prior: &prior,
        truth: &truth,
        meta,
        sun: Some((&light.sun).into()),
    };
    let t4 = Instant::now();
    match &calib_text {
        Some(text) => write_scene_with_calib(&args.out, &files, text, args.force)?,
        None => write_scene(&args.out, &files, args.force)?,
    }
    let write_s = t4.elapsed().as_secs_f64();
    println!(
        "timing (wall, {} threads): terrain {terrain_s:.2} s, shadow map {shadow_s:.2} s, \
         stereo pair {pair_s:.2} s, map {map_s:.2} s, write {write_s:.2} s",
        rayon::current_num_threads()
    );
    if let Some(c) = pair_cpu_s {
        println!("stereo pair CPU time (all threads): {c:.2} s");
    }
    println!(
        "wrote {} ({} {}x{}, {} triangles, sun el {:.1}° az {:.1}°)",
        args.out.display(),
        profile.name(),
        rig.cam().width(),
        rig.cam().height(),
        map.triangles.len(),
        light.sun.elevation_deg,
        light.sun.azimuth_deg
    );
    Ok(0)
}

/// CPU time (user + system) of this process so far, seconds, from `/proc/self/stat`
/// (Linux; `None` elsewhere). Wall time on a shared machine overstates the cost.
fn process_cpu_s() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised command name; utime and stime are fields 14 and 15.
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}
