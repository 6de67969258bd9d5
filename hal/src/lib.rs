//! # vtsm-hal
//!
//! Hardware-abstraction traits (stereo camera, clock, map storage, pose prior,
//! telemetry) in the embedded-io style, and a bounded runner that feeds the core.
#![no_std]
#![forbid(unsafe_code)]
