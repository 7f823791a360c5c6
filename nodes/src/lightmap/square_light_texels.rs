//! The square lights at lightmap texels, traced. The viewport shades a vertex as
//! `Σᵢ Iᵢ Ωᵢ ρ̄ᵢ V̄ᵢ` (Xu et al. 2006 Eq. 5), with `V̄ᵢ` from visibility distance tables built
//! per vertex. A texel has no table, so the bake estimates the integral itself: the mean of
//! `V cos⁺θ / π` over each light's cap of equal solid angle (the lights are fitted averaged
//! over their turns, so the cap is their rotation-free shape), with shadow rays. It is
//! the quantity Eq. 5 factorises, so texels are at least as accurate as the vertices.

use crate::engine::{CancelToken, StageError};
use crate::raycast::RayScene;
use crate::rsl::WorldLights;
use crate::transport::Receivers;
use glam::{DVec3, Vec3A};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

crate::stage_type!(SquareLightTexels, "square lights at lightmap texels", |v| v.values.len() * 4);

/// Rings × sectors of shadow rays per light and texel.
pub const RINGS: usize = 4;
pub const SECTORS: usize = 4;

/// Per texel and light (`values[texel · lights + light]`): the mean of `V cos⁺θ / π` over the
/// light's cap. `E/π` at a texel is `Σᵢ Iᵢ Ωᵢ values[i]`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SquareLightTexels {
    pub lights: usize,
    pub values: Vec<f32>,
}

/// Traces every light's cap from every receiver, [`RINGS`]` × `[`SECTORS`] rays each,
/// stratified by area on the cap and turned per receiver by a hash of its index (so shadow
/// edges dither instead of banding, and bakes repeat).
pub fn trace(
    scene: &RayScene,
    receivers: &Receivers,
    lights: &WorldLights,
    cancel: &CancelToken,
    progress: &dyn Fn(f64),
) -> Result<SquareLightTexels, StageError> {
    let k = lights.lights.len();
    let caps: Vec<Cap> = lights.lights.iter().map(|l| Cap::new(DVec3::from(l.direction), l.solid_angle)).collect();
    const CHUNK: usize = 1024;
    let mut values = vec![0.0f32; receivers.len() * k];
    for (c, chunk) in values.chunks_mut(CHUNK * k.max(1)).enumerate() {
        if cancel.is_cancelled() {
            return Err(StageError::Cancelled);
        }
        chunk.par_chunks_mut(k.max(1)).enumerate().for_each(|(j, row)| {
            let i = c * CHUNK + j;
            let (position, normal) = receivers.point(i);
            let origin = scene.leave_surface(position, normal);
            let turn = hash_turn(i);
            for (value, cap) in row.iter_mut().zip(&caps) {
                *value = cap.mean_lit_cosine(normal, turn, |d| !scene.occluded(origin, d, f32::INFINITY)) as f32;
            }
        });
        progress(((c + 1) * CHUNK).min(receivers.len()) as f64 / receivers.len().max(1) as f64);
    }
    Ok(SquareLightTexels { lights: k, values })
}

/// A spherical cap around `axis` of solid angle `Ω = 2π(1 − cos θ_c)`.
struct Cap {
    axis: DVec3,
    tangent: DVec3,
    bitangent: DVec3,
    cos_edge: f64,
    sin_edge: f64,
}

impl Cap {
    fn new(axis: DVec3, solid_angle: f64) -> Self {
        let axis = axis.normalize_or(DVec3::Y);
        let (tangent, bitangent) = axis.any_orthonormal_pair();
        let cos_edge = (1.0 - solid_angle / (2.0 * PI)).clamp(-1.0, 1.0);
        Self { axis, tangent, bitangent, cos_edge, sin_edge: (1.0 - cos_edge * cos_edge).sqrt() }
    }

    /// The mean over the cap of `cos⁺θ / π · visible(ω)`, with `visible` asked only where
    /// `cos θ > 0`; zero without a ray when the whole cap is below the horizon.
    fn mean_lit_cosine(&self, normal: DVec3, turn: f64, mut visible: impl FnMut(Vec3A) -> bool) -> f64 {
        // Below the horizon entirely: the axis is more than 90° + θ_c from the normal.
        let cos_axis = normal.dot(self.axis);
        if cos_axis < -self.sin_edge && self.cos_edge > 0.0 {
            return 0.0;
        }
        let mut sum = 0.0;
        for ring in 0..RINGS {
            // Equal-area rings: cos θ uniform in [cos θ_c, 1].
            let cos_theta = 1.0 - (ring as f64 + 0.5) / RINGS as f64 * (1.0 - self.cos_edge);
            let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
            for sector in 0..SECTORS {
                let phi = 2.0 * PI * (sector as f64 + 0.5 * (ring % 2) as f64 + turn) / SECTORS as f64;
                let direction =
                    self.axis * cos_theta + (self.tangent * phi.cos() + self.bitangent * phi.sin()) * sin_theta;
                let cos = normal.dot(direction);
                if cos > 0.0 && visible(Vec3A::from(direction.as_vec3())) {
                    sum += cos / PI;
                }
            }
        }
        sum / (RINGS * SECTORS) as f64
    }
}

/// A turn in `[0, 1)` from `i` (SplitMix64's finaliser).
fn hash_turn(i: usize) -> f64 {
    let mut z = (i as u64).wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    (z ^ (z >> 31)) as f64 / u64::MAX as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Unoccluded, a small cap straight overhead gives `cos θ/π` at its centre, and a cap
    /// of any size matches the closed form of the lit cosine over a cap about the normal,
    /// `(1 + cos θ_c)/(2π)`.
    #[test]
    fn an_open_cap_matches_its_closed_form() {
        for solid_angle in [1e-4, 0.05, 0.5, 2.0] {
            let cap = Cap::new(DVec3::Y, solid_angle);
            let got = cap.mean_lit_cosine(DVec3::Y, 0.3, |_| true);
            let expected = (1.0 + cap.cos_edge) / (2.0 * PI);
            // The stratified rings integrate the linear cos θ exactly.
            assert!((got - expected).abs() < 1e-9 * expected.max(1.0), "Ω {solid_angle}: {got} vs {expected}");
        }
        // Tilted by 60°, a small cap gives cos 60° / π.
        let tilted = DVec3::new(60f64.to_radians().sin(), 60f64.to_radians().cos(), 0.0);
        let small = Cap::new(tilted, 1e-5).mean_lit_cosine(DVec3::Y, 0.0, |_| true);
        assert!((small - 0.5 / PI).abs() < 1e-3 * 0.5 / PI, "{small}");
        // Behind the surface, nothing and no ray.
        let below = Cap::new(-DVec3::Y, 0.2).mean_lit_cosine(DVec3::Y, 0.0, |_| panic!("a ray below the horizon"));
        assert_eq!(below, 0.0);
    }

    /// Half the cap blocked (every direction with x > 0) gives half the open value for a cap
    /// about the normal, to the sampling's stratification.
    #[test]
    fn a_half_blocked_cap_is_half_lit() {
        let cap = Cap::new(DVec3::Y, 0.3);
        let open = cap.mean_lit_cosine(DVec3::Y, 0.1, |_| true);
        let half = cap.mean_lit_cosine(DVec3::Y, 0.1, |d| d.x <= 0.0);
        assert!((half / open - 0.5).abs() < 0.07, "{}", half / open);
    }
}
