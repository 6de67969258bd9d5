//! Simulated devices implementing the `vtsm-hal` traits, with seeded fault injection.
//!
//! * [`MemMapStore`]: a map product in memory.
//! * [`ManualClock`]: a clock that advances only when told (clones share one time).
//! * [`RecordingSink`]: an `embedded_io::Write` that records bytes; with
//!   [`vtsm_hal::FramedTelemetry`] it is the telemetry downlink, and
//!   [`RecordingSink::frames`] decodes the stream back.
//! * [`FixedCamera`]: serves the same stereo pair on every capture, into the
//!   caller's buffers ([`StereoCamera`]) or kept in its own memory and read a
//!   window at a time ([`FrameStore`], with its own window-read faults).
//! * [`FixedPrior`]: serves one pose prior.
//!
//! Faults ([`FaultConfig`]): each operation draws once from a [`vtsm_core::rng::Rng`]
//! seeded by the caller; with the given percentages it times out, is truncated,
//! or delivers silently corrupted bytes. Same seed and same call sequence ⇒ same
//! faults, on every machine.

use std::borrow::Cow;
use std::cell::Cell;
use std::rc::Rc;
use vtsm_core::frame::Eye;
use vtsm_core::image::Rect;
use vtsm_core::map::MapView;
use vtsm_core::rng::Rng;
use vtsm_hal::camera::{FrameInfo, StereoCamera};
use vtsm_hal::telemetry::{decode_prefix, FrameError, SYNC};
use vtsm_hal::{Clock, ErrorKind, ErrorType, FrameStore, MapStore, PosePrior, PriorEstimate};

/// Largest number of bytes one corruption fault damages.
pub const MAX_CORRUPT_BYTES: u32 = 4;

/// Fault percentages of one device. The sum must not exceed 100.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FaultConfig {
    /// Percent of operations that time out.
    pub timeout_pct: u8,
    /// Percent of operations that deliver only part of the data.
    pub truncate_pct: u8,
    /// Percent of operations that deliver data with 1..=MAX_CORRUPT_BYTES damaged bytes, silently.
    pub corrupt_pct: u8,
}

impl FaultConfig {
    /// No faults.
    pub const NONE: FaultConfig = FaultConfig {
        timeout_pct: 0,
        truncate_pct: 0,
        corrupt_pct: 0,
    };

    /// Whether the percentages add up to at most 100.
    pub fn is_valid(&self) -> bool {
        u16::from(self.timeout_pct) + u16::from(self.truncate_pct) + u16::from(self.corrupt_pct)
            <= 100
    }
}

/// One injected fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    /// The operation times out.
    Timeout,
    /// The operation delivers part of its data.
    Truncate,
    /// The operation delivers damaged data and reports success.
    Corrupt,
}

/// How many faults of each kind were injected.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FaultStats {
    /// Operations that drew.
    pub operations: u64,
    /// Timeouts injected.
    pub timeouts: u64,
    /// Truncations injected.
    pub truncations: u64,
    /// Corruptions injected.
    pub corruptions: u64,
    /// Bytes damaged by corruptions.
    pub corrupted_bytes: u64,
}

/// Seeded fault source of one device.
#[derive(Clone, Debug)]
pub struct FaultInjector {
    cfg: FaultConfig,
    rng: Rng,
    /// What was injected so far.
    pub stats: FaultStats,
}

impl FaultInjector {
    /// A fault source; `Err` if the percentages add up to more than 100.
    pub fn new(cfg: FaultConfig, seed: u64) -> Result<Self, crate::Error> {
        if !cfg.is_valid() {
            return Err(crate::Error::msg(format!(
                "fault percentages add up to more than 100: {cfg:?}"
            )));
        }
        Ok(Self {
            cfg,
            rng: Rng::new(seed),
            stats: FaultStats::default(),
        })
    }

    /// A source that never injects a fault.
    pub fn none() -> Self {
        Self {
            cfg: FaultConfig::NONE,
            rng: Rng::new(0),
            stats: FaultStats::default(),
        }
    }

    /// Draw the fault (if any) of the next operation.
    pub fn draw(&mut self) -> Option<Fault> {
        self.stats.operations += 1;
        let r = self.rng.below(100);
        let t = u32::from(self.cfg.timeout_pct);
        let tr = t + u32::from(self.cfg.truncate_pct);
        let c = tr + u32::from(self.cfg.corrupt_pct);
        if r < t {
            self.stats.timeouts += 1;
            Some(Fault::Timeout)
        } else if r < tr {
            self.stats.truncations += 1;
            Some(Fault::Truncate)
        } else if r < c {
            self.stats.corruptions += 1;
            Some(Fault::Corrupt)
        } else {
            None
        }
    }

    /// Damage a burst of 1..=MAX_CORRUPT_BYTES consecutive bytes of `buf`,
    /// each changed to a different value; returns how many bytes changed.
    pub fn corrupt(&mut self, buf: &mut [u8]) -> usize {
        let len = u32::try_from(buf.len()).unwrap_or(u32::MAX);
        if len == 0 {
            return 0;
        }
        let start = self.rng.below(len) as usize;
        let k = (1 + self.rng.below(MAX_CORRUPT_BYTES)) as usize;
        let end = (start + k).min(buf.len());
        let burst = &mut buf[start..end];
        for b in burst.iter_mut() {
            *b ^= 1 + self.rng.below(255) as u8;
        }
        self.stats.corrupted_bytes += burst.len() as u64;
        burst.len()
    }

    /// Length of a truncated transfer of `n` bytes: 0..n.
    pub fn truncated_len(&mut self, n: usize) -> usize {
        let n32 = u32::try_from(n).unwrap_or(u32::MAX);
        if n32 == 0 {
            0
        } else {
            self.rng.below(n32) as usize
        }
    }
}

// ---- map store ------------------------------------------------------------

