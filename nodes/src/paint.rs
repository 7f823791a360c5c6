//! A light texture's paint operations: the data a project stores for a painted area light
//! (replayed by `crate::light_texture`). Coordinates are the light's `[0, 1)²`.

use serde::{Deserialize, Serialize};

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
    /// The image file an import reads (relative to the project).
    pub fn file(&self) -> Option<&str> {
        match self {
            PaintOp::Import { path, .. } if !path.is_empty() => Some(path),
            _ => None,
        }
    }

    pub fn file_mut(&mut self) -> Option<&mut String> {
        match self {
            PaintOp::Import { path, .. } if !path.is_empty() => Some(path),
            _ => None,
        }
    }

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
            if colour.iter().any(|c| !(0.0..=1e6).contains(c)) || !(0.0..=1e6).contains(&intensity) {
                return Err("paint colour components and intensity must be within 0..=1e6".into());
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
