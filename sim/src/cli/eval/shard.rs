//! Campaigns split over machines: `vtsm eval --shard K/N` runs one part of a
//! campaign, `vtsm eval merge` joins the parts into the result of the whole.
//!
//! The campaign's trials are numbered in its fixed order, index
//! `group × trials + k` for trial `k` of group `group`; shard `K` of `N` holds
//! the indices `i` with `i mod N = K`. A trial's capture and seed depend
//! only on `k`, the trial count and the campaign seed, so a trial gives the
//! same outcome in whichever part it runs.
//!
//! A part is a result directory like any run's, whose tables and figures are
//! those of its trials only, with a `part.json` ([`PartRecord`]): what the
//! campaign is, which shard, the campaign indices it holds and each trial's
//! outcome in a lossless form (floats as their IEEE-754 bits). `merge` checks
//! that the parts belong together and cover every index exactly once, puts
//! the trials back in campaign order and writes the table, `trials.csv`,
//! `summary.json` and figures a single-process run writes.
//!
//! While a part runs, each finished trial is recorded at once in its
//! [`Journal`] (`part.d/`), so a killed shard rerun into the same directory
//! runs only the trials not recorded.

use super::config::{Method, SuiteConfig};
use super::run::SuiteRun;
use super::{replot, write_run};
use crate::error::{Error, Result};
use crate::eval::columns::{
    AccuracyColumns, CaptureColumns, CovarianceColumns, EngineColumns, FeatureColumns,
    GroupColumns, TrialColumns, VerifyColumns, ViewColumns,
};
use crate::eval::{self, RunMeta, TrialOutcome};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::{Path, PathBuf};

/// Name of a part's record in its result directory.
pub const PART_FILE: &str = "part.json";

/// Shard `k` of `n` (0-based, as a Slurm array task id): the campaign
/// indices `i` with `i mod n = k`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// This shard, 0..n.
    pub k: usize,
    /// Number of shards.
    pub n: usize,
}

impl Shard {
    /// Parse `K/N` with `0 ≤ K < N`.
    ///
    /// # Errors
    /// Anything else, with what is accepted.
    pub fn parse(s: &str) -> std::result::Result<Self, String> {
        let bad = || format!("`{s}` is not a shard K/N with 0 <= K < N");
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let k: usize = k.trim().parse().map_err(|_| bad())?;
        let n: usize = n.trim().parse().map_err(|_| bad())?;
        if k >= n {
            return Err(bad());
        }
        Ok(Self { k, n })
    }

    /// Whether campaign index `i` belongs to this shard.
    pub fn holds(self, i: usize) -> bool {
        i % self.n == self.k
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.k, self.n)
    }
}

/// One trial's outcome as a part records it: every field of
/// [`TrialOutcome`], floats as their bits so that the merged outputs are
/// those of a single run to the last digit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartTrial {
    /// Campaign index.
    pub index: usize,
    /// Group label.
    pub group: String,
    /// Relocalization method.
    pub method: String,
    /// Trial index within the group.
    pub trial: usize,
    /// Seed of the trial.
    pub seed: u64,
    /// Whether the relocalization succeeded.
    pub success: bool,
    /// Failure code, if any.
    pub failure: Option<String>,
    /// Bits of `init_t_mm`, `init_r_deg`, `final_t_mm`, `final_r_deg`, `time_s`.
    pub errors_bits: [u64; 5],
    /// Inliers.
    pub inliers: u32,
    /// Iterations.
    pub iterations: u32,
    /// The set [`TrialColumns`] as `(name, bits)`, sorted by name.
    pub columns: Vec<(String, u64)>,
}

