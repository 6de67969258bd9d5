// Determinism workload shared by the firmware image (Cortex-M7 under QEMU) and
// the host test `tests/tests/cross_target.rs` (via `include!`). It exercises the
// core's floating-point and integer paths and folds every output, bit for bit,
// into one FNV-1a digest: equal digests mean bit-identical results on both targets.

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

/// Run the workload and return the digest.
pub fn workload() -> u64 {
    use vtsm_core::geom::{Camera, Pose, StereoRig, Vec3};
    use vtsm_core::rng::Rng;

    let mut d = Digest::new();
    let mut rng = Rng::new(2026);
    for _ in 0..64 {
        d.u64(rng.next_u64());
    }
    let cam = match Camera::from_hfov(1368, 912, 77.0) {
        Ok(c) => c,
        Err(e) => return u64::from(e.code()),
    };
    let rig = match StereoRig::new(cam, 0.4) {
        Ok(r) => r,
        Err(e) => return u64::from(e.code()),
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
    d.0
}
