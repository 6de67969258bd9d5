//! `vtsm budget`: the memory and work budgets, computed from the code itself.
//!
//! Every number is derived at run time from `vtsm_core::config` and
//! `core::mem::size_of` of the core's types, never typed in. Each stage adds its
//! rows to [`rows`] (measured work counters belong in the section of the stage
//! that measures them).
//!
//! The `measured` section ([`measured_rows`]) comes from actually running one
//! relocalization of a simulated test-profile scene through the same
//! [`crate::locate::relocalize`] as every other command.

use crate::locate::{self, Request, RunOptions};
use crate::scene::{perturbed_prior, Capture, Profile, Scene};
use crate::terrain::TerrainKind;
use std::mem::size_of;
use vtsm_core::config as cfg;
use vtsm_core::reloc::workspace::{
    WorkspaceSizes, PAPER_WORKSPACE, PAPER_WORKSPACE_BYTES, TEST_WORKSPACE, TEST_WORKSPACE_BYTES,
};
use vtsm_core::reloc::{Outcome, Pipeline, RansacSolver, Relocalizer};
use vtsm_hal::StoreFrames;

/// RAM of the flight envelope the budgets are held against (10 MB).
pub const ENVELOPE_RAM_BYTES: u64 = 10_000_000;
/// Instructions of the flight envelope: 30 minutes of one 200 MHz core at one
/// instruction per cycle.
pub const ENVELOPE_INSTRUCTIONS: u64 = 200_000_000 * 30 * 60;

/// Arguments of `vtsm budget`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Print JSON lines (one object per row) instead of a Markdown table.
    #[arg(long)]
    pub json: bool,
    /// Skip the measured relocalization (static rows only; no scene is built).
    #[arg(long)]
    pub no_run: bool,
    /// Seed of the measured test-profile scene, prior and relocalization.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub seed: u64,
    /// Write the budget into DIR: `budget.md` (the table, for reading) and
    /// `budget.snapshot.json` (one JSON object per row, compared by the
    /// snapshot test). Existing files there are replaced.
    #[arg(long, value_name = "DIR")]
    pub write: Option<std::path::PathBuf>,
    /// Add the section sizes of the firmware images found under DIR (the
    /// firmware crate's `target/`: `DIR/<target>/release/vtsm-firmware` for
    /// each target of [`FIRMWARE_TARGETS`]), read from their ELF headers.
    /// These rows describe a build, not the code alone, so they are kept out
    /// of the snapshot.
    #[arg(long, value_name = "DIR")]
    pub firmware: Option<std::path::PathBuf>,
}

/// The firmware targets whose images `--firmware` looks for.
pub const FIRMWARE_TARGETS: [&str; 4] = [
    "thumbv7em-none-eabihf",
    "armv8r-none-eabihf",
    "riscv64gc-unknown-none-elf",
    "aarch64-unknown-none",
];

/// Section sizes of one bare-metal image, bytes, by what they hold.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ImageSections {
    /// Executable code (`.text`, vectors).
    pub text: u64,
    /// Read-only data (`.rodata`).
    pub rodata: u64,
    /// Initialised data (`.data`): in flash, copied to RAM at start-up.
    pub data: u64,
    /// Zeroed data (`.bss`, `.uninit`): RAM only. Reserved stack and heap
    /// regions are not counted.
    pub bss: u64,
}

impl ImageSections {
    /// Non-volatile memory the image occupies: code, read-only and initial data.
    pub fn flash(&self) -> u64 {
        self.text + self.rodata + self.data
    }
    /// Static RAM: initialised plus zeroed data (the stack comes on top).
    pub fn static_ram(&self) -> u64 {
        self.data + self.bss
    }
}

/// Sum the allocated sections of an ELF image by kind (executable,
/// read-only, writable with contents, writable without).
///
/// # Errors
/// The bytes are not an ELF file the `object` crate can read.
pub fn image_sections(elf: &[u8]) -> std::result::Result<ImageSections, String> {
    use object::{Object, ObjectSection, SectionFlags, SectionKind};
    let file = object::File::parse(elf).map_err(|e| e.to_string())?;
    let mut out = ImageSections::default();
    for sec in file.sections() {
        let SectionFlags::Elf { sh_flags } = sec.flags() else {
            continue;
        };
        const ALLOC: u64 = 0x2;
        // Reserved regions (riscv-rt's `.stack` and `.heap`) are not static
        // data: the stack is measured by the image itself (high-water mark).
        if sh_flags & ALLOC == 0 || matches!(sec.name(), Ok(".stack" | ".heap")) {
            continue;
        }
        let size = sec.size();
        match sec.kind() {
            SectionKind::Text => out.text += size,
            SectionKind::ReadOnlyData | SectionKind::ReadOnlyString => out.rodata += size,
            SectionKind::Data => out.data += size,
            SectionKind::UninitializedData => out.bss += size,
            // Anything else allocated (start-up tables, `.ARM.exidx`) is
            // counted as read-only data.
            _ => out.rodata += size,
        }
    }
    Ok(out)
}

