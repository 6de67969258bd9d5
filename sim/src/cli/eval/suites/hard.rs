//! `hard`: the operating envelope. Each terrain is relocalized under
//! conditions beyond the paper's, one axis at a time and in the worst
//! combinations, each against the same reference (map and pairs at 9:30, the
//! depot as mapped, the profile's map, the ideal camera):
//!
//! - **sun**: the pairs in the afternoon with the sun 12° down to 2° above
//!   the horizon (shadows 5 to 30 times longer than the rocks are high), the
//!   map at 9:30 (Δ 5.7–7.4 h); and the map at 8:00 with the pairs at 16:00
//!   (Δ 8 h, both suns low, from opposite sides);
//! - **depot**: wheel tracks, rocks moved or taken away, dust
//!   ([`DepotChange`]);
//! - **map**: the map from imagery 2, 4 and 8 times coarser;
//! - **camera**: each effect of [`REALISTIC`] at its realistic level;
//! - **worst**: the low sun with tracks and moved rocks, then with a 4×
//!   coarser map and a noisy, JPEG-compressed camera on top, and the Δ 8 h
//!   light with the changed depot and the coarse map.
//!
//! The captures go round the sample tubes (the paper's grid), so the sun
//! stands behind, across and into the cameras within every group. The notes
//! are the envelope: success within 5 cm per condition and terrain, the
//! confident-wrong count and the slowest failure; the figures draw success
//! against sun elevation, time difference, rocks moved and map coarseness.

use super::{full_maps, SuiteDef};
use crate::cli::demo::MAP_HOURS;
use crate::cli::eval::config::SuiteConfig;
use crate::cli::eval::depot::{mapped_mesh, Depot, World};
use crate::cli::eval::group::Group;
use crate::cli::eval::maps::{MapEntry, Scoring};
use crate::cli::eval::plot::{Figure, Kind, Series, Style};
use crate::cli::eval::tables::confident_wrong;
use crate::effects::{CameraEffects, REALISTIC};
use crate::error::{Error, Result};
use crate::eval::columns::GroupColumns;
use crate::eval::TrialOutcome;
use crate::render::Sun;
use crate::scene::{mapping_trajectory, Trajectory};
use crate::terrain::DepotChange;
use rayon::prelude::*;

/// The envelope's conditions and worst combinations.
pub struct Hard;

/// A trial within this of the truth counts towards the envelope, mm (the
/// paper's accuracy threshold).
pub const WITHIN_MM: f64 = 50.0;

/// Sun elevations of the `sun` axis, degrees (afternoon, map at 9:30).
pub const SUN_ELEVATIONS_DEG: [f32; 5] = [12.0, 8.0, 6.0, 4.0, 2.0];

/// Local solar times of the Δ 8 h condition: map, pairs.
pub const DELTA8_HOURS: (f32, f32) = (8.0, 16.0);

/// The axis a condition varies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    /// The paper's conditions at Δ0 h.
    Reference,
    /// Sun elevation and time difference.
    Sun,
    /// The depot changed since mapping.
    Depot,
    /// Map resolution.
    Map,
    /// The live camera.
    Camera,
    /// Several axes at once.
    Worst,
}

impl Axis {
    /// Name in the envelope table.
    pub fn name(self) -> &'static str {
        match self {
            Self::Reference => "reference",
            Self::Sun => "sun",
            Self::Depot => "depot",
            Self::Map => "map",
            Self::Camera => "camera",
            Self::Worst => "worst",
        }
    }
}

/// One condition: what differs from the reference.
#[derive(Clone, Debug, PartialEq)]
pub struct Condition {
    /// The axis it varies.
    pub axis: Axis,
    /// Its name in the group labels (after the terrain).
    pub name: String,
    /// Local solar time of the mapping images, hours.
    pub map_hours: f32,
    /// Local solar time of the live pairs, hours.
    pub hours: f32,
    /// How the depot changed since mapping.
    pub change: DepotChange,
    /// Map coarsening factor.
    pub map_coarse: u32,
    /// The live camera's effects.
    pub camera: CameraEffects,
}

