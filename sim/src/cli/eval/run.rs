//! A suite run: build the depots and maps, make the groups, run every
//! trial, summarize, and draw the tables and figures.

use super::config::{Method, SuiteConfig};
use super::depot::Depot;
use super::figures;
use super::group::with_baseline_groups;
use super::maps::MapEntry;
use super::plot::Figure;
use super::protocol::{MAP_VIEW_RANGE_M, PRIOR_MAX_DEG, TILE_M};
use super::suites::SuiteDef;
use super::tables::{integrity_table, score_decile_table, side_by_side, variant_table};
use super::trial::{run_trial, Shared, Spec};
use crate::cli::demo::MAP_HOURS;
use crate::error::{Error, Result};
use crate::eval::{self, GroupSummary, RunMeta, TrialOutcome};
use crate::locate;
use rayon::prelude::*;
use std::time::Instant;

/// A finished suite run.
pub struct SuiteRun {
    /// Reproducibility record.
    pub meta: RunMeta,
    /// One outcome per trial, in group then trial order.
    pub outcomes: Vec<TrialOutcome>,
    /// The campaign index of each outcome (`group × trials + k`): every
    /// index of the campaign, or those of its `--shard`.
    pub indices: Vec<usize>,
    /// Trials of the whole campaign (groups × trials per group).
    pub total: usize,
    /// One summary per group.
    pub groups: Vec<GroupSummary>,
    /// Extra Markdown (per-suite breakdowns) printed after the table.
    pub notes: String,
    /// Figures, each written as SVG and PNG.
    pub plots: Vec<Figure>,
    /// Wall time of building scenes, lightings and maps, seconds.
    pub setup_s: f64,
    /// Wall time of all trials, seconds.
    pub trials_s: f64,
}

/// Run a suite: build the shared scenes, lightings and maps, run every trial,
/// summarize and draw the plots.
///
/// # Errors
/// Empty terrain/hour/step lists. Per-trial problems (a map that cannot be
/// encoded, a rejected request) are recorded as failed trials, not errors.
pub fn run_suite(cfg: &SuiteConfig, command: &str) -> Result<SuiteRun> {
    run_suite_journaled(cfg, command, None)
}

/// [`run_suite`] keeping each finished trial in `journal` (a part's
/// [`Journal`](super::shard::Journal)): trials it already holds are not run
/// again.
///
/// # Errors
/// As [`run_suite`], or a journal of another campaign.
pub fn run_suite_journaled(
    cfg: &SuiteConfig,
    command: &str,
    journal: Option<&super::shard::Journal>,
) -> Result<SuiteRun> {
    if cfg.suite == super::config::Suite::Dataset {
        return Err(Error::msg(
            "the dataset suite runs from its data set (cli::eval::dataset::run)",
        ));
    }
    let def = cfg.suite.def();
    if cfg.terrains.is_empty() || cfg.hours.is_empty() || cfg.trials == 0 {
        return Err(Error::msg("a suite needs terrains, hours and trials"));
    }
    def.check(cfg)?;
    let t_setup = Instant::now();
    let depot = Depot::build(cfg, def.live_hours(cfg), &def.worlds(cfg));
    let maps = def.maps(cfg, &depot);
    let groups = def.groups(cfg, &depot, &maps);
    let (maps, groups) = if cfg.relight {
        relit_groups(cfg, &depot, maps, groups)
    } else {
        (maps, groups)
    };
    let groups = with_baseline_groups(groups, cfg.baseline);
    let setup_s = t_setup.elapsed().as_secs_f64();
    let meta = run_meta(cfg, def, &depot, command);
    let shared = Shared {
        cfg,
        groups: &groups,
        depot: &depot,
        maps: &maps,
    };
    run_campaign(cfg, meta, groups.len(), journal, setup_s, |group, k| {
        run_trial(&shared, &Spec { group, k })
    })
}

