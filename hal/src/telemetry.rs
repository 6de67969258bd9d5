//! Telemetry: small self-delimiting frames over any [`embedded_io::Write`].
//!
//! Frame layout (all integers little-endian), see `fsw-docs/interfaces/telemetry.md`:
//!
//! | bytes | field | notes |
//! |---|---|---|
//! | 2 | sync | [`SYNC`] = `EB 90` |
//! | 1 | kind | [`FrameKind`] or a mission-defined value |
//! | 2 | length | payload bytes, `0..=MAX_PAYLOAD` |
//! | length | payload | |
//! | 2 | crc | CRC-16/CCITT-FALSE over kind, length and payload |
//!
//! The encoder streams a frame to the writer without a buffer ([`write_frame`])
//! or encodes into a caller slice ([`encode`]); [`decode`] / [`decode_prefix`]
//! check a frame without copying. Work per frame is O(payload), payload ≤
//! [`MAX_PAYLOAD`]. The CRC detects every error burst of up to 16 bits inside
//! the covered bytes, so any single damaged byte is detected.

use crate::error::{Error, ErrorKind, ErrorType};
use vtsm_core::failure::{Event, FailureLog};
use vtsm_core::FailureCode;

/// Frame sync word, first on the wire.
pub const SYNC: [u8; 2] = [0xEB, 0x90];
/// Largest payload a frame carries.
pub const MAX_PAYLOAD: usize = 1024;
/// Bytes of a frame that are not payload (sync, kind, length, crc).
pub const OVERHEAD: usize = 7;
/// Largest encoded frame.
pub const MAX_FRAME: usize = MAX_PAYLOAD + OVERHEAD;
const HEADER: usize = 5;

/// Frame kinds defined by VTSM. Values 0x80..=0xFF are left to the mission.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum FrameKind {
    /// One failure event: code u16, tick u64, detail u32 (14 bytes).
    FailureEvent = 0x01,
    /// Non-zero failure counters: `(code u16, count u16)` pairs.
    FailureCounters = 0x02,
    /// Free-form status text (ASCII), for bring-up.
    Text = 0x03,
    /// The result of one relocalization ([`outcome_payload`], [`OUTCOME_LEN`] bytes).
    Outcome = 0x04,
}

/// Size of a [`FrameKind::FailureEvent`] payload.
pub const FAILURE_EVENT_LEN: usize = 14;
const _: () = assert!(FailureCode::ALL.len() * 4 <= MAX_PAYLOAD);

/// Why a frame could not be encoded or decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// The payload is longer than [`MAX_PAYLOAD`].
    PayloadTooLong,
    /// The output slice is too small for the frame.
    BufferTooSmall,
    /// The bytes end before the frame does.
    Truncated,
    /// The bytes do not start with [`SYNC`].
    BadSync,
    /// The length field is above [`MAX_PAYLOAD`].
    BadLength,
    /// The slice is longer than the one frame it should hold.
    TrailingBytes,
    /// The CRC does not match.
    BadCrc,
}

/// A decoded frame borrowing its payload from the input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame<'a> {
    /// Frame kind byte.
    pub kind: u8,
    /// Payload bytes.
    pub payload: &'a [u8],
}

// Indexing is bounded: the loop runs i in 0..256 over a [u16; 256] at compile time.
#[allow(clippy::indexing_slicing)]
const CRC_TABLE: [u16; 256] = {
    let mut t = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = (i as u16) << 8;
        let mut b = 0;
        while b < 8 {
            c = if c & 0x8000 != 0 {
                (c << 1) ^ 0x1021
            } else {
                c << 1
            };
            b += 1;
        }
        t[i] = c;
        i += 1;
    }
    t
};

/// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no xor-out),
/// continued from `crc` over `bytes`. Start with `0xFFFF`.
pub fn crc16_update(mut crc: u16, bytes: &[u8]) -> u16 {
    for &b in bytes {
        let idx = usize::from((crc >> 8) as u8 ^ b);
        crc = (crc << 8) ^ CRC_TABLE.get(idx).copied().unwrap_or(0);
    }
    crc
}

