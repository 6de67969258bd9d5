//! Every form of `calib.json` (design §5; `fsw-docs/interfaces/files.md`),
//! one file each, and the one reader that tells them apart
//! ([`read_calib_any`]):
//!
//! * the rectified form ([`crate::io::json::Calib`]): an ideal pair, used as it is;
//! * the OpenCV stereo form ([`opencv`]) and the files other tools write for
//!   a physical pair: ROS `camera_info` ([`ros`]), a Kalibr camera chain
//!   ([`kalibr`]) and `cv::FileStorage` YAML or XML ([`storage`]); each
//!   becomes the one physical model ([`model::OpenCvCalib`]) that the host
//!   rectifier ([`crate::rectify`]) turns into a rectified pair.
//!
//! [`yaml`] holds the YAML helpers the ROS, Kalibr and FileStorage readers share.

pub mod kalibr;
pub mod model;
pub mod opencv;
pub mod ros;
pub mod storage;
pub mod yaml;

use crate::error::Result;
use crate::io::json::{self, Calib};
use model::OpenCvCalib;
use std::path::Path;

/// Either form of `calib.json`.
#[derive(Clone, Debug, PartialEq)]
pub enum CalibFile {
    /// An ideal rectified pair (`width`, `height`, `fx`, ...).
    Rectified(Calib),
    /// A physical pair as OpenCV calibrates it.
    OpenCv(Box<OpenCvCalib>),
}

/// Parse any form of `calib.json`: a FileStorage file itself
/// ([`storage`]) when it begins with `%YAML` or is XML, the FileStorage
/// form when the top-level object has an `opencv_storage` key, the Kalibr form
/// ([`kalibr`]) when it has a `kalibr_camchain` key, the ROS form
/// ([`ros`]) when it has a `ros_camera_info` key, the OpenCV form when it has an
/// `image_size` key, the rectified form otherwise. The ROS form is returned as
/// the OpenCV form it describes, as are the Kalibr and FileStorage forms.
///
/// # Errors
/// As [`json::parse_calib`], [`opencv::parse_opencv_calib`],
/// [`storage::parse_storage_calib`],
/// [`ros::parse_ros_calib`] or
/// [`kalibr::parse_kalibr_calib`].
pub fn parse_calib_any(bytes: &[u8], path: &Path) -> Result<CalibFile> {
    if storage::is_storage_file(bytes) {
        return storage::parse_storage_file(bytes, path).map(|c| CalibFile::OpenCv(Box::new(c)));
    }
    // The top-level keys, parsed once; malformed JSON is reported by the
    // rectified form's parser below.
    let top = serde_json::from_slice::<serde_json::Value>(bytes).ok();
    let has = |key: &str| {
        top.as_ref()
            .and_then(|v| v.as_object())
            .is_some_and(|o| o.contains_key(key))
    };
    if has("opencv_storage") {
        storage::parse_storage_calib(bytes, path).map(|c| CalibFile::OpenCv(Box::new(c)))
    } else if has("kalibr_camchain") {
        kalibr::parse_kalibr_calib(bytes, path).map(|c| CalibFile::OpenCv(Box::new(c)))
    } else if has("ros_camera_info") {
        ros::parse_ros_calib(bytes, path).map(|c| CalibFile::OpenCv(Box::new(c)))
    } else if has("image_size") {
        opencv::parse_opencv_calib(bytes, path).map(|c| CalibFile::OpenCv(Box::new(c)))
    } else {
        json::parse_calib(bytes, path).map(CalibFile::Rectified)
    }
}

/// Read either form of `calib.json`.
///
/// # Errors
/// As [`parse_calib_any`], plus I/O errors.
pub fn read_calib_any(path: &Path) -> Result<CalibFile> {
    parse_calib_any(&crate::io::read_file(path)?, path)
}