/// A map product held in memory: owned bytes, bytes borrowed from the
/// caller (nothing copied), or a view the caller already checked
/// ([`MemMapStore::from_checked`], handed to the runner as is).
#[derive(Clone, Debug)]
pub struct MemMapStore<'a> {
    data: Cow<'a, [u8]>,
    mapped: bool,
    checked: Option<MapView<'a>>,
    /// Fault source for `read_range`.
    pub faults: FaultInjector,
}

impl<'a> MemMapStore<'a> {
    /// A store holding `data` (owned or borrowed), without faults, read
    /// only through `read_range`.
    pub fn new(data: impl Into<Cow<'a, [u8]>>) -> Self {
        Self {
            data: data.into(),
            mapped: false,
            checked: None,
            faults: FaultInjector::none(),
        }
    }

    /// A memory-mapped store of a product the caller checked once
    /// ([`MapView::new_checked`]): [`MapStore::checked`] gives `view`, so
    /// the runner neither reads, copies nor checks it again.
    pub fn from_checked(view: MapView<'a>) -> Self {
        Self {
            data: Cow::Borrowed(view.bytes()),
            mapped: true,
            checked: Some(view),
            faults: FaultInjector::none(),
        }
    }

    /// The same store, also memory-mapped: [`MapStore::mapped`] gives the
    /// bytes themselves (read faults do not apply to them; corrupt the
    /// bytes given to [`MemMapStore::new`] to test the checks).
    pub fn memory_mapped(mut self) -> Self {
        self.mapped = true;
        self
    }

    /// The same store with seeded faults.
    pub fn with_faults(mut self, faults: FaultInjector) -> Self {
        self.faults = faults;
        self
    }

    /// The stored bytes.
    pub fn data(&self) -> &[u8] {
        &self.data
    }
}

impl ErrorType for MemMapStore<'_> {
    type Error = ErrorKind;
}

impl MapStore for MemMapStore<'_> {
    fn len(&mut self) -> Result<u32, ErrorKind> {
        u32::try_from(self.data.len()).map_err(|_| ErrorKind::Other)
    }

    fn mapped(&self) -> Option<&[u8]> {
        self.mapped.then_some(&*self.data)
    }

    fn checked(&self) -> Option<MapView<'_>> {
        self.checked
    }

    fn read_range(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), ErrorKind> {
        let start = offset as usize;
        let src = start
            .checked_add(buf.len())
            .and_then(|end| self.data.get(start..end))
            .ok_or(ErrorKind::Other)?;
        match self.faults.draw() {
            Some(Fault::Timeout) => Err(ErrorKind::Timeout),
            Some(Fault::Truncate) => {
                let n = self.faults.truncated_len(buf.len());
                buf[..n].copy_from_slice(&src[..n]);
                Err(ErrorKind::Truncated)
            }
            Some(Fault::Corrupt) => {
                buf.copy_from_slice(src);
                self.faults.corrupt(buf);
                Ok(())
            }
            None => {
                buf.copy_from_slice(src);
                Ok(())
            }
        }
    }
}

// ---- clock ----------------------------------------------------------------

/// A clock that advances only when told. Clones share the same time, so a
/// device holding a clone (the camera) sees the test's clock.
#[derive(Clone, Debug)]
pub struct ManualClock {
    ticks: Rc<Cell<u64>>,
    cycles: Option<Rc<Cell<u64>>>,
    hz: u32,
    per_read: u64,
}

impl ManualClock {
    /// A clock at tick 0 running at `hz` (≥ 1) ticks per second, without a cycle counter.
    pub fn new(hz: u32) -> Self {
        Self {
            ticks: Rc::new(Cell::new(0)),
            cycles: None,
            hz: hz.max(1),
            per_read: 0,
        }
    }

    /// The same clock, advancing by `dt` ticks at every read through the
    /// trait (before the read), so time passes with each runner step; clones
    /// made before this call keep reading without advancing.
    pub fn with_ticks_per_read(mut self, dt: u64) -> Self {
        self.per_read = dt;
        self
    }

    /// The same clock with a cycle counter starting at 0.
    pub fn with_cycles(mut self) -> Self {
        self.cycles = Some(Rc::new(Cell::new(0)));
        self
    }

    /// Advance time by `dt` ticks (saturating).
    pub fn advance(&self, dt: u64) {
        self.ticks.set(self.ticks.get().saturating_add(dt));
    }

    /// Advance the cycle counter by `dc` (wrapping, like hardware); no-op without one.
    pub fn advance_cycles(&self, dc: u64) {
        if let Some(c) = &self.cycles {
            c.set(c.get().wrapping_add(dc));
        }
    }

    /// Current time without going through the trait.
    pub fn ticks(&self) -> u64 {
        self.ticks.get()
    }
}

impl ErrorType for ManualClock {
    type Error = core::convert::Infallible;
}

impl Clock for ManualClock {
    fn tick_hz(&self) -> u32 {
        self.hz
    }
    fn now_ticks(&mut self) -> Result<u64, Self::Error> {
        self.advance(self.per_read);
        Ok(self.ticks.get())
    }
    fn cycles(&mut self) -> Option<u64> {
        self.cycles.as_ref().map(|c| c.get())
    }
}

// ---- telemetry sink ---------------------------------------------------------

/// One frame decoded back from a recorded telemetry stream.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DecodedFrame {
    /// Frame kind byte.
    pub kind: u8,
    /// Payload bytes.
    pub payload: Vec<u8>,
}

/// Result of decoding a recorded stream.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Decoded {
    /// Valid frames, in order.
    pub frames: Vec<DecodedFrame>,
    /// Bytes skipped while resynchronising (damaged or partial frames).
    pub skipped_bytes: usize,
    /// Bytes at the end that start a frame that is not complete.
    pub trailing_bytes: usize,
}

