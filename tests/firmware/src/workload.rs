// Determinism workload shared by the firmware images (Cortex-M7, RISC-V 64 and
// AArch64 under QEMU) and the host test `tests/tests/integration/cross_target.rs` (via
// `include!`). It exercises the core's floating-point and integer paths and folds
// every output, bit for bit, into one FNV-1a digest: equal digests mean
// bit-identical results on every target.

/// FNV-1a over 64 bits.
pub struct Digest(pub u64);

impl Digest {
    /// Empty digest.
    pub const fn new() -> Self {
        Digest(0xcbf2_9ce4_8422_2325)
    }

    /// Fold bytes.
    pub fn bytes(&mut self, b: &[u8]) {
        for &x in b {
            self.0 ^= u64::from(x);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    /// Fold an f32 by its bits.
    pub fn f32(&mut self, v: f32) {
        self.bytes(&v.to_bits().to_le_bytes());
    }

    /// Fold a u64.
    pub fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }
}

/// Fold an outcome, bit for bit: pose, residual, inliers, work counters,
/// failure code. The flight-profile run and its host reference use it too.
pub fn fold_outcome(d: &mut Digest, out: &vtsm_core::reloc::Outcome) {
    for v in out.pose.t().into_iter().chain(out.pose.q()) {
        d.f32(v);
    }
    d.f32(out.quality.rms_m);
    d.u64(u64::from(out.quality.inliers));
    d.u64(u64::from(out.stats.attempts));
    d.u64(u64::from(out.stats.ransac_iterations));
    d.u64(out.stats.pipeline.ncc_macs);
    d.u64(u64::from(out.failure.map_or(0, |c| c.code())));
}

/// Run the workload and return the digest.
pub fn workload() -> u64 {
    let mut d = Digest::new();
    base_block(&mut d);
    let summary = reloc_block(&mut d, &|| 0);
    d.u64(u64::from(summary.final_error_um));
    d.0
}

/// Summary of the relocalization part of the workload.
pub struct Summary {
    /// Whether the engine reported success.
    pub success: bool,
    /// Failure code value (0 when none).
    pub failure: u16,
    /// Final translation error against the truth, micrometres.
    pub final_error_um: u32,
    /// Initial translation error, micrometres.
    pub initial_error_um: u32,
    /// Correspondence attempts.
    pub attempts: u32,
    /// Clock ticks from the runner's first engine step to its last.
    pub engine_ticks: u64,
    /// Engine step calls made by the runner.
    pub steps: u32,
    /// Telemetry frames the runner sent.
    pub telemetry_frames: u32,
    /// Telemetry payload bytes the runner sent.
    pub telemetry_bytes: u32,
}

/// Run only the relocalization part (for reporting), with `clock` as the
/// runner's clock.
pub fn relocalization(clock: &dyn Fn() -> u64) -> Summary {
    reloc_block(&mut Digest::new(), clock)
}

fn base_block(d: &mut Digest) {
    use vtsm_core::geom::{Camera, Pose, StereoRig, Vec3};
    use vtsm_core::rng::Rng;

    let mut rng = Rng::new(2026);
    for _ in 0..64 {
        d.u64(rng.next_u64());
    }
    let cam = match Camera::from_hfov(1368, 912, 77.0) {
        Ok(c) => c,
        Err(e) => return d.u64(u64::from(e.code())),
    };
    let rig = match StereoRig::new(cam, 0.4) {
        Ok(r) => r,
        Err(e) => return d.u64(u64::from(e.code())),
    };
    for _ in 0..256 {
        let axis = rng.unit_vector3();
        let angle = rng.uniform(-0.5, 0.5);
        let t = Vec3::new(rng.normal(), rng.normal(), rng.normal());
        let pose = Pose::new(nalgebra::UnitQuaternion::from_scaled_axis(axis * angle), t);
        let p = Vec3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(1.0, 8.0));
        let q = pose.inverse().compose(&pose).transform_point(&p);
        for v in q.iter() {
            d.f32(*v);
        }
        if let Some((l, r)) = rig.project_stereo(&p) {
            d.f32(l[0]);
            d.f32(l[1]);
            d.f32(r[0]);
        }
        for v in pose.q() {
            d.f32(v);
        }
    }
}

