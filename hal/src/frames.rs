//! Frame store: a stereo pair kept where the camera put it (its frame
//! buffer, or mass memory behind a driver), read one rectangle at a time.
//!
//! A [`FrameStore`] captures a pair into its own memory and serves
//! rectangles of it on demand, so a relocalization holds in RAM only the
//! search windows the engine copies out (`vtsm_core::frame`), not the pair:
//! at the paper's 5472 × 3648 one pair is 40 MB, four times the flight RAM.
//!
//! [`StoreFrames`] is the core's [`FrameSource`] over a store: every read is
//! retried on transient faults ([`ErrorKind::is_transient`]) at most
//! `attempts` times; every failed read is recorded in its own
//! [`FailureLog`] with its device code, which the runner merges into its
//! log when the engine is done.

use crate::camera::FrameInfo;
use crate::error::{failure_code, Device, Error, ErrorKind, ErrorType};
use vtsm_core::failure::FailureLog;
use vtsm_core::frame::{Eye, FrameSource};
use vtsm_core::image::Rect;
use vtsm_core::FailureCode;

/// A camera's frame memory holding the last captured stereo pair.
pub trait FrameStore: ErrorType {
    /// Capture one synchronised, rectified pair into the store's memory.
    ///
    /// # Contract
    /// * Blocks for at most `timeout_ticks` ticks of the system clock; if no pair
    ///   is complete by then, returns an error of kind
    ///   [`Timeout`](crate::ErrorKind::Timeout).
    /// * On `Ok(info)` the store holds both images of the layout of `info`
    ///   (8-bit gray, rectified, taken at the same instant) and serves them
    ///   through [`FrameStore::read_window`] unchanged until the next
    ///   `capture_in_place`; `info.sequence` is larger than that of every earlier `Ok`.
    /// * A transfer into the store that ended early is kind
    ///   [`Truncated`](crate::ErrorKind::Truncated), detected damage kind
    ///   [`Corrupted`](crate::ErrorKind::Corrupted). After any error no pair
    ///   is available (reads fail) until a `capture_in_place` succeeds.
    fn capture_in_place(&mut self, timeout_ticks: u64) -> Result<FrameInfo, Self::Error>;

    /// Read `rect` of `eye`'s image of the last captured pair into `out`,
    /// row-major with `rect.w` bytes per row.
    ///
    /// # Contract
    /// * `rect` must be non-empty and lie inside `0..width × 0..height` of the
    ///   last [`FrameInfo`], and `out` must hold `rect.w · rect.h` bytes;
    ///   otherwise the result is kind [`Other`](crate::ErrorKind::Other) and
    ///   nothing is read.
    /// * On `Ok(())` the first `rect.w · rect.h` bytes of `out` are the
    ///   pixels of `rect`, the same on every read of it.
    /// * A short read is kind [`Truncated`](crate::ErrorKind::Truncated), a
    ///   detected media or link error is [`Corrupted`](crate::ErrorKind::Corrupted),
    ///   a busy device that did not answer in time is
    ///   [`Timeout`](crate::ErrorKind::Timeout); no pair captured is
    ///   [`Unavailable`](crate::ErrorKind::Unavailable). After an error the
    ///   contents of `out` are unspecified.
    /// * Bounded: the time taken is proportional to `rect.w · rect.h`.
    /// * Never writes outside `out`; keeps no reference to it.
    fn read_window(&mut self, eye: Eye, rect: Rect, out: &mut [u8]) -> Result<(), Self::Error>;
}

impl<T: FrameStore + ?Sized> FrameStore for &mut T {
    fn capture_in_place(&mut self, timeout_ticks: u64) -> Result<FrameInfo, Self::Error> {
        T::capture_in_place(self, timeout_ticks)
    }
    fn read_window(&mut self, eye: Eye, rect: Rect, out: &mut [u8]) -> Result<(), Self::Error> {
        T::read_window(self, eye, rect, out)
    }
}

/// Work done reading windows from a frame store.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WindowReport {
    /// Windows (and preflight rows) the engine asked for.
    pub windows: u32,
    /// `read_window` calls made, retries included.
    pub reads: u32,
    /// Of those, failed.
    pub failed_reads: u32,
    /// Pixels delivered by successful reads.
    pub pixels: u64,
}

/// The core's [`FrameSource`] over a [`FrameStore`] holding a pair of
/// `info`'s layout, with bounded retries per read.
#[derive(Debug)]
pub struct StoreFrames<F> {
    store: F,
    size: (usize, usize),
    attempts: u8,
    /// Clock time stamped on the failure events (the start of the run: the
    /// engine does not read the clock).
    tick: u64,
    /// Every failed read, with its device code.
    pub log: FailureLog,
    /// Read work.
    pub report: WindowReport,
}

