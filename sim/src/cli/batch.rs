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

use crate::error::{Error, Result, EXIT_RELOC_FAILED};
use crate::io;
use crate::job::{self, Pair};
pub use crate::job::{PairResult, PairSpec};
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// What a batch did.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    /// One line per pair, in input order.
    pub results: Vec<PairResult>,
    /// Times the map product was loaded (read, or built): 1.
    pub map_loads: usize,
    /// Checks of the map product over the batch: 1 (the job's; the runner
    /// uses the checked view for every pair).
    pub map_checks: u32,
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

/// Run a batch: read the pairs of `pairs`, then run them as one job
/// ([`job::run`]: the map loaded and checked once), `seed` the seed of every
/// pair that names none, `out` the results file (without it each line goes
/// to stdout as its pair ends). `progress` shows a bar on stderr.
///
/// # Errors
/// Bad input of the batch itself (see the module doc); per-pair problems are
/// in the returned lines.
pub fn run_batch(
    spec: &job::Spec,
    seed: u64,
    pairs: &Path,
    out: Option<&Path>,
    progress: bool,
) -> Result<Summary> {
    if let Some(out) = out {
        io::check_output(out, spec.force)?;
    }
    let entries = read_entries(pairs)?;
    let bar = crate::progress::Progress::new(entries.len() as u64, 0, "pairs", progress);
    let jobs: Vec<std::result::Result<Pair, String>> = entries
        .iter()
        .map(|e| {
            e.spec
                .as_ref()
                .map(|s| s.pair(&e.base, seed))
                .map_err(Clone::clone)
        })
        .collect();
    let id = |i: usize| {
        entries
            .get(i)
            .and_then(|e| e.spec.as_ref().ok()?.id.clone())
    };
    let source = |i: usize| entries.get(i).map(|e| e.source.clone()).unwrap_or_default();
    let summary = job::run(spec, &jobs, |i, r| {
        if out.is_none() {
            let line = PairResult::of(i, source(i), id(i), r, 0.0);
            let text = serde_json::to_string(&line).unwrap_or_default();
            bar.suspend(|| {
                let mut so = std::io::stdout().lock();
                let _ = writeln!(so, "{text}");
                let _ = so.flush();
            });
        }
        bar.inc();
    })?;
    bar.finish();
    let results = summary
        .pairs
        .iter()
        .enumerate()
        .map(|(i, (r, t))| PairResult::of(i, source(i), id(i), r, *t))
        .collect();
    Ok(Summary {
        results,
        map_loads: summary.map_loads,
        map_checks: summary.map_checks,
        map_load_s: summary.map_load_s,
        pairs_s: summary.pairs_s,
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

/// Run `vtsm relocalize --pairs` ([`run_batch`]), write the results to
/// `out` or stdout and the summary line to stderr; returns the exit code.
///
/// # Errors
/// Bad input of the batch itself (exit code 2 at the command line).
pub fn run(spec: &job::Spec, seed: u64, pairs: &Path, out: Option<&Path>) -> Result<u8> {
    let summary = run_batch(spec, seed, pairs, out, true)?;
    if let Some(out) = out {
        io::write_atomic(out, results_text(&summary.results).as_bytes(), spec.force)?;
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
