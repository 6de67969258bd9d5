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

/// The trial records (`<index>.json`) in a part's journal, by name, with
/// their content.
fn records(journal: &Path) -> std::collections::BTreeMap<String, String> {
    std::fs::read_dir(journal)
        .map(|d| {
            d.flatten()
                .map(|e| e.path())
                .filter(|p| {
                    p.extension().is_some_and(|x| x == "json")
                        && p.file_name().is_some_and(|n| n != "campaign.json")
                })
                .map(|p| {
                    let name = p.file_name().unwrap().to_string_lossy().into_owned();
                    (name, std::fs::read_to_string(&p).unwrap())
                })
                .collect()
        })
        .unwrap_or_default()
}

/// A shard killed for real (SIGKILL while trials run, one worker thread)
/// and rerun into the same directory: the rerun reports the trials done
/// before on stderr, runs only the others (the records written before the
/// kill are unchanged, their recorded times kept), and its `trials.csv`
/// equals, but for `time_s`, the campaign run whole in one process.
///
/// Verifies: VTSM-CLI-046, VTSM-CLI-048
#[test]
fn a_killed_shard_rerun_completes_with_the_same_rows() {
    let root = dir("eval_shards", "kill");
    let (part, whole) = (root.join("part"), root.join("whole"));
    let args = |out: &Path| -> Vec<String> {
        [
            "eval",
            "--suite",
            "paper",
            "--profile",
            "test",
            "--trials",
            "8",
            "--terrains",
            "flagstone",
            "--hours",
            "0",
            "--shard",
            "0/1",
            "--out",
            s(out),
        ]
        .map(str::to_string)
        .to_vec()
    };
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_vtsm"))
        .args(args(&part))
        .env("RAYON_NUM_THREADS", "1")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let journal = part.join("part.d");
    let t0 = std::time::Instant::now();
    while records(&journal).len() < 2 {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the shard ended before the kill"
        );
        assert!(t0.elapsed().as_secs() < 600, "no trial recorded in 600 s");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let before = records(&journal);
    assert!(
        (2..8).contains(&before.len()),
        "{} of 8 trials recorded at the kill",
        before.len()
    );
    assert!(
        !part.join("trials.csv").exists(),
        "outputs written before the kill"
    );

    let o = vtsm(&args(&part).iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(0), "{o:?}");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(&format!("8/8 trials ({} done before)", before.len())),
        "{err}"
    );
    let after = records(&journal);
    assert_eq!(after.len(), 8);
    for (name, text) in &before {
        assert_eq!(&after[name], text, "record {name} was run again");
    }
    let mut single = args(&whole);
    single.retain(|a| a != "--shard" && a != "0/1");
    single.push("--quiet".into());
    let o = vtsm(&single.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(0), "{o:?}");
    assert_eq!(
        without_time(&part.join("trials.csv")),
        without_time(&whole.join("trials.csv"))
    );
}
