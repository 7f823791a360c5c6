//! A painted area-light texture: an operation log replayed onto a linear HDR RGB image with an
//! emission mask (the area-light painter of Sun 2008 §4.5.6: paint, blend, filter, warp,
//! reshape). Projects store the log and the source images' paths, never the pixels or the
//! coefficients, so every edit is one appended operation and replay is deterministic.
//!
//! Coordinates are the light's `[0, 1)²` (`u` along the light's width, `v` along its depth),
//! resolution-independent, so the same log renders at 32², 64² or 128².

use serde::{Deserialize, Serialize};

/// Texture sides the painter renders at.
pub const RESOLUTIONS: [usize; 3] = [32, 64, 128];
/// Operations a log may hold, and dabs a stroke may hold: bounds on replay time.
pub const MAX_OPERATIONS: usize = 10_000;
pub const MAX_DABS: usize = 100_000;

/// How a stroke's colour combines with the texture under it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Blend {
    /// Replace, by the brush's coverage.
    Mix,
    Add,
    Multiply,
}

/// An emission shape: the mask outside it is zero.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Shape {
    Rectangle,
    Disc,
}

/// One edit of the texture.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum PaintOp {
    /// Dabs of a round brush at `points`; `radius` in light units, `hardness` the share of
    /// the radius at full strength (the rest falls off smoothly).
    Stroke { points: Vec<[f64; 2]>, radius: f64, hardness: f64, colour: [f64; 3], intensity: f64, blend: Blend },
    /// The same brush lowering the emission mask.
    Erase { points: Vec<[f64; 2]>, radius: f64, hardness: f64 },
    /// The whole texture set to one radiance.
    Fill { colour: [f64; 3], intensity: f64 },
    /// A Gaussian blur of this standard deviation (light units).
    Blur { sigma: f64 },
    /// An image file (EXR, HDR, PNG; relative to the project), resampled over the light and
    /// scaled by `intensity`.
    Import { path: String, intensity: f64 },
    /// The content moved, scaled about the centre and turned (degrees), with zero radiance
    /// where nothing maps.
    Warp { offset: [f64; 2], scale: f64, angle: f64 },
    /// The mask cut to a shape inscribed in the light.
    Reshape { shape: Shape },
}

impl PaintOp {
    /// Checks ranges; the error names the problem.
    pub fn check(&self) -> Result<(), String> {
        let finite = |v: f64, what: &str| {
            if v.is_finite() { Ok(()) } else { Err(format!("the {what} of a paint operation is {v}")) }
        };
        let brush = |points: &[[f64; 2]], radius: f64, hardness: f64| -> Result<(), String> {
            if points.len() > MAX_DABS {
                return Err(format!("a stroke has {} dabs; at most {MAX_DABS}", points.len()));
            }
            points.iter().flatten().try_for_each(|v| finite(*v, "stroke point"))?;
            finite(radius, "brush radius")?;
            if !(1e-4..=2.0).contains(&radius) {
                return Err(format!("brush radius {radius} is outside 0.0001..=2 (light units)"));
            }
            if !(0.0..=1.0).contains(&hardness) {
                return Err(format!("brush hardness {hardness} is outside 0..=1"));
            }
            Ok(())
        };
        let radiance = |colour: &[f64; 3], intensity: f64| -> Result<(), String> {
            colour.iter().chain([&intensity]).try_for_each(|v| finite(*v, "colour or intensity"))?;
            if colour.iter().any(|c| *c < 0.0) || !(0.0..=1e6).contains(&intensity) {
                return Err("paint colour must be non-negative and intensity within 0..=1e6".into());
            }
            Ok(())
        };
        match self {
            PaintOp::Stroke { points, radius, hardness, colour, intensity, .. } => {
                brush(points, *radius, *hardness)?;
                radiance(colour, *intensity)
            }
            PaintOp::Erase { points, radius, hardness } => brush(points, *radius, *hardness),
            PaintOp::Fill { colour, intensity } => radiance(colour, *intensity),
            PaintOp::Blur { sigma } => {
                finite(*sigma, "blur")?;
                if (0.0..=1.0).contains(sigma) { Ok(()) } else { Err(format!("blur {sigma} is outside 0..=1")) }
            }
            PaintOp::Import { intensity, .. } => radiance(&[1.0; 3], *intensity),
            PaintOp::Warp { offset, scale, angle } => {
                offset.iter().chain([scale, angle]).try_for_each(|v| finite(*v, "warp"))?;
                if (1e-3..=1e3).contains(scale) {
                    Ok(())
                } else {
                    Err(format!("warp scale {scale} is outside 0.001..=1000"))
                }
            }
            PaintOp::Reshape { .. } => Ok(()),
        }
    }
}

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

    fn centre(&self, k: usize) -> [f64; 2] {
        let s = self.side as f64;
        [((k % self.side) as f64 + 0.5) / s, ((k / self.side) as f64 + 0.5) / s]
    }
}

/// A decoded image for [`PaintOp::Import`]: `width × height` linear RGB, row-major, top row
/// first (it maps to `v = 0`).
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<[f64; 3]>,
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
    let mut texture = LightTexture { side, radiance: vec![[1.0; 3]; side * side], mask: vec![1.0; side * side] };
    for op in ops {
        op.check()?;
        apply(&mut texture, op, load)?;
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

fn apply(
    texture: &mut LightTexture,
    op: &PaintOp,
    load: &mut dyn FnMut(&str) -> Result<Image, String>,
) -> Result<(), String> {
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
            let image = load(path)?;
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
