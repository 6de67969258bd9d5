//! Host-side stereo rectification of a physical pair calibrated by OpenCV
//! ([`crate::io::calib::model::OpenCvCalib`]), so the core only ever sees an
//! ideal rectified pair.
//!
//! [`stereo_rectify`] follows `cv2.stereoRectify` with its default arguments:
//! `flags = CALIB_ZERO_DISPARITY` (both rectified cameras share `cx`, which the
//! core's single-camera [`StereoRig`] needs), `alpha = -1` (no scaling: the
//! rectified focal length is the mean of the two `fy`), and the new image size
//! equal to the calibration's. Like OpenCV it rotates each camera by half the
//! relative rotation, then both about the axis that brings the baseline onto
//! +x, and centres the principal point on the mean of the four image corners
//! undistorted by OpenCV's five fixed-point iterations (so the principal points
//! agree with OpenCV's to rounding). Only horizontal pairs are accepted.
//!
//! [`MapModel`] is the per-pixel lookup of `cv2.initUndistortRectifyMap`
//! (`CV_32FC1` maps; stored by [`RectifyMap`] for comparison, computed on the
//! fly by [`MapModel::remap`]), and the remap samples it with a constant 0
//! border (`BORDER_CONSTANT`) by one of three kernels ([`Interp`]), those of
//! `cv2.remap`: `INTER_LINEAR` (bilinear with exact weights: OpenCV 5 gives the
//! same pixels, OpenCV 4 quantises positions to 1/32 pixel), `INTER_CUBIC`
//! (Keys' cubic, a = −0.75, 4 × 4 taps) and `INTER_LANCZOS4` (8 × 8 taps), the
//! last two with exact f32 weights where OpenCV quantises positions to 1/32
//! pixel and weights to 15 bits. Bilinear resampling is a low-pass filter
//! whose strength changes with the fractional position, so it blurs each
//! template-sized patch of the rectified pair differently from the rendered
//! templates; the default, [`Interp::Lanczos4`], keeps the pair's detail (the
//! measured comparison is in `fsw-docs/eval/physical.md`). Pixel coordinates
//! use the pixel-centre convention of design §3, which is OpenCV's.
//!
//! [`Rectifier`] bundles both and converts poses: the rectified left camera has
//! the physical left camera's centre and the orientation `R1` (OpenCV's: it maps
//! physical-left coordinates to rectified-left ones), so
//! `world_from_rect = world_from_phys · R1ᵀ`.
//!
//! Work is bounded: one map entry per rectified pixel, a fixed number of
//! iterations per undistortion.

use crate::io::calib::model::{OpenCvCalib, OpenCvCamera};
use crate::io::image::Gray8;
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use rayon::prelude::*;
use vtsm_core::geom::{Camera, Pose, StereoRig, Vec3};

/// Iterations of OpenCV's `undistortPoints` default (fixed point, no tolerance).
pub const OPENCV_UNDISTORT_ITERS: usize = 5;
/// Cap on Newton iterations of [`Distortion::undistort`].
pub const MAX_NEWTON_ITERS: usize = 30;

/// OpenCV's distortion model with coefficients `k1,k2,p1,p2,k3,k4,k5,k6`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Distortion(pub [f64; 8]);

impl Distortion {
    /// No distortion.
    pub const NONE: Self = Self([0.0; 8]);

    /// The radial factor and its derivative with respect to `r²`.
    fn radial(&self, r2: f64) -> (f64, f64) {
        let k = &self.0;
        let a = 1.0 + ((k[4] * r2 + k[1]) * r2 + k[0]) * r2;
        let b = 1.0 + ((k[7] * r2 + k[6]) * r2 + k[5]) * r2;
        let da = (3.0 * k[4] * r2 + 2.0 * k[1]) * r2 + k[0];
        let db = (3.0 * k[7] * r2 + 2.0 * k[6]) * r2 + k[5];
        (a / b, (da * b - a * db) / (b * b))
    }