impl Condition {
    fn reference(axis: Axis, name: String) -> Self {
        Self {
            axis,
            name,
            map_hours: MAP_HOURS,
            hours: MAP_HOURS,
            change: DepotChange::NONE,
            map_coarse: 1,
            camera: CameraEffects::NONE,
        }
    }

    /// Its world: (live hours, change); the reference's is the depot's own.
    fn world(&self) -> (f32, DepotChange) {
        (self.hours, self.change)
    }

    /// Its map: (mapping hours, coarsening).
    fn map(&self) -> (f32, u32) {
        (self.map_hours, self.map_coarse)
    }
}

/// The conditions, in table order.
pub fn conditions() -> Vec<Condition> {
    let r = |axis, name: &str| Condition::reference(axis, name.to_string());
    let mut out = vec![r(Axis::Reference, "ref Δ0h")];
    let low_sun = |el: f32| Sun::depot_afternoon_at(el).unwrap_or(MAP_HOURS);
    for el in SUN_ELEVATIONS_DEG {
        let hours = low_sun(el);
        out.push(Condition {
            hours,
            ..r(
                Axis::Sun,
                &format!("sun {el:.0}° (Δ{:.1}h)", hours - MAP_HOURS),
            )
        });
    }
    let (m8, h8) = DELTA8_HOURS;
    out.push(Condition {
        map_hours: m8,
        hours: h8,
        ..r(
            Axis::Sun,
            &format!(
                "Δ8h map {:.0}° pairs {:.0}°",
                Sun::depot(m8).elevation_deg,
                Sun::depot(h8).elevation_deg
            ),
        )
    });
    let change = |tracks, rocks_moved, dust| DepotChange {
        tracks,
        rocks_moved,
        dust,
    };
    for c in [
        change(2, 0.0, 0.0),
        change(0, 0.3, 0.0),
        change(2, 0.3, 0.0),
        change(0, 0.6, 0.0),
        change(0, 0.0, 0.5),
        change(4, 0.3, 0.3),
    ] {
        out.push(Condition {
            change: c,
            ..r(Axis::Depot, &c.label())
        });
    }
    for k in [2, 4, 8] {
        out.push(Condition {
            map_coarse: k,
            ..r(Axis::Map, &format!("map {k}x"))
        });
    }
    for (name, camera) in REALISTIC {
        out.push(Condition {
            camera: *camera,
            ..r(Axis::Camera, &format!("camera {name}"))
        });
    }
    let tracks_rocks = change(2, 0.3, 0.0);
    let worst_camera = CameraEffects {
        noise_dn: 4.0,
        jpeg_quality: 60,
        ..CameraEffects::NONE
    };
    let sun8 = low_sun(8.0);
    out.push(Condition {
        hours: sun8,
        change: tracks_rocks,
        ..r(Axis::Worst, "sun 8° + tracks=2,rocks=0.3")
    });
    out.push(Condition {
        hours: sun8,
        change: tracks_rocks,
        map_coarse: 4,
        camera: worst_camera,
        ..r(
            Axis::Worst,
            &format!(
                "sun 8° + tracks=2,rocks=0.3 + map 4x + {}",
                worst_camera.label()
            ),
        )
    });
    out.push(Condition {
        map_hours: m8,
        hours: h8,
        change: tracks_rocks,
        map_coarse: 4,
        ..r(Axis::Worst, "Δ8h + tracks=2,rocks=0.3 + map 4x")
    });
    out
}

/// The distinct worlds of the conditions other than the reference's, in
/// first-use order.
fn distinct_worlds() -> Vec<(f32, DepotChange)> {
    let mut out: Vec<(f32, DepotChange)> = Vec::new();
    for c in conditions() {
        if c.world() != (MAP_HOURS, DepotChange::NONE) && !out.contains(&c.world()) {
            out.push(c.world());
        }
    }
    out
}

/// The distinct maps of the conditions other than the depot's own, in
/// first-use order.
fn distinct_maps() -> Vec<(f32, u32)> {
    let mut out: Vec<(f32, u32)> = Vec::new();
    for c in conditions() {
        if c.map() != (MAP_HOURS, 1) && !out.contains(&c.map()) {
            out.push(c.map());
        }
    }
    out
}

