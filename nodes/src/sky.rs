//! A procedural sky with a sun: the built-in environment of the default project, so a fresh
//! machine needs no image files.

use glam::DVec3;
use serde::{Deserialize, Serialize};

/// Gradient sky (zenith → horizon), a darker ground below the horizon, and a sun disk with a
/// soft aureole. Radiance is linear, in the same arbitrary units as HDR environment maps.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ProceduralSky {
    /// Direction towards the sun (normalised on use).
    pub sun_direction: [f64; 3],
    /// Angular radius of the sun disk, degrees.
    pub sun_radius_deg: f64,
    pub sun_radiance: [f64; 3],
    pub zenith: [f64; 3],
    pub horizon: [f64; 3],
    pub ground: [f64; 3],
}

impl Default for ProceduralSky {
    fn default() -> Self {
        Self {
            sun_direction: [0.4, 0.6, -0.5],
            sun_radius_deg: 2.5,
            sun_radiance: [400.0, 370.0, 320.0],
            zenith: [0.25, 0.45, 0.9],
            horizon: [0.9, 0.95, 1.0],
            ground: [0.25, 0.22, 0.2],
        }
    }
}

impl ProceduralSky {
    /// Radiance arriving from direction `dir` (pointing away from the viewer, into the sky).
    pub fn radiance(&self, dir: DVec3) -> [f64; 3] {
        let d = dir.normalize();
        let sun = DVec3::from(self.sun_direction).normalize();
        let mut out = if d.y >= 0.0 {
            let t = d.y.powf(0.5);
            std::array::from_fn(|c| self.horizon[c] * (1.0 - t) + self.zenith[c] * t)
        } else {
            let t = (-d.y * 8.0).min(1.0);
            std::array::from_fn(|c| self.horizon[c] * 0.5 * (1.0 - t) + self.ground[c] * t)
        };
        let cos_angle = d.dot(sun).clamp(-1.0, 1.0);
        let angle = cos_angle.acos();
        let radius = self.sun_radius_deg.to_radians();
        // Disk with a smooth limb (so it band-limits gracefully) plus a faint aureole.
        let disk = 1.0 - smoothstep(radius * 0.8, radius * 1.2, angle);
        let aureole = 0.02 * (-(angle / (6.0 * radius)).powi(2)).exp();
        for c in 0..3 {
            out[c] += self.sun_radiance[c] * (disk + aureole);
        }
        out
    }
}

fn smoothstep(edge0: f64, edge1: f64, x: f64) -> f64 {
    let t = ((x - edge0) / (edge1 - edge0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}