impl PartTrial {
    /// The record of outcome `o` at campaign index `index`.
    pub fn new(index: usize, o: &TrialOutcome) -> Self {
        Self {
            index,
            group: o.group.clone(),
            method: o.method.clone(),
            trial: o.trial,
            seed: o.seed,
            success: o.success,
            failure: o.failure.clone(),
            errors_bits: [
                o.init_t_mm,
                o.init_r_deg,
                o.final_t_mm,
                o.final_r_deg,
                o.time_s,
            ]
            .map(f64::to_bits),
            inliers: o.inliers,
            iterations: o.iterations,
            columns: o
                .columns
                .entries()
                .into_iter()
                .map(|(k, v)| (k.to_string(), v.to_bits()))
                .collect(),
        }
    }

    /// The outcome back.
    ///
    /// # Errors
    /// Columns that do not make a [`TrialColumns`].
    pub fn outcome(&self) -> std::result::Result<TrialOutcome, String> {
        let [init_t_mm, init_r_deg, final_t_mm, final_r_deg, time_s] =
            self.errors_bits.map(f64::from_bits);
        Ok(TrialOutcome {
            group: self.group.clone(),
            method: self.method.clone(),
            trial: self.trial,
            seed: self.seed,
            success: self.success,
            failure: self.failure.clone(),
            init_t_mm,
            init_r_deg,
            final_t_mm,
            final_r_deg,
            inliers: self.inliers,
            iterations: self.iterations,
            time_s,
            columns: columns_from(&self.columns)?,
        })
    }
}

/// The [`TrialColumns`] whose [`TrialColumns::entries`] are `entries`.
fn columns_from(entries: &[(String, u64)]) -> std::result::Result<TrialColumns, String> {
    let get = |name: &str| {
        entries
            .iter()
            .find(|e| e.0 == name)
            .map(|e| f64::from_bits(e.1))
    };
    let has = |name: &str| get(name).is_some();
    let v = |name: &str| get(name).ok_or_else(|| format!("trial record lacks column `{name}`"));
    let f32_ = |name: &str| v(name).map(|x| x as f32);
    let flag = |name: &str| v(name).map(|x| x != 0.0);
    let group = if has("prior_max_m") {
        Some(GroupColumns::Prior {
            hours: f32_("hours")?,
            prior_max_m: f32_("prior_max_m")?,
            seeds_k: v("seeds_k")? as u16,
            t0_m: f32_("t0_m")?,
            r0_deg: f32_("r0_deg")?,
        })
    } else if has("wrong_place") {
        Some(GroupColumns::WrongPlace {
            hours: f32_("hours")?,
            other_depot: flag("wrong_place")?,
        })
    } else if has("pair") {
        Some(GroupColumns::Dataset {
            pair: v("pair")? as u32,
            t0_m: f32_("t0_m")?,
            r0_deg: f32_("r0_deg")?,
        })
    } else if has("sun_el_deg") {
        Some(GroupColumns::Condition {
            hours: f32_("hours")?,
            sun_el_deg: f32_("sun_el_deg")?,
            map_sun_el_deg: f32_("map_sun_el_deg")?,
            map_coarse: v("map_coarse")? as u32,
            tracks: v("tracks")? as u32,
            rocks_moved: f32_("rocks_moved")?,
            dust: f32_("dust")?,
            camera: flag("camera_effects")?,
        })
    } else if has("step") {
        Some(GroupColumns::Step {
            hours: f32_("hours")?,
            step: v("step")? as usize,
            forward: flag("forward")?,
        })
    } else {
        None
    };
    let mut c = TrialColumns {
        group,
        ..TrialColumns::default()
    };
    if has("stop") {
        c.capture = Some(CaptureColumns {
            stop: v("stop")? as u32,
            look_at: v("look_at")? as u32,
        });
    }
    if has("view_dist_m") {
        c.view = Some(ViewColumns {
            dist_m: v("view_dist_m")?,
            angle_deg: v("view_angle_deg")?,
        });
    }
    if has("attempts") {
        c.engine = Some(EngineColumns {
            attempts: v("attempts")? as u32,
            // Columns a campaign recorded before Revisit lack: 0.
            pairs: get("pairs").unwrap_or(0.0) as u32,
            revisited: get("revisited").unwrap_or(0.0) as u32,
            revisit_pairs: get("revisit_pairs").unwrap_or(0.0) as u32,
            near_drawn: get("near_drawn").unwrap_or(0.0) as u32,
            near_pairs: get("near_pairs").unwrap_or(0.0) as u32,
            stalls: v("stalls")? as u16,
            reseeds: v("reseeds")? as u16,
            focused_rounds: v("focused_rounds")? as u16,
            gradient_rounds: v("gradient_rounds")? as u16,
            refine_accepted: v("refine_accepted")? as u32,
            spread_m: f32_("spread_m")?,
            reproj_px: f32_("reproj_px")?,
            prior_dt_m: f32_("prior_dt_m")?,
            prior_dr_deg: f32_("prior_dr_deg")?,
        });
    }
    if has("cov_d2_t") {
        c.covariance = Some(CovarianceColumns {
            d2_t: v("cov_d2_t")?,
            d2_r: v("cov_d2_r")?,
            sigma_t_mm: v("sigma_t_mm")?,
            sigma_r_deg: v("sigma_r_deg")?,
        });
    }
    if has("rounds_saved") {
        c.accuracy = Some(AccuracyColumns {
            rounds_saved: v("rounds_saved")? as u16,
            accuracy_checks: v("accuracy_checks")? as u16,
        });
    }
    if has("verify_repeat_solve") {
        c.verify = Some(VerifyColumns {
            repeat_solve: flag("verify_repeat_solve")?,
            recheck_map: flag("verify_recheck_map")?,
        });
    }
    if has("map_keypoints") {
        c.features = Some(FeatureColumns {
            map_keypoints: v("map_keypoints")? as usize,
            live_keypoints: v("live_keypoints")? as usize,
            matches: v("matches")? as usize,
            stereo_points: v("stereo_points")? as usize,
        });
    }
    let back: Vec<(String, u64)> = c
        .entries()
        .into_iter()
        .map(|(k, v)| (k.to_string(), v.to_bits()))
        .collect();
    if back != entries {
        return Err("trial record has columns that do not belong together".into());
    }
    Ok(c)
}

