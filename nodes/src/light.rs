//! Lights as every technique sees them: plain data, whatever node made them.
//!
//! A point light radiates `I(ω) = intensity · P(ω)` W/sr towards `ω`, where the angular profile
//! `P` is 1 for an isotropic light, and for a spot or a photometric (IES) light a table over the
//! light's own frame with values in `[0, 1]`. Irradiance at distance `d` on a surface whose
//! normal makes angle `θ` with the way to the light is `I(ω) cos θ / d²`. Every consumer that
//! lights with it (the viewport's shading, the bake, the probes, the Monte Carlo reference)
//! evaluates the profile through [`PointLight::intensity_toward`] or the same table on the
//! GPU, so a new kind of light that fills in a profile needs no change anywhere else; the glTF
//! export, whose lights have no profiles, keeps a spot's beam or else the mean intensity.

use glam::{DMat3, DVec3};
use std::f64::consts::PI;
use std::sync::Arc;

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(Vec<PointLight>, "lights", |v| v.len() * 48
    + v.iter().filter_map(|l| l.profile.as_ref()).map(|p| p.values.len() * 4).sum::<usize>());

/// Rows of a profile's table: polar angle `θ` from the light's axis, `0..=π` inclusive.
pub const PROFILE_THETA: usize = 129;
/// Columns of a profile's table: azimuth `φ` about the axis, `[0, 2π)`, wrapping.
pub const PROFILE_PHI: usize = 64;

/// A point light.
#[derive(Clone, Debug, PartialEq)]
pub struct PointLight {
    pub position: [f64; 3],
    /// Radiant intensity per channel, W/sr, where the profile is 1 (everywhere for an
    /// isotropic light).
    pub intensity: [f64; 3],
    /// How the intensity varies with direction (none: isotropic).
    pub profile: Option<Arc<AngularProfile>>,
}

impl PointLight {
    /// An isotropic point light.
    pub fn isotropic(position: [f64; 3], intensity: [f64; 3]) -> Self {
        Self { position, intensity, profile: None }
    }

    /// Radiant intensity per channel (W/sr) leaving the light along the unit vector `dir`.
    pub fn intensity_toward(&self, dir: DVec3) -> [f64; 3] {
        let p = self.profile.as_ref().map_or(1.0, |p| p.toward(dir));
        self.intensity.map(|c| c * p)
    }

    /// Total radiant flux per channel (W): `∫ I(ω) dω`.
    pub fn flux(&self) -> [f64; 3] {
        let scale = self.profile.as_ref().map_or(4.0 * PI, |p| p.integral());
        self.intensity.map(|c| c * scale)
    }
}

/// A light's intensity relative to its peak over directions in its own frame: a table over
/// `(θ, φ)` (rows `θ` from the axis, [`PROFILE_THETA`] of them from 0 to π; columns `φ` about
/// it, [`PROFILE_PHI`] of them from 0, wrapping), read bilinearly, as the viewport's shader
/// reads the same table (`fog.wgsl` `light_profile`).
#[derive(Clone, Debug, PartialEq)]
pub struct AngularProfile {
    /// World directions of the light's frame: `x` (where `φ = 0`), `y` (`φ = 90°`) and the
    /// axis `z` (`θ = 0`), orthonormal.
    pub frame: DMat3,
    /// `PROFILE_THETA × PROFILE_PHI` values in `[0, 1]`, row by row.
    pub values: Vec<f32>,
    /// The beam, `(inner, outer)` half-angles in radians, of a light that shines into at most
    /// a hemisphere: what formats without profiles (glTF's `KHR_lights_punctual`) keep of it.
    pub cone: Option<(f64, f64)>,
}

impl AngularProfile {
    /// The profile `f(θ, φ)` (radians) sampled on the table, with its axis along `axis` and
    /// `φ = 0` turned `spin` radians about it from a fixed reference direction. Values are
    /// clamped to `[0, 1]`.
    pub fn tabulate(axis: DVec3, spin: f64, f: impl Fn(f64, f64) -> f64) -> Self {
        let z = axis.try_normalize().unwrap_or(DVec3::NEG_Y);
        // φ = 0 points along the world direction least aligned with the axis, projected.
        let reference = if z.y.abs() < 0.9 { DVec3::Y } else { DVec3::Z };
        let x0 = (reference - z * z.dot(reference)).normalize();
        let y0 = z.cross(x0);
        let (s, c) = spin.sin_cos();
        let x = x0 * c + y0 * s;
        let frame = DMat3::from_cols(x, z.cross(x), z);
        let mut values = Vec::with_capacity(PROFILE_THETA * PROFILE_PHI);
        for row in 0..PROFILE_THETA {
            let theta = PI * row as f64 / (PROFILE_THETA - 1) as f64;
            for col in 0..PROFILE_PHI {
                let phi = 2.0 * PI * col as f64 / PROFILE_PHI as f64;
                values.push(f(theta, phi).clamp(0.0, 1.0) as f32);
            }
        }
        Self { frame, values, cone: None }
    }

