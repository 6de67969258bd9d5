//! The frame-store path: the camera keeps the pair in its own memory and the
//! engine reads each search window (and the preflight's rows) from it through
//! `Runner::relocalize_from_store`. Same pixels ⇒ the same outcome as the
//! path that captures the whole pair into RAM; a window read that fails
//! after its retries ends the relocalization in its failure code.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use vtsm_core::reloc::Outcome;
use vtsm_core::FailureCode;
use vtsm_hal::telemetry::{parse_outcome, FrameKind};
use vtsm_sim::devices::FaultConfig;
use vtsm_sim::locate::{run, DeviceFaults, DeviceRun, PairPath, Request, RunOptions};
use vtsm_tests::scene::{scene, RELOC_SEED};
use vtsm_tests::testkit;

fn request(map: &[u8]) -> Request<'_> {
    scene()
        .request(map, RELOC_SEED)
        .with_params(vtsm_core::config::Params {
            attempts_per_iter: 300,
            ..testkit::test_params()
        })
}

fn from_store(window_faults: FaultConfig) -> DeviceRun {
    let faults = DeviceFaults {
        seed: 11,
        ..DeviceFaults::default()
    };
    run(
        &request(&scene().map),
        RunOptions::default().faults(faults).path(PairPath::Store {
            window_faults,
            map_in_place: false,
        }),
    )
    .unwrap()
}

fn bits(o: &Outcome) -> Vec<u32> {
    o.pose
        .t()
        .into_iter()
        .chain(o.pose.q())
        .map(f32::to_bits)
        .collect()
}

/// Verifies: VTSM-HAL-027
#[test]
fn reading_windows_from_the_store_gives_the_outcome_of_the_pair_in_ram() {
    let ram = run(&request(&scene().map), RunOptions::default()).unwrap();
    let store = from_store(FaultConfig::NONE);
    let (r, _) = ram.result.as_ref().unwrap();
    let (s, rep) = store.result.as_ref().unwrap();
    assert_eq!(r.failure, None);
    assert_eq!(bits(s), bits(r));
    assert_eq!(s.stats, r.stats);
    assert_eq!(s.quality, r.quality);
    assert_eq!(s.failure, r.failure);
    // Preflight rows (two per eye per sampled row) and at most two windows
    // per attempt, each read once.
    let w = rep.windows;
    println!("windows {w:?}, attempts {}", s.stats.attempts);
    assert_eq!(w.reads, w.windows);
    assert_eq!(w.failed_reads, 0);
    assert!(w.windows > 2 * 64);
    assert!(w.windows <= 2 * 64 + 2 * s.stats.attempts);
    assert_eq!(store.log.count(FailureCode::HalFrameStoreRead), 0);
}

/// A store whose every window read times out (or is cut short) fails the
/// preflight's first read after its retries: the relocalization ends at once
/// with `RELOC_FRAME_READ_FAILED` in its outcome (downlinked), and each failed
/// read is in the runner's log as `HAL_FRAME_STORE_READ`.
///
/// Verifies: VTSM-HAL-027, VTSM-RELOC-037
#[test]
fn a_failing_frame_store_ends_in_its_failure_code() {
    let timeouts = FaultConfig {
        timeout_pct: 100,
        ..FaultConfig::NONE
    };
    let truncations = FaultConfig {
        truncate_pct: 100,
        ..FaultConfig::NONE
    };
    for faults in [timeouts, truncations] {
        let run = from_store(faults);
        let (o, rep) = run.result.as_ref().unwrap();
        assert_eq!(
            o.failure,
            Some(FailureCode::RelocFrameReadFailed),
            "{faults:?}"
        );
        assert_eq!(o.stats.attempts, 0);
        // The runner's three attempts at the first read.
        assert_eq!((rep.windows.windows, rep.windows.reads), (1, 3));
        assert_eq!(run.log.count(FailureCode::HalFrameStoreRead), 3);
        let sent = run
            .telemetry
            .iter()
            .find(|f| f.kind == FrameKind::Outcome as u8)
            .and_then(|f| parse_outcome(&f.payload))
            .unwrap();
        assert_eq!(sent.failure, FailureCode::RelocFrameReadFailed.code());
    }
}

