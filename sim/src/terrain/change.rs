//! A depot changed since it was mapped ([`DepotChange`], `--change`): rover
//! wheel tracks with tread pressed across it, a fraction of its rocks moved
//! or taken away, and dust that lowers its albedo contrast. Wind
//! ([`Terrain::with_wind`]) is the other, milder change.
//!
//! Input: a freshly generated [`Terrain`] and a seed; output: the changed
//! terrain (a new value; the mapped one is untouched). Work is bounded by the
//! grid (one pass over the cells per wheel-track pass and one for dust) and by
//! the rock count; every draw comes from the seed, so the same seed gives the
//! same depot on any thread count.

use super::{
    fbm, CellBox, Rock, Terrain, DEPOT_HALF_X_M, DEPOT_HALF_Y_M, GRID_HALF_X_M, GRID_HALF_Y_M,
    LABEL_SAND, LABEL_TUBE, TUBE_LENGTH_M, TUBE_XY_M,
};
use core::f32::consts::PI;
use vtsm_core::rng::Rng;

/// Distance between the two wheel tracks of a pass (centre to centre), metres.
pub const TRACK_GAUGE_M: f32 = 0.80;
/// Width of one wheel track, metres.
pub const WHEEL_WIDTH_M: f32 = 0.12;
/// Depth of a wheel track's floor below the ground it pressed, metres.
pub const RUT_DEPTH_M: f32 = 0.008;
/// Spacing of the grouser (tread) marks along a track, metres.
pub const GROUSER_PITCH_M: f32 = 0.06;
/// Extra depth of a grouser mark, metres.
pub const GROUSER_DEPTH_M: f32 = 0.003;
/// Width of the berm of pushed-aside soil on each side of a track, metres.
pub const BERM_WIDTH_M: f32 = 0.04;
/// Height of the berm's crest, metres.
pub const BERM_HEIGHT_M: f32 = 0.003;
/// Albedo factor of the compacted floor of a track (disturbed soil reads darker).
pub const TRACK_ALBEDO: f32 = 0.85;
/// Albedo factor inside a grouser mark.
pub const GROUSER_ALBEDO: f32 = 0.78;
/// Albedo of settled dust.
pub const DUST_ALBEDO: f32 = 0.30;
/// Most wheel-track passes `--change` accepts.
pub const MAX_TRACKS: u32 = 8;
/// Clearance kept between a pass's wheels and a sample tube, metres.
const TUBE_CLEARANCE_M: f32 = 0.10;
/// Candidate lines drawn per pass before it is dropped (all would run over a
/// tube): a bound, never reached in practice.
const PASS_TRIES: u32 = 16;

/// How the depot changed between mapping and relocalization; [`Self::NONE`]
/// is the mapped depot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepotChange {
    /// Rover passes across the depot, each leaving two wheel tracks
    /// ([`TRACK_GAUGE_M`] apart) with grouser marks and berms, on loose ground
    /// only (rocks and sample tubes are driven around, not flattened).
    pub tracks: u32,
    /// Fraction of the rocks (every size) disturbed: each one moved 5–30 cm
    /// in a random direction, or taken away (one in three). Rocks near a
    /// sample tube stay. Flagstone has no loose rocks and is unchanged by it.
    pub rocks_moved: f32,
    /// Dust cover in [0, 0.9]: every albedo is pulled towards
    /// [`DUST_ALBEDO`] by this fraction (±20 % in patches), lowering contrast.
    pub dust: f32,
}

impl Default for DepotChange {
    fn default() -> Self {
        Self::NONE
    }
}

impl DepotChange {
    /// No change.
    pub const NONE: Self = Self {
        tracks: 0,
        rocks_moved: 0.0,
        dust: 0.0,
    };

    /// Whether this is [`Self::NONE`].
    pub fn is_none(&self) -> bool {
        *self == Self::NONE
    }

