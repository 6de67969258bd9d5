//! The physical stereo pair every calibration form becomes: the OpenCV
//! stereo model ([`OpenCvCalib`], `X_right = R · X_left + T`, two cameras of
//! intrinsic matrix and distortion), and the checks that refuse what the
//! rectifier ([`crate::rectify`]) and the core cannot use, naming the field
//! ([`OpenCvCalib::validate`]).

use crate::io::json::short_number;
use serde::{Deserialize, Serialize};
use vtsm_core::geom;

/// Largest accepted deviation of `RᵀR` from the identity (any element) and of
/// `det R` from 1.
pub const ROTATION_TOL: f64 = 1.0e-5;
/// Largest accepted angle, degrees, between the right camera's centre seen from
/// the left camera and the left camera's +x axis (the core needs a horizontal
/// pair with the right camera on the right).
pub const MAX_BASELINE_TILT_DEG: f64 = 20.0;
/// Largest accepted baseline, metres.
pub const MAX_BASELINE_M: f64 = 100.0;
/// Largest accepted magnitude of a distortion coefficient.
pub const MAX_DIST_COEFF: f64 = 1.0e3;

/// One camera of the OpenCV form: intrinsic matrix and distortion coefficients.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OpenCvCamera {
    /// Intrinsic matrix `[[fx,0,cx],[0,fy,cy],[0,0,1]]`, pixels (pixel-centre
    /// convention, as OpenCV).
    #[serde(rename = "K")]
    pub k: [[f64; 3]; 3],
    /// Distortion `k1,k2,p1,p2[,k3[,k4,k5,k6]]`.
    pub dist: Vec<f64>,
}

impl OpenCvCamera {
    /// `(fx, fy, cx, cy)`.
    pub fn intrinsics(&self) -> (f64, f64, f64, f64) {
        (self.k[0][0], self.k[1][1], self.k[0][2], self.k[1][2])
    }

    /// The 8 coefficients `k1,k2,p1,p2,k3,k4,k5,k6` (missing ones are 0).
    pub fn dist8(&self) -> [f64; 8] {
        let mut d = [0.0; 8];
        for (o, v) in d.iter_mut().zip(&self.dist) {
            *o = *v;
        }
        d
    }
}

/// `calib.json` in the OpenCV stereo form.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OpenCvCalib {
    /// `[width, height]`, pixels, of both cameras.
    pub image_size: [u32; 2],
    /// Left camera.
    pub left: OpenCvCamera,
    /// Right camera.
    pub right: OpenCvCamera,
    /// Rotation of `X_right = R · X_left + T`.
    #[serde(rename = "R")]
    pub r: [[f64; 3]; 3],
    /// Translation of `X_right = R · X_left + T`, metres.
    #[serde(rename = "T")]
    pub t: [f64; 3],
}

fn mat_ok(m: &[[f64; 3]; 3]) -> bool {
    m.iter().flatten().all(|v| v.is_finite())
}