/// The `firmware` rows for every image found under `dir`.
///
/// # Errors
/// No image found, or one that cannot be read as ELF.
pub fn firmware_rows(dir: &std::path::Path) -> crate::Result<Vec<Row>> {
    let mut rows = Vec::new();
    for t in FIRMWARE_TARGETS {
        let path = dir.join(t).join("release").join("vtsm-firmware");
        let Ok(bytes) = std::fs::read(&path) else {
            continue;
        };
        let s = image_sections(&bytes).map_err(|e| crate::Error::file(&path, e))?;
        let to = |v: u64| usize::try_from(v).unwrap_or(usize::MAX);
        rows.extend([
            row("firmware", format!("{t}: .text"), to(s.text), "bytes"),
            row("firmware", format!("{t}: .rodata"), to(s.rodata), "bytes"),
            row("firmware", format!("{t}: .data"), to(s.data), "bytes"),
            row("firmware", format!("{t}: .bss"), to(s.bss), "bytes"),
            row(
                "firmware",
                format!("{t}: flash (text + rodata + data)"),
                to(s.flash()),
                "bytes",
            ),
            row(
                "firmware",
                format!("{t}: static RAM (data + bss)"),
                to(s.static_ram()),
                "bytes",
            ),
        ]);
    }
    if rows.is_empty() {
        return Err(crate::Error::file(
            dir,
            "no firmware image (<target>/release/vtsm-firmware) here; build one with \
             `(cd tests/firmware && cargo build --release --target <t>)`",
        ));
    }
    Ok(rows)
}

/// One line of the budget.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// Section (`capacity`, `memory`, ...).
    pub section: &'static str,
    /// What is counted.
    pub item: String,
    /// The number.
    pub value: u64,
    /// Its unit (`count`, `px`, `bytes`).
    pub unit: &'static str,
}

fn row(section: &'static str, item: impl Into<String>, value: usize, unit: &'static str) -> Row {
    Row {
        section,
        item: item.into(),
        value: value as u64,
        unit,
    }
}

