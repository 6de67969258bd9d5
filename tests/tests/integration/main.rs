//! The system tests of vtsm: end-to-end relocalization on simulated and
//! physical inputs, the runner and its fault scenarios, upsets, integrity,
//! fuzzing, the failure-code table, traceability and the cross-target digest.
//!
//! One test binary with one module per former file, so the workspace links
//! the simulator into one test executable here instead of fifteen. Run one
//! module with a filter: `cargo test -p vtsm-tests --test integration -- traceability::`.

mod cross_target;
mod e2e_acceptance;
mod e2e_budget;
mod e2e_file_path;
mod e2e_georef;
mod e2e_physical;
mod e2e_relight;
mod e2e_uncertainty;
mod failure_codes;
mod fault_scenarios;
mod frame_store;
mod fuzz_smoke;
mod integrity;
mod runner_path;
mod scenes;
mod traceability;
mod upsets;
