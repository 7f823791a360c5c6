//! A painted area-light texture: an operation log replayed onto a linear HDR RGB image with an
//! emission mask (the area-light painter of Sun 2008 §4.5.6: paint, blend, filter, warp,
//! reshape). Projects store the log and the source images' paths, never the pixels or the
//! coefficients, so every edit is one appended operation and replay is deterministic.
//!
//! Coordinates are the light's `[0, 1)²` (`u` along the light's width, `v` along its depth),
//! resolution-independent, so the same log renders at 32², 64² or 128².

pub use crate::paint::{Blend, MAX_DABS, MAX_OPERATIONS, PaintOp, Shape};
use serde::{Deserialize, Serialize};

/// Texture sides the painter renders at.
pub const RESOLUTIONS: [usize; 3] = [32, 64, 128];

/// The rendered texture: linear RGB radiance and the emission mask, `side²` texels each
/// (row `y` at `y·side`, `u` along the row).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LightTexture {
    pub side: usize,
    pub radiance: Vec<[f64; 3]>,
    pub mask: Vec<f64>,
}

crate::stage_type!(LightTexture, "light texture", |v| v.radiance.len() * 32 + 32);

impl LightTexture {
    /// What the light emits: radiance times mask.
    pub fn emission(&self) -> Vec<[f64; 3]> {
        self.radiance.iter().zip(&self.mask).map(|(c, m)| c.map(|v| v * m)).collect()
    }

    /// The emission of a `width × depth` light turned by `angle` degrees about its centre
    /// (right-handed about +y, as objects turn: the width axis goes from +x towards −z),
    /// resampled (nearest texel) over its axis-aligned bounding rectangle
    /// ([`turned_extent`]) at the same resolution; zero outside the light.
    pub fn turned(&self, width: f64, depth: f64, angle: f64) -> Vec<[f64; 3]> {
        let emission = self.emission();
        if angle.rem_euclid(360.0) == 0.0 {
            return emission;
        }
        let n = self.side;
        let extent = turned_extent(width, depth, angle);
        let (sin, cos) = angle.to_radians().sin_cos();
        (0..n * n)
            .map(|k| {
                // A texel of the bounding rectangle, in metres from the centre, turned back
                // into the light's own frame.
                let c = self.centre(k);
                let (x, z) = ((c[0] - 0.5) * extent[0], (c[1] - 0.5) * extent[1]);
                let (u, v) = ((cos * x - sin * z) / width + 0.5, (sin * x + cos * z) / depth + 0.5);
                if (0.0..1.0).contains(&u) && (0.0..1.0).contains(&v) {
                    emission[((v * n as f64) as usize).min(n - 1) * n + ((u * n as f64) as usize).min(n - 1)]
                } else {
                    [0.0; 3]
                }
            })
            .collect()
    }

    fn centre(&self, k: usize) -> [f64; 2] {
        let s = self.side as f64;
        [((k % self.side) as f64 + 0.5) / s, ((k / self.side) as f64 + 0.5) / s]
    }
}

/// The axis-aligned bounding rectangle of a `width × depth` light turned by `angle` degrees.
pub fn turned_extent(width: f64, depth: f64, angle: f64) -> [f64; 2] {
    let (sin, cos) = angle.to_radians().sin_cos();
    [width * cos.abs() + depth * sin.abs(), width * sin.abs() + depth * cos.abs()]
}

/// A decoded image for [`PaintOp::Import`]: `width × height` linear RGB, row-major, top row
/// first (it maps to `v = 0`).
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<[f64; 3]>,
}

/// Pixels an imported image may have (a light texture is at most 128²; 4096² is ample).
pub const MAX_IMPORT_PIXELS: u64 = 4096 * 4096;

/// Texel operations a replay may take (about a second): a log beyond it is refused.
pub const MAX_REPLAY_WORK: f64 = 2e9;

/// Texel operations replaying `op` at `side²` takes, about.
pub fn replay_work(op: &PaintOp, side: usize) -> f64 {
    let texels = (side * side) as f64;
    let dabs = |points: &[[f64; 2]], radius: f64| {
        let across = (2.0 * radius * side as f64 + 2.0).powi(2).min(texels);
        points.len() as f64 * across + texels
    };
    match op {
        PaintOp::Stroke { points, radius, .. } | PaintOp::Erase { points, radius, .. } => dabs(points, *radius),
        PaintOp::Blur { sigma } => texels * 2.0 * (6.0 * sigma * side as f64 + 1.0),
        _ => texels,
    }
}

