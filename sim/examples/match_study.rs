//! Template-matching study on simulated depot images (fsw-docs/eval/matching.md).
//!
//! For each terrain (flagstone, cfa6, cfa2) the depot is mapped at 9.5 h and a
//! stereo pair is captured at 9.5 h + Δ (Δ = 0, 3, 6 h). Mask vertices visible in
//! the real left image are sampled; for each, the ℓ×ℓ template and its §III-C mask
//! are rendered from a viewpoint perturbed from the true pose (as the engine's
//! Synthesize step does), and the real image is searched in the engine's window
//! (projected uncertainty + margin, capped at ~3.2 ℓ) with every variant
//! (gray / Sobel / Laplacian at ℓ and ℓ/2), once exhaustively and once
//! coarse-to-fine. A match is correct when the vertex it places lies within
//! `--tol` pixels of the vertex's true projection.
//!
//! Prints Markdown tables: coarse-to-fine vs exhaustive agreement, correct-match
//! rate per variant and Δ, false-accept rate per (min score, runner-up ratio),
//! and the yield of candidate match policies (first accepted variant wins).
//!
//! ```text
//! cargo run --release -p vtsm-sim --example match_study -- [--profile demo] [--terrains flagstone,cfa6,cfa2]
//!     [--stops 3,11] [--samples 40] [--seed 1] [--tol 2] [--csv out.csv]
//!     [--variants 0,1,3,4] [--compare NAME,NAME,...]
//! ```
//! `--variants` limits the searches to some variants (0–2 gray/Sobel/Laplacian at ℓ,
//! 3–5 at ℓ/2; the others count as failed searches). `--compare` also runs
//! alternative coarse-to-fine configurations (see [`named_config`]) on the same
//! templates and prints their agreement with the exhaustive search.

#![allow(clippy::expect_used, clippy::panic)] // a study harness: a failed setup step or a bad argument should stop it loudly

use nalgebra::UnitQuaternion;
use rayon::prelude::*;
use std::fmt::Write as _;
use std::time::Instant;
use vtsm_core::geom::{Camera, Pose, Vec3};
use vtsm_core::image::{GrayView, Rect};
use vtsm_core::map::MapView;
use vtsm_core::ncc::{self, Filter, Run, Scratch, ScratchSizes, Search, SearchConfig};
use vtsm_core::raster;
use vtsm_core::rng::Rng;
use vtsm_sim::locate::{self, Template};
use vtsm_sim::scene::{Capture, Profile, Scene};
use vtsm_sim::terrain::TerrainKind;

const MAP_HOURS: f32 = 9.5;
const DELTAS: [f32; 3] = [0.0, 3.0, 6.0];
const FILTERS: [Filter; 3] = [Filter::Gray, Filter::Sobel, Filter::Laplacian];
/// Viewpoint perturbation levels: (name, max translation m, max rotation deg).
/// "prior" is the paper's prior (10–20 cm, 1.5°) i.e. the first iteration;
/// "near" is a converging iteration (≤ 2 cm, ≤ 0.2°).
const LEVELS: [(&str, f32, f32, f32); 2] = [("prior", 0.10, 0.20, 1.5), ("near", 0.0, 0.02, 0.2)];

/// One search result (left image only).
#[derive(Clone, Copy, Debug)]
struct Found {
    x: i32,
    y: i32,
    score: f32,
    runner_up: f32,
    /// Pixel distance of the placed vertex from its true projection.
    err_px: f32,
    /// Multiply-accumulates of the search (all levels).
    macs: u64,
}

/// Per variant: (index, exhaustive result, coarse-to-fine result, results of the
/// compared configurations).
type SampleResult = Vec<(usize, Option<Found>, Option<Found>, Vec<Option<Found>>)>;