/// `--relight on`: every group's map relit to the sun of its live pairs,
/// one product per distinct (map, lighting), appended to `maps`, and the
/// groups pointed at them. A map whose source was not kept (a suite with
/// maps of its own, as `dataset`) stays as made.
fn relit_groups(
    cfg: &SuiteConfig,
    depot: &Depot,
    mut maps: Vec<MapEntry>,
    mut groups: Vec<super::group::Group>,
) -> (Vec<MapEntry>, Vec<super::group::Group>) {
    let mut keys: Vec<(usize, usize)> = Vec::new();
    for g in &groups {
        if !keys.contains(&(g.map, g.light)) {
            keys.push((g.map, g.light));
        }
    }
    let scoring = super::maps::Scoring::of(cfg);
    let relit: Vec<Option<MapEntry>> = keys
        .par_iter()
        .map(|&(m, l)| {
            let sun = &depot.lights.get(l)?.sun;
            maps.get(m)?.relit(sun, scoring, cfg.origin)
        })
        .collect();
    let mut index = vec![None; keys.len()];
    for (k, r) in relit.into_iter().enumerate() {
        if let Some(entry) = r {
            index[k] = Some(maps.len());
            maps.push(entry);
        }
    }
    for g in &mut groups {
        let k = keys.iter().position(|&key| key == (g.map, g.light));
        if let Some(Some(m)) = k.map(|k| index[k]) {
            g.map = m;
        }
    }
    (maps, groups)
}

/// Run the campaign of `groups` groups of `cfg.trials` trials described by
/// `meta`: the indices of `cfg.shard` ([`campaign_indices`]), those in
/// `journal` read back, the others run in parallel by `trial(group, k)`
/// (in campaign order whatever the scheduling), then [`finish`]ed.
/// A trial's capture and seed depend only on `k`, the trial count and the
/// seed, never on which other trials run.
///
/// # Errors
/// A shard that holds no trial, or a journal of another campaign.
pub(super) fn run_campaign(
    cfg: &SuiteConfig,
    meta: RunMeta,
    groups: usize,
    journal: Option<&super::shard::Journal>,
    setup_s: f64,
    trial: impl Fn(usize, usize) -> TrialOutcome + Sync,
) -> Result<SuiteRun> {
    let t_trials = Instant::now();
    let total = groups * cfg.trials;
    let indices = campaign_indices(cfg, total)?;
    let outcomes = run_journaled(&indices, &meta, journal, cfg.progress, |todo, finished| {
        eval::run_parallel(todo, |&i| {
            let o = trial(i / cfg.trials, i % cfg.trials);
            finished(i, &o);
            o
        })
    })?;
    let trials_s = t_trials.elapsed().as_secs_f64();
    Ok(finish(
        cfg,
        meta,
        outcomes,
        (indices, total),
        (setup_s, trials_s),
    ))
}

/// The campaign indices of `total` trials that this run holds: all, or
/// those of its `--shard`.
///
/// # Errors
/// A shard that holds none of them.
fn campaign_indices(cfg: &SuiteConfig, total: usize) -> Result<Vec<usize>> {
    let indices: Vec<usize> = (0..total)
        .filter(|&i| cfg.shard.is_none_or(|s| s.holds(i)))
        .collect();
    if indices.is_empty() {
        return Err(Error::msg(format!(
            "shard {} holds no trial of the campaign's {total}",
            cfg.shard.map(|s| s.to_string()).unwrap_or_default()
        )));
    }
    Ok(indices)
}

/// The outcomes of the campaign indices `indices`, in that order: those
/// `journal` already holds read back, the others run by `run` (given the
/// indices to run and a callback for each finished one), each recorded in
/// `journal` as it finishes; with `progress`, the trials done of
/// `indices`, the rate and the time left on stderr
/// ([`crate::progress::Progress`]).
///
/// # Errors
/// A journal of another campaign.
fn run_journaled<R>(
    indices: &[usize],
    meta: &RunMeta,
    journal: Option<&super::shard::Journal>,
    progress: bool,
    run: R,
) -> Result<Vec<TrialOutcome>>
where
    R: FnOnce(&[usize], &(dyn Fn(usize, &TrialOutcome) + Sync)) -> Vec<TrialOutcome>,
{
    let done = match journal {
        Some(j) => j.open(meta)?,
        None => std::collections::BTreeMap::new(),
    };
    let todo: Vec<usize> = indices
        .iter()
        .copied()
        .filter(|i| !done.contains_key(i))
        .collect();
    let bar = crate::progress::Progress::new(
        indices.len() as u64,
        (indices.len() - todo.len()) as u64,
        "trials",
        progress,
    );
    let fresh = run(&todo, &|i, o| {
        if let Some(j) = journal {
            j.record(i, o);
        }
        bar.inc();
    });
    bar.finish();
    let mut fresh = todo.into_iter().zip(fresh);
    let mut all = Vec::with_capacity(indices.len());
    for i in indices {
        match done.get(i) {
            Some(o) => all.push(o.clone()),
            None => all.extend(fresh.next().map(|(_, o)| o)),
        }
    }
    Ok(all)
}

