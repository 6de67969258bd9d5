//! # vtsm-sim
//!
//! Desktop simulator for VTSM: procedural depots, a photometric renderer,
//! photogrammetry-like map products, HAL implementations with fault injection,
//! file formats, evaluation suites and the `vtsm` command line.
#![forbid(unsafe_code)]