/// CRC-16/CCITT-FALSE of `bytes`.
pub fn crc16(bytes: &[u8]) -> u16 {
    crc16_update(0xFFFF, bytes)
}

fn header(kind: u8, payload: &[u8]) -> Result<[u8; HEADER], FrameError> {
    let len = u16::try_from(payload.len()).map_err(|_| FrameError::PayloadTooLong)?;
    if payload.len() > MAX_PAYLOAD {
        return Err(FrameError::PayloadTooLong);
    }
    let [l0, l1] = len.to_le_bytes();
    Ok([SYNC[0], SYNC[1], kind, l0, l1])
}

fn frame_crc(h: &[u8; HEADER], payload: &[u8]) -> u16 {
    let [_, _, kind, l0, l1] = *h;
    crc16_update(crc16(&[kind, l0, l1]), payload)
}

/// Encode one frame into `out`; returns the number of bytes written
/// (`payload.len() + OVERHEAD`). Nothing is written on error.
pub fn encode(kind: u8, payload: &[u8], out: &mut [u8]) -> Result<usize, FrameError> {
    let h = header(kind, payload)?;
    let n = payload.len() + OVERHEAD;
    let out = out.get_mut(..n).ok_or(FrameError::BufferTooSmall)?;
    let (hd, rest) = out.split_at_mut(HEADER);
    let (pl, cr) = rest.split_at_mut(payload.len());
    hd.copy_from_slice(&h);
    pl.copy_from_slice(payload);
    cr.copy_from_slice(&frame_crc(&h, payload).to_le_bytes());
    Ok(n)
}

/// Decode the frame at the start of `bytes`; returns it and the bytes it used.
///
/// For stream receivers: on [`FrameError::Truncated`] wait for more bytes; on
/// any other error skip one byte and search for [`SYNC`] again.
pub fn decode_prefix(bytes: &[u8]) -> Result<(Frame<'_>, usize), FrameError> {
    let hd = bytes.get(..HEADER).ok_or(FrameError::Truncated)?;
    let [s0, s1, kind, l0, l1] = [0, 1, 2, 3, 4].map(|i| hd.get(i).copied().unwrap_or(0));
    if [s0, s1] != SYNC {
        return Err(FrameError::BadSync);
    }
    let len = usize::from(u16::from_le_bytes([l0, l1]));
    if len > MAX_PAYLOAD {
        return Err(FrameError::BadLength);
    }
    let n = len + OVERHEAD;
    let frame = bytes.get(..n).ok_or(FrameError::Truncated)?;
    let payload = frame
        .get(HEADER..HEADER + len)
        .ok_or(FrameError::Truncated)?;
    let crc = frame.get(HEADER + len..).ok_or(FrameError::Truncated)?;
    let want = crc16_update(crc16(&[kind, l0, l1]), payload);
    if crc != want.to_le_bytes() {
        return Err(FrameError::BadCrc);
    }
    Ok((Frame { kind, payload }, n))
}

/// Decode a slice that holds exactly one frame.
pub fn decode(bytes: &[u8]) -> Result<Frame<'_>, FrameError> {
    let (f, n) = decode_prefix(bytes)?;
    if n != bytes.len() {
        return Err(FrameError::TrailingBytes);
    }
    Ok(f)
}

/// Write one frame to `w`, streaming (no buffer). Errors of the writer are
/// returned as they are; on error a partial frame may have been written and
/// the receiver resynchronises on the next [`SYNC`].
pub fn write_frame<W: embedded_io::Write>(
    w: &mut W,
    kind: u8,
    payload: &[u8],
) -> Result<(), TelemetryError<W::Error>> {
    let h = header(kind, payload).map_err(|_| TelemetryError::PayloadTooLong)?;
    let crc = frame_crc(&h, payload).to_le_bytes();
    write_all(w, &h)?;
    write_all(w, payload)?;
    write_all(w, &crc)
}

