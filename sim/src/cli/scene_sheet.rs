//! `vtsm scene sheet`: a contact sheet PNG of the three terrains at am, noon and pm
//! (rows: Flagstone, CFA6, CFA2; columns: am, noon, pm), left images of one capture.
//! Prints the time spent per stereo-less render.

use crate::error::{Error, Result};
use crate::render::render;
use crate::scene::export::write_png_gray;
use crate::scene::{capture_pose, Capture, Profile, Scene, TIMES_H};
use crate::terrain::TerrainKind;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `vtsm scene sheet`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Output PNG.
    #[arg(long)]
    pub out: PathBuf,
    /// Seed of the depots.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Profile of each tile: test or demo.
    #[arg(long, default_value = "test")]
    pub profile: String,
    /// Stop of the capture grid, 0..30.
    #[arg(long, default_value_t = 4)]
    pub stop: u32,
    /// Tube looked at: 0 or 1.
    #[arg(long, default_value_t = 0)]
    pub look_at: u32,
    /// Overwrite an existing file.
    #[arg(long)]
    pub force: bool,
}

/// Run the command; returns the exit code.
pub fn run(args: &Args) -> Result<u8> {
    let profile = Profile::parse(&args.profile).ok_or_else(|| {
        Error::msg(format!(
            "unknown profile `{}` (paper, demo, test)",
            args.profile
        ))
    })?;
    if args.out.exists() && !args.force {
        return Err(Error::file(
            &args.out,
            "already exists (use --force to overwrite)",
        ));
    }
    let cap = Capture::from_index(args.stop.min(29), args.look_at.min(1), 0.40);
    let (tw, th) = profile.image_size();
    let gap = 8usize;
    let (tw, th) = (tw as usize, th as usize);
    let sw = 3 * tw + 4 * gap;
    let sh = 3 * th + 4 * gap;
    let mut sheet = vec![0u8; sw * sh];
    for (r, kind) in TerrainKind::ALL.into_iter().enumerate() {
        let t0 = Instant::now();
        let scene = Scene::new(kind, args.seed, profile);
        let gen_s = t0.elapsed().as_secs_f64();
        let pose = capture_pose(&scene.terrain, &cap);
        for (c, (name, hours)) in TIMES_H.iter().enumerate() {
            let t1 = Instant::now();
            let light = scene.lighting(*hours);
            let shadow_s = t1.elapsed().as_secs_f64();
            let t2 = Instant::now();
            let img = render(
                &scene.terrain,
                &light,
                &scene.camera(),
                &pose,
                &scene.render_options(args.seed),
            );
            let render_s = t2.elapsed().as_secs_f64();
            println!(
                "{:9} {:4} sun el {:5.1} az {:5.1}  terrain {:.2} s  shadows {:.2} s  render {:.2} s  shadowed {:.1} %",
                kind.name(),
                name,
                light.sun.elevation_deg,
                light.sun.azimuth_deg,
                gen_s,
                shadow_s,
                render_s,
                100.0 * light.shadow_fraction()
            );
            let (ox, oy) = (gap + c * (tw + gap), gap + r * (th + gap));
            for (y, row) in img.chunks(tw).enumerate() {
                let start = (oy + y) * sw + ox;
                if let Some(dst) = sheet.get_mut(start..start + tw) {
                    dst.copy_from_slice(row);
                }
            }
        }
    }
    write_png_gray(&args.out, sw as u32, sh as u32, &sheet)?;
    println!(
        "wrote {} ({}x{}; rows flagstone, cfa6, cfa2; columns am, noon, pm)",
        args.out.display(),
        sw,
        sh
    );
    Ok(0)
}
