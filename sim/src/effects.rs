//! Camera effects: a camera that is not ideal, applied to a rendered stereo pair.
//!
//! [`CameraEffects::apply`] takes the 8-bit gamma-2.2 pair of [`crate::render`] and
//! returns a new pair as a worse camera would have captured it. Per image, in physical
//! order: undo gamma 2.2 to linear `[0, 1]` → defocus (separable Gaussian, radius
//! ⌈3σ⌉, edges clamped) → motion blur (line of ⌈len⌉ + 1 bilinear samples) →
//! vignetting (`1 − v·r²/r_max²` from the image centre) → gain (right also × (1 +
//! mismatch)), saturating at 1 → Gaussian read and shot noise in output counts →
//! encoding (gamma 2.2, or a 12-bit capture companded by a square-root LUT) → round to
//! 8 bits → JPEG encode and decode. Stages at their identity value are skipped; with no
//! linear-domain stage the bytes are not round-tripped through floats, and
//! [`CameraEffects::NONE`] returns the pair unchanged.
//!
//! Noise is keyed by (seed, side, pixel index), rows run in parallel with rayon, and the
//! output is byte-identical for any thread count. Work is O(pixels × kernel): at most
//! 61 taps per pass for defocus and 31 bilinear samples for motion blur, as
//! [`CameraEffects::check`] bounds the parameters to the ranges [`CameraEffects::parse`]
//! accepts.

use crate::error::{Error, Result};
use crate::scene::StereoPair;
use rayon::prelude::*;
use vtsm_core::rng::Rng;

/// A camera that is not ideal: the effects [`CameraEffects::apply`] adds to a rendered pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraEffects {
    /// Exposure × gain of the camera relative to the ideal one, linear factor (1 = none).
    pub gain: f32,
    /// Right camera's gain relative to the left, minus 1 (0.1 = right 10 % brighter).
    pub gain_mismatch: f32,
    /// Extra read noise standard deviation, 8-bit counts; shot-noise variance is
    /// `noise_dn / 16 × signal` counts² (photon noise grows with the gain that
    /// makes the read noise large).
    pub noise_dn: f32,
    /// Gaussian defocus blur sigma, pixels (0 = none).
    pub defocus_px: f32,
    /// Motion blur length, pixels (0 = none).
    pub motion_px: f32,
    /// Direction of the motion blur, degrees from the +u axis towards +v.
    pub motion_deg: f32,
    /// Extra radial quadratic fall-off, fraction lost at the corners (0 = none).
    pub vignetting: f32,
    /// JPEG quality of an encode–decode round trip, 1..=100 (0 = no JPEG).
    pub jpeg_quality: u8,
    /// A 12-bit linear capture companded to 8 bits by a square-root LUT instead of gamma 2.2.
    pub compand: bool,
}

/// Key, lowest and highest value of the real-valued parameters, in field order.
const RANGES: [(&str, f32, f32); 6] = [
    ("gain", 0.1, 10.0),
    ("mismatch", -0.5, 0.5),
    ("noise", 0.0, 50.0),
    ("defocus", 0.0, 10.0),
    ("motion", 0.0, 30.0),
    ("vignetting", 0.0, 0.9),
];
const KEYS: &str = "none gain mismatch noise defocus motion motion-deg vignetting jpeg compand";
const JPEG: &str = "a quality in 1..=100 (0 = off)";
const DEG: &str = "a finite angle, degrees";
const COMPAND: &str = "`compand`, `compand=1` or `compand=0`";
const LEFT_STREAM: u64 = 0xEFFE_C750_0000_0001;
const RIGHT_STREAM: u64 = 0xEFFE_C750_0000_0002;
const N: CameraEffects = CameraEffects::NONE;

