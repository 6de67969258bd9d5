//! `vtsm ncc`: find one template in one image with the core's integer NCC and
//! print one JSON line `{"x":..,"y":..,"score":..,"ms_per_match":..}`.
//!
//! (x, y) is the top-left offset of the best match (OpenCV `matchTemplate` +
//! `minMaxLoc` convention), score the zero-mean NCC (`TM_CCOEFF_NORMED`), and
//! `ms_per_match` the median wall-clock time of `--repeat` in-process searches,
//! excluding decoding. The whole image is the search window, so its sides must
//! not exceed `config::MAX_SEARCH_PX`. Colour images are converted to gray (luma).

use std::path::{Path, PathBuf};
use std::time::Instant;

use vtsm_core::image::{GrayView, Rect};
use vtsm_core::ncc::{self, Filter, Run, Scratch, ScratchSizes, Search};
use vtsm_core::FailureCode;

use crate::{Error, Result};

/// Largest `--repeat` accepted.
pub const MAX_REPEAT: u32 = 10_000;

/// Image domain of the correlation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FilterArg {
    /// Raw gray levels.
    Gray,
    /// Sobel magnitude.
    Sobel,
    /// Laplacian.
    Laplacian,
}

impl From<FilterArg> for Filter {
    fn from(f: FilterArg) -> Self {
        match f {
            FilterArg::Gray => Filter::Gray,
            FilterArg::Sobel => Filter::Sobel,
            FilterArg::Laplacian => Filter::Laplacian,
        }
    }
}

/// Arguments of `vtsm ncc`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Template image (PNG, PGM, JPEG, TIFF); colour is converted to gray.
    #[arg(long)]
    pub template: PathBuf,
    /// Image to search in; the whole image is the search window.
    #[arg(long)]
    pub image: PathBuf,
    /// Optional template mask of the template's size (non-zero keeps a pixel).
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Correlation domain.
    #[arg(long, value_enum, default_value = "gray")]
    pub filter: FilterArg,
    /// Number of in-process searches; the reported time is their median.
    #[arg(long, default_value_t = 1)]
    pub repeat: u32,
    /// Score every position instead of the default coarse-to-fine search.
    #[arg(long)]
    pub exhaustive: bool,
}

/// What `vtsm ncc` prints.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Output {
    /// Column of the best match's top-left corner.
    pub x: i32,
    /// Row of the best match's top-left corner.
    pub y: i32,
    /// Zero-mean NCC of the best match.
    pub score: f32,
    /// Median time of one search, milliseconds.
    pub ms_per_match: f64,
}

fn load_gray(path: &Path) -> Result<(Vec<u8>, usize, usize)> {
    let img =
        image::open(path).map_err(|e| Error::file(path, format!("cannot read image: {e}")))?;
    let g = img.to_luma8();
    let (w, h) = (g.width() as usize, g.height() as usize);
    Ok((g.into_raw(), w, h))
}

fn view<'a>(px: &'a [u8], w: usize, h: usize, path: &Path) -> Result<GrayView<'a>> {
    GrayView::new(px, w, h, w).map_err(|c| {
        Error::file(path, format!("unusable image size {w}x{h}: {}", c.name())).with_code(c)
    })
}

/// Load the files, search `--repeat` times and return the result.
///
/// # Errors
/// A one-line [`Error`] naming the file at fault (unreadable file, template size,
/// mask size, image too large) or the core's failure code.
pub fn execute(args: &Args) -> Result<Output> {
    if !(1..=MAX_REPEAT).contains(&args.repeat) {
        return Err(Error::msg(format!(
            "--repeat must be in 1..={MAX_REPEAT}, got {}",
            args.repeat
        )));
    }
    let (tpx, tw, th) = load_gray(&args.template)?;
    let (ipx, iw, ih) = load_gray(&args.image)?;
    let mask = match &args.mask {
        Some(p) => {
            let (m, mw, mh) = load_gray(p)?;
            if (mw, mh) != (tw, th) {
                return Err(Error::file(
                    p,
                    format!("mask is {mw}x{mh} but the template is {tw}x{th}"),
                ));
            }
            Some(m)
        }
        None => None,
    };
    let template = view(&tpx, tw, th, &args.template)?;
    let image = view(&ipx, iw, ih, &args.image)?;
    let mask_view = match (&mask, &args.mask) {
        (Some(m), Some(p)) => Some(view(m, tw, th, p)?),
        _ => None,
    };
    let mode = if args.exhaustive {
        Search::Exhaustive
    } else {
        Search::CoarseToFine
    };
    let sz = ScratchSizes::new(tw, th, iw, ih, mode);
    let (mut wb, mut tb, mut ib, mut rb) = (
        vec![0u8; sz.window],
        vec![0u8; sz.template],
        vec![0u32; sz.integral],
        vec![Run::default(); sz.runs],
    );
    let mut scratch = Scratch {
        window: &mut wb,
        template: &mut tb,
        integral: &mut ib,
        runs: &mut rb,
    };
    let search = Rect::new(0, 0, iw as u32, ih as u32);
    let mut times = Vec::with_capacity(args.repeat as usize);
    let mut found = None;
    for _ in 0..args.repeat {
        let t0 = Instant::now();
        let r = ncc::match_template(
            template,
            mask_view,
            image,
            search,
            args.filter.into(),
            mode,
            &mut scratch,
        );
        times.push(t0.elapsed().as_secs_f64() * 1e3);
        found = Some(r.map_err(|c| blame(c, args))?);
    }
    times.sort_by(f64::total_cmp);
    let ms = times.get(times.len() / 2).copied().unwrap_or(f64::NAN);
    let (m, _) = found.ok_or_else(|| Error::msg("no search was run"))?;
    Ok(Output {
        x: m.x,
        y: m.y,
        score: m.score,
        ms_per_match: ms,
    })
}