/// An `embedded_io::Write` that records everything written to it.
#[derive(Clone, Debug)]
pub struct RecordingSink {
    bytes: Vec<u8>,
    /// Fault source, one draw per `write` call: timeout → `TimedOut` error,
    /// truncate → part recorded then a `WriteZero` error (the link took only part),
    /// corrupt → damaged bytes recorded and success reported.
    pub faults: FaultInjector,
}

impl Default for RecordingSink {
    fn default() -> Self {
        Self::new()
    }
}

impl RecordingSink {
    /// An empty sink without faults.
    pub fn new() -> Self {
        Self {
            bytes: Vec::new(),
            faults: FaultInjector::none(),
        }
    }

    /// The same sink with seeded faults.
    pub fn with_faults(mut self, faults: FaultInjector) -> Self {
        self.faults = faults;
        self
    }

    /// Everything recorded so far.
    pub fn bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// Decode the recorded stream: frames in order, resynchronising on the
    /// sync word after damaged bytes, as a ground station would.
    pub fn frames(&self) -> Decoded {
        decode_stream(&self.bytes)
    }
}

/// Decode a byte stream of frames, skipping damaged data. O(len · MAX_FRAME) worst case.
pub fn decode_stream(bytes: &[u8]) -> Decoded {
    let mut out = Decoded::default();
    let mut i = 0;
    while i < bytes.len() {
        match decode_prefix(&bytes[i..]) {
            Ok((f, n)) => {
                out.frames.push(DecodedFrame {
                    kind: f.kind,
                    payload: f.payload.to_vec(),
                });
                i += n;
            }
            Err(FrameError::Truncated) if bytes[i..].starts_with(&SYNC[..1]) => {
                // Either a frame still being received or a damaged length
                // field: look for a later sync word before giving up.
                match find_sync(&bytes[i + 1..]) {
                    Some(k) => {
                        out.skipped_bytes += k + 1;
                        i += k + 1;
                    }
                    None => {
                        out.trailing_bytes = bytes.len() - i;
                        break;
                    }
                }
            }
            Err(_) => {
                let k = find_sync(&bytes[i + 1..]).map_or(bytes.len() - i, |k| k + 1);
                out.skipped_bytes += k;
                i += k;
            }
        }
    }
    out
}

fn find_sync(bytes: &[u8]) -> Option<usize> {
    bytes.windows(2).position(|w| w == SYNC)
}

impl embedded_io::ErrorType for RecordingSink {
    type Error = embedded_io::ErrorKind;
}

impl embedded_io::Write for RecordingSink {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        if buf.is_empty() {
            return Ok(0);
        }
        match self.faults.draw() {
            Some(Fault::Timeout) => Err(embedded_io::ErrorKind::TimedOut),
            Some(Fault::Truncate) => {
                let n = self.faults.truncated_len(buf.len());
                self.bytes.extend_from_slice(&buf[..n]);
                Err(embedded_io::ErrorKind::WriteZero)
            }
            Some(Fault::Corrupt) => {
                let mut tmp = buf.to_vec();
                self.faults.corrupt(&mut tmp);
                self.bytes.extend_from_slice(&tmp);
                Ok(buf.len())
            }
            None => {
                self.bytes.extend_from_slice(buf);
                Ok(buf.len())
            }
        }
    }

    fn flush(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}

// ---- camera -----------------------------------------------------------------

/// A stereo camera serving one fixed pair on every capture: owned images,
/// or images borrowed from the caller (the decoded files: nothing is copied
/// to set the camera up).
#[derive(Clone, Debug)]
pub struct FixedCamera<'a> {
    left: Cow<'a, [u8]>,
    right: Cow<'a, [u8]>,
    width: u32,
    height: u32,
    stride: u32,
    /// Exposure reported in [`FrameInfo`].
    pub exposure_us: u32,
    sequence: u32,
    clock: Option<ManualClock>,
    /// Fault source, one draw per capture. A timeout advances the attached
    /// clock by the timeout (the capture blocked that long).
    pub faults: FaultInjector,
    /// Fault source of [`FrameStore::read_window`], one draw per read.
    pub window_faults: FaultInjector,
    /// Whether a pair is held for [`FrameStore::read_window`] (the last
    /// [`FrameStore::capture_in_place`] succeeded).
    latched: bool,
    /// Whole pairs copied out of the camera into a caller's buffers
    /// ([`StereoCamera::capture`]); a capture in place copies none.
    pub pair_copies: u32,
}

impl<'a> FixedCamera<'a> {
    /// A camera serving `left`/`right` (`width × height`, rows packed:
    /// stride = width), owned or borrowed.
    pub fn new(
        left: impl Into<Cow<'a, [u8]>>,
        right: impl Into<Cow<'a, [u8]>>,
        width: u32,
        height: u32,
    ) -> crate::Result<Self> {
        let (left, right) = (left.into(), right.into());
        let need = (width as usize)
            .checked_mul(height as usize)
            .filter(|n| *n > 0)
            .ok_or_else(|| crate::Error::msg("camera image size is zero or overflows"))?;
        if left.len() != need || right.len() != need {
            return Err(crate::Error::msg(format!(
                "camera images must be {width}x{height} = {need} bytes, got {} and {}",
                left.len(),
                right.len()
            )));
        }
        Ok(Self {
            left,
            right,
            width,
            height,
            stride: width,
            exposure_us: 1000,
            sequence: 0,
            clock: None,
            faults: FaultInjector::none(),
            window_faults: FaultInjector::none(),
            latched: false,
            pair_copies: 0,
        })
    }

    /// The same camera with seeded faults of its window reads.
    pub fn with_window_faults(mut self, faults: FaultInjector) -> Self {
        self.window_faults = faults;
        self
    }

    /// Stamp frames with (and block on) this clock.
    pub fn with_clock(mut self, clock: ManualClock) -> Self {
        self.clock = Some(clock);
        self
    }

    /// The same camera with seeded faults.
    pub fn with_faults(mut self, faults: FaultInjector) -> Self {
        self.faults = faults;
        self
    }