impl OpenCvCamera {
    fn validate(&self, side: &'static str) -> std::result::Result<(), (String, String)> {
        let field = |f: &str| format!("{side}.{f}");
        if !mat_ok(&self.k) {
            return Err((field("K"), "has a non-finite element".into()));
        }
        let k = &self.k;
        if k[1][0] != 0.0 || k[2][0] != 0.0 || k[2][1] != 0.0 || k[2][2] != 1.0 {
            return Err((
                field("K"),
                "must be [[fx,0,cx],[0,fy,cy],[0,0,1]] (last row 0,0,1; K[1][0] = 0)".into(),
            ));
        }
        if k[0][1] != 0.0 {
            return Err((
                field("K"),
                format!("skew K[0][1] = {} is not supported", short_number(k[0][1])),
            ));
        }
        let (fx, fy, cx, cy) = self.intrinsics();
        for (name, f) in [("fx", fx), ("fy", fy)] {
            if !geom::focal_px_ok(f as f32) {
                return Err((
                    field("K"),
                    format!(
                        "{name} = {} px is outside the accepted focal length range (0, {}] px",
                        short_number(f),
                        short_number(f64::from(geom::MAX_FOCAL_PX))
                    ),
                ));
            }
        }
        for (name, c) in [("cx", cx), ("cy", cy)] {
            if !geom::principal_px_ok(c as f32) {
                return Err((
                    field("K"),
                    format!(
                        "{name} = {} px is outside the accepted principal point range ±{} px",
                        short_number(c),
                        short_number(f64::from(geom::MAX_PRINCIPAL_PX))
                    ),
                ));
            }
        }
        if ![4, 5, 8].contains(&self.dist.len()) {
            return Err((
                field("dist"),
                format!(
                    "has {} coefficients; give 4 (k1,k2,p1,p2), 5 (+k3) or 8 (+k4,k5,k6)",
                    self.dist.len()
                ),
            ));
        }
        if let Some(v) = self
            .dist
            .iter()
            .find(|v| !(v.is_finite() && v.abs() <= MAX_DIST_COEFF))
        {
            return Err((
                field("dist"),
                format!(
                    "coefficient {} is not finite or exceeds {} in magnitude",
                    short_number(*v),
                    short_number(MAX_DIST_COEFF)
                ),
            ));
        }
        Ok(())
    }
}

impl OpenCvCalib {
    /// Width, height.
    pub fn size(&self) -> (u32, u32) {
        (self.image_size[0], self.image_size[1])
    }

    /// Check every field; returns the dotted name of the bad field and why.
    pub fn validate(&self) -> std::result::Result<(), (String, String)> {
        for (i, v) in self.image_size.iter().enumerate() {
            if !geom::image_dim_ok(*v) {
                return Err((
                    "image_size".into(),
                    format!(
                        "{} {v} is outside 1..={}",
                        ["width", "height"][i],
                        vtsm_core::config::MAX_IMAGE_DIM
                    ),
                ));
            }
        }
        self.left.validate("left")?;
        self.right.validate("right")?;
        let r = &self.r;
        if !mat_ok(r) {
            return Err(("R".into(), "has a non-finite element".into()));
        }
        for i in 0..3 {
            for j in 0..3 {
                let dot: f64 = (0..3).map(|k| r[k][i] * r[k][j]).sum();
                let want = if i == j { 1.0 } else { 0.0 };
                if (dot - want).abs() > ROTATION_TOL {
                    return Err((
                        "R".into(),
                        format!(
                            "is not orthonormal (RᵀR deviates from I by more than {ROTATION_TOL})"
                        ),
                    ));
                }
            }
        }
        let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
            - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
            + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
        if (det - 1.0).abs() > ROTATION_TOL {
            return Err((
                "R".into(),
                format!("has determinant {det:.6}, not 1 (a reflection?)"),
            ));
        }
        let t = &self.t;
        if !t.iter().all(|v| v.is_finite()) {
            return Err(("T".into(), "has a non-finite element".into()));
        }
        let n = t.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !(n > 1.0e-6 && n <= MAX_BASELINE_M) {
            return Err((
                "T".into(),
                format!(
                    "baseline |T| = {} m must be in (1e-6, {MAX_BASELINE_M}] m",
                    short_number(n)
                ),
            ));
        }
        // Centre of the right camera in the left frame: c = -Rᵀ T.
        let cx: f64 = -(0..3).map(|k| r[k][0] * t[k]).sum::<f64>();
        let cos = cx / n;
        if cos < MAX_BASELINE_TILT_DEG.to_radians().cos() {
            return Err((
                "T".into(),
                format!(
                    "the right camera is {:.1}° away from the left camera's +x axis \
                     (at most {MAX_BASELINE_TILT_DEG}°: a horizontal pair, right camera on the right)",
                    cos.clamp(-1.0, 1.0).acos().to_degrees()
                ),
            ));
        }
        Ok(())
    }
}
