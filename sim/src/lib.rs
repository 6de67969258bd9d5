//! # vtsm-sim
//!
//! Desktop side of VTSM (std): procedural depots ([`terrain`]), a photometric
//! renderer of its own ([`render`]), photogrammetry-like map products
//! ([`mapping`]), capture grids and scenes ([`scene`]), HAL implementations with
//! seeded fault injection ([`devices`]), a camera that is not ideal ([`effects`]), file formats ([`io`]), the user and
//! map-local frames ([`frame`]), the host relocalization job ([`job`]), evaluation suites
//! ([`eval`]), the local-feature baseline ([`features`]) and the `vtsm`
//! command line ([`cli`]).
#![forbid(unsafe_code)]

pub mod cli;
pub mod devices;
pub mod effects;
pub mod error;
pub mod eval;
pub mod features;
pub mod frame;
pub mod io;
pub mod job;
pub mod locate;
pub mod mapping;
pub mod mapscore;
pub mod panel;
pub mod progress;
pub mod rectify;
pub mod relight;
pub mod render;
pub mod scene;
pub mod terrain;
pub mod workers;

pub use error::{Error, Result};
