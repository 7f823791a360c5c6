//! Painted area lights in the reference: emission sampled from the texture itself on the
//! turned rectangle (not from the resampled or compressed form the relighting reads), with
//! shadow rays to the sampled point.

use glam::DVec3;
use serde::{Deserialize, Serialize};

/// A planar light: a `width × depth` rectangle centred at `centre`, facing down, tilted by
/// `tilt` degrees about its width axis and turned by `angle` degrees about the vertical (both
/// right-handed; [`crate::near_field::LightFrame`]), emitting `radiance` (texel `(i, j)` at
/// `j·side + i`, `i` along the light's width) uniformly in angle from its facing side.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AreaEmitter {
    pub centre: [f64; 3],
    pub width: f64,
    pub depth: f64,
    pub angle: f64,
    pub tilt: f64,
    pub side: usize,
    pub radiance: Vec<[f64; 3]>,
    /// Cumulative `r + g + b` over the texels (the sampling density); empty for a dark light.
    cdf: Vec<f64>,
}

impl AreaEmitter {
    pub fn new(centre: [f64; 3], (width, depth, angle): (f64, f64, f64), side: usize, radiance: Vec<[f64; 3]>) -> Self {
        let mut total = 0.0;
        let mut cdf: Vec<f64> = radiance
            .iter()
            .map(|c| {
                total += (c[0] + c[1] + c[2]).max(0.0);
                total
            })
            .collect();
        if total <= 0.0 || !total.is_finite() {
            cdf.clear();
        }
        Self { centre, width, depth, angle, tilt: 0.0, side, radiance, cdf }
    }

    /// The light tilted by `tilt` degrees about its width axis.
    pub fn tilted(self, tilt: f64) -> Self {
        Self { tilt, ..self }
    }

    /// Light coordinates to world offsets from the centre: tilt about the width axis (x), then turn about +y.
    fn orientation(&self) -> glam::DMat3 {
        crate::near_field::light_orientation(self.angle, self.tilt)
    }

    /// The world point at light coordinates `(u, v) ∈ [0, 1)²`.
    pub fn point(&self, u: f64, v: f64) -> DVec3 {
        let (a, b) = ((u - 0.5) * self.width, (v - 0.5) * self.depth);
        DVec3::from(self.centre) + self.orientation() * DVec3::new(a, 0.0, b)
    }

    /// The direction the light faces (the normal of its emitting side).
    pub fn facing(&self) -> DVec3 {
        self.orientation() * DVec3::NEG_Y
    }

    /// A point on the light by `u` (texels by their `r + g + b`, uniform within one), its
    /// radiance and its area density; `None` for a dark light.
    pub fn sample(&self, u: [f64; 3]) -> Option<(DVec3, DVec3, f64)> {
        let total = *self.cdf.last()?;
        let k = self.cdf.partition_point(|&c| c <= u[0] * total).min(self.cdf.len() - 1);
        let n = self.side as f64;
        let (i, j) = ((k % self.side) as f64, (k / self.side) as f64);
        let point = self.point((i + u[1]) / n, (j + u[2]) / n);
        let c = self.radiance[k];
        let texel_area = self.width * self.depth / (n * n);
        let pdf = (c[0] + c[1] + c[2]) / total / texel_area;
        Some((point, DVec3::from(c), pdf))
    }

