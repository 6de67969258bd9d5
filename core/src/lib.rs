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
//! ## Start here
//!
//! One relocalization, end to end, on a small built-in map (a textured
//! heightfield 8 m across, built by the crate's test kit; `vtsm map build`
//! makes the same product from a photogrammetry mesh). The caller owns every
//! buffer: the map bytes, the two images and the engine's workspace, sized for
//! the profile by [`reloc::workspace`]. The engine is built once by
//! [`reloc::Setup`], which checks every input, and then stepped with the time
//! as an argument until it reports an [`reloc::Outcome`].
//!
//! ```
//! # #[path = "../testkit/testkit.rs"]
//! # mod testkit;
//! use vtsm_core::geom::Pose;
//! use vtsm_core::image::GrayView;
//! use vtsm_core::map::MapView;
//! use vtsm_core::ncc::Run;
//! use vtsm_core::nalgebra::{UnitQuaternion, Vector3};
//! use vtsm_core::reloc::{workspace::TEST_WORKSPACE, Setup, Workspace};
//!
//! // The map product, checked once; afterwards no accessor can fail.
//! let bytes: Vec<u8> = testkit::build_map(1);
//! let map = MapView::new_checked(&bytes)?;
//!
//! // A rectified 640×480 pair seen from the true pose (rendered from the map
//! // here; on a rover these are the camera's images).
//! let rig = testkit::rig();
//! let truth = testkit::camera_pose(0.6, 0.2);
//! let left = testkit::render_full(&map, &rig.cam(), &truth, 0.85, 20.0);
//! let right = testkit::render_full(&map, &rig.cam(), &rig.world_from_right(&truth), 0.85, 20.0);
//! let left = GrayView::new(&left, 640, 480, 640)?;
//! let right = GrayView::new(&right, 640, 480, 640)?;
//!
//! // The prior: 15 cm and 1° off the truth.
//! let prior = Pose::new(
//!     truth.rotation() * UnitQuaternion::from_scaled_axis(Vector3::z() * 1f32.to_radians()),
//!     truth.translation() + Vector3::new(0.12, -0.09, 0.0),
//! );
//!
//! // The engine's workspace for the test profile, borrowed from the caller.
//! let (mut bytes_ws, mut words, mut runs) = (
//!     vec![0u8; TEST_WORKSPACE.bytes],
//!     vec![0u32; TEST_WORKSPACE.words],
//!     vec![Run::default(); TEST_WORKSPACE.runs],
//! );
//! let ws = Workspace::new(TEST_WORKSPACE, &mut bytes_ws, &mut words, &mut runs)?;
//!
//! // Check everything once, then run the bounded state machine to its end
//! // (`step(now)` does one bounded unit of work at a time instead).
//! let params = testkit::test_params();
//! let seed = 7;
//! let mut engine = Setup::new(&map, left, right, &rig, &params, &prior, seed).build(ws)?;
//! let outcome = engine.run_to_completion(0);
//!
//! assert!(outcome.failure.is_none(), "{:?}", outcome.failure);
//! let (err_m, err_rad) = outcome.pose.error_to(&truth);
//! assert!(err_m < 0.02 && err_rad.to_degrees() < 0.2, "{err_m} m, {err_rad} rad");
//! println!("{} inliers after {} attempts", outcome.quality.inliers, outcome.stats.attempts);
//! # Ok::<(), vtsm_core::FailureCode>(())
//! ```
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
