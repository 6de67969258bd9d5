//! The `vtsm` command line.

fn main() {}
