//! Device errors in the embedded-io style, and their mapping to core failure codes.
//!
//! Every HAL trait has an associated `Error` type (through [`ErrorType`]) that
//! only has to say which [`ErrorKind`] it is. The runner never looks further
//! than the kind: [`failure_code`] turns `(Device, ErrorKind)` into the
//! [`FailureCode`] that is logged and reported. Pure table, no loops.

use vtsm_core::FailureCode;

/// What kind of fault a device reported. Drivers map their own errors onto these.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ErrorKind {
    /// The device did not answer within the time it was given.
    Timeout,
    /// The device delivered less data than was asked for.
    Truncated,
    /// The device detected that the data it delivered is damaged (link CRC, ECC).
    Corrupted,
    /// The device is not available (powered off, not initialised, no estimate yet).
    Unavailable,
    /// Any other fault.
    Other,
}

impl ErrorKind {
    /// Every kind, for exhaustive tests and tables.
    pub const ALL: [ErrorKind; 5] = [
        ErrorKind::Timeout,
        ErrorKind::Truncated,
        ErrorKind::Corrupted,
        ErrorKind::Unavailable,
        ErrorKind::Other,
    ];

    /// Whether the runner retries an operation that failed with this kind.
    ///
    /// Timeouts, short transfers and detected corruption are transient; an
    /// unavailable device or an unknown fault is reported at once.
    pub const fn is_transient(self) -> bool {
        matches!(
            self,
            ErrorKind::Timeout | ErrorKind::Truncated | ErrorKind::Corrupted
        )
    }
}

/// A device error: anything that can say which [`ErrorKind`] it is.
pub trait Error: core::fmt::Debug {
    /// The kind of this error.
    fn kind(&self) -> ErrorKind;
}

impl Error for ErrorKind {
    fn kind(&self) -> ErrorKind {
        *self
    }
}

impl Error for core::convert::Infallible {
    fn kind(&self) -> ErrorKind {
        match *self {}
    }
}

/// Associates an error type with a device.
pub trait ErrorType {
    /// The device's error type.
    type Error: Error;
}

impl<T: ErrorType + ?Sized> ErrorType for &mut T {
    type Error = T::Error;
}

/// Which device an error came from (the same kind means different things on different devices).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Device {
    /// [`crate::StereoCamera`].
    Camera,
    /// [`crate::Clock`].
    Clock,
    /// [`crate::MapStore`].
    MapStore,
    /// [`crate::PosePrior`].
    PosePrior,
    /// [`crate::Telemetry`].
    Telemetry,
    /// [`crate::FrameStore`].
    FrameStore,
}

impl Device {
    /// Every device.
    pub const ALL: [Device; 6] = [
        Device::Camera,
        Device::Clock,
        Device::MapStore,
        Device::PosePrior,
        Device::Telemetry,
        Device::FrameStore,
    ];
}

/// The failure code for an error of `kind` reported by `device`.
///
/// Every result is in the 0x09xx (hardware) group.
pub const fn failure_code(device: Device, kind: ErrorKind) -> FailureCode {
    match (device, kind) {
        (Device::Camera, ErrorKind::Timeout) => FailureCode::HalCameraTimeout,
        (Device::Camera, ErrorKind::Truncated) => FailureCode::HalCameraFrameTruncated,
        (Device::Camera, _) => FailureCode::HalCameraFault,
        (Device::Clock, _) => FailureCode::HalClockFault,
        (Device::MapStore, _) => FailureCode::HalStorageRead,
        (Device::PosePrior, _) => FailureCode::HalPriorUnavailable,
        (Device::Telemetry, _) => FailureCode::HalTelemetryWrite,
        (Device::FrameStore, _) => FailureCode::HalFrameStoreRead,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Verifies: VTSM-HAL-002
    #[test]
    fn every_device_error_maps_into_the_hardware_group() {
        for d in Device::ALL {
            for k in ErrorKind::ALL {
                let c = failure_code(d, k);
                assert_eq!(c.group(), 0x09, "{d:?} {k:?} -> {c:?}");
            }
        }
        assert_eq!(
            failure_code(Device::Camera, ErrorKind::Timeout),
            FailureCode::HalCameraTimeout
        );
        assert_eq!(
            failure_code(Device::Camera, ErrorKind::Truncated),
            FailureCode::HalCameraFrameTruncated
        );
        assert_eq!(
            failure_code(Device::Camera, ErrorKind::Corrupted),
            FailureCode::HalCameraFault
        );
        assert_eq!(
            failure_code(Device::MapStore, ErrorKind::Timeout),
            FailureCode::HalStorageRead
        );
        let transient: usize = ErrorKind::ALL.iter().filter(|k| k.is_transient()).count();
        assert_eq!(transient, 3);
        assert!(!ErrorKind::Unavailable.is_transient());
    }
}
