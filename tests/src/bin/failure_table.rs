//! Print `fsw-docs/failure-codes.md`, generated from `FailureCode::ALL`.
//!
//! `cargo run -p vtsm-tests --bin failure_table > fsw-docs/failure-codes.md`

fn main() {
    print!("{}", vtsm_tests::failure_table_markdown());
}
