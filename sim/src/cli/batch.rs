//! `vtsm relocalize --pairs`: many stereo pairs against one map.
//!
//! The map (`--map`, or `--mesh` built in memory) is loaded and checked once;
//! `--calib` is checked once and is the calibration of every pair that does
//! not name its own. The pairs come from a JSON-lines file (one object per
//! non-blank line) or from a directory of `*.json` files (one object each, in
//! file-name order); see `fsw-docs/interfaces/files.md` ("pairs.jsonl"). Paths
//! in a pair are relative to the file that names them.
//!
//! Output: one JSON line per pair, in input order, to stdout or `--out`
//! (written atomically at the end): the result (user-frame pose, inliers,
//! iterations, and the error to `truth` when given) or the failure code and a
//! one-line message. A bad pair (malformed line, missing image, bad prior, an
//! existing `out`) is reported on its own line and counts as failed; it does not
//! stop the batch. Progress goes to stderr, ending with a summary line that
//! counts the map loads.
//!
//! Exit code: 0 every pair succeeded, 1 some pair failed (cleanly or as bad
//! input), 2 the batch itself is bad (pairs file or directory unreadable or
//! empty, bad map or `--calib`, `--out` exists) — then nothing is written.

use super::relocalize::{self, Args};
use crate::error::{Error, Result, EXIT_RELOC_FAILED};
use crate::io::{self, json};
use indicatif::{ProgressBar, ProgressStyle};
use serde::{Deserialize, Serialize};
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// One pair of a batch, as written in `pairs.jsonl`. Its prior file may
/// state the prior's own uncertainty (`prior.json` form).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PairSpec {
    /// Label echoed in the output line (default: the source `file:line`).
    #[serde(default)]
    pub id: Option<String>,
    /// Left image.
    pub left: PathBuf,
    /// Right image.
    pub right: PathBuf,
    /// Prior pose file (`prior.json` form, user frame).
    pub prior: PathBuf,
    /// Calibration of this pair (default: `--calib`).
    #[serde(default)]
    pub calib: Option<PathBuf>,
    /// Truth pose file: adds the final error to the output line.
    #[serde(default)]
    pub truth: Option<PathBuf>,
    /// Also write this pair's `result.json` here (refused if it exists, unless `--force`).
    #[serde(default)]
    pub out: Option<PathBuf>,
    /// Seed of this pair (default: `--seed`).
    #[serde(default)]
    pub seed: Option<u64>,
}

/// One output line of a batch.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PairResult {
    /// Position of the pair in the batch, from 0.
    pub index: usize,
    /// Where the pair was read: `file:line` or the pair file.
    pub source: String,
    /// The pair's `id`, when it had one.
    pub id: Option<String>,
    /// `"ok"`, `"failed"` (clean relocalization failure) or `"error"` (bad pair input).
    pub status: String,
    /// Failure code name, or `null` (success, or a bad input without a code).
    pub failure: Option<String>,
    /// One-line reason when not `"ok"`.
    pub message: Option<String>,
    /// Final estimate in the user frame (the last estimate when failed), or `null`.
    pub world_from_left: Option<json::PoseJson>,
    /// RANSAC inliers of the final estimate.
    pub inliers: u32,
    /// Successful iterations.
    pub iterations: u32,
    /// The prior uncertainty (t̃₀, r̃₀) the engine ran with (the prior's
    /// stated `uncertainty`, else the default); `null` for a bad pair.
    #[serde(default)]
    pub prior_uncertainty: Option<json::UncertaintyJson>,
    /// Translation error to `truth`, mm (when given).
    pub error_t_mm: Option<f64>,
    /// Rotation error to `truth`, degrees (when given).
    pub error_r_deg: Option<f64>,
    /// Wall time of the pair (loading its files and relocalizing), seconds.
    pub time_s: f64,
}

/// What a batch did.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    /// One line per pair, in input order.
    pub results: Vec<PairResult>,
    /// Times the map product was loaded (read and checked, or built): 1.
    pub map_loads: usize,
    /// Wall time of loading the map, seconds.
    pub map_load_s: f64,
    /// Wall time of all pairs, seconds.
    pub pairs_s: f64,
}

impl Summary {
    /// The exit code: 0 all succeeded, 1 some failed.
    pub fn exit_code(&self) -> u8 {
        if self.results.iter().all(|r| r.status == "ok") {
            0
        } else {
            EXIT_RELOC_FAILED
        }
    }

