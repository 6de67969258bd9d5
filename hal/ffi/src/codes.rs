// Generated from `vtsm_core::FailureCode::ALL` by
// `VTSM_FFI_BLESS=1 cargo test -p vtsm-ffi -- codes_rs`; do not edit by hand.
// The test `codes_rs_is_generated_from_the_core_table` checks it.

use core::ffi::CStr;

/// The failure codes (the core's `FailureCode` table, and 0 for none):
/// `#[repr(u16)]`, grouped by subsystem in the high byte (0x01 config,
/// 0x02 image, 0x03 map, 0x04 raster, 0x05 ncc, 0x06 stereo, 0x07 pose,
/// 0x08 reloc, 0x09 hardware, 0x0A C interface). Every function of the
/// interface that can fail returns one as a `uint16_t`;
/// `vtsm_failure_name` gives its name. Severity, retry hint and the
/// list are in `fsw-docs/failure-codes.md`.
#[repr(u16)]
#[allow(non_camel_case_types)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VtsmFailure {
    /// No failure.
    VTSM_OK = 0,
    /// A runtime parameter is outside the range allowed by config; nothing runs until it is fixed.
    VTSM_CONFIG_PARAM_OUT_OF_RANGE = 0x0101,
    /// A caller-provided buffer is smaller than the configuration requires; nothing runs.
    VTSM_CONFIG_CAPACITY_TOO_SMALL = 0x0102,
    /// Image width or height is zero or above config::MAX_IMAGE_DIM; the frame is rejected.
    VTSM_IMAGE_DIMENSIONS_INVALID = 0x0201,
    /// Image stride is smaller than its width; the frame is rejected.
    VTSM_IMAGE_STRIDE_INVALID = 0x0202,
    /// Image buffer is shorter than (height-1)*stride+width; the frame is rejected.
    VTSM_IMAGE_BUFFER_TOO_SHORT = 0x0203,
    /// Image size differs from the camera calibration or from its stereo partner; the frame is rejected.
    VTSM_IMAGE_SIZE_MISMATCH = 0x0204,
    /// The map product is shorter than its header or a section says; it is not used.
    VTSM_MAP_TRUNCATED = 0x0301,
    /// The map product does not start with the expected magic; it is not used.
    VTSM_MAP_BAD_MAGIC = 0x0302,
    /// The map product's format version is not supported by this build; it is not used.
    VTSM_MAP_UNSUPPORTED_VERSION = 0x0303,
    /// A section of the map product fails its CRC (corruption in storage or transfer); it is not used.
    VTSM_MAP_CRC_MISMATCH = 0x0304,
    /// A count in the map header is zero where it must not be or above its config cap; it is not used.
    VTSM_MAP_COUNT_OUT_OF_RANGE = 0x0305,
    /// A triangle or tile refers to a vertex or triangle that does not exist; the map is not used.
    VTSM_MAP_INDEX_OUT_OF_RANGE = 0x0306,
    /// A vertex, UV or bound in the map product is NaN or infinite; the map is not used.
    VTSM_MAP_NON_FINITE = 0x0307,
    /// Map sections disagree (tile bounds, texture size, section layout); the map is not used.
    VTSM_MAP_INCONSISTENT = 0x0308,
    /// The output buffer given to the map encoder is too small; nothing was written past it.
    VTSM_MAP_ENCODE_BUFFER_TOO_SMALL = 0x0309,
    /// The tile size is not a positive finite number, or so small that the tile grid over the map exceeds MAX_MAP_TILES; nothing is encoded.
    VTSM_MAP_TILE_SIZE_OUT_OF_RANGE = 0x030A,
    /// Every triangle of the map has zero area, so there is no surface to render; the map is not used.
    VTSM_MAP_NO_SURFACE = 0x030B,
    /// A texture coordinate lies beyond map::MAX_UV_PX texture pixels; the map is not used.
    VTSM_MAP_UV_OUT_OF_RANGE = 0x030C,
    /// The map's origin is not finite or a coordinate exceeds config::MAX_MAP_ORIGIN_M; the map is not used (nothing is encoded).
    VTSM_MAP_ORIGIN_OUT_OF_RANGE = 0x030D,
    /// The map's mask-vertex sampling scores are not a valid running sum (a step above 255, a decrease, or a zero total over the mask vertices); the map is not used (nothing is encoded).
    VTSM_MAP_BAD_SCORES = 0x030E,
    /// The render window is empty, larger than the template cap or outside the guard band; nothing is drawn.
    VTSM_RASTER_WINDOW_INVALID = 0x0401,
    /// A render target buffer is smaller than the window; nothing is drawn.
    VTSM_RASTER_BUFFER_TOO_SMALL = 0x0402,
    /// The virtual camera pose is not finite; the template is skipped.
    VTSM_RASTER_POSE_INVALID = 0x0403,
    /// No mesh triangle covers the window; the sample is skipped and another is drawn.
    VTSM_RASTER_NOTHING_VISIBLE = 0x0404,
    /// The template has zero variance under its mask; it cannot be matched and is skipped.
    VTSM_NCC_TEMPLATE_FLAT = 0x0501,
    /// The search window lies outside the image; the sample is skipped.
    VTSM_NCC_WINDOW_OUTSIDE_IMAGE = 0x0502,
    /// The template does not fit inside the search window; the sample is skipped.
    VTSM_NCC_TEMPLATE_LARGER_THAN_WINDOW = 0x0503,
    /// Every candidate position of the window has zero variance; no match is reported.
    VTSM_NCC_WINDOW_FLAT = 0x0504,
    /// The NCC scratch buffers are smaller than the template or window needs; nothing is matched.
    VTSM_NCC_SCRATCH_TOO_SMALL = 0x0505,
    /// The template mask keeps too few pixels to correlate; the sample is skipped.
    VTSM_NCC_MASK_EMPTY = 0x0506,
    /// The best score is below the acceptance threshold; the match is rejected.
    VTSM_NCC_LOW_SCORE = 0x0507,
    /// The runner-up peak scores too close to the best one; the match is rejected as ambiguous.
    VTSM_NCC_AMBIGUOUS = 0x0508,
    /// The search window is larger than config::MAX_SEARCH_PX; nothing is matched.
    VTSM_NCC_WINDOW_TOO_LARGE = 0x0509,
    /// The template side is outside MIN_TEMPLATE_PX..=MAX_TEMPLATE_PX or its mask differs in size; nothing is matched.
    VTSM_NCC_TEMPLATE_SIZE_INVALID = 0x050A,
    /// Left and right peaks differ by more than epsilon rows; the pair is rejected (Valid).
    VTSM_STEREO_EPIPOLAR_VIOLATION = 0x0601,
    /// Disparity is non-positive or below the plausible minimum; the pair is rejected.
    VTSM_STEREO_DISPARITY_INVALID = 0x0602,
    /// Camera intrinsics or baseline are non-finite or non-positive; nothing is triangulated.
    VTSM_STEREO_RIG_INVALID = 0x0603,
    /// A left or right peak coordinate is NaN or infinite; the pair is rejected.
    VTSM_STEREO_PIXEL_NON_FINITE = 0x0604,
    /// Fewer than three correspondences; no transform can be estimated.
    VTSM_POSE_TOO_FEW_POINTS = 0x0701,
    /// Points are coincident or collinear; the rigid transform is not determined.
    VTSM_POSE_DEGENERATE = 0x0702,
    /// RANSAC found no hypothesis with enough inliers within its iteration cap.
    VTSM_POSE_RANSAC_NO_CONSENSUS = 0x0703,
    /// An input point or an estimated pose is not finite; it is discarded.
    VTSM_POSE_NON_FINITE = 0x0704,
    /// Consecutive Stall attempts reached their cap without a pose update; relocalization failed.
    VTSM_RELOC_STALL_CAP_REACHED = 0x0801,
    /// Consecutive Reseed attempts reached their cap without a pose update; relocalization failed.
    VTSM_RELOC_RESEED_CAP_REACHED = 0x0802,
    /// The work or tick budget ran out; the best pose so far is returned with its quality.
    VTSM_RELOC_BUDGET_EXHAUSTED = 0x0803,
    /// The prior pose is not finite or its quaternion is not unit; nothing runs.
    VTSM_RELOC_PRIOR_INVALID = 0x0804,
    /// The per-iteration attempt cap was reached before N_corr correspondences; the iteration fails.
    VTSM_RELOC_SAMPLE_CAP_REACHED = 0x0805,
    /// No vertex of the sampling mask is in view from the prior; relocalization cannot start.
    VTSM_RELOC_NO_VISIBLE_MASK_VERTEX = 0x0806,
    /// No drawn mask vertex projected inside both images from the viewpoint; the attempt is skipped.
    VTSM_RELOC_SAMPLE_OUT_OF_VIEW = 0x0808,
    /// The sampled vertex is hidden behind other surface in the virtual view; the attempt is skipped.
    VTSM_RELOC_SAMPLE_OCCLUDED = 0x0809,
    /// A stereo image is black, saturated or flat on almost every sampled pixel, so nothing can be matched; relocalization does not start.
    VTSM_RELOC_FRAME_NO_TEXTURE = 0x080A,
    /// The left and right images are identical on every sampled row (one sensor delivered twice); relocalization does not start.
    VTSM_RELOC_STEREO_IDENTICAL = 0x080B,
    /// No correspondence was accepted in the first Options::no_evidence_attempts attempts; the frame does not show the map here, and the run stops early.
    VTSM_RELOC_NO_EVIDENCE = 0x080C,
    /// The final estimate lies farther from the prior than Options::gates.prior_factor times the prior's uncertainty, in translation or rotation; the pose is not trusted and the relocalization fails.
    VTSM_RELOC_POSE_OUTSIDE_PRIOR = 0x080D,
    /// The final inliers' camera points span less than Options::gates.min_spread_m across their principal direction (one cluster or one line), so they do not fix the pose; the relocalization fails.
    VTSM_RELOC_INLIERS_DEGENERATE = 0x080E,
    /// The RMS reprojection residual of the final inliers exceeds Options::gates.max_reproj_px, more than the matcher's noise explains; the pose is not trusted and the relocalization fails.
    VTSM_RELOC_RESIDUAL_HIGH = 0x080F,
    /// The repeated final solve (Options::verify.repeat_solve) found no solution or one farther from the final estimate than its tolerance: one computation was upset; the pose is not trusted, run again.
    VTSM_RELOC_VERIFY_DISAGREE = 0x0810,
    /// The map product failed its re-check before the result was returned (Options::verify.recheck_map) although it passed at load: it changed in memory; the pose is not trusted, reload the map.
    VTSM_RELOC_MAP_CHANGED = 0x0811,
    /// The first Options::first_fix_rounds rounds from the prior all ended without a consensus of Options::min_inliers (no pose update yet); the frames do not show the map as seen from near the prior, and the run stops early.
    VTSM_RELOC_NO_CONSENSUS = 0x0812,
    /// A search window or a preflight row could not be read from the frame source (the frame store failed after its retries, or refused the range); the relocalization ends with this code at once, capture a new pair.
    VTSM_RELOC_FRAME_READ_FAILED = 0x0813,
    /// The stereo camera did not deliver a frame within its timeout; capture again.
    VTSM_HAL_CAMERA_TIMEOUT = 0x0901,
    /// The camera delivered fewer bytes than a full frame; the frame is discarded.
    VTSM_HAL_CAMERA_FRAME_TRUNCATED = 0x0902,
    /// Map storage failed to read a range; read again.
    VTSM_HAL_STORAGE_READ = 0x0903,
    /// A telemetry frame could not be written; it is counted as dropped.
    VTSM_HAL_TELEMETRY_WRITE = 0x0904,
    /// The pose prior source had no valid estimate; ask again.
    VTSM_HAL_PRIOR_UNAVAILABLE = 0x0905,
    /// The stereo camera reported corrupted data or a device fault; the frame is discarded.
    VTSM_HAL_CAMERA_FAULT = 0x0906,
    /// Every capture attempt allowed by the runner failed; no frame is available for this run.
    VTSM_HAL_CAMERA_RETRIES_EXHAUSTED = 0x0907,
    /// Every read attempt of the map product allowed by the runner failed; the map is not used.
    VTSM_HAL_STORAGE_RETRIES_EXHAUSTED = 0x0908,
    /// The stored map product is empty or longer than the buffer given to the runner; nothing is read.
    VTSM_HAL_MAP_TOO_LARGE = 0x0909,
    /// The camera's frame info disagrees with the buffers or the expected size; the frame is rejected.
    VTSM_HAL_FRAME_INFO_INVALID = 0x090A,
    /// A telemetry payload is longer than the frame format allows; nothing is written.
    VTSM_HAL_TELEMETRY_PAYLOAD_TOO_LONG = 0x090B,
    /// The clock could not be read or went backwards; the step is not timed.
    VTSM_HAL_CLOCK_FAULT = 0x090C,
    /// The pose prior has a non-finite pose, a covariance that is not symmetric non-negative, or stated half-widths (t̃₀, r̃₀) outside the engine's ranges; it is rejected.
    VTSM_HAL_PRIOR_INVALID = 0x090D,
    /// The frame store failed to read a window of the stereo pair (timeout, short read, detected corruption or device fault); the runner reads it again within its retry cap.
    VTSM_HAL_FRAME_STORE_READ = 0x090E,
    /// A pointer given to the C interface is null where an object or a callback is required; nothing is done.
    VTSM_FFI_NULL_POINTER = 0x0A01,
    /// A buffer given to the C interface is not aligned as its contents require (engine storage: VTSM_STORAGE_ALIGN); nothing is done.
    VTSM_FFI_MISALIGNED = 0x0A02,
    /// The engine handle does not point at storage set up by vtsm_engine_create (never created, released, or overwritten since); nothing is done.
    VTSM_FFI_BAD_HANDLE = 0x0A03,
    /// vtsm_engine_step or vtsm_engine_outcome on an engine with no relocalization under way (not started, or its outcome already taken), or vtsm_engine_start on one that has one; nothing is done.
    VTSM_FFI_ENGINE_STATE = 0x0A04,
}