/// `part.json`: what a part of a campaign is and the trials it holds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartRecord {
    /// Suite name.
    pub suite: String,
    /// Image profile.
    pub profile: String,
    /// Campaign seed.
    pub seed: u64,
    /// Trials per group.
    pub trials: usize,
    /// Build revision of the binary that ran the part.
    pub git_revision: String,
    /// `K/N`.
    pub shard: String,
    /// Trials of the whole campaign.
    pub total: usize,
    /// The campaign indices the part holds, ascending.
    pub indices: Vec<usize>,
    /// The part's trials, in the order of `indices`.
    pub outcomes: Vec<PartTrial>,
}

/// Write the `part.json` of a `--shard` run into `dir`.
///
/// # Errors
/// An existing file without `force`, or an I/O failure.
pub fn write_part(dir: &Path, run: &SuiteRun, shard: Shard, force: bool) -> Result<()> {
    let rec = PartRecord {
        suite: run.meta.suite.clone(),
        profile: run.meta.profile.clone(),
        seed: run.meta.seed,
        trials: run.meta.trials,
        git_revision: run.meta.git_revision.clone(),
        shard: shard.to_string(),
        total: run.total,
        indices: run.indices.clone(),
        outcomes: run
            .indices
            .iter()
            .zip(&run.outcomes)
            .map(|(&i, o)| PartTrial::new(i, o))
            .collect(),
    };
    let text = serde_json::to_string_pretty(&rec)
        .map_err(|e| Error::msg(format!("cannot encode JSON: {e}")))?;
    eval::write_new(&dir.join(PART_FILE), &text, force)
}

/// Directory of a part's finished trials, one `<index>.json`
/// ([`PartTrial`]) each, beside `campaign.json` (the run's meta without the
/// command).
pub const JOURNAL_DIR: &str = "part.d";

