//! Numbered failure codes and the failure log.
//!
//! Every way an input or a stage can fail has its own [`FailureCode`]:
//! `#[repr(u16)]`, grouped by subsystem in the high byte (0x01xx config,
//! 0x02xx image, 0x03xx map, 0x04xx raster, 0x05xx ncc, 0x06xx stereo,
//! 0x07xx pose, 0x08xx reloc, 0x09xx hardware/HAL, 0x0Axx C interface). Zero is
//! never an error.
//! Each code carries a [`Severity`] and a [`Retry`] hint; the table in
//! `fsw-docs/failure-codes.md` is checked against [`FailureCode::ALL`] by a test.
//!
//! [`FailureLog`] keeps one saturating counter per code and a ring of the last
//! [`crate::config::FAILURE_RING_LEN`] events. Bounded: recording is O(codes).

use crate::config::{ParamError, FAILURE_RING_LEN};

/// How bad a failure is for the relocalization that saw it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Severity {
    /// Expected during normal operation (a template did not match); counted, not reported.
    Info,
    /// One attempt or one iteration is lost; the run continues.
    Degraded,
    /// The relocalization cannot produce a pose from these inputs.
    Fatal,
}

/// What the caller should do next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Retry {
    /// Try again with the same inputs (a transient device fault, another random sample).
    Same,
    /// Retry only with new inputs (a new frame, a new prior, a re-read of storage).
    NewInput,
    /// Retrying cannot help: fix the configuration or the data product.
    Never,
}

macro_rules! failure_codes {
    ($( $name:ident = $val:literal, $sev:ident, $retry:ident, $label:literal, $doc:literal; )*) => {
        /// A numbered failure. See the module documentation for the grouping.
        #[repr(u16)]
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        pub enum FailureCode {
            $( #[doc = $doc] $name = $val, )*
        }

        impl FailureCode {
            /// Every code, in table order.
            pub const ALL: &'static [FailureCode] = &[$(FailureCode::$name),*];

            /// Severity of this failure.
            pub const fn severity(self) -> Severity {
                match self { $(FailureCode::$name => Severity::$sev,)* }
            }

            /// Retry hint for this failure.
            pub const fn retry(self) -> Retry {
                match self { $(FailureCode::$name => Retry::$retry,)* }
            }

            /// Stable upper-case name used in telemetry and `result.json`.
            pub const fn name(self) -> &'static str {
                match self { $(FailureCode::$name => $label,)* }
            }

            /// One-sentence description: what happened and what happens next.
            pub const fn description(self) -> &'static str {
                match self { $(FailureCode::$name => $doc,)* }
            }

            /// The code for a raw value, if it is one.
            pub const fn from_u16(raw: u16) -> Option<FailureCode> {
                match raw { $($val => Some(FailureCode::$name),)* _ => None }
            }
        }
    };
}

