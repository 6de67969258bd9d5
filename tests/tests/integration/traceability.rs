//! Traceability: every requirement verified by test is named by a test tag,
//! and every tag names a real requirement.
//!
//! Reads every `fsw-docs/requirements/*.md` (any area) and every `.rs` file of
//! the workspace, so new requirement files and new tests are covered as they land.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::collections::{BTreeMap, BTreeSet};
use vtsm_tests::{
    is_requirement_id, parse_requirements, parse_tags, rust_files, workspace_root, Requirement, Tag,
};

const METHODS: [&str; 4] = ["Test", "Analysis", "Inspection", "Demonstration"];

fn requirements() -> Vec<Requirement> {
    let dir = workspace_root().join("fsw-docs/requirements");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    files.sort();
    assert!(
        !files.is_empty(),
        "no requirement files in {}",
        dir.display()
    );
    let mut out = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        out.extend(parse_requirements(&f, &text));
    }
    out
}

fn tags() -> Vec<Tag> {
    let root = workspace_root();
    let mut out = Vec::new();
    for f in rust_files(&root) {
        let text = std::fs::read_to_string(&f).unwrap();
        out.extend(parse_tags(f.strip_prefix(&root).unwrap_or(&f), &text));
    }
    out
}

#[test]
fn requirements_are_well_formed_and_unique() {
    let reqs = requirements();
    let mut seen: BTreeMap<&str, &Requirement> = BTreeMap::new();
    let mut bad = Vec::new();
    for r in &reqs {
        if !is_requirement_id(&r.id) {
            bad.push(format!(
                "{}:{}: malformed ID {}",
                r.file.display(),
                r.line,
                r.id
            ));
        }
        if !METHODS.contains(&r.verification.as_str()) {
            bad.push(format!(
                "{}:{}: {} has verification {:?}, expected one of {METHODS:?}",
                r.file.display(),
                r.line,
                r.id,
                r.verification
            ));
        }
        if let Some(prev) = seen.insert(&r.id, r) {
            bad.push(format!(
                "{}:{}: {} already defined at {}:{}",
                r.file.display(),
                r.line,
                r.id,
                prev.file.display(),
                prev.line
            ));
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

#[test]
fn every_test_requirement_is_named_by_a_tag() {
    let tagged: BTreeSet<String> = tags().into_iter().map(|t| t.id).collect();
    let untested: Vec<String> = requirements()
        .into_iter()
        .filter(|r| r.verification == "Test" && !tagged.contains(&r.id))
        .map(|r| format!("{}:{}: {}", r.file.display(), r.line, r.id))
        .collect();
    assert!(
        untested.is_empty(),
        "requirements with Verification = Test that no test names:\n{}",
        untested.join("\n")
    );
}

#[test]
fn every_tag_names_a_real_requirement() {
    let known: BTreeSet<String> = requirements().into_iter().map(|r| r.id).collect();
    let dangling: Vec<String> = tags()
        .into_iter()
        .filter(|t| !known.contains(&t.id))
        .map(|t| format!("{}:{}: {}", t.file.display(), t.line, t.id))
        .collect();
    assert!(
        dangling.is_empty(),
        "tags naming no requirement:\n{}",
        dangling.join("\n")
    );
}