    /// Distort normalised image coordinates (`x = X/Z`, `y = Y/Z`), as
    /// `cv2.projectPoints` does.
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let (p1, p2) = (self.0[2], self.0[3]);
        let r2 = x * x + y * y;
        let (g, _) = self.radial(r2);
        (
            x * g + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
            y * g + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
        )
    }

    /// Invert [`Self::distort`] by Newton's method (at most [`MAX_NEWTON_ITERS`]
    /// steps, from the distorted point). `None` when it does not converge to
    /// 1e-12 or the model folds over (non-positive Jacobian) there.
    pub fn undistort(&self, xd: f64, yd: f64) -> Option<(f64, f64)> {
        let (p1, p2) = (self.0[2], self.0[3]);
        let (mut x, mut y) = (xd, yd);
        for _ in 0..MAX_NEWTON_ITERS {
            let (fx, fy) = self.distort(x, y);
            let (ex, ey) = (fx - xd, fy - yd);
            if ex.abs() < 1e-12 && ey.abs() < 1e-12 {
                return Some((x, y));
            }
            let r2 = x * x + y * y;
            let (g, dg) = self.radial(r2);
            let a = g + 2.0 * x * x * dg + 2.0 * p1 * y + 6.0 * p2 * x;
            let b = 2.0 * x * y * dg + 2.0 * p1 * x + 2.0 * p2 * y;
            let d = g + 2.0 * y * y * dg + 6.0 * p1 * y + 2.0 * p2 * x;
            let det = a * d - b * b;
            if !(det > 0.0 && det.is_finite()) {
                return None;
            }
            x -= (d * ex - b * ey) / det;
            y -= (a * ey - b * ex) / det;
        }
        let (fx, fy) = self.distort(x, y);
        ((fx - xd).abs() < 1e-12 && (fy - yd).abs() < 1e-12).then_some((x, y))
    }

    /// OpenCV's `undistortPoints` iteration (fixed point, `iters` steps,
    /// falling back to the distorted point where the radial factor turns
    /// negative). Used where OpenCV itself uses it, to agree with it.
    pub fn undistort_opencv(&self, xd: f64, yd: f64, iters: usize) -> (f64, f64) {
        let k = &self.0;
        let (mut x, mut y) = (xd, yd);
        for _ in 0..iters {
            let r2 = x * x + y * y;
            let icdist = (1.0 + ((k[7] * r2 + k[6]) * r2 + k[5]) * r2)
                / (1.0 + ((k[4] * r2 + k[1]) * r2 + k[0]) * r2);
            if icdist < 0.0 {
                return (xd, yd);
            }
            let dx = 2.0 * k[2] * x * y + k[3] * (r2 + 2.0 * x * x);
            let dy = k[2] * (r2 + 2.0 * y * y) + 2.0 * k[3] * x * y;
            x = (xd - dx) * icdist;
            y = (yd - dy) * icdist;
        }
        (x, y)
    }
}

/// A physical camera: intrinsics (no skew) and distortion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhysicalCamera {
    /// Focal length x, pixels.
    pub fx: f64,
    /// Focal length y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Distortion.
    pub dist: Distortion,
}

impl PhysicalCamera {
    /// From the OpenCV form's camera.
    pub fn from_opencv(c: &OpenCvCamera) -> Self {
        let (fx, fy, cx, cy) = c.intrinsics();
        Self {
            fx,
            fy,
            cx,
            cy,
            dist: Distortion(c.dist8()),
        }
    }

    /// The pixel of a point in the camera frame (`None` behind the camera).
    pub fn project(&self, p: [f64; 3]) -> Option<[f64; 2]> {
        if p[2] <= 0.0 {
            return None;
        }
        let (xd, yd) = self.dist.distort(p[0] / p[2], p[1] / p[2]);
        Some([self.fx * xd + self.cx, self.fy * yd + self.cy])
    }

    /// The normalised undistorted ray `(X/Z, Y/Z)` through pixel `(u, v)`.
    pub fn ray(&self, u: f64, v: f64) -> Option<(f64, f64)> {
        self.dist
            .undistort((u - self.cx) / self.fx, (v - self.cy) / self.fy)
    }
}

