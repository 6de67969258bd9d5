//! The scene of the flight-path tests (`tests/tests/integration/runner_path.rs`,
//! `tests/tests/integration/fault_scenarios.rs`) and of the upset campaign ([`crate::upsets`]):
//! the test kit's map product (seed 1), a 640×480 pair rendered from the left
//! camera at (0.6, 0.2) m, a prior 12 cm off the truth, and the runner
//! requests over them (test kit rig, test profile, seed [`RELOC_SEED`]).

use crate::testkit;
use std::sync::OnceLock;
use vtsm_core::geom::{Pose, Vec3};
use vtsm_core::map::MapView;
use vtsm_sim::locate::Request;

/// Seed of the relocalization of every request built here (the upset
/// campaign's own seed only chooses the bits).
pub const RELOC_SEED: u64 = 42;

/// The scene: map product, stereo pair, truth and prior.
pub struct Scene {
    /// Encoded map product.
    pub map: Vec<u8>,
    /// Left image.
    pub left: Vec<u8>,
    /// Right image.
    pub right: Vec<u8>,
    /// True `world_from_left`.
    pub truth: Pose,
    /// The prior: 12 cm and no rotation off the truth, inside the paper's
    /// 20 cm uncertainty.
    pub prior: Pose,
}

impl Scene {
    /// The test-kit scene (map seed 1, camera at (0.6, 0.2)).
    pub fn test_profile() -> Self {
        let map = testkit::build_map(1);
        let truth = testkit::camera_pose(0.6, 0.2);
        let Ok(view) = MapView::new_checked(&map) else {
            return Self::empty();
        };
        let (left, right) = render_pair(&view, &truth);
        let prior = Pose::new(
            truth.rotation(),
            truth.translation() + Vec3::new(0.09, -0.08, 0.02),
        );
        Self {
            map,
            left,
            right,
            truth,
            prior,
        }
    }

    fn empty() -> Self {
        Self {
            map: Vec::new(),
            left: Vec::new(),
            right: Vec::new(),
            truth: Pose::identity(),
            prior: Pose::identity(),
        }
    }

    /// The runner request for `map` with this scene's pair and prior.
    pub fn request<'a>(&'a self, map: &'a [u8], seed: u64) -> Request<'a> {
        request(map, &self.left, &self.right, self.prior).with_seed(seed)
    }
}

/// [`Scene::test_profile`], built once per process.
pub fn scene() -> &'static Scene {
    static S: OnceLock<Scene> = OnceLock::new();
    S.get_or_init(Scene::test_profile)
}

/// Left and right images of `map` seen by the test kit's rig with its left
/// camera at `pose` (gain 0.85, offset 20).
pub fn render_pair(map: &MapView, pose: &Pose) -> (Vec<u8>, Vec<u8>) {
    let rig = testkit::rig();
    (
        testkit::render_full(map, &rig.cam(), pose, 0.85, 20.0),
        testkit::render_full(map, &rig.cam(), &rig.world_from_right(pose), 0.85, 20.0),
    )
}

/// The runner request for `map`, `left`/`right` and `prior` on the test kit's
/// rig, with the test profile and seed [`RELOC_SEED`].
pub fn request<'a>(map: &'a [u8], left: &'a [u8], right: &'a [u8], prior: Pose) -> Request<'a> {
    Request::new(map, left, right, testkit::rig(), prior)
        .with_params(testkit::test_params())
        .with_seed(RELOC_SEED)
}