/// A coarse-to-fine configuration by name: `default` (the core's choice per
/// filter) or `+`-joined changes to the previous defaults (8 candidates, 4
/// verified at full resolution, ±2 / ±1 px, NMS 2, coarsest side ≥ 16, `o` alone):
/// `cN` N candidates all verified, `fN` N verified at full resolution (after
/// `cN`), `rN` every radius N, `aN` radius at least N at the level below the
/// coarsest, `mN` coarsest side ≥ N, `nN` NMS radius N.
fn named_config(name: &str, filter: Filter) -> SearchConfig {
    if name == "default" {
        return SearchConfig::for_filter(filter);
    }
    let base = SearchConfig::for_filter(filter)
        .with_candidates(8, 4)
        .and_then(|c| c.with_refine_radii_px(2, 1, 0))
        .and_then(|c| c.with_coarse_px(16, 16))
        .map(|c| c.with_nms_and_verify_px(2, 0))
        .expect("previous defaults are in range");
    let mut c = base;
    for part in name.split('+') {
        let num = |p: &str| p[1..].parse::<usize>().expect("config number");
        let changed = match part.chars().next() {
            Some('c') => c.with_candidates(num(part), num(part)),
            Some('r') => c.with_refine_radii_px(num(part), num(part), c.first_refine_radius_px()),
            Some('a') => {
                c.with_refine_radii_px(c.refine_radius_px(), c.final_refine_radius_px(), num(part))
            }
            Some('f') => c.with_candidates(c.candidates(), num(part)),
            Some('m') => c.with_coarse_px(num(part), num(part)),
            Some('n') => Ok(c.with_nms_and_verify_px(num(part), c.verify_all_below_px())),
            Some('o') => Ok(c),
            _ => panic!("unknown config part {part}"),
        };
        c = changed.unwrap_or_else(|code| panic!("config part {part} out of range: {code:?}"));
    }
    c
}

#[derive(Clone, Debug)]
struct Record {
    terrain: &'static str,
    dh: f32,
    level: &'static str,
    /// Variant index: half * 3 + filter.
    variant: usize,
    exh: Option<Found>,
    c2f: Option<Found>,
    alt: Vec<Option<Found>>,
}

fn variant_name(v: usize) -> String {
    let f = ["gray", "sobel", "laplacian"][v % 3];
    format!("{f} {}", if v >= 3 { "ℓ/2" } else { "ℓ" })
}

struct Buffers {
    window: Vec<u8>,
    template: Vec<u8>,
    integral: Vec<u32>,
    runs: Vec<Run>,
}

impl Buffers {
    fn new(mode: Search) -> Self {
        // Field-wise maximum over the coarsest-side settings the study uses.
        let (a, b) = (
            ScratchSizes::max(mode),
            ScratchSizes::max(Search::Exhaustive),
        );
        let s = ScratchSizes {
            window: a.window.max(b.window),
            template: a.template.max(b.template),
            integral: a.integral.max(b.integral),
            runs: a.runs.max(b.runs),
        };
        Self {
            window: vec![0; s.window],
            template: vec![0; s.template],
            integral: vec![0; s.integral],
            runs: vec![Run::default(); s.runs],
        }
    }
    fn scratch(&mut self) -> Scratch<'_> {
        Scratch {
            window: &mut self.window,
            template: &mut self.template,
            integral: &mut self.integral,
            runs: &mut self.runs,
        }
    }
}

fn perturb(truth: &Pose, rng: &mut Rng, t_lo: f32, t_hi: f32, r_deg: f32) -> Pose {
    let dt = rng.unit_vector3() * rng.uniform(t_lo, t_hi);
    let axis = rng.unit_vector3();
    let angle = rng.uniform(-r_deg, r_deg).to_radians();
    let dq = UnitQuaternion::from_scaled_axis(axis * angle);
    Pose::new(dq * truth.rotation(), truth.translation() + dt)
}

/// The engine's search rectangle (reloc::pipeline::search_rect).
fn search_rect(px: [f32; 2], l: usize, r: i32, cap: usize, w: usize, h: usize) -> Rect {
    let half_max = (cap.saturating_sub(l) / 2) as i32;
    let r = r.clamp(0, half_max);
    let side = l as i32 + 2 * r;
    let x0 = (px[0] + 0.5).floor() as i32 - side / 2;
    let y0 = (px[1] + 0.5).floor() as i32 - side / 2;
    let (w, h) = (w as i32, h as i32);
    let (cx0, cy0) = (x0.clamp(0, w), y0.clamp(0, h));
    let (cx1, cy1) = ((x0 + side).clamp(0, w), (y0 + side).clamp(0, h));
    Rect::new(
        cx0,
        cy0,
        (cx1 - cx0).max(0) as u32,
        (cy1 - cy0).max(0) as u32,
    )
}

