//! `vtsm eval --replot DIR`: the figures of a recorded run drawn again from
//! its `trials.csv`, without running a trial (the recorded campaigns of the
//! paper profile take hours). The suite, profile and terrains come from its
//! `summary.json`; the figures are those a run writes, from the same trials.

use super::config::{Suite, SuiteConfig};
use super::figures;
use super::plot::Figure;
use crate::error::{Error, Result};
use crate::eval::columns::{TrialColumns, ViewColumns};
use crate::eval::{self, TrialOutcome};
use crate::scene::Profile;
use crate::terrain::TerrainKind;
use std::path::{Path, PathBuf};

/// Draw the figures of the run recorded in `dir` into `dir`; the files written.
///
/// # Errors
/// A missing or malformed `summary.json` or `trials.csv`, an existing figure
/// without `force`, or a figure that cannot be drawn.
pub fn replot(dir: &Path, force: bool) -> Result<Vec<PathBuf>> {
    let cfg = recorded_config(&dir.join("summary.json"))?;
    let path = dir.join("trials.csv");
    let text = std::fs::read_to_string(&path)
        .map_err(|e| Error::file(&path, format!("cannot read: {e}")))?;
    let outcomes = parse_trials(&text).map_err(|e| Error::file(&path, e))?;
    write_figures(dir, &figures::all(&cfg, &outcomes), force)
}

/// Write each figure as `<stem>.svg` and `<stem>.png` into `dir`.
///
/// # Errors
/// An existing file without `force`, a drawing or I/O failure.
pub fn write_figures(dir: &Path, figs: &[Figure], force: bool) -> Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    for fig in figs {
        let svg = dir.join(format!("{}.svg", fig.stem));
        eval::write_new(&svg, &fig.svg()?, force)?;
        let png = dir.join(format!("{}.png", fig.stem));
        eval::write_bytes_new(&png, &fig.png()?, force)?;
        written.extend([svg, png]);
    }
    Ok(written)
}

/// The suite, profile, trials, seed, terrains and time differences of a
/// recorded run.
pub(crate) fn recorded_config(path: &Path) -> Result<SuiteConfig> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| Error::file(path, format!("cannot read: {e}")))?;
    let json: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| Error::file(path, format!("invalid JSON: {e}")))?;
    let meta = &json["meta"];
    let bad = |what: &str| Error::file(path, format!("no usable meta.{what}"));
    let suite = meta["suite"]
        .as_str()
        .and_then(Suite::parse)
        .ok_or_else(|| bad("suite"))?;
    // A data set's images are its own: its runs record no simulated profile.
    let profile = match meta["profile"].as_str() {
        Some(super::dataset::DATA_PROFILE) if suite == Suite::Dataset => Profile::Test,
        p => p.and_then(Profile::parse).ok_or_else(|| bad("profile"))?,
    };
    let trials = meta["trials"].as_u64().ok_or_else(|| bad("trials"))? as usize;
    let seed = meta["seed"].as_u64().ok_or_else(|| bad("seed"))?;
    let mut cfg = SuiteConfig::new(suite, profile, trials, seed);
    let params = &meta["params"];
    if let Some(t) = params["terrains"].as_array() {
        cfg.terrains = t
            .iter()
            .map(|n| n.as_str().and_then(TerrainKind::parse))
            .collect::<Option<_>>()
            .ok_or_else(|| bad("params.terrains"))?;
    }
    if let Some(h) = params["hours"].as_array() {
        cfg.hours = h
            .iter()
            .filter_map(|v| v.as_f64())
            .map(|v| v as f32)
            .collect();
    }
    Ok(cfg)
}

/// The trials of a `trials.csv`, with what the figures read: group, method
/// (`vtsm` if the file has none), success, initial and final errors and the
/// nearest mapping view.
///
/// # Errors
/// A missing column or a malformed row, with its line number.
pub fn parse_trials(text: &str) -> std::result::Result<Vec<TrialOutcome>, String> {
    let mut lines = text.lines();
    let header = split_csv(lines.next().ok_or("empty file")?);
    let col = |name: &str| header.iter().position(|h| h == name);
    let need = |name: &str| col(name).ok_or(format!("no column `{name}`"));
    // Runs recorded before the baselines had no `method` column: all VTSM.
    let (cg, cm, cs) = (need("group")?, col("method"), need("success")?);
    let (ci, cf) = (need("init_t_mm")?, need("final_t_mm")?);
    let (cd, ca) = (col("view_dist_m"), col("view_angle_deg"));
    lines
        .enumerate()
        .map(|(i, line)| {
            let row = split_csv(line);
            let at = |c: usize| row.get(c).map(String::as_str).unwrap_or("");
            let num = |c: usize| -> std::result::Result<f64, String> {
                at(c)
                    .parse::<f64>()
                    .map_err(|_| format!("line {}: bad number `{}`", i + 2, at(c)))
            };
            let view = match (cd, ca) {
                (Some(d), Some(a)) if !at(d).is_empty() => Some(ViewColumns {
                    dist_m: num(d)?,
                    angle_deg: num(a)?,
                }),
                _ => None,
            };
            Ok(TrialOutcome {
                group: at(cg).to_string(),
                method: cm.map_or("vtsm", at).to_string(),
                trial: i,
                seed: 0,
                success: at(cs) == "true",
                failure: None,
                init_t_mm: num(ci)?,
                init_r_deg: f64::NAN,
                final_t_mm: num(cf)?,
                final_r_deg: f64::NAN,
                inliers: 0,
                iterations: 0,
                time_s: f64::NAN,
                columns: TrialColumns {
                    view,
                    ..TrialColumns::default()
                },
            })
        })
        .collect()
}

/// The fields of a CSV line, `"…"` quoting with `""` for a quote.
fn split_csv(line: &str) -> Vec<String> {
    let mut fields = vec![String::new()];
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                chars.next();
                push_char(&mut fields, '"');
            }
            ('"', _) => quoted = !quoted,
            (',', false) => fields.push(String::new()),
            _ => push_char(&mut fields, c),
        }
    }
    fields
}

fn push_char(fields: &mut [String], c: char) {
    if let Some(f) = fields.last_mut() {
        f.push(c);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trials_read_back_from_their_csv() {
        let o = TrialOutcome {
            group: "cfa2 Δ0h right = left shifted 4 px, \"small\" params".into(),
            method: "vtsm".into(),
            trial: 0,
            seed: 9,
            success: true,
            failure: None,
            init_t_mm: 150.25,
            init_r_deg: 1.0,
            final_t_mm: 7.5,
            final_r_deg: 0.1,
            inliers: 40,
            iterations: 5,
            time_s: 2.0,
            columns: TrialColumns {
                view: Some(ViewColumns {
                    dist_m: 0.5,
                    angle_deg: 12.25,
                }),
                ..TrialColumns::default()
            },
        };
        let back = parse_trials(&eval::csv(std::slice::from_ref(&o))).unwrap();
        assert_eq!(back.len(), 1);
        let b = &back[0];
        assert_eq!(
            (&b.group, &b.method, b.success),
            (&o.group, &o.method, true)
        );
        assert_eq!((b.init_t_mm, b.final_t_mm), (o.init_t_mm, o.final_t_mm));
        assert_eq!(b.columns.view, o.columns.view);
        assert!(parse_trials("group,method\nx,y\n").is_err());
    }
}