    /// Bytes of one image.
    pub fn image_len(&self) -> usize {
        self.left.len()
    }

    /// The pair the camera serves (the caller's own memory when it was
    /// given borrowed images).
    pub fn pixels(&self) -> (&[u8], &[u8]) {
        (&self.left, &self.right)
    }
}

impl ErrorType for FixedCamera<'_> {
    type Error = ErrorKind;
}

impl StereoCamera for FixedCamera<'_> {
    fn capture(
        &mut self,
        left: &mut [u8],
        right: &mut [u8],
        timeout_ticks: u64,
    ) -> Result<FrameInfo, ErrorKind> {
        let n = self.left.len();
        if left.len() < n || right.len() < n {
            return Err(ErrorKind::Other);
        }
        let (l, r) = (&mut left[..n], &mut right[..n]);
        match self.faults.draw() {
            Some(Fault::Timeout) => {
                if let Some(c) = &self.clock {
                    c.advance(timeout_ticks);
                }
                return Err(ErrorKind::Timeout);
            }
            Some(Fault::Truncate) => {
                let k = self.faults.truncated_len(n);
                l[..k].copy_from_slice(&self.left[..k]);
                return Err(ErrorKind::Truncated);
            }
            Some(Fault::Corrupt) => {
                l.copy_from_slice(&self.left);
                r.copy_from_slice(&self.right);
                // Damage spans both images as one transfer would.
                if self.faults.draw_side() {
                    self.faults.corrupt(l);
                } else {
                    self.faults.corrupt(r);
                }
            }
            None => {
                l.copy_from_slice(&self.left);
                r.copy_from_slice(&self.right);
            }
        }
        self.pair_copies = self.pair_copies.saturating_add(1);
        self.sequence = self.sequence.wrapping_add(1);
        Ok(FrameInfo {
            width: self.width,
            height: self.height,
            stride: self.stride,
            sequence: self.sequence,
            timestamp_ticks: self.clock.as_ref().map_or(0, ManualClock::ticks),
            exposure_us: self.exposure_us,
        })
    }
}

/// The camera's frame memory read in place: `capture_in_place` latches the pair (a
/// drawn timeout blocks the attached clock for the timeout; a truncation or
/// corruption of the transfer into the memory is reported as that kind), and
/// `read_window` copies a rectangle out of it with one draw of
/// `window_faults` per read: a timeout, a truncated copy (part of the
/// rectangle, then kind `Truncated`) or a silently damaged copy.
impl FrameStore for FixedCamera<'_> {
    fn capture_in_place(&mut self, timeout_ticks: u64) -> Result<FrameInfo, ErrorKind> {
        self.latched = false;
        match self.faults.draw() {
            Some(Fault::Timeout) => {
                if let Some(c) = &self.clock {
                    c.advance(timeout_ticks);
                }
                return Err(ErrorKind::Timeout);
            }
            Some(Fault::Truncate) => return Err(ErrorKind::Truncated),
            Some(Fault::Corrupt) => return Err(ErrorKind::Corrupted),
            None => {}
        }
        self.latched = true;
        self.sequence = self.sequence.wrapping_add(1);
        Ok(FrameInfo {
            width: self.width,
            height: self.height,
            stride: self.stride,
            sequence: self.sequence,
            timestamp_ticks: self.clock.as_ref().map_or(0, ManualClock::ticks),
            exposure_us: self.exposure_us,
        })
    }

    fn read_window(&mut self, eye: Eye, rect: Rect, out: &mut [u8]) -> Result<(), ErrorKind> {
        if !self.latched {
            return Err(ErrorKind::Unavailable);
        }
        let frame = Rect::new(0, 0, self.width, self.height);
        if rect.w == 0 || rect.h == 0 || !frame.contains(&rect) {
            return Err(ErrorKind::Other);
        }
        let (x, y, w, h) = (
            rect.x as usize,
            rect.y as usize,
            rect.w as usize,
            rect.h as usize,
        );
        let n = w * h;
        let Some(out) = out.get_mut(..n) else {
            return Err(ErrorKind::Other);
        };
        let src = match eye {
            Eye::Left => &self.left,
            Eye::Right => &self.right,
        };
        let stride = self.stride as usize;
        let copy = |out: &mut [u8], rows: usize| {
            for (k, dst) in out.chunks_exact_mut(w).take(rows).enumerate() {
                let at = (y + k) * stride + x;
                dst.copy_from_slice(&src[at..at + w]);
            }
        };
        match self.window_faults.draw() {
            Some(Fault::Timeout) => Err(ErrorKind::Timeout),
            Some(Fault::Truncate) => {
                let rows = self.window_faults.truncated_len(h);
                copy(out, rows);
                Err(ErrorKind::Truncated)
            }
            Some(Fault::Corrupt) => {
                copy(out, h);
                self.window_faults.corrupt(out);
                Ok(())
            }
            None => {
                copy(out, h);
                Ok(())
            }
        }
    }
}

impl FaultInjector {
    fn draw_side(&mut self) -> bool {
        self.rng.below(2) == 0
    }
}

// ---- prior ----------------------------------------------------------------

/// A pose-prior source serving one estimate (or none: `Unavailable`).
#[derive(Clone, Debug)]
pub struct FixedPrior {
    /// The estimate served, if any.
    pub estimate: Option<PriorEstimate>,
}

impl ErrorType for FixedPrior {
    type Error = ErrorKind;
}