// ---- a small but complete relocalization -------------------------------------
//
// A 4 m × 4 m textured bumpy heightfield is encoded as a map product, stereo
// images are rendered from it with a gain/offset lighting change, and the engine
// relocalizes from a prior 13 cm / 1° off. Every output bit (pose, quality,
// counters) goes into the digest.

const GRID: usize = 33;
const EXTENT_M: f32 = 4.0;
const TEX: usize = 256;
const W: usize = 320;
const H: usize = 240;
const TILE: usize = 64;
const WS: vtsm_core::reloc::WorkspaceSizes =
    vtsm_core::reloc::WorkspaceSizes::new(32, 128, vtsm_core::ncc::Search::CoarseToFine);
const MAP_BYTES: usize = 200_000;

fn height(bumps: &[[f32; 3]; 12], x: f32, y: f32) -> f32 {
    let mut z = 0.04 * libm::sinf(1.7 * x) * libm::cosf(1.3 * y);
    for b in bumps {
        let d2 = (x - b[0]) * (x - b[0]) + (y - b[1]) * (y - b[1]);
        z += b[2] * libm::expf(-d2 / (2.0 * 0.12 * 0.12));
    }
    z
}

fn camera_pose(x: f32, y: f32, z: f32, yaw: f32) -> vtsm_core::geom::Pose {
    use nalgebra::{Matrix3, Rotation3, UnitQuaternion};
    use vtsm_core::geom::{Pose, Vec3};
    let pitch = 35.0f32.to_radians();
    let fwd = Vec3::new(libm::cosf(yaw) * libm::cosf(pitch), libm::sinf(yaw) * libm::cosf(pitch), -libm::sinf(pitch));
    let right = Vec3::new(libm::sinf(yaw), -libm::cosf(yaw), 0.0);
    let down = fwd.cross(&right);
    let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[right, down, fwd]));
    Pose::new(UnitQuaternion::from_rotation_matrix(&r), Vec3::new(x, y, z))
}