/// `embedded_io::Write::write_all` without its panic on `Ok(0)`: a writer that
/// accepts nothing is an error. At most `buf.len()` calls, since every other
/// success consumes at least one byte.
fn write_all<W: embedded_io::Write>(
    w: &mut W,
    mut buf: &[u8],
) -> Result<(), TelemetryError<W::Error>> {
    for _ in 0..buf.len() {
        if buf.is_empty() {
            break;
        }
        match w.write(buf) {
            Ok(0) => return Err(TelemetryError::WriteZero),
            Ok(n) => buf = buf.get(n..).unwrap_or(&[]),
            Err(e) => return Err(TelemetryError::Io(e)),
        }
    }
    Ok(())
}

/// Payload of a [`FrameKind::FailureEvent`] frame.
pub fn failure_event_payload(e: &Event) -> [u8; FAILURE_EVENT_LEN] {
    let mut p = [0u8; FAILURE_EVENT_LEN];
    let (c, rest) = p.split_at_mut(2);
    let (t, d) = rest.split_at_mut(8);
    c.copy_from_slice(&e.code.code().to_le_bytes());
    t.copy_from_slice(&e.tick.to_le_bytes());
    d.copy_from_slice(&e.detail.to_le_bytes());
    p
}

/// Size of a [`FrameKind::Outcome`] payload.
pub const OUTCOME_LEN: usize = 42;

/// The fields of a [`FrameKind::Outcome`] frame.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OutcomeSummary {
    /// Failure code value, 0 on success.
    pub failure: u16,
    /// Inliers of the returned pose.
    pub inliers: u16,
    /// Successful iterations.
    pub successes: u16,
    /// Correspondence attempts.
    pub attempts: u32,
    /// Work units done.
    pub work_units: u32,
    /// `world_from_left` translation, metres.
    pub t: [f32; 3],
    /// `world_from_left` rotation quaternion `[w, x, y, z]`.
    pub q: [f32; 4],
}

impl OutcomeSummary {
    /// The summary of an engine outcome.
    pub fn of(o: &vtsm_core::reloc::Outcome) -> Self {
        Self {
            failure: o.failure.map_or(0, FailureCode::code),
            inliers: o.quality.inliers,
            successes: o.stats.successes,
            attempts: o.stats.attempts,
            work_units: o.stats.work_units,
            t: o.pose.t(),
            q: o.pose.q(),
        }
    }
}

/// Payload of a [`FrameKind::Outcome`] frame, little-endian: failure u16,
/// inliers u16, successes u16, attempts u32, work units u32, t 3×f32, q 4×f32.
pub fn outcome_payload(s: &OutcomeSummary) -> [u8; OUTCOME_LEN] {
    let mut p = [0u8; OUTCOME_LEN];
    let mut at = 0usize;
    let mut put = |b: &[u8]| {
        if let Some(d) = p.get_mut(at..).and_then(|d| d.get_mut(..b.len())) {
            d.copy_from_slice(b);
        }
        at = at.saturating_add(b.len());
    };
    put(&s.failure.to_le_bytes());
    put(&s.inliers.to_le_bytes());
    put(&s.successes.to_le_bytes());
    put(&s.attempts.to_le_bytes());
    put(&s.work_units.to_le_bytes());
    for v in s.t.iter().chain(s.q.iter()) {
        put(&v.to_le_bytes());
    }
    p
}

