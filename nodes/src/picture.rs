//! What node previews show (plain data: the graph model holds them without depending on the
//! techniques that make them, [`crate::preview`] and [`crate::brdf`]).

use serde::{Deserialize, Serialize};

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(PreviewImage, "preview image", |v| v.rgba.len() * 4);

/// An 8-bit sRGB image with alpha (row 0 at the top).
#[derive(Clone, Debug, PartialEq)]
pub struct PreviewImage {
    pub width: usize,
    pub height: usize,
    pub rgba: Vec<[u8; 4]>,
}

/// A preview's content.
#[derive(Clone, Debug)]
pub enum Preview {
    Image(PreviewImage),
    /// Curves of `f·cos θ_i` in the plane of incidence.
    Lobe(LobePreview),
}

/// What the BRDF editor's node shows: the lobe `f(ω_i, ω_o)·cos θ_i` in the plane of
/// incidence for a few outgoing angles, and the directional albedo at each.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LobePreview {
    /// Outgoing polar angles (degrees) of the curves.
    pub theta_out_deg: Vec<f64>,
    /// Per curve: luminance of `f·cos θ_i` at incoming angles `-90..=90°` in 1° steps
    /// (negative angles on the mirror side of the normal).
    pub curves: Vec<Vec<f32>>,
    /// Per curve: `∫ f cos θ_i dω_i` (luminance), by quadrature.
    pub directional_albedo: Vec<f64>,
}

/// The sRGB transfer function inverted: an encoded value in `[0, 1]` to linear.
pub fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}
