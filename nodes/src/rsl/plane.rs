//! The hemisphere-to-disc map of Xu et al. 2006 §5: `p(θ, φ) = sinθ/√(1+cosθ) · (cosφ, sinφ)`,
//! that is `p = (x, y)/√(1+z)` for a unit direction in the local frame (normal `+z`).
//!
//! `|p|² = 1 − z`, so this is Lambert's azimuthal equal-area map scaled by `1/√2`: plane area
//! is exactly half the solid angle (notes §1.6), and a mean over a plane region equals the mean
//! over its spherical preimage without a Jacobian (Eq. 6). The upper hemisphere fills the unit
//! disc; the lower one the ring out to `|p| = √2`. (The paper writes `(sinφ, cosφ)`, a
//! reflection of this map; nothing depends on the choice.)

use glam::{DVec2, DVec3};

/// Plane point of a unit direction (local frame). The nadir, which has no single image, maps
/// to the ring `|p| = √2` along `+x`.
pub fn to_plane(d: DVec3) -> DVec2 {
    let s = 1.0 + d.z;
    if s <= 1e-12 {
        return DVec2::new(std::f64::consts::SQRT_2, 0.0);
    }
    DVec2::new(d.x, d.y) / s.sqrt()
}

/// Unit direction of a plane point with `|p| ≤ √2` (points beyond are pulled onto that ring).
pub fn from_plane(p: DVec2) -> DVec3 {
    let r2 = p.length_squared().min(2.0);
    let scale = (2.0 - r2).sqrt();
    DVec3::new(p.x * scale, p.y * scale, 1.0 - r2).normalize()
}

/// Edge of the plane square of a light of solid angle `omega` (plane area = `Ω/2`).
pub fn square_edge(omega: f64) -> f64 {
    (omega / 2.0).sqrt()
}

/// Texel coordinates (in texels, `0..n`) of a plane point on an `n × n` grid over `[-1, 1]²`.
pub fn to_texels(p: f64, n: usize) -> f64 {
    (p + 1.0) * 0.5 * n as f64
}

/// Plane coordinate of a texel coordinate (the inverse of [`to_texels`]).
pub fn from_texels(t: f64, n: usize) -> f64 {
    t / n as f64 * 2.0 - 1.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::test_rng;
    use rand::Rng;

    #[test]
    fn round_trips_and_maps_the_rim_to_the_unit_circle() {
        let mut rng = test_rng(3);
        for _ in 0..1000 {
            let d = crate::sampling::uniform_sphere(rng.random(), rng.random());
            if d.z < -0.999 {
                continue;
            }
            let back = from_plane(to_plane(d));
            assert!((back - d).length() < 1e-9, "{d} -> {back}");
        }
        for k in 0..16 {
            let a = k as f64 * 0.4;
            let p = to_plane(DVec3::new(a.cos(), a.sin(), 0.0));
            assert!((p.length() - 1.0).abs() < 1e-12);
        }
        assert!(to_plane(DVec3::Z).length() < 1e-12);
    }

    #[test]
    fn plane_area_is_half_the_solid_angle() {
        // Monte Carlo: uniform points on the sphere; the fraction landing in a plane region,
        // times 4π, is its solid angle; it must be twice the region's exact plane area.
        let mut rng = test_rng(4);
        let n = 400_000;
        let (mut in_disc, mut in_box) = (0usize, 0usize);
        for _ in 0..n {
            let d = crate::sampling::uniform_sphere(rng.random(), rng.random());
            let p = to_plane(d);
            in_disc += (p.length() <= 1.0) as usize;
            in_box += (p.x > 0.1 && p.x < 0.6 && p.y > -0.3 && p.y < 0.2) as usize;
        }
        let solid = |count: usize| count as f64 / n as f64 * 4.0 * std::f64::consts::PI;
        assert!((solid(in_disc) - 2.0 * std::f64::consts::PI).abs() < 0.03, "{}", solid(in_disc));
        assert!((solid(in_box) - 2.0 * 0.25).abs() < 0.015, "{}", solid(in_box));
    }
}