#[allow(clippy::too_many_lines)]
fn reloc_block(d: &mut Digest, clock: &dyn Fn() -> u64) -> Summary {
    use vtsm_core::config::Params;
    use vtsm_core::geom::{Camera, StereoRig, Vec3};
    use vtsm_core::image::GrayView;
    use vtsm_core::map::{MapSource, MapView};
    use vtsm_core::reloc::{MatchPolicy, Storage, WorkspaceSizes};
    use vtsm_core::rng::Rng;
    use vtsm_hal::runner::{DriveLimits, Job, RamPair, Runner, RunnerConfig, VerifyChecks};

    let fail = |code: u16| Summary { success: false, failure: code, final_error_um: u32::MAX, initial_error_um: 0, attempts: 0, engine_ticks: 0, steps: 0, telemetry_frames: 0, telemetry_bytes: 0 };
    let mut rng = Rng::new(7);
    let mut bumps = [[0.0f32; 3]; 12];
    for b in bumps.iter_mut() {
        *b = [rng.uniform(0.5, 3.8), rng.uniform(-1.8, 1.8), rng.uniform(0.03, 0.15)];
    }
    let step = EXTENT_M / (GRID - 1) as f32;
    let mut vertices = [[0.0f32; 3]; GRID * GRID];
    for (k, v) in vertices.iter_mut().enumerate() {
        let (i, j) = (k % GRID, k / GRID);
        let (x, y) = (i as f32 * step, -2.0 + j as f32 * step);
        *v = [x, y, height(&bumps, x, y)];
    }
    const NT: usize = 2 * (GRID - 1) * (GRID - 1);
    let mut triangles = [[0u32; 3]; NT];
    let mut uvs = [[[0.0f32; 2]; 3]; NT];
    let mut mask = [true; NT];
    let uv = |i: usize, j: usize| [i as f32 / (GRID - 1) as f32, j as f32 / (GRID - 1) as f32];
    let vid = |i: usize, j: usize| (j * GRID + i) as u32;
    for j in 0..GRID - 1 {
        for i in 0..GRID - 1 {
            let t = 2 * (j * (GRID - 1) + i);
            triangles[t] = [vid(i, j), vid(i + 1, j), vid(i + 1, j + 1)];
            uvs[t] = [uv(i, j), uv(i + 1, j), uv(i + 1, j + 1)];
            triangles[t + 1] = [vid(i, j), vid(i + 1, j + 1), vid(i, j + 1)];
            uvs[t + 1] = [uv(i, j), uv(i + 1, j + 1), uv(i, j + 1)];
        }
    }
    // Leave a band of ground out of the sampling mask, as sand would be.
    for (t, m) in mask.iter_mut().enumerate() {
        *m = (t / (2 * (GRID - 1))) % 8 != 3;
    }
    // Two-octave value noise texture.
    let mut texture = [0u8; TEX * TEX];
    let mut lattice = [[0.0f32; 18]; 18];
    let mut fine = [[0.0f32; 66]; 66];
    for row in lattice.iter_mut() {
        for v in row.iter_mut() {
            *v = rng.uniform(-60.0, 60.0);
        }
    }
    for row in fine.iter_mut() {
        for v in row.iter_mut() {
            *v = rng.uniform(-35.0, 35.0);
        }
    }
    let sample = |l: &[[f32; 18]; 18], x: f32, y: f32| {
        let (i, j) = (x as usize, y as usize);
        let (fx, fy) = (x - i as f32, y - j as f32);
        // Lattice reads through `get` (x, y < 17 here): no panic path.
        let at = |j: usize, i: usize| l.get(j).and_then(|r| r.get(i)).copied().unwrap_or(0.0);
        let (i1, j1) = (i.saturating_add(1), j.saturating_add(1));
        let a = at(j, i) * (1.0 - fx) + at(j, i1) * fx;
        let b = at(j1, i) * (1.0 - fx) + at(j1, i1) * fx;
        a * (1.0 - fy) + b * fy
    };
    for (k, px) in texture.iter_mut().enumerate() {
        let (x, y) = ((k % TEX) as f32, (k / TEX) as f32);
        let coarse = sample(&lattice, x / 16.0, y / 16.0);
        let (i, j) = ((x / 4.0) as usize, (y / 4.0) as usize);
        let v = 128.0 + coarse + fine[j.min(65)][i.min(65)];
        *px = v.clamp(0.0, 255.0) as u8;
    }
    let Ok(tex_view) = GrayView::new(&texture, TEX, TEX, TEX) else { return fail(1) };
    let src = MapSource { vertices: &vertices, triangles: &triangles, uvs: &uvs, mask: &mask, texture: tex_view, tile_size_m: 0.5, origin: [0.0; 3], vertex_scores: None };
    let mut map_bytes = [0u8; MAP_BYTES];
    let n = match vtsm_core::map::encode(&src, &mut map_bytes) {
        Ok(n) => n,
        Err(e) => return fail(e.code()),
    };
    let Some(encoded) = map_bytes.get(..n) else { return fail(2) };
    d.bytes(encoded);
    let map = match MapView::new_checked(encoded) {
        Ok(m) => m,
        Err(e) => return fail(e.code()),
    };

    let Ok(cam) = Camera::from_hfov(W as u32, H as u32, 70.0) else { return fail(3) };
    let Ok(rig) = StereoRig::new(cam, 0.3) else { return fail(4) };
    let truth = camera_pose(0.1, -0.15, 1.1, 0.05);
    let p = Params { template_px: 32, search_px: 128, n_corr: 24, n_iter: 3, attempts_per_iter: 300, ransac_iter: 300, max_reseed: 3, ..Params::paper() };
    let dq = nalgebra::UnitQuaternion::from_scaled_axis(Vec3::new(0.3, -0.5, 0.8).normalize() * 1.0f32.to_radians());
    let prior = vtsm_core::geom::Pose::new(dq * truth.rotation(), truth.translation() + Vec3::new(0.11, -0.06, 0.03));
    if WorkspaceSizes::for_params(&p, MatchPolicy::for_params(&p).search) != WS {
        return fail(6);
    }

    // The flight path: the runner captures the pair through the camera (which
    // renders it from the map at the true pose, with another gain and offset),
    // reads the prior and the map product through their devices, builds the
    // engine with the one constructor and steps it with the clock's time.
    let mut runner = Runner::new(
        devices::SceneCamera { map: &map, rig: &rig, truth, sequence: 0, clock },
        devices::TickClock(clock),
        devices::FlashStore(encoded),
        devices::FixedPrior(prior),
        devices::CountingTelemetry::default(),
        RunnerConfig { attempts: 3, product_attempts: 2, chunk_len: 4096, capture_timeout_ticks: u64::MAX, image_size: (W as u32, H as u32) },
    );
    let mut left = [0u8; W * H];
    let mut right = [0u8; W * H];
    let mut map_ram = [0u8; MAP_BYTES];
    let Some(map_buf) = map_ram.get_mut(..n) else { return fail(7) };
    let mut storage = Storage::<{ WS.bytes }, { WS.words }, { WS.runs }>::new();
    let Ok(ws) = storage.workspace(WS) else { return fail(8) };
    let limits = DriveLimits { units_per_step: 16, max_steps: u32::MAX, budget_ticks: u64::MAX };
    let job = Job { rig, params: p, seed: 2026, limits, verify: VerifyChecks::OFF, accuracy: None, final_pairs: 0, search: vtsm_core::reloc::Search::DEFAULT };
    let (out, report) = match runner.run(&job, map_buf, RamPair::new(&mut left, &mut right), ws, None) {
        Ok(r) => r,
        Err(e) => return fail(e.code()),
    };
    d.bytes(&left);
    d.bytes(&right);
    fold_outcome(d, &out);
    let (e1, _) = out.pose.error_to(&truth);
    let (e0, _) = prior.error_to(&truth);
    Summary {
        success: out.failure.is_none(),
        failure: out.failure.map_or(0, |c| c.code()),
        final_error_um: (e1 * 1e6) as u32,
        initial_error_um: (e0 * 1e6) as u32,
        attempts: out.stats.attempts,
        engine_ticks: report.drive.elapsed_ticks,
        steps: report.drive.steps,
        telemetry_frames: runner.telemetry.frames,
        telemetry_bytes: runner.telemetry.bytes,
    }
}

