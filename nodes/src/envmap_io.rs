//! Loading equirectangular environment maps from OpenEXR and Radiance HDR files, with
//! repair of non-finite and negative pixels.

use crate::cubemap::{Equirect, Rgb};
use std::path::{Path, PathBuf};

/// Why an environment map could not be loaded. Every message names the file.
#[derive(Debug, thiserror::Error)]
pub enum EnvmapError {
    #[error("cannot read environment map {path}: {cause}")]
    Io { path: PathBuf, cause: std::io::Error },
    #[error(
        "environment map {path} uses EXR compression `{compression}`, which Lightloom's EXR reader cannot decode: \
         re-save it with ZIP, PIZ or no compression (for example `oiiotool {path} --compression zip -o fixed.exr`), \
         or use a Radiance .hdr copy"
    )]
    UnsupportedCompression { path: PathBuf, compression: String },
    #[error("environment map {path} is not a readable OpenEXR image: {message}")]
    Exr { path: PathBuf, message: String },
    #[error("environment map {path} is not a readable Radiance HDR image: {message}")]
    Hdr { path: PathBuf, message: String },
    #[error("environment map {path} has extension `{extension}`; Lightloom reads equirectangular .exr and .hdr files")]
    UnknownFormat { path: PathBuf, extension: String },
    #[error("environment map {path} is {width}x{height}; it needs at least 2x1 pixels")]
    TooSmall { path: PathBuf, width: usize, height: usize },
    #[error(
        "environment map {path} declares {width}x{height} pixels; the limit is {} megapixels (16384x8192)",
        crate::limits::MAX_IMAGE_PIXELS / 1_000_000
    )]
    TooLarge { path: PathBuf, width: u64, height: u64 },
    #[error("environment map {0}")]
    NotAFile(String),
}

/// A loaded environment with what was repaired on the way.
#[derive(Clone, Debug)]
pub struct LoadedEnvmap {
    pub image: Equirect,
    /// Pixels with a NaN, infinite or negative channel, set to zero in that channel.
    pub repaired_pixels: usize,
    /// Human-readable notes (repairs, odd aspect ratio).
    pub warnings: Vec<String>,
}

/// Loads an equirectangular `.exr` or `.hdr` file as linear RGB radiance.
pub fn load_equirect(path: &Path) -> Result<LoadedEnvmap, EnvmapError> {
    let extension = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    if !path.exists() {
        return Err(EnvmapError::Io { path: path.into(), cause: std::io::Error::from(std::io::ErrorKind::NotFound) });
    }
    crate::limits::check_regular_file(path, crate::limits::MAX_FILE_BYTES).map_err(EnvmapError::NotAFile)?;
    let (width, height, mut pixels) = match extension.as_str() {
        "exr" => read_exr(path)?,
        "hdr" | "pic" => read_hdr(path)?,
        _ => return Err(EnvmapError::UnknownFormat { path: path.into(), extension }),
    };
    if width < 2 || height < 1 {
        return Err(EnvmapError::TooSmall { path: path.into(), width, height });
    }
    let repaired_pixels = repair(&mut pixels);
    let clamped_pixels = clamp_radiance(&mut pixels);
    let mut warnings = Vec::new();
    if clamped_pixels > 0 {
        warnings.push(format!(
            "{}: {clamped_pixels} pixel(s) were brighter than {:e}; clamped to it",
            path.display(),
            crate::limits::MAX_RADIANCE
        ));
    }
    if repaired_pixels > 0 {
        warnings.push(format!(
            "{}: {repaired_pixels} pixel(s) had NaN, infinite or negative values; those channels were set to 0",
            path.display()
        ));
    }
    if width != 2 * height {
        warnings.push(format!(
            "{}: {width}x{height} is not 2:1; it is read as equirectangular anyway, so it will look stretched",
            path.display()
        ));
    }
    Ok(LoadedEnvmap { image: Equirect::new(width, height, pixels), repaired_pixels, warnings })
}

/// Sets non-finite and negative channels to zero; returns the number of pixels touched.
pub fn repair(pixels: &mut [Rgb]) -> usize {
    let mut count = 0;
    for p in pixels {
        if p.iter().any(|v| !v.is_finite() || *v < 0.0) {
            count += 1;
            for v in p.iter_mut() {
                if !v.is_finite() || *v < 0.0 {
                    *v = 0.0;
                }
            }
        }
    }
    count
}

/// Clamps channels above [`crate::limits::MAX_RADIANCE`] (a huge finite value, such as 3e38 or
/// an RGBE exponent of 255, would make sums and SH infinite); returns the pixels touched.
pub fn clamp_radiance(pixels: &mut [Rgb]) -> usize {
    let max = crate::limits::MAX_RADIANCE;
    let mut count = 0;
    for p in pixels.iter_mut().filter(|p| p.iter().any(|v| *v > max)) {
        count += 1;
        for v in p.iter_mut() {
            *v = v.min(max);
        }
    }
    count
}

/// Refuses declared sizes beyond [`crate::limits::MAX_IMAGE_PIXELS`] before any allocation.
fn check_dimensions(path: &Path, width: u64, height: u64) -> Result<(), EnvmapError> {
    if width.saturating_mul(height) > crate::limits::MAX_IMAGE_PIXELS {
        return Err(EnvmapError::TooLarge { path: path.into(), width, height });
    }
    Ok(())
}

