//! `vtsm map build`: textured mesh (+ optional mask mesh) → map product file.
//!
//! Nothing is written unless every input is valid and the product encodes; the
//! output appears atomically (temporary file + rename) and an existing file is
//! only replaced with `--force`. On a terminal, stderr shows the progress of
//! reading the mesh (bytes parsed) and then the stage being run.

use crate::io::{self, mesh};
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::PathBuf;

/// Default tile edge of the map product, metres.
pub const DEFAULT_TILE_SIZE_M: f32 = 0.5;

/// Arguments of `vtsm map build`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Textured mesh: Wavefront OBJ (textures from the MTL's map_Kd) or PLY
    /// (textures from `comment TextureFile`, page per face from `texnumber`, or
    /// per-vertex colour). Several texture pages are packed into one atlas.
    #[arg(long, value_name = "M.obj|M.ply")]
    pub mesh: PathBuf,
    /// Mask mesh K: the triangles of the mesh to sample points from (same vertex
    /// coordinates). Without it every triangle is sampled.
    #[arg(long, value_name = "K.obj")]
    pub mask: Option<PathBuf>,
    /// Output map product.
    #[arg(long, value_name = "D.vmap")]
    pub out: PathBuf,
    /// Overwrite the output if it exists.
    #[arg(long)]
    pub force: bool,
    /// Edge of the square culling tiles, metres.
    #[arg(long, value_name = "S", default_value_t = DEFAULT_TILE_SIZE_M)]
    pub tile_size_m: f32,
    /// Origin X,Y,Z of the map's local frame, metres in the mesh's frame
    /// (default: the exact bounding-box centre).
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub origin: Option<String>,
    /// `--map-scores on|off`: score every mask vertex for how likely its
    /// template is to match ([`crate::mapscore`]) and ship the scores
    /// (a version-3 product).
    #[command(flatten)]
    pub map_scores: super::MapScoresArg,
}

/// Load, mask and encode: the product bytes and a one-line summary.
///
/// # Errors
/// Any input or encoding error.
pub fn build(args: &Args) -> crate::Result<(Vec<u8>, String)> {
    if !(args.tile_size_m.is_finite() && args.tile_size_m > 0.0) {
        return Err(crate::Error::msg(format!(
            "--tile-size-m {} must be a positive number",
            args.tile_size_m
        ))
        .with_code(vtsm_core::FailureCode::MapTileSizeOutOfRange));
    }
    let origin = args
        .origin
        .as_deref()
        .map(crate::frame::parse_origin)
        .transpose()?;
    let bar = progress_bar();
    bar.set_message("reading");
    let loaded = mesh::load_mesh_with_progress(&args.mesh, origin, &bar);
    let mut m = match loaded {
        Ok(m) => m,
        Err(e) => {
            bar.finish_and_clear();
            return Err(e);
        }
    };
    // The rest is one pass each over the mesh: shown as a spinner with the stage.
    bar.set_style(
        ProgressStyle::with_template("{spinner} {elapsed} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    let built = finish(args, &mut m, &bar);
    bar.finish_and_clear();
    built
}

/// A progress bar on stderr when it is a terminal (hidden otherwise, so logs and
/// the one-line errors stay clean).
fn progress_bar() -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(0);
    if let Ok(style) = ProgressStyle::with_template(
        "{msg} {elapsed} [{bar:40}] {bytes}/{total_bytes} ({eta} left)",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

/// Mask and encode a loaded mesh, naming the stage on `bar`.
fn finish(
    args: &Args,
    m: &mut mesh::MeshData,
    bar: &ProgressBar,
) -> crate::Result<(Vec<u8>, String)> {
    let mask_note = match &args.mask {
        Some(k) => {
            bar.set_message(format!("matching mask {}", k.display()));
            let geo = mesh::load_geometry(k)?;
            let s = m.apply_mask(&geo, k)?;
            format!(
                ", mask {} of {} triangles matched",
                s.matched, s.mask_triangles
            )
        }
        None => String::new(),
    };
    let scored = args.map_scores.on();
    bar.set_message(format!(
        "{}encoding {} triangles",
        if scored { "scoring and " } else { "" },
        m.triangles.len()
    ));
    let bytes = crate::mapscore::encode(m, args.tile_size_m, scored).map_err(|mut e| {
        if e.file.is_none() {
            e.file = Some(args.mesh.clone());
        }
        e
    })?;
    let summary = format!(
        "{}: {} vertices, {} triangles ({} in mask{mask_note}{}), texture {}x{}, origin ({}, {}, {}) m, {} bytes",
        args.out.display(),
        m.vertices.len(),
        m.triangles.len(),
        m.mask_count(),
        if scored { ", scored" } else { "" },
        m.texture.width,
        m.texture.height,
        m.origin[0],
        m.origin[1],
        m.origin[2],
        bytes.len()
    );
    Ok((bytes, summary))
}

/// Run the command; returns the exit code.
pub fn run(args: &Args) -> crate::Result<u8> {
    // Refuse early, before the (possibly long) load.
    io::check_output(&args.out, args.force)?;
    let (bytes, summary) = build(args)?;
    io::write_atomic(&args.out, &bytes, args.force)?;
    println!("{summary}");
    Ok(0)
}
