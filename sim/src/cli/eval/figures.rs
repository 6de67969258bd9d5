//! The figures of the suites, built from the trials and their groups' styles.

use super::config::SuiteConfig;
use super::plot::{Figure, Kind, Series, Style};
use crate::eval::TrialOutcome;
use crate::terrain::TerrainKind;

/// Every figure of a run of `cfg`'s suite: the error CDF, then the suite's.
pub fn all(cfg: &SuiteConfig, outcomes: &[TrialOutcome]) -> Vec<Figure> {
    let styled = if cfg.suite == super::config::Suite::Dataset {
        pair_styles(outcomes)
    } else {
        styles(&cfg.terrains, outcomes)
    };
    let mut figs = vec![error_cdf(cfg, &styled, outcomes)];
    figs.extend(cfg.suite.def().figures(cfg, &styled, outcomes));
    figs
}

/// The style of each group, in order of first appearance in `outcomes`:
/// colour per terrain (the first word of the label), line style (or marker)
/// per rank among the terrain's groups (per lighting change in `paper` and
/// `baseline`, per kind of group in the others); a baseline relocalizer's
/// groups in the style of the VTSM group they pair with, thin or hollow.
pub fn styles(terrains: &[TerrainKind], outcomes: &[TrialOutcome]) -> Vec<(String, Style)> {
    let mut seen: Vec<(&str, &str)> = Vec::new();
    for o in outcomes {
        if !seen.iter().any(|(g, _)| *g == o.group) {
            seen.push((&o.group, &o.method));
        }
    }
    let terrain = |label: &str| {
        let first = label.split(' ').next().unwrap_or("");
        terrains.iter().position(|k| k.name() == first).unwrap_or(0)
    };
    let mut ranks: Vec<(usize, &str, usize)> = Vec::new();
    seen.iter()
        .map(|&(label, method)| {
            let t = terrain(label);
            let rank = ranks
                .iter()
                .filter(|(rt, rm, _)| *rt == t && *rm == method)
                .count();
            ranks.push((t, method, rank));
            let style = Style::new(t, rank);
            let style = if method == "vtsm" {
                style
            } else {
                style.as_baseline()
            };
            (label.to_string(), style)
        })
        .collect()
}

/// The style of each group of a data set's run, in order of first
/// appearance: colour (then line style, past the palette) per pair; the
/// baseline's group of a pair in the pair's style, thin or hollow.
pub fn pair_styles(outcomes: &[TrialOutcome]) -> Vec<(String, Style)> {
    let mut pairs: Vec<&str> = Vec::new();
    let mut out: Vec<(String, Style)> = Vec::new();
    for o in outcomes {
        if out.iter().any(|(g, _)| *g == o.group) {
            continue;
        }
        let pair = o.group.split(" · ").next().unwrap_or(&o.group);
        let i = pairs.iter().position(|p| *p == pair).unwrap_or_else(|| {
            pairs.push(pair);
            pairs.len() - 1
        });
        let style = Style::new(i % PALETTE_LEN, i / PALETTE_LEN);
        let style = if o.method == "vtsm" {
            style
        } else {
            style.as_baseline()
        };
        out.push((o.group.clone(), style));
    }
    out
}

/// Colours of the figures' palette.
const PALETTE_LEN: usize = super::plot::PALETTE_LEN;

/// The distribution of the final translation error of every group (its
/// successful trials), one step CDF per group.
pub fn error_cdf(
    cfg: &SuiteConfig,
    groups: &[(String, Style)],
    outcomes: &[TrialOutcome],
) -> Figure {
    let series = groups
        .iter()
        .map(|(label, style)| Series {
            name: label.clone(),
            style: *style,
            points: outcomes
                .iter()
                .filter(|o| &o.group == label && o.success)
                .map(|o| (o.final_t_mm, 0.0))
                .collect(),
        })
        .collect();
    Figure {
        stem: "final_error_cdf".into(),
        title: format!(
            "{}: distribution of the final error (successful trials)",
            cfg.suite.name()
        ),
        x_label: "final translation error (mm)".into(),
        y_label: "successful trials at or below (%)".into(),
        kind: Kind::Cdf,
        series,
    }
}

/// The final translation error of every trial against `x`: the successes
/// of each group in its style, the failures as black crosses.
pub fn scatter(
    stem: &str,
    title: &str,
    x_label: &str,
    groups: &[(String, Style)],
    outcomes: &[TrialOutcome],
    x: fn(&TrialOutcome) -> f64,
) -> Figure {
    let mut series: Vec<Series> = groups
        .iter()
        .map(|(label, style)| Series {
            name: label.clone(),
            style: *style,
            points: outcomes
                .iter()
                .filter(|o| &o.group == label && o.success)
                .map(|o| (x(o), o.final_t_mm))
                .collect(),
        })
        .collect();
    let failed: Vec<(f64, f64)> = outcomes
        .iter()
        .filter(|o| !o.success)
        .map(|o| (x(o), o.final_t_mm))
        .collect();
    if !failed.is_empty() {
        series.push(Series {
            name: "failed (any group)".into(),
            style: Style::FAILED,
            points: failed,
        });
    }
    Figure {
        stem: stem.into(),
        title: title.into(),
        x_label: x_label.into(),
        y_label: "final translation error (mm)".into(),
        kind: Kind::Scatter,
        series,
    }
}

/// The final error against the distance and the angle to the nearest
/// mapping view (`paper`, `baseline`).
pub fn view_scatters(
    cfg: &SuiteConfig,
    groups: &[(String, Style)],
    outcomes: &[TrialOutcome],
) -> Vec<Figure> {
    let title = format!("{}: final error vs nearest mapping view", cfg.suite.name());
    vec![
        scatter(
            "final_vs_view_distance",
            &title,
            "distance to nearest mapping view (m)",
            groups,
            outcomes,
            |o| o.columns.view.map_or(f64::NAN, |v| v.dist_m),
        ),
        scatter(
            "final_vs_view_angle",
            &title,
            "angle to nearest mapping view (°)",
            groups,
            outcomes,
            |o| o.columns.view.map_or(f64::NAN, |v| v.angle_deg),
        ),
    ]
}
