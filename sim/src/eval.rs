//! Evaluation plumbing: run trials in parallel (one relocalization per thread,
//! each single-threaded and deterministic), aggregate them by group, and write
//! the results as a Markdown table, CSV and JSON (the figures are drawn by
//! [`crate::cli::eval::plot`]).
//!
//! The suites themselves (which trials, which parameters) live in
//! [`crate::cli::eval`]; this module knows nothing of terrains or cameras, only
//! of [`TrialOutcome`]s and their typed [`columns`].

pub mod columns;

use crate::error::{Error, Result};
use columns::TrialColumns;
use rayon::prelude::*;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// What one trial produced.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrialOutcome {
    /// Group label (a row of the table), e.g. `"flagstone Δ6h"`.
    pub group: String,
    /// Relocalization method: `"vtsm"` or a baseline's name (`"features"`).
    pub method: String,
    /// Trial index within the suite.
    pub trial: usize,
    /// Seed of the trial (scene, perturbation and relocalization).
    pub seed: u64,
    /// Relocalization reported success (all iterations updated the pose).
    pub success: bool,
    /// Failure code name when it did not.
    pub failure: Option<String>,
    /// Initial translation error, mm.
    pub init_t_mm: f64,
    /// Initial rotation error, degrees.
    pub init_r_deg: f64,
    /// Final translation error, mm.
    pub final_t_mm: f64,
    /// Final rotation error, degrees.
    pub final_r_deg: f64,
    /// RANSAC inliers of the last update.
    pub inliers: u32,
    /// Successful iterations.
    pub iterations: u32,
    /// Wall time of the relocalization alone, seconds.
    pub time_s: f64,
    /// The columns beyond these (group settings, capture, nearest mapping
    /// view, work counters, ...), typed; `extra` in `summary.json`.
    #[serde(rename = "extra")]
    pub columns: TrialColumns,
}

/// Aggregate of one group.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GroupSummary {
    /// Group label.
    pub group: String,
    /// Trials run.
    pub trials: usize,
    /// Trials that reported success.
    pub successes: usize,
    /// successes / trials, percent.
    pub success_pct: f64,
    /// Mean initial translation error, mm.
    pub init_t_mm_mean: f64,
    /// Median final translation error over successful trials, mm (NaN if none).
    pub final_t_mm_median: f64,
    /// Mean final translation error over successful trials, mm (NaN if none).
    pub final_t_mm_mean: f64,
    /// Median final rotation error over successful trials, degrees (NaN if none).
    pub final_r_deg_median: f64,
    /// The tail of the final translation error over successful trials, mm
    /// (NaN if none): 90th and 95th percentile (linear between order
    /// statistics) and the largest.
    pub final_t_mm_p90: f64,
    /// 95th percentile, mm.
    pub final_t_mm_p95: f64,
    /// Largest, mm.
    pub final_t_mm_max: f64,
    /// Mean final rotation error over successful trials, degrees.
    pub final_r_deg_mean: f64,
    /// 90th percentile of the final rotation error, degrees.
    pub final_r_deg_p90: f64,
    /// 95th percentile of the final rotation error, degrees.
    pub final_r_deg_p95: f64,
    /// Largest final rotation error, degrees.
    pub final_r_deg_max: f64,
    /// Successful trials with a covariance whose true translation error lies
    /// inside its 95 % ellipsoid (`d² ≤ χ²₃(0.95)`, extra `cov_d2_t`), percent
    /// of those with a covariance (NaN if none).
    pub cov_t_within_pct: f64,
    /// The same for the rotation error (column `cov_d2_r`), percent.
    pub cov_r_within_pct: f64,
    /// Successful trials that had a covariance.
    pub cov_trials: usize,
    /// Mean relocalization time, seconds.
    pub time_s_mean: f64,
}

/// Facts that make a run reproducible, recorded with every output.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunMeta {
    /// Suite name.
    pub suite: String,
    /// Git revision of the source tree (or `"unknown"`).
    pub git_revision: String,
    /// Image profile.
    pub profile: String,
    /// Base seed.
    pub seed: u64,
    /// Trials per group.
    pub trials: usize,
    /// Whether the live pairs were physical (distorted, rotated cameras with
    /// an OpenCV calibration), rectified on the host before relocalization.
    pub physical: bool,
    /// Relocalization parameters and suite settings.
    pub params: serde_json::Value,
    /// The command line that produced the run.
    pub command: String,
}

