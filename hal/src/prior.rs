//! Pose prior: the visual-inertial odometry estimate the relocalization starts from.
//!
//! Output: [`PriorEstimate`] = `world_from_left` pose, its covariance (full 6×6
//! or diagonal), optionally the half-widths of the region the true pose lies
//! in ([`PriorUncertainty`], the paper's t̃₀, r̃₀, which the runner hands to the
//! engine), and the time it refers to. [`PriorEstimate::check`] rejects
//! non-finite poses, covariances that are not symmetric with a non-negative
//! diagonal, and half-widths outside the engine's ranges. Fixed-size, no loops
//! beyond 6×6.

use crate::error::ErrorType;
pub use vtsm_core::config::PriorUncertainty;
use vtsm_core::geom::Pose;
use vtsm_core::FailureCode;

/// Covariance of a pose prior. Order of the six components: translation x, y, z
/// in metres (world frame), then rotation about x, y, z in radians (small
/// angles, world frame). Units: m², m·rad, rad².
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Covariance {
    /// A full symmetric 6×6 matrix, row-major.
    Full([[f32; 6]; 6]),
    /// Variances only (the off-diagonal terms are zero).
    Diagonal([f32; 6]),
}

impl Covariance {
    /// Variance of component `i` (0..6), `None` if `i` is out of range.
    pub fn variance(&self, i: usize) -> Option<f32> {
        match self {
            Covariance::Full(m) => m.get(i).and_then(|r| r.get(i)).copied(),
            Covariance::Diagonal(d) => d.get(i).copied(),
        }
    }

    /// Whether every entry is finite, the diagonal is non-negative and a full
    /// matrix is symmetric (to a relative 1e-5).
    pub fn is_valid(&self) -> bool {
        match self {
            Covariance::Diagonal(d) => d.iter().all(|v| v.is_finite() && *v >= 0.0),
            Covariance::Full(m) => {
                let mut ok = true;
                for (i, row) in m.iter().enumerate() {
                    for (j, a) in row.iter().enumerate() {
                        let b = m.get(j).and_then(|r| r.get(i)).copied().unwrap_or(f32::NAN);
                        let tol = 1e-5 * (a.abs() + b.abs()) + f32::MIN_POSITIVE;
                        ok &= a.is_finite() && (a - b).abs() <= tol;
                        if i == j {
                            ok &= *a >= 0.0;
                        }
                    }
                }
                ok
            }
        }
    }
}

/// One pose-prior estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PriorEstimate {
    /// Estimated pose of the left camera in the world (`p_world = R p_cam + t`).
    pub world_from_left: Pose,
    /// Uncertainty of that pose.
    pub covariance: Covariance,
    /// Half-widths of the region the true pose lies in around
    /// `world_from_left`, when the source states them: the runner builds the
    /// engine with them as t̃₀, r̃₀ ([`vtsm_core::config::Params::with_uncertainty`]).
    /// `None`: the caller's parameters keep their own t̃₀, r̃₀.
    pub uncertainty: Option<PriorUncertainty>,
    /// Time the estimate refers to, in ticks of the system [`crate::Clock`].
    pub timestamp_ticks: u64,
}

impl PriorEstimate {
    /// Reject a non-finite pose, an invalid covariance or stated half-widths
    /// outside the engine's ranges ([`PriorUncertainty::validate`]) with
    /// [`FailureCode::HalPriorInvalid`].
    pub fn check(&self) -> Result<(), FailureCode> {
        let bounds_ok = self.uncertainty.is_none_or(|u| u.validate().is_ok());
        if self.world_from_left.is_finite() && self.covariance.is_valid() && bounds_ok {
            Ok(())
        } else {
            Err(FailureCode::HalPriorInvalid)
        }
    }
}

/// A source of pose priors (VIO, wheel odometry, ground update).
pub trait PosePrior: ErrorType {
    /// The most recent estimate.
    ///
    /// # Contract
    /// * Does not block. If there is no estimate yet, returns kind
    ///   [`Unavailable`](crate::ErrorKind::Unavailable).
    /// * Timestamps of successive estimates never decrease.
    /// * The estimate is not trusted by the caller: it is checked with
    ///   [`PriorEstimate::check`] before use.
    fn latest(&mut self) -> Result<PriorEstimate, Self::Error>;
}

impl<T: PosePrior + ?Sized> PosePrior for &mut T {
    fn latest(&mut self) -> Result<PriorEstimate, Self::Error> {
        T::latest(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Verifies: VTSM-HAL-004
    #[test]
    fn prior_check_rejects_bad_pose_and_covariance() {
        let pose = Pose::from_t_q([1.0, 2.0, 0.5], [1.0, 0.0, 0.0, 0.0]).unwrap();
        let mut full = [[0.0f32; 6]; 6];
        for (i, row) in full.iter_mut().enumerate() {
            row[i] = 0.01;
        }
        full[0][1] = 0.002;
        full[1][0] = 0.002;
        let good = PriorEstimate {
            world_from_left: pose,
            covariance: Covariance::Full(full),
            uncertainty: None,
            timestamp_ticks: 5,
        };
        assert_eq!(good.check(), Ok(()));
        assert_eq!(good.covariance.variance(1), Some(0.01));
        assert_eq!(good.covariance.variance(6), None);

        let mut asym = full;
        asym[0][1] = 0.003;
        let mut neg = full;
        neg[4][4] = -0.01;
        let mut nan = full;
        nan[2][3] = f32::NAN;
        nan[3][2] = f32::NAN;
        for c in [
            Covariance::Full(asym),
            Covariance::Full(neg),
            Covariance::Full(nan),
            Covariance::Diagonal([0.1, 0.1, -0.1, 0.0, 0.0, 0.0]),
            Covariance::Diagonal([0.1, 0.1, 0.1, f32::INFINITY, 0.0, 0.0]),
        ] {
            let p = PriorEstimate {
                covariance: c,
                ..good
            };
            assert_eq!(p.check(), Err(FailureCode::HalPriorInvalid), "{c:?}");
        }
        assert!(Covariance::Diagonal([0.0; 6]).is_valid());
    }

    /// Verifies: VTSM-HAL-026
    #[test]
    fn prior_check_rejects_half_widths_outside_the_engine_ranges() {
        let good = PriorEstimate {
            world_from_left: Pose::identity(),
            covariance: Covariance::Diagonal([0.25, 0.25, 0.25, 1e-3, 1e-3, 1e-3]),
            uncertainty: Some(PriorUncertainty {
                t_m: 0.5,
                r_deg: 1.5,
            }),
            timestamp_ticks: 0,
        };
        assert_eq!(good.check(), Ok(()));
        for (t_m, r_deg) in [
            (0.0, 1.5),
            (-0.5, 1.5),
            (f32::NAN, 1.5),
            (vtsm_core::config::MAX_T0_M + 0.01, 1.5),
            (0.5, 0.0),
            (0.5, f32::INFINITY),
            (0.5, vtsm_core::config::MAX_R0_DEG + 0.01),
        ] {
            let p = PriorEstimate {
                uncertainty: Some(PriorUncertainty { t_m, r_deg }),
                ..good
            };
            assert_eq!(
                p.check(),
                Err(FailureCode::HalPriorInvalid),
                "{t_m} {r_deg}"
            );
        }
    }
}