    /// Radiance emitted towards a point at `x` in front of the light (direct lighting at `x`
    /// from the point `p` on the light, `p − x` normalised to `wi`): `(wi, distance, L cos θ_l /
    /// d²)` per unit area, `None` behind its plane.
    pub fn towards(&self, x: DVec3, p: DVec3) -> Option<(DVec3, f64, f64)> {
        let d = p - x;
        let dist = d.length();
        let cos_light = -d.dot(self.facing()) / dist;
        (cos_light > 0.0 && dist > 0.0).then(|| (d / dist, dist, cos_light / (dist * dist)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::test_rng;
    use rand::Rng;

    /// Irradiance at a point below a constant light, by sampling it, equals the closed form
    /// for a rectangle parallel to the receiver.
    #[test]
    fn sampled_irradiance_matches_the_parallel_rectangle_closed_form() {
        // E = L ∫∫ h² / (h² + x² + z²)² dx dz over [x0, x1] × [z0, z1] (receiver at the origin,
        // light at height h), whose antiderivative is F(x, z) = x/(2a) atan(z/a) +
        // z/(2b) atan(x/b) with a = √(h² + x²), b = √(h² + z²).
        let closed = |x: f64, z: f64, h: f64| {
            let (a, b) = ((h * h + x * x).sqrt(), (h * h + z * z).sqrt());
            x / (2.0 * a) * (z / a).atan() + z / (2.0 * b) * (x / b).atan()
        };
        let (h, x0, x1, z0, z1) = (1.5, -0.4, 1.1, 0.2, 0.9);
        let exact = 3.0 * (closed(x1, z1, h) - closed(x0, z1, h) - closed(x1, z0, h) + closed(x0, z0, h));
        let side = 8;
        let emitter = AreaEmitter::new(
            [(x0 + x1) / 2.0, h, (z0 + z1) / 2.0],
            (x1 - x0, z1 - z0, 0.0),
            side,
            vec![[3.0, 3.0, 3.0]; side * side],
        );
        let mut rng = test_rng(5);
        let n = 200_000;
        let mut e = 0.0;
        for _ in 0..n {
            let (p, radiance, pdf) = emitter.sample([rng.random(), rng.random(), rng.random()]).unwrap();
            let (wi, _, g) = emitter.towards(DVec3::ZERO, p).unwrap();
            e += radiance.x * wi.y * g / pdf;
        }
        e /= n as f64;
        assert!((e - exact).abs() < 0.01 * exact, "sampled {e}, closed form {exact}");
    }

    /// Irradiance below a tilted, turned light, by sampling it, equals Lambert's closed form for
    /// its rectangle in the world; a point behind its plane receives nothing.
    #[test]
    fn a_tilted_light_samples_like_the_polygon_closed_form() {
        let emitter = AreaEmitter::new([0.3, 2.0, -0.4], (1.5, 0.8, 25.0), 4, vec![[2.0; 3]; 16]).tilted(60.0);
        let corners: Vec<DVec3> =
            [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)].map(|(u, v)| emitter.point(u, v)).into();
        let (x, normal) = (DVec3::new(-0.5, 0.2, -1.6), DVec3::new(0.3, 1.0, -0.2).normalize());
        let exact = 2.0 * crate::near_field::beyond_face::polygon_irradiance(x, normal, &corners);
        let mut rng = test_rng(9);
        let n = 200_000;
        let mut e = 0.0;
        for _ in 0..n {
            let (p, radiance, pdf) = emitter.sample([rng.random(), rng.random(), rng.random()]).unwrap();
            if let Some((wi, _, g)) = emitter.towards(x, p) {
                e += radiance.x * wi.dot(normal).max(0.0) * g / pdf;
            }
        }
        e /= n as f64;
        assert!(exact > 0.05 && (e - exact).abs() < 0.01 * exact, "sampled {e}, closed form {exact}");
        // Behind the light (on the side its facing points away from), nothing.
        let behind = DVec3::from(emitter.centre) - emitter.facing();
        assert!(emitter.towards(behind, emitter.point(0.5, 0.5)).is_none());
    }

    /// A quarter turn (right-handed about +y) maps the light's width onto −z, and the emitter
    /// puts every texel where `LightTexture::turned` does.
    #[test]
    fn a_turned_light_lies_where_the_resampled_texture_puts_it() {
        let emitter = AreaEmitter::new([1.0, 2.0, -1.0], (2.0, 1.0, 90.0), 4, vec![[1.0; 3]; 16]);
        let corner = emitter.point(1.0, 0.5);
        let turned_x = glam::DQuat::from_rotation_y(90f64.to_radians()) * DVec3::X;
        assert!((corner - (DVec3::new(1.0, 2.0, -1.0) + turned_x)).length() < 1e-12, "{corner}");
        let texture = crate::light_texture::LightTexture {
            side: 4,
            radiance: (0..16).map(|k| [k as f64; 3]).collect(),
            mask: vec![1.0; 16],
        };
        let turned = texture.turned(2.0, 1.0, 90.0);
        let extent = crate::light_texture::turned_extent(2.0, 1.0, 90.0);
        // Every texel of the turned rectangle holds the texel the emitter puts at its centre.
        for k in 0..16 {
            let (cx, cz) = (((k % 4) as f64 + 0.5) / 4.0, ((k / 4) as f64 + 0.5) / 4.0);
            let world = [1.0 + (cx - 0.5) * extent[0], -1.0 + (cz - 0.5) * extent[1]];
            let found = (0..16).find(|&t| {
                let p = emitter.point(((t % 4) as f64 + 0.5) / 4.0, ((t / 4) as f64 + 0.5) / 4.0);
                (p.x - world[0]).abs() < 1e-9 && (p.z - world[1]).abs() < 1e-9
            });
            let t = found.unwrap_or_else(|| panic!("no emitter texel at turned texel {k}"));
            assert_eq!(turned[k], [t as f64; 3], "texel {k}");
        }
    }
}