/// One realistic level per effect, for evaluation suites: `(name, effects)`.
#[rustfmt::skip]
pub const REALISTIC: &[(&str, CameraEffects)] = &[
    // Exposure metered on bright sunlit rock, leaving the regolith dark: ~0.7 stop under.
    ("under-exposed", CameraEffects { gain: 0.6, ..N }),
    // Exposure metered on dark regolith or a shadow: ~0.7 stop over, bright faces clip.
    ("over-exposed", CameraEffects { gain: 1.6, ..N }),
    // Responsivity of two nominally identical cameras without flat-field calibration.
    ("mismatch", CameraEffects { gain_mismatch: 0.15, ..N }),
    // Read noise of a warm, uncooled detector; with the tied shot term ≈ 7 DN at mid-gray.
    ("noise", CameraEffects { noise_dn: 4.0, ..N }),
    // Fixed-focus optics set beyond the 1–3 m working range, or dust on the window.
    ("defocus", CameraEffects { defocus_px: 1.5, ..N }),
    // Residual mast slew or vibration during the exposure smears a few pixels.
    ("motion", CameraEffects { motion_px: 4.0, ..N }),
    // An uncorrected 77° lens loses ~70 % at the corner (cos⁴); 0.4 is partly corrected.
    ("vignetting", CameraEffects { vignetting: 0.4, ..N }),
    // A lossy downlink-compressed browse product.
    ("jpeg", CameraEffects { jpeg_quality: 60, ..N }),
    // The 12→8-bit square-root LUT of MSL (Mastcam, MAHLI, MARDI) and Mars 2020 products.
    ("compand", CameraEffects { compand: true, ..N }),
];

fn bad(what: impl std::fmt::Display, expected: &str) -> String {
    format!("camera effects: `{what}`: expected {expected}")
}

fn range(lo: f32, hi: f32) -> String {
    format!("a number in [{lo}, {hi}]")
}

impl Default for CameraEffects {
    fn default() -> Self {
        Self::NONE
    }
}

impl CameraEffects {
    /// The ideal camera: gain 1, everything else off.
    pub const NONE: Self = Self {
        gain: 1.0,
        gain_mismatch: 0.0,
        noise_dn: 0.0,
        defocus_px: 0.0,
        motion_px: 0.0,
        motion_deg: 0.0,
        vignetting: 0.0,
        jpeg_quality: 0,
        compand: false,
    };

    /// Whether applying these effects leaves a pair unchanged (`motion_deg` is ignored
    /// without motion blur).
    pub fn is_none(&self) -> bool {
        let mut e = *self;
        e.motion_deg = 0.0;
        e == Self::NONE
    }

    fn reals_mut(&mut self) -> [&mut f32; 6] {
        let s = self;
        [
            &mut s.gain,
            &mut s.gain_mismatch,
            &mut s.noise_dn,
            &mut s.defocus_px,
            &mut s.motion_px,
            &mut s.vignetting,
        ]
    }

    fn reals(&self) -> [f32; 6] {
        let mut c = *self;
        c.reals_mut().map(|x| *x)
    }

    /// Check every parameter is in the range [`CameraEffects::parse`] accepts; the
    /// error names the key and the range.
    pub fn check(&self) -> std::result::Result<(), String> {
        for ((key, lo, hi), v) in RANGES.iter().zip(self.reals()) {
            if !(v.is_finite() && (*lo..=*hi).contains(&v)) {
                return Err(bad(format!("{key}={v}"), &range(*lo, *hi)));
            }
        }
        if !self.motion_deg.is_finite() {
            return Err(bad(format!("motion-deg={}", self.motion_deg), DEG));
        }
        if self.jpeg_quality > 100 {
            return Err(bad(format!("jpeg={}", self.jpeg_quality), JPEG));
        }
        Ok(())
    }