/// Parse a [`FrameKind::Outcome`] payload; `None` if its length is wrong.
pub fn parse_outcome(p: &[u8]) -> Option<OutcomeSummary> {
    if p.len() != OUTCOME_LEN {
        return None;
    }
    let u16_at = |i: usize| Some(u16::from_le_bytes(p.get(i..i + 2)?.try_into().ok()?));
    let u32_at = |i: usize| Some(u32::from_le_bytes(p.get(i..i + 4)?.try_into().ok()?));
    let f32_at = |k: usize| Some(f32::from_bits(u32_at(14 + 4 * k)?));
    Some(OutcomeSummary {
        failure: u16_at(0)?,
        inliers: u16_at(2)?,
        successes: u16_at(4)?,
        attempts: u32_at(6)?,
        work_units: u32_at(10)?,
        t: [f32_at(0)?, f32_at(1)?, f32_at(2)?],
        q: [f32_at(3)?, f32_at(4)?, f32_at(5)?, f32_at(6)?],
    })
}

/// Parse a [`FrameKind::FailureEvent`] payload; `None` if malformed or the code is unknown.
pub fn parse_failure_event(p: &[u8]) -> Option<Event> {
    if p.len() != FAILURE_EVENT_LEN {
        return None;
    }
    let code = FailureCode::from_u16(u16::from_le_bytes(p.get(0..2)?.try_into().ok()?))?;
    let tick = u64::from_le_bytes(p.get(2..10)?.try_into().ok()?);
    let detail = u32::from_le_bytes(p.get(10..14)?.try_into().ok()?);
    Some(Event { code, tick, detail })
}

/// Fill `out` with the [`FrameKind::FailureCounters`] payload of `log`; returns its length.
pub fn failure_counters_payload(log: &FailureLog, out: &mut [u8; MAX_PAYLOAD]) -> usize {
    let mut n = 0;
    for ((code, count), slot) in log.counters().zip(out.chunks_exact_mut(4)) {
        let [a, b] = code.code().to_le_bytes();
        let [c, d] = count.to_le_bytes();
        slot.copy_from_slice(&[a, b, c, d]);
        n += 4;
    }
    n
}

/// Error of [`FramedTelemetry`]: the writer's error, or a payload too long to frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TelemetryError<E> {
    /// The writer failed.
    Io(E),
    /// The payload is longer than [`MAX_PAYLOAD`]; nothing was written.
    PayloadTooLong,
    /// The writer accepted no bytes (`Ok(0)`); the frame is incomplete.
    WriteZero,
}

impl<E: embedded_io::Error> Error for TelemetryError<E> {
    fn kind(&self) -> ErrorKind {
        match self {
            TelemetryError::Io(e) => match e.kind() {
                embedded_io::ErrorKind::TimedOut => ErrorKind::Timeout,
                embedded_io::ErrorKind::WriteZero => ErrorKind::Truncated,
                embedded_io::ErrorKind::NotConnected => ErrorKind::Unavailable,
                _ => ErrorKind::Other,
            },
            TelemetryError::PayloadTooLong => ErrorKind::Other,
            TelemetryError::WriteZero => ErrorKind::Truncated,
        }
    }
}

/// A telemetry downlink that sends framed messages.
pub trait Telemetry: ErrorType {
    /// Send one frame of `kind` carrying `payload`.
    ///
    /// # Contract
    /// * `payload.len() <= MAX_PAYLOAD`, else an error and nothing is sent.
    /// * On `Ok(())` the whole frame has been handed to the link, in order
    ///   after every frame sent before it.
    /// * On error the frame may be partly sent; the receiver drops it by CRC and
    ///   resynchronises on the next sync word. The caller counts it as dropped
    ///   and does not retry (telemetry is never worth blocking the core for).
    /// * Keeps no reference to `payload`.
    fn send(&mut self, kind: u8, payload: &[u8]) -> Result<(), Self::Error>;
}

impl<T: Telemetry + ?Sized> Telemetry for &mut T {
    fn send(&mut self, kind: u8, payload: &[u8]) -> Result<(), Self::Error> {
        T::send(self, kind, payload)
    }
}

/// [`Telemetry`] over any [`embedded_io::Write`], framing each message.
#[derive(Debug)]
pub struct FramedTelemetry<W> {
    writer: W,
    sent: u32,
    failed: u32,
}

