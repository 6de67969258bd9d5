//! Determinism across targets: the workload of `tests/firmware/src/workload.rs`
//! runs here on the host and, in CI, as a Cortex-M7 image under QEMU
//! (`.ci/run`, step "firmware under QEMU"). Both must print the digest checked in
//! at `tests/firmware/expected-digest.txt`.

mod workload_mod {
    #![allow(dead_code, missing_docs)]
    use vtsm_core::nalgebra;
    include!("../firmware/src/workload.rs");
}

/// Verifies: VTSM-RNG-002
#[test]
fn host_digest_matches_the_checked_in_cross_target_digest() {
    let expected = include_str!("../firmware/expected-digest.txt").trim();
    let got = format!("{:016x}", workload_mod::workload());
    assert_eq!(
        got, expected,
        "host digest differs from the bare-metal digest on record"
    );
}