/// What [`stereo_rectify`] computes (OpenCV's `R1, R2, P1, P2`) and the core's rig.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rectification {
    /// Rectified-left from physical-left rotation (OpenCV `R1`).
    pub r1: Matrix3<f64>,
    /// Rectified-right from physical-right rotation (OpenCV `R2`).
    pub r2: Matrix3<f64>,
    /// Rectified left projection `[[f,0,cx,0],[0,f,cy,0],[0,0,1,0]]` (OpenCV `P1`).
    pub p1: [[f64; 4]; 3],
    /// Rectified right projection, `P2[0][3] = -f · baseline` (OpenCV `P2`).
    pub p2: [[f64; 4]; 3],
    /// Image width and height (input and rectified).
    pub size: (u32, u32),
    /// Rectified focal length, pixels (`fx = fy`).
    pub f_px: f64,
    /// Rectified principal point, pixels (same for both cameras).
    pub c_px: [f64; 2],
    /// Rectified baseline, metres (the right camera at `+baseline` along x).
    pub baseline_m: f64,
}

impl Rectification {
    /// The core's checked rectified rig.
    ///
    /// # Errors
    /// The core's failure code when a rectified value is out of its range.
    pub fn rig(&self) -> Result<StereoRig, vtsm_core::FailureCode> {
        let cam = Camera::new(
            self.f_px as f32,
            self.f_px as f32,
            self.c_px[0] as f32,
            self.c_px[1] as f32,
            self.size.0,
            self.size.1,
        )?;
        StereoRig::new(cam, self.baseline_m as f32)
    }
}