failure_codes! {
    // 0x01xx configuration
    ConfigParamOutOfRange = 0x0101, Fatal, Never, "CONFIG_PARAM_OUT_OF_RANGE",
        "A runtime parameter is outside the range allowed by config; nothing runs until it is fixed.";
    ConfigCapacityTooSmall = 0x0102, Fatal, Never, "CONFIG_CAPACITY_TOO_SMALL",
        "A caller-provided buffer is smaller than the configuration requires; nothing runs.";
    // 0x02xx image
    ImageDimensionsInvalid = 0x0201, Fatal, NewInput, "IMAGE_DIMENSIONS_INVALID",
        "Image width or height is zero or above config::MAX_IMAGE_DIM; the frame is rejected.";
    ImageStrideInvalid = 0x0202, Fatal, NewInput, "IMAGE_STRIDE_INVALID",
        "Image stride is smaller than its width; the frame is rejected.";
    ImageBufferTooShort = 0x0203, Fatal, NewInput, "IMAGE_BUFFER_TOO_SHORT",
        "Image buffer is shorter than (height-1)*stride+width; the frame is rejected.";
    ImageSizeMismatch = 0x0204, Fatal, NewInput, "IMAGE_SIZE_MISMATCH",
        "Image size differs from the camera calibration or from its stereo partner; the frame is rejected.";
    // 0x03xx map product
    MapTruncated = 0x0301, Fatal, NewInput, "MAP_TRUNCATED",
        "The map product is shorter than its header or a section says; it is not used.";
    MapBadMagic = 0x0302, Fatal, NewInput, "MAP_BAD_MAGIC",
        "The map product does not start with the expected magic; it is not used.";
    MapUnsupportedVersion = 0x0303, Fatal, Never, "MAP_UNSUPPORTED_VERSION",
        "The map product's format version is not supported by this build; it is not used.";
    MapCrcMismatch = 0x0304, Fatal, NewInput, "MAP_CRC_MISMATCH",
        "A section of the map product fails its CRC (corruption in storage or transfer); it is not used.";
    MapCountOutOfRange = 0x0305, Fatal, NewInput, "MAP_COUNT_OUT_OF_RANGE",
        "A count in the map header is zero where it must not be or above its config cap; it is not used.";
    MapIndexOutOfRange = 0x0306, Fatal, NewInput, "MAP_INDEX_OUT_OF_RANGE",
        "A triangle or tile refers to a vertex or triangle that does not exist; the map is not used.";
    MapNonFinite = 0x0307, Fatal, NewInput, "MAP_NON_FINITE",
        "A vertex, UV or bound in the map product is NaN or infinite; the map is not used.";
    MapInconsistent = 0x0308, Fatal, NewInput, "MAP_INCONSISTENT",
        "Map sections disagree (tile bounds, texture size, section layout); the map is not used.";
    MapEncodeBufferTooSmall = 0x0309, Fatal, Never, "MAP_ENCODE_BUFFER_TOO_SMALL",
        "The output buffer given to the map encoder is too small; nothing was written past it.";
    MapTileSizeOutOfRange = 0x030A, Fatal, Never, "MAP_TILE_SIZE_OUT_OF_RANGE",
        "The tile size is not a positive finite number, or so small that the tile grid over the map exceeds MAX_MAP_TILES; nothing is encoded.";
    MapNoSurface = 0x030B, Fatal, NewInput, "MAP_NO_SURFACE",
        "Every triangle of the map has zero area, so there is no surface to render; the map is not used.";
    MapUvOutOfRange = 0x030C, Fatal, NewInput, "MAP_UV_OUT_OF_RANGE",
        "A texture coordinate lies beyond map::MAX_UV_PX texture pixels; the map is not used.";
    MapOriginOutOfRange = 0x030D, Fatal, NewInput, "MAP_ORIGIN_OUT_OF_RANGE",
        "The map's origin is not finite or a coordinate exceeds config::MAX_MAP_ORIGIN_M; the map is not used (nothing is encoded).";
    MapBadScores = 0x030E, Fatal, NewInput, "MAP_BAD_SCORES",
        "The map's mask-vertex sampling scores are not a valid running sum (a step above 255, a decrease, or a zero total over the mask vertices); the map is not used (nothing is encoded).";
    // 0x04xx raster
    RasterWindowInvalid = 0x0401, Degraded, Same, "RASTER_WINDOW_INVALID",
        "The render window is empty, larger than the template cap or outside the guard band; nothing is drawn.";
    RasterBufferTooSmall = 0x0402, Fatal, Never, "RASTER_BUFFER_TOO_SMALL",
        "A render target buffer is smaller than the window; nothing is drawn.";
    RasterPoseInvalid = 0x0403, Degraded, Same, "RASTER_POSE_INVALID",
        "The virtual camera pose is not finite; the template is skipped.";
    RasterNothingVisible = 0x0404, Info, Same, "RASTER_NOTHING_VISIBLE",
        "No mesh triangle covers the window; the sample is skipped and another is drawn.";
    // 0x0405 (RASTER_CAMERA_INVALID) is retired: `Camera` is a checked type, so
    // the renderer no longer re-checks it. Numbers are not reused.
    // 0x05xx ncc
    NccTemplateFlat = 0x0501, Info, Same, "NCC_TEMPLATE_FLAT",
        "The template has zero variance under its mask; it cannot be matched and is skipped.";
    NccWindowOutsideImage = 0x0502, Info, Same, "NCC_WINDOW_OUTSIDE_IMAGE",
        "The search window lies outside the image; the sample is skipped.";
    NccTemplateLargerThanWindow = 0x0503, Info, Same, "NCC_TEMPLATE_LARGER_THAN_WINDOW",
        "The template does not fit inside the search window; the sample is skipped.";
    NccWindowFlat = 0x0504, Info, Same, "NCC_WINDOW_FLAT",
        "Every candidate position of the window has zero variance; no match is reported.";
    NccScratchTooSmall = 0x0505, Fatal, Never, "NCC_SCRATCH_TOO_SMALL",
        "The NCC scratch buffers are smaller than the template or window needs; nothing is matched.";
    NccMaskEmpty = 0x0506, Info, Same, "NCC_MASK_EMPTY",
        "The template mask keeps too few pixels to correlate; the sample is skipped.";
    NccLowScore = 0x0507, Info, Same, "NCC_LOW_SCORE",
        "The best score is below the acceptance threshold; the match is rejected.";
    NccAmbiguous = 0x0508, Info, Same, "NCC_AMBIGUOUS",
        "The runner-up peak scores too close to the best one; the match is rejected as ambiguous.";
    NccWindowTooLarge = 0x0509, Fatal, Never, "NCC_WINDOW_TOO_LARGE",
        "The search window is larger than config::MAX_SEARCH_PX; nothing is matched.";
    NccTemplateSizeInvalid = 0x050A, Fatal, Never, "NCC_TEMPLATE_SIZE_INVALID",
        "The template side is outside MIN_TEMPLATE_PX..=MAX_TEMPLATE_PX or its mask differs in size; nothing is matched.";
    // 0x06xx stereo
    StereoEpipolarViolation = 0x0601, Info, Same, "STEREO_EPIPOLAR_VIOLATION",
        "Left and right peaks differ by more than epsilon rows; the pair is rejected (Valid).";
    StereoDisparityInvalid = 0x0602, Info, Same, "STEREO_DISPARITY_INVALID",
        "Disparity is non-positive or below the plausible minimum; the pair is rejected.";
    StereoRigInvalid = 0x0603, Fatal, Never, "STEREO_RIG_INVALID",
        "Camera intrinsics or baseline are non-finite or non-positive; nothing is triangulated.";
    StereoPixelNonFinite = 0x0604, Info, Same, "STEREO_PIXEL_NON_FINITE",
        "A left or right peak coordinate is NaN or infinite; the pair is rejected.";
    // 0x07xx pose
    PoseTooFewPoints = 0x0701, Degraded, Same, "POSE_TOO_FEW_POINTS",
        "Fewer than three correspondences; no transform can be estimated.";
    PoseDegenerate = 0x0702, Degraded, Same, "POSE_DEGENERATE",
        "Points are coincident or collinear; the rigid transform is not determined.";
    PoseRansacNoConsensus = 0x0703, Degraded, Same, "POSE_RANSAC_NO_CONSENSUS",
        "RANSAC found no hypothesis with enough inliers within its iteration cap.";
    PoseNonFinite = 0x0704, Degraded, NewInput, "POSE_NON_FINITE",
        "An input point or an estimated pose is not finite; it is discarded.";
    // 0x08xx reloc
    RelocStallCapReached = 0x0801, Fatal, NewInput, "RELOC_STALL_CAP_REACHED",
        "Consecutive Stall attempts reached their cap without a pose update; relocalization failed.";
    RelocReseedCapReached = 0x0802, Fatal, NewInput, "RELOC_RESEED_CAP_REACHED",
        "Consecutive Reseed attempts reached their cap without a pose update; relocalization failed.";
    RelocBudgetExhausted = 0x0803, Degraded, NewInput, "RELOC_BUDGET_EXHAUSTED",
        "The work or tick budget ran out; the best pose so far is returned with its quality.";
    RelocPriorInvalid = 0x0804, Fatal, NewInput, "RELOC_PRIOR_INVALID",
        "The prior pose is not finite or its quaternion is not unit; nothing runs.";
    RelocSampleCapReached = 0x0805, Degraded, Same, "RELOC_SAMPLE_CAP_REACHED",
        "The per-iteration attempt cap was reached before N_corr correspondences; the iteration fails.";
    RelocNoVisibleMaskVertex = 0x0806, Fatal, NewInput, "RELOC_NO_VISIBLE_MASK_VERTEX",
        "No vertex of the sampling mask is in view from the prior; relocalization cannot start.";
    // 0x0807 (RELOC_NOT_STARTED) is retired: no path raised it. Numbers are not reused.
    RelocSampleOutOfView = 0x0808, Info, Same, "RELOC_SAMPLE_OUT_OF_VIEW",
        "No drawn mask vertex projected inside both images from the viewpoint; the attempt is skipped.";
    RelocSampleOccluded = 0x0809, Info, Same, "RELOC_SAMPLE_OCCLUDED",
        "The sampled vertex is hidden behind other surface in the virtual view; the attempt is skipped.";
    RelocFrameNoTexture = 0x080A, Fatal, NewInput, "RELOC_FRAME_NO_TEXTURE",
        "A stereo image is black, saturated or flat on almost every sampled pixel, so nothing can be matched; relocalization does not start.";
    RelocStereoIdentical = 0x080B, Fatal, NewInput, "RELOC_STEREO_IDENTICAL",
        "The left and right images are identical on every sampled row (one sensor delivered twice); relocalization does not start.";
    RelocNoEvidence = 0x080C, Fatal, NewInput, "RELOC_NO_EVIDENCE",
        "No correspondence was accepted in the first Options::no_evidence_attempts attempts; the frame does not show the map here, and the run stops early.";
    RelocPoseOutsidePrior = 0x080D, Fatal, NewInput, "RELOC_POSE_OUTSIDE_PRIOR",
        "The final estimate lies farther from the prior than Options::gates.prior_factor times the prior's uncertainty, in translation or rotation; the pose is not trusted and the relocalization fails.";
    RelocInliersDegenerate = 0x080E, Fatal, NewInput, "RELOC_INLIERS_DEGENERATE",
        "The final inliers' camera points span less than Options::gates.min_spread_m across their principal direction (one cluster or one line), so they do not fix the pose; the relocalization fails.";
    RelocResidualHigh = 0x080F, Fatal, NewInput, "RELOC_RESIDUAL_HIGH",
        "The RMS reprojection residual of the final inliers exceeds Options::gates.max_reproj_px, more than the matcher's noise explains; the pose is not trusted and the relocalization fails.";
    RelocVerifyDisagree = 0x0810, Fatal, Same, "RELOC_VERIFY_DISAGREE",
        "The repeated final solve (Options::verify.repeat_solve) found no solution or one farther from the final estimate than its tolerance: one computation was upset; the pose is not trusted, run again.";
    RelocMapChanged = 0x0811, Fatal, NewInput, "RELOC_MAP_CHANGED",
        "The map product failed its re-check before the result was returned (Options::verify.recheck_map) although it passed at load: it changed in memory; the pose is not trusted, reload the map.";
    RelocNoConsensus = 0x0812, Fatal, NewInput, "RELOC_NO_CONSENSUS",
        "The first Options::first_fix_rounds rounds from the prior all ended without a consensus of Options::min_inliers (no pose update yet); the frames do not show the map as seen from near the prior, and the run stops early.";
    RelocFrameReadFailed = 0x0813, Fatal, NewInput, "RELOC_FRAME_READ_FAILED",
        "A search window or a preflight row could not be read from the frame source (the frame store failed after its retries, or refused the range); the relocalization ends with this code at once, capture a new pair.";
    // 0x09xx hardware
    HalCameraTimeout = 0x0901, Degraded, Same, "HAL_CAMERA_TIMEOUT",
        "The stereo camera did not deliver a frame within its timeout; capture again.";
    HalCameraFrameTruncated = 0x0902, Degraded, Same, "HAL_CAMERA_FRAME_TRUNCATED",
        "The camera delivered fewer bytes than a full frame; the frame is discarded.";
    HalStorageRead = 0x0903, Degraded, Same, "HAL_STORAGE_READ",
        "Map storage failed to read a range; read again.";
    HalTelemetryWrite = 0x0904, Info, Same, "HAL_TELEMETRY_WRITE",
        "A telemetry frame could not be written; it is counted as dropped.";
    HalPriorUnavailable = 0x0905, Degraded, Same, "HAL_PRIOR_UNAVAILABLE",
        "The pose prior source had no valid estimate; ask again.";
    HalCameraFault = 0x0906, Degraded, Same, "HAL_CAMERA_FAULT",
        "The stereo camera reported corrupted data or a device fault; the frame is discarded.";
    HalCameraRetriesExhausted = 0x0907, Fatal, NewInput, "HAL_CAMERA_RETRIES_EXHAUSTED",
        "Every capture attempt allowed by the runner failed; no frame is available for this run.";
    HalStorageRetriesExhausted = 0x0908, Fatal, NewInput, "HAL_STORAGE_RETRIES_EXHAUSTED",
        "Every read attempt of the map product allowed by the runner failed; the map is not used.";
    HalMapTooLarge = 0x0909, Fatal, Never, "HAL_MAP_TOO_LARGE",
        "The stored map product is empty or longer than the buffer given to the runner; nothing is read.";
    HalFrameInfoInvalid = 0x090A, Fatal, NewInput, "HAL_FRAME_INFO_INVALID",
        "The camera's frame info disagrees with the buffers or the expected size; the frame is rejected.";
    HalTelemetryPayloadTooLong = 0x090B, Info, Never, "HAL_TELEMETRY_PAYLOAD_TOO_LONG",
        "A telemetry payload is longer than the frame format allows; nothing is written.";
    HalClockFault = 0x090C, Degraded, Same, "HAL_CLOCK_FAULT",
        "The clock could not be read or went backwards; the step is not timed.";
    HalPriorInvalid = 0x090D, Degraded, NewInput, "HAL_PRIOR_INVALID",
        "The pose prior has a non-finite pose, a covariance that is not symmetric non-negative, or stated half-widths (t̃₀, r̃₀) outside the engine's ranges; it is rejected.";
    HalFrameStoreRead = 0x090E, Degraded, Same, "HAL_FRAME_STORE_READ",
        "The frame store failed to read a window of the stereo pair (timeout, short read, detected corruption or device fault); the runner reads it again within its retry cap.";
    // 0x0Axx C interface (vtsm-ffi)
    FfiNullPointer = 0x0A01, Fatal, Never, "FFI_NULL_POINTER",
        "A pointer given to the C interface is null where an object or a callback is required; nothing is done.";
    FfiMisaligned = 0x0A02, Fatal, Never, "FFI_MISALIGNED",
        "A buffer given to the C interface is not aligned as its contents require (engine storage: VTSM_STORAGE_ALIGN); nothing is done.";
    FfiBadHandle = 0x0A03, Fatal, Never, "FFI_BAD_HANDLE",
        "The engine handle does not point at storage set up by vtsm_engine_create (never created, released, or overwritten since); nothing is done.";
    FfiEngineState = 0x0A04, Fatal, Never, "FFI_ENGINE_STATE",
        "vtsm_engine_step or vtsm_engine_outcome on an engine with no relocalization under way (not started, or its outcome already taken), or vtsm_engine_start on one that has one; nothing is done.";
}

