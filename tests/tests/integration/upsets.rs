//! A handful of single-bit upsets, bounded: every flip of the stored map
//! product is detected at load by the runner's check, and the engine's upset
//! hook reaches every region. The full
//! campaign is `tests/src/bin/upsets.rs` (report in `fsw-docs/eval/upsets.md`).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use vtsm_core::reloc::UpsetRegion;
use vtsm_core::rng::Rng;
use vtsm_core::FailureCode;
use vtsm_tests::scene::Scene;
use vtsm_tests::upsets::{clean_run, engine_run, map_regions, map_trial, params, Class};

/// Map flips in this test: enough to land in several sections, few enough to
/// stay in seconds (each is one checked load of a 1.7 MB product).
const MAP_FLIPS: u32 = 12;

/// Every single-bit flip of the stored product is refused at load with a map
/// code; outside the magic and version fields (checked before the header CRC)
/// the code is the CRC's.
///
/// Verifies: VTSM-SIM-015, VTSM-MAP-003
#[test]
fn map_flips_in_storage_are_all_detected_at_load() {
    let scene = Scene::test_profile();
    let clean = clean_run(&scene).unwrap();
    assert_eq!(clean.failure, None);
    let mut rng = Rng::new(7);
    let mut regions = std::collections::BTreeSet::new();
    for _ in 0..MAP_FLIPS {
        let t = map_trial(&scene, &clean, &mut rng, false);
        println!("{} bit {}: {:?} {:?}", t.region, t.bit, t.class, t.code);
        assert_eq!(t.class, Class::DetectedAtLoad, "{t:?}");
        if t.bit >= 12 * 8 {
            assert_eq!(t.code, Some(FailureCode::MapCrcMismatch), "{t:?}");
        }
        regions.insert(t.region);
    }
    assert!(regions.len() >= 2, "{regions:?}");
    let names: Vec<&str> = map_regions(&scene.map).iter().map(|r| r.0).collect();
    assert_eq!(names.len(), 7);
}

/// With the hook unused, the directly stepped engine is the runner's run bit
/// for bit; with it, a flip lands in every region late in the run, and the
/// run still ends within the engine's structural work bound.
///
/// Verifies: VTSM-SIM-015
#[test]
fn engine_upset_hook_reaches_every_region() {
    let scene = Scene::test_profile();
    let clean = clean_run(&scene).unwrap();
    let (direct, none) = engine_run(&scene, None, &mut Rng::new(0)).unwrap();
    assert_eq!(none, None);
    assert_eq!(direct.stats, clean.stats);
    assert_eq!(
        direct.pose.t().map(f32::to_bits),
        clean.pose.t().map(f32::to_bits)
    );
    // Flip late in the run, when every region holds something.
    let late = clean.stats.work_units.saturating_sub(2);
    for region in UpsetRegion::ALL {
        let (o, flipped) = engine_run(&scene, Some((region, late)), &mut Rng::new(3)).unwrap();
        let (unit, _) = flipped.unwrap_or_else(|| panic!("{region:?} stayed empty"));
        assert!(unit >= late);
        let cap = <vtsm_core::reloc::Engine>::max_work_units(&params());
        assert!(o.stats.work_units <= cap, "{region:?}");
    }
}