/// Occasional faults are retried: the run either recovers every read (and
/// gives the clean outcome bit for bit) or ends in the read failure; every
/// failed read is counted and logged either way.
///
/// Verifies: VTSM-HAL-027
#[test]
fn occasional_window_faults_are_retried_and_counted() {
    let clean = from_store(FaultConfig::NONE);
    let (c, _) = clean.result.as_ref().unwrap();
    let run = from_store(FaultConfig {
        timeout_pct: 3,
        truncate_pct: 3,
        ..FaultConfig::NONE
    });
    let (o, rep) = run.result.as_ref().unwrap();
    let w = rep.windows;
    println!("{:?}: {w:?}", o.failure);
    assert!(w.failed_reads > 0 && w.reads == w.windows + w.failed_reads);
    assert_eq!(
        u32::from(run.log.count(FailureCode::HalFrameStoreRead)),
        w.failed_reads
    );
    match o.failure {
        Some(FailureCode::RelocFrameReadFailed) => {}
        _ => {
            assert_eq!(bits(o), bits(c));
            assert_eq!(o.stats, c.stats);
        }
    }
}

fn in_place(map: &[u8]) -> DeviceRun {
    run(
        &request(map),
        RunOptions::default().path(PairPath::Store {
            window_faults: FaultConfig::NONE,
            map_in_place: true,
        }),
    )
    .unwrap()
}

/// A memory-mapped map store: the product is checked and used in place,
/// without a single `read_range` call, and the outcome is the one of the
/// product read into RAM, bit for bit.
///
/// Verifies: VTSM-HAL-028
#[test]
fn a_memory_mapped_map_is_used_in_place_with_the_same_outcome() {
    let copied = from_store(FaultConfig::NONE);
    let mapped = in_place(&scene().map);
    let (c, crep) = copied.result.as_ref().unwrap();
    let (m, mrep) = mapped.result.as_ref().unwrap();
    assert_eq!(c.failure, None);
    assert_eq!(bits(m), bits(c));
    assert_eq!(m.stats, c.stats);
    assert_eq!(m.quality, c.quality);
    assert_eq!(m.failure, c.failure);
    assert!(!crep.map_read.in_place && crep.map_read.reads > 0);
    assert!(mrep.map_read.in_place);
    assert_eq!(mrep.map_read.reads, 0);
    assert_eq!(mrep.map_read.len, crep.map_read.len);
    assert_eq!(mrep.windows, crep.windows);
    // The flight path's counts: one check of the product (in place, or in
    // the retry loop after the read), the pair never copied out of the
    // camera's memory.
    assert_eq!((mrep.map_read.checks, crep.map_read.checks), (1, 1));
    assert_eq!((mapped.pair_copies, copied.pair_copies), (0, 0));
}

/// A damaged mapped product ends in the failure code the copied product ends
/// in, logged once (no re-read); a cut one in `MAP_TRUNCATED`; an empty one in
/// `HAL_MAP_TOO_LARGE`.
///
/// Verifies: VTSM-HAL-028
#[test]
fn a_damaged_or_empty_mapped_map_ends_in_its_failure_code() {
    let mut bad = scene().map.clone();
    let mid = bad.len() / 2;
    bad[mid] ^= 0x10;
    let copied = run(
        &request(&bad),
        RunOptions::default().path(PairPath::Store {
            window_faults: FaultConfig::NONE,
            map_in_place: false,
        }),
    )
    .unwrap();
    let mapped = in_place(&bad);
    let code = mapped.result.as_ref().unwrap_err();
    assert_eq!(copied.result.as_ref().unwrap_err(), code);
    assert_eq!(*code, FailureCode::MapCrcMismatch);
    assert_eq!(mapped.log.count(FailureCode::MapCrcMismatch), 1);
    // A product cut short in the mapped memory (a partial write, a wrong
    // length in the store's directory) ends in its own code, like a short read.
    let cut = in_place(&scene().map[..scene().map.len() / 2]);
    let code = *cut.result.as_ref().unwrap_err();
    assert_eq!(code, FailureCode::MapTruncated);
    assert_eq!(cut.log.count(code), 1);
    let empty = in_place(&[]);
    assert_eq!(
        empty.result.as_ref().unwrap_err(),
        &FailureCode::HalMapTooLarge
    );
    assert_eq!(empty.log.count(FailureCode::HalMapTooLarge), 1);
}