/// Run `run` on every spec in parallel across cores. Results come back in
/// spec order, whatever the scheduling, so outputs are reproducible.
pub fn run_parallel<T, F>(specs: &[T], run: F) -> Vec<TrialOutcome>
where
    T: Sync,
    F: Fn(&T) -> TrialOutcome + Sync,
{
    specs.par_iter().map(&run).collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// `q`-quantile (0..=1) of `v`, linear between order statistics (NaN if empty).
pub fn quantile(mut v: Vec<f64>, q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let pos = q.clamp(0.0, 1.0) * (v.len() - 1) as f64;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    let (a, b) = (v[lo], v[hi.min(v.len() - 1)]);
    a + (b - a) * (pos - lo as f64)
}

/// χ²₃ at 0.95: the squared Mahalanobis radius of a 3-D 95 % ellipsoid.
pub const CHI2_3_95: f64 = 7.814_727_903_251_178;

/// Percent of the finite values of `d2` at or below [`CHI2_3_95`], and their count.
fn within_95(d2: &[f64]) -> (f64, usize) {
    let v: Vec<f64> = d2.iter().copied().filter(|x| x.is_finite()).collect();
    let n = v.len();
    let inside = v.iter().filter(|&&x| x <= CHI2_3_95).count();
    let pct = if n == 0 {
        f64::NAN
    } else {
        100.0 * inside as f64 / n as f64
    };
    (pct, n)
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        f64::NAN
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

/// Aggregate outcomes by group, groups in order of first appearance.
pub fn summarize(outcomes: &[TrialOutcome]) -> Vec<GroupSummary> {
    let mut order: Vec<&str> = Vec::new();
    for o in outcomes {
        if !order.contains(&o.group.as_str()) {
            order.push(&o.group);
        }
    }
    order
        .into_iter()
        .map(|g| {
            let rows: Vec<&TrialOutcome> = outcomes.iter().filter(|o| o.group == g).collect();
            let ok: Vec<&&TrialOutcome> = rows.iter().filter(|o| o.success).collect();
            let final_t: Vec<f64> = ok.iter().map(|o| o.final_t_mm).collect();
            let final_r: Vec<f64> = ok.iter().map(|o| o.final_r_deg).collect();
            let d2 = |f: fn(&columns::CovarianceColumns) -> f64| -> Vec<f64> {
                ok.iter()
                    .map(|o| o.columns.covariance.as_ref().map_or(f64::NAN, f))
                    .collect()
            };
            let (cov_t, cov_n) = within_95(&d2(|c| c.d2_t));
            let (cov_r, _) = within_95(&d2(|c| c.d2_r));
            GroupSummary {
                group: g.to_string(),
                trials: rows.len(),
                successes: ok.len(),
                success_pct: 100.0 * ok.len() as f64 / rows.len().max(1) as f64,
                init_t_mm_mean: mean(&rows.iter().map(|o| o.init_t_mm).collect::<Vec<_>>()),
                final_t_mm_median: median(final_t.clone()),
                final_t_mm_mean: mean(&final_t),
                final_r_deg_median: median(final_r.clone()),
                final_t_mm_p90: quantile(final_t.clone(), 0.90),
                final_t_mm_p95: quantile(final_t.clone(), 0.95),
                final_t_mm_max: quantile(final_t.clone(), 1.0),
                final_r_deg_mean: mean(&final_r),
                final_r_deg_p90: quantile(final_r.clone(), 0.90),
                final_r_deg_p95: quantile(final_r.clone(), 0.95),
                final_r_deg_max: quantile(final_r, 1.0),
                cov_t_within_pct: cov_t,
                cov_r_within_pct: cov_r,
                cov_trials: cov_n,
                time_s_mean: mean(&rows.iter().map(|o| o.time_s).collect::<Vec<_>>()),
            }
        })
        .collect()
}

fn num(v: f64, decimals: usize) -> String {
    if v.is_finite() {
        format!("{v:.decimals$}")
    } else {
        "—".to_string()
    }
}

/// The Markdown table printed to the terminal and saved as `table.md`.
pub fn markdown_table(meta: &RunMeta, rows: &[GroupSummary]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "suite `{}` · rev `{}` · profile `{}` · seed {} · {} trials per group · {} pairs",
        meta.suite,
        meta.git_revision,
        meta.profile,
        meta.seed,
        meta.trials,
        if meta.physical {
            "physical (rectified on the host)"
        } else {
            "rectified"
        }
    );
    s.push('\n');
    s.push_str("| group | trials | success | initial error (mm, mean) | final error (mm, median) | final error (mm, mean) | final rotation (°, median) | time (s, mean) |\n");
    s.push_str("|---|---:|---:|---:|---:|---:|---:|---:|\n");
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.0} % | {} | {} | {} | {} | {} |",
            r.group,
            r.trials,
            r.success_pct,
            num(r.init_t_mm_mean, 0),
            num(r.final_t_mm_median, 1),
            num(r.final_t_mm_mean, 1),
            num(r.final_r_deg_median, 3),
            num(r.time_s_mean, 2)
        );
    }
    s.push_str(&tail_table(rows));
    s
}