    /// The stderr summary line.
    pub fn line(&self) -> String {
        let n = self.results.len();
        let ok = self.results.iter().filter(|r| r.status == "ok").count();
        format!(
            "batch: {n} pairs ({ok} ok, {} failed) in {:.2} s, {:.3} s per pair; \
             map loaded {} time(s) ({:.2} s)",
            n - ok,
            self.pairs_s,
            self.pairs_s / n.max(1) as f64,
            self.map_loads,
            self.map_load_s
        )
    }
}

/// A pair as read: where from, and the parsed spec or why it could not be parsed.
struct Entry {
    source: String,
    base: PathBuf,
    spec: std::result::Result<PairSpec, String>,
}

fn base_dir(p: &Path) -> PathBuf {
    p.parent().map(Path::to_path_buf).unwrap_or_default()
}

/// Read the pairs of a JSON-lines file or a directory of pair files.
///
/// # Errors
/// The file or directory cannot be read, or holds no pair (bad input of the batch).
fn read_entries(path: &Path) -> Result<Vec<Entry>> {
    let parse = |text: &str| {
        serde_json::from_str::<PairSpec>(text).map_err(|e| format!("invalid pair: {e}"))
    };
    let mut out = Vec::new();
    if path.is_dir() {
        let rd = std::fs::read_dir(path)
            .map_err(|e| Error::file(path, format!("cannot read: {}", io::io_reason(&e))))?;
        let mut files: Vec<PathBuf> = rd
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.is_file() && io::has_extension(p, "json"))
            .collect();
        files.sort();
        for f in files {
            let spec = std::fs::read_to_string(&f)
                .map_err(|e| format!("cannot read: {}", io::io_reason(&e)))
                .and_then(|t| parse(&t));
            out.push(Entry {
                source: f.display().to_string(),
                base: path.to_path_buf(),
                spec,
            });
        }
    } else {
        let bytes = io::read_file(path)?;
        let text = String::from_utf8(bytes)
            .map_err(|_| Error::file(path, "pairs file is not UTF-8 text"))?;
        for (i, line) in text.lines().enumerate() {
            if line.trim().is_empty() {
                continue;
            }
            out.push(Entry {
                source: format!("{}:{}", path.display(), i + 1),
                base: base_dir(path),
                spec: parse(line),
            });
        }
    }
    if out.is_empty() {
        return Err(Error::file(
            path,
            "no pairs (expected JSON lines or *.json pair files)",
        ));
    }
    Ok(out)
}

fn resolve(base: &Path, p: &Path) -> PathBuf {
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        base.join(p)
    }
}

fn failed_line(index: usize, e: &Entry, id: Option<String>, err: &Error) -> PairResult {
    PairResult {
        index,
        source: e.source.clone(),
        id,
        status: "error".to_string(),
        failure: err.code.map(|c| c.name().to_string()),
        message: Some(err.to_string()),
        world_from_left: None,
        inliers: 0,
        iterations: 0,
        prior_uncertainty: None,
        error_t_mm: None,
        error_r_deg: None,
        time_s: 0.0,
    }
}

/// Relocalize one pair against the loaded map, with its own calibration
/// when it names one, else `calib` (the batch's `--calib`, read once).
fn run_pair(
    args: &Args,
    calib: &relocalize::Calibration,
    map: &[u8],
    index: usize,
    e: &Entry,
) -> PairResult {
    let t0 = Instant::now();
    let spec = match &e.spec {
        Ok(s) => s,
        Err(m) => return failed_line(index, e, None, &Error::msg(m.clone())),
    };
    let id = spec.id.clone();
    let r = (|| -> Result<PairResult> {
        let a = Args {
            left: Some(resolve(&e.base, &spec.left)),
            right: Some(resolve(&e.base, &spec.right)),
            prior: Some(resolve(&e.base, &spec.prior)),
            calib: spec
                .calib
                .as_ref()
                .map_or_else(|| args.calib.clone(), |c| resolve(&e.base, c)),
            seed: spec.seed.unwrap_or(args.seed),
            out: spec.out.as_ref().map(|o| resolve(&e.base, o)),
            pairs: None,
            ..args.clone()
        };
        if let Some(out) = &a.out {
            io::check_output(out, args.force)?;
        }
        let truth = spec
            .truth
            .as_ref()
            .map(|t| json::read_user_pose(&resolve(&e.base, t)))
            .transpose()?;
        let own;
        let calib = match &spec.calib {
            Some(_) => {
                own = relocalize::read_calibration(&a.calib, &a.interp)?;
                &own
            }
            None => calib,
        };
        let (outcome, result) = relocalize::relocalize_pair(&a, calib, map.to_vec())?;
        let user = outcome
            .pose
            .as_ref()
            .map(|p| crate::frame::to_user(p, outcome.origin));
        let err = truth
            .as_ref()
            .zip(user.as_ref())
            .map(|(t, u)| crate::frame::error_to(u, t));
        Ok(PairResult {
            index,
            source: e.source.clone(),
            id: id.clone(),
            status: result.status.clone(),
            failure: result.failure.clone(),
            message: outcome.failure.map(|c| c.description().to_string()),
            world_from_left: result.world_from_left,
            inliers: result.inliers,
            iterations: result.iterations,
            prior_uncertainty: result.prior_uncertainty,
            error_t_mm: err.map(|(t, _)| t * 1e3),
            error_r_deg: err.map(|(_, r)| r.to_degrees()),
            time_s: 0.0,
        })
    })();
    let mut line = r.unwrap_or_else(|err| failed_line(index, e, id, &err));
    line.time_s = t0.elapsed().as_secs_f64();
    line
}

