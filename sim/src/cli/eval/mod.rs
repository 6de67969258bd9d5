//! `vtsm eval`: the evaluation suites of the paper (§V) on the simulated depot.
//!
//! Each suite is a list of groups (rows of the table). Every terrain's
//! [`Scene`](crate::scene::Scene), every map product and every lighting are
//! built once and shared read-only by all trials, which run in parallel through
//! [`crate::eval::run_parallel`]. A trial is one capture of the paper's grid
//! (stops spread over the 30), its live lighting, a perturbed prior with a
//! per-trial seed and one [`crate::locate::relocalize`]. Trial `k` uses the same
//! capture and the same seed in every group, so groups are paired comparisons,
//! and everything is a function of `--seed`.
//!
//! Suites:
//! - `paper`: flagstone, cfa6, cfa2 × time difference 0/3/6 h (map at 9.5 h),
//!   0.40 m baseline, priors 10–20 cm / ≤ 1.5°.
//! - `baseline`: the same with the 0.20 m baseline.
//! - `uncertainty50`: priors 25–50 cm / ≤ 1.5°, from a single start that is
//!   told the priors' real uncertainty ([`UNCERTAINTY_50`], served with the
//!   prior as a `prior.json` `uncertainty` is, so the engine runs with it as
//!   t̃₀, r̃₀), from a single start told nothing (the default t̃₀ 0.20 m,
//!   `K=0 untold`), and with the multi-seed mode (`Params.seeds = K` seeds
//!   spread over the same 0.50 m, t̃₀ 0.20 m; left out with `--seeds-k 0`);
//!   first, a reference group with the paper's 10–20 cm priors on the same
//!   captures (`ref 10-20cm`), so that the cost of the wider prior is
//!   measured in the same run.
//! - `stepsize`: maps restricted to what sub-sampled wave and forward mapping
//!   paths see (see [`restrict_to_views`]); reports range to the nearest view.
//! - `wrongplace`: inputs that must not give a confident answer, per terrain:
//!   the correct pair with small parameters (N_corr 27, N_iter 1, reseed cap
//!   3; priors 10–20 cm), the same with a "right" image that is the left one
//!   shifted by [`SHIFT_PX`] pixels (prior at the truth), frames taken at
//!   another stop of the grid with the prior of this one, and frames of the
//!   next terrain's depot at this stop (two or more terrains).
//!
//! Every suite ends with an integrity table: successes, and successes whose
//! true error exceeds [`WRONG_T_MM`] or [`WRONG_R_DEG`] ("confident wrong";
//! on `wrongplace` frames of another depot, every success).
//!
//! `--origin X,Y,Z` offsets the whole scene (mesh, priors, truths) by that
//! vector: maps are built from the offset mesh through the file readers' path
//! (f64 vertices, f32 local vertices about the map origin; [`offset_mesh`]),
//! with the map origin at X,Y,Z, as `vtsm map build --origin X,Y,Z` would;
//! priors go into the map's local frame and estimates come back in f64, and
//! errors are measured in the offset frame. The local frame is then the
//! simulator's (`f64(v) + X − X = v` wherever the sum is exact), so the results
//! do not depend on the offset.
//!
//! `--physical` renders every live pair (and the `wrongplace` frames) in the
//! physical form of `vtsm scene export --physical`
//! ([`crate::scene::physical::capture_physical`]: same truth and sensor-noise
//! seeds), rectifies it with
//! [`Rectifier::rectify_input`](crate::rectify::Rectifier::rectify_input) as
//! `vtsm relocalize` does for an OpenCV calibration, and turns the estimate
//! back to the physical left camera
//! ([`Rectifier::to_physical`](crate::rectify::Rectifier::to_physical)) before
//! measuring its error.
//!
//! Two diagnostics change the simulated depot, not the engine: `--light-model`
//! takes cast shadows or attached shading out of the mapping-time and the live
//! lighting alike ([`LightModel`](crate::render::LightModel)), and `--mask
//! all` puts every map triangle in the sampling mask M̂ (the paper keeps only
//! rocks on Flagstone and CFA6).
//! `--wind S` changes the live depot after mapping (`Terrain::with_wind`: sand
//! ripples, dust, moved pebbles), the maps staying those of the mapped one: what
//! the rock-only masks of the paper guard against. Their defaults (`full`,
//! `paper`, 0) are the suites as the paper ran them.
//!
//! "Mapping views" for the distance/angle columns of `paper`, `baseline` and
//! `uncertainty50` are the 60 viewpoints of the wave mapping path
//! ([`mapping_trajectory`](crate::scene::mapping_trajectory) with step 1);
//! for `stepsize` they are the sub-sampled path the map was restricted to.

