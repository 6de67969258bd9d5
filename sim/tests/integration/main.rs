//! The simulator's file-format and command-line tests: images, meshes
//! (OBJ, PLY), calibrations (OpenCV, ROS, Kalibr, FileStorage), JSON, the
//! `vtsm` CLI, sharded `vtsm eval` campaigns, `vtsm bench`, result pages and the OpenCV rectification oracle.
//!
//! One test binary with one module per former file (one link instead of
//! ten). Run one module with a filter: `cargo test -p vtsm-sim --test integration -- io_cli::`.
#![allow(missing_docs)]

mod bench_cli;
mod common;
mod eval_dataset;
mod eval_shards;
mod io_calib_opencv;
mod io_calib_yaml;
mod io_cli;
mod io_image;
mod io_json;
mod io_obj;
mod io_pages;
mod io_ply;
mod rectify_cv2;