impl SuiteDef for Hard {
    fn name(&self) -> &'static str {
        "hard"
    }

    fn default_hours(&self) -> Vec<f32> {
        vec![0.0]
    }

    fn takes_baseline(&self) -> bool {
        true
    }

    fn check(&self, cfg: &SuiteConfig) -> Result<()> {
        if cfg.hours != [0.0] {
            return Err(Error::msg(
                "the hard suite sets its own times of day (--hours is not for it)",
            ));
        }
        if cfg.map_coarse != 1 || !cfg.change.is_none() || !cfg.camera.is_none() {
            return Err(Error::msg(
                "the hard suite sets its own maps, depot changes and camera effects \
                 (--map-coarse, --change and --camera are not for it)",
            ));
        }
        Ok(())
    }

    fn worlds(&self, cfg: &SuiteConfig) -> Vec<World> {
        (0..cfg.terrains.len())
            .flat_map(|terrain| {
                distinct_worlds()
                    .into_iter()
                    .map(move |(hours, change)| World {
                        terrain,
                        hours,
                        change,
                    })
            })
            .collect()
    }

    fn maps(&self, cfg: &SuiteConfig, depot: &Depot) -> Vec<MapEntry> {
        let mut maps = full_maps(cfg, depot);
        let keys: Vec<(usize, (f32, u32))> = (0..depot.scenes.len())
            .flat_map(|t| distinct_maps().into_iter().map(move |m| (t, m)))
            .collect();
        maps.par_extend(keys.par_iter().map(|&(t, (hours, k))| {
            let scene = depot.scenes[t].clone().with_map_coarse(k);
            let views = mapping_trajectory(&scene.terrain, Trajectory::Wave, 1);
            let mesh = mapped_mesh(cfg, &scene, hours);
            MapEntry::encode(&mesh, cfg.origin, views, Scoring::of(cfg)).with_source(
                &mesh,
                &Sun::depot(hours),
                cfg.relight,
            )
        }));
        maps
    }

    fn groups(&self, cfg: &SuiteConfig, depot: &Depot, _maps: &[MapEntry]) -> Vec<Group> {
        let (worlds, maps, n) = (distinct_worlds(), distinct_maps(), cfg.terrains.len());
        let mut groups = Vec::new();
        for (t, kind) in cfg.terrains.iter().enumerate() {
            for c in conditions() {
                let light = worlds
                    .iter()
                    .position(|w| *w == c.world())
                    .map_or(depot.light_of(t, 0), |w| {
                        depot.world_light(t * worlds.len() + w)
                    });
                let map = maps
                    .iter()
                    .position(|m| *m == c.map())
                    .map_or(t, |m| n + t * maps.len() + m);
                let columns = GroupColumns::Condition {
                    hours: c.hours - c.map_hours,
                    sun_el_deg: depot.lights[light].sun.elevation_deg,
                    map_sun_el_deg: Sun::depot(c.map_hours).elevation_deg,
                    map_coarse: c.map_coarse,
                    tracks: c.change.tracks,
                    rocks_moved: c.change.rocks_moved,
                    dust: c.change.dust,
                    camera: !c.camera.is_none(),
                };
                let label = format!("{} {}", kind.name(), c.name);
                groups.push(
                    Group::new(label, t, light, columns)
                        .on_map(map)
                        .with_camera(c.camera),
                );
            }
        }
        groups
    }

    fn figures(
        &self,
        cfg: &SuiteConfig,
        _groups: &[(String, Style)],
        outcomes: &[TrialOutcome],
    ) -> Vec<Figure> {
        envelope_figures(cfg, outcomes)
    }

    fn notes(&self, outcomes: &[TrialOutcome]) -> String {
        envelope_table(outcomes)
    }
}

/// A trial that counts towards the envelope: a success within [`WITHIN_MM`].
fn within(o: &TrialOutcome) -> bool {
    o.success && o.final_t_mm <= WITHIN_MM
}

/// `(terrain, condition, method)` of a group label `"<terrain> <condition>[ · <method>]"`.
fn split_label(label: &str) -> (&str, &str, &str) {
    let (rest, method) = label.split_once(" · ").unwrap_or((label, "vtsm"));
    let (terrain, condition) = rest.split_once(' ').unwrap_or((rest, ""));
    (terrain, condition, method)
}

