//! `wrongplace`: inputs that must not give a confident answer, per terrain:
//! the correct pair with small parameters (N_corr 27, N_iter 1, reseed cap
//! 3; priors 10–20 cm), the same with a "right" image that is the left one
//! shifted by [`SHIFT_PX`] pixels (prior at the truth), frames taken at
//! another stop of the grid with the prior of this one, and frames of the
//! next terrain's depot at this stop (two or more terrains).

use super::{terrain_hours, SuiteDef};
use crate::cli::eval::config::SuiteConfig;
use crate::cli::eval::depot::Depot;
use crate::cli::eval::group::{Frames, Group};
use crate::cli::eval::maps::MapEntry;
use crate::cli::eval::protocol::SHIFT_PX;
use crate::eval::columns::GroupColumns;

/// Inputs that do not show the map from the prior.
pub struct Wrongplace;

/// The wrong inputs of terrain `t`: (name, frames).
fn kinds(cfg: &SuiteConfig, depot: &Depot, t: usize) -> Vec<(String, Frames)> {
    let n = cfg.terrains.len();
    let shift = SHIFT_PX * (depot.scenes[t].camera().width() / 480).max(1);
    let mut kinds = vec![
        ("correct, small params".to_string(), Frames::Truth),
        (
            format!("right = left shifted {shift} px, small params"),
            Frames::ShiftedRight(shift),
        ),
        ("another spot".to_string(), Frames::OtherSpot),
        ("another spot, small params".to_string(), Frames::OtherSpot),
    ];
    if n > 1 {
        let o = (t + 1) % n;
        let other = cfg.terrains[o].name();
        kinds.push((format!("{other} depot"), Frames::OtherDepot(o)));
        kinds.push((
            format!("{other} depot, small params"),
            Frames::OtherDepot(o),
        ));
    }
    kinds
}

impl SuiteDef for Wrongplace {
    fn name(&self) -> &'static str {
        "wrongplace"
    }

    fn default_hours(&self) -> Vec<f32> {
        vec![0.0]
    }

    fn groups(&self, cfg: &SuiteConfig, depot: &Depot, _maps: &[MapEntry]) -> Vec<Group> {
        let mut groups = Vec::new();
        for (t, hi, base, h) in terrain_hours(cfg, depot) {
            for (name, frames) in kinds(cfg, depot, t) {
                let columns = GroupColumns::WrongPlace {
                    hours: h,
                    other_depot: matches!(frames, Frames::OtherDepot(_)),
                };
                let small = name.ends_with("small params");
                let g = Group::new(format!("{base} {name}"), t, depot.light_of(t, hi), columns);
                groups.push(g.with_frames(frames, small));
            }
        }
        groups
    }
}