    /// Parse a comma-separated `key=value` list: `gain` [0.1, 10], `mismatch`
    /// [−0.5, 0.5], `noise` [0, 50], `defocus` [0, 10], `motion` [0, 30], `motion-deg`
    /// (any finite, reduced mod 180), `vignetting` [0, 0.9], `jpeg` 1..=100 (0 = off),
    /// `compand` (bare, `=1` or `=0`) and `none`. Keys left out are at their identity.
    pub fn parse(spec: &str) -> std::result::Result<Self, String> {
        if spec.trim().is_empty() {
            return Err(format!("camera effects: empty spec; keys: {KEYS}"));
        }
        let mut e = Self::NONE;
        let mut seen: Vec<&str> = Vec::new();
        for item in spec.split(',').map(str::trim) {
            let (key, val) = match item.split_once('=') {
                Some((k, v)) => (k.trim(), Some(v.trim())),
                None => (item, None),
            };
            if seen.contains(&key) {
                return Err(format!("camera effects: `{key}` given twice"));
            }
            seen.push(key);
            let real = val
                .and_then(|v| v.parse::<f32>().ok())
                .filter(|x| x.is_finite());
            match (key, val) {
                ("none", None) => {}
                ("compand", None | Some("1")) => e.compand = true,
                ("compand", Some("0")) => e.compand = false,
                ("compand", _) => return Err(bad(item, COMPAND)),
                ("jpeg", _) => {
                    let q = val.and_then(|v| v.parse::<u8>().ok()).filter(|q| *q <= 100);
                    e.jpeg_quality = q.ok_or_else(|| bad(item, JPEG))?;
                }
                ("motion-deg", _) => {
                    let d = real.ok_or_else(|| bad(item, DEG))?.rem_euclid(180.0);
                    e.motion_deg = if d < 180.0 { d } else { 0.0 };
                }
                _ => {
                    let Some(i) = RANGES.iter().position(|r| r.0 == key) else {
                        return Err(format!(
                            "camera effects: `{item}`: unknown key; keys: {KEYS}"
                        ));
                    };
                    let (_, lo, hi) = RANGES[i];
                    let x = real.filter(|x| (lo..=hi).contains(x));
                    *e.reals_mut()[i] = x.ok_or_else(|| bad(item, &range(lo, hi)))?;
                }
            }
        }
        Ok(e)
    }

    /// A short canonical spec that [`CameraEffects::parse`] reads back to `self`
    /// (`none` for [`CameraEffects::NONE`]).
    pub fn label(&self) -> String {
        let mut parts = Vec::new();
        for (i, ((key, _, _), v)) in RANGES.iter().zip(self.reals()).enumerate() {
            if v != N.reals()[i] {
                parts.push(format!("{key}={v}"));
            }
            if i == 4 && self.motion_deg != 0.0 {
                parts.push(format!("motion-deg={}", self.motion_deg));
            }
        }
        if self.jpeg_quality > 0 {
            parts.push(format!("jpeg={}", self.jpeg_quality));
        }
        if self.compand {
            parts.push("compand".into());
        }
        if parts.is_empty() {
            return "none".into();
        }
        parts.join(",")
    }

    /// Apply the effects to `pair`, noise drawn from `seed`: a new pair of the same size.
    /// Errors on parameters out of range ([`CameraEffects::check`]), image buffers that
    /// do not match the size, or a failed JPEG round trip.
    pub fn apply(&self, pair: &StereoPair, seed: u64) -> Result<StereoPair> {
        if self.is_none() {
            return Ok(pair.clone());
        }
        self.check().map_err(Error::msg)?;
        let (w, h) = (pair.width as usize, pair.height as usize);
        let (nl, nr) = (pair.left.len(), pair.right.len());
        if nl != w * h || nr != w * h {
            let size = format!("{w}×{h}");
            return Err(Error::msg(format!(
                "camera effects: {size} pair of {nl} and {nr} bytes"
            )));
        }
        let root = Rng::new(seed);
        let right_gain = self.gain * (1.0 + self.gain_mismatch);
        Ok(StereoPair {
            width: pair.width,
            height: pair.height,
            left: self.image(&pair.left, w, h, self.gain, root.fork(LEFT_STREAM))?,
            right: self.image(&pair.right, w, h, right_gain, root.fork(RIGHT_STREAM))?,
        })
    }