    /// Parse `--change`: `none`, or a comma-separated list of `tracks=N`
    /// (0–[`MAX_TRACKS`]), `rocks=F` (fraction moved, 0–1) and `dust=F`
    /// (0–0.9); keys left out are unchanged.
    ///
    /// # Errors
    /// An empty spec, an unknown key, or a value that is not a number in its
    /// range, named with what is accepted.
    pub fn parse(spec: &str) -> Result<Self, String> {
        let spec = spec.trim();
        if spec.is_empty() {
            return Err("--change: empty; give none or tracks=N,rocks=F,dust=F".into());
        }
        let mut out = Self::NONE;
        for part in spec.split(',').map(str::trim) {
            if part == "none" {
                continue;
            }
            let (key, value) = part
                .split_once('=')
                .ok_or_else(|| format!("--change: `{part}` is not key=value"))?;
            let number = |lo: f32, hi: f32| -> Result<f32, String> {
                value
                    .trim()
                    .parse::<f32>()
                    .ok()
                    .filter(|v| v.is_finite() && (lo..=hi).contains(v))
                    .ok_or_else(|| format!("--change: {key} must be a number in [{lo}, {hi}]"))
            };
            match key.trim() {
                "tracks" => {
                    out.tracks = value
                        .trim()
                        .parse::<u32>()
                        .ok()
                        .filter(|n| *n <= MAX_TRACKS)
                        .ok_or_else(|| format!("--change: tracks must be 0..={MAX_TRACKS}"))?;
                }
                "rocks" => out.rocks_moved = number(0.0, 1.0)?,
                "dust" => out.dust = number(0.0, 0.9)?,
                other => {
                    return Err(format!(
                        "--change: unknown key `{other}` (tracks, rocks, dust or none)"
                    ))
                }
            }
        }
        Ok(out)
    }

    /// The canonical spec, read back by [`Self::parse`] to the same value
    /// (`none` for [`Self::NONE`]).
    pub fn label(&self) -> String {
        let mut parts = Vec::new();
        if self.tracks > 0 {
            parts.push(format!("tracks={}", self.tracks));
        }
        if self.rocks_moved > 0.0 {
            parts.push(format!("rocks={}", self.rocks_moved));
        }
        if self.dust > 0.0 {
            parts.push(format!("dust={}", self.dust));
        }
        if parts.is_empty() {
            "none".into()
        } else {
            parts.join(",")
        }
    }
}

/// One straight pass of a rover across the depot: a point on its centre line
/// and the line's unit direction.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Pass {
    origin: [f32; 2],
    dir: [f32; 2],
}

impl Pass {
    /// `(along, across)` coordinates of `(x, y)` relative to the centre line.
    fn coords(&self, x: f32, y: f32) -> (f32, f32) {
        let (dx, dy) = (x - self.origin[0], y - self.origin[1]);
        (
            dx * self.dir[0] + dy * self.dir[1],
            -dx * self.dir[1] + dy * self.dir[0],
        )
    }

    /// Whether a wheel or berm comes within [`TUBE_CLEARANCE_M`] of a tube.
    fn runs_over_a_tube(&self) -> bool {
        let reach = 0.5 * WHEEL_WIDTH_M + BERM_WIDTH_M + 0.5 * TUBE_LENGTH_M + TUBE_CLEARANCE_M;
        TUBE_XY_M.iter().any(|t| {
            let (_, across) = self.coords(t[0], t[1]);
            (across.abs() - 0.5 * TRACK_GAUGE_M).abs() < reach
        })
    }

