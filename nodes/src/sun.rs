//! Dominant-light separation: a sun found in an environment map becomes a uniform disc light,
//! shadowed per pixel in the viewport (shadow maps over the disc), and the precomputed
//! transport carries only the residual sky. Cell-averaged (Ma et al.) or band-limited (SH)
//! lighting smears a small, bright source into blocky shadows and banding; the residual is
//! smooth, so the same coefficients represent it far better.
//!
//! The split conserves the map's power: the residual plus the disc integrate, against any
//! clamped cosine, to the original map's irradiance up to the disc's shape (a uniform disc with
//! the sun's power, power-weighted centroid and second angular moment).

use crate::cubemap::CubeMap;
use glam::DVec3;

/// Texels brighter than this share of the brightest one (and within [`MAX_RADIUS_DEG`] of it)
/// belong to the sun.
pub const THRESHOLD: f64 = 0.025;
/// A source wider than this (angular radius) is sky, not a sun.
pub const MAX_RADIUS_DEG: f64 = 12.0;
/// A sun carrying less than this share of the map's luminous power is left in the map.
pub const MIN_POWER_SHARE: f64 = 0.01;
/// A sun must be this many times brighter than the sky around it.
pub const MIN_CONTRAST: f64 = 20.0;
/// How many sample directions over the disc the viewport shadows (one shadow map each).
pub const DISC_SAMPLES: usize = 32;

/// A uniform disc light at infinity.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Sun {
    /// Unit vector towards the sun's centre.
    pub direction: [f64; 3],
    /// Angular radius, radians.
    pub radius: f64,
    /// Radiance inside the disc.
    pub radiance: [f64; 3],
}

impl Sun {
    pub fn solid_angle(&self) -> f64 {
        std::f64::consts::TAU * (1.0 - self.radius.cos())
    }

    /// Power per channel: radiance times solid angle.
    pub fn power(&self) -> [f64; 3] {
        self.radiance.map(|l| l * self.solid_angle())
    }

    /// The disc turned by `rotation`.
    pub fn rotated(&self, rotation: glam::DMat3) -> Self {
        Self { direction: (rotation * DVec3::from(self.direction)).normalize().to_array(), ..*self }
    }

    /// `count` directions spreading the disc evenly (equal solid angle each). The inner
    /// `count - rim_directions(count)` follow a Fibonacci spiral (uniform steps in `cos θ`, the
    /// golden angle in azimuth) over the inner part of the cap; the last `rim_directions(count)`
    /// sit at equal azimuth steps in the middle of the outer ring of equal solid angle, so the
    /// viewport can test them first: a shadow edge that reaches none of them covers at most the
    /// circular segment between two neighbours (about 1.2% of the disc with 8).
    pub fn disc_directions(&self, count: usize) -> Vec<DVec3> {
        let axis = DVec3::from(self.direction).normalize();
        let (t, b) = axis.any_orthonormal_pair();
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let rim = rim_directions(count);
        let inner = count - rim;
        let at = |u: f64, phi: f64| {
            let cos_theta = 1.0 - u * (1.0 - self.radius.cos());
            let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
            (axis * cos_theta + (t * phi.cos() + b * phi.sin()) * sin_theta).normalize()
        };
        let spiral = (0..inner).map(|i| at((i as f64 + 0.5) / count as f64, i as f64 * golden));
        let ring = (0..rim).map(|k| {
            let u = 1.0 - rim as f64 / (2.0 * count as f64);
            at(u, std::f64::consts::TAU * k as f64 / rim as f64)
        });
        spiral.chain(ring).collect()
    }

    /// Radiance of the disc in direction `dir`.
    pub fn radiance_towards(&self, dir: DVec3) -> [f64; 3] {
        if dir.normalize().dot(DVec3::from(self.direction)) >= self.radius.cos() { self.radiance } else { [0.0; 3] }
    }
}

/// How many of [`Sun::disc_directions`]'s directions (the last ones) lie evenly on its rim:
/// a quarter of them from 16 on, none below (the viewport tests them first, told the count).
pub fn rim_directions(count: usize) -> usize {
    if count >= 16 { count / 4 } else { 0 }
}

/// An environment split into a sun and what remains.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SunSplit {
    /// `None` when the map has no dominant compact source (then `residual` is the map).
    pub sun: Option<Sun>,
    /// The map with the sun's texels replaced by the sky around it.
    pub residual: CubeMap,
}