/// An image file for [`PaintOp::Import`]: EXR and HDR as stored (linear), PNG and the other
/// formats of the `image` crate through sRGB; bounded in bytes and pixels.
pub fn load_image(path: &std::path::Path) -> Result<Image, String> {
    let extension = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    if matches!(extension.as_str(), "exr" | "hdr") {
        let loaded = crate::envmap_io::load_equirect(path).map_err(|e| e.to_string())?;
        let image = loaded.image;
        if (image.width * image.height) as u64 > MAX_IMPORT_PIXELS {
            return Err(format!(
                "{}: {} × {} pixels is too large to paint with (at most {MAX_IMPORT_PIXELS})",
                path.display(),
                image.width,
                image.height
            ));
        }
        let pixels = image.pixels.iter().map(|p| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])]).collect();
        return Ok(Image { width: image.width, height: image.height, pixels });
    }
    let named = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    crate::limits::check_regular_file(path, crate::limits::MAX_FILE_BYTES).map_err(|e| named(&e))?;
    let reader = image::ImageReader::open(path).and_then(|r| r.with_guessed_format()).map_err(|e| named(&e))?;
    let (width, height) = reader.into_dimensions().map_err(|e| named(&e))?;
    if u64::from(width) * u64::from(height) > MAX_IMPORT_PIXELS {
        return Err(named(&format!("{width} × {height} pixels is too large to paint with")));
    }
    let decoded = image::open(path).map_err(|e| named(&e))?.to_rgb32f();
    let to_linear = |c: f32| crate::picture::srgb_to_linear(f64::from(c));
    let pixels = decoded.pixels().map(|p| [to_linear(p[0]), to_linear(p[1]), to_linear(p[2])]).collect();
    Ok(Image { width: width as usize, height: height as usize, pixels })
}

/// Replays `ops` at `side²` onto a white, fully emitting texture. `load` decodes an imported
/// image by its path.
pub fn render(
    ops: &[PaintOp],
    side: usize,
    load: &mut dyn FnMut(&str) -> Result<Image, String>,
) -> Result<LightTexture, String> {
    if !RESOLUTIONS.contains(&side) {
        return Err(format!("light textures are {RESOLUTIONS:?} texels wide, not {side}"));
    }
    if ops.len() > MAX_OPERATIONS {
        return Err(format!("the paint log has {} operations; at most {MAX_OPERATIONS}", ops.len()));
    }
    let mut work = 0.0;
    for op in ops {
        op.check()?;
        work += replay_work(op, side);
    }
    if work > MAX_REPLAY_WORK {
        return Err(format!(
            "the paint log would take too long to replay at {side}² ({work:.1e} texel operations; at most \
             {MAX_REPLAY_WORK:.0e}): blur less, use fewer or smaller strokes, or a smaller texture"
        ));
    }
    let mut texture = LightTexture { side, radiance: vec![[1.0; 3]; side * side], mask: vec![1.0; side * side] };
    let ceiling = f64::from(crate::limits::MAX_RADIANCE);
    // Each imported file is decoded once, and its pixels count against the same budget.
    let mut images: std::collections::HashMap<String, std::rc::Rc<Image>> = Default::default();
    let mut cached = |path: &str| -> Result<std::rc::Rc<Image>, String> {
        if let Some(image) = images.get(path) {
            return Ok(image.clone());
        }
        let image = std::rc::Rc::new(load(path)?);
        images.insert(path.to_string(), image.clone());
        Ok(image)
    };
    for op in ops {
        let image = match op {
            PaintOp::Import { path, .. } => {
                let image = cached(path)?;
                work += (image.width * image.height) as f64;
                if work > MAX_REPLAY_WORK {
                    return Err(format!(
                        "the paint log's imported images are too large to replay ({work:.1e} texel and pixel \
                         operations; at most {MAX_REPLAY_WORK:.0e}): import smaller images or fewer of them"
                    ));
                }
                Some(image)
            }
            _ => None,
        };
        apply(&mut texture, op, image.as_deref())?;
        // Repeated multiplies and adds stay finite; imports are repaired and clamped already.
        texture.radiance.iter_mut().flatten().for_each(|v| *v = v.clamp(0.0, ceiling));
    }
    Ok(texture)
}

/// Coverage of a round brush at distance `d`: 1 inside `hardness · radius`, a smoothstep to 0
/// at `radius`.
pub fn brush_coverage(d: f64, radius: f64, hardness: f64) -> f64 {
    let inner = hardness * radius;
    if d <= inner {
        1.0
    } else if d >= radius {
        0.0
    } else {
        let t = (d - inner) / (radius - inner);
        1.0 - t * t * (3.0 - 2.0 * t)
    }
}

/// Per texel, the largest coverage of any dab (a stroke paints each texel once, however many
/// dabs overlap it).
fn stroke_coverage(texture: &LightTexture, points: &[[f64; 2]], radius: f64, hardness: f64) -> Vec<f64> {
    let side = texture.side as f64;
    let mut coverage = vec![0.0f64; texture.side * texture.side];
    for p in points {
        let lo = |c: f64| ((c - radius) * side).floor().max(0.0) as usize;
        let hi = |c: f64| (((c + radius) * side).ceil().max(0.0) as usize).min(texture.side);
        for y in lo(p[1])..hi(p[1]) {
            for x in lo(p[0])..hi(p[0]) {
                let k = y * texture.side + x;
                let c = texture.centre(k);
                let d = ((c[0] - p[0]).powi(2) + (c[1] - p[1]).powi(2)).sqrt();
                coverage[k] = coverage[k].max(brush_coverage(d, radius, hardness));
            }
        }
    }
    coverage
}