    /// The pipeline for one image of `w × h` with total gain `gain`.
    fn image(&self, img: &[u8], w: usize, h: usize, gain: f32, noise: Rng) -> Result<Vec<u8>> {
        let blur = self.defocus_px > 0.0 || self.motion_px > 0.0;
        let linear = blur || self.vignetting > 0.0 || gain != 1.0 || self.compand;
        let mut out = img.to_vec();
        if linear || self.noise_dn > 0.0 {
            let dn = if linear {
                self.linear(img, w, h, gain)
            } else {
                img.iter().map(|&v| f32::from(v)).collect()
            };
            let n = self.noise_dn;
            rows(&mut out, w, |y, row| {
                for (i, px) in (y * w..).zip(row) {
                    let mut v = dn[i];
                    if n > 0.0 {
                        let sd = (n * n + n / 16.0 * v.max(0.0)).sqrt();
                        v += sd * noise.at((i as u64) << 2).normal();
                    }
                    *px = v.round().clamp(0.0, 255.0) as u8;
                }
            });
        }
        if self.jpeg_quality > 0 && !out.is_empty() {
            out = jpeg(&out, w, h, self.jpeg_quality)?;
        }
        Ok(out)
    }

    /// Linear-domain stages and encoding: output counts before noise and rounding.
    fn linear(&self, img: &[u8], w: usize, h: usize, gain: f32) -> Vec<f32> {
        let lut: [f32; 256] = std::array::from_fn(|v| (v as f32 / 255.0).powf(2.2));
        let mut lin: Vec<f32> = img.iter().map(|&v| lut[usize::from(v)]).collect();
        if self.defocus_px > 0.0 {
            lin = defocus(&lin, w, h, self.defocus_px);
        }
        if self.motion_px > 0.0 {
            lin = motion(&lin, w, h, self.motion_px, self.motion_deg);
        }
        let (cx, cy) = ((w as f32 - 1.0) / 2.0, (h as f32 - 1.0) / 2.0);
        let r_max2 = (cx * cx + cy * cy).max(f32::MIN_POSITIVE);
        let (vig, compand) = (self.vignetting, self.compand);
        rows(&mut lin, w, |y, row| {
            for (x, v) in row.iter_mut().enumerate() {
                let r2 = (x as f32 - cx).powi(2) + (y as f32 - cy).powi(2);
                let l = (*v * (1.0 - vig * r2 / r_max2) * gain).clamp(0.0, 1.0);
                *v = if compand {
                    255.0 * ((l * 4095.0).round() / 4095.0).sqrt()
                } else {
                    255.0 * l.powf(1.0 / 2.2)
                };
            }
        });
        lin
    }
}

/// Separable Gaussian blur of sigma `sigma` pixels, radius ⌈3σ⌉, edges clamped.
fn defocus(src: &[f32], w: usize, h: usize, sigma: f32) -> Vec<f32> {
    let r = (3.0 * sigma).ceil() as isize;
    let mut k: Vec<f32> = (-r..=r)
        .map(|i| (-((i * i) as f32) / (2.0 * sigma * sigma)).exp())
        .collect();
    let sum: f32 = k.iter().sum();
    k.iter_mut().for_each(|x| *x /= sum);
    let at = |i: isize, n: usize| i.clamp(0, n as isize - 1) as usize;
    let mut tmp = vec![0.0f32; w * h];
    rows(&mut tmp, w, |y, row| {
        for (j, kj) in (-r..).zip(&k) {
            for (x, o) in row.iter_mut().enumerate() {
                *o += kj * src[y * w + at(x as isize + j, w)];
            }
        }
    });
    let mut out = vec![0.0f32; w * h];
    rows(&mut out, w, |y, row| {
        for (j, kj) in (-r..).zip(&k) {
            let sy = at(y as isize + j, h);
            for (o, v) in row.iter_mut().zip(&tmp[sy * w..(sy + 1) * w]) {
                *o += kj * v;
            }
        }
    });
    out
}