fn mat(m: &[[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::new(
        m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2], m[2][0], m[2][1], m[2][2],
    )
}

/// Rotation vector (Rodrigues) of a near-orthonormal matrix, after projecting it
/// onto the nearest rotation.
fn rotation_vector(m: &Matrix3<f64>) -> Vector3<f64> {
    let r = Rotation3::from_matrix_eps(m, 1e-15, 100, Rotation3::identity());
    r.scaled_axis()
}

/// `cv2.stereoRectify(K1, d1, K2, d2, size, R, T)` with the default flags
/// (`CALIB_ZERO_DISPARITY`) and `alpha = -1`, for a horizontal pair.
///
/// # Errors
/// A vertical pair (the baseline after the half rotation is more vertical
/// than horizontal) or the right camera on the left.
pub fn stereo_rectify(c: &OpenCvCalib) -> Result<Rectification, String> {
    let r = mat(&c.r);
    let t = Vector3::new(c.t[0], c.t[1], c.t[2]);
    let om = rotation_vector(&r) * -0.5;
    let r_r = Rotation3::new(om).into_inner();
    let th = r_r * t;
    if th.x.abs() <= th.y.abs() {
        return Err("vertical stereo pairs are not supported".into());
    }
    let cval = th.x;
    let nt = th.norm();
    let uu = Vector3::new(if cval > 0.0 { 1.0 } else { -1.0 }, 0.0, 0.0);
    let mut ww = th.cross(&uu);
    let nw = ww.norm();
    if nw > 0.0 {
        ww *= (cval.abs() / nt).clamp(-1.0, 1.0).acos() / nw;
    }
    let wr = Rotation3::new(ww).into_inner();
    let r1 = wr * r_r.transpose();
    let r2 = wr * r_r;
    let t2 = r2 * t;
    if t2.x >= 0.0 {
        return Err("the right camera is not on the +x side of the left camera".into());
    }
    let (w, h) = c.size();
    let (nx, ny) = (f64::from(w), f64::from(h));
    let f = (c.left.k[1][1] + c.right.k[1][1]) * 0.5;
    let mut cc = [[0.0f64; 2]; 2];
    for (k, (cam, rk)) in [(&c.left, &r1), (&c.right, &r2)].into_iter().enumerate() {
        let pc = PhysicalCamera::from_opencv(cam);
        let mut sum = [0.0f64; 2];
        for i in 0..4 {
            // OpenCV holds these points as f32 between its steps.
            let u = f64::from(((i % 2) as f64 * (nx - 1.0)) as f32);
            let v = f64::from(((i / 2) as f64 * (ny - 1.0)) as f32);
            let (x, y) = pc.dist.undistort_opencv(
                (u - pc.cx) / pc.fx,
                (v - pc.cy) / pc.fy,
                OPENCV_UNDISTORT_ITERS,
            );
            let p = rk * Vector3::new(f64::from(x as f32), f64::from(y as f32), 1.0);
            sum[0] += f64::from((f * p.x / p.z) as f32);
            sum[1] += f64::from((f * p.y / p.z) as f32);
        }
        cc[k] = [
            (nx - 1.0) / 2.0 - sum[0] / 4.0,
            (ny - 1.0) / 2.0 - sum[1] / 4.0,
        ];
    }
    let c_px = [(cc[0][0] + cc[1][0]) * 0.5, (cc[0][1] + cc[1][1]) * 0.5];
    let p1 = [
        [f, 0.0, c_px[0], 0.0],
        [0.0, f, c_px[1], 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ];
    let mut p2 = p1;
    p2[0][3] = t2.x * f;
    Ok(Rectification {
        r1,
        r2,
        p1,
        p2,
        size: (w, h),
        f_px: f,
        c_px,
        baseline_m: -t2.x,
    })
}

/// The physical pixel seen by each rectified pixel: the inverse of the rectified
/// pinhole and rotation, then the physical camera's distortion and intrinsics
/// (the arithmetic of `cv2.initUndistortRectifyMap`, in f64, rounded to f32).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapModel {
    /// `(P · R)⁻¹` of the rectified pinhole `P` (3 × 3) and rotation `R`.
    ir: Matrix3<f64>,
    /// The physical camera sampled.
    cam: PhysicalCamera,
}

impl MapModel {
    /// For `cam`, the rectifying rotation `r` and the rectified pinhole `(f, c)`.
    pub fn new(cam: &PhysicalCamera, r: &Matrix3<f64>, f: f64, c: [f64; 2]) -> Self {
        let kp = Matrix3::new(f, 0.0, c[0], 0.0, f, c[1], 0.0, 0.0, 1.0);
        Self {
            ir: (kp * r).try_inverse().unwrap_or_else(Matrix3::identity),
            cam: *cam,
        }
    }

    /// The physical pixel `(x, y)` sampled by rectified pixel `(u, v)`.
    pub fn at(&self, u: u32, v: u32) -> (f32, f32) {
        let q = self.ir * Vector3::new(f64::from(u), f64::from(v), 1.0);
        let (x, y) = (q.x / q.z, q.y / q.z);
        let (xd, yd) = self.cam.dist.distort(x, y);
        (
            (self.cam.fx * xd + self.cam.cx) as f32,
            (self.cam.fy * yd + self.cam.cy) as f32,
        )
    }

    /// Rectify `src` into a `size` image by `interp` without storing the map
    /// (rows in parallel; the same pixels as [`RectifyMap::remap`]).
    pub fn remap(&self, src: &Gray8, size: (u32, u32), interp: Interp) -> Gray8 {
        let w = size.0 as usize;
        let mut pixels = vec![0u8; w * size.1 as usize];
        pixels
            .par_chunks_mut(w.max(1))
            .enumerate()
            .for_each(|(v, row)| {
                for (u, px) in row.iter_mut().enumerate() {
                    let (sx, sy) = self.at(u as u32, v as u32);
                    *px = sample(src, sx, sy, interp);
                }
            });
        Gray8 {
            width: size.0,
            height: size.1,
            pixels,
        }
    }
}

/// The interpolation kernel of a remap, as `cv2.remap`'s flag of that name
/// (also the command-line value of `--interp`, by [`Interp::name`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
#[value(rename_all = "lower")]
pub enum Interp {
    /// `INTER_LINEAR`: 2 × 2 taps, bilinear.
    Linear,
    /// `INTER_CUBIC`: 4 × 4 taps, Keys' cubic convolution with a = −0.75.
    Cubic,
    /// `INTER_LANCZOS4`: 8 × 8 taps, the Lanczos window of order 4,
    /// normalised to unit sum.
    #[default]
    Lanczos4,
}

impl Interp {
    /// Every kernel, cheapest first.
    pub const ALL: [Self; 3] = [Self::Linear, Self::Cubic, Self::Lanczos4];

    /// The name used on the command line and in result files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Linear => "linear",
            Self::Cubic => "cubic",
            Self::Lanczos4 => "lanczos4",
        }
    }

    /// The kernel called `s` ([`Self::name`]).
    ///
    /// # Errors
    /// A message naming the accepted names.
    pub fn parse(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|i| i.name() == s)
            .ok_or_else(|| {
                format!("unknown interpolation {s:?}: expected linear, cubic or lanczos4")
            })
    }
}