/// The finished run of `outcomes` (the campaign indices `indices` of
/// `total`): the summary, the figures, the suite's notes, the integrity
/// table and the baseline's side-by-side table.
pub(super) fn finish(
    cfg: &SuiteConfig,
    meta: RunMeta,
    outcomes: Vec<TrialOutcome>,
    (indices, total): (Vec<usize>, usize),
    (setup_s, trials_s): (f64, f64),
) -> SuiteRun {
    let summary = eval::summarize(&outcomes);
    let plots = figures::all(cfg, &outcomes);
    let mut notes = cfg.suite.def().notes(&outcomes);
    notes.push_str(&integrity_table(&outcomes));
    notes.push_str(&score_decile_table(&outcomes));
    notes.push_str(&variant_table(&outcomes));
    if let Some(m) = cfg.baseline {
        notes = side_by_side(&summary, m) + &notes;
    }
    SuiteRun {
        meta,
        outcomes,
        indices,
        total,
        groups: summary,
        notes,
        plots,
        setup_s,
        trials_s,
    }
}

/// The upset checks of a run's VTSM trials, as its record states them.
pub(super) fn verify_json(cfg: &SuiteConfig) -> serde_json::Value {
    serde_json::json!({
        "repeat_solve": cfg.verify.repeat_solve,
        "recheck_map": cfg.verify.recheck_map,
    })
}

/// The accuracy asked of a run's VTSM trials (`--accuracy`), as its record
/// states it (`null`: none).
pub(super) fn accuracy_json(cfg: &SuiteConfig) -> serde_json::Value {
    cfg.accuracy.map_or(
        serde_json::Value::Null,
        |a| serde_json::json!({ "sigma_t_m": a.sigma_t_m, "sigma_r_deg": a.sigma_r_deg }),
    )
}

/// The reproducibility record of a run.
fn run_meta(cfg: &SuiteConfig, def: &dyn SuiteDef, depot: &Depot, command: &str) -> RunMeta {
    let width = depot.scenes[0].camera().width();
    let params = locate::params_for_width(width);
    RunMeta {
        suite: def.name().to_string(),
        git_revision: eval::git_revision(),
        profile: cfg.profile.name().to_string(),
        seed: cfg.seed,
        trials: cfg.trials,
        physical: cfg.physical,
        params: serde_json::json!({
            "relocalization": format!("{params:?}"),
            "terrains": cfg.terrains.iter().map(|k| k.name()).collect::<Vec<_>>(),
            "hours": depot.live_hours,
            "map_hours": MAP_HOURS,
            "steps": def.steps(cfg),
            "seeds_k": cfg.seeds_k,
            "stated_uncertainty": def.stated_uncertainty().map_or(serde_json::Value::Null, |u| {
                serde_json::json!({ "groups": "K=0", "t_m": u.t_m, "r_deg": u.r_deg })
            }),
            "prior_m": def.prior_m(),
            "prior_max_deg": PRIOR_MAX_DEG,
            "map_view_range_m": MAP_VIEW_RANGE_M,
            "tile_m": TILE_M,
            "light_model": cfg.light_model.name(),
            "mask": if cfg.mask_all { "all" } else { "paper" },
            "wind": cfg.wind,
            "map_coarse": cfg.map_coarse,
            "change": cfg.change.label(),
            "camera": cfg.camera.label(),
            "rectify_interp": if cfg.physical { Some(cfg.interp.name()) } else { None },
            "baseline": cfg.baseline.map(Method::name),
            "origin": cfg.origin,
            "verify": verify_json(cfg),
            "accuracy": accuracy_json(cfg),
            "final_pairs": cfg.final_pairs,
            "revisit": cfg.search.revisit,
            "near": cfg.search.near.share_256 > 0,
            "map_scores": cfg.map_scores,
            "score_deciles": cfg.score_deciles,
            "features": cfg.baseline.map(|_| {
                format!("{:?}", crate::features::FeatureParams::for_width(width))
            }),
            "mapping_views": def.mapping_views(),
        }),
        command: command.to_string(),
    }
}