/// Motion blur: the mean of ⌈len⌉ + 1 bilinear samples along a centred segment of
/// `len` pixels at `deg` degrees, edges clamped.
fn motion(src: &[f32], w: usize, h: usize, len: f32, deg: f32) -> Vec<f32> {
    let n = len.ceil() as usize + 1;
    let (s, c) = deg.to_radians().sin_cos();
    let offsets: Vec<(f32, f32)> = (0..n)
        .map(|i| {
            let t = len * (i as f32 / (n - 1) as f32 - 0.5);
            (t * c, t * s)
        })
        .collect();
    let sample = |x: f32, y: f32| {
        let (x, y) = (x.clamp(0.0, w as f32 - 1.0), y.clamp(0.0, h as f32 - 1.0));
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let row = |yy: usize| src[yy * w + x0] * (1.0 - fx) + src[yy * w + x1] * fx;
        row(y0) * (1.0 - fy) + row(y1) * fy
    };
    let mut out = vec![0.0f32; w * h];
    rows(&mut out, w, |y, row| {
        for (x, o) in row.iter_mut().enumerate() {
            for (dx, dy) in &offsets {
                *o += sample(x as f32 + dx, y as f32 + dy) / n as f32;
            }
        }
    });
    out
}

/// Encode an 8-bit gray image as JPEG at `quality` and decode it back.
fn jpeg(img: &[u8], w: usize, h: usize, quality: u8) -> Result<Vec<u8>> {
    let fail = |e: image::ImageError| Error::msg(format!("camera effects: JPEG q={quality}: {e}"));
    let mut buf = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut buf, quality)
        .encode(img, w as u32, h as u32, image::ExtendedColorType::L8)
        .map_err(fail)?;
    let back = image::load_from_memory_with_format(&buf, image::ImageFormat::Jpeg)
        .map_err(fail)?
        .into_luma8();
    if back.dimensions() != (w as u32, h as u32) {
        return Err(Error::msg(
            "camera effects: the JPEG decoded to another size",
        ));
    }
    Ok(back.into_raw())
}

/// `f(y, row)` for every row of the `w`-wide image `buf`, rows in parallel.
fn rows<T: Send>(buf: &mut [T], w: usize, f: impl Fn(usize, &mut [T]) + Sync + Send) {
    buf.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| f(y, row));
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
mod tests {
    use super::*;

    const W: usize = 64;
    const H: usize = 48;

    fn pair_of(f: impl Fn(usize, usize) -> u8) -> StereoPair {
        let img: Vec<u8> = (0..W * H).map(|i| f(i % W, i / W)).collect();
        StereoPair {
            width: W as u32,
            height: H as u32,
            left: img.clone(),
            right: img,
        }
    }

    fn fx(spec: &str) -> CameraEffects {
        CameraEffects::parse(spec).unwrap()
    }

    /// The left image of `pair` after the effects of `spec`, seed 0.
    fn left(spec: &str, pair: &StereoPair) -> Vec<u8> {
        fx(spec).apply(pair, 0).unwrap().left
    }

    fn mean(img: &[u8]) -> f64 {
        img.iter().map(|&v| f64::from(v)).sum::<f64>() / img.len() as f64
    }

    fn variance(img: &[u8]) -> f64 {
        let m = mean(img);
        img.iter().map(|&v| (f64::from(v) - m).powi(2)).sum::<f64>() / img.len() as f64
    }

    /// Reference: a gamma-2.2 pixel `v` times `gain` in linear light, saturating.
    fn gained(v: u8, gain: f64) -> f64 {
        let lin = (f64::from(v) / 255.0).powf(2.2) * gain;
        255.0 * lin.min(1.0).powf(1.0 / 2.2)
    }