/// The finished trials of a `--shard` run, each written atomically (a
/// temporary file and a rename) as it finishes; a rerun of the shard into the
/// same directory takes them as done, so a killed shard loses at most the
/// trials in flight.
pub struct Journal {
    dir: PathBuf,
}

impl Journal {
    /// The journal of the part written into `out`.
    pub fn new(out: &Path) -> Self {
        Self {
            dir: out.join(JOURNAL_DIR),
        }
    }

    fn campaign(meta: &RunMeta) -> serde_json::Value {
        let mut v = serde_json::to_value(meta).unwrap_or_default();
        if let Some(m) = v.as_object_mut() {
            m.remove("command");
        }
        v
    }

    /// Create the journal for the campaign of `meta`, or open the one there:
    /// the trials it holds, by campaign index.
    ///
    /// # Errors
    /// A journal of another campaign (suite, seed, settings, revision...), a
    /// malformed record, or an I/O failure.
    pub fn open(&self, meta: &RunMeta) -> Result<std::collections::BTreeMap<usize, TrialOutcome>> {
        let head = self.dir.join("campaign.json");
        let want = Self::campaign(meta);
        let mut done = std::collections::BTreeMap::new();
        if head.exists() {
            let text = std::fs::read_to_string(&head)
                .map_err(|e| Error::file(&head, format!("cannot read: {e}")))?;
            let have: serde_json::Value = serde_json::from_str(&text)
                .map_err(|e| Error::file(&head, format!("invalid JSON: {e}")))?;
            if have != want {
                return Err(Error::file(
                    &self.dir,
                    "holds trials of another campaign; remove it or use another --out",
                ));
            }
            let entries = std::fs::read_dir(&self.dir)
                .map_err(|e| Error::file(&self.dir, format!("cannot read: {e}")))?;
            for e in entries.flatten() {
                let path = e.path();
                if path.extension().is_none_or(|x| x != "json") || path == head {
                    continue;
                }
                let text = std::fs::read_to_string(&path)
                    .map_err(|e| Error::file(&path, format!("cannot read: {e}")))?;
                let t: PartTrial = serde_json::from_str(&text)
                    .map_err(|e| Error::file(&path, format!("invalid trial record: {e}")))?;
                let o = t.outcome().map_err(|e| Error::file(&path, e))?;
                done.insert(t.index, o);
            }
        } else {
            std::fs::create_dir_all(&self.dir)
                .map_err(|e| Error::file(&self.dir, format!("cannot create directory: {e}")))?;
            let text = serde_json::to_string_pretty(&want)
                .map_err(|e| Error::msg(format!("cannot encode JSON: {e}")))?;
            eval::write_new(&head, &text, true)?;
        }
        Ok(done)
    }

    /// Record finished trial `index` (a failure to write is reported on
    /// stderr; the trial is then run again by a rerun).
    pub fn record(&self, index: usize, o: &TrialOutcome) {
        let path = self.dir.join(format!("{index}.json"));
        let written = serde_json::to_string(&PartTrial::new(index, o))
            .map_err(|e| Error::msg(format!("cannot encode JSON: {e}")))
            .and_then(|text| eval::write_new(&path, &text, true));
        if let Err(e) = written {
            eprintln!("vtsm: warning: trial {index} not recorded: {e}");
        }
    }
}

/// A part as read back: its record and the run's meta.
struct Part {
    dir: PathBuf,
    rec: PartRecord,
    meta: RunMeta,
}