    /// Height change and albedo factor the pass leaves at `(x, y)` on loose
    /// ground, or `None` where it leaves none.
    fn imprint(&self, x: f32, y: f32) -> Option<(f32, f32)> {
        let (along, across) = self.coords(x, y);
        // Distance from the nearer wheel's centre line.
        let d = (across.abs() - 0.5 * TRACK_GAUGE_M).abs();
        let half = 0.5 * WHEEL_WIDTH_M;
        if d < half {
            // Flat-bottomed rut with chevron grousers.
            let u = d / half;
            let floor = RUT_DEPTH_M * (1.0 - u * u * u * u);
            let phase = ((along + 0.5 * d) / GROUSER_PITCH_M).rem_euclid(1.0);
            if phase < 0.35 {
                Some((-(floor + GROUSER_DEPTH_M), GROUSER_ALBEDO))
            } else {
                Some((-floor, TRACK_ALBEDO))
            }
        } else if d < half + BERM_WIDTH_M {
            let t = (d - half) / BERM_WIDTH_M;
            Some((BERM_HEIGHT_M * (PI * t).sin(), 1.0))
        } else {
            None
        }
    }
}

impl Terrain {
    /// The same depot after `change`, drawn from `seed`: rocks moved or
    /// taken away first (their cells regenerated as
    /// [`Terrain::with_pebbles_displaced`] does), then the wheel tracks
    /// pressed into the loose ground, then dust over everything but the sample
    /// tubes. [`DepotChange::NONE`] returns an identical terrain. Meant for a
    /// freshly generated terrain, like the other edits.
    pub fn with_change(&self, seed: u64, change: &DepotChange) -> Terrain {
        let mut out = self.clone();
        if change.is_none() {
            return out;
        }
        let rng = Rng::new(seed).fork(0x4348_414E_4745);
        if change.rocks_moved > 0.0 {
            out.disturb_rocks(rng.fork(1), change.rocks_moved.clamp(0.0, 1.0));
        }
        let passes = draw_passes(rng.fork(2), change.tracks.min(MAX_TRACKS));
        let dust = change.dust.clamp(0.0, 0.9);
        let dseed = rng.fork(3).next_u64();
        out.edit_cells(|x, y, h, a, l| {
            if l == LABEL_SAND {
                for p in &passes {
                    if let Some((dh, fa)) = p.imprint(x, y) {
                        *h += dh;
                        *a *= fa;
                    }
                }
            }
            if dust > 0.0 && l != LABEL_TUBE {
                let cover = (0.5 + fbm(dseed, x, y, 0.8, 3)).clamp(0.0, 1.0);
                let k = (dust * (0.8 + 0.4 * cover)).min(1.0);
                *a += (DUST_ALBEDO - *a) * k;
            }
            *a = a.clamp(0.03, 0.95);
        });
        out.refresh_derived();
        out
    }

    /// Move `frac` of the rocks 5–30 cm or take them away (one in three);
    /// rocks that would come near a tube or leave the grid stay.
    fn disturb_rocks(&mut self, mut rng: Rng, frac: f32) {
        let (nx, ny, x0, y0, c) = (self.nx, self.ny, self.x0, self.y0, self.cell_m);
        let mut keep = vec![true; self.rocks.len()];
        let mut boxes: Vec<CellBox> = Vec::new();
        for (idx, rock) in self.rocks.iter_mut().enumerate() {
            // The same four draws per rock whatever happens, so choices are independent.
            let (pick, remove, dist, ang) = (
                rng.next_f32(),
                rng.next_f32(),
                rng.uniform(0.05, 0.30),
                rng.uniform(0.0, 2.0 * PI),
            );
            if pick >= frac || rock.near_tube(TUBE_CLEARANCE_M) {
                continue;
            }
            let moved = Rock {
                x: rock.x + dist * ang.cos(),
                y: rock.y + dist * ang.sin(),
                ..*rock
            };
            let off_grid = moved.x.abs() >= GRID_HALF_X_M - moved.bound_m()
                || moved.y.abs() >= GRID_HALF_Y_M - moved.bound_m();
            if remove < 1.0 / 3.0 {
                boxes.push(rock.cell_box(x0, y0, c, nx, ny));
                keep[idx] = false;
            } else if !off_grid && !moved.near_tube(TUBE_CLEARANCE_M) {
                boxes.push(rock.cell_box(x0, y0, c, nx, ny));
                *rock = moved;
                boxes.push(rock.cell_box(x0, y0, c, nx, ny));
            }
        }
        if boxes.is_empty() {
            return;
        }
        self.regenerate(&boxes, &keep);
        let mut k = keep.iter();
        self.rocks.retain(|_| k.next().copied().unwrap_or(true));
    }
}

