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
    let (width, height, mut pixels) = match extension.as_str() {
        "exr" => read_exr(path)?,
        "hdr" | "pic" => read_hdr(path)?,
        _ => return Err(EnvmapError::UnknownFormat { path: path.into(), extension }),
    };
    if width < 2 || height < 1 {
        return Err(EnvmapError::TooSmall { path: path.into(), width, height });
    }
    let repaired_pixels = repair(&mut pixels);
    let mut warnings = Vec::new();
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

fn read_exr(path: &Path) -> Result<(usize, usize, Vec<Rgb>), EnvmapError> {
    use exr::prelude::*;
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
