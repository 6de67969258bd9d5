//! Memory budget of the relocalization engine: `size_of` of the engine state
//! and of its outcome, and the byte counts of the pipeline workspace at the
//! paper profile (ℓ = 256, search window 1024², coarse-to-fine) and the test
//! profile (ℓ = 64, search window 256²). Recorded in `fsw-docs/budgets/memory.md`.
//!
//! ```text
//! cargo run -p vtsm-core --example budget_memory
//! ```
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use core::mem::size_of;
use vtsm_core::ncc::{Run, Search};
use vtsm_core::reloc::workspace::{PAPER_WORKSPACE, TEST_WORKSPACE};
use vtsm_core::reloc::{
    Outcome, Pipeline, RansacSolver, Relocalizer, Stats, WorkspaceSizes, PAPER_WORKSPACE_BYTES,
    TEST_WORKSPACE_BYTES,
};

fn print_workspace(name: &str, s: &WorkspaceSizes) {
    let l = s.template_px;
    println!("{name}: template {l}x{l}, search {w}x{w}", w = s.search_px);
    println!("  templates+masks  u8  {:>10} B  (4 x {l}^2)", 4 * l * l);
    println!(
        "  depth+mask depth u32 {:>10} B  (4 x {l}^2 x 4)",
        16 * l * l
    );
    println!("  ncc window       u8  {:>10} B", s.ncc.window);
    println!("  ncc template     u8  {:>10} B", s.ncc.template);
    println!("  ncc integral     u32 {:>10} B", 4 * s.ncc.integral);
    println!(
        "  ncc runs         Run {:>10} B  ({} x {} B)",
        s.runs * size_of::<Run>(),
        s.runs,
        size_of::<Run>()
    );
    println!("  total                {:>10} B", s.total_bytes());
}

fn main() {
    let engine = size_of::<Relocalizer<(), ()>>();
    let full = size_of::<Relocalizer<Pipeline<'static, 'static>, RansacSolver>>();
    println!("engine state (Relocalizer without pipeline/solver): {engine} B");
    println!("Relocalizer<Pipeline, RansacSolver> (by value, workspace borrowed): {full} B");
    println!(
        "Pipeline (views + borrowed workspace): {} B",
        size_of::<Pipeline<'static, 'static>>()
    );
    println!(
        "Outcome: {} B (Stats {} B)",
        size_of::<Outcome>(),
        size_of::<Stats>()
    );
    print_workspace("paper workspace", &PAPER_WORKSPACE);
    print_workspace("test workspace", &TEST_WORKSPACE);
    let exhaustive = WorkspaceSizes::new(256, 1024, Search::Exhaustive);
    println!(
        "paper workspace, exhaustive search: {} B",
        exhaustive.total_bytes()
    );
    println!("PAPER_WORKSPACE_BYTES = {PAPER_WORKSPACE_BYTES}");
    println!("TEST_WORKSPACE_BYTES = {TEST_WORKSPACE_BYTES}");
}