/// Applies one operation; `image` is the decoded file of an import.
fn apply(texture: &mut LightTexture, op: &PaintOp, image: Option<&Image>) -> Result<(), String> {
    let n = texture.side;
    match op {
        PaintOp::Stroke { points, radius, hardness, colour, intensity, blend } => {
            let coverage = stroke_coverage(texture, points, *radius, *hardness);
            let paint = colour.map(|c| c * intensity);
            for (texel, w) in texture.radiance.iter_mut().zip(coverage) {
                for c in 0..3 {
                    texel[c] = match blend {
                        Blend::Mix => texel[c] + w * (paint[c] - texel[c]),
                        Blend::Add => texel[c] + w * paint[c],
                        Blend::Multiply => texel[c] * (1.0 + w * (paint[c] - 1.0)),
                    };
                }
            }
        }
        PaintOp::Erase { points, radius, hardness } => {
            let coverage = stroke_coverage(texture, points, *radius, *hardness);
            texture.mask.iter_mut().zip(coverage).for_each(|(m, w)| *m *= 1.0 - w);
        }
        PaintOp::Fill { colour, intensity } => texture.radiance.fill(colour.map(|c| c * intensity)),
        PaintOp::Blur { sigma } => {
            let sigma_texels = sigma * n as f64;
            if sigma_texels > 1e-3 {
                let reach = (3.0 * sigma_texels).ceil() as isize;
                let kernel: Vec<f64> =
                    (-reach..=reach).map(|i| (-(i as f64).powi(2) / (2.0 * sigma_texels.powi(2))).exp()).collect();
                // Separable, clamped at the edges, normalised over the taps inside.
                for pass in 0..2 {
                    let source = texture.radiance.clone();
                    for k in 0..n * n {
                        let (x, y) = ((k % n) as isize, (k / n) as isize);
                        let (mut sum, mut weight) = ([0.0; 3], 0.0);
                        for (t, w) in kernel.iter().enumerate() {
                            let offset = t as isize - reach;
                            let (sx, sy) = if pass == 0 { (x + offset, y) } else { (x, y + offset) };
                            if sx < 0 || sy < 0 || sx >= n as isize || sy >= n as isize {
                                continue;
                            }
                            let s = source[sy as usize * n + sx as usize];
                            for c in 0..3 {
                                sum[c] += w * s[c];
                            }
                            weight += w;
                        }
                        texture.radiance[k] = sum.map(|v| v / weight);
                    }
                }
            }
        }
        PaintOp::Import { path, intensity } => {
            let image = image.ok_or_else(|| format!("`{path}` was not loaded"))?;
            if image.width == 0 || image.height == 0 || image.pixels.len() != image.width * image.height {
                return Err(format!("`{path}` holds no image"));
            }
            // Each texel averages the image pixels whose centres fall in it (nearest when the
            // image is coarser than the texture).
            let mut sums = vec![([0.0; 3], 0.0); n * n];
            for (p, pixel) in image.pixels.iter().enumerate() {
                let u = ((p % image.width) as f64 + 0.5) / image.width as f64;
                let v = ((p / image.width) as f64 + 0.5) / image.height as f64;
                let k = ((v * n as f64) as usize).min(n - 1) * n + ((u * n as f64) as usize).min(n - 1);
                for c in 0..3 {
                    sums[k].0[c] += pixel[c];
                }
                sums[k].1 += 1.0;
            }
            for k in 0..n * n {
                texture.radiance[k] = if sums[k].1 > 0.0 {
                    sums[k].0.map(|v| v / sums[k].1 * intensity)
                } else {
                    let c = texture.centre(k);
                    let x = ((c[0] * image.width as f64) as usize).min(image.width - 1);
                    let y = ((c[1] * image.height as f64) as usize).min(image.height - 1);
                    image.pixels[y * image.width + x].map(|v| v * intensity)
                };
            }
        }
        PaintOp::Warp { offset, scale, angle } => {
            let source = texture.radiance.clone();
            let (sin, cos) = angle.to_radians().sin_cos();
            for k in 0..n * n {
                // Where this texel's content came from: undo the move, turn and scale about
                // the centre.
                let c = texture.centre(k);
                let (x, y) = ((c[0] - offset[0] - 0.5) / scale, (c[1] - offset[1] - 0.5) / scale);
                let from = [cos * x + sin * y + 0.5, -sin * x + cos * y + 0.5];
                texture.radiance[k] = if (0.0..1.0).contains(&from[0]) && (0.0..1.0).contains(&from[1]) {
                    source[((from[1] * n as f64) as usize).min(n - 1) * n + ((from[0] * n as f64) as usize).min(n - 1)]
                } else {
                    [0.0; 3]
                };
            }
        }
        PaintOp::Reshape { shape } => {
            for k in 0..n * n {
                let c = texture.centre(k);
                let inside = match shape {
                    Shape::Rectangle => true,
                    Shape::Disc => (c[0] - 0.5).powi(2) + (c[1] - 0.5).powi(2) <= 0.25,
                };
                if !inside {
                    texture.mask[k] = 0.0;
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