/// The trials of condition `name` relocalized by `method`, on `terrain`
/// (every terrain: `None`).
fn trials_of<'o>(
    outcomes: &'o [TrialOutcome],
    name: &str,
    method: &str,
    terrain: Option<&str>,
) -> Vec<&'o TrialOutcome> {
    outcomes
        .iter()
        .filter(|o| {
            let (ot, oc, om) = split_label(&o.group);
            oc == name && om == method && terrain.is_none_or(|t| t == ot)
        })
        .collect()
}

/// The envelope: per condition, VTSM's trials within 5 cm per terrain and
/// overall, the baseline's overall, the confident-wrong count, the median
/// error of the successes and the slowest failure.
pub fn envelope_table(outcomes: &[TrialOutcome]) -> String {
    let mut terrains: Vec<&str> = Vec::new();
    let mut baselines: Vec<&str> = Vec::new();
    for o in outcomes {
        let (t, _, m) = split_label(&o.group);
        if !terrains.contains(&t) {
            terrains.push(t);
        }
        if m != "vtsm" && !baselines.contains(&m) {
            baselines.push(m);
        }
    }
    let mut s = String::from(
        "\n## Operating envelope\n\nTrials within 5 cm of the truth (success and final \
         error ≤ 50 mm) per condition; confident wrong = successes beyond 100 mm or 1.5°; \
         slowest failure = the longest time to a failure code.\n\n| axis | condition | sun el (°) | Δ (h) |",
    );
    for t in &terrains {
        s += &format!(" {t} |");
    }
    s += " all | confident wrong | median error (mm) | slowest failure (s) |";
    for b in &baselines {
        s += &format!(" {b} all | {b} confident wrong |");
    }
    s += "\n|---|---|---:|---:|";
    s += &"---:|".repeat(terrains.len() + 4 + 2 * baselines.len());
    s += "\n";
    for c in conditions() {
        let of = |m: &str, t: Option<&str>| trials_of(outcomes, &c.name, m, t);
        let all = of("vtsm", None);
        if all.is_empty() {
            continue;
        }
        let frac =
            |v: &[&TrialOutcome]| format!("{}/{}", v.iter().filter(|o| within(o)).count(), v.len());
        let wrong =
            |v: &[&TrialOutcome]| v.iter().filter(|o| confident_wrong(o, o.success)).count();
        let sun = Sun::depot(c.hours).elevation_deg;
        s += &format!(
            "| {} | {} | {sun:.1} | {:.1} |",
            c.axis.name(),
            c.name,
            c.hours - c.map_hours
        );
        for t in &terrains {
            s += &format!(" {} |", frac(&of("vtsm", Some(t))));
        }
        let mut errs: Vec<f64> = all
            .iter()
            .filter(|o| o.success)
            .map(|o| o.final_t_mm)
            .collect();
        errs.sort_by(f64::total_cmp);
        let median = errs
            .get(errs.len() / 2)
            .map_or("–".into(), |e| format!("{e:.1}"));
        let slowest = all
            .iter()
            .filter(|o| !o.success)
            .map(|o| o.time_s)
            .fold(None, |m: Option<f64>, t| Some(m.map_or(t, |m| m.max(t))))
            .map_or("–".into(), |t| format!("{t:.1}"));
        s += &format!(
            " **{}** | {} | {median} | {slowest} |",
            frac(&all),
            wrong(&all)
        );
        for b in &baselines {
            let v = of(b, None);
            s += &format!(" {} | {} |", frac(&v), wrong(&v));
        }
        s += "\n";
    }
    s
}