/// The tail of the final error per group (successful trials), and how often
/// the reported covariance's 95 % ellipsoid holds the true error.
pub fn tail_table(rows: &[GroupSummary]) -> String {
    let mut s = String::from(
        "\nTail of the final error (successful trials) and covariance check (true error inside the reported 95 % ellipsoid, d² ≤ χ²₃(0.95) = 7.81):\n\n| group | t median (mm) | t p90 | t p95 | t max | r median (°) | r mean | r p95 | r max | inside 95 %: t | inside 95 %: r | with covariance |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    let pct = |v: f64| {
        if v.is_finite() {
            format!("{v:.0} %")
        } else {
            "—".to_string()
        }
    };
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.group,
            num(r.final_t_mm_median, 1),
            num(r.final_t_mm_p90, 1),
            num(r.final_t_mm_p95, 1),
            num(r.final_t_mm_max, 1),
            num(r.final_r_deg_median, 3),
            num(r.final_r_deg_mean, 3),
            num(r.final_r_deg_p95, 3),
            num(r.final_r_deg_max, 3),
            pct(r.cov_t_within_pct),
            pct(r.cov_r_within_pct),
            r.cov_trials
        );
    }
    s
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// Per-trial CSV, one row per trial; the [`TrialColumns`] set in any trial
/// become columns (sorted by name).
pub fn csv(outcomes: &[TrialOutcome]) -> String {
    let entries: Vec<Vec<(&'static str, f64)>> =
        outcomes.iter().map(|o| o.columns.entries()).collect();
    let mut keys: Vec<&'static str> = entries.iter().flatten().map(|e| e.0).collect();
    keys.sort_unstable();
    keys.dedup();
    let mut s = String::from(
        "group,method,trial,seed,success,failure,init_t_mm,init_r_deg,final_t_mm,final_r_deg,inliers,iterations,time_s",
    );
    for k in &keys {
        s.push(',');
        s.push_str(&csv_field(k));
    }
    s.push('\n');
    for (o, set) in outcomes.iter().zip(&entries) {
        let _ = write!(
            s,
            "{},{},{},{},{},{},{:.3},{:.4},{:.3},{:.4},{},{},{:.4}",
            csv_field(&o.group),
            csv_field(&o.method),
            o.trial,
            o.seed,
            o.success,
            o.failure.as_deref().unwrap_or(""),
            o.init_t_mm,
            o.init_r_deg,
            o.final_t_mm,
            o.final_r_deg,
            o.inliers,
            o.iterations,
            o.time_s
        );
        for k in &keys {
            let _ = write!(
                s,
                ",{}",
                set.iter()
                    .find(|e| e.0 == *k)
                    .map(|e| format!("{:.4}", e.1))
                    .unwrap_or_default()
            );
        }
        s.push('\n');
    }
    s
}

/// Write `table.md`, `trials.csv`, `summary.json` (meta + groups + trials) into
/// `dir`, creating it. Existing files are replaced only when `force` is set.
///
/// # Errors
/// An existing output without `force`, or an I/O failure, naming the file.
pub fn write_outputs(
    dir: &Path,
    meta: &RunMeta,
    rows: &[GroupSummary],
    outcomes: &[TrialOutcome],
    force: bool,
) -> Result<()> {
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::file(dir, format!("cannot create directory: {e}")))?;
    let json = serde_json::json!({ "meta": meta, "groups": rows, "trials": outcomes });
    let json = serde_json::to_string_pretty(&json)
        .map_err(|e| Error::msg(format!("cannot encode JSON: {e}")))?;
    write_new(&dir.join("table.md"), &markdown_table(meta, rows), force)?;
    write_new(&dir.join("trials.csv"), &csv(outcomes), force)?;
    write_new(&dir.join("summary.json"), &json, force)
}

/// Write `text` to `path` through a temporary file and a rename, so a reader
/// never sees half a file; refuse to replace an existing file unless `force`.
///
/// # Errors
/// The file exists and `force` is not set, or an I/O failure, naming the file.
pub fn write_new(path: &Path, text: &str, force: bool) -> Result<()> {
    write_bytes_new(path, text.as_bytes(), force)
}

/// Byte form of [`write_new`].
///
/// # Errors
/// As [`write_new`].
pub fn write_bytes_new(path: &Path, bytes: &[u8], force: bool) -> Result<()> {
    if path.exists() && !force {
        return Err(Error::file(path, "exists; pass --force to overwrite"));
    }
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".partial");
    let tmp = std::path::PathBuf::from(tmp);
    std::fs::write(&tmp, bytes).map_err(|e| Error::file(&tmp, format!("cannot write: {e}")))?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::file(path, format!("cannot write: {e}"))
    })
}

