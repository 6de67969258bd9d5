//! One trial: the group's frames at capture `k`, a prior drawn with the
//! trial's seed, one relocalization, its error measured to the truth.

use super::config::{Method, SuiteConfig};
use super::covariance::covariance_check;
use super::depot::Depot;
use super::frames::{live_frames, LiveFrames};
use super::group::Group;
use super::maps::MapEntry;
use super::protocol::{capture_for_trial, nearest_view, trial_seed, CAMERA_SEED};
use crate::eval::columns::{
    CaptureColumns, EngineColumns, FeatureColumns, TrialColumns, VerifyColumns, ViewColumns,
};
use crate::eval::TrialOutcome;
use crate::io::image::Gray8;
use crate::locate::{self, Request, RunOptions};
use crate::rectify::Rectifier;
use crate::scene::STOPS_PER_CIRCLE;
use vtsm_core::geom::{Pose, StereoRig, Vec3};
use vtsm_core::map::MapView;
use vtsm_core::FailureCode;

/// Trial `k` of a group.
#[derive(Clone, Copy)]
pub struct Spec {
    /// Group index.
    pub group: usize,
    /// Trial index within the group.
    pub k: usize,
}

/// Everything a trial reads, shared by all trials.
pub struct Shared<'a> {
    /// The run's settings.
    pub cfg: &'a SuiteConfig,
    /// The groups.
    pub groups: &'a [Group],
    /// The depots.
    pub depot: &'a Depot,
    /// The map products.
    pub maps: &'a [MapEntry],
}

/// Where the errors are measured: the truth, in the offset (user) frame
/// under `--origin` or for a data set's pair, estimates coming back from the
/// map's local frame; no truth (a data set's pair without `truth.json`):
/// every error is NaN and no covariance is checked.
pub(super) struct ErrorFrame {
    truth: Option<Pose>,
    truth_user: Option<crate::frame::UserPose>,
    map_origin: [f64; 3],
}

impl ErrorFrame {
    fn new(truth: Pose, origin: Option<[f64; 3]>, map_origin: [f64; 3]) -> Self {
        let truth_user =
            origin.map(|o| crate::frame::offset(&crate::frame::to_user(&truth, [0.0; 3]), o));
        Self {
            truth: Some(truth),
            truth_user,
            map_origin,
        }
    }

    /// The truth `truth` in the user frame of a map whose origin is
    /// `map_origin`, and `local` the same pose in the map's local frame (for
    /// the covariance check); without a truth, no errors.
    pub(super) fn user(
        truth: Option<(crate::frame::UserPose, Pose)>,
        map_origin: [f64; 3],
    ) -> Self {
        Self {
            truth: truth.as_ref().map(|t| t.1),
            truth_user: truth.map(|t| t.0),
            map_origin,
        }
    }

    /// The truth in the map's local frame (the simulator's suites: the
    /// frame the engine works in), `None` without one.
    pub(super) fn local_truth(&self) -> Option<Pose> {
        self.truth
    }

    /// Translation (m) and rotation (rad) error of `est` (NaN without a truth).
    pub(super) fn error(&self, est: &Pose) -> (f64, f64) {
        match (&self.truth_user, &self.truth) {
            (Some(tu), _) => {
                crate::frame::error_to(&crate::frame::to_user(est, self.map_origin), tu)
            }
            (None, Some(t)) => {
                let (t, r) = est.error_to(t);
                (f64::from(t), f64::from(r))
            }
            (None, None) => (f64::NAN, f64::NAN),
        }
    }

    /// The covariance check of `est` against the truth, if there is one.
    fn covariance(
        &self,
        est: &Pose,
        c: &vtsm_core::pose::Covariance,
    ) -> Option<crate::eval::columns::CovarianceColumns> {
        self.truth.as_ref().map(|t| covariance_check(est, t, c))
    }
}

/// The images, rig and prior the relocalizer sees, and the rectifier that
/// turns its estimate back to the physical camera (physical frames only).
pub(super) struct Inputs {
    pub(super) rig: StereoRig,
    pub(super) left: Vec<u8>,
    pub(super) right: Vec<u8>,
    pub(super) prior: Pose,
    pub(super) rectifier: Option<Rectifier>,
}

