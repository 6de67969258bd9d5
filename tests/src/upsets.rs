//! Single-bit-upset campaign in the simulator: seeded, deterministic trials
//! that each flip one bit and classify how the relocalization ended.
//!
//! Three campaigns, all on the test-kit scene ([`Scene`]: an 8 m textured heightfield,
//! a 640×480 pair, the test profile ℓ = 64, N_corr = 40):
//! * **map in storage**: one bit of the stored map product is flipped and the
//!   relocalization runs through the HAL runner (`locate::run`), which
//!   checks the product at load;
//! * **map, CRC-blind**: the same flip, then every CRC recomputed
//!   (`map::reseal`), as if the bit had flipped before the CRCs were computed
//!   or after the load check: what the structural checks and the engine do
//!   with a damaged map the CRCs cannot see;
//! * **engine memory**: the engine is built with the core's one constructor
//!   and stepped one work unit at a time (the runner's outcome does not depend
//!   on the step granularity); between two steps one bit of one region of its
//!   workspace or state ([`UpsetRegion`]) is flipped, then it runs to the end.
//!
//! Each trial is compared with the clean run: [`Class`].

use crate::scene::{Scene, RELOC_SEED};
use crate::testkit;
use std::collections::BTreeMap;
use vtsm_core::geom::Pose;
use vtsm_core::image::GrayView;
use vtsm_core::map::{self, MapView};
use vtsm_core::ncc::Run;
use vtsm_core::reloc::{Outcome, Setup, StepResult, UpsetRegion, Workspace};
use vtsm_core::rng::Rng;
use vtsm_core::FailureCode;
use vtsm_sim::locate::{run, workspace_sizes, RunOptions};

/// How one upset trial ended, compared with the clean run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Class {
    /// The runner refused the map at load (CRC or structural check).
    DetectedAtLoad,
    /// The relocalization ended with a failure code (no pose) where the
    /// clean run returned one: the upset became a no-fix, not a wrong fix.
    DetectedLater,
    /// Same pose as the clean run, bit for bit.
    Identical,
    /// A pose within 1 mm of the clean run's.
    Tolerated,
    /// A pose more than 1 mm from the clean run's, still within 5 cm of the truth.
    Degraded,
    /// A pose more than 5 cm from the truth, returned as a success.
    WrongPose,
    /// Anything else (a runner error that is not a map check, or an outcome
    /// whose failure differs from the clean run's while that one also failed).
    Other,
}

impl Class {
    /// Every class, in table order.
    pub const ALL: [Class; 7] = [
        Class::DetectedAtLoad,
        Class::DetectedLater,
        Class::Identical,
        Class::Tolerated,
        Class::Degraded,
        Class::WrongPose,
        Class::Other,
    ];

    /// Column title.
    pub const fn name(self) -> &'static str {
        match self {
            Class::DetectedAtLoad => "detected at load",
            Class::DetectedLater => "detected later (no pose)",
            Class::Identical => "tolerated: identical",
            Class::Tolerated => "tolerated: ≤ 1 mm",
            Class::Degraded => "degraded: ≤ 5 cm",
            Class::WrongPose => "wrong pose: > 5 cm",
            Class::Other => "other",
        }
    }
}

/// One trial.
#[derive(Clone, Debug)]
pub struct Trial {
    /// Region the bit was in.
    pub region: &'static str,
    /// Bit index within the region.
    pub bit: u64,
    /// Engine work units done before the flip (engine campaign), else 0.
    pub before_unit: u32,
    /// How it ended.
    pub class: Class,
    /// The failure code it ended with, if any.
    pub code: Option<FailureCode>,
    /// Pose error to the truth, metres, when a pose was returned.
    pub error_m: Option<f32>,
}

/// Regions of the map product: the header and the six sections, by the
/// header's section table. `(name, start, end)`.
pub fn map_regions(bytes: &[u8]) -> Vec<(&'static str, usize, usize)> {
    const NAMES: [&str; 6] = [
        "tiles",
        "vertices",
        "triangles",
        "uvs",
        "texture",
        "mask vertices",
    ];
    let rd = |off: usize| {
        bytes
            .get(off..off + 4)
            .and_then(|b| b.try_into().ok())
            .map_or(0, |b: [u8; 4]| u32::from_le_bytes(b) as usize)
    };
    let header_len = rd(12);
    let mut out = vec![("header", 0, header_len)];
    for (i, name) in NAMES.iter().enumerate() {
        let e = 76 + 12 * i;
        let (off, len) = (rd(e), rd(e + 4));
        out.push((name, off, off + len));
    }
    out
}