// ---- devices ------------------------------------------------------------------
//
// The no_std device set the runner drives on the bare-metal images (and on the
// host, for the same digest): a camera that renders its frames from the map,
// the target's instruction-driven clock, the map product in flash, a fixed
// prior, and a telemetry link that counts what it is sent.
pub mod devices {
    use core::convert::Infallible;
    use vtsm_core::geom::{Pose, StereoRig};
    use vtsm_core::image::Rect;
    use vtsm_core::map::MapView;
    use vtsm_core::raster::{self, Target};
    use vtsm_hal::prior::{Covariance, PriorEstimate};
    use super::TILE;
    use vtsm_core::frame::Eye;
    use vtsm_hal::{Clock, ErrorKind, ErrorType, FrameInfo, FrameStore, MapStore, PosePrior, StereoCamera, Telemetry};

    /// A stereo camera looking at the map from `truth`: each capture renders
    /// the pair, in 64-pixel tiles, with a gain and offset unlike the map's
    /// lighting.
    pub struct SceneCamera<'a, 'm> {
        pub map: &'a MapView<'m>,
        pub rig: &'a StereoRig,
        pub truth: Pose,
        pub sequence: u32,
        pub clock: &'a dyn Fn() -> u64,
    }

    impl ErrorType for SceneCamera<'_, '_> {
        type Error = ErrorKind;
    }