impl FailureCode {
    /// Raw numeric value of the code.
    pub const fn code(self) -> u16 {
        self as u16
    }

    /// Subsystem group (the high byte).
    pub const fn group(self) -> u8 {
        (self.code() >> 8) as u8
    }
}

/// One recorded failure event.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Event {
    /// What failed.
    pub code: FailureCode,
    /// Caller-supplied time of the event (ticks of the caller's clock).
    pub tick: u64,
    /// Free-form detail (an index, a count), code-specific.
    pub detail: u32,
}

/// Saturating per-code counters and a ring of the last events.
#[derive(Clone, Debug)]
pub struct FailureLog {
    counts: [u16; FailureCode::ALL.len()],
    ring: [Option<Event>; FAILURE_RING_LEN],
    next: usize,
    total: u32,
}

impl Default for FailureLog {
    fn default() -> Self {
        Self::new()
    }
}

impl FailureLog {
    /// An empty log.
    pub const fn new() -> Self {
        Self {
            counts: [0; FailureCode::ALL.len()],
            ring: [None; FAILURE_RING_LEN],
            next: 0,
            total: 0,
        }
    }

    fn index_of(code: FailureCode) -> Option<usize> {
        FailureCode::ALL.iter().position(|c| *c == code)
    }

    /// Record one event: bump the code's counter (saturating) and push into the ring.
    pub fn record(&mut self, code: FailureCode, tick: u64, detail: u32) {
        if let Some(c) = Self::index_of(code).and_then(|i| self.counts.get_mut(i)) {
            *c = c.saturating_add(1);
        }
        if let Some(slot) = self.ring.get_mut(self.next) {
            *slot = Some(Event { code, tick, detail });
        }
        // next < FAILURE_RING_LEN, so the increment cannot wrap.
        self.next = self.next.wrapping_add(1) % FAILURE_RING_LEN;
        self.total = self.total.saturating_add(1);
    }