fn read_part(dir: &Path) -> Result<Part> {
    let path = dir.join(PART_FILE);
    let text = std::fs::read_to_string(&path)
        .map_err(|e| Error::file(dir, format!("not a part (cannot read {PART_FILE}: {e})")))?;
    let rec: PartRecord = serde_json::from_str(&text)
        .map_err(|e| Error::file(&path, format!("invalid part record: {e}")))?;
    let spath = dir.join("summary.json");
    let text = std::fs::read_to_string(&spath)
        .map_err(|e| Error::file(&spath, format!("cannot read: {e}")))?;
    let json: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| Error::file(&spath, format!("invalid JSON: {e}")))?;
    let m = &json["meta"];
    let meta = RunMeta {
        suite: m["suite"].as_str().unwrap_or_default().to_string(),
        git_revision: m["git_revision"].as_str().unwrap_or_default().to_string(),
        profile: m["profile"].as_str().unwrap_or_default().to_string(),
        seed: m["seed"].as_u64().unwrap_or_default(),
        trials: m["trials"].as_u64().unwrap_or_default() as usize,
        physical: m["physical"].as_bool().unwrap_or_default(),
        params: m["params"].clone(),
        command: m["command"].as_str().unwrap_or_default().to_string(),
    };
    let same = (&meta.suite, &meta.profile, meta.seed, meta.trials)
        == (&rec.suite, &rec.profile, rec.seed, rec.trials)
        && meta.git_revision == rec.git_revision;
    if !same {
        return Err(Error::file(
            dir,
            "summary.json and part.json describe different campaigns",
        ));
    }
    if rec.indices.len() != rec.outcomes.len()
        || rec
            .indices
            .iter()
            .zip(&rec.outcomes)
            .any(|(i, o)| *i != o.index)
    {
        return Err(Error::file(&path, "indices and trials do not match"));
    }
    Ok(Part {
        dir: dir.to_path_buf(),
        rec,
        meta,
    })
}

/// Check that `parts` make one whole campaign; its outcomes in campaign order.
fn check_parts(parts: &[Part]) -> Result<Vec<TrialOutcome>> {
    let first = parts
        .first()
        .ok_or_else(|| Error::msg("merge needs at least one part"))?;
    let f = &first.rec;
    for p in parts {
        let r = &p.rec;
        let differ = |what: &str, a: &dyn fmt::Display, b: &dyn fmt::Display| {
            Error::file(
                &p.dir,
                format!("{what} {a} differs from {b} of {}", first.dir.display()),
            )
        };
        if r.suite != f.suite {
            return Err(differ("suite", &r.suite, &f.suite));
        }
        if r.profile != f.profile {
            return Err(differ("profile", &r.profile, &f.profile));
        }
        if r.seed != f.seed {
            return Err(differ("seed", &r.seed, &f.seed));
        }
        if r.trials != f.trials || r.total != f.total {
            return Err(differ("trial count", &r.total, &f.total));
        }
        if r.git_revision != f.git_revision {
            return Err(differ("revision", &r.git_revision, &f.git_revision));
        }
        if p.meta.params != first.meta.params || p.meta.physical != first.meta.physical {
            return Err(Error::file(
                &p.dir,
                format!("settings differ from those of {}", first.dir.display()),
            ));
        }
    }
    let mut slots: Vec<Option<TrialOutcome>> = vec![None; f.total];
    for p in parts {
        for t in &p.rec.outcomes {
            let slot = slots.get_mut(t.index).ok_or_else(|| {
                Error::file(
                    &p.dir,
                    format!("trial {} is outside the campaign's {}", t.index, f.total),
                )
            })?;
            if slot.is_some() {
                return Err(Error::file(
                    &p.dir,
                    format!("trial {} is held by an earlier part too", t.index),
                ));
            }
            *slot = Some(t.outcome().map_err(|e| Error::file(&p.dir, e))?);
        }
    }
    let missing: Vec<usize> = (0..slots.len()).filter(|&i| slots[i].is_none()).collect();
    if let Some(&i) = missing.first() {
        return Err(Error::file(
            &first.dir,
            format!(
                "the parts miss {} of the campaign's {} trials (first: trial {i})",
                missing.len(),
                f.total
            ),
        ));
    }
    Ok(slots.into_iter().flatten().collect())
}