impl Inputs {
    pub(super) fn as_physical(&self, est: &Pose) -> Pose {
        self.rectifier.as_ref().map_or(*est, |r| r.to_physical(est))
    }
}

/// Run one trial.
pub fn run_trial(sh: &Shared<'_>, s: &Spec) -> TrialOutcome {
    let (cfg, g) = (sh.cfg, &sh.groups[s.group]);
    let map = &sh.maps[g.map];
    let seed = trial_seed(cfg.seed, s.k);
    let capture = capture_for_trial(s.k, cfg.trials, g.baseline_m);
    let live = live_frames(cfg.physical, g, sh.depot, &capture, seed);
    let frame = ErrorFrame::new(live.truth, cfg.origin, map.origin);
    let (prior, prior_rejected) = prior_in_map_frame(live.prior, cfg.origin, map.origin);
    let (t0, r0) = frame.error(&prior);
    let columns = TrialColumns {
        group: Some(g.columns),
        capture: Some(CaptureColumns {
            stop: capture.circle * STOPS_PER_CIRCLE + capture.stop,
            look_at: capture.look_at,
        }),
        view: nearest_view(&live.truth, &map.views)
            .map(|(dist_m, angle_deg)| ViewColumns { dist_m, angle_deg }),
        ..TrialColumns::default()
    };
    let mut o = TrialOutcome {
        group: g.label.clone(),
        method: g.method.name().to_string(),
        trial: s.k,
        seed,
        success: false,
        failure: None,
        init_t_mm: t0 * 1e3,
        init_r_deg: r0.to_degrees(),
        final_t_mm: t0 * 1e3,
        final_r_deg: r0.to_degrees(),
        inliers: 0,
        iterations: 0,
        time_s: 0.0,
        columns,
    };
    let bytes = match &map.bytes {
        Ok(b) => b,
        Err(e) => {
            o.failure = Some(format!("map: {e}"));
            return o;
        }
    };
    if let Some(c) = prior_rejected {
        o.failure = Some(format!("prior in the map's frame: {}", c.name()));
        return o;
    }
    // The live camera's effects (the group's, else the run's `--camera`), on
    // the frames as the camera delivers them (before any rectification).
    let camera = if g.camera.is_none() {
        cfg.camera
    } else {
        g.camera
    };
    let live = match camera.apply(&live.pair, seed ^ CAMERA_SEED) {
        Ok(pair) => LiveFrames { pair, ..live },
        Err(e) => {
            o.failure = Some(format!("camera effects: {e}"));
            return o;
        }
    };
    let inputs = match inputs(cfg, live, prior) {
        Ok(i) => i,
        Err(e) => {
            o.failure = Some(format!("rectification: {e}"));
            return o;
        }
    };
    // The trial's one check of the map product; the runner uses the view.
    let view = match MapView::new_checked(bytes) {
        Ok(v) => v,
        Err(c) => {
            o.failure = Some(format!("map: {}", c.name()));
            return o;
        }
    };
    let req = request(cfg, g, view, &inputs, seed);
    match g.method {
        Method::Features => run_features(&mut o, &req, &inputs, &frame),
        Method::Vtsm => {
            let deciles = (cfg.score_deciles && inputs.rectifier.is_none() && cfg.origin.is_none())
                .then_some(map.deciles.as_slice());
            run_vtsm(&mut o, cfg, &req, &inputs, &frame, deciles);
        }
    }
    o
}

/// With `--origin`: the prior (drawn in the simulator's frame) turned into the
/// map's local frame through the offset frame in f64, and why not when it
/// does not fit in f32 there; the rotation is the same in every frame, so it
/// is kept as is (no renormalisation).
fn prior_in_map_frame(
    prior: Pose,
    origin: Option<[f64; 3]>,
    map_origin: [f64; 3],
) -> (Pose, Option<FailureCode>) {
    let Some(o) = origin else {
        return (prior, None);
    };
    let user = crate::io::json::PoseJson::from_local(&prior, o);
    let t = [0, 1, 2].map(|k| (user.t[k] - map_origin[k]) as f32);
    if t.iter().all(|c| c.is_finite()) {
        (
            Pose::new(prior.rotation(), Vec3::new(t[0], t[1], t[2])),
            None,
        )
    } else {
        (prior, Some(FailureCode::MapOriginOutOfRange))
    }
}