/// One sampled vertex: search every variant both ways. `None` if the sample is
/// out of view or occluded at the viewpoint.
#[allow(clippy::too_many_arguments)]
fn one_sample(
    map: &MapView,
    cam: &Camera,
    img: GrayView,
    truth: &Pose,
    vp: &Pose,
    world: &Vec3,
    t_max: f32,
    r_deg: f32,
    tol: f32,
    variants: &[usize],
    compare: &[String],
    bufs: &mut (Buffers, Buffers),
) -> Option<SampleResult> {
    let l = vtsm_core::config::template_px_for_width(cam.width()) as usize;
    let cap = vtsm_core::config::search_px_for_template(l as u16) as usize;
    let margin = (l / 2) as f32;
    let p_vp = vp.inverse().transform_point(world);
    let uv_vp = cam.project(&p_vp)?;
    let uv_true = cam.project(&truth.inverse().transform_point(world))?;
    if !cam.contains(uv_vp[0], uv_vp[1], margin) || !cam.contains(uv_true[0], uv_true[1], margin) {
        return None;
    }
    let Template {
        rect,
        intensity: inten,
        depth,
        mask,
    } = locate::render_template(map, cam, vp, uv_vp, l)?;
    // The engine's occlusion test at the viewpoint.
    let drawn = raster::depth_to_m(depth[(l / 2) * l + l / 2]);
    if drawn.is_none_or(|z| z < p_vp.z - (0.03 + 0.02 * p_vp.z)) {
        return None;
    }
    let f = cam.fx().max(cam.fy());
    let r_px = (f * (2.0 * t_max / p_vp.z.max(0.1) + 2.0 * r_deg.to_radians())).ceil() as i32 + 4;
    let search = search_rect(
        uv_vp,
        l,
        r_px,
        cap,
        cam.width() as usize,
        cam.height() as usize,
    );
    let tv = GrayView::new(&inten, l, l, l).ok()?;
    let mv = GrayView::new(&mask, l, l, l).ok()?;
    let mut out = Vec::new();
    for v in 0..6 {
        if !variants.contains(&v) {
            out.push((v, None, None, vec![None; compare.len()]));
            continue;
        }
        let half = v >= 3;
        let filter = FILTERS[v % 3];
        let (t, m, ox, oy) = if half {
            let r = ncc::sub_template_rect(l, l);
            (
                ncc::sub_template(&tv)?,
                ncc::sub_template(&mv)?,
                r.x as f32,
                r.y as f32,
            )
        } else {
            (tv, mv, 0.0, 0.0)
        };
        let run_with = |mode: Search, cfg: &SearchConfig, b: &mut Buffers| {
            let (m, stats) = ncc::match_template_with(
                t,
                Some(m),
                img,
                search,
                filter,
                mode,
                cfg,
                &mut b.scratch(),
            )
            .ok()?;
            let px = m.sub_x + (uv_vp[0] - rect.x as f32 - ox);
            let py = m.sub_y + (uv_vp[1] - rect.y as f32 - oy);
            Some(Found {
                x: m.x,
                y: m.y,
                score: m.score,
                runner_up: m.runner_up,
                err_px: (px - uv_true[0]).hypot(py - uv_true[1]),
                macs: stats.macs,
            })
        };
        let default = SearchConfig::for_filter(filter);
        let e = run_with(Search::Exhaustive, &default, &mut bufs.0);
        let c = run_with(Search::CoarseToFine, &default, &mut bufs.1);
        let alt = compare
            .iter()
            .map(|n| run_with(Search::CoarseToFine, &named_config(n, filter), &mut bufs.1))
            .collect();
        out.push((v, e, c, alt));
    }
    let _ = tol;
    Some(out)
}