fn luminance(c: [f32; 3]) -> f64 {
    0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64
}

impl SunSplit {
    /// The split of the map scaled per channel by `scale` (exposure and tint): the same sun and
    /// residual, their radiance scaled.
    pub fn scaled(&self, scale: [f64; 3]) -> Self {
        Self {
            sun: self.sun.map(|s| Sun { radiance: std::array::from_fn(|c| s.radiance[c] * scale[c]), ..s }),
            residual: CubeMap {
                size: self.residual.size,
                texels: self
                    .residual
                    .texels
                    .iter()
                    .map(|t| std::array::from_fn(|c| (f64::from(t[c]) * scale[c]) as f32))
                    .collect(),
            },
        }
    }
}

/// Finds the brightest compact source of `map` and separates it (see the module docs).
pub fn split(map: &CubeMap) -> SunSplit {
    let keep = || SunSplit { sun: None, residual: map.clone() };
    if map.size == 0 || map.texels.is_empty() {
        return keep();
    }
    let n = map.size;
    let solid_angles = map.face_solid_angles();
    let texel = |i: usize| (i / (n * n), i % n, (i / n) % n);
    let dir_of = |i: usize| {
        let (f, x, y) = texel(i);
        map.texel_dir(f, x, y)
    };
    let weight = |i: usize| solid_angles[i % (n * n)];
    let lum: Vec<f64> = map.texels.iter().map(|&t| luminance(t)).collect();
    let Some(peak) = (0..lum.len()).filter(|&i| lum[i].is_finite()).max_by(|&a, &b| lum[a].total_cmp(&lum[b])) else {
        return keep();
    };
    if lum[peak] <= 0.0 {
        return keep();
    }
    let peak_dir = dir_of(peak);
    let cos_peak: Vec<f64> = map.samples().map(|(d, _, _)| d.dot(peak_dir)).collect();
    let cos_max = MAX_RADIUS_DEG.to_radians().cos();
    let threshold = THRESHOLD * lum[peak];
    // Non-finite texels (a broken map) belong to neither the sun nor the sky around it.
    let in_region = |i: usize| lum[i].is_finite() && lum[i] > threshold && cos_peak[i] >= cos_max;
    let region: Vec<usize> = (0..lum.len()).filter(|&i| in_region(i)).collect();
    // The sky behind the sun: the median of a ring three texels wide around the region.
    let region_cos = region.iter().map(|&i| cos_peak[i]).fold(1.0f64, f64::min);
    let texel_angle = std::f64::consts::FRAC_PI_2 / n as f64;
    let ring_cos = (region_cos.clamp(-1.0, 1.0).acos() + 3.0 * texel_angle).cos();
    let ring: Vec<usize> =
        (0..lum.len()).filter(|&i| !in_region(i) && lum[i].is_finite() && cos_peak[i] >= ring_cos).collect();
    // A bright area reaching past the widest sun is sky (an overcast patch, a window).
    if ring.iter().any(|&i| lum[i] > threshold) {
        return keep();
    }
    let background: [f32; 3] = std::array::from_fn(|c| {
        let mut v: Vec<f32> = ring.iter().map(|&i| map.texels[i][c]).collect();
        v.sort_by(f32::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(0.0)
    });
    let background_lum = luminance(background);
    // Power, centroid and second angular moment of the excess over the sky.
    let mut power = [0.0; 3];
    let mut luminous = 0.0;
    let mut centroid = DVec3::ZERO;
    for &i in &region {
        let w = weight(i);
        for c in 0..3 {
            power[c] += (map.texels[i][c] as f64 - background[c] as f64).max(0.0) * w;
        }
        let excess = (lum[i] - background_lum).max(0.0) * w;
        luminous += excess;
        centroid += dir_of(i) * excess;
    }
    let total: f64 = (0..lum.len()).filter(|&i| lum[i].is_finite()).map(|i| lum[i].max(0.0) * weight(i)).sum();
    let faint = lum[peak] < MIN_CONTRAST * background_lum;
    if faint || luminous <= 0.0 || luminous < MIN_POWER_SHARE * total || centroid.length() == 0.0 {
        return keep();
    }
    let axis = centroid.normalize();
    let second_moment: f64 = region
        .iter()
        .map(|&i| {
            let angle = dir_of(i).dot(axis).clamp(-1.0, 1.0).acos();
            (lum[i] - background_lum).max(0.0) * weight(i) * angle * angle
        })
        .sum::<f64>()
        / luminous;
    // A uniform disc of angular radius r has E[θ²] = r²/2 (small-angle).
    let radius = (2.0 * second_moment).sqrt().max(texel_angle * 0.5);
    if radius > MAX_RADIUS_DEG.to_radians() {
        return keep();
    }
    let solid_angle = std::f64::consts::TAU * (1.0 - radius.cos());
    let sun = Sun { direction: axis.to_array(), radius, radiance: power.map(|p| p / solid_angle) };
    let mut residual = map.clone();
    for &i in &region {
        residual.texels[i] = background;
    }
    SunSplit { sun: Some(sun), residual }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sky::ProceduralSky;

    fn sky_map(sky: &ProceduralSky, size: usize) -> CubeMap {
        CubeMap::from_fn(size, 4, |d| sky.radiance(d))
    }

    /// Irradiance at normal `n` of the map, by its texels (clamped cosine).
    fn irradiance(map: &CubeMap, n: DVec3) -> [f64; 3] {
        let mut e = [0.0; 3];
        for (d, w, l) in map.samples() {
            let c = d.dot(n).max(0.0);
            for k in 0..3 {
                e[k] += l[k] * w * c;
            }
        }
        e
    }

    /// The disc's irradiance at `n` by dense quadrature over the cap (independent of the
    /// shadow sampling directions).
    fn disc_irradiance(sun: &Sun, n: DVec3) -> [f64; 3] {
        let axis = DVec3::from(sun.direction);
        let (t, b) = axis.any_orthonormal_pair();
        let (rings, steps) = (200, 400);
        let mut sum = 0.0;
        for i in 0..rings {
            let cos_theta = 1.0 - (i as f64 + 0.5) / rings as f64 * (1.0 - sun.radius.cos());
            let sin_theta = (1.0 - cos_theta * cos_theta).sqrt();
            for j in 0..steps {
                let phi = (j as f64 + 0.5) / steps as f64 * std::f64::consts::TAU;
                let d = axis * cos_theta + (t * phi.cos() + b * phi.sin()) * sin_theta;
                sum += d.dot(n).max(0.0);
            }
        }
        let mean = sum / (rings * steps) as f64;
        sun.radiance.map(|l| l * sun.solid_angle() * mean)
    }

    #[test]
    fn the_procedural_sun_is_found_where_and_as_strong_as_it_is() {
        for (elevation, azimuth, radius_deg) in [(35.0f64, 40.0f64, 2.5), (70.0, -120.0, 1.0), (10.0, 170.0, 5.0)] {
            let (e, a) = (elevation.to_radians(), azimuth.to_radians());
            let direction = DVec3::new(e.cos() * a.sin(), e.sin(), -e.cos() * a.cos());
            let sky =
                ProceduralSky { sun_direction: direction.to_array(), sun_radius_deg: radius_deg, ..Default::default() };
            let map = sky_map(&sky, 128);
            let split = split(&map);
            let sun = split.sun.expect("a 400x sun is dominant");
            let error_deg = DVec3::from(sun.direction).angle_between(direction).to_degrees();
            assert!(error_deg < 0.3, "sun at ({elevation}, {azimuth}) found {error_deg:.3} deg away");
            // The disc's limb is smooth (0.8r..1.2r): the equivalent uniform disc lies inside it.
            let found = sun.radius.to_degrees();
            assert!((found / radius_deg - 1.0).abs() < 0.25, "radius {found:.2} deg for a {radius_deg} deg sun");
            // Its power is the disc's (radiance × the smooth disc's solid angle), within the
            // limb's and the residual aureole's share.
            let disc_power = 400.0 * std::f64::consts::PI * radius_deg.to_radians().powi(2);
            assert!((sun.power()[0] / disc_power - 1.0).abs() < 0.1, "power {} vs {disc_power}", sun.power()[0]);
        }
    }

    #[test]
    fn the_sun_and_the_residual_light_every_normal_as_the_map_does() {
        let sky = ProceduralSky::default();
        for size in [32, 64, 128] {
            let map = sky_map(&sky, size);
            let split = split(&map);
            let sun = split.sun.expect("dominant");
            let mut worst = 0.0f64;
            let mut rng = 7u64;
            for _ in 0..60 {
                let mut next = || {
                    rng = rng.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    (rng >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
                };
                let n = DVec3::new(next(), next(), next()).normalize_or(DVec3::Y);
                let full = irradiance(&map, n);
                let rest = irradiance(&split.residual, n);
                let disc = disc_irradiance(&sun, n);
                let scale = irradiance(&map, DVec3::from(sun.direction))[0];
                for c in 0..3 {
                    worst = worst.max((rest[c] + disc[c] - full[c]).abs() / scale);
                }
            }
            // Relative to the brightest irradiance: the disc's shape differs from the texels'
            // only near the horizon of a normal, where the disc is partly below it.
            assert!(worst < 0.01, "{size}: irradiance of sun + residual off the map's by {:.3}%", worst * 100.0);
        }
    }

    #[test]
    fn the_residual_is_smooth_where_the_sun_was() {
        let map = sky_map(&ProceduralSky::default(), 64);
        let split = split(&map);
        let peak = split.residual.texels.iter().map(|&t| luminance(t)).fold(0.0, f64::max);
        // The aureole (2% of the sun's radiance at its centre) stays in the sky.
        assert!(peak < 0.03 * 400.0, "the residual still peaks at {peak}");
    }

    #[test]
    fn maps_without_a_compact_bright_source_keep_their_light() {
        let overcast = CubeMap::from_fn(32, 2, |d| [1.0 + d.y.max(0.0); 3].map(|v| v * 0.5));
        assert!(split(&overcast).sun.is_none());
        let wide = CubeMap::from_fn(32, 2, |d| [if d.y > 0.7 { 50.0 } else { 1.0 }; 3]);
        assert!(split(&wide).sun.is_none(), "a 45-degree bright cap is sky, not a sun");
        let empty = CubeMap::new(4, vec![[0.0; 3]; 96]);
        assert_eq!(split(&empty), SunSplit { sun: None, residual: empty.clone() });
    }

    #[test]
    fn broken_texels_neither_panic_nor_make_an_infinite_sun() {
        let mut map = sky_map(&ProceduralSky::default(), 32);
        let n = map.texels.len();
        map.texels[n / 3] = [f32::INFINITY; 3];
        map.texels[n / 2] = [f32::NAN, 1.0, f32::NEG_INFINITY];
        map.texels[n / 5] = [-5.0; 3];
        let split = split(&map);
        let sun = split.sun.expect("the real sun is still found");
        assert!(sun.radiance.iter().all(|l| l.is_finite() && *l > 0.0), "{sun:?}");
        let all_nan = CubeMap::new(4, vec![[f32::NAN; 3]; 96]);
        assert!(super::split(&all_nan).sun.is_none());
    }

    #[test]
    fn disc_directions_cover_the_disc_evenly() {
        let sun = Sun { direction: [0.3, 0.8, -0.2], radius: 0.05, radiance: [1.0; 3] };
        let axis = DVec3::from(sun.direction).normalize();
        let dirs = sun.disc_directions(DISC_SAMPLES);
        assert!(dirs.iter().all(|d| d.dot(axis) >= sun.radius.cos() - 1e-12));
        // Mean of the directions is the axis; the mean cosine is the cap's.
        let mean = dirs.iter().sum::<DVec3>() / dirs.len() as f64;
        assert!(mean.normalize().angle_between(axis) < 2e-3);
        let mean_cos = dirs.iter().map(|d| d.dot(axis)).sum::<f64>() / dirs.len() as f64;
        assert!((mean_cos - (1.0 + sun.radius.cos()) / 2.0).abs() < 1e-9);
        // The rim directions are the last quarter, at one distance from the axis and equal
        // azimuth steps (each neighbour pair equally far apart).
        let rim = &dirs[DISC_SAMPLES - rim_directions(DISC_SAMPLES)..];
        assert_eq!(rim.len(), 8);
        let gaps: Vec<f64> = (0..rim.len()).map(|k| rim[k].angle_between(rim[(k + 1) % rim.len()])).collect();
        assert!(gaps.iter().all(|g| (g / gaps[0] - 1.0).abs() < 1e-6), "{gaps:?}");
        assert!(rim.iter().all(|d| (d.dot(axis) - rim[0].dot(axis)).abs() < 1e-12));
        // Every inner direction lies inside the rim's ring.
        assert!(dirs[..DISC_SAMPLES - 8].iter().all(|d| d.dot(axis) > rim[0].dot(axis)));
    }
}
