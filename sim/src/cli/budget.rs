//! `vtsm budget`: the memory and work budgets, computed from the code itself.
//!
//! Every number is derived at run time from `vtsm_core::config` and
//! `core::mem::size_of` of the core's types, never typed in. Each stage adds its
//! rows to [`rows`] (measured work counters belong in the section of the stage
//! that measures them).

use std::mem::size_of;
use vtsm_core::config as cfg;

/// Arguments of `vtsm budget`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Print JSON lines (one object per row) instead of a Markdown table.
    #[arg(long)]
    pub json: bool,
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
    ]
}

/// Run the command; returns the exit code.
pub fn run(args: &Args) -> crate::Result<u8> {
    let rows = rows();
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