    /// How many times `code` was recorded (saturates at `u16::MAX`).
    pub fn count(&self, code: FailureCode) -> u16 {
        Self::index_of(code)
            .and_then(|i| self.counts.get(i))
            .copied()
            .unwrap_or(0)
    }

    /// Total events recorded (saturating).
    pub fn total(&self) -> u32 {
        self.total
    }

    /// The ring's events, oldest first.
    pub fn recent(&self) -> impl Iterator<Item = Event> + '_ {
        let (newer, older) = self.ring.split_at(self.next.min(FAILURE_RING_LEN));
        older.iter().chain(newer.iter()).filter_map(|e| *e)
    }

    /// Non-zero counters as `(code, count)`, in table order.
    pub fn counters(&self) -> impl Iterator<Item = (FailureCode, u16)> + '_ {
        FailureCode::ALL
            .iter()
            .zip(self.counts.iter())
            .filter(|(_, n)| **n > 0)
            .map(|(c, n)| (*c, *n))
    }

    /// Add `other`'s counters to this log's (saturating) and record its
    /// ring's events after this log's, oldest first. Bounded: O(codes + ring).
    pub fn absorb(&mut self, other: &FailureLog) {
        for (c, n) in self.counts.iter_mut().zip(other.counts.iter()) {
            *c = c.saturating_add(*n);
        }
        self.total = self.total.saturating_add(other.total);
        for e in other.recent() {
            if let Some(slot) = self.ring.get_mut(self.next) {
                *slot = Some(e);
            }
            self.next = self.next.wrapping_add(1) % FAILURE_RING_LEN;
        }
    }

    /// Forget everything.
    pub fn clear(&mut self) {
        *self = Self::new();
    }
}