/// Attach a core failure to the file it is about.
fn blame(code: FailureCode, args: &Args) -> Error {
    let file: &Path = match code {
        FailureCode::NccTemplateFlat
        | FailureCode::NccTemplateSizeInvalid
        | FailureCode::NccTemplateLargerThanWindow => &args.template,
        FailureCode::NccMaskEmpty => args.mask.as_deref().unwrap_or(&args.template),
        _ => &args.image,
    };
    Error::file(
        file,
        format!(
            "{} (0x{:04x}): {}",
            code.name(),
            code.code(),
            code.description()
        ),
    )
    .with_code(code)
}

/// Run the command; returns the exit code.
pub fn run(args: &Args) -> Result<u8> {
    let out = execute(args)?;
    let line = serde_json::to_string(&out).map_err(|e| Error::msg(e.to_string()))?;
    println!("{line}");
    Ok(0)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("vtsm-ncc-cli-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d.join(name)
    }

    fn args(t: &Path, i: &Path) -> Args {
        Args {
            template: t.to_path_buf(),
            image: i.to_path_buf(),
            mask: None,
            filter: FilterArg::Gray,
            repeat: 3,
            exhaustive: false,
        }
    }

    /// Verifies: VTSM-NCC-013
    #[test]
    fn finds_a_template_cut_from_a_colour_png() {
        let (w, h) = (120u32, 100u32);
        let rgb = image::RgbImage::from_fn(w, h, |x, y| {
            let v = ((x * 37 + y * 91) ^ (x * y)) as u8;
            image::Rgb([v, v.wrapping_mul(3), v / 2])
        });
        let ip = tmp("image.png");
        rgb.save(&ip).unwrap();
        let gray = image::DynamicImage::ImageRgb8(rgb).to_luma8();
        let tpl = image::imageops::crop_imm(&gray, 41, 23, 32, 32).to_image();
        let tp = tmp("t.png");
        tpl.save(&tp).unwrap();
        for (exhaustive, filter) in [(false, FilterArg::Gray), (true, FilterArg::Sobel)] {
            let a = Args {
                exhaustive,
                filter,
                ..args(&tp, &ip)
            };
            let out = execute(&a).unwrap();
            assert_eq!((out.x, out.y), (41, 23));
            // Sobel: the template's one-pixel border is filtered with replicated
            // neighbours, the image's with true ones, so the peak is a little below 1.
            let floor = if filter == FilterArg::Gray {
                0.9999
            } else {
                0.8
            };
            assert!(
                out.score > floor && out.ms_per_match >= 0.0,
                "{}",
                out.score
            );
            assert_eq!(run(&a).unwrap(), 0);
        }
        let json = serde_json::to_value(execute(&args(&tp, &ip)).unwrap()).unwrap();
        for k in ["x", "y", "score", "ms_per_match"] {
            assert!(json.get(k).is_some(), "{k}");
        }
    }

    /// Verifies: VTSM-NCC-013
    #[test]
    fn bad_input_names_the_file() {
        let ip = tmp("img2.png");
        image::GrayImage::from_fn(64, 64, |x, y| image::Luma([((x * 7) ^ (y * 13)) as u8]))
            .save(&ip)
            .unwrap();
        let missing = tmp("missing.png");
        let e = execute(&args(&missing, &ip)).unwrap_err();
        assert_eq!(e.file.as_deref(), Some(missing.as_path()));
        let flat = tmp("flat.png");
        image::GrayImage::from_pixel(20, 20, image::Luma([5]))
            .save(&flat)
            .unwrap();
        let e = execute(&args(&flat, &ip)).unwrap_err();
        assert_eq!(e.file.as_deref(), Some(flat.as_path()));
        assert_eq!(e.code, Some(FailureCode::NccTemplateFlat));
        let big = tmp("big.png");
        image::GrayImage::from_fn(80, 80, |x, y| image::Luma([(x + y) as u8]))
            .save(&big)
            .unwrap();
        let e = execute(&args(&big, &ip)).unwrap_err();
        assert_eq!(e.code, Some(FailureCode::NccTemplateLargerThanWindow));
        assert!(e.to_string().starts_with(&big.display().to_string()));
        let e = execute(&Args {
            repeat: 0,
            ..args(&ip, &ip)
        })
        .unwrap_err();
        assert!(e.msg.contains("--repeat"));
    }
}
