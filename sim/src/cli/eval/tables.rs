//! The tables every suite prints after the summary: integrity (confident
//! wrong answers with and without the gates), VTSM next to a baseline, and
//! the stepsize suite's breakdown by range.

use super::config::Method;
use super::protocol::{WRONG_R_DEG, WRONG_T_MM};
use crate::eval::{GroupSummary, TrialOutcome};
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// Codes of the integrity gates on the final estimate. They act only in the
/// last work unit, after the search, so a trial that ended in one of them is
/// exactly a trial that reported success before the gates existed.
pub const GATE_CODES: [&str; 3] = [
    "RELOC_POSE_OUTSIDE_PRIOR",
    "RELOC_INLIERS_DEGENERATE",
    "RELOC_RESIDUAL_HIGH",
];

/// Whether the trial would have reported success without the integrity gates.
pub fn success_without_gates(o: &TrialOutcome) -> bool {
    o.success
        || o.failure
            .as_deref()
            .is_some_and(|f| GATE_CODES.contains(&f))
}

/// Whether a trial whose success is `success` is a confident wrong answer: a
/// success whose true error exceeds [`WRONG_T_MM`] or [`WRONG_R_DEG`], or any
/// success on frames of another depot (column `wrong_place` = 1).
pub fn confident_wrong(o: &TrialOutcome, success: bool) -> bool {
    success
        && (o.final_t_mm.is_nan()
            || o.final_t_mm > WRONG_T_MM
            || o.final_r_deg.is_nan()
            || o.final_r_deg > WRONG_R_DEG
            || o.columns.other_depot())
}

/// Per group: trials; successes and confident wrong answers without the
/// integrity gates (gate codes counted as successes) and with them; the
/// successes beyond 50 mm (the paper's accuracy threshold) for reference;
/// the failure codes.
pub fn integrity_table(outcomes: &[TrialOutcome]) -> String {
    let mut s = format!(
        "\nIntegrity: confident wrong = success with true error > {WRONG_T_MM} mm or > {WRONG_R_DEG}° (any success on another depot's frames); \"without gates\" counts the integrity-gate codes as successes (the acceptance before the gates, same trials):\n\n| group | trials | successes without gates | confident wrong without gates | successes | confident wrong | successes > 50 mm | failure codes |\n|---|---:|---:|---:|---:|---:|---:|---|\n"
    );
    let mut order: Vec<&str> = Vec::new();
    for o in outcomes {
        if !order.contains(&o.group.as_str()) {
            order.push(&o.group);
        }
    }
    let mut total = [0usize; 6];
    for g in order {
        let rows: Vec<&TrialOutcome> = outcomes.iter().filter(|o| o.group == g).collect();
        let before = rows.iter().filter(|o| success_without_gates(o)).count();
        let wrong_before = rows
            .iter()
            .filter(|o| confident_wrong(o, success_without_gates(o)))
            .count();
        let ok = rows.iter().filter(|o| o.success).count();
        let wrong = rows
            .iter()
            .filter(|o| confident_wrong(o, o.success))
            .count();
        let over = rows
            .iter()
            .filter(|o| o.success && o.final_t_mm > 50.0)
            .count();
        let mut codes: BTreeMap<&str, usize> = BTreeMap::new();
        for o in &rows {
            if let Some(f) = &o.failure {
                *codes.entry(f.as_str()).or_default() += 1;
            }
        }
        let codes: Vec<String> = codes.iter().map(|(c, n)| format!("{c} ×{n}")).collect();
        let _ = writeln!(
            s,
            "| {g} | {} | {before} | {wrong_before} | {ok} | {wrong} | {over} | {} |",
            rows.len(),
            codes.join(", ")
        );
        for (t, v) in total
            .iter_mut()
            .zip([rows.len(), before, wrong_before, ok, wrong, over])
        {
            *t += v;
        }
    }
    let [tt, tb, twb, ts, tw, t50] = total;
    let _ = writeln!(
        s,
        "| **all** | {tt} | {tb} | {twb} | {ts} | {tw} | {t50} | |"
    );
    s
}

/// VTSM and a baseline next to each other, one row per VTSM group (the
/// baseline's group is the next one, labelled `"<group> · <method>"`).
pub fn side_by_side(groups: &[GroupSummary], m: Method) -> String {
    let mut s = format!(
        "\nVTSM and the {0} baseline on the same trials:\n\n| group | VTSM success | VTSM final error (mm, median) | {0} success | {0} final error (mm, median) | {0} final error (mm, mean) |\n|---|---:|---:|---:|---:|---:|\n",
        m.name()
    );
    let num = |v: f64| {
        if v.is_finite() {
            format!("{v:.1}")
        } else {
            "—".to_string()
        }
    };
    for g in groups {
        let label = format!("{} · {}", g.group, m.name());
        let Some(b) = groups.iter().find(|b| b.group == label) else {
            continue;
        };
        let _ = writeln!(
            s,
            "| {} | {:.0} % | {} | {:.0} % | {} | {} |",
            g.group,
            g.success_pct,
            num(g.final_t_mm_median),
            b.success_pct,
            num(b.final_t_mm_median),
            num(b.final_t_mm_mean)
        );
    }
    s
}

/// Range bins (m) of the stepsize breakdown.
pub const RANGE_BINS_M: [f64; 6] = [0.0, 0.5, 1.0, 1.5, 2.0, 3.0];