    fn near(v: u8, want: f64) -> bool {
        (f64::from(v) - want).abs() <= 0.5 + 1e-3
    }

    /// Verifies: VTSM-SIM-020
    #[test]
    fn none_is_the_default_and_leaves_the_pair_byte_identical() {
        assert_eq!(CameraEffects::default(), CameraEffects::NONE);
        assert!(CameraEffects::NONE.is_none());
        assert_eq!(fx("none"), CameraEffects::NONE);
        let p = pair_of(|x, y| (x * 7 + y * 13) as u8);
        assert_eq!(CameraEffects::NONE.apply(&p, 9).unwrap(), p);
        let only_deg = fx("motion-deg=30");
        assert!(only_deg.is_none() && only_deg != N);
        assert_eq!(only_deg.apply(&p, 1).unwrap(), p);
        // Gain only on the right: every left byte value passes through untouched.
        let all = pair_of(|x, y| (x + W * y) as u8);
        assert_eq!(left("mismatch=0.2", &all), all.left);
    }

    /// Verifies: VTSM-SIM-020
    #[test]
    fn label_round_trips_every_realistic_level_and_a_combined_spec() {
        assert_eq!(CameraEffects::NONE.label(), "none");
        for (name, e) in REALISTIC {
            assert!(!e.is_none(), "{name}");
            e.check().unwrap();
            assert_eq!(fx(&e.label()), *e, "{name}: {}", e.label());
        }
        let e = fx(
            "gain=1.25, mismatch=-0.1,noise=3,defocus=0.8,motion=6,motion-deg=200,\
                    vignetting=0.3,jpeg=75,compand",
        );
        assert_eq!(e.motion_deg, 20.0);
        assert!(e.compand && e.jpeg_quality == 75 && e.gain_mismatch == -0.1);
        assert_eq!(fx(&e.label()), e);
        assert_eq!(fx("motion-deg=-90").motion_deg, 90.0);
        assert!(!fx("compand=0").compand);
    }

    /// Verifies: VTSM-SIM-020
    #[test]
    fn parse_rejects_bad_specs_naming_the_key_and_range() {
        for (spec, want) in [
            ("", "empty"),
            ("bogus=1", "unknown key"),
            ("gain", "`gain`: expected a number in [0.1, 10]"),
            ("gain=20", "`gain=20`: expected a number in [0.1, 10]"),
            ("noise=NaN", "`noise=NaN`: expected a number in [0, 50]"),
            ("defocus=inf", "`defocus=inf`: expected a number in [0, 10]"),
            ("motion-deg=nan", "motion-deg"),
            ("jpeg=101", "1..=100"),
            ("compand=yes", "compand"),
            ("gain=2,gain=3", "twice"),
        ] {
            let err = CameraEffects::parse(spec).unwrap_err();
            assert!(err.contains(want), "{spec}: {err}");
        }
        let mut bad = N;
        bad.vignetting = 1.5;
        let err = bad.apply(&pair_of(|_, _| 9), 0).unwrap_err();
        assert!(err.msg.contains("vignetting=1.5"), "{err}");
    }

    /// Verifies: VTSM-SIM-020
    #[test]
    fn noise_is_seeded_and_differs_between_seeds_and_sides() {
        let p = pair_of(|x, _| 60 + x as u8);
        let e = fx("noise=4,defocus=0.7");
        let a = e.apply(&p, 5).unwrap();
        assert_eq!(a, e.apply(&p, 5).unwrap());
        assert_ne!(a.left, e.apply(&p, 6).unwrap().left);
        assert_ne!(a.left, a.right);
        let one = rayon::ThreadPoolBuilder::new().num_threads(1);
        assert_eq!(one.build().unwrap().install(|| e.apply(&p, 5)).unwrap(), a);
    }