/// All rows, in print order.
pub fn rows() -> Vec<Row> {
    let cap = |name: &str, v: usize, unit| row("capacity", name, v, unit);
    let tpl = cfg::MAX_TEMPLATE_PX * cfg::MAX_TEMPLATE_PX;
    let render = cfg::MAX_RENDER_PX * cfg::MAX_RENDER_PX;
    vec![
        cap("MAX_IMAGE_DIM", cfg::MAX_IMAGE_DIM, "px"),
        cap("MAX_TEMPLATE_PX", cfg::MAX_TEMPLATE_PX, "px"),
        cap("MIN_TEMPLATE_PX", cfg::MIN_TEMPLATE_PX, "px"),
        cap("MAX_SEARCH_PX", cfg::MAX_SEARCH_PX, "px"),
        cap("MAX_RENDER_PX", cfg::MAX_RENDER_PX, "px"),
        cap("MAX_CORR", cfg::MAX_CORR, "count"),
        cap("MAX_ITER", cfg::MAX_ITER, "count"),
        cap("MAX_RANSAC_ITER", cfg::MAX_RANSAC_ITER, "count"),
        cap("MAX_REFINE_ITER", cfg::MAX_REFINE_ITER, "count"),
        cap("MAX_POSE_CANDIDATES", cfg::MAX_POSE_CANDIDATES, "count"),
        cap("MAX_SEEDS", cfg::MAX_SEEDS, "count"),
        cap("MAX_CONSECUTIVE_CAP", cfg::MAX_CONSECUTIVE_CAP, "count"),
        cap("MAX_ATTEMPTS_PER_ITER", cfg::MAX_ATTEMPTS_PER_ITER, "count"),
        cap("FAILURE_RING_LEN", cfg::FAILURE_RING_LEN, "count"),
        cap("MAX_MAP_VERTICES", cfg::MAX_MAP_VERTICES, "count"),
        cap("MAX_MAP_TRIANGLES", cfg::MAX_MAP_TRIANGLES, "count"),
        cap("MAX_MAP_TILES", cfg::MAX_MAP_TILES, "count"),
        cap("MAX_TEXTURE_DIM", cfg::MAX_TEXTURE_DIM, "px"),
        row(
            "memory",
            "core::config::Params",
            size_of::<cfg::Params>(),
            "bytes",
        ),
        row(
            "memory",
            "core::failure::FailureLog",
            size_of::<vtsm_core::failure::FailureLog>(),
            "bytes",
        ),
        row("memory", "template, MAX_TEMPLATE_PX² u8", tpl, "bytes"),
        row(
            "memory",
            "search window, MAX_SEARCH_PX² u8",
            cfg::MAX_SEARCH_PX * cfg::MAX_SEARCH_PX,
            "bytes",
        ),
        row(
            "memory",
            "raster target, MAX_RENDER_PX² × (u8 + 2 × u32)",
            render * (size_of::<u8>() + 2 * size_of::<u32>()),
            "bytes",
        ),
        row(
            "memory",
            workspace_item("paper", &PAPER_WORKSPACE),
            PAPER_WORKSPACE_BYTES,
            "bytes",
        ),
        row(
            "memory",
            workspace_item("test", &TEST_WORKSPACE),
            TEST_WORKSPACE_BYTES,
            "bytes",
        ),
        row(
            "memory",
            "core::reloc::Relocalizer<(), ()> (engine state)",
            size_of::<Relocalizer<(), ()>>(),
            "bytes",
        ),
        row(
            "memory",
            "core::reloc::Relocalizer<Pipeline, RansacSolver>",
            size_of::<Relocalizer<Pipeline<'static, 'static>, RansacSolver>>(),
            "bytes",
        ),
        row(
            "memory",
            "core::reloc::Outcome",
            size_of::<Outcome>(),
            "bytes",
        ),
    ]
}

/// Per-profile rows: the parameters' template and window, the workspace they
/// size, the stereo pair held in RAM, the engine state, the sum against the
/// RAM envelope, and the structural bound on work units.
pub fn profile_rows() -> Vec<Row> {
    let mut out = Vec::new();
    for profile in [Profile::Test, Profile::Demo, Profile::Paper] {
        let (w, h) = profile.image_size();
        let p = locate::params_for_width(w);
        let ws = locate::workspace_sizes(&p);
        let pair = 2 * (w as usize) * (h as usize);
        let engine = size_of::<Relocalizer<Pipeline<'static, 'static>, RansacSolver>>();
        let ram = ws.total_bytes() + pair + engine;
        // The pair left in the camera's frame memory: the engine reads its
        // windows through the frame store into the workspace (its two frame
        // windows are part of `ws`).
        let store_engine = size_of::<
            Relocalizer<
                Pipeline<'static, 'static, StoreFrames<&'static mut crate::devices::FixedCamera>>,
                RansacSolver,
            >,
        >();
        let windows_ram = ws.total_bytes() + store_engine;
        let name = profile.name();
        let r = |item: &str, v: usize, unit| row("profile", format!("{name}: {item}"), v, unit);
        out.extend([
            r("image width", w as usize, "px"),
            r("image height", h as usize, "px"),
            r("template side ℓ", usize::from(p.template_px), "px"),
            r("search window cap", usize::from(p.search_px), "px"),
            r("pipeline workspace", ws.total_bytes(), "bytes"),
            r("stereo pair in RAM", pair, "bytes"),
            r("engine state", engine, "bytes"),
            r("RAM: workspace + pair + engine", ram, "bytes"),
            r(
                "RAM margin against the 10 MB envelope (‰ of envelope left, 0 if over)",
                (1000u64.saturating_sub(ram as u64 * 1000 / ENVELOPE_RAM_BYTES)) as usize,
                "‰",
            ),
            r(
                "frame windows (2 × (W + 2)², in the workspace)",
                2 * ws.frame,
                "bytes",
            ),
            r(
                "RAM with the pair in a frame store: workspace + engine",
                windows_ram,
                "bytes",
            ),
            r(
                "RAM margin with the pair in a frame store (‰ of envelope left, 0 if over)",
                (1000u64.saturating_sub(windows_ram as u64 * 1000 / ENVELOPE_RAM_BYTES)) as usize,
                "‰",
            ),
            r(
                "work units, structural bound (attempts + solves + RANSAC chunks)",
                Relocalizer::<Pipeline<'static, 'static>, RansacSolver>::max_work_units(&p)
                    as usize,
                "count",
            ),
            // pose::refine: one pass for the RANSAC pose, one for the weighted
            // fit, one per Levenberg–Marquardt iteration, each over ≤ N_corr
            // inliers; done once, in the unit that concludes the last solve.
            r(
                "final refinement, structural bound (pair evaluations: (2 + refine_iter) × N_corr)",
                (2 + usize::from(p.refine_iter)) * usize::from(p.n_corr),
                "count",
            ),
        ]);
    }
    out
}