    impl StereoCamera for SceneCamera<'_, '_> {
        fn capture(&mut self, left: &mut [u8], right: &mut [u8], _timeout_ticks: u64) -> Result<FrameInfo, ErrorKind> {
            let cam = self.rig.cam();
            let (w, h) = (cam.width() as usize, cam.height() as usize);
            let n = w.saturating_mul(h);
            let (Some(left), Some(right)) = (left.get_mut(..n), right.get_mut(..n)) else { return Err(ErrorKind::Other) };
            let (mut inten, mut depth, mut mdepth) = ([0u8; TILE * TILE], [0u32; TILE * TILE], [0u32; TILE * TILE]);
            for (img, pose) in [(left, self.truth), (right, self.rig.world_from_right(&self.truth))] {
                for ty in (0..h).step_by(TILE) {
                    for tx in (0..w).step_by(TILE) {
                        let (tw, th) = (TILE.min(w.saturating_sub(tx)), TILE.min(h.saturating_sub(ty)));
                        let rect = Rect::new(tx as i32, ty as i32, tw as u32, th as u32);
                        let mut target = Target { intensity: &mut inten, depth: &mut depth, mask_depth: &mut mdepth };
                        if raster::render_window(self.map, &cam, &pose, rect, &mut target).is_err() {
                            continue;
                        }
                        // Tile rows into the frame, through `get`: no panic path.
                        for (y, trow) in (0..th).zip(inten.chunks_exact(tw.max(1))) {
                            let at = ty.saturating_add(y).saturating_mul(w).saturating_add(tx);
                            let Some(frow) = img.get_mut(at..).and_then(|r| r.get_mut(..tw)) else { continue };
                            for (p, &i) in frow.iter_mut().zip(trow) {
                                let v = f32::from(i) * 0.85 + 14.0;
                                *p = v.clamp(0.0, 255.0) as u8;
                            }
                        }
                    }
                }
            }
            self.sequence = self.sequence.wrapping_add(1);
            Ok(FrameInfo { width: cam.width(), height: cam.height(), stride: cam.width(), sequence: self.sequence, timestamp_ticks: (self.clock)(), exposure_us: 2000 })
        }
    }