/// The config the figures and notes of the merged run are drawn with.
fn merged_config(part: &Part) -> Result<SuiteConfig> {
    let mut cfg = replot::recorded_config(&part.dir.join("summary.json"))?;
    if let Some(s) = part.meta.params["steps"].as_array() {
        cfg.steps = s
            .iter()
            .filter_map(|v| v.as_u64())
            .map(|v| v as usize)
            .collect();
    }
    if let Some(k) = part.meta.params["seeds_k"].as_u64() {
        cfg.seeds_k = k as u16;
    }
    cfg.baseline = part.meta.params["baseline"]
        .as_str()
        .filter(|b| *b == Method::Features.name())
        .map(|_| Method::Features);
    Ok(cfg)
}

/// `vtsm eval merge`: check the parts in `dirs` belong together and cover the
/// campaign, then write the single run's outputs into `out`; the files
/// written. Nothing is written when a check fails.
///
/// # Errors
/// A part that cannot be read, parts of different campaigns (suite, profile,
/// seed, trial count, revision, settings), a trial held twice or missing, an
/// existing non-empty `out` without `force`, or an I/O failure.
pub fn merge(out: &Path, dirs: &[PathBuf], force: bool, command: &str) -> Result<()> {
    let parts = dirs
        .iter()
        .map(|d| read_part(d))
        .collect::<Result<Vec<_>>>()?;
    let outcomes = check_parts(&parts)?;
    let first = &parts[0];
    let cfg = merged_config(first)?;
    if !force
        && std::fs::read_dir(out)
            .map(|mut d| d.next().is_some())
            .unwrap_or(false)
    {
        return Err(Error::file(out, "exists and is not empty; pass --force"));
    }
    let meta = RunMeta {
        command: command.to_string(),
        ..first.meta.clone()
    };
    let total = outcomes.len();
    let run = super::run::finish(
        &cfg,
        meta,
        outcomes,
        ((0..total).collect(), total),
        (0.0, 0.0),
    );
    std::fs::create_dir_all(out)
        .map_err(|e| Error::file(out, format!("cannot create directory: {e}")))?;
    print!("{}", eval::markdown_table(&run.meta, &run.groups));
    print!("{}", run.notes);
    write_run(out, &run, force)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_split_the_indices() {
        let s = Shard::parse("1/3").unwrap();
        assert_eq!(s.to_string(), "1/3");
        let held: Vec<usize> = (0..7).filter(|&i| s.holds(i)).collect();
        assert_eq!(held, [1, 4]);
        for bad in ["3/3", "4/3", "3", "a/b", "0/0", "1/0"] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn a_trial_record_gives_the_outcome_back() {
        let o = TrialOutcome {
            group: "cfa2 Δ3h".into(),
            method: "vtsm".into(),
            trial: 1,
            seed: 77,
            success: false,
            failure: Some("E_X".into()),
            init_t_mm: 123.456,
            init_r_deg: 0.1,
            final_t_mm: f64::NAN,
            final_r_deg: f64::INFINITY,
            inliers: 3,
            iterations: 2,
            time_s: 0.5,
            columns: TrialColumns {
                group: Some(GroupColumns::Prior {
                    hours: 3.0,
                    prior_max_m: 0.2,
                    seeds_k: 0,
                    t0_m: 0.2,
                    r0_deg: 1.5,
                }),
                capture: Some(CaptureColumns {
                    stop: 4,
                    look_at: 1,
                }),
                engine: Some(EngineColumns {
                    attempts: 9,
                    pairs: 6,
                    revisited: 4,
                    revisit_pairs: 3,
                    near_drawn: 5,
                    near_pairs: 2,
                    stalls: 1,
                    reseeds: 2,
                    focused_rounds: 3,
                    gradient_rounds: 4,
                    refine_accepted: 5,
                    spread_m: 0.123,
                    reproj_px: 0.7,
                    prior_dt_m: 0.15,
                    prior_dr_deg: 1.1,
                }),
                ..TrialColumns::default()
            },
        };
        let back = PartTrial::new(5, &o).outcome().unwrap();
        assert_eq!(
            eval::csv(std::slice::from_ref(&back)),
            eval::csv(std::slice::from_ref(&o))
        );
        assert_eq!(back.columns, o.columns);
        assert!(back.final_t_mm.is_nan());
    }
}