    /// The profile towards the world unit vector `dir` (bilinear in `θ` and `φ`).
    pub fn toward(&self, dir: DVec3) -> f64 {
        let local = self.frame.transpose() * dir;
        let theta = local.z.clamp(-1.0, 1.0).acos();
        let phi = local.y.atan2(local.x).rem_euclid(2.0 * PI);
        self.at(theta, phi)
    }

    /// The profile at `(θ, φ)` in the light's frame (radians; bilinear between samples).
    pub fn at(&self, theta: f64, phi: f64) -> f64 {
        let y = (theta / PI).clamp(0.0, 1.0) * (PROFILE_THETA - 1) as f64;
        let x = phi.rem_euclid(2.0 * PI) / (2.0 * PI) * PROFILE_PHI as f64;
        let (y0, x0) = (y.floor() as usize, x.floor() as usize);
        let (ty, tx) = (y - y0 as f64, x - x0 as f64);
        let y1 = (y0 + 1).min(PROFILE_THETA - 1);
        let (x0, x1) = (x0 % PROFILE_PHI, (x0 + 1) % PROFILE_PHI);
        let v = |r: usize, c: usize| f64::from(self.values[r * PROFILE_PHI + c]);
        let top = v(y0, x0) * (1.0 - tx) + v(y0, x1) * tx;
        let bottom = v(y1, x0) * (1.0 - tx) + v(y1, x1) * tx;
        top * (1.0 - ty) + bottom * ty
    }

    /// `∫ P(ω) dω` over the sphere (sr), by the midpoint rule on a grid finer than the table.
    pub fn integral(&self) -> f64 {
        let (rows, cols) = (4 * PROFILE_THETA, 2 * PROFILE_PHI);
        let (d_theta, d_phi) = (PI / rows as f64, 2.0 * PI / cols as f64);
        let mut sum = 0.0;
        for r in 0..rows {
            let theta = (r as f64 + 0.5) * d_theta;
            let ring: f64 = (0..cols).map(|c| self.at(theta, (c as f64 + 0.5) * d_phi)).sum();
            sum += ring * theta.sin() * d_theta * d_phi;
        }
        sum
    }
}

/// A spot's cone: 1 inside `inner` (radians from the axis), 0 outside `outer`, and a smooth
/// step between (as Blender's spot blend and glTF's `KHR_lights_punctual` cones).
pub fn cone(theta: f64, inner: f64, outer: f64) -> f64 {
    if theta <= inner {
        return 1.0;
    }
    if theta >= outer {
        return 0.0;
    }
    let t = (outer - theta) / (outer - inner).max(1e-9);
    t * t * (3.0 - 2.0 * t)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An isotropic profile integrates to 4π and a cone of half-angle α with a hard edge to
    /// `2π(1 − cos α)`, within the table's resolution.
    #[test]
    fn profiles_integrate_to_their_solid_angles() {
        let flat = AngularProfile::tabulate(DVec3::Y, 0.0, |_, _| 1.0);
        assert!((flat.integral() / (4.0 * PI) - 1.0).abs() < 1e-5, "{}", flat.integral());
        let alpha = 30f64.to_radians();
        let spot = AngularProfile::tabulate(DVec3::NEG_Y, 0.0, |t, _| cone(t, alpha, alpha + 1e-6));
        let exact = 2.0 * PI * (1.0 - alpha.cos());
        // The edge is smeared over one row (1.4°): about that band's area.
        assert!((spot.integral() / exact - 1.0).abs() < 0.05, "{} vs {exact}", spot.integral());
    }

    /// The frame puts the axis where asked and `φ` where the spin turns it; a light's
    /// intensity follows its profile.
    #[test]
    fn a_profile_is_read_in_the_lights_frame() {
        let axis = DVec3::new(1.0, -1.0, 0.5).normalize();
        let lobe = |t: f64, p: f64| t.cos().max(0.0) * (0.75 + 0.25 * p.cos() * t.sin());
        let profile = AngularProfile::tabulate(axis, 0.3, lobe);
        assert!((profile.toward(axis) - 0.75).abs() < 1e-6);
        assert!(profile.toward(-axis) < 1e-6);
        let x = profile.frame.x_axis;
        assert!(x.dot(axis).abs() < 1e-12 && (profile.frame.z_axis - axis).length() < 1e-12);
        let off = (axis * 45f64.to_radians().cos() + x * 45f64.to_radians().sin()).normalize();
        assert!((profile.toward(off) - lobe(45f64.to_radians(), 0.0)).abs() < 2e-3, "{}", profile.toward(off));
        let light = PointLight { position: [0.0; 3], intensity: [2.0, 4.0, 6.0], profile: Some(Arc::new(profile)) };
        let i = light.intensity_toward(off);
        assert!((i[1] / i[0] - 2.0).abs() < 1e-12 && i[0] < 2.0);
        assert_eq!(PointLight::isotropic([0.0; 3], [1.0; 3]).intensity_toward(DVec3::X), [1.0; 3]);
    }
}