fn region_of(regions: &[(&'static str, usize, usize)], byte: usize) -> &'static str {
    regions
        .iter()
        .find(|(_, a, b)| (*a..*b).contains(&byte))
        .map_or("outside", |r| r.0)
}

/// Pose error of `o` to the truth, metres, if it returned a pose.
fn classify(
    o: &Outcome,
    clean: &Outcome,
    truth: &Pose,
) -> (Class, Option<FailureCode>, Option<f32>) {
    if o.failure.is_some() && o.failure == clean.failure && o.pose.to_bits() == clean.pose.to_bits()
    {
        return (Class::Identical, o.failure, None);
    }
    match (o.failure, clean.failure) {
        (None, None) => {
            let (e, _) = o.pose.error_to(truth);
            let (d, _) = o.pose.error_to(&clean.pose);
            let class = if o.pose.to_bits() == clean.pose.to_bits() {
                Class::Identical
            } else if d <= 1.0e-3 {
                Class::Tolerated
            } else if e <= 0.05 {
                Class::Degraded
            } else {
                Class::WrongPose
            };
            (class, None, Some(e))
        }
        (Some(code), None) => (Class::DetectedLater, Some(code), None),
        (code, _) => (Class::Other, code, None),
    }
}

/// The relocalization parameters of every trial: the test profile.
pub fn params() -> vtsm_core::config::Params {
    testkit::test_params()
}

/// The clean run through the runner.
///
/// # Errors
/// The runner's failure code, if the clean scene does not relocalize.
pub fn clean_run(scene: &Scene) -> Result<Outcome, FailureCode> {
    let req = scene.request(&scene.map, RELOC_SEED);
    let run = run(&req, RunOptions::default()).map_err(|_| FailureCode::ConfigParamOutOfRange)?;
    run.result.map(|(o, _)| o)
}

/// Flip one bit of the map, uniformly over its bits, and run it through the
/// runner; with `reseal`, recompute the CRCs first (CRC-blind).
pub fn map_trial(scene: &Scene, clean: &Outcome, rng: &mut Rng, reseal: bool) -> Trial {
    let regions = map_regions(&scene.map);
    let n = scene.map.len() as u64 * 8;
    let bit = below_u64(rng, n);
    let byte = (bit / 8) as usize;
    let mut bytes = scene.map.clone();
    if let Some(b) = bytes.get_mut(byte) {
        *b ^= 1 << (bit % 8);
    }
    if reseal {
        // A flip in the section table can make the sections unreadable; the
        // product then stays as it is and the load check sees it.
        let _ = map::reseal(&mut bytes);
    }
    let region = region_of(&regions, byte);
    let req = scene.request(&bytes, RELOC_SEED);
    let result = run(&req, RunOptions::default()).map(|r| r.result);
    let (class, code, error_m) = match result {
        Ok(Ok((o, _))) => classify(&o, clean, &scene.truth),
        Ok(Err(code)) if code.group() == 0x03 => (Class::DetectedAtLoad, Some(code), None),
        Ok(Err(code)) => (Class::Other, Some(code), None),
        Err(_) => (Class::Other, None, None),
    };
    Trial {
        region,
        bit,
        before_unit: 0,
        class,
        code,
        error_m,
    }
}

fn below_u64(rng: &mut Rng, n: u64) -> u64 {
    if n == 0 {
        return 0;
    }
    ((u128::from(rng.next_u64()) * u128::from(n)) >> 64) as u64
}

/// Build the engine over fresh heap workspace and run it, flipping one bit
/// of `region` after `before_unit` work units (the first unit at or after it
/// where the region is not empty). `None` for `region` runs it clean.
///
/// Returns the outcome, the unit the flip happened after and the bit (or
/// `None` if the region stayed empty until the end).
///
/// # Errors
/// The engine constructor's failure code.
pub fn engine_run(
    scene: &Scene,
    upset: Option<(UpsetRegion, u32)>,
    rng: &mut Rng,
) -> Result<(Outcome, Option<(u32, u64)>), FailureCode> {
    let view = MapView::new_checked(&scene.map)?;
    let rig = testkit::rig();
    let params = testkit::test_params();
    let (w, h) = (rig.cam().width() as usize, rig.cam().height() as usize);
    let left = GrayView::new(&scene.left, w, h, w)?;
    let right = GrayView::new(&scene.right, w, h, w)?;
    let sizes = workspace_sizes(&params);
    let mut bytes = vec![0u8; sizes.bytes];
    let mut words = vec![0u32; sizes.words];
    let mut runs = vec![Run::default(); sizes.runs];
    let ws = Workspace::new(sizes, &mut bytes, &mut words, &mut runs)?;
    let setup = Setup::new(&view, left, right, &rig, &params, &scene.prior, RELOC_SEED);
    let mut engine = setup.build(ws)?;
    let cap = <vtsm_core::reloc::Engine>::max_work_units(&params);
    let mut flipped = None;
    for unit in 0..=cap {
        if let Some((region, at)) = upset {
            if flipped.is_none() && unit >= at {
                let n = engine.upset_bits(region);
                if n > 0 {
                    let bit = below_u64(rng, n);
                    if engine.flip_bit(region, bit) {
                        flipped = Some((unit, bit));
                    }
                }
            }
        }
        if let StepResult::Done(_) = engine.step(0) {
            break;
        }
    }
    Ok((engine.stop(0).clone(), flipped))
}

/// One engine trial: a uniformly drawn unit of the clean run's length, one
/// bit of `region`.
pub fn engine_trial(
    scene: &Scene,
    clean: &Outcome,
    region: UpsetRegion,
    rng: &mut Rng,
) -> Option<Trial> {
    let at = rng.below(clean.stats.work_units.max(1));
    let (o, flipped) = engine_run(scene, Some((region, at)), rng).ok()?;
    let (unit, bit) = flipped?;
    let (class, code, error_m) = classify(&o, clean, &scene.truth);
    Some(Trial {
        region: region.name(),
        bit,
        before_unit: unit,
        class,
        code,
        error_m,
    })
}

/// Counts per region and class, and the codes seen per region.
#[derive(Default)]
pub struct Table {
    /// `region → class → count`.
    pub counts: BTreeMap<String, BTreeMap<Class, u32>>,
    /// `region → code → count`.
    pub codes: BTreeMap<String, BTreeMap<&'static str, u32>>,
    /// Engine flips that found their region empty until the end of the run.
    pub empty: BTreeMap<String, u32>,
    /// Region order of first appearance.
    pub order: Vec<String>,
}

impl Table {
    /// Count one trial.
    pub fn add(&mut self, t: &Trial) {
        let r = t.region.to_string();
        if !self.order.contains(&r) {
            self.order.push(r.clone());
        }
        *self
            .counts
            .entry(r.clone())
            .or_default()
            .entry(t.class)
            .or_default() += 1;
        if let Some(c) = t.code {
            *self
                .codes
                .entry(r)
                .or_default()
                .entry(c.name())
                .or_default() += 1;
        }
    }

    /// Count an engine flip whose region stayed empty.
    pub fn add_empty(&mut self, region: &str) {
        if !self.order.contains(&region.to_string()) {
            self.order.push(region.to_string());
        }
        *self.empty.entry(region.to_string()).or_default() += 1;
    }

    /// Total of one class.
    pub fn total(&self, class: Class) -> u32 {
        self.counts
            .values()
            .map(|m| m.get(&class).copied().unwrap_or(0))
            .sum()
    }

    /// The table as Markdown rows (header included), one row per region and a total row.
    pub fn markdown(&self, with_empty: bool) -> String {
        let mut s = String::from("| region | trials |");
        for c in Class::ALL {
            s += &format!(" {} |", c.name());
        }
        if with_empty {
            s += " region empty |";
        }
        s += " codes |\n|---|---:|";
        for _ in Class::ALL {
            s += "---:|";
        }
        if with_empty {
            s += "---:|";
        }
        s += "---|\n";
        let mut totals = [0u32; Class::ALL.len()];
        let mut total_empty = 0;
        for r in &self.order {
            let m = self.counts.get(r).cloned().unwrap_or_default();
            let empty = self.empty.get(r).copied().unwrap_or(0);
            let n: u32 = m.values().sum::<u32>() + empty;
            s += &format!("| {r} | {n} |");
            for (i, c) in Class::ALL.iter().enumerate() {
                let k = m.get(c).copied().unwrap_or(0);
                totals[i] += k;
                s += &format!(" {k} |");
            }
            if with_empty {
                total_empty += empty;
                s += &format!(" {empty} |");
            }
            let codes = self
                .codes
                .get(r)
                .map(|m| {
                    m.iter()
                        .map(|(c, n)| format!("`{c}` {n}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                })
                .unwrap_or_default();
            s += &format!(" {codes} |\n");
        }
        let n: u32 = totals.iter().sum::<u32>() + total_empty;
        s += &format!("| **all** | **{n}** |");
        for t in totals {
            s += &format!(" **{t}** |");
        }
        if with_empty {
            s += &format!(" **{total_empty}** |");
        }
        s += " |\n";
        s
    }
}

/// Run `flips` map-in-storage trials from `seed`.
pub fn map_campaign(scene: &Scene, clean: &Outcome, flips: u32, seed: u64, reseal: bool) -> Table {
    let mut rng = Rng::new(seed).fork(u64::from(reseal));
    let mut t = Table::default();
    for _ in 0..flips {
        t.add(&map_trial(scene, clean, &mut rng, reseal));
    }
    t
}

/// Run `flips_per_region` engine trials in every [`UpsetRegion`] from `seed`.
pub fn engine_campaign(scene: &Scene, clean: &Outcome, flips_per_region: u32, seed: u64) -> Table {
    let mut t = Table::default();
    for (i, region) in UpsetRegion::ALL.iter().enumerate() {
        let mut rng = Rng::new(seed).fork(2 + i as u64);
        for _ in 0..flips_per_region {
            match engine_trial(scene, clean, *region, &mut rng) {
                Some(trial) => t.add(&trial),
                None => t.add_empty(region.name()),
            }
        }
    }
    t
}
