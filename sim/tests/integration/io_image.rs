//! Image loading: formats, bit depths, colour → gray, size checks, errors.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, missing_docs)]

use image::{ImageBuffer, ImageFormat, Luma, Rgb, Rgba};
use proptest::prelude::*;
use std::io::Cursor;
use std::path::{Path, PathBuf};
use vtsm_sim::io::image::{decode_gray, read_gray, read_gray_sized};

fn dir(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("io_image_{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn encode<P, C>(img: &ImageBuffer<P, C>, f: ImageFormat) -> Vec<u8>
where
    P: image::Pixel + image::PixelWithColorType,
    [P::Subpixel]: image::EncodableLayout,
    C: std::ops::Deref<Target = [P::Subpixel]>,
{
    let mut out = Cursor::new(Vec::new());
    img.write_to(&mut out, f).unwrap();
    out.into_inner()
}

/// Exact BT.601 luma, for comparison with the integer conversion.
fn luma_exact(r: f64, g: f64, b: f64) -> f64 {
    0.299 * r + 0.587 * g + 0.114 * b
}

fn p() -> &'static Path {
    Path::new("img")
}

/// Verifies: VTSM-CLI-005
#[test]
fn rgb8_png_and_tiff_convert_with_bt601_rounding() {
    let img = ImageBuffer::from_fn(37, 11, |x, y| {
        Rgb([
            (x * 7 % 256) as u8,
            (y * 23 % 256) as u8,
            ((x * y) % 256) as u8,
        ])
    });
    for f in [ImageFormat::Png, ImageFormat::Tiff] {
        let g = decode_gray(&encode(&img, f), p()).unwrap();
        assert_eq!((g.width, g.height), (37, 11));
        for (p, &v) in img.pixels().zip(&g.pixels) {
            let e = luma_exact(p.0[0].into(), p.0[1].into(), p.0[2].into());
            assert!(
                (f64::from(v) - e).abs() <= 0.5 + 1e-9,
                "{p:?} -> {v}, exact {e}"
            );
        }
    }
    // Alpha is ignored.
    let rgba = ImageBuffer::from_fn(4, 4, |x, _| Rgba([200, 10, (x * 60) as u8, (x * 80) as u8]));
    let g = decode_gray(&encode(&rgba, ImageFormat::Png), p()).unwrap();
    for (p, &v) in rgba.pixels().zip(&g.pixels) {
        let e = luma_exact(p.0[0].into(), p.0[1].into(), p.0[2].into());
        assert!((f64::from(v) - e).abs() <= 0.5 + 1e-9);
    }
}

/// Verifies: VTSM-CLI-005
#[test]
fn sixteen_bit_gray_and_colour_scale_to_eight_bit() {
    let gray16 = ImageBuffer::from_fn(64, 3, |x, y| Luma([(x * 1031 + y * 20000) as u16]));
    let g = decode_gray(&encode(&gray16, ImageFormat::Png), p()).unwrap();
    for (p, &v) in gray16.pixels().zip(&g.pixels) {
        let e = f64::from(p.0[0]) * 255.0 / 65535.0;
        assert!((f64::from(v) - e).abs() <= 0.5 + 1e-9, "{} -> {v}", p.0[0]);
    }
    let rgb16 = ImageBuffer::from_fn(16, 4, |x, y| {
        Rgb([(x * 4000) as u16, (y * 16000) as u16, 65535])
    });
    for f in [ImageFormat::Png, ImageFormat::Tiff] {
        let g = decode_gray(&encode(&rgb16, f), p()).unwrap();
        for (p, &v) in rgb16.pixels().zip(&g.pixels) {
            let e = luma_exact(p.0[0].into(), p.0[1].into(), p.0[2].into()) * 255.0 / 65535.0;
            // two roundings (16-bit luma, then 8-bit scale)
            assert!(
                (f64::from(v) - e).abs() <= 0.5 + 255.0 / 65535.0,
                "{p:?} -> {v}, exact {e}"
            );
        }
    }
}

/// Verifies: VTSM-CLI-005
#[test]
fn pgm_8_and_16_bit_and_jpeg_load() {
    // P5 written by hand: 3x2, maxval 255
    let mut pgm = b"P5\n3 2\n255\n".to_vec();
    pgm.extend([0u8, 1, 2, 253, 254, 255]);
    assert_eq!(
        decode_gray(&pgm, p()).unwrap().pixels,
        vec![0, 1, 2, 253, 254, 255]
    );
    // 16-bit: big-endian samples
    let mut pgm16 = b"P5\n2 1\n65535\n".to_vec();
    pgm16.extend(0x8000u16.to_be_bytes());
    pgm16.extend(65535u16.to_be_bytes());
    assert_eq!(decode_gray(&pgm16, p()).unwrap().pixels, vec![128, 255]);
    // JPEG is lossy: a flat image stays flat within a level or two.
    let flat = ImageBuffer::from_pixel(16, 16, Luma([90u8]));
    let g = decode_gray(&encode(&flat, ImageFormat::Jpeg), p()).unwrap();
    assert!(g.pixels.iter().all(|&v| v.abs_diff(90) <= 2));
}

/// Verifies: VTSM-CLI-008, VTSM-CLI-013
#[test]
fn bad_images_and_wrong_size_are_reported_with_the_file() {
    let d = dir("bad");
    let png = encode(
        &ImageBuffer::from_pixel(8, 6, Luma([1u8])),
        ImageFormat::Png,
    );
    let p = d.join("l.png");
    std::fs::write(&p, &png).unwrap();
    assert!(read_gray_sized(&p, 8, 6).is_ok());
    let e = read_gray_sized(&p, 8, 7).unwrap_err();
    assert_eq!(e.file.as_deref(), Some(p.as_path()));
    assert!(e.msg.contains("8x6") && e.msg.contains("8x7"), "{e}");

    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "truncated.png",
            png[..png.len() / 2].to_vec(),
            "cannot decode",
        ),
        (
            "garbage.png",
            b"hello world, not an image".to_vec(),
            "unrecognised",
        ),
        ("empty.png", Vec::new(), "unrecognised"),
        (
            "gif.png",
            b"GIF89a\x01\x00\x01\x00\x00\x00\x00;".to_vec(),
            "unsupported",
        ),
        ("zero.pgm", b"P5\n0 0\n255\n".to_vec(), ""),
    ];
    for (name, bytes, what) in cases {
        let p = d.join(name);
        std::fs::write(&p, bytes).unwrap();
        let e = read_gray(&p).unwrap_err();
        assert_eq!(e.file.as_deref(), Some(p.as_path()), "{name}");
        assert!(e.msg.contains(what), "{name}: {e}");
        assert_eq!(e.to_string().lines().count(), 1, "{name}: {e}");
    }
    let e = read_gray(&d.join("absent.png")).unwrap_err();
    assert!(e.msg.contains("no such file"), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Verifies: VTSM-CLI-008
    #[test]
    fn image_decoder_never_panics_on_corrupted_png(pos in any::<prop::sample::Index>(), byte in any::<u8>()) {
        let img = ImageBuffer::from_fn(9, 7, |x, y| Rgb([x as u8 * 20, y as u8 * 30, 7]));
        let mut b = encode(&img, ImageFormat::Png);
        let i = pos.index(b.len());
        b[i] = byte;
        if let Ok(g) = decode_gray(&b, p()) {
            prop_assert_eq!(g.pixels.len(), g.width as usize * g.height as usize);
        }
    }
}