    /// A stereo camera whose frame memory holds one captured pair: each
    /// capture delivers it (the DMA copy into the caller's buffers). Used by
    /// the flight-profile image (`src/flight.rs`).
    #[allow(dead_code)]
    pub struct FrameCamera<'a> {
        pub left: &'a [u8],
        pub right: &'a [u8],
        pub width: u32,
        pub height: u32,
        pub sequence: u32,
        pub clock: &'a dyn Fn() -> u64,
    }

    impl ErrorType for FrameCamera<'_> {
        type Error = ErrorKind;
    }

    impl StereoCamera for FrameCamera<'_> {
        fn capture(&mut self, left: &mut [u8], right: &mut [u8], _timeout_ticks: u64) -> Result<FrameInfo, ErrorKind> {
            let n = self.left.len();
            let (Some(l), Some(r)) = (left.get_mut(..n), right.get_mut(..n)) else { return Err(ErrorKind::Other) };
            if self.right.len() != n {
                return Err(ErrorKind::Other);
            }
            l.copy_from_slice(self.left);
            r.copy_from_slice(self.right);
            self.sequence = self.sequence.wrapping_add(1);
            Ok(FrameInfo { width: self.width, height: self.height, stride: self.width, sequence: self.sequence, timestamp_ticks: (self.clock)(), exposure_us: 2000 })
        }
    }

    /// The same frame memory read in place: a capture latches the pair, and
    /// the engine reads its windows straight from it (no copy of the pair).
    impl FrameStore for FrameCamera<'_> {
        fn capture_in_place(&mut self, _timeout_ticks: u64) -> Result<FrameInfo, ErrorKind> {
            let n = (self.width as usize).saturating_mul(self.height as usize);
            if n == 0 || self.left.len() != n || self.right.len() != n {
                return Err(ErrorKind::Other);
            }
            self.sequence = self.sequence.wrapping_add(1);
            Ok(FrameInfo { width: self.width, height: self.height, stride: self.width, sequence: self.sequence, timestamp_ticks: (self.clock)(), exposure_us: 2000 })
        }

        fn read_window(&mut self, eye: Eye, rect: Rect, out: &mut [u8]) -> Result<(), ErrorKind> {
            let frame = match eye {
                Eye::Left => self.left,
                Eye::Right => self.right,
            };
            let (w, h) = (self.width as usize, self.height as usize);
            let (x, y, rw, rh) = (rect.x as usize, rect.y as usize, rect.w as usize, rect.h as usize);
            let inside = rect.x >= 0 && rect.y >= 0 && rw > 0 && rh > 0 && x.saturating_add(rw) <= w && y.saturating_add(rh) <= h;
            if !inside {
                return Err(ErrorKind::Other);
            }
            let out = out.get_mut(..rw.saturating_mul(rh)).ok_or(ErrorKind::Other)?;
            // `max(1)`: `chunks_exact_mut(0)` panics (rw ≥ 1 here anyway).
            // Rows as a bounded range, not `enumerate` (its counter keeps an
            // overflow check, a panic path).
            for (row, dst) in (y..y.saturating_add(rh)).zip(out.chunks_exact_mut(rw.max(1))) {
                let at = row.saturating_mul(w).saturating_add(x);
                let src = frame.get(at..).and_then(|r| r.get(..rw)).ok_or(ErrorKind::Other)?;
                dst.copy_from_slice(src);
            }
            Ok(())
        }
    }

    /// The target's tick counter.
    pub struct TickClock<'a>(pub &'a dyn Fn() -> u64);

    impl ErrorType for TickClock<'_> {
        type Error = Infallible;
    }

    impl Clock for TickClock<'_> {
        fn tick_hz(&self) -> u32 {
            1_000_000
        }
        fn now_ticks(&mut self) -> Result<u64, Infallible> {
            Ok((self.0)())
        }
    }

    /// The map product in memory-mapped flash.
    pub struct FlashStore<'a>(pub &'a [u8]);

    impl ErrorType for FlashStore<'_> {
        type Error = ErrorKind;
    }

    impl MapStore for FlashStore<'_> {
        fn len(&mut self) -> Result<u32, ErrorKind> {
            u32::try_from(self.0.len()).map_err(|_| ErrorKind::Other)
        }
        fn read_range(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), ErrorKind> {
            let start = offset as usize;
            let src = start.checked_add(buf.len()).and_then(|end| self.0.get(start..end)).ok_or(ErrorKind::Other)?;
            buf.copy_from_slice(src);
            Ok(())
        }
        fn mapped(&self) -> Option<&[u8]> {
            // Flash is memory-mapped: the frame-store path checks and uses
            // the product in place.
            Some(self.0)
        }
    }

    /// A prior from the navigation filter, fixed for the run.
    pub struct FixedPrior(pub Pose);

    impl ErrorType for FixedPrior {
        type Error = Infallible;
    }

    impl PosePrior for FixedPrior {
        fn latest(&mut self) -> Result<PriorEstimate, Infallible> {
            let (t, r) = (0.2f32 * 0.2, 1.5f32.to_radians() * 1.5f32.to_radians());
            Ok(PriorEstimate { world_from_left: self.0, covariance: Covariance::Diagonal([t, t, t, r, r, r]), uncertainty: None, timestamp_ticks: 0 })
        }
    }

    /// A downlink that counts frames and payload bytes.
    #[derive(Default)]
    pub struct CountingTelemetry {
        pub frames: u32,
        pub bytes: u32,
    }

    impl ErrorType for CountingTelemetry {
        type Error = Infallible;
    }

    impl Telemetry for CountingTelemetry {
        fn send(&mut self, _kind: u8, payload: &[u8]) -> Result<(), Infallible> {
            self.frames = self.frames.saturating_add(1);
            self.bytes = self.bytes.saturating_add(payload.len() as u32);
            Ok(())
        }
    }
}