/// The NUL-terminated name of a raw code.
pub(crate) fn c_name(code: u16) -> &'static CStr {
    match code {
        0 => c"OK",
        0x0101 => c"CONFIG_PARAM_OUT_OF_RANGE",
        0x0102 => c"CONFIG_CAPACITY_TOO_SMALL",
        0x0201 => c"IMAGE_DIMENSIONS_INVALID",
        0x0202 => c"IMAGE_STRIDE_INVALID",
        0x0203 => c"IMAGE_BUFFER_TOO_SHORT",
        0x0204 => c"IMAGE_SIZE_MISMATCH",
        0x0301 => c"MAP_TRUNCATED",
        0x0302 => c"MAP_BAD_MAGIC",
        0x0303 => c"MAP_UNSUPPORTED_VERSION",
        0x0304 => c"MAP_CRC_MISMATCH",
        0x0305 => c"MAP_COUNT_OUT_OF_RANGE",
        0x0306 => c"MAP_INDEX_OUT_OF_RANGE",
        0x0307 => c"MAP_NON_FINITE",
        0x0308 => c"MAP_INCONSISTENT",
        0x0309 => c"MAP_ENCODE_BUFFER_TOO_SMALL",
        0x030A => c"MAP_TILE_SIZE_OUT_OF_RANGE",
        0x030B => c"MAP_NO_SURFACE",
        0x030C => c"MAP_UV_OUT_OF_RANGE",
        0x030D => c"MAP_ORIGIN_OUT_OF_RANGE",
        0x030E => c"MAP_BAD_SCORES",
        0x0401 => c"RASTER_WINDOW_INVALID",
        0x0402 => c"RASTER_BUFFER_TOO_SMALL",
        0x0403 => c"RASTER_POSE_INVALID",
        0x0404 => c"RASTER_NOTHING_VISIBLE",
        0x0501 => c"NCC_TEMPLATE_FLAT",
        0x0502 => c"NCC_WINDOW_OUTSIDE_IMAGE",
        0x0503 => c"NCC_TEMPLATE_LARGER_THAN_WINDOW",
        0x0504 => c"NCC_WINDOW_FLAT",
        0x0505 => c"NCC_SCRATCH_TOO_SMALL",
        0x0506 => c"NCC_MASK_EMPTY",
        0x0507 => c"NCC_LOW_SCORE",
        0x0508 => c"NCC_AMBIGUOUS",
        0x0509 => c"NCC_WINDOW_TOO_LARGE",
        0x050A => c"NCC_TEMPLATE_SIZE_INVALID",
        0x0601 => c"STEREO_EPIPOLAR_VIOLATION",
        0x0602 => c"STEREO_DISPARITY_INVALID",
        0x0603 => c"STEREO_RIG_INVALID",
        0x0604 => c"STEREO_PIXEL_NON_FINITE",
        0x0701 => c"POSE_TOO_FEW_POINTS",
        0x0702 => c"POSE_DEGENERATE",
        0x0703 => c"POSE_RANSAC_NO_CONSENSUS",
        0x0704 => c"POSE_NON_FINITE",
        0x0801 => c"RELOC_STALL_CAP_REACHED",
        0x0802 => c"RELOC_RESEED_CAP_REACHED",
        0x0803 => c"RELOC_BUDGET_EXHAUSTED",
        0x0804 => c"RELOC_PRIOR_INVALID",
        0x0805 => c"RELOC_SAMPLE_CAP_REACHED",
        0x0806 => c"RELOC_NO_VISIBLE_MASK_VERTEX",
        0x0808 => c"RELOC_SAMPLE_OUT_OF_VIEW",
        0x0809 => c"RELOC_SAMPLE_OCCLUDED",
        0x080A => c"RELOC_FRAME_NO_TEXTURE",
        0x080B => c"RELOC_STEREO_IDENTICAL",
        0x080C => c"RELOC_NO_EVIDENCE",
        0x080D => c"RELOC_POSE_OUTSIDE_PRIOR",
        0x080E => c"RELOC_INLIERS_DEGENERATE",
        0x080F => c"RELOC_RESIDUAL_HIGH",
        0x0810 => c"RELOC_VERIFY_DISAGREE",
        0x0811 => c"RELOC_MAP_CHANGED",
        0x0812 => c"RELOC_NO_CONSENSUS",
        0x0813 => c"RELOC_FRAME_READ_FAILED",
        0x0901 => c"HAL_CAMERA_TIMEOUT",
        0x0902 => c"HAL_CAMERA_FRAME_TRUNCATED",
        0x0903 => c"HAL_STORAGE_READ",
        0x0904 => c"HAL_TELEMETRY_WRITE",
        0x0905 => c"HAL_PRIOR_UNAVAILABLE",
        0x0906 => c"HAL_CAMERA_FAULT",
        0x0907 => c"HAL_CAMERA_RETRIES_EXHAUSTED",
        0x0908 => c"HAL_STORAGE_RETRIES_EXHAUSTED",
        0x0909 => c"HAL_MAP_TOO_LARGE",
        0x090A => c"HAL_FRAME_INFO_INVALID",
        0x090B => c"HAL_TELEMETRY_PAYLOAD_TOO_LONG",
        0x090C => c"HAL_CLOCK_FAULT",
        0x090D => c"HAL_PRIOR_INVALID",
        0x090E => c"HAL_FRAME_STORE_READ",
        0x0A01 => c"FFI_NULL_POINTER",
        0x0A02 => c"FFI_MISALIGNED",
        0x0A03 => c"FFI_BAD_HANDLE",
        0x0A04 => c"FFI_ENGINE_STATE",
        _ => c"UNKNOWN",
    }
}
