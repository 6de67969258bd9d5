//! End-to-end and traceability tests for VTSM live in `tests/tests/`.
//!
//! This library holds what those tests share with the `failure_table` tool:
//! the generator of `fsw-docs/failure-codes.md` and the parsers of the
//! requirement tables and `Verifies:` tags; the seeded mutation fuzzer
//! ([`fuzz`]) run by `tests/tests/integration/fuzz_smoke.rs` and the `fuzz` tool; the
//! core's test kit ([`testkit`]) and the flight-path scene built on it
//! ([`scene`]); and the upset campaign ([`upsets`]).

pub mod fuzz;

pub mod scene;

// The core's shared test scene (`core/testkit/testkit.rs`), compiled here once
// for the tests, the fuzz corpus and the upset campaign.
#[path = "../../core/testkit/testkit.rs"]
pub mod testkit;

pub mod upsets;

use std::path::{Path, PathBuf};
use vtsm_core::failure::{Retry, Severity};
use vtsm_core::FailureCode;

/// Root of the workspace (parent of this crate's directory).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

/// Severity as written in the table.
pub fn severity_str(s: Severity) -> &'static str {
    match s {
        Severity::Info => "Info",
        Severity::Degraded => "Degraded",
        Severity::Fatal => "Fatal",
    }
}

/// Retry hint as written in the table.
pub fn retry_str(r: Retry) -> &'static str {
    match r {
        Retry::Same => "Same",
        Retry::NewInput => "NewInput",
        Retry::Never => "Never",
    }
}

/// Code as written in the table: `0x0301`.
pub fn code_str(c: FailureCode) -> String {
    format!("0x{:04X}", c.code())
}

/// The whole text of `fsw-docs/failure-codes.md`, generated from [`FailureCode::ALL`].
pub fn failure_table_markdown() -> String {
    let mut s = String::new();
    s.push_str("# Failure codes\n\n");
    s.push_str(
        "Generated from `vtsm_core::FailureCode::ALL` by\n\
         `cargo run -p vtsm-tests --bin failure_table > fsw-docs/failure-codes.md`;\n\
         do not edit by hand. `tests/tests/integration/failure_codes.rs` checks this table\n\
         against the enum in both directions.\n\n\
         Groups (high byte): 0x01 config, 0x02 image, 0x03 map, 0x04 raster, 0x05 ncc,\n\
         0x06 stereo, 0x07 pose, 0x08 reloc, 0x09 hardware (HAL), 0x0A C interface. Zero is never an error.\n\n\
         Severity: Info = expected, counted only; Degraded = one attempt or iteration lost;\n\
         Fatal = no pose from these inputs. Retry: Same = retry with the same inputs;\n\
         NewInput = only with new inputs; Never = fix configuration or data.\n\n",
    );
    s.push_str("| Code | Name | Severity | Retry | Description |\n");
    s.push_str("|---|---|---|---|---|\n");
    for &c in FailureCode::ALL {
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} |\n",
            code_str(c),
            c.name(),
            severity_str(c.severity()),
            retry_str(c.retry()),
            c.description().replace('|', "\\|")
        ));
    }
    s
}

/// Split a Markdown table row into trimmed cells (`None` if not a row).
pub fn table_cells(line: &str) -> Option<Vec<String>> {
    let t = line.trim();
    if !t.starts_with('|') || !t.ends_with('|') || t.len() < 2 {
        return None;
    }
    let inner = &t[1..t.len() - 1];
    // Split on unescaped pipes.
    let mut cells = Vec::new();
    let mut cur = String::new();
    let mut prev_backslash = false;
    for ch in inner.chars() {
        if ch == '|' && !prev_backslash {
            cells.push(cur.trim().to_string());
            cur.clear();
        } else {
            cur.push(ch);
        }
        prev_backslash = ch == '\\';
    }
    cells.push(cur.trim().to_string());
    Some(cells)
}

/// One requirement row.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Requirement {
    /// `VTSM-AREA-NNN`.
    pub id: String,
    /// Test / Analysis / Inspection / Demonstration.
    pub verification: String,
    /// File it is defined in.
    pub file: PathBuf,
    /// 1-based line.
    pub line: usize,
}