/// The git revision the binary was built from (`VTSM_GIT_REV` at build time),
/// else the current checkout's, else `"unknown"`.
pub fn git_revision() -> String {
    if let Some(r) = option_env!("VTSM_GIT_REV") {
        return r.to_string();
    }
    std::process::Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "unknown".to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outcome(group: &str, trial: usize, success: bool, final_t_mm: f64) -> TrialOutcome {
        TrialOutcome {
            group: group.into(),
            method: "vtsm".into(),
            trial,
            seed: trial as u64,
            success,
            failure: (!success).then(|| "RELOC_STALL_CAP_REACHED".into()),
            init_t_mm: 150.0,
            init_r_deg: 1.0,
            final_t_mm,
            final_r_deg: 0.1,
            inliers: 40,
            iterations: 5,
            time_s: 2.0,
            columns: TrialColumns {
                view: Some(columns::ViewColumns {
                    dist_m: 1.5,
                    angle_deg: 2.0,
                }),
                ..TrialColumns::default()
            },
        }
    }

    #[test]
    fn summarizes_by_group_in_order_with_success_only_errors() {
        let o = vec![
            outcome("b", 0, true, 10.0),
            outcome("a", 1, true, 30.0),
            outcome("b", 2, false, 900.0),
            outcome("b", 3, true, 20.0),
        ];
        let s = summarize(&o);
        assert_eq!(s.len(), 2);
        assert_eq!(s[0].group, "b");
        assert_eq!((s[0].trials, s[0].successes), (3, 2));
        assert!((s[0].success_pct - 200.0 / 3.0).abs() < 1e-9);
        assert_eq!(s[0].final_t_mm_median, 15.0);
        assert_eq!(s[1].final_t_mm_mean, 30.0);
        // Tail over the two successes of "b" (10, 20): linear quantiles, max.
        assert!((s[0].final_t_mm_p90 - 19.0).abs() < 1e-9);
        assert!((s[0].final_t_mm_p95 - 19.5).abs() < 1e-9);
        assert_eq!(s[0].final_t_mm_max, 20.0);
        assert!(s[0].cov_t_within_pct.is_nan() && s[0].cov_trials == 0);
        let md = markdown_table(
            &RunMeta {
                suite: "t".into(),
                git_revision: "r".into(),
                profile: "test".into(),
                seed: 1,
                trials: 3,
                physical: true,
                params: serde_json::Value::Null,
                command: "x".into(),
            },
            &s,
        );
        assert!(md.contains("| b | 3 | 67 % |"), "{md}");
        assert!(
            md.lines()
                .next()
                .is_some_and(|l| l.ends_with("· physical (rectified on the host) pairs")),
            "{md}"
        );
        let c = csv(&o);
        assert_eq!(c.lines().count(), 5);
        assert!(c
            .lines()
            .next()
            .unwrap()
            .ends_with(",view_angle_deg,view_dist_m"));
    }

    /// Verifies: VTSM-CLI-034
    #[test]
    fn tail_quantiles_and_covariance_coverage_per_group() {
        let mut o: Vec<TrialOutcome> = (0..21).map(|i| outcome("g", i, true, i as f64)).collect();
        // d² of 0..20 against 7.81: 8 of 21 inside (0..=7).
        for (i, t) in o.iter_mut().enumerate() {
            t.columns.covariance = Some(columns::CovarianceColumns {
                d2_t: i as f64,
                d2_r: 0.5,
                sigma_t_mm: 1.0,
                sigma_r_deg: 0.1,
            });
        }
        o.push(outcome("g", 21, false, 1000.0));
        let s = summarize(&o);
        assert_eq!(s[0].final_t_mm_median, 10.0);
        assert!((s[0].final_t_mm_p90 - 18.0).abs() < 1e-9);
        assert!((s[0].final_t_mm_p95 - 19.0).abs() < 1e-9);
        assert_eq!(s[0].final_t_mm_max, 20.0);
        assert_eq!(s[0].cov_trials, 21);
        assert!((s[0].cov_t_within_pct - 800.0 / 21.0).abs() < 1e-9);
        assert_eq!(s[0].cov_r_within_pct, 100.0);
        let t = tail_table(&s);
        assert!(t.contains("| g | 10.0 | 18.0 | 19.0 | 20.0 |"), "{t}");
    }

    #[test]
    fn parallel_runner_keeps_spec_order() {
        let specs: Vec<usize> = (0..50).collect();
        let out = run_parallel(&specs, |&i| outcome("g", i, i % 2 == 0, i as f64));
        assert!(out.iter().enumerate().all(|(i, o)| o.trial == i));
    }

    #[test]
    fn write_new_refuses_to_overwrite_without_force() {
        let dir = std::env::temp_dir().join(format!("vtsm-eval-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("x.txt");
        let _ = std::fs::remove_file(&p);
        write_new(&p, "one", false).unwrap();
        assert!(write_new(&p, "two", false).is_err());
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "one");
        write_new(&p, "three", true).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "three");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
