//! # vtsm-core
//!
//! The flight core of VTSM (Virtual Template Synthesis and Matching) rover
//! relocalization: given a stereo pair, a textured depot map and a pose prior,
//! render small virtual templates of the map around the prior, match them into
//! the real images with integer normalized cross-correlation, triangulate, and
//! solve the pose with Umeyama + RANSAC, iterating with Stall / Reseed / Anneal /
//! Distribute / Reuse.
//!
//! ## Layers (imports only point down)
//!
//! | layer | modules |
//! |---|---|
//! | engine | [`reloc`] |
//! | stages | [`raster`], [`ncc`] |
//! | geometry & data | [`map`], [`stereo`], [`pose`], [`image`] |
//! | base | [`geom`], [`failure`], [`config`], [`rng`] |
//!
//! ## Guarantees
//!
//! * `#![no_std]`, no `alloc`: every buffer is borrowed from the caller or sized
//!   by a constant from [`config`].
//! * No I/O and no clock reads: time enters as an argument.
//! * No panics on any input: data from cameras, storage and the caller is checked
//!   once by a `new_checked`-style constructor and errors are [`failure::FailureCode`]s.
//! * Every loop is bounded by a constant or a validated parameter of [`config`],
//!   and each stage reports the work it did.
//! * Determinism: the same inputs and seed give bit-identical outputs on every
//!   target (own PRNG, integer raster and NCC, libm for floating-point functions).
#![no_std]
#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::indexing_slicing))]
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

#[macro_use]
mod fmt;

// Lets the shared test scene (`core/testkit/testkit.rs`) name this crate the way
// the examples do.
#[cfg(test)]
extern crate self as vtsm_core;
#[cfg(test)]
#[path = "../testkit/testkit.rs"]
pub(crate) mod testkit;

pub mod config;
pub mod failure;
pub mod frame;
pub mod geom;
pub mod image;
// Integer arithmetic and narrowing casts in the modules that handle raw bytes and
// pixels are audited: each is checked, saturating or wrapping, or sits in a
// function whose `allow` states the bound that keeps it exact.
#[cfg_attr(
    not(test),
    warn(clippy::arithmetic_side_effects, clippy::cast_possible_truncation)
)]
pub mod map;
#[cfg_attr(
    not(test),
    warn(clippy::arithmetic_side_effects, clippy::cast_possible_truncation)
)]
pub mod ncc;
pub mod pose;
#[cfg_attr(
    not(test),
    warn(clippy::arithmetic_side_effects, clippy::cast_possible_truncation)
)]
pub mod raster;
pub mod reloc;
pub mod rng;
#[cfg_attr(
    not(test),
    warn(clippy::arithmetic_side_effects, clippy::cast_possible_truncation)
)]
pub mod stereo;

pub use failure::FailureCode;
/// The nalgebra version the core is built with, so callers use the same types.
pub use nalgebra;