/// The relocalizer's inputs. A physical pair goes through `vtsm relocalize`'s
/// path for an OpenCV calibration: rectified on the host, the prior turned to
/// the rectified left camera (the estimate is turned back by
/// [`Inputs::as_physical`]).
fn inputs(cfg: &SuiteConfig, live: LiveFrames, prior: Pose) -> Result<Inputs, String> {
    let rectifier = live
        .calib
        .as_ref()
        .map(|c| Rectifier::new(c).map(|r| r.with_interp(cfg.interp)))
        .transpose()
        .map_err(|e| e.to_string())?;
    let pair = live.pair;
    Ok(match rectifier {
        Some(r) => {
            let gray = |pixels| Gray8 {
                width: pair.width,
                height: pair.height,
                pixels,
            };
            let (l, rr, p) = r.rectify_input(&gray(pair.left), &gray(pair.right), &prior);
            Inputs {
                rig: r.rig,
                left: l.pixels,
                right: rr.pixels,
                prior: p,
                rectifier: Some(r),
            }
        }
        None => Inputs {
            rig: live.rig,
            left: pair.left,
            right: pair.right,
            prior,
            rectifier: None,
        },
    })
}

/// The relocalization request of a trial of group `g`: the profile's
/// parameters with the group's seeds K (and small parameters).
pub(super) fn request<'a>(
    cfg: &SuiteConfig,
    g: &Group,
    map: MapView<'a>,
    inputs: &'a Inputs,
    seed: u64,
) -> Request<'a> {
    let mut params = locate::params_for_width(inputs.rig.cam().width());
    params.seeds = g.seeds;
    if g.small {
        params.n_corr = 27;
        params.n_iter = 1;
        params.max_reseed = 3;
    }
    Request::new(map, &inputs.left, &inputs.right, inputs.rig, inputs.prior)
        .with_uncertainty(g.uncertainty)
        .with_params(params)
        .with_seed(seed)
        .with_verify(cfg.verify)
        .with_accuracy(cfg.accuracy)
        .with_final_pairs(cfg.final_pairs)
        .with_search(cfg.search)
}

/// The local-feature baseline on the same request.
pub(super) fn run_features(
    o: &mut TrialOutcome,
    req: &Request<'_>,
    inputs: &Inputs,
    frame: &ErrorFrame,
) {
    let fp = crate::features::FeatureParams::for_width(inputs.rig.cam().width());
    match crate::features::relocalize_features(req, &fp) {
        Ok(r) => {
            let (t1, r1) = frame.error(&inputs.as_physical(&r.pose));
            o.success = r.failure.is_none();
            o.failure = r.failure;
            o.final_t_mm = t1 * 1e3;
            o.final_r_deg = r1.to_degrees();
            o.inliers = r.inliers;
            o.iterations = r.iterations;
            o.time_s = r.elapsed.as_secs_f64();
            o.columns.features = Some(FeatureColumns {
                map_keypoints: r.map_keypoints,
                live_keypoints: r.live_keypoints,
                matches: r.matches,
                stereo_points: r.stereo_points,
            });
        }
        Err(e) => o.failure = Some(format!("error: {e}")),
    }
}