/// Every out-of-range parameter is one code: the field is in the
/// [`ParamError`], the code says only that nothing runs until it is fixed.
impl From<ParamError> for FailureCode {
    fn from(_: ParamError) -> Self {
        FailureCode::ConfigParamOutOfRange
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Verifies: VTSM-FAIL-001
    #[test]
    fn codes_are_unique_nonzero_and_grouped() {
        for (i, a) in FailureCode::ALL.iter().enumerate() {
            assert_ne!(a.code(), 0);
            assert!((1..=0x0A).contains(&a.group()), "{a:?}");
            assert_eq!(FailureCode::from_u16(a.code()), Some(*a));
            for b in &FailureCode::ALL[i + 1..] {
                assert_ne!(a.code(), b.code());
                assert_ne!(a.name(), b.name());
            }
        }
        assert_eq!(FailureCode::from_u16(0), None);
    }

    /// Verifies: VTSM-FAIL-003
    #[test]
    fn counters_saturate_and_ring_keeps_last_events() {
        let mut log = FailureLog::new();
        for i in 0..70_000u32 {
            log.record(FailureCode::NccLowScore, u64::from(i), i);
        }
        assert_eq!(log.count(FailureCode::NccLowScore), u16::MAX);
        assert_eq!(log.count(FailureCode::MapTruncated), 0);
        let recent: heapless::Vec<Event, FAILURE_RING_LEN> = log.recent().collect();
        assert_eq!(recent.len(), FAILURE_RING_LEN);
        assert_eq!(recent.last().unwrap().detail, 69_999);
        assert_eq!(
            recent.first().unwrap().detail,
            70_000 - FAILURE_RING_LEN as u32
        );
        assert_eq!(log.total(), 70_000);

        let mut a = FailureLog::new();
        a.record(FailureCode::MapTruncated, 1, 1);
        let mut b = FailureLog::new();
        b.record(FailureCode::HalFrameStoreRead, 2, 2);
        b.record(FailureCode::MapTruncated, 3, 3);
        a.absorb(&b);
        assert_eq!(a.count(FailureCode::MapTruncated), 2);
        assert_eq!(a.count(FailureCode::HalFrameStoreRead), 1);
        assert_eq!(a.total(), 3);
        let ticks: heapless::Vec<u64, 4> = a.recent().map(|e| e.tick).collect();
        assert_eq!(ticks.as_slice(), &[1, 2, 3]);
    }
}
