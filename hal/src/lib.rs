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
//! | [`pool`] | [`AttemptPool`]: workers for a relocalization's attempts, same outcome for any number |
//!
//! ## Start here
//!
//! A flight integrator implements five small traits for its devices — a
//! stereo camera, a clock, the map store, the pose-prior source and the
//! telemetry link — and makes one call, [`runner::Runner::run`], per
//! relocalization: a [`runner::Job`] (rig, parameters, seed, limits, upset
//! checks), the map product's RAM (unused when the store is memory-mapped, as
//! here), where the stereo pair goes ([`runner::RamPair`] into RAM, or
//! [`runner::InStore`] left in the camera's frame memory) and the engine's
//! workspace. The runner reads and checks the map product, the prior and the
//! pair with bounded retries, builds the engine and drives it under the
//! job's step, work and tick budget; every fault lands in the failure log and
//! the outcome goes out as telemetry.
//!
//! ```
//! # #[path = "../../core/testkit/testkit.rs"]
//! # mod testkit;
//! use core::convert::Infallible;
//! use vtsm_core::geom::Pose;
//! use vtsm_core::nalgebra::Vector3;
//! use vtsm_core::ncc::Run;
//! use vtsm_core::reloc::{workspace::TEST_WORKSPACE, Workspace};
//! use vtsm_hal::runner::{DriveLimits, Job, RamPair, Runner, RunnerConfig, VerifyChecks};
//! use vtsm_hal::{Clock, Covariance, ErrorType, FrameInfo, MapStore, PosePrior};
//! use vtsm_hal::{PriorEstimate, StereoCamera, Telemetry};
//!
//! /// A camera that always delivers the same rectified pair.
//! struct Camera { left: Vec<u8>, right: Vec<u8>, sequence: u32 }
//! impl ErrorType for Camera { type Error = Infallible; }
//! impl StereoCamera for Camera {
//!     fn capture(&mut self, l: &mut [u8], r: &mut [u8], _: u64) -> Result<FrameInfo, Infallible> {
//!         l[..self.left.len()].copy_from_slice(&self.left);
//!         r[..self.right.len()].copy_from_slice(&self.right);
//!         self.sequence += 1;
//!         Ok(FrameInfo { width: 640, height: 480, stride: 640, sequence: self.sequence,
//!                        timestamp_ticks: 0, exposure_us: 2_000 })
//!     }
//! }
//! /// A clock that does not move (a host would read its monotonic timer).
//! struct Ticks;
//! impl ErrorType for Ticks { type Error = Infallible; }
//! impl Clock for Ticks {
//!     fn tick_hz(&self) -> u32 { 1_000 }
//!     fn now_ticks(&mut self) -> Result<u64, Infallible> { Ok(0) }
//! }
//! /// The map product in memory-mapped flash: checked and used in place.
//! struct Flash<'a>(&'a [u8]);
//! impl ErrorType for Flash<'_> { type Error = Infallible; }
//! impl MapStore for Flash<'_> {
//!     fn len(&mut self) -> Result<u32, Infallible> { Ok(self.0.len() as u32) }
//!     fn read_range(&mut self, at: u32, buf: &mut [u8]) -> Result<(), Infallible> {
//!         buf.copy_from_slice(&self.0[at as usize..at as usize + buf.len()]);
//!         Ok(())
//!     }
//!     fn mapped(&self) -> Option<&[u8]> { Some(self.0) }
//! }
//! /// The navigation filter's latest estimate.
//! struct Nav(PriorEstimate);
//! impl ErrorType for Nav { type Error = Infallible; }
//! impl PosePrior for Nav {
//!     fn latest(&mut self) -> Result<PriorEstimate, Infallible> { Ok(self.0) }
//! }
//! /// A downlink that counts bytes.
//! struct Downlink(usize);
//! impl ErrorType for Downlink { type Error = Infallible; }
//! impl Telemetry for Downlink {
//!     fn send(&mut self, _kind: u8, payload: &[u8]) -> Result<(), Infallible> {
//!         self.0 += payload.len();
//!         Ok(())
//!     }
//! }
//!
//! // The built-in test map, and a pair rendered from it at the true pose.
//! let map_bytes = testkit::build_map(1);
//! let map = vtsm_core::map::MapView::new_checked(&map_bytes)?;
//! let rig = testkit::rig();
//! let truth = testkit::camera_pose(0.6, 0.2);
//! let left = testkit::render_full(&map, &rig.cam(), &truth, 0.85, 20.0);
//! let right = testkit::render_full(&map, &rig.cam(), &rig.world_from_right(&truth), 0.85, 20.0);
//! // The prior: 12 cm off the truth, with a 1 cm (1-σ) diagonal covariance.
//! let prior_pose = Pose::new(truth.rotation(), truth.translation() + Vector3::new(0.08, -0.09, 0.0));
//! let prior = PriorEstimate {
//!     world_from_left: prior_pose,
//!     covariance: Covariance::Diagonal([1e-4, 1e-4, 1e-4, 1e-4, 1e-4, 1e-4]),
//!     uncertainty: None,
//!     timestamp_ticks: 0,
//! };
//!
//! let cfg = RunnerConfig { attempts: 3, product_attempts: 2, chunk_len: 1 << 16,
//!                          capture_timeout_ticks: 100, image_size: (640, 480) };
//! let camera = Camera { left, right, sequence: 0 };
//! let mut runner = Runner::new(camera, Ticks, Flash(&map_bytes), Nav(prior), Downlink(0), cfg);
//!
//! // Caller-owned memory: the pair's RAM and the engine's workspace.
//! let (mut l, mut r) = (vec![0u8; 640 * 480], vec![0u8; 640 * 480]);
//! let (mut bytes, mut words, mut runs) = (
//!     vec![0u8; TEST_WORKSPACE.bytes],
//!     vec![0u32; TEST_WORKSPACE.words],
//!     vec![Run::default(); TEST_WORKSPACE.runs],
//! );
//! let ws = Workspace::new(TEST_WORKSPACE, &mut bytes, &mut words, &mut runs)?;
//!
//! let job = Job { rig, params: testkit::test_params(), seed: 7,
//!                 limits: DriveLimits::UNLIMITED, verify: VerifyChecks::ALL, accuracy: None,
//!                 final_pairs: 0, search: vtsm_core::reloc::Search::DEFAULT };
//! let (outcome, report) = runner.run(&job, &mut [], RamPair::new(&mut l, &mut r), ws, None)?;
//!
//! assert!(outcome.failure.is_none(), "{:?}", outcome.failure);
//! let (err_m, _) = outcome.pose.error_to(&truth);
//! assert!(err_m < 0.02, "{err_m} m");
//! assert!(report.map_read.in_place && report.map_read.checks == 1 && runner.telemetry.0 > 0);
//! # Ok::<(), vtsm_core::FailureCode>(())
//! ```
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
pub mod pool;
pub mod prior;
pub mod runner;
pub mod store;
pub mod telemetry;

pub use camera::{FrameInfo, StereoCamera};
pub use clock::Clock;
pub use error::{failure_code, Device, Error, ErrorKind, ErrorType};
pub use frames::{FrameStore, StoreFrames};
pub use pool::AttemptPool;
pub use prior::{Covariance, PosePrior, PriorEstimate, PriorUncertainty};
pub use store::MapStore;
pub use telemetry::{FramedTelemetry, Telemetry};