fn read_exr(path: &Path) -> Result<(usize, usize, Vec<Rgb>), EnvmapError> {
    use exr::prelude::*;
    let meta = MetaData::read_from_file(path, false)
        .map_err(|e| EnvmapError::Exr { path: path.into(), message: e.to_string() })?;
    for header in &meta.headers {
        let size = header.layer_size;
        check_dimensions(path, size.width() as u64, size.height() as u64)?;
    }
    let image = read_first_rgba_layer_from_file(
        path,
        |resolution, _| (resolution.width(), vec![[0.0f32; 3]; resolution.width() * resolution.height()]),
        |(width, pixels): &mut (usize, Vec<Rgb>), position, (r, g, b, _a): (f32, f32, f32, f32)| {
            pixels[position.y() * *width + position.x()] = [r, g, b];
        },
    )
    .map_err(|e| match e {
        exr::error::Error::NotSupported(message) if message.contains("compression") => {
            let compression = MetaData::read_from_file(path, false)
                .ok()
                .and_then(|m| m.headers.first().map(|h| h.compression.to_string()))
                .unwrap_or_else(|| message.to_string());
            EnvmapError::UnsupportedCompression { path: path.into(), compression }
        }
        exr::error::Error::Io(cause) => EnvmapError::Io { path: path.into(), cause },
        other => EnvmapError::Exr { path: path.into(), message: other.to_string() },
    })?;
    let size = image.layer_data.size;
    let (_, pixels) = image.layer_data.channel_data.pixels;
    Ok((size.width(), size.height(), pixels))
}

fn read_hdr(path: &Path) -> Result<(usize, usize, Vec<Rgb>), EnvmapError> {
    let file = std::fs::File::open(path).map_err(|cause| EnvmapError::Io { path: path.into(), cause })?;
    let decoder = image::codecs::hdr::HdrDecoder::new(std::io::BufReader::new(file))
        .map_err(|e| EnvmapError::Hdr { path: path.into(), message: e.to_string() })?;
    let meta = decoder.metadata();
    check_dimensions(path, meta.width as u64, meta.height as u64)?;
    let image = image::DynamicImage::from_decoder(decoder)
        .map_err(|e| EnvmapError::Hdr { path: path.into(), message: e.to_string() })?;
    let rgb = image.into_rgb32f();
    let (width, height) = (rgb.width() as usize, rgb.height() as usize);
    let pixels = rgb.pixels().map(|p| p.0).collect();
    Ok((width, height, pixels))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repair_zeroes_bad_channels_and_counts_pixels() {
        let mut pixels = vec![[1.0, f32::NAN, 2.0], [f32::INFINITY, -1.0, 0.5], [0.1, 0.2, 0.3]];
        assert_eq!(repair(&mut pixels), 2);
        assert_eq!(pixels, vec![[1.0, 0.0, 2.0], [0.0, 0.0, 0.5], [0.1, 0.2, 0.3]]);
    }

    #[test]
    fn huge_declared_sizes_and_values_are_refused_or_clamped_before_allocating() {
        let dir = std::env::temp_dir().join(format!("lightloom-envmap-huge-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (w, h) in [(100_000u64, 100_000u64), (32, 100_000_000)] {
            // A Radiance header declaring the size, then a few pixels.
            let path = dir.join(format!("huge-{w}x{h}.hdr"));
            let mut bytes = format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n").into_bytes();
            bytes.extend([128u8, 128, 128, 129].repeat(64));
            std::fs::write(&path, bytes).unwrap();
            let e = load_equirect(&path).unwrap_err().to_string();
            assert!(e.contains(&format!("declares {w}x{h} pixels")), "{e}");
        }
        // An RGBE exponent of 255 is about 1.7e38: clamped, with a warning.
        let path = dir.join("bright.hdr");
        let mut bytes = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 4\n".to_vec();
        bytes.extend([200u8, 200, 200, 255].repeat(8));
        std::fs::write(&path, bytes).unwrap();
        let loaded = load_equirect(&path).unwrap();
        assert!(loaded.image.pixels.iter().flatten().all(|v| *v <= crate::limits::MAX_RADIANCE));
        assert!(loaded.warnings.iter().any(|w| w.contains("clamped")), "{:?}", loaded.warnings);
        // A FIFO named like an environment map is refused, not waited on.
        let fifo = dir.join("fifo.exr");
        let _ = std::fs::remove_file(&fifo);
        if std::process::Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success()) {
            let e = load_equirect(&fifo).unwrap_err().to_string();
            assert!(e.contains("not a regular file"), "{e}");
        }
    }

    #[test]
    fn missing_and_unknown_files_give_named_errors() {
        let missing = load_equirect(Path::new("/nonexistent/sky.exr")).unwrap_err().to_string();
        assert!(missing.contains("/nonexistent/sky.exr"), "{missing}");
        let dir = std::env::temp_dir().join("lightloom-envmap-test");
        std::fs::create_dir_all(&dir).unwrap();
        let txt = dir.join("sky.png");
        std::fs::write(&txt, b"not an image").unwrap();
        assert!(matches!(load_equirect(&txt), Err(EnvmapError::UnknownFormat { .. })));
        let bad_exr = dir.join("broken.exr");
        std::fs::write(&bad_exr, b"definitely not an exr").unwrap();
        let err = load_equirect(&bad_exr).unwrap_err().to_string();
        assert!(err.contains("broken.exr") && err.contains("OpenEXR"), "{err}");
        let bad_hdr = dir.join("broken.hdr");
        std::fs::write(&bad_hdr, b"#?RADIANCE\ngarbage").unwrap();
        let err = load_equirect(&bad_hdr).unwrap_err().to_string();
        assert!(err.contains("broken.hdr") && err.contains("Radiance"), "{err}");
    }
}
