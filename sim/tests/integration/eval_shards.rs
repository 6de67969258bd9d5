//! `vtsm eval --shard K/N` and `vtsm eval merge`: a campaign run in parts is
//! the same campaign, and parts that do not make one are refused.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, missing_docs)]

use crate::common::{dir, s, vtsm};
use std::path::Path;

/// `trials.csv` without its `time_s` column (the only timing column).
fn without_time(path: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(path).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let t = header.iter().position(|h| *h == "time_s").unwrap();
    text.lines()
        .map(|l| {
            let mut f: Vec<&str> = l.split(',').collect();
            f.remove(t);
            f.join(",")
        })
        .collect()
}

/// Run the small campaign (flagstone, Δ0h, 3 trials) into `out`.
fn campaign(out: &Path, extra: &[&str]) {
    let mut args = vec![
        "eval",
        "--suite",
        "paper",
        "--profile",
        "test",
        "--trials",
        "3",
        "--terrains",
        "flagstone",
        "--hours",
        "0",
        "--quiet",
        "--out",
        s(out),
    ];
    args.extend_from_slice(extra);
    let o = vtsm(&args);
    assert_eq!(o.status.code(), Some(0), "{o:?}");
}

/// The campaign run as two shards and merged gives the single run's
/// `trials.csv` (but `time_s`), table rows and figures; a part records its
/// shard and indices (index `i` in shard `i mod N + 1`). A part given twice,
/// a missing part or parts of different seeds are refused with exit code 2,
/// one line naming the part, and no output directory.
///
/// Verifies: VTSM-CLI-046
#[test]
fn sharded_campaign_merges_to_the_single_run() {
    let root = dir("eval_shards", "campaign");
    let (full, p1, p2, other) = (
        root.join("full"),
        root.join("p1"),
        root.join("p2"),
        root.join("p2_seed2"),
    );
    campaign(&full, &[]);
    campaign(&p1, &["--shard", "0/2"]);
    campaign(&p2, &["--shard", "1/2"]);
    campaign(&other, &["--shard", "1/2", "--seed", "2"]);

    let part: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(p1.join("part.json")).unwrap()).unwrap();
    assert_eq!(part["shard"], "0/2");
    assert_eq!(part["total"], 3);
    assert_eq!(part["indices"], serde_json::json!([0, 2]));
    assert_eq!(part["suite"], "paper");
    assert_eq!(part["profile"], "test");
    assert_eq!(part["seed"], 1);
    assert_eq!(without_time(&p1.join("trials.csv")).len(), 3);

    let merged = root.join("merged");
    let o = vtsm(&["eval", "merge", "--out", s(&merged), s(&p2), s(&p1)]);
    assert_eq!(o.status.code(), Some(0), "{o:?}");
    assert_eq!(
        without_time(&merged.join("trials.csv")),
        without_time(&full.join("trials.csv"))
    );
    for fig in ["final_error_cdf.svg", "final_vs_view_distance.svg"] {
        assert_eq!(
            std::fs::read(merged.join(fig)).unwrap(),
            std::fs::read(full.join(fig)).unwrap(),
            "{fig}"
        );
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(merged.join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["trials"].as_array().unwrap().len(), 3);
    assert_eq!(summary["meta"]["seed"], 1);
    // Merging into a non-empty directory needs --force.
    let o = vtsm(&["eval", "merge", "--out", s(&merged), s(&p1), s(&p2)]);
    assert_eq!(o.status.code(), Some(2), "{o:?}");

    let refused = |name: &str, parts: &[&Path], names: &Path, says: &str| {
        let out = root.join(name);
        let mut args = vec!["eval", "merge", "--out", s(&out)];
        args.extend(parts.iter().map(|p| s(p)));
        let o = vtsm(&args);
        assert_eq!(o.status.code(), Some(2), "{name}: {o:?}");
        let err = String::from_utf8(o.stderr).unwrap();
        assert_eq!(err.lines().count(), 1, "{name}: {err}");
        assert!(err.contains(s(names)), "{name}: {err}");
        assert!(err.contains(says), "{name}: {err}");
        assert!(!out.exists(), "{name}: output written");
    };
    refused("duplicated", &[&p1, &p2, &p1], &p1, "earlier part");
    refused("missing", &[&p1], &p1, "miss 1 of the campaign's 3");
    refused("seeds", &[&p1, &other], &other, "seed 2 differs");
}

/// A part records each finished trial as it finishes (`part.d/<index>.json`);
/// a shard killed before its outputs are written, rerun into the same
/// directory, takes the recorded trials as done (here trial 0, whose
/// recorded time is marked) and runs the rest (trial 2, whose record was
/// lost with the kill); a rerun with another seed is refused.
///
/// Verifies: VTSM-CLI-046
#[test]
fn a_rerun_shard_skips_the_recorded_trials() {
    let root = dir("eval_shards", "resume");
    let part = root.join("p1");
    campaign(&part, &["--shard", "0/2"]);
    let first = without_time(&part.join("trials.csv"));
    let journal = part.join("part.d");
    assert!(journal.join("0.json").exists() && journal.join("2.json").exists());
    // The kill: the outputs and trial 2's record never written.
    for e in std::fs::read_dir(&part).unwrap() {
        let p = e.unwrap().path();
        if p.is_file() {
            std::fs::remove_file(p).unwrap();
        }
    }
    std::fs::remove_file(journal.join("2.json")).unwrap();
    let rec = journal.join("0.json");
    let mut t: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&rec).unwrap()).unwrap();
    t["errors_bits"][4] = serde_json::json!(123.0f64.to_bits());
    std::fs::write(&rec, t.to_string()).unwrap();

    let o = vtsm(&[
        "eval",
        "--suite",
        "paper",
        "--trials",
        "3",
        "--terrains",
        "flagstone",
        "--hours",
        "0",
        "--quiet",
        "--shard",
        "0/2",
        "--seed",
        "2",
        "--out",
        s(&part),
    ]);
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    assert!(String::from_utf8_lossy(&o.stderr).contains("another campaign"));

    campaign(&part, &["--shard", "0/2"]);
    assert_eq!(without_time(&part.join("trials.csv")), first);
    let csv = std::fs::read_to_string(part.join("trials.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    let t = rows[0].split(',').position(|h| h == "time_s").unwrap();
    assert_eq!(rows[1].split(',').nth(t), Some("123.0000"), "{csv}");
    assert_ne!(rows[2].split(',').nth(t), Some("123.0000"), "{csv}");
    assert!(journal.join("2.json").exists());
}
