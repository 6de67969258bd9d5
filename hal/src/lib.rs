//! # vtsm-hal
//!
//! Hardware-abstraction traits for VTSM in the embedded-io style, and a
//! bounded runner that feeds the core from them.
//!
//! | module | what |
//! |---|---|
//! | [`error`] | [`ErrorType`], [`Error`]`::kind()`, [`ErrorKind`], the `(Device, ErrorKind)` → [`FailureCode`](vtsm_core::FailureCode) table |
//! | [`camera`] | [`StereoCamera`], [`FrameInfo`] |
//! | [`clock`] | [`Clock`]: monotonic ticks, optional cycle counter |
//! | [`store`] | [`MapStore`]: ranged reads of the map product |
//! | [`frames`] | [`FrameStore`]: the stereo pair in the camera's memory, read a window at a time; [`StoreFrames`], the core's frame source over it |
//! | [`prior`] | [`PosePrior`], [`PriorEstimate`], [`Covariance`], [`PriorUncertainty`] |
//! | [`telemetry`] | [`Telemetry`], the frame format, [`FramedTelemetry`] over `embedded_io::Write` |
//! | [`runner`] | bounded capture / map read with retries, the step driver |
//!
//! ## Guarantees
//!
//! * `#![no_std]`, no `alloc`, no `unsafe`; every buffer is borrowed per call.
//! * Every trait method is fallible and documents its `# Contract`.
//! * The runner retries only transient faults and only a bounded number of
//!   times; every fault lands in a [`FailureLog`](vtsm_core::failure::FailureLog).
#![no_std]
#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::indexing_slicing))]
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

pub mod camera;
pub mod clock;
pub mod error;
pub mod frames;
pub mod prior;
pub mod runner;
pub mod store;
pub mod telemetry;

pub use camera::{FrameInfo, StereoCamera};
pub use clock::Clock;
pub use error::{failure_code, Device, Error, ErrorKind, ErrorType};
pub use frames::{FrameStore, StoreFrames};
pub use prior::{Covariance, PosePrior, PriorEstimate, PriorUncertainty};
pub use store::MapStore;
pub use telemetry::{FramedTelemetry, Telemetry};