impl PosePrior for FixedPrior {
    fn latest(&mut self) -> Result<PriorEstimate, ErrorKind> {
        self.estimate.ok_or(ErrorKind::Unavailable)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
    use super::*;
    use vtsm_core::failure::FailureLog;
    use vtsm_core::geom::Pose;
    use vtsm_core::FailureCode;
    use vtsm_hal::runner::{
        capture_pair, read_map_verified, Buffers, Runner, RunnerConfig, StepStatus,
    };
    use vtsm_hal::telemetry::{parse_failure_event, FrameKind, MAX_PAYLOAD};
    use vtsm_hal::{Covariance, FramedTelemetry, Telemetry};

    fn pattern(n: usize, salt: u8) -> Vec<u8> {
        (0..n)
            .map(|i| (i as u8).wrapping_mul(31).wrapping_add(salt))
            .collect()
    }

    fn faults(t: u8, tr: u8, c: u8, seed: u64) -> FaultInjector {
        FaultInjector::new(
            FaultConfig {
                timeout_pct: t,
                truncate_pct: tr,
                corrupt_pct: c,
            },
            seed,
        )
        .unwrap()
    }

    fn cfg() -> RunnerConfig {
        RunnerConfig {
            attempts: 8,
            product_attempts: 4,
            chunk_len: 100,
            capture_timeout_ticks: 50,
            image_size: (16, 8),
        }
    }

    fn prior() -> PriorEstimate {
        PriorEstimate {
            world_from_left: Pose::from_t_q([1.0, 0.0, 0.3], [1.0, 0.0, 0.0, 0.0]).unwrap(),
            covariance: Covariance::Diagonal([0.01; 6]),
            uncertainty: None,
            timestamp_ticks: 0,
        }
    }

    /// Verifies: VTSM-HAL-010
    #[test]
    fn fault_draws_are_deterministic_and_follow_percentages() {
        let draw = |seed| {
            let mut f = faults(10, 20, 30, seed);
            let v: Vec<_> = (0..20_000).map(|_| f.draw()).collect();
            (v, f.stats)
        };
        let (a, sa) = draw(3);
        let (b, _) = draw(3);
        let (c, _) = draw(4);
        assert_eq!(a, b);
        assert_ne!(a, c);
        // Counted independently from the recorded draws.
        let count = |k| a.iter().filter(|d| **d == Some(k)).count() as f64 / 20_000.0;
        assert!((count(Fault::Timeout) - 0.10).abs() < 0.015);
        assert!((count(Fault::Truncate) - 0.20).abs() < 0.015);
        assert!((count(Fault::Corrupt) - 0.30).abs() < 0.015);
        assert_eq!(sa.timeouts as f64 / 20_000.0, count(Fault::Timeout));
        let mut none = faults(0, 0, 0, 1);
        assert!((0..1000).all(|_| none.draw().is_none()));
        assert!(FaultInjector::new(
            FaultConfig {
                timeout_pct: 50,
                truncate_pct: 50,
                corrupt_pct: 1
            },
            0
        )
        .is_err());
    }

    /// Verifies: VTSM-HAL-010
    #[test]
    fn corruption_changes_a_bounded_burst() {
        let mut f = faults(0, 0, 100, 9);
        for _ in 0..500 {
            let orig = pattern(64, 1);
            let mut buf = orig.clone();
            let n = f.corrupt(&mut buf);
            let diff: Vec<usize> = (0..64).filter(|&i| buf[i] != orig[i]).collect();
            assert_eq!(diff.len(), n);
            assert!((1..=MAX_CORRUPT_BYTES as usize).contains(&n));
            assert_eq!(
                diff.last().unwrap() - diff[0] + 1,
                n,
                "a burst is contiguous"
            );
        }
        assert_eq!(f.corrupt(&mut []), 0);
    }

    /// Verifies: VTSM-HAL-011
    #[test]
    fn manual_clock_advances_only_when_told() {
        let mut c = ManualClock::new(1000).with_cycles();
        let shared = c.clone();
        assert_eq!(c.tick_hz(), 1000);
        assert_eq!(c.now_ticks().unwrap(), 0);
        assert_eq!(c.now_ticks().unwrap(), 0);
        shared.advance(250);
        assert_eq!(c.now_ticks().unwrap(), 250);
        shared.advance(u64::MAX);
        assert_eq!(c.now_ticks().unwrap(), u64::MAX);
        assert_eq!(c.cycles(), Some(0));
        c.advance_cycles(u64::MAX);
        c.advance_cycles(2);
        assert_eq!(c.cycles(), Some(1));
        assert_eq!(ManualClock::new(0).tick_hz(), 1);
        assert_eq!(ManualClock::new(5).cycles(), None);
    }

    /// Verifies: VTSM-HAL-012
    #[test]
    fn store_serves_ranges_and_injects_each_fault() {
        let data = pattern(1000, 7);
        let mut s = MemMapStore::new(data.clone());
        assert_eq!(s.len(), Ok(1000));
        assert_eq!(s.is_empty(), Ok(false));
        let mut buf = [0u8; 10];
        s.read_range(990, &mut buf).unwrap();
        assert_eq!(&buf[..], &data[990..]);
        assert_eq!(s.read_range(991, &mut buf), Err(ErrorKind::Other));
        assert_eq!(s.read_range(u32::MAX, &mut buf), Err(ErrorKind::Other));

        let mut t = MemMapStore::new(data.clone()).with_faults(faults(100, 0, 0, 1));
        assert_eq!(t.read_range(0, &mut buf), Err(ErrorKind::Timeout));
        let mut t = MemMapStore::new(data.clone()).with_faults(faults(0, 100, 0, 1));
        assert_eq!(t.read_range(0, &mut buf), Err(ErrorKind::Truncated));
        let mut t = MemMapStore::new(data.clone()).with_faults(faults(0, 0, 100, 1));
        let mut big = vec![0u8; 200];
        t.read_range(100, &mut big).unwrap();
        let diff = (0..200).filter(|&i| big[i] != data[100 + i]).count();
        assert!((1..=MAX_CORRUPT_BYTES as usize).contains(&diff));
    }

    /// Verifies: VTSM-HAL-013
    #[test]
    fn camera_serves_fixed_frames_and_injects_each_fault() {
        let (l0, r0) = (pattern(128, 0), pattern(128, 100));
        let clock = ManualClock::new(1000);
        let mut cam = FixedCamera::new(l0.clone(), r0.clone(), 16, 8)
            .unwrap()
            .with_clock(clock.clone());
        let (mut l, mut r) = (vec![0u8; 128], vec![0u8; 130]);
        clock.advance(7);
        let i1 = cam.capture(&mut l, &mut r, 50).unwrap();
        assert_eq!((l.as_slice(), &r[..128]), (&l0[..], &r0[..]));
        assert_eq!(
            (
                i1.width,
                i1.height,
                i1.stride,
                i1.sequence,
                i1.timestamp_ticks
            ),
            (16, 8, 16, 1, 7)
        );
        assert_eq!(cam.capture(&mut l, &mut r, 50).unwrap().sequence, 2);
        assert_eq!(
            cam.capture(&mut l[..127], &mut r, 50),
            Err(ErrorKind::Other)
        );
        assert!(FixedCamera::new(l0.clone(), r0.clone(), 16, 9).is_err());

        let mut cam = FixedCamera::new(l0.clone(), r0.clone(), 16, 8)
            .unwrap()
            .with_clock(clock.clone())
            .with_faults(faults(100, 0, 0, 2));
        let t0 = clock.ticks();
        assert_eq!(cam.capture(&mut l, &mut r, 50), Err(ErrorKind::Timeout));
        assert_eq!(clock.ticks(), t0 + 50, "a timeout blocks for the timeout");

        let mut cam = FixedCamera::new(l0.clone(), r0.clone(), 16, 8)
            .unwrap()
            .with_faults(faults(0, 100, 0, 2));
        assert_eq!(cam.capture(&mut l, &mut r, 50), Err(ErrorKind::Truncated));

        let mut cam = FixedCamera::new(l0.clone(), r0.clone(), 16, 8)
            .unwrap()
            .with_faults(faults(0, 0, 100, 2));
        for _ in 0..20 {
            cam.capture(&mut l, &mut r, 50).unwrap();
            let d = (0..128).filter(|&i| l[i] != l0[i] || r[i] != r0[i]).count();
            assert!((1..=MAX_CORRUPT_BYTES as usize).contains(&d), "{d}");
        }
    }

    /// Verifies: VTSM-HAL-014
    #[test]
    fn telemetry_sink_records_frames_and_decodes_them_back() {
        let mut tl = FramedTelemetry::new(RecordingSink::new());
        let msgs: Vec<(u8, Vec<u8>)> = (0..20u8).map(|k| (k, pattern(k as usize * 7, k))).collect();
        for (k, p) in &msgs {
            tl.send(*k, p).unwrap();
        }
        let d = tl.writer().frames();
        assert_eq!(d.skipped_bytes, 0);
        assert_eq!(d.trailing_bytes, 0);
        let got: Vec<(u8, Vec<u8>)> = d.frames.into_iter().map(|f| (f.kind, f.payload)).collect();
        assert_eq!(got, msgs);
        assert_eq!(tl.sent(), 20);
    }

    /// Verifies: VTSM-HAL-014, VTSM-HAL-006
    #[test]
    fn damaged_telemetry_frames_are_dropped_and_the_rest_recovered() {
        // Corrupt 15 % of writes: every frame that decodes must be one that was sent.
        let mut tl = FramedTelemetry::new(RecordingSink::new().with_faults(faults(0, 0, 15, 5)));
        let msgs: Vec<(u8, Vec<u8>)> = (0..200u32)
            .map(|k| (0x10, k.to_le_bytes().to_vec()))
            .collect();
        for (k, p) in &msgs {
            tl.send(*k, p).unwrap();
        }
        let stats = tl.writer().faults.stats;
        assert!(stats.corruptions > 0);
        let d = tl.writer().frames();
        assert!(d.frames.len() < msgs.len());
        assert!(d.frames.len() > msgs.len() / 3, "{}", d.frames.len());
        // In order and genuine: a subsequence of what was sent.
        let mut it = msgs.iter();
        for f in &d.frames {
            assert!(it.any(|(k, p)| *k == f.kind && *p == f.payload), "{f:?}");
        }
        // Timeouts and short writes reach the sender as errors of the right kind.
        let mut tl = FramedTelemetry::new(RecordingSink::new().with_faults(faults(100, 0, 0, 5)));
        let e = tl.send(1, &[1, 2]).unwrap_err();
        assert_eq!(vtsm_hal::Error::kind(&e), ErrorKind::Timeout);
        let mut tl = FramedTelemetry::new(RecordingSink::new().with_faults(faults(0, 100, 0, 5)));
        let e = tl.send(1, &[1, 2]).unwrap_err();
        assert_eq!(vtsm_hal::Error::kind(&e), ErrorKind::Truncated);
        assert_eq!(tl.failed(), 1);
        assert!(tl.writer().frames().frames.is_empty());
    }

    /// Verifies: VTSM-HAL-020
    #[test]
    fn runner_capture_retries_transient_faults_within_the_cap() {
        let (l0, r0) = (pattern(128, 3), pattern(128, 4));
        // 60 % timeouts or truncations: the capture needs retries, and succeeds
        // with the exact frames; every failed attempt is logged.
        for seed in 0..20 {
            let mut cam = FixedCamera::new(l0.clone(), r0.clone(), 16, 8)
                .unwrap()
                .with_faults(faults(30, 30, 0, seed));
            let (mut l, mut r) = (vec![0u8; 128], vec![0u8; 128]);
            let mut log = FailureLog::new();
            match capture_pair(&mut cam, &mut l, &mut r, &cfg(), 0, &mut log) {
                Ok((info, rep)) => {
                    assert_eq!((l.as_slice(), r.as_slice()), (&l0[..], &r0[..]));
                    assert_eq!(info.sequence, 1);
                    let failed = rep.timeouts + rep.truncated;
                    assert_eq!(rep.attempts, failed + 1);
                    assert_eq!(
                        u64::from(failed),
                        cam.faults.stats.timeouts + cam.faults.stats.truncations
                    );
                    assert_eq!(
                        log.count(FailureCode::HalCameraTimeout),
                        u16::from(rep.timeouts)
                    );
                    assert_eq!(
                        log.count(FailureCode::HalCameraFrameTruncated),
                        u16::from(rep.truncated)
                    );
                }
                Err(code) => {
                    assert_eq!(code, FailureCode::HalCameraRetriesExhausted);
                    assert_eq!(cam.faults.stats.operations, 8);
                }
            }
        }
    }

    /// Verifies: VTSM-HAL-020, VTSM-HAL-003
    #[test]
    fn runner_capture_gives_up_after_the_cap_or_on_a_contract_breach() {
        let (l0, r0) = (pattern(128, 3), pattern(128, 4));
        let mut cam = FixedCamera::new(l0.clone(), r0.clone(), 16, 8)
            .unwrap()
            .with_faults(faults(100, 0, 0, 1));
        let (mut l, mut r) = (vec![0u8; 128], vec![0u8; 128]);
        let mut log = FailureLog::new();
        let res = capture_pair(&mut cam, &mut l, &mut r, &cfg(), 3, &mut log);
        assert_eq!(res.err(), Some(FailureCode::HalCameraRetriesExhausted));
        assert_eq!(cam.faults.stats.operations, u64::from(cfg().attempts));
        assert_eq!(log.count(FailureCode::HalCameraTimeout), 8);
        assert_eq!(log.count(FailureCode::HalCameraRetriesExhausted), 1);
        // A frame of the wrong size is rejected, not retried.
        let mut cam = FixedCamera::new(pattern(64, 0), pattern(64, 0), 8, 8).unwrap();
        let res = capture_pair(&mut cam, &mut l, &mut r, &cfg(), 3, &mut log);
        assert_eq!(res.err(), Some(FailureCode::HalFrameInfoInvalid));
        // Too-small buffers are a non-transient camera fault.
        let mut cam = FixedCamera::new(l0, r0, 16, 8).unwrap();
        let res = capture_pair(&mut cam, &mut l[..10], &mut r, &cfg(), 3, &mut log);
        assert_eq!(res.err(), Some(FailureCode::HalCameraFault));
        assert_eq!(cam.faults.stats.operations, 0);
    }

    /// Verifies: VTSM-HAL-021
    #[test]
    fn runner_reads_the_map_exactly_despite_faults_and_rereads_on_bad_check() {
        let data = pattern(1234, 9);
        let reference = data.clone();
        // The check stands in for the map product's CRCs: it compares with the original.
        let check = |b: &[u8]| {
            if b == reference.as_slice() {
                Ok(())
            } else {
                Err(FailureCode::MapCrcMismatch)
            }
        };
        let mut ok = 0;
        for seed in 0..30 {
            let mut s = MemMapStore::new(data.clone()).with_faults(faults(10, 10, 2, seed));
            let mut buf = vec![0u8; 2000];
            let mut log = FailureLog::new();
            match read_map_verified(&mut s, &mut buf, &cfg(), 0, &mut log, check) {
                Ok((n, rep)) => {
                    ok += 1;
                    assert_eq!(&buf[..n], &data[..]);
                    assert_eq!(rep.len, 1234);
                    assert_eq!(u64::from(rep.reads), s.faults.stats.operations);
                    assert_eq!(
                        u64::from(rep.failed_reads),
                        s.faults.stats.timeouts + s.faults.stats.truncations
                    );
                    // Each silent corruption cost one extra whole-product pass at most.
                    assert!(u64::from(rep.product_attempts) <= 1 + s.faults.stats.corruptions);
                    assert_eq!(
                        u64::from(log.count(FailureCode::MapCrcMismatch)),
                        u64::from(rep.product_attempts - 1)
                    );
                }
                Err(code) => assert!(
                    code == FailureCode::MapCrcMismatch
                        || code == FailureCode::HalStorageRetriesExhausted,
                    "{code:?}"
                ),
            }
        }
        assert!(ok >= 25, "{ok}/30");
        // Always corrupt: every pass fails the check, bounded by product_attempts.
        let mut s = MemMapStore::new(data.clone()).with_faults(faults(0, 0, 100, 1));
        let mut buf = vec![0u8; 2000];
        let mut log = FailureLog::new();
        let res = read_map_verified(&mut s, &mut buf, &cfg(), 0, &mut log, check);
        assert_eq!(res.err(), Some(FailureCode::MapCrcMismatch));
        assert_eq!(log.count(FailureCode::MapCrcMismatch), 4);
        assert_eq!(s.faults.stats.operations, 4 * 13);
        // Too small a buffer: nothing is read.
        let mut s = MemMapStore::new(data.clone());
        let res = read_map_verified(&mut s, &mut buf[..1233], &cfg(), 0, &mut log, check);
        assert_eq!(res.err(), Some(FailureCode::HalMapTooLarge));
        assert_eq!(s.faults.stats.operations, 0);
        // Always time out: the chunk cap ends it.
        let mut s = MemMapStore::new(data).with_faults(faults(100, 0, 0, 1));
        let res = read_map_verified(&mut s, &mut buf, &cfg(), 0, &mut log, check);
        assert_eq!(res.err(), Some(FailureCode::HalStorageRetriesExhausted));
        assert_eq!(s.faults.stats.operations, 8);
    }

    fn runner(
        cam_faults: FaultInjector,
        prior_est: Option<PriorEstimate>,
    ) -> (
        Runner<
            FixedCamera<'static>,
            ManualClock,
            MemMapStore<'static>,
            FixedPrior,
            FramedTelemetry<RecordingSink>,
        >,
        ManualClock,
    ) {
        let clock = ManualClock::new(1000).with_cycles();
        let cam = FixedCamera::new(pattern(128, 1), pattern(128, 2), 16, 8)
            .unwrap()
            .with_clock(clock.clone())
            .with_faults(cam_faults);
        let r = Runner::new(
            cam,
            clock.clone(),
            MemMapStore::new(pattern(500, 5)),
            FixedPrior {
                estimate: prior_est,
            },
            FramedTelemetry::new(RecordingSink::new()),
            cfg(),
        );
        (r, clock)
    }

    /// Verifies: VTSM-HAL-022, VTSM-HAL-014
    #[test]
    fn runner_acquires_inputs_and_downlinks_its_failure_log() {
        let (mut run, clock) = runner(faults(100, 0, 0, 1), Some(prior()));
        clock.advance(10);
        let (mut l, mut r, mut m) = (vec![0u8; 128], vec![0u8; 128], vec![0u8; 600]);
        let res = run.acquire(
            Buffers {
                left: &mut l,
                right: &mut r,
                map: &mut m,
            },
            |_| Ok(()),
        );
        assert_eq!(res.err(), Some(FailureCode::HalCameraRetriesExhausted));
        // Each timeout blocked 50 ticks on the shared clock.
        assert_eq!(clock.ticks(), 10 + 8 * 50);
        run.send_failure_log();
        let d = run.telemetry.writer().frames();
        assert_eq!(d.frames.len(), 1 + 9);
        assert_eq!(d.frames[0].kind, FrameKind::FailureCounters as u8);
        let expect_counters = [0x01u8, 0x09, 8, 0, 0x07, 0x09, 1, 0];
        assert_eq!(d.frames[0].payload, expect_counters);
        let events: Vec<_> = d.frames[1..]
            .iter()
            .map(|f| parse_failure_event(&f.payload).unwrap())
            .collect();
        assert!(events[..8]
            .iter()
            .all(|e| e.code == FailureCode::HalCameraTimeout));
        assert_eq!(events[8].code, FailureCode::HalCameraRetriesExhausted);

        let (mut run, _) = runner(FaultInjector::none(), Some(prior()));
        let inputs = run
            .acquire(
                Buffers {
                    left: &mut l,
                    right: &mut r,
                    map: &mut m,
                },
                |_| Ok(()),
            )
            .unwrap();
        assert_eq!(inputs.map, &pattern(500, 5)[..]);
        assert_eq!(inputs.left.get(3, 2), Some(pattern(128, 1)[2 * 16 + 3]));
        assert_eq!(inputs.prior, prior());
        assert_eq!(inputs.capture.attempts, 1);

        let (mut run, _) = runner(FaultInjector::none(), None);
        let res = run.acquire(
            Buffers {
                left: &mut l,
                right: &mut r,
                map: &mut m,
            },
            |_| Ok(()),
        );
        assert_eq!(res.err(), Some(FailureCode::HalPriorUnavailable));
        let mut bad = prior();
        bad.covariance = Covariance::Diagonal([-1.0; 6]);
        let (mut run, _) = runner(FaultInjector::none(), Some(bad));
        let res = run.acquire(
            Buffers {
                left: &mut l,
                right: &mut r,
                map: &mut m,
            },
            |_| Ok(()),
        );
        assert_eq!(res.err(), Some(FailureCode::HalPriorInvalid));
    }

    /// Verifies: VTSM-HAL-022
    #[test]
    fn runner_drops_a_payload_the_frame_cannot_carry_and_logs_it() {
        let (mut run, _) = runner(FaultInjector::none(), Some(prior()));
        run.send(FrameKind::Outcome as u8, &[0u8; MAX_PAYLOAD + 1]);
        assert_eq!(run.telemetry_dropped, 1);
        assert_eq!(run.log.count(FailureCode::HalTelemetryPayloadTooLong), 1);
        assert!(run.telemetry.writer().frames().frames.is_empty());
        // The largest payload the format carries goes out.
        run.send(FrameKind::Outcome as u8, &[0u8; MAX_PAYLOAD]);
        assert_eq!(run.telemetry_dropped, 1);
        assert_eq!(run.telemetry.writer().frames().frames.len(), 1);
    }

    /// Verifies: VTSM-HAL-023
    #[test]
    fn drive_stops_at_done_error_step_cap_or_tick_budget() {
        let (mut run, clock) = runner(FaultInjector::none(), Some(prior()));
        // Each step costs 7 ticks and 100 cycles; done on the 5th.
        let mut calls = 0;
        let (rep, res) = run.drive(100, 1_000, |_| {
            calls += 1;
            clock.advance(7);
            clock.advance_cycles(100);
            Ok(if calls == 5 {
                StepStatus::Done
            } else {
                StepStatus::Continue
            })
        });
        assert_eq!(res, Ok(()));
        assert_eq!(
            (rep.steps, rep.elapsed_ticks, rep.cycles, rep.done),
            (5, 35, Some(500), true)
        );
        // Tick budget: 30 ticks at 7 per step → 5 steps (0,7,14,21,28 < 30).
        let (rep, res) = run.drive(100, 30, |_| {
            clock.advance(7);
            Ok(StepStatus::Continue)
        });
        assert_eq!(res, Err(FailureCode::RelocBudgetExhausted));
        assert_eq!(rep.steps, 5);
        // Step cap with a stopped clock.
        let (rep, res) = run.drive(12, 1_000, |_| Ok(StepStatus::Continue));
        assert_eq!(
            (rep.steps, res),
            (12, Err(FailureCode::RelocBudgetExhausted))
        );
        assert_eq!(run.log.count(FailureCode::RelocBudgetExhausted), 2);
        // An engine error ends the run at once.
        let (rep, res) = run.drive(12, 1_000, |now| {
            assert_eq!(now, clock.ticks());
            Err(FailureCode::RelocStallCapReached)
        });
        assert_eq!(
            (rep.steps, res),
            (1, Err(FailureCode::RelocStallCapReached))
        );
    }
}