fn workspace_item(scale: &str, w: &WorkspaceSizes) -> String {
    format!(
        "pipeline workspace, {scale} (ℓ {}, W {}, coarse-to-fine)",
        w.template_px, w.search_px
    )
}

/// The scene of the measured row: terrain, map and image time, stop.
pub const MEASURED_SCENE: (TerrainKind, f32, u32) = (TerrainKind::Flagstone, 9.5, 3);

/// Rows measured by running one relocalization of a test-profile scene
/// (flagstone, map and images at 9.5 h, stop 3, prior perturbed 10–20 cm and
/// ≤ 1.5° with `seed`): the engine's work counters, its wall time and the
/// outcome. Only the engine call is timed (not the scene or map building).
///
/// # Errors
/// The map or inputs refused by the core (a bug of the simulator).
pub fn measured_rows(seed: u64) -> crate::Result<Vec<Row>> {
    let (kind, hours, stop) = MEASURED_SCENE;
    let scene = Scene::new(kind, seed, Profile::Test);
    let light = scene.lighting(hours);
    let map = scene.map(&light);
    let bytes = map.encode_map(super::map_build::DEFAULT_TILE_SIZE_M)?;
    let (rig, truth, pair) = scene.capture(&light, &Capture::from_index(stop, 0, 0.40));
    let prior = perturbed_prior(&truth, seed);
    let view = vtsm_core::map::MapView::new_checked(&bytes)?;
    let req = Request::new(view, &pair.left, &pair.right, rig, prior).with_seed(seed);
    let report = locate::relocalize(&req, RunOptions::default())?;
    let o = &report.outcome;
    let s = &o.stats;
    let p = &s.pipeline;
    let m = |item: &str, v: u64, unit: &'static str| Row {
        section: "measured",
        item: format!("test-profile relocalization: {item}"),
        value: v,
        unit,
    };
    let (t0, _) = prior.error_to(&truth);
    let (t1, _) = o.pose.error_to(&truth);
    let mm = |x: f32| (f64::from(x) * 1e6).round() as u64;
    Ok(vec![
        m("image width", u64::from(rig.cam().width()), "px"),
        m("image height", u64::from(rig.cam().height()), "px"),
        m("template side ℓ", u64::from(report.template_px), "px"),
        m("search window cap", u64::from(report.search_px), "px"),
        m(
            "workspace allocated",
            report.workspace_bytes as u64,
            "bytes",
        ),
        m(
            "failure code (0 = success)",
            o.failure.map_or(0, |c| u64::from(c.code())),
            "code",
        ),
        m("initial error", mm(t0), "µm"),
        m("final error", mm(t1), "µm"),
        m("inliers", u64::from(o.quality.inliers), "count"),
        m("successful iterations", u64::from(s.successes), "count"),
        m("attempts", u64::from(s.attempts), "count"),
        m("correspondences", u64::from(s.correspondences), "count"),
        m("renders", u64::from(p.renders), "count"),
        m("render pixels", p.render_pixels, "px"),
        m(
            "NCC matches",
            p.matches.iter().map(|&v| u64::from(v)).sum(),
            "count",
        ),
        m("NCC positions scored", p.ncc_positions, "count"),
        m("NCC MACs", p.ncc_macs, "count"),
        m("RANSAC iterations", u64::from(s.ransac_iterations), "count"),
        m(
            "refinement iterations",
            u64::from(s.refine.iterations),
            "count",
        ),
        m(
            "refinement pair evaluations",
            u64::from(s.refine.residuals_evaluated),
            "count",
        ),
        m("stalls", u64::from(s.stalls), "count"),
        m("reseeds", u64::from(s.reseeds), "count"),
        m(
            "engine wall time (one thread)",
            report.elapsed.as_micros() as u64,
            "µs",
        ),
    ])
}