/// Keys' cubic convolution weights (a = −0.75, OpenCV's `interpolateCubic`)
/// of the taps at offsets −1, 0, 1, 2 for the fraction `x` in `[0, 1)`.
pub fn cubic_weights(x: f32) -> [f32; 4] {
    const A: f32 = -0.75;
    let w0 = ((A * (x + 1.0) - 5.0 * A) * (x + 1.0) + 8.0 * A) * (x + 1.0) - 4.0 * A;
    let w1 = ((A + 2.0) * x - (A + 3.0)) * x * x + 1.0;
    let w2 = ((A + 2.0) * (1.0 - x) - (A + 3.0)) * (1.0 - x) * (1.0 - x) + 1.0;
    [w0, w1, w2, 1.0 - w0 - w1 - w2]
}

/// Lanczos-4 weights (OpenCV's `interpolateLanczos4`) of the taps at offsets
/// −3 … 4 for the fraction `x` in `[0, 1)`, normalised to unit sum; `x = 0`
/// gives the unit impulse at offset 0.
pub fn lanczos4_weights(x: f32) -> [f32; 8] {
    let mut w = [0.0f32; 8];
    if x < f32::EPSILON {
        w[3] = 1.0;
        return w;
    }
    let x = f64::from(x);
    let mut sum = 0.0f64;
    for (i, wi) in w.iter_mut().enumerate() {
        // sinc(d) · sinc(d / 4) at the tap's distance d, π-scaled.
        let d = (x + 3.0 - i as f64) * core::f64::consts::PI;
        let v = 4.0 * (d).sin() * (d / 4.0).sin() / (d * d);
        *wi = v as f32;
        sum += v;
    }
    let inv = (1.0 / sum) as f32;
    for wi in &mut w {
        *wi *= inv;
    }
    w
}

/// Sample of `src` at `(sx, sy)` by `interp`; taps outside `src` count as 0
/// (OpenCV's `BORDER_CONSTANT`), so a position wholly outside gives 0, and the
/// result is rounded to the nearest gray level and saturated.
fn sample(src: &Gray8, sx: f32, sy: f32, interp: Interp) -> u8 {
    // Beyond 8 pixels outside the image every kernel reads only the border
    // (and the integer tap positions below stay far from overflow); this
    // also catches NaN.
    let inside = |p: f32, n: u32| p > -8.0 && p < n as f32 + 8.0;
    if !(inside(sx, src.width) && inside(sy, src.height)) {
        return 0;
    }
    match interp {
        Interp::Linear => sample_linear(src, sx, sy),
        Interp::Cubic => {
            let (fx, fy) = (sx.floor(), sy.floor());
            let (wx, wy) = (cubic_weights(sx - fx), cubic_weights(sy - fy));
            sample_separable(src, fx as i64 - 1, fy as i64 - 1, &wx, &wy)
        }
        Interp::Lanczos4 => {
            let (fx, fy) = (sx.floor(), sy.floor());
            let (wx, wy) = (lanczos4_weights(sx - fx), lanczos4_weights(sy - fy));
            sample_separable(src, fx as i64 - 3, fy as i64 - 3, &wx, &wy)
        }
    }
}