impl<F: FrameStore> StoreFrames<F> {
    /// Reads from `store`, whose last capture is described by `info`, each
    /// tried at most `attempts` (≥ 1) times; failures are stamped `tick`.
    pub fn new(store: F, info: &FrameInfo, attempts: u8, tick: u64) -> Self {
        Self {
            store,
            size: (
                usize::try_from(info.width).unwrap_or(0),
                usize::try_from(info.height).unwrap_or(0),
            ),
            attempts: attempts.max(1),
            tick,
            log: FailureLog::new(),
            report: WindowReport::default(),
        }
    }
}

impl<F: FrameStore> FrameSource for StoreFrames<F> {
    fn size(&self) -> (usize, usize) {
        self.size
    }

    /// The store's read, retried while it fails with a transient kind.
    ///
    /// # Errors
    /// [`FailureCode::HalFrameStoreRead`] after a non-transient fault or
    /// `attempts` failed reads.
    fn read_window(&mut self, eye: Eye, rect: Rect, out: &mut [u8]) -> Result<(), FailureCode> {
        self.report.windows = self.report.windows.saturating_add(1);
        let code = failure_code(Device::FrameStore, ErrorKind::Other);
        for attempt in 0..self.attempts {
            self.report.reads = self.report.reads.saturating_add(1);
            match self.store.read_window(eye, rect, out) {
                Ok(()) => {
                    let px = u64::from(rect.w).saturating_mul(u64::from(rect.h));
                    self.report.pixels = self.report.pixels.saturating_add(px);
                    return Ok(());
                }
                Err(e) => {
                    self.report.failed_reads = self.report.failed_reads.saturating_add(1);
                    let kind = e.kind();
                    self.log.record(
                        failure_code(Device::FrameStore, kind),
                        self.tick,
                        u32::from(attempt),
                    );
                    if !kind.is_transient() {
                        break;
                    }
                }
            }
        }
        Err(code)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4 × 3 store whose reads fail with `fail` the first `n` times.
    struct Flaky {
        n: u32,
        fail: ErrorKind,
    }

    impl ErrorType for Flaky {
        type Error = ErrorKind;
    }

    impl FrameStore for Flaky {
        fn capture_in_place(&mut self, _: u64) -> Result<FrameInfo, ErrorKind> {
            Err(ErrorKind::Other)
        }
        fn read_window(&mut self, _: Eye, r: Rect, out: &mut [u8]) -> Result<(), ErrorKind> {
            if self.n > 0 {
                self.n -= 1;
                return Err(self.fail);
            }
            let n = (r.w * r.h) as usize;
            out.get_mut(..n).ok_or(ErrorKind::Other)?.fill(7);
            Ok(())
        }
    }

    fn info() -> FrameInfo {
        FrameInfo {
            width: 4,
            height: 3,
            stride: 4,
            sequence: 1,
            timestamp_ticks: 0,
            exposure_us: 0,
        }
    }

    /// Verifies: VTSM-HAL-027
    #[test]
    fn store_reads_retry_transient_faults_within_the_cap_and_log_each() {
        let r = Rect::new(0, 0, 2, 2);
        let mut out = [0u8; 4];
        // Two timeouts, then a read: within three attempts.
        let mut src = StoreFrames::new(
            Flaky {
                n: 2,
                fail: ErrorKind::Timeout,
            },
            &info(),
            3,
            5,
        );
        assert_eq!(src.size(), (4, 3));
        assert_eq!(src.read_window(Eye::Left, r, &mut out), Ok(()));
        assert_eq!(out, [7; 4]);
        assert_eq!(src.log.count(FailureCode::HalFrameStoreRead), 2);
        assert_eq!((src.report.reads, src.report.failed_reads), (3, 2));
        // Three truncated reads exhaust the cap.
        let mut src = StoreFrames::new(
            Flaky {
                n: 3,
                fail: ErrorKind::Truncated,
            },
            &info(),
            3,
            5,
        );
        let e = src.read_window(Eye::Right, r, &mut out).err();
        assert_eq!(e, Some(FailureCode::HalFrameStoreRead));
        assert_eq!(src.report.reads, 3);
        // A non-transient fault is not retried.
        let mut src = StoreFrames::new(
            Flaky {
                n: 1,
                fail: ErrorKind::Unavailable,
            },
            &info(),
            3,
            5,
        );
        assert!(src.read_window(Eye::Left, r, &mut out).is_err());
        assert_eq!(src.report.reads, 1);
        assert_eq!(src.log.recent().next().map(|e| e.tick), Some(5));
    }
}