/// The paper's method: the core's engine through the runner; the final
/// estimate of the core's (rectified) left camera and the template size ℓ,
/// unless the request was refused. With `deciles` (each mask vertex's score
/// decile; frames without rectification), every attempt is counted in its
/// vertex's decile, and as correct when its correspondence is within
/// `max(3σ, 1 cm)` of the truth.
pub(super) fn run_vtsm(
    o: &mut TrialOutcome,
    cfg: &SuiteConfig,
    req: &Request<'_>,
    inputs: &Inputs,
    frame: &ErrorFrame,
    deciles: Option<&[u8]>,
) -> Option<(Pose, u16)> {
    let mut counts = crate::eval::columns::ScoreColumns::default();
    let mut variants = crate::eval::columns::VariantColumns::default();
    let truth = frame.local_truth();
    let mut count = |s: crate::workers::SampleRecord| {
        // Whether the attempt gave a correspondence within max(3σ, 1 cm)
        // of the vertex's true position in the camera.
        let correct = match (&s.result, truth) {
            (Ok(c), Some(t)) => {
                let want = t.inverse().transform_point(&c.world);
                (c.cam - want).norm() <= (3.0 * c.sigma_m).max(0.01)
            }
            _ => false,
        };
        if let Ok(c) = &s.result {
            let v = usize::from(c.variant);
            if let (Some(a), Some(r)) = (variants.accepted.get_mut(v), variants.correct.get_mut(v))
            {
                *a += 1;
                *r += u32::from(correct);
            }
        }
        let (Some(dec), Some(k)) = (deciles, s.mask_index) else {
            return;
        };
        let Some(d) = dec.get(k as usize).map(|d| usize::from(*d).min(9)) else {
            return;
        };
        counts.attempts[d] += 1;
        counts.correct[d] += u32::from(correct);
    };
    let record = deciles.is_some() || cfg.variant_counts;
    let opts = if record {
        RunOptions::default().samples(&mut count)
    } else {
        RunOptions::default()
    };
    let r = locate::relocalize(req, opts);
    if deciles.is_some() {
        o.columns.scores = Some(counts);
    }
    if cfg.variant_counts {
        if let Ok(r) = &r {
            variants.matches = r.outcome.stats.pipeline.matches;
        }
        o.columns.variants = Some(variants);
    }
    let r = match r {
        Ok(r) => r,
        Err(e) => {
            o.failure = Some(format!("error: {e}"));
            return None;
        }
    };
    let out = &r.outcome;
    let est = inputs.as_physical(&out.pose);
    let (t1, r1) = frame.error(&est);
    o.success = out.failure.is_none();
    o.failure = out.failure.map(|c| c.name().to_string());
    o.final_t_mm = t1 * 1e3;
    o.final_r_deg = r1.to_degrees();
    o.inliers = u32::from(out.quality.inliers);
    o.iterations = u32::from(out.stats.successes);
    o.time_s = r.elapsed.as_secs_f64();
    o.columns.engine = Some(engine_columns(out, &inputs.prior));
    // Its world-frame blocks hold for the physical camera too: the same
    // centre, a rotation differing by a fixed right factor.
    o.columns.covariance = out
        .quality
        .covariance
        .as_ref()
        .and_then(|c| frame.covariance(&est, c));
    // What the caller's accuracy saved, only when one was asked for.
    if cfg.accuracy.is_some() {
        o.columns.accuracy = Some(crate::eval::columns::AccuracyColumns {
            rounds_saved: out.stats.rounds_saved,
            accuracy_checks: out.stats.accuracy_checks,
        });
    }
    // Which upset checks ran, only when asked for.
    if cfg.verify.any() {
        let v = crate::cli::relocalize::verified(out, cfg.verify);
        o.columns.verify = Some(VerifyColumns {
            repeat_solve: v.repeat_solve,
            recheck_map: v.recheck_map,
        });
    }
    Some((out.pose, r.template_px))
}

/// The engine's work counters, so a slow trial can be told apart from a
/// loaded machine, and what the integrity gates saw (the core's camera), to
/// show their margins.
fn engine_columns(out: &vtsm_core::reloc::Outcome, prior: &Pose) -> EngineColumns {
    let (dt, dr) = vtsm_core::reloc::integrity::distance_to(prior, &out.pose);
    EngineColumns {
        attempts: out.stats.attempts,
        pairs: out.stats.correspondences,
        revisited: out.stats.pipeline.revisited,
        revisit_pairs: out.stats.pipeline.revisit_pairs,
        near_drawn: out.stats.pipeline.near_drawn,
        near_pairs: out.stats.pipeline.near_pairs,
        stalls: out.stats.stalls,
        reseeds: out.stats.reseeds,
        focused_rounds: out.stats.focused_rounds,
        gradient_rounds: out.stats.gradient_rounds,
        refine_accepted: u32::from(out.stats.refine.accepted),
        spread_m: out.quality.spread_m,
        reproj_px: out.quality.reproj_rms_px,
        prior_dt_m: dt,
        prior_dr_deg: dr.to_degrees(),
    }
}