    /// Verifies: VTSM-SIM-020
    #[test]
    fn gain_brightens_by_the_gamma_correct_amount_and_saturates() {
        let out = left("gain=2", &pair_of(|x, _| if x < W / 2 { 128 } else { 250 }));
        assert!(near(out[0], gained(128, 2.0)), "{}", out[0]);
        assert_eq!(out[W - 1], 255);
        let m = fx("mismatch=0.1").apply(&pair_of(|_, _| 100), 0).unwrap();
        assert!(m.left.iter().all(|&v| v == 100));
        assert!(m
            .right
            .iter()
            .all(|&v| v > 100 && near(v, gained(100, 1.1))));
    }

    /// Verifies: VTSM-SIM-020
    #[test]
    fn defocus_keeps_a_flat_mean_and_smooths_a_checkerboard() {
        assert!(left("defocus=2", &pair_of(|_, _| 100))
            .iter()
            .all(|&v| v == 100));
        let board = pair_of(|x, y| if (x / 4 + y / 4) % 2 == 0 { 20 } else { 200 });
        let var = variance(&left("defocus=2", &board));
        assert!(var < 0.25 * variance(&board.left), "{var}");
    }

    /// Verifies: VTSM-SIM-020
    #[test]
    fn horizontal_motion_spreads_a_vertical_stripe_by_its_length_only() {
        let out = left("motion=4", &pair_of(|x, _| if x == 32 { 255 } else { 0 }));
        let lit: Vec<usize> = (0..W).filter(|&x| out[x] > 0).collect();
        assert_eq!(lit, (30..=34).collect::<Vec<_>>());
        // A fifth of the light in each of the 5 columns, the same on every row.
        let fifth = 255.0 * 0.2f64.powf(1.0 / 2.2);
        assert!(lit.iter().all(|&x| near(out[x], fifth)));
        for y in 0..H {
            assert_eq!(out[y * W..(y + 1) * W], out[..W], "row {y}");
        }
    }

    /// Verifies: VTSM-SIM-020
    #[test]
    fn vignetting_darkens_the_corners_not_the_centre() {
        let out = left("vignetting=0.5", &pair_of(|_, _| 200));
        assert_eq!(out[(H / 2) * W + W / 2], 200);
        for corner in [0, W - 1, (H - 1) * W, H * W - 1] {
            assert!(near(out[corner], gained(200, 0.5)), "{}", out[corner]);
        }
    }

    /// Verifies: VTSM-SIM-020
    #[test]
    fn compand_maps_mid_gray_through_the_square_root_lut() {
        let out = left("compand", &pair_of(|_, _| 128));
        let sqrt = 255.0 * (128.0f64 / 255.0).powf(2.2).sqrt();
        assert!(out.iter().all(|&v| near(v, sqrt)), "{} vs {sqrt}", out[0]);
        assert!(out[0] < 128);
    }

    /// Verifies: VTSM-SIM-020
    #[test]
    fn jpeg_keeps_a_gradient_mean_and_alters_texture() {
        let smooth = pair_of(|x, y| (60 + 2 * x + y) as u8);
        assert!((mean(&left("jpeg=60", &smooth)) - mean(&smooth.left)).abs() < 2.0);
        let texture = pair_of(|x, y| ((x * 37 + y * 91) % 101 + 70) as u8);
        assert_ne!(left("jpeg=60", &texture), texture.left);
    }

    /// Verifies: VTSM-SIM-020
    #[test]
    fn noise_std_dev_matches_read_plus_shot_model() {
        let out = left("noise=4", &pair_of(|_, _| 128));
        let expect = (4.0f64 * 4.0 + 4.0 / 16.0 * 128.0).sqrt();
        let sd = variance(&out).sqrt();
        assert!((sd / expect - 1.0).abs() < 0.2, "sd {sd} vs {expect}");
        assert!((mean(&out) - 128.0).abs() < 1.0);
    }
}