//! The rooms: [`args`] (the command line), [`config`] (a run's settings),
//! [`suites`] (one module per suite behind one trait, and the registry),
//! [`protocol`] (captures, seeds, priors), [`depot`] and [`maps`] (what is
//! built once), [`group`], [`frames`] and [`trial`] (one trial), [`mod@run`]
//! (a whole run), [`tables`], [`figures`] and [`plot`] (what is reported),
//! [`replot`] (the figures of a recorded run drawn again from its trials),
//! [`shard`] (a campaign split into parts, `--shard K/N`, and their merge).

pub mod args;
pub mod config;
pub mod covariance;
pub mod dataset;
pub mod depot;
pub mod figures;
pub mod frames;
pub mod group;
pub mod maps;
pub mod plot;
pub mod protocol;
pub mod replot;
pub mod run;
pub mod shard;
pub mod suites;
pub mod tables;
pub mod trial;
pub mod views;

pub use args::{config_from_args, Args};
pub use config::{Method, Suite, SuiteConfig};
pub use covariance::covariance_check;
pub use maps::offset_mesh;
pub use protocol::*;
pub use run::{run_suite, SuiteRun};
pub use tables::{
    confident_wrong, integrity_table, range_table, side_by_side, success_without_gates, GATE_CODES,
    RANGE_BINS_M,
};
pub use views::{restrict_to_views, seen_by};

use crate::error::{Error, Result};
use crate::eval;
use std::path::{Path, PathBuf};

/// Write `table.md` (with the breakdown appended), `trials.csv`, `summary.json`
/// and the figures (SVG and PNG) into `dir`.
///
/// # Errors
/// As [`eval::write_outputs`], or a figure that cannot be drawn.
pub fn write_run(dir: &Path, run: &SuiteRun, force: bool) -> Result<()> {
    eval::write_outputs(dir, &run.meta, &run.groups, &run.outcomes, force)?;
    if !run.notes.is_empty() {
        let table = eval::markdown_table(&run.meta, &run.groups) + &run.notes;
        eval::write_new(&dir.join("table.md"), &table, true)?;
    }
    replot::write_figures(dir, &run.plots, force)?;
    Ok(())
}

fn default_out(suite: Suite) -> PathBuf {
    (1..)
        .map(|k| PathBuf::from(format!("vtsm-eval/{}-{k}", suite.name())))
        .find(|p| !p.exists())
        .unwrap_or_else(|| PathBuf::from("vtsm-eval/run"))
}

/// Run the command; returns the exit code.
pub fn run(args: &Args) -> Result<u8> {
    if let Some(args::EvalCommand::Merge(m)) = &args.command {
        let command = std::env::args().collect::<Vec<_>>().join(" ");
        shard::merge(&m.out, &m.parts, m.force, &command)?;
        println!("wrote {}", m.out.display());
        return Ok(0);
    }
    if let Some(dir) = &args.replot {
        for p in replot::replot(dir, args.force)? {
            println!("wrote {}", p.display());
        }
        return Ok(0);
    }
    let mut cfg = config_from_args(args)?;
    let out = args.out.clone().unwrap_or_else(|| default_out(cfg.suite));
    if args.panels {
        cfg.panels = Some(out.join("panels"));
    }
    let created = !out.exists();
    std::fs::create_dir_all(&out)
        .map_err(|e| Error::file(&out, format!("cannot create directory: {e}")))?;
    for name in ["table.md", "trials.csv", "summary.json", shard::PART_FILE] {
        crate::io::check_output(&out.join(name), args.force)?;
    }
    let command = std::env::args().collect::<Vec<_>>().join(" ");
    let journal = cfg.shard.map(|_| shard::Journal::new(&out));
    let ran = match cfg.suite {
        Suite::Dataset => dataset::run(&cfg, &command, journal.as_ref()),
        _ => run::run_suite_journaled(&cfg, &command, journal.as_ref()),
    };
    let run = match ran {
        Ok(r) => r,
        Err(e) => {
            // A run refused before any trial leaves no empty directory behind.
            if created {
                let _ = std::fs::remove_dir(&out);
            }
            return Err(e);
        }
    };
    print!("{}", eval::markdown_table(&run.meta, &run.groups));
    print!("{}", run.notes);
    println!(
        "setup ({}) {:.1} s; {} trials in {:.1} s wall on {} threads",
        if cfg.suite == Suite::Dataset {
            "data set checks, map"
        } else {
            "scenes, lightings, maps"
        },
        run.setup_s,
        run.outcomes.len(),
        run.trials_s,
        rayon::current_num_threads()
    );
    write_run(&out, &run, args.force)?;
    match cfg.shard {
        Some(s) => shard::write_part(&out, &run, s, args.force)?,
        // A whole run replacing a part (`--force`) is no longer a part.
        None => {
            let _ = std::fs::remove_file(out.join(shard::PART_FILE));
        }
    }
    println!("wrote {}", out.display());
    Ok(0)
}

#[cfg(test)]
mod tests;