/// `Σ_j wy[j] Σ_i wx[i] src(x0 + i, y0 + j)` over the taps inside `src`,
/// rounded and saturated to a gray level.
fn sample_separable<const N: usize>(
    src: &Gray8,
    x0: i64,
    y0: i64,
    wx: &[f32; N],
    wy: &[f32; N],
) -> u8 {
    let (sw, sh) = (i64::from(src.width), i64::from(src.height));
    let mut acc = 0.0f32;
    for (j, &wyj) in wy.iter().enumerate() {
        let y = y0.saturating_add(j as i64);
        if y < 0 || y >= sh {
            continue;
        }
        let row = &src.pixels[(y * sw) as usize..][..sw as usize];
        let mut r = 0.0f32;
        for (i, &wxi) in wx.iter().enumerate() {
            let x = x0.saturating_add(i as i64);
            if x >= 0 && x < sw {
                r += wxi * f32::from(row[x as usize]);
            }
        }
        acc += wyj * r;
    }
    (acc + 0.5).floor().clamp(0.0, 255.0) as u8
}

/// Bilinear sample of `src` at finite `(sx, sy)` (exact weights).
fn sample_linear(src: &Gray8, sx: f32, sy: f32) -> u8 {
    let (sw, sh) = (i64::from(src.width), i64::from(src.height));
    let px = |x: i64, y: i64| -> f32 {
        if x < 0 || y < 0 || x >= sw || y >= sh {
            0.0
        } else {
            f32::from(src.pixels.get((y * sw + x) as usize).copied().unwrap_or(0))
        }
    };
    let (fx, fy) = (sx.floor(), sy.floor());
    let (x0, y0) = (fx as i64, fy as i64);
    let (ax, ay) = (sx - fx, sy - fy);
    let top = px(x0, y0) * (1.0 - ax) + px(x0 + 1, y0) * ax;
    let bot = px(x0, y0 + 1) * (1.0 - ax) + px(x0 + 1, y0 + 1) * ax;
    let v = top * (1.0 - ay) + bot * ay;
    (v + 0.5).floor().clamp(0.0, 255.0) as u8
}

/// The stored lookup of `cv2.initUndistortRectifyMap` (`CV_32FC1`): for each
/// rectified pixel, the physical pixel it samples.
#[derive(Clone, Debug, PartialEq)]
pub struct RectifyMap {
    /// Width of the rectified image.
    pub width: u32,
    /// Height of the rectified image.
    pub height: u32,
    /// Physical x per rectified pixel, row-major.
    pub map_x: Vec<f32>,
    /// Physical y per rectified pixel, row-major.
    pub map_y: Vec<f32>,
}

impl RectifyMap {
    /// The map of `model` over a `size` rectified image.
    pub fn new(model: &MapModel, size: (u32, u32)) -> Self {
        let n = size.0 as usize * size.1 as usize;
        let (mut map_x, mut map_y) = (Vec::with_capacity(n), Vec::with_capacity(n));
        for v in 0..size.1 {
            for u in 0..size.0 {
                let (x, y) = model.at(u, v);
                map_x.push(x);
                map_y.push(y);
            }
        }
        Self {
            width: size.0,
            height: size.1,
            map_x,
            map_y,
        }
    }

    /// Sample `src` through the map by `interp`, with a 0 border.
    pub fn remap(&self, src: &Gray8, interp: Interp) -> Gray8 {
        let pixels = self
            .map_x
            .iter()
            .zip(&self.map_y)
            .map(|(&sx, &sy)| sample(src, sx, sy, interp))
            .collect();
        Gray8 {
            width: self.width,
            height: self.height,
            pixels,
        }
    }
}