/// Run the command; returns the exit code.
pub fn run(args: &Args) -> crate::Result<u8> {
    let mut rows = rows();
    rows.extend(profile_rows());
    if !args.no_run {
        rows.extend(measured_rows(args.seed)?);
    }
    if let Some(dir) = &args.firmware {
        rows.extend(firmware_rows(dir)?);
    }
    if let Some(dir) = &args.write {
        write(dir, &rows)?;
        println!("wrote {} rows to {}", rows.len(), dir.display());
        return Ok(0);
    }
    if args.json {
        for r in &rows {
            let v = serde_json::json!({
                "section": r.section, "item": r.item, "value": r.value, "unit": r.unit
            });
            println!("{v}");
        }
    } else {
        println!("| section | item | value | unit |");
        println!("|---|---|---:|---|");
        for r in &rows {
            println!("| {} | {} | {} | {} |", r.section, r.item, r.value, r.unit);
        }
    }
    Ok(0)
}

/// Rows whose value is not a deterministic function of the code and seed
/// (wall time, and the firmware images, which depend on the toolchain that
/// built them): left out of the snapshot.
pub fn in_snapshot(r: &Row) -> bool {
    r.unit != "µs" && r.section != "firmware"
}

/// Relative tolerance of a row in the snapshot comparison: static sizes and
/// bounds must match exactly; counters of the measured relocalization may
/// move by 2 % before the snapshot must be renewed on purpose.
pub fn tolerance(r: &Row) -> f64 {
    if r.section == "measured" {
        0.02
    } else {
        0.0
    }
}

/// One snapshot line for `r`.
pub fn snapshot_line(r: &Row) -> String {
    serde_json::json!({
        "section": r.section, "item": r.item, "value": r.value, "unit": r.unit
    })
    .to_string()
}

fn write(dir: &std::path::Path, rows: &[Row]) -> crate::Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| crate::Error::file(dir, e.to_string()))?;
    let mut md = String::from(
        "# Budget (generated)\n\nWritten by `vtsm budget --write fsw-docs/budgets/`; do not edit: \
         `tests/tests/integration/e2e_budget.rs` compares `budget.snapshot.json` with the code \
         (static rows exactly, measured counters within 2 %). The `firmware` rows, when \
         present, are read from the ELF images by `--firmware tests/firmware/target` \
         (after `cargo build --release --target <t>` in `tests/firmware/`) and are not \
         in the snapshot.\n\n\
         | section | item | value | unit |\n|---|---|---:|---|\n",
    );
    for r in rows {
        md.push_str(&format!(
            "| {} | {} | {} | {} |\n",
            r.section, r.item, r.value, r.unit
        ));
    }
    let snap: String = rows
        .iter()
        .filter(|r| in_snapshot(r))
        .map(|r| snapshot_line(r) + "\n")
        .collect();
    for (name, text) in [("budget.md", md), ("budget.snapshot.json", snap)] {
        let path = dir.join(name);
        crate::io::write_atomic(&path, text.as_bytes(), true)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// The host test binary is an ELF image too: its code, read-only data and
    /// zeroed data are found, and flash and RAM are the documented sums.
    #[test]
    fn image_sections_of_an_elf_image() {
        let exe = std::fs::read(std::env::current_exe().unwrap()).unwrap();
        let s = image_sections(&exe).unwrap();
        assert!(s.text > 100_000, "{s:?}");
        assert!(s.rodata > 0 && s.bss > 0, "{s:?}");
        assert_eq!(s.flash(), s.text + s.rodata + s.data);
        assert_eq!(s.static_ram(), s.data + s.bss);
    }

    /// Bytes that are not ELF, and a directory without images, are errors
    /// naming the file.
    #[test]
    fn firmware_rows_refuse_what_is_not_an_image() {
        assert!(image_sections(b"not an elf file at all").is_err());
        let dir = std::env::temp_dir().join(format!("vtsm-fw-none-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let e = firmware_rows(&dir).unwrap_err().to_string();
        assert!(e.contains("no firmware image"), "{e}");
        let bin = dir.join(FIRMWARE_TARGETS[0]).join("release");
        std::fs::create_dir_all(&bin).unwrap();
        std::fs::write(bin.join("vtsm-firmware"), b"garbage").unwrap();
        let e = firmware_rows(&dir).unwrap_err().to_string();
        assert!(e.contains("vtsm-firmware"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