/// Success and median final error by range to the nearest mapping view (Fig. 7d).
pub fn range_table(outcomes: &[TrialOutcome]) -> String {
    let mut s = String::from(
        "\nBy range to the nearest mapping view:\n\n| range (m) | trials | success | final error (mm, median of successes) |\n|---|---:|---:|---:|\n",
    );
    for (i, &lo) in RANGE_BINS_M.iter().enumerate() {
        let hi = RANGE_BINS_M.get(i + 1).copied().unwrap_or(f64::INFINITY);
        let rows: Vec<&TrialOutcome> = outcomes
            .iter()
            .filter(|o| {
                let d = view_dist_m(o);
                d >= lo && d < hi
            })
            .collect();
        if rows.is_empty() {
            continue;
        }
        let mut ok: Vec<f64> = rows
            .iter()
            .filter(|o| o.success)
            .map(|o| o.final_t_mm)
            .collect();
        ok.sort_by(f64::total_cmp);
        let med = match ok.len() {
            0 => "—".to_string(),
            m if m % 2 == 1 => format!("{:.1}", ok[m / 2]),
            m => format!("{:.1}", 0.5 * (ok[m / 2 - 1] + ok[m / 2])),
        };
        let range = if hi.is_finite() {
            format!("{lo:.1}–{hi:.1}")
        } else {
            format!("≥ {lo:.1}")
        };
        let _ = writeln!(
            s,
            "| {range} | {} | {:.0} % | {med} |",
            rows.len(),
            100.0 * ok.len() as f64 / rows.len() as f64
        );
    }
    s
}

/// Distance of the trial's truth to the nearest mapping view, metres (NaN
/// if the map has none).
pub fn view_dist_m(o: &TrialOutcome) -> f64 {
    o.columns.view.map_or(f64::NAN, |v| v.dist_m)
}

/// Matches per template variant (`--variant-counts`), one row per group:
/// for each variant, the correspondences it gave per attempt and the share
/// of them that were correct (within `max(3σ, 1 cm)` of the truth). Empty
/// when no trial counted them.
pub fn variant_table(outcomes: &[TrialOutcome]) -> String {
    use crate::eval::columns::{VariantColumns, VARIANTS};
    let mut groups: Vec<(&str, u64, VariantColumns)> = Vec::new();
    for o in outcomes {
        let (Some(v), Some(e)) = (&o.columns.variants, &o.columns.engine) else {
            continue;
        };
        let at = match groups.iter().position(|(g, _, _)| *g == o.group) {
            Some(i) => i,
            None => {
                groups.push((&o.group, 0, VariantColumns::default()));
                groups.len() - 1
            }
        };
        let (_, attempts, sum) = &mut groups[at];
        *attempts += u64::from(e.attempts);
        for k in 0..VARIANTS {
            sum.matches[k] += v.matches[k];
            sum.accepted[k] += v.accepted[k];
            sum.correct[k] += v.correct[k];
        }
    }
    if groups.is_empty() {
        return String::new();
    }
    let mut s = String::from(
        "\nCorrespondences per attempt by template variant, and the share of them correct (gray, Sobel, Laplacian at ℓ, then at ℓ/2; all trials of the group):\n\n| group | attempts | gray | Sobel | Laplacian | gray ℓ/2 | Sobel ℓ/2 | Laplacian ℓ/2 | all |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for (g, attempts, v) in &groups {
        let n = (*attempts).max(1) as f64;
        let cell = |a: u32, c: u32| {
            if a == 0 {
                "0".to_string()
            } else {
                format!(
                    "{:.3} ({:.0} %)",
                    f64::from(a) / n,
                    100.0 * f64::from(c) / f64::from(a)
                )
            }
        };
        let _ = write!(s, "| {g} | {attempts} |");
        for k in 0..VARIANTS {
            let _ = write!(s, " {} |", cell(v.accepted[k], v.correct[k]));
        }
        let (a, c) = (
            v.accepted.iter().sum::<u32>(),
            v.correct.iter().sum::<u32>(),
        );
        let _ = writeln!(s, " {} |", cell(a, c));
    }
    s
}

/// Correct matches per attempt by decile of the map's sampling scores
/// (`--score-deciles`), one row per group: what the scores predict. Empty
/// when no trial counted them.
pub fn score_decile_table(outcomes: &[TrialOutcome]) -> String {
    let mut groups: Vec<(&str, crate::eval::columns::ScoreColumns)> = Vec::new();
    for o in outcomes {
        let Some(sc) = &o.columns.scores else {
            continue;
        };
        let at = match groups.iter().position(|(g, _)| *g == o.group) {
            Some(i) => i,
            None => {
                groups.push((&o.group, Default::default()));
                groups.len() - 1
            }
        };
        let sum = &mut groups[at].1;
        for k in 0..10 {
            sum.attempts[k] += sc.attempts[k];
            sum.correct[k] += sc.correct[k];
        }
    }
    if groups.is_empty() {
        return String::new();
    }
    let mut s = String::from(
        "\nCorrect matches per attempt by decile of the map's sampling scores (d0: lowest tenth of the mask; attempts in parentheses):\n\n| group | d0 | d1 | d2 | d3 | d4 | d5 | d6 | d7 | d8 | d9 | d9 / d0 |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for (g, sc) in &groups {
        let rate = |k: usize| f64::from(sc.correct[k]) / f64::from(sc.attempts[k].max(1));
        let _ = write!(s, "| {g} |");
        for k in 0..10 {
            let _ = write!(s, " {:.2} ({}) |", rate(k), sc.attempts[k]);
        }
        let ratio = if rate(0) > 0.0 {
            format!("{:.1}", rate(9) / rate(0))
        } else {
            "—".to_string()
        };
        let _ = writeln!(s, " {ratio} |");
    }
    s
}