/// Whether `id` has the form `VTSM-<AREA>-<NNN>` (area upper-case letters, three digits).
pub fn is_requirement_id(id: &str) -> bool {
    let parts: Vec<&str> = id.split('-').collect();
    parts.len() == 3
        && parts[0] == "VTSM"
        && !parts[1].is_empty()
        && parts[1].chars().all(|c| c.is_ascii_uppercase())
        && parts[2].len() == 3
        && parts[2].chars().all(|c| c.is_ascii_digit())
}

/// Parse every requirement row (first cell starts with `VTSM-`) of one file.
pub fn parse_requirements(file: &Path, text: &str) -> Vec<Requirement> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if let Some(cells) = table_cells(line) {
            if cells.first().is_some_and(|c| c.starts_with("VTSM-")) {
                out.push(Requirement {
                    id: cells[0].clone(),
                    verification: cells.last().cloned().unwrap_or_default(),
                    file: file.to_path_buf(),
                    line: i + 1,
                });
            }
        }
    }
    out
}

/// One `Verifies:` tag occurrence.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Tag {
    /// The requirement ID named.
    pub id: String,
    /// File it is in.
    pub file: PathBuf,
    /// 1-based line.
    pub line: usize,
}

/// Parse the `Verifies:` doc-comment lines of one Rust file (a line whose
/// first non-blank characters are three slashes, then `Verifies:` and a
/// comma-separated list of IDs).
pub fn parse_tags(file: &Path, text: &str) -> Vec<Tag> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let Some(rest) = line.trim_start().strip_prefix("///") else {
            continue;
        };
        let Some(list) = rest.trim_start().strip_prefix("Verifies:") else {
            continue;
        };
        for id in list.split(',') {
            let id = id.trim();
            if !id.is_empty() {
                out.push(Tag {
                    id: id.to_string(),
                    file: file.to_path_buf(),
                    line: i + 1,
                });
            }
        }
    }
    out
}

/// Every `.rs` file under `root`, skipping `target/` and hidden directories, sorted.
pub fn rust_files(root: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let Ok(rd) = std::fs::read_dir(&dir) else {
            continue;
        };
        for e in rd.flatten() {
            let p = e.path();
            let name = e.file_name().to_string_lossy().into_owned();
            if p.is_dir() {
                if name != "target" && !name.starts_with('.') {
                    stack.push(p);
                }
            } else if name.ends_with(".rs") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn parsers_read_rows_and_tags() {
        let f = Path::new("x.md");
        let reqs = parse_requirements(
            f,
            "| ID | R | Why | Verification |\n|---|---|---|---|\n| VTSM-AB-001 | a \\| b | c | Test |\ntext\n",
        );
        assert_eq!(reqs.len(), 1);
        assert_eq!(
            (
                reqs[0].id.as_str(),
                reqs[0].verification.as_str(),
                reqs[0].line
            ),
            ("VTSM-AB-001", "Test", 3)
        );
        let src = "    /// Verifies: VTSM-A-001, VTSM-B-002\n// Verifies: VTSM-C-003\nlet s = \"/// Verifies: VTSM-D-004\";\n";
        let tags = parse_tags(Path::new("a.rs"), src);
        let ids: Vec<&str> = tags.iter().map(|t| t.id.as_str()).collect();
        assert_eq!(ids, ["VTSM-A-001", "VTSM-B-002"]);
        assert!(is_requirement_id("VTSM-GEOM-004"));
        assert!(!is_requirement_id("VTSM-geom-004"));
        assert!(!is_requirement_id("VTSM-GEOM-04"));
    }
}

/// The firmware's determinism workload (`tests/firmware/src/workload.rs`),
/// compiled for the host: the same digest and outcome folding as the images.
#[allow(
    dead_code,
    missing_docs,
    clippy::indexing_slicing,
    clippy::new_without_default
)]
pub mod workload {
    use vtsm_core::nalgebra;
    include!("../firmware/src/workload.rs");
}

/// Digest of an outcome as the firmware folds it ([`workload::fold_outcome`]).
pub fn outcome_digest(o: &vtsm_core::reloc::Outcome) -> u64 {
    let mut d = workload::Digest::new();
    workload::fold_outcome(&mut d, o);
    d.0
}