fn pct(a: usize, n: usize) -> String {
    if n == 0 {
        "–".into()
    } else {
        format!("{:.1}", 100.0 * a as f64 / n as f64)
    }
}

fn accepted(f: &Found, min_score: f32, ratio: f32) -> bool {
    f.score >= min_score && f.runner_up <= ratio * f.score
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let get = |k: &str| {
        args.iter()
            .position(|a| a == k)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let profile = Profile::parse(&get("--profile").unwrap_or_else(|| "demo".into()))
        .expect("--profile demo|test|paper");
    let samples: usize = get("--samples").map_or(40, |s| s.parse().expect("--samples N"));
    let seed: u64 = get("--seed").map_or(1, |s| s.parse().expect("--seed N"));
    let tol: f32 = get("--tol").map_or(2.0, |s| s.parse().expect("--tol px"));
    let stops: Vec<u32> = get("--stops").map_or(vec![3, 11], |s| {
        s.split(',')
            .map(|x| x.parse().expect("--stops a,b"))
            .collect()
    });
    let csv = get("--csv");
    let variants: Vec<usize> = get("--variants").map_or((0..6).collect(), |s| {
        s.split(',')
            .map(|x| x.parse().expect("--variants 0,1,3,4"))
            .collect()
    });
    let compare: Vec<String> =
        get("--compare").map_or(Vec::new(), |s| s.split(',').map(str::to_string).collect());
    for n in &compare {
        let _ = named_config(n, Filter::Gray);
    }
    let t_all = Instant::now();
    let mut records: Vec<Record> = Vec::new();
    let names = get("--terrains").unwrap_or_else(|| "flagstone,cfa6,cfa2".into());
    let terrains: Vec<TerrainKind> = names
        .split(',')
        .map(|n| TerrainKind::parse(n).expect("--terrains flagstone,cfa6,cfa2"))
        .collect();
    for kind in terrains {
        let t0 = Instant::now();
        let scene = Scene::new(kind, seed, profile);
        let map_mesh = scene.map(&scene.lighting(MAP_HOURS));
        let map_bytes = map_mesh.encode_map(0.5).expect("encode map");
        let map = MapView::new_checked(&map_bytes).expect("map view");
        eprintln!(
            "{}: depot and map [{:.1} s]",
            kind.name(),
            t0.elapsed().as_secs_f64()
        );
        for &stop in &stops {
            for &dh in &DELTAS {
                let capture = Capture::from_index(stop, 0, 0.40);
                let (rig, truth, pair) = scene.capture(&scene.lighting(MAP_HOURS + dh), &capture);
                let cam = rig.cam();
                let (w, h) = (cam.width() as usize, cam.height() as usize);
                let img = GrayView::new(&pair.left, w, h, w).expect("left view");
                for &(level, t_lo, t_hi, r_deg) in &LEVELS {
                    // Same vertices and viewpoints for every Δ (the seed ignores Δ).
                    let jobs: Vec<(Pose, Vec3)> = (0..samples * 4)
                        .filter_map(|k| {
                            let mut rng = Rng::new(seed)
                                .fork(u64::from(stop) << 32 | k as u64)
                                .fork(level.len() as u64);
                            let n = map.mask_vertex_count();
                            let world =
                                map.mask_vertex(rng.below(n)).and_then(|i| map.vertex(i))?;
                            let vp = perturb(&truth, &mut rng, t_lo, t_hi, r_deg);
                            // Cheap in-view pre-check; occlusion is tested after rendering.
                            let m =
                                (vtsm_core::config::template_px_for_width(cam.width()) / 2) as f32;
                            let ok = |pose: &Pose| {
                                cam.project(&pose.inverse().transform_point(&world))
                                    .is_some_and(|[u, v]| cam.contains(u, v, m))
                            };
                            (ok(&truth) && ok(&vp)).then_some((vp, world))
                        })
                        .take(samples)
                        .collect();
                    let got: Vec<_> = jobs
                        .par_iter()
                        .map_init(
                            || {
                                (
                                    Buffers::new(Search::Exhaustive),
                                    Buffers::new(Search::CoarseToFine),
                                )
                            },
                            |bufs, (vp, world)| {
                                one_sample(
                                    &map, &cam, img, &truth, vp, world, t_hi, r_deg, tol,
                                    &variants, &compare, bufs,
                                )
                            },
                        )
                        .flatten()
                        .collect();
                    let n = got.len();
                    for s in got {
                        for (variant, exh, c2f, alt) in s {
                            records.push(Record {
                                terrain: kind.name(),
                                dh,
                                level,
                                variant,
                                exh,
                                c2f,
                                alt,
                            });
                        }
                    }
                    eprintln!(
                        "  stop {stop} Δ{dh} h {level}: {n} samples [{:.1} s]",
                        t_all.elapsed().as_secs_f64()
                    );
                }
            }
        }
    }
    if let Some(path) = csv {
        let mut s = String::from("terrain,dh,level,variant,exh_x,exh_y,exh_score,exh_runner_up,exh_err_px,c2f_x,c2f_y,c2f_score,c2f_runner_up,c2f_err_px\n");
        for r in &records {
            let f = |o: &Option<Found>| {
                o.map_or(",,,,".to_string(), |f| {
                    format!("{},{},{},{},{}", f.x, f.y, f.score, f.runner_up, f.err_px)
                })
            };
            let _ = writeln!(
                s,
                "{},{},{},{},{},{}",
                r.terrain,
                r.dh,
                r.level,
                variant_name(r.variant),
                f(&r.exh),
                f(&r.c2f)
            );
        }
        std::fs::write(&path, s).expect("write csv");
    }
    report(&records, tol, profile, samples, seed, &stops);
    agreement(&records, &variants, &compare);
    eprintln!("total {:.1} s", t_all.elapsed().as_secs_f64());
}

fn report(
    records: &[Record],
    tol: f32,
    profile: Profile,
    samples: usize,
    seed: u64,
    stops: &[u32],
) {
    println!(
        "## Match study: profile {}, ℓ = {} px, stops {:?}, up to {samples} samples per (terrain, stop, Δ, level), seed {seed}, correct = within {tol} px\n",
        profile.name(),
        vtsm_core::config::template_px_for_width(profile.image_size().0),
        stops
    );
    // 1. Agreement.
    println!("### Coarse-to-fine vs exhaustive (same integer argmax)\n");
    println!("| variant | level | searches | same argmax % | within 1 px % | c2f correct % | exh correct % |");
    println!("|---|---|---|---|---|---|---|");
    for v in 0..6 {
        for &(level, ..) in &LEVELS {
            let both: Vec<(Found, Found)> = records
                .iter()
                .filter(|r| r.variant == v && r.level == level)
                .filter_map(|r| Some((r.exh?, r.c2f?)))
                .collect();
            let n = both.len();
            let same = both
                .iter()
                .filter(|(e, c)| e.x == c.x && e.y == c.y)
                .count();
            let near = both
                .iter()
                .filter(|(e, c)| (e.x - c.x).abs() <= 1 && (e.y - c.y).abs() <= 1)
                .count();
            let cc = both.iter().filter(|(_, c)| c.err_px <= tol).count();
            let ec = both.iter().filter(|(e, _)| e.err_px <= tol).count();
            println!(
                "| {} | {level} | {n} | {} | {} | {} | {} |",
                variant_name(v),
                pct(same, n),
                pct(near, n),
                pct(cc, n),
                pct(ec, n)
            );
        }
    }
    // 2. Correct-match rate per variant and Δ (coarse-to-fine, no acceptance test).
    println!("\n### Correct-match rate (coarse-to-fine, before acceptance), % of searches\n");
    println!("| variant | level | Δ0 h | Δ3 h | Δ6 h | median score correct / wrong (all Δ) |");
    println!("|---|---|---|---|---|---|");
    for v in 0..6 {
        for &(level, ..) in &LEVELS {
            let mut cells = Vec::new();
            for &dh in &DELTAS {
                let fs: Vec<Found> = records
                    .iter()
                    .filter(|r| r.variant == v && r.level == level && r.dh == dh)
                    .filter_map(|r| r.c2f)
                    .collect();
                let ok = fs.iter().filter(|f| f.err_px <= tol).count();
                cells.push(format!("{} (n {})", pct(ok, fs.len()), fs.len()));
            }
            let med = |want: bool| {
                let mut s: Vec<f32> = records
                    .iter()
                    .filter(|r| r.variant == v && r.level == level)
                    .filter_map(|r| r.c2f)
                    .filter(|f| (f.err_px <= tol) == want)
                    .map(|f| f.score)
                    .collect();
                s.sort_by(f32::total_cmp);
                s.get(s.len() / 2).map_or("–".into(), |m| format!("{m:.2}"))
            };
            println!(
                "| {} | {level} | {} | {} | {} | {} / {} |",
                variant_name(v),
                cells[0],
                cells[1],
                cells[2],
                med(true),
                med(false)
            );
        }
    }
    // 3. Thresholds, per variant pooled over Δ and levels.
    let scores = [0.3f32, 0.4, 0.5, 0.6, 0.7, 0.8];
    let ratios = [0.8f32, 0.9, 0.95, 1.0];
    println!("\n### Acceptance thresholds (coarse-to-fine, all Δ and levels): accepted % / false-accept % of accepted\n");
    print!("| variant | ratio |");
    for s in scores {
        print!(" score ≥ {s} |");
    }
    println!();
    println!("|---|---|{}", "---|".repeat(scores.len()));
    for v in 0..6 {
        for ratio in ratios {
            print!("| {} | {ratio} |", variant_name(v));
            let fs: Vec<Found> = records
                .iter()
                .filter(|r| r.variant == v)
                .filter_map(|r| r.c2f)
                .collect();
            for s in scores {
                let acc: Vec<&Found> = fs.iter().filter(|f| accepted(f, s, ratio)).collect();
                let bad = acc.iter().filter(|f| f.err_px > tol).count();
                print!(" {} / {} |", pct(acc.len(), fs.len()), pct(bad, acc.len()));
            }
            println!();
        }
    }
    // 4. Policies: first accepted variant in order wins.
    let orders: [(&str, &[usize]); 7] = [
        ("G S L g s l", &[0, 1, 2, 3, 4, 5]),
        ("S G L s g l", &[1, 0, 2, 4, 3, 5]),
        ("S L G s l g", &[1, 2, 0, 4, 5, 3]),
        ("L S G l s g", &[2, 1, 0, 5, 4, 3]),
        ("G S L", &[0, 1, 2]),
        ("S G", &[1, 0]),
        ("S G s g", &[1, 0, 4, 3]),
    ];
    println!("\n### Policies (coarse-to-fine; first accepted variant in order wins): yield % / false % of accepted / searches per sample\n");
    println!("G/S/L = gray/Sobel/Laplacian at ℓ, g/s/l at ℓ/2.\n");
    println!("| order | min score | ratio | level | Δ0 h | Δ3 h | Δ6 h |");
    println!("|---|---|---|---|---|---|---|");
    for (name, order) in orders {
        for (s, ratio) in [
            (0.4f32, 0.9f32),
            (0.5, 0.9),
            (0.5, 0.95),
            (0.6, 0.9),
            (0.6, 0.95),
            (0.7, 0.95),
        ] {
            for &(level, ..) in &LEVELS {
                let mut cells = Vec::new();
                for &dh in &DELTAS {
                    // Group the records of one sample: consecutive runs of 6 variants.
                    let rs: Vec<&Record> = records
                        .iter()
                        .filter(|r| r.level == level && r.dh == dh)
                        .collect();
                    let (mut n, mut yielded, mut bad, mut searches) =
                        (0usize, 0usize, 0usize, 0usize);
                    for chunk in rs.chunks(6) {
                        n += 1;
                        for &v in order {
                            searches += 1;
                            let Some(f) = chunk.iter().find(|r| r.variant == v).and_then(|r| r.c2f)
                            else {
                                continue;
                            };
                            if accepted(&f, s, ratio) {
                                yielded += 1;
                                if f.err_px > tol {
                                    bad += 1;
                                }
                                break;
                            }
                        }
                    }
                    cells.push(format!(
                        "{} / {} / {:.1}",
                        pct(yielded, n),
                        pct(bad, yielded),
                        searches as f64 / n.max(1) as f64
                    ));
                }
                println!(
                    "| {name} | {s} | {ratio} | {level} | {} | {} | {} |",
                    cells[0], cells[1], cells[2]
                );
            }
        }
    }
}

/// Agreement of the default and each compared configuration with the exhaustive
/// search: same integer peak over all searches, over the searches whose exhaustive
/// peak the default policy would accept (score ≥ 0.5, runner-up ≤ 0.9·score), and
/// the misses that are near-ties (coarse-to-fine score within 1e-3 of the exhaustive one).
fn agreement(records: &[Record], variants: &[usize], compare: &[String]) {
    println!("\n### Coarse-to-fine configurations vs exhaustive (same integer peak)\n");
    println!("Cells: all searches % (n) / accepted exhaustive peaks % (n) / misses within 1e-3 of the exhaustive score / mean MACs per search (millions).\n");
    let names: Vec<String> = std::iter::once("default".to_string())
        .chain(compare.iter().cloned())
        .collect();
    print!("| variant | level |");
    for n in &names {
        print!(" {n} |");
    }
    println!();
    println!("|---|---|{}", "---|".repeat(names.len()));
    for &v in variants {
        for &(level, ..) in &LEVELS {
            print!("| {} | {level} |", variant_name(v));
            for k in 0..names.len() {
                let pairs: Vec<(Found, Found)> = records
                    .iter()
                    .filter(|r| r.variant == v && r.level == level)
                    .filter_map(|r| {
                        let c = if k == 0 { r.c2f } else { *r.alt.get(k - 1)? };
                        Some((r.exh?, c?))
                    })
                    .collect();
                let same = |(e, c): &(Found, Found)| e.x == c.x && e.y == c.y;
                let all = pairs.iter().filter(|p| same(p)).count();
                let acc: Vec<&(Found, Found)> = pairs
                    .iter()
                    .filter(|(e, _)| accepted(e, 0.5, 0.9))
                    .collect();
                let acc_same = acc.iter().filter(|p| same(p)).count();
                let ties = pairs
                    .iter()
                    .filter(|p| !same(p) && (p.0.score - p.1.score).abs() < 1e-3)
                    .count();
                let macs = pairs.iter().map(|p| p.1.macs as f64).sum::<f64>()
                    / pairs.len().max(1) as f64
                    / 1e6;
                print!(
                    " {} ({}) / {} ({}) / {} of {} / {macs:.1}M |",
                    pct(all, pairs.len()),
                    pairs.len(),
                    pct(acc_same, acc.len()),
                    acc.len(),
                    ties,
                    pairs.len() - all
                );
            }
            println!();
        }
    }
    // Every miss of the default on an accepted exhaustive peak, with the peak of
    // each compared configuration (`=` when it equals the exhaustive one).
    println!("\n### Default misses on accepted exhaustive peaks\n");
    println!("| terrain | Δ h | level | variant | exhaustive (x, y) score / runner-up | default (x, y) score | compared |");
    println!("|---|---|---|---|---|---|---|");
    for r in records {
        let (Some(e), Some(c)) = (r.exh, r.c2f) else {
            continue;
        };
        if !accepted(&e, 0.5, 0.9) || (e.x == c.x && e.y == c.y) {
            continue;
        }
        let alts: Vec<String> = r
            .alt
            .iter()
            .map(|a| match a {
                Some(a) if a.x == e.x && a.y == e.y => "=".to_string(),
                Some(a) => format!("({}, {}) {:.4}", a.x, a.y, a.score),
                None => "–".to_string(),
            })
            .collect();
        println!(
            "| {} | {} | {} | {} | ({}, {}) {:.4} / {:.4} | ({}, {}) {:.4} | {} |",
            r.terrain,
            r.dh,
            r.level,
            variant_name(r.variant),
            e.x,
            e.y,
            e.score,
            e.runner_up,
            c.x,
            c.y,
            c.score,
            alts.join(" · ")
        );
    }
}
