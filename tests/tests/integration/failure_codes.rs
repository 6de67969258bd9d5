//! The checked-in failure-code table agrees with `FailureCode::ALL` in both directions.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::collections::BTreeMap;
use vtsm_core::FailureCode;
use vtsm_tests::{
    code_str, failure_table_markdown, retry_str, severity_str, table_cells, workspace_root,
};

const TABLE: &str = "fsw-docs/failure-codes.md";

/// Rows of the checked-in table, keyed by the Code cell.
fn table_rows() -> BTreeMap<String, Vec<String>> {
    let path = workspace_root().join(TABLE);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut rows = BTreeMap::new();
    for (i, line) in text.lines().enumerate() {
        let Some(cells) = table_cells(line) else {
            continue;
        };
        let Some(code) = cells.first().cloned() else {
            continue;
        };
        if !code.starts_with("0x") {
            continue;
        }
        assert_eq!(cells.len(), 5, "{TABLE}:{}: expected 5 cells", i + 1);
        let dup = rows.insert(code.clone(), cells);
        assert!(dup.is_none(), "{TABLE}:{}: code {code} listed twice", i + 1);
    }
    rows
}

/// Verifies: VTSM-FAIL-002
#[test]
fn every_code_is_in_the_table_with_its_attributes() {
    let rows = table_rows();
    let mut missing = Vec::new();
    for &c in FailureCode::ALL {
        match rows.get(&code_str(c)) {
            None => missing.push(format!("{} {}", code_str(c), c.name())),
            Some(r) => {
                assert_eq!(r[1], c.name(), "name of {}", code_str(c));
                assert_eq!(r[2], severity_str(c.severity()), "severity of {}", c.name());
                assert_eq!(r[3], retry_str(c.retry()), "retry of {}", c.name());
                assert_eq!(
                    r[4].replace("\\|", "|"),
                    c.description(),
                    "description of {}",
                    c.name()
                );
            }
        }
    }
    assert!(
        missing.is_empty(),
        "codes missing from {TABLE} (regenerate with `cargo run -p vtsm-tests --bin failure_table > {TABLE}`): {missing:?}"
    );
}

/// Verifies: VTSM-FAIL-002
#[test]
fn every_table_row_is_a_code() {
    let mut unknown = Vec::new();
    for (code, cells) in table_rows() {
        let raw = u16::from_str_radix(code.trim_start_matches("0x"), 16).ok();
        match raw.and_then(FailureCode::from_u16) {
            Some(c) => assert_eq!(cells[1], c.name(), "row {code} names another code"),
            None => unknown.push(format!("{code} {}", cells[1])),
        }
    }
    assert!(
        unknown.is_empty(),
        "rows of {TABLE} with no FailureCode: {unknown:?}"
    );
}

/// Verifies: VTSM-FAIL-002
#[test]
fn table_is_exactly_the_generated_text() {
    let text = std::fs::read_to_string(workspace_root().join(TABLE)).unwrap();
    assert!(
        text == failure_table_markdown(),
        "{TABLE} is stale: regenerate with `cargo run -p vtsm-tests --bin failure_table > {TABLE}`"
    );
}
