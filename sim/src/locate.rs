//! One relocalization on the desktop: build the engine with the core's one
//! constructor ([`Setup`]), its workspace on the heap (sized by
//! [`Setup::sizes`]), and run it to completion. Used by `vtsm demo`,
//! `vtsm relocalize`, `vtsm eval` and the end-to-end tests, so every path runs
//! exactly the same code.

use crate::error::{Error, Result};
use std::time::{Duration, Instant};
use vtsm_core::config::Params;
use vtsm_core::geom::Camera;
use vtsm_core::geom::{Pose, StereoRig};
use vtsm_core::image::{GrayView, Rect};
use vtsm_core::map::MapView;
use vtsm_core::ncc::Run;
use vtsm_core::raster::{self, Target};
use vtsm_core::reloc::{Outcome, Setup, Workspace};

/// The parameters used for an image width: the paper's, with ℓ and the
/// search window scaled to the image ([`Params::for_image_width`]).
pub fn params_for_width(width: u32) -> Params {
    Params::for_image_width(width)
}

/// Everything one relocalization needs.
#[derive(Clone, Copy)]
pub struct Request<'a> {
    /// Encoded map product (checked here).
    pub map: &'a [u8],
    /// Left image, row-major, `rig.cam.width × rig.cam.height`.
    pub left: &'a [u8],
    /// Right image, same size.
    pub right: &'a [u8],
    /// Calibrated rig.
    pub rig: StereoRig,
    /// Prior `world_from_left`.
    pub prior: Pose,
    /// Relocalization parameters (validated by the core).
    pub params: Params,
    /// Seed of the relocalization's random streams.
    pub seed: u64,
}

/// What one relocalization produced.
pub struct Report {
    /// The engine's outcome.
    pub outcome: Outcome,
    /// Wall time of the engine alone (not of loading or workspace allocation).
    pub elapsed: Duration,
    /// Template side used.
    pub template_px: u16,
    /// Search-window cap used.
    pub search_px: u16,
    /// Workspace bytes allocated for the core.
    pub workspace_bytes: usize,
}

/// Run one relocalization to completion.
///
/// # Errors
/// Bad map product, image sizes that disagree with the rig, or parameters the
/// core rejects — each with its failure code. A relocalization that fails
/// cleanly is not an error: it is an [`Outcome`] with a failure code.
pub fn relocalize(req: &Request<'_>) -> Result<Report> {
    let map = MapView::new_checked(req.map)?;
    let (w, h) = (req.rig.cam.width as usize, req.rig.cam.height as usize);
    if req.left.len() != w * h || req.right.len() != w * h {
        return Err(Error::from(vtsm_core::FailureCode::ImageSizeMismatch));
    }
    let left = GrayView::new(req.left, w, h, w)?;
    let right = GrayView::new(req.right, w, h, w)?;
    let setup = Setup::new(
        &map,
        left,
        right,
        &req.rig,
        &req.params,
        &req.prior,
        req.seed,
    );
    // Check before allocating: a bad parameter must not size a huge workspace.
    setup.validate()?;
    let sizes = setup.sizes();
    let mut bytes = vec![0u8; sizes.bytes];
    let mut words = vec![0u32; sizes.words];
    let mut runs = vec![Run::default(); sizes.runs];
    let ws = Workspace::new(sizes, &mut bytes, &mut words, &mut runs)?;
    let mut reloc = setup.build(ws)?;
    let t0 = Instant::now();
    let outcome = reloc.run_to_completion(0);
    Ok(Report {
        outcome,
        elapsed: t0.elapsed(),
        template_px: req.params.template_px,
        search_px: req.params.search_px,
        workspace_bytes: sizes.total_bytes(),
    })
}

/// An ℓ×ℓ synthetic template with its depth and §III-C mask, row-major.
pub struct Template {
    /// The window of the full virtual image that was rendered.
    pub rect: Rect,
    /// Rendered intensity.
    pub intensity: Vec<u8>,
    /// Depth, fixed point (`raster::depth_to_m`), `raster::DEPTH_NONE` where empty.
    pub depth: Vec<u32>,
    /// Template mask: 255 keep, 0 drop.
    pub mask: Vec<u8>,
}

/// Render the ℓ×ℓ template of `map` seen from `world_from_cam`, centred on the
/// pixel nearest to `centre_px` (the way the engine's Synthesize step does), and
/// form its mask. `None` when nothing is drawn or ℓ is out of range.
pub fn render_template(
    map: &MapView<'_>,
    cam: &Camera,
    world_from_cam: &Pose,
    centre_px: [f32; 2],
    l: usize,
) -> Option<Template> {
    let h = (l / 2) as i32;
    let rect = Rect::new(
        (centre_px[0] + 0.5).floor() as i32 - h,
        (centre_px[1] + 0.5).floor() as i32 - h,
        l as u32,
        l as u32,
    );
    let (mut intensity, mut depth, mut mask_depth) =
        (vec![0u8; l * l], vec![0u32; l * l], vec![0u32; l * l]);
    let mut target = Target {
        intensity: &mut intensity,
        depth: &mut depth,
        mask_depth: &mut mask_depth,
    };
    raster::render_window(map, cam, world_from_cam, rect, &mut target).ok()?;
    let mut mask = vec![0u8; l * l];
    raster::template_mask(&depth, &mask_depth, l, l, &mut mask);
    Some(Template {
        rect,
        intensity,
        depth,
        mask,
    })
}