/// Success within 5 cm (%) against one axis's level, one series per terrain
/// (VTSM) and one for the baseline over every terrain.
fn envelope_figures(cfg: &SuiteConfig, outcomes: &[TrialOutcome]) -> Vec<Figure> {
    type Level = fn(&Condition) -> Option<f64>;
    let axes: [(&str, &str, &str, Level); 4] = [
        (
            "envelope_sun",
            "sun elevation at capture (°)",
            "success vs sun elevation (map at 9:30)",
            |c| {
                (c.axis == Axis::Reference || (c.axis == Axis::Sun && c.map_hours == MAP_HOURS))
                    .then(|| f64::from(Sun::depot(c.hours).elevation_deg))
            },
        ),
        (
            "envelope_hours",
            "time difference between mapping and capture (h)",
            "success vs time difference",
            |c| {
                matches!(c.axis, Axis::Reference | Axis::Sun)
                    .then(|| f64::from(c.hours - c.map_hours))
            },
        ),
        (
            "envelope_rocks",
            "fraction of the rocks moved or taken away",
            "success vs rocks moved (no tracks, no dust)",
            |c| {
                (c.axis == Axis::Reference
                    || (c.axis == Axis::Depot && c.change.tracks == 0 && c.change.dust == 0.0))
                    .then(|| f64::from(c.change.rocks_moved))
            },
        ),
        (
            "envelope_map",
            "map coarseness (× the profile's texel and vertex spacing)",
            "success vs map resolution",
            |c| matches!(c.axis, Axis::Reference | Axis::Map).then(|| f64::from(c.map_coarse)),
        ),
    ];
    let conds = conditions();
    axes.iter()
        .map(|&(stem, x_label, title, level)| {
            let points = |m: &str, t: Option<&str>| -> Vec<(f64, f64)> {
                let mut pts: Vec<(f64, f64)> = conds
                    .iter()
                    .filter_map(|c| {
                        let x = level(c)?;
                        let v = trials_of(outcomes, &c.name, m, t);
                        (!v.is_empty()).then(|| {
                            let n = v.iter().filter(|o| within(o)).count();
                            (x, 100.0 * n as f64 / v.len() as f64)
                        })
                    })
                    .collect();
                pts.sort_by(|a, b| a.0.total_cmp(&b.0));
                pts
            };
            let mut series: Vec<Series> = cfg
                .terrains
                .iter()
                .enumerate()
                .map(|(i, k)| Series {
                    name: k.name().to_string(),
                    style: Style::new(i, 0),
                    points: points("vtsm", Some(k.name())),
                })
                .collect();
            if let Some(b) = cfg.baseline {
                series.push(Series {
                    name: format!("{} (all terrains)", b.name()),
                    style: Style::new(cfg.terrains.len(), 1).as_baseline(),
                    points: points(b.name(), None),
                });
            }
            Figure {
                stem: stem.into(),
                title: format!("hard: {title}"),
                x_label: x_label.into(),
                y_label: "trials within 5 cm (%)".into(),
                kind: Kind::Rate,
                series,
            }
        })
        .collect()
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
mod tests {
    use super::*;

    /// Verifies: VTSM-SIM-019
    #[test]
    fn conditions_vary_one_axis_or_say_they_combine() {
        let cs = conditions();
        let names: Vec<&str> = cs.iter().map(|c| c.name.as_str()).collect();
        for (i, n) in names.iter().enumerate() {
            assert!(!names[..i].contains(n), "{n} twice");
        }
        for c in &cs {
            let differs = [
                c.hours != MAP_HOURS || c.map_hours != MAP_HOURS,
                !c.change.is_none(),
                c.map_coarse != 1,
                !c.camera.is_none(),
            ];
            let n = differs.iter().filter(|d| **d).count();
            match c.axis {
                Axis::Reference => assert_eq!(n, 0, "{}", c.name),
                Axis::Worst => assert!(n >= 2, "{}", c.name),
                _ => assert_eq!(n, 1, "{}", c.name),
            }
        }
        // The sun axis reaches the elevations it names.
        for c in cs
            .iter()
            .filter(|c| c.axis == Axis::Sun && c.map_hours == MAP_HOURS)
        {
            let el = Sun::depot(c.hours).elevation_deg;
            assert!(
                SUN_ELEVATIONS_DEG.iter().any(|e| (e - el).abs() < 0.01),
                "{el}"
            );
        }
        assert!(cs.iter().any(|c| c.hours - c.map_hours >= 8.0));
    }

    /// Verifies: VTSM-SIM-019
    #[test]
    fn labels_split_into_terrain_condition_and_method() {
        assert_eq!(
            split_label("cfa6 sun 8° (Δ6.9h) · features"),
            ("cfa6", "sun 8° (Δ6.9h)", "features")
        );
        assert_eq!(
            split_label("flagstone map 4x"),
            ("flagstone", "map 4x", "vtsm")
        );
    }
}
