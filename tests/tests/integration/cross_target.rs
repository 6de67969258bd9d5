//! Determinism across targets: the workload of `tests/firmware/src/workload.rs`
//! (PRNG, geometry, map encoding, rasterized stereo images and a complete
//! relocalization) runs here on the host and, in CI, as a Cortex-M7 image under
//! QEMU (`.ci/run`, step "firmware under QEMU"). Both must produce the digest
//! checked in at `tests/firmware/expected-digest.txt`.

#![allow(clippy::panic)] // test-only helper below panics by design

use vtsm_tests::workload as workload_mod;

/// The workload keeps its buffers on the stack, as the firmware does.
fn on_big_stack<T: Send + 'static>(f: fn() -> T) -> T {
    let handle = std::thread::Builder::new().stack_size(64 << 20).spawn(f);
    match handle.map(std::thread::JoinHandle::join) {
        Ok(Ok(v)) => v,
        Ok(Err(p)) => std::panic::resume_unwind(p),
        Err(e) => panic!("cannot spawn the workload thread: {e}"),
    }
}

/// Verifies: VTSM-RNG-002
#[test]
fn host_digest_matches_the_checked_in_cross_target_digest() {
    let expected = include_str!("../../firmware/expected-digest.txt").trim();
    let got = format!("{:016x}", on_big_stack(workload_mod::workload));
    assert_eq!(
        got, expected,
        "host digest differs from the bare-metal digest on record"
    );
}

/// Verifies: VTSM-RELOC-001
#[test]
fn workload_relocalization_converges() {
    let s = on_big_stack(|| workload_mod::relocalization(&|| 0));
    assert!(s.success, "failure code 0x{:04x}", s.failure);
    assert!(
        s.initial_error_um > 100_000,
        "prior must start over 10 cm off"
    );
    assert!(
        s.final_error_um < 50_000,
        "final error {} µm",
        s.final_error_um
    );
}

/// The workload runs the flight path: the HAL runner captures the pair, reads
/// the map and the prior through the bare-metal device set, steps the engine
/// 16 work units at a time and sends the outcome and the failure counters.
///
/// Verifies: VTSM-HAL-024
#[test]
fn workload_relocalizes_through_the_runner() {
    let s = on_big_stack(|| workload_mod::relocalization(&|| 0));
    assert!(s.success, "failure code 0x{:04x}", s.failure);
    // One step per 16 attempts or RANSAC chunks, plus the last one.
    assert!(
        s.steps > s.attempts / 16,
        "{} steps for {} attempts",
        s.steps,
        s.attempts
    );
    assert_eq!(s.telemetry_frames, 2, "outcome and failure-counter frames");
    assert!(
        s.telemetry_bytes >= 42,
        "{} payload bytes",
        s.telemetry_bytes
    );
}