/// `n` passes whose lines cross the depot through a point in its inner half
/// at any heading, each clear of the sample tubes ([`PASS_TRIES`] lines drawn
/// at most; a pass with no clear line is left out).
fn draw_passes(rng: Rng, n: u32) -> Vec<Pass> {
    (0..n)
        .filter_map(|k| {
            let mut r = rng.fork(u64::from(k));
            (0..PASS_TRIES)
                .map(|_| {
                    let origin = [
                        r.uniform(-0.5, 0.5) * DEPOT_HALF_X_M,
                        r.uniform(-0.5, 0.5) * DEPOT_HALF_Y_M,
                    ];
                    let a = r.uniform(0.0, PI);
                    Pass {
                        origin,
                        dir: [a.cos(), a.sin()],
                    }
                })
                .find(|p| !p.runs_over_a_tube())
        })
        .collect()
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
mod tests {
    use super::*;
    use crate::terrain::{TerrainKind, LABEL_ROCK};

    fn change(tracks: u32, rocks_moved: f32, dust: f32) -> DepotChange {
        DepotChange {
            tracks,
            rocks_moved,
            dust,
        }
    }

    /// Verifies: VTSM-SIM-018
    #[test]
    fn no_change_is_the_mapped_depot() {
        let t = Terrain::generate(TerrainKind::Cfa6, 5, 0.04);
        let same = t.with_change(9, &DepotChange::NONE);
        assert_eq!(same.height, t.height);
        assert_eq!(same.albedo, t.albedo);
        assert_eq!(same.rocks, t.rocks);
        assert_eq!(DepotChange::default(), DepotChange::NONE);
    }

    /// Verifies: VTSM-SIM-018
    #[test]
    fn the_spec_reads_back_and_bad_specs_are_refused() {
        for c in [
            DepotChange::NONE,
            change(2, 0.3, 0.0),
            change(0, 0.0, 0.5),
            change(8, 1.0, 0.9),
        ] {
            assert_eq!(DepotChange::parse(&c.label()).unwrap(), c, "{}", c.label());
        }
        for bad in [
            "",
            "tracks=9",
            "tracks=-1",
            "rocks=1.5",
            "dust=NaN",
            "dust=0.95",
            "wheels=2",
            "tracks",
        ] {
            let e = DepotChange::parse(bad).unwrap_err();
            assert!(e.starts_with("--change"), "{bad}: {e}");
        }
    }

    /// Verifies: VTSM-SIM-018
    #[test]
    fn wheel_tracks_press_loose_ground_only_and_are_seeded() {
        let t = Terrain::generate(TerrainKind::Cfa2, 3, 0.01);
        let w = t.with_change(4, &change(2, 0.0, 0.0));
        assert_eq!(w.height, t.with_change(4, &change(2, 0.0, 0.0)).height);
        assert_ne!(w.height, t.with_change(5, &change(2, 0.0, 0.0)).height);
        let (mut deepest, mut pressed, mut raised) = (0.0f32, 0usize, 0usize);
        for k in 0..t.height.len() {
            let dh = w.height[k] - t.height[k];
            if t.label[k] != LABEL_SAND {
                assert_eq!(dh, 0.0, "a rock or tube cell moved");
                assert_eq!(w.albedo[k], t.albedo[k]);
                continue;
            }
            deepest = deepest.min(dh);
            if dh < -0.001 {
                pressed += 1;
                assert!(w.albedo[k] < t.albedo[k] || w.albedo[k] == 0.03);
            } else if dh > 0.0 {
                raised += 1;
                assert!(dh <= 2.0 * BERM_HEIGHT_M + 1e-6);
            }
        }
        // Two passes of two tracks, each WHEEL_WIDTH_M wide and metres long.
        let cells_per_m = (WHEEL_WIDTH_M / t.cell_m) / t.cell_m;
        assert!(
            pressed as f32 > 4.0 * 2.0 * cells_per_m * 0.8,
            "{pressed} cells pressed"
        );
        assert!(raised > pressed / 4, "{raised} berm cells");
        assert!(
            (-2.0 * (RUT_DEPTH_M + GROUSER_DEPTH_M) - 1e-6..-(RUT_DEPTH_M + 0.5 * GROUSER_DEPTH_M))
                .contains(&deepest),
            "deepest {deepest}"
        );
        assert_eq!(w.rocks, t.rocks);
    }

    /// Verifies: VTSM-SIM-018
    #[test]
    fn a_fraction_of_the_rocks_is_moved_or_taken_away() {
        let t = Terrain::generate(TerrainKind::Cfa6, 8, 0.02);
        let d = t.with_change(6, &change(0, 0.3, 0.0));
        let kept: Vec<&Rock> = t.rocks.iter().filter(|r| d.rocks.contains(r)).collect();
        let removed = t.rocks.len() - d.rocks.len();
        let moved = d.rocks.iter().filter(|r| !t.rocks.contains(r)).count();
        let share = (removed + moved) as f32 / t.rocks.len() as f32;
        assert!(t.rocks.len() > 100, "{} rocks", t.rocks.len());
        assert!((0.2..0.4).contains(&share), "{share} disturbed");
        assert!(
            removed > 0 && moved > removed,
            "{removed} removed, {moved} moved"
        );
        assert_eq!(kept.len() + moved, d.rocks.len());
        for r in d.rocks.iter().filter(|r| !t.rocks.contains(r)) {
            let from = t
                .rocks
                .iter()
                .find(|o| o.diameter_m == r.diameter_m && o.shape == r.shape)
                .unwrap();
            let dist = (from.x - r.x).hypot(from.y - r.y);
            assert!((0.0499..=0.3001).contains(&dist), "moved {dist} m");
        }
        // A removed big rock leaves bare ground where it stood.
        let gone = t
            .rocks
            .iter()
            .filter(|r| !d.rocks.iter().any(|n| n.shape == r.shape) && r.diameter_m > 0.1)
            .find(|r| {
                !d.rocks
                    .iter()
                    .any(|n| (n.x - r.x).hypot(n.y - r.y) < n.bound_m() + r.bound_m())
                    && !t.rocks.iter().any(|n| {
                        n != *r && (n.x - r.x).hypot(n.y - r.y) < n.bound_m() + r.bound_m()
                    })
            });
        let r = gone.expect("no big, isolated rock was taken away");
        assert_eq!(t.label(r.x, r.y), LABEL_ROCK);
        assert_eq!(d.label(r.x, r.y), LABEL_SAND);
        // Flagstone has no loose rocks.
        let f = Terrain::generate(TerrainKind::Flagstone, 8, 0.04);
        assert_eq!(f.with_change(6, &change(0, 1.0, 0.0)).height, f.height);
    }

    /// Verifies: VTSM-SIM-018
    #[test]
    fn dust_lowers_albedo_contrast_and_leaves_the_relief() {
        let t = Terrain::generate(TerrainKind::Cfa6, 2, 0.04);
        let sd = |a: &[f32]| {
            let m = a.iter().sum::<f32>() / a.len() as f32;
            (a.iter().map(|v| (v - m) * (v - m)).sum::<f32>() / a.len() as f32).sqrt()
        };
        let d = t.with_change(1, &change(0, 0.0, 0.5));
        assert_eq!(d.height, t.height);
        let ratio = sd(&d.albedo) / sd(&t.albedo);
        assert!((0.35..0.65).contains(&ratio), "contrast × {ratio}");
        let tube = t.label.iter().position(|l| *l == LABEL_TUBE).unwrap();
        assert_eq!(d.albedo[tube], t.albedo[tube]);
    }
}