/// Rectification of one physical rig: the map models of both cameras, the
/// core's rig and the pose conversions between the physical and rectified left
/// cameras. Holds no per-pixel map (a paper-size map pair would be 320 MB).
#[derive(Clone, Debug, PartialEq)]
pub struct Rectifier {
    /// `R1`, `R2`, `P1`, `P2` and the rectified pinhole.
    pub rect: Rectification,
    /// The core's rectified rig.
    pub rig: StereoRig,
    /// Map model of the left camera.
    pub left: MapModel,
    /// Map model of the right camera.
    pub right: MapModel,
    /// Physical-left from rectified-left (`R1ᵀ`), as a core pose (no translation).
    pub phys_from_rect: Pose,
    /// Kernel of the image remap ([`Interp::default`] unless chosen).
    pub interp: Interp,
}

impl Rectifier {
    /// Rectify `c`.
    ///
    /// # Errors
    /// As [`stereo_rectify`], or a rectified rig the core refuses.
    pub fn new(c: &OpenCvCalib) -> Result<Self, String> {
        let rect = stereo_rectify(c)?;
        let rig = rect
            .rig()
            .map_err(|e| format!("rectified rig rejected: {}", e.description()))?;
        let left = MapModel::new(
            &PhysicalCamera::from_opencv(&c.left),
            &rect.r1,
            rect.f_px,
            rect.c_px,
        );
        let right = MapModel::new(
            &PhysicalCamera::from_opencv(&c.right),
            &rect.r2,
            rect.f_px,
            rect.c_px,
        );
        let rt =
            Rotation3::from_matrix_eps(&rect.r1.transpose(), 1e-15, 100, Rotation3::identity());
        let q = UnitQuaternion::from_rotation_matrix(&rt);
        let q32 = UnitQuaternion::new_normalize(q.into_inner().cast::<f32>());
        Ok(Self {
            rect,
            rig,
            left,
            right,
            phys_from_rect: Pose::new(q32, Vec3::zeros()),
            interp: Interp::default(),
        })
    }

    /// The same rectifier remapping images by `interp`.
    pub fn with_interp(self, interp: Interp) -> Self {
        Self { interp, ..self }
    }

    /// The stored maps of both cameras (as `cv2.initUndistortRectifyMap`).
    pub fn maps(&self) -> (RectifyMap, RectifyMap) {
        (
            RectifyMap::new(&self.left, self.rect.size),
            RectifyMap::new(&self.right, self.rect.size),
        )
    }

    /// The rectified pair as the rectified form of `calib.json` (`fx = fy`, the
    /// baseline along +x).
    pub fn calib(&self) -> crate::io::json::Calib {
        let c = self.rig.cam();
        crate::io::json::Calib {
            width: c.width(),
            height: c.height(),
            fx: f64::from(c.fx()),
            fy: f64::from(c.fy()),
            cx: f64::from(c.cx()),
            cy: f64::from(c.cy()),
            baseline_m: f64::from(self.rig.baseline_m()),
        }
    }

    /// Rectify a physical pair (each image of the calibration's size).
    pub fn rectify_pair(&self, left: &Gray8, right: &Gray8) -> (Gray8, Gray8) {
        (
            self.left.remap(left, self.rect.size, self.interp),
            self.right.remap(right, self.rect.size, self.interp),
        )
    }

    /// What the core is given for a physical pair: both images rectified and
    /// the prior `world_from_left` of the physical left camera turned to the
    /// rectified one ([`Self::rectify_pair`], [`Self::to_rectified`]). The
    /// core's estimate comes back through [`Self::to_physical`].
    pub fn rectify_input(
        &self,
        left: &Gray8,
        right: &Gray8,
        world_from_phys: &Pose,
    ) -> (Gray8, Gray8, Pose) {
        let (l, r) = self.rectify_pair(left, right);
        (l, r, self.to_rectified(world_from_phys))
    }

    /// `world_from_left` of the rectified left camera, from the physical one's.
    pub fn to_rectified(&self, world_from_phys: &Pose) -> Pose {
        world_from_phys.compose(&self.phys_from_rect)
    }

    /// `world_from_left` of the physical left camera, from the rectified one's.
    pub fn to_physical(&self, world_from_rect: &Pose) -> Pose {
        world_from_rect.compose(&self.phys_from_rect.inverse())
    }
}

#[cfg(test)]
mod tests;