impl<W: embedded_io::Write> FramedTelemetry<W> {
    /// Frame messages onto `writer`.
    pub const fn new(writer: W) -> Self {
        Self {
            writer,
            sent: 0,
            failed: 0,
        }
    }
    /// Frames sent successfully (saturating).
    pub fn sent(&self) -> u32 {
        self.sent
    }
    /// Frames that failed (saturating).
    pub fn failed(&self) -> u32 {
        self.failed
    }
    /// The underlying writer.
    pub fn writer(&self) -> &W {
        &self.writer
    }
    /// Give the writer back.
    pub fn into_inner(self) -> W {
        self.writer
    }
}

impl<W: embedded_io::Write> ErrorType for FramedTelemetry<W> {
    type Error = TelemetryError<W::Error>;
}

impl<W: embedded_io::Write> Telemetry for FramedTelemetry<W> {
    fn send(&mut self, kind: u8, payload: &[u8]) -> Result<(), Self::Error> {
        match write_frame(&mut self.writer, kind, payload) {
            Ok(()) => {
                self.sent = self.sent.saturating_add(1);
                Ok(())
            }
            Err(e) => {
                self.failed = self.failed.saturating_add(1);
                Err(e)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use proptest::prelude::*;
    use std::vec::Vec;

    /// A growable in-memory writer for tests.
    struct VecWriter(Vec<u8>);
    impl embedded_io::ErrorType for VecWriter {
        type Error = core::convert::Infallible;
    }
    impl embedded_io::Write for VecWriter {
        fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
            self.0.extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> Result<(), Self::Error> {
            Ok(())
        }
    }

    /// Bit-by-bit CRC-16/CCITT-FALSE, independent of the table version.
    fn crc_ref(bytes: &[u8]) -> u16 {
        let mut c: u16 = 0xFFFF;
        for &b in bytes {
            c ^= u16::from(b) << 8;
            for _ in 0..8 {
                c = if c & 0x8000 != 0 {
                    (c << 1) ^ 0x1021
                } else {
                    c << 1
                };
            }
        }
        c
    }

    /// Verifies: VTSM-HAL-006
    #[test]
    fn crc_matches_the_standard_check_value() {
        // Published check value of CRC-16/CCITT-FALSE for "123456789".
        assert_eq!(crc16(b"123456789"), 0x29B1);
        assert_eq!(crc_ref(b"123456789"), 0x29B1);
    }

    /// Verifies: VTSM-HAL-006
    #[test]
    fn frame_layout_is_as_documented() {
        let mut out = [0u8; 16];
        let n = encode(0x42, &[1, 2, 3], &mut out).unwrap();
        assert_eq!(n, 10);
        assert_eq!(&out[..5], &[0xEB, 0x90, 0x42, 3, 0]);
        assert_eq!(&out[5..8], &[1, 2, 3]);
        let crc = crc_ref(&[0x42, 3, 0, 1, 2, 3]);
        assert_eq!(&out[8..10], &crc.to_le_bytes());
        assert_eq!(
            encode(1, &[0; 4], &mut [0u8; 10]),
            Err(FrameError::BufferTooSmall)
        );
        assert_eq!(
            encode(1, &[0; MAX_PAYLOAD + 1], &mut [0u8; MAX_FRAME + 1]),
            Err(FrameError::PayloadTooLong)
        );
        let mut tl = FramedTelemetry::new(VecWriter(Vec::new()));
        assert_eq!(
            tl.send(1, &[0; MAX_PAYLOAD + 1]),
            Err(TelemetryError::PayloadTooLong)
        );
        assert!(tl.writer().0.is_empty());
        assert_eq!(tl.failed(), 1);
    }

    /// Accepts at most `per_call` bytes per write, and nothing once `budget` is spent.
    struct Trickle {
        out: Vec<u8>,
        per_call: usize,
        budget: usize,
    }
    impl embedded_io::ErrorType for Trickle {
        type Error = core::convert::Infallible;
    }
    impl embedded_io::Write for Trickle {
        fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
            let n = buf.len().min(self.per_call).min(self.budget);
            self.out.extend_from_slice(&buf[..n]);
            self.budget -= n;
            Ok(n)
        }
        fn flush(&mut self) -> Result<(), Self::Error> {
            Ok(())
        }
    }

    /// Verifies: VTSM-HAL-006
    #[test]
    fn short_writes_are_completed_and_a_stalled_writer_is_an_error() {
        let payload = [7u8; 40];
        let mut t = Trickle {
            out: Vec::new(),
            per_call: 1,
            budget: usize::MAX,
        };
        write_frame(&mut t, 9, &payload).unwrap();
        assert_eq!(decode(&t.out).unwrap().payload, &payload[..]);
        let mut t = Trickle {
            out: Vec::new(),
            per_call: 3,
            budget: 20,
        };
        let e = write_frame(&mut t, 9, &payload).unwrap_err();
        assert_eq!(e, TelemetryError::WriteZero);
        assert_eq!(e.kind(), ErrorKind::Truncated);
        assert_eq!(t.out.len(), 20);
    }

    /// Verifies: VTSM-HAL-007
    #[test]
    fn failure_payloads_round_trip() {
        let e = Event {
            code: FailureCode::HalCameraTimeout,
            tick: 0x0102_0304_0506_0708,
            detail: 77,
        };
        assert_eq!(parse_failure_event(&failure_event_payload(&e)), Some(e));
        assert_eq!(parse_failure_event(&[0u8; 14]), None);
        let mut log = FailureLog::new();
        log.record(FailureCode::NccLowScore, 1, 0);
        log.record(FailureCode::NccLowScore, 2, 0);
        log.record(FailureCode::MapTruncated, 3, 0);
        let mut buf = [0u8; MAX_PAYLOAD];
        let n = failure_counters_payload(&log, &mut buf);
        assert_eq!(n, 8);
        // Table order: map (0x0301) before ncc (0x0507).
        assert_eq!(&buf[..8], &[0x01, 0x03, 1, 0, 0x07, 0x05, 2, 0]);
    }

    proptest! {
        /// Verifies: VTSM-HAL-006
        #[test]
        fn decode_inverts_encode_and_streaming_agrees(kind in any::<u8>(),
                payload in proptest::collection::vec(any::<u8>(), 0..=MAX_PAYLOAD)) {
            let mut buf = [0u8; MAX_FRAME];
            let n = encode(kind, &payload, &mut buf).unwrap();
            prop_assert_eq!(n, payload.len() + OVERHEAD);
            let f = decode(&buf[..n]).unwrap();
            prop_assert_eq!(f.kind, kind);
            prop_assert_eq!(f.payload, &payload[..]);
            let mut w = VecWriter(Vec::new());
            write_frame(&mut w, kind, &payload).unwrap();
            prop_assert_eq!(&w.0[..], &buf[..n]);
            // Every strict prefix is reported as incomplete, never as a frame.
            for cut in [0, 1, 4, 5, n / 2, n - 1] {
                prop_assert_eq!(decode_prefix(&buf[..cut]).err(), Some(FrameError::Truncated));
            }
        }

        /// Verifies: VTSM-HAL-006
        #[test]
        fn any_corrupted_byte_is_detected(kind in any::<u8>(),
                payload in proptest::collection::vec(any::<u8>(), 0..64),
                pos in any::<proptest::sample::Index>(), flip in 1u8..=255) {
            let mut buf = [0u8; MAX_FRAME];
            let n = encode(kind, &payload, &mut buf).unwrap();
            let i = pos.index(n);
            buf[i] ^= flip;
            prop_assert!(decode(&buf[..n]).is_err(), "byte {} ^ {:#x} not detected", i, flip);
        }
    }
}