/// Run a batch: check the batch's own inputs, load the map once, relocalize
/// every pair in order. `progress` shows a bar on stderr.
///
/// # Errors
/// Bad input of the batch itself (see the module doc); per-pair problems are
/// in the returned lines.
pub fn run_batch(args: &Args, pairs: &Path, progress: bool) -> Result<Summary> {
    relocalize::check_args(args)?;
    if let Some(out) = &args.out {
        io::check_output(out, args.force)?;
    }
    let entries = read_entries(pairs)?;
    // Every form of calibration the single-pair path reads, by the same reader.
    let calib = relocalize::read_calibration(&args.calib, &args.interp)?;
    let t_map = Instant::now();
    let map = relocalize::load_map(args)?;
    let map_load_s = t_map.elapsed().as_secs_f64();
    let map_loads = 1;
    let bar = if progress {
        let b = ProgressBar::new(entries.len() as u64);
        if let Ok(style) = ProgressStyle::with_template(
            "{elapsed_precise} [{bar:40}] {pos}/{len} pairs ({eta} left)",
        ) {
            b.set_style(style.progress_chars("=> "));
        }
        b
    } else {
        ProgressBar::hidden()
    };
    let t_pairs = Instant::now();
    let mut results = Vec::with_capacity(entries.len());
    for (i, e) in entries.iter().enumerate() {
        let line = run_pair(args, &calib, &map, i, e);
        if args.out.is_none() {
            let text = serde_json::to_string(&line).unwrap_or_default();
            bar.suspend(|| {
                let mut so = std::io::stdout().lock();
                let _ = writeln!(so, "{text}");
                let _ = so.flush();
            });
        }
        results.push(line);
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(Summary {
        results,
        map_loads,
        map_load_s,
        pairs_s: t_pairs.elapsed().as_secs_f64(),
    })
}

/// The text of `results.jsonl`: one JSON object per line.
pub fn results_text(results: &[PairResult]) -> String {
    let mut s = String::new();
    for r in results {
        s.push_str(&serde_json::to_string(r).unwrap_or_default());
        s.push('\n');
    }
    s
}

/// Run `vtsm relocalize --pairs`; returns the exit code.
///
/// # Errors
/// Bad input of the batch itself (exit code 2 at the command line).
pub fn run(args: &Args, pairs: &Path) -> Result<u8> {
    let summary = run_batch(args, pairs, true)?;
    if let Some(out) = &args.out {
        io::write_atomic(out, results_text(&summary.results).as_bytes(), args.force)?;
    }
    eprintln!("vtsm: {}", summary.line());
    Ok(summary.exit_code())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// The documented example `pairs.jsonl` parses line by line, and a line
    /// with an unknown key does not.
    ///
    /// Verifies: VTSM-CLI-038
    #[test]
    fn documented_example_pairs_parse() {
        let text = include_str!("../../../fsw-docs/interfaces/examples/pairs.jsonl");
        let pairs: Vec<PairSpec> = text
            .lines()
            .filter(|l| !l.trim().is_empty())
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert!(pairs.len() >= 3);
        assert_eq!(pairs[0].id.as_deref(), Some("stop03-am"));
        assert!(pairs[0].truth.is_some() && pairs[1].seed == Some(7));
        assert!(pairs[2].calib.is_some());
        let bad = r#"{"left":"l.png","right":"r.png","prior":"p.json","colour":1}"#;
        assert!(serde_json::from_str::<PairSpec>(bad).is_err());
    }
}
