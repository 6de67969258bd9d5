//! The figures of the suites, built from the trials and their groups' styles.

use super::config::SuiteConfig;
use super::group::Group;
use super::plot::{Figure, Kind, Series, Style};
use crate::eval::TrialOutcome;

/// The distribution of the final translation error of every group (its
/// successful trials), one step CDF per group.
pub fn error_cdf(
    cfg: &SuiteConfig,
    groups: &[(Group, Style)],
    outcomes: &[TrialOutcome],
) -> Figure {
    let series = groups
        .iter()
        .map(|(g, style)| Series {
            name: g.label.clone(),
            style: *style,
            points: outcomes
                .iter()
                .filter(|o| o.group == g.label && o.success)
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
    groups: &[(Group, Style)],
    outcomes: &[TrialOutcome],
    x: fn(&TrialOutcome) -> f64,
) -> Figure {
    let mut series: Vec<Series> = groups
        .iter()
        .map(|(g, style)| Series {
            name: g.label.clone(),
            style: *style,
            points: outcomes
                .iter()
                .filter(|o| o.group == g.label && o.success)
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
    groups: &[(Group, Style)],
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
