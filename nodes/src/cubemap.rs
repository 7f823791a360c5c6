//! Cube maps and equirectangular images: the two parameterisations of the sphere that
//! environment maps and wavelet lighting use.
//!
//! # Conventions
//!
//! * Cube faces follow wgpu/Vulkan order and orientation: `+X, -X, +Y, -Y, +Z, -Z`. On a face,
//!   `u` runs left to right and `v` top to bottom (texel row 0 is the top row), exactly as a
//!   Vulkan cube-map sampler addresses it: for `+X`, `(sc, tc, ma) = (-z, -y, x)`, and
//!   `u = (sc/|ma| + 1)/2`, `v = (tc/|ma| + 1)/2`.
//! * Equirectangular (lat-long) images: `u = 0.5 + atan2(x, -z) / 2π`, `v = acos(y) / π`, so the
//!   image centre looks down **-Z**, `u = 0.75` is **+X**, the top row is **+Y** (up).

use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::PI;

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(
    Equirect,
    "image",
    |v| v.pixels.len() * 12,
    numbers = |v| v.pixels.iter().flatten().map(|x| f64::from(*x))
);
crate::stage_type!(
    CubeMap,
    "cube map",
    |v| v.texels.len() * 12,
    numbers = |v| v.texels.iter().flatten().map(|x| f64::from(*x))
);

/// Number of cube faces.
pub const FACES: usize = 6;

/// Linear RGB pixel.
pub type Rgb = [f32; 3];

/// Maps a direction (need not be normalised) to `(face, u, v)` with `u, v ∈ [0, 1]`.
pub fn dir_to_face_uv(dir: DVec3) -> (usize, f64, f64) {
    let a = dir.abs();
    let (face, sc, tc, ma) = if a.x >= a.y && a.x >= a.z {
        if dir.x >= 0.0 { (0, -dir.z, -dir.y, a.x) } else { (1, dir.z, -dir.y, a.x) }
    } else if a.y >= a.z {
        if dir.y >= 0.0 { (2, dir.x, dir.z, a.y) } else { (3, dir.x, -dir.z, a.y) }
    } else if dir.z >= 0.0 {
        (4, dir.x, -dir.y, a.z)
    } else {
        (5, -dir.x, -dir.y, a.z)
    };
    (face, 0.5 * (sc / ma + 1.0), 0.5 * (tc / ma + 1.0))
}

/// Unit direction through `(u, v)` on `face`; inverse of [`dir_to_face_uv`].
pub fn face_uv_to_dir(face: usize, u: f64, v: f64) -> DVec3 {
    let (sc, tc) = (2.0 * u - 1.0, 2.0 * v - 1.0);
    let d = match face {
        0 => DVec3::new(1.0, -tc, -sc),
        1 => DVec3::new(-1.0, -tc, sc),
        2 => DVec3::new(sc, 1.0, tc),
        3 => DVec3::new(sc, -1.0, -tc),
        4 => DVec3::new(sc, -tc, 1.0),
        5 => DVec3::new(-sc, -tc, -1.0),
        _ => panic!("cube face index {face} out of range"),
    };
    d.normalize()
}

/// Solid angle subtended by the face rectangle `[x0,x1]×[y0,y1]` in `[-1,1]²` face coordinates.
pub fn face_rect_solid_angle(x0: f64, y0: f64, x1: f64, y1: f64) -> f64 {
    let area = |x: f64, y: f64| (x * y).atan2((x * x + y * y + 1.0).sqrt());
    area(x1, y1) - area(x0, y1) - area(x1, y0) + area(x0, y0)
}

/// Solid angle of texel `(x, y)` of a `size × size` face (exact).
pub fn texel_solid_angle(size: usize, x: usize, y: usize) -> f64 {
    let s = 2.0 / size as f64;
    face_rect_solid_angle(
        -1.0 + x as f64 * s,
        -1.0 + y as f64 * s,
        -1.0 + (x + 1) as f64 * s,
        -1.0 + (y + 1) as f64 * s,
    )
}

/// `(u, v)` of a direction in the equirectangular parameterisation.
pub fn dir_to_equirect_uv(dir: DVec3) -> (f64, f64) {
    let d = dir.normalize();
    let u = 0.5 + d.x.atan2(-d.z) / (2.0 * PI);
    let v = d.y.clamp(-1.0, 1.0).acos() / PI;
    (u, v)
}

/// Unit direction at equirectangular `(u, v)`; inverse of [`dir_to_equirect_uv`].
pub fn equirect_uv_to_dir(u: f64, v: f64) -> DVec3 {
    let phi = 2.0 * PI * (u - 0.5);
    let theta = PI * v;
    DVec3::new(theta.sin() * phi.sin(), theta.cos(), -theta.sin() * phi.cos())
}

/// An equirectangular (lat-long) linear-radiance image.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Equirect {
    pub width: usize,
    pub height: usize,
    /// Row-major, row 0 at the top (+Y).
    pub pixels: Vec<Rgb>,
}

impl Equirect {
    pub fn new(width: usize, height: usize, pixels: Vec<Rgb>) -> Self {
        assert_eq!(pixels.len(), width * height, "pixel count does not match {width}x{height}");
        Self { width, height, pixels }
    }

    /// Fills an image from a radiance function, averaging `supersample²` directions per pixel.
    pub fn from_fn(width: usize, height: usize, supersample: usize, f: impl Fn(DVec3) -> [f64; 3] + Sync) -> Self {
        let s = supersample.max(1);
        let pixels = (0..width * height)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % width, i / width);
                let mut acc = [0.0; 3];
                let mut weight = 0.0;
                for sy in 0..s {
                    for sx in 0..s {
                        let u = (x as f64 + (sx as f64 + 0.5) / s as f64) / width as f64;
                        let v = (y as f64 + (sy as f64 + 0.5) / s as f64) / height as f64;
                        // Weight by sin θ so the average is over solid angle.
                        let w = (PI * v).sin();
                        let value = f(equirect_uv_to_dir(u, v));
                        for c in 0..3 {
                            acc[c] += w * value[c];
                        }
                        weight += w;
                    }
                }
                acc.map(|a| (a / weight) as f32)
            })
            .collect();
        Self { width, height, pixels }
    }

    /// Solid angle of any pixel in row `y`: `(2π / W)(cos θ_top - cos θ_bottom)`.
    pub fn row_solid_angle(&self, y: usize) -> f64 {
        let t0 = PI * y as f64 / self.height as f64;
        let t1 = PI * (y + 1) as f64 / self.height as f64;
        2.0 * PI / self.width as f64 * (t0.cos() - t1.cos())
    }

    /// Direction through the centre of pixel `(x, y)`.
    pub fn pixel_dir(&self, x: usize, y: usize) -> DVec3 {
        equirect_uv_to_dir((x as f64 + 0.5) / self.width as f64, (y as f64 + 0.5) / self.height as f64)
    }

    /// Bilinear lookup; wraps in `u`, clamps in `v`.
    pub fn sample(&self, dir: DVec3) -> [f64; 3] {
        let (u, v) = dir_to_equirect_uv(dir);
        let fx = u * self.width as f64 - 0.5;
        let fy = (v * self.height as f64 - 0.5).clamp(0.0, (self.height - 1) as f64);
        let (x0, y0) = (fx.floor(), fy.floor());
        let (tx, ty) = (fx - x0, fy - y0);
        let wrap = |x: f64| (x as i64).rem_euclid(self.width as i64) as usize;
        let (xa, xb) = (wrap(x0), wrap(x0 + 1.0));
        let ya = y0 as usize;
        let yb = (ya + 1).min(self.height - 1);
        let p = |x: usize, y: usize| self.pixels[y * self.width + x];
        let mut out = [0.0; 3];
        for c in 0..3 {
            let top = p(xa, ya)[c] as f64 * (1.0 - tx) + p(xb, ya)[c] as f64 * tx;
            let bottom = p(xa, yb)[c] as f64 * (1.0 - tx) + p(xb, yb)[c] as f64 * tx;
            out[c] = top * (1.0 - ty) + bottom * ty;
        }
        out
    }

    /// Every pixel as `(direction, solid angle, radiance)`, e.g. for SH projection.
    pub fn samples(&self) -> impl Iterator<Item = (DVec3, f64, [f64; 3])> + '_ {
        (0..self.height).flat_map(move |y| {
            let solid_angle = self.row_solid_angle(y);
            (0..self.width).map(move |x| {
                let p = self.pixels[y * self.width + x];
                (self.pixel_dir(x, y), solid_angle, p.map(f64::from))
            })
        })
    }

    /// Resamples to a cube map of `size`², box-filtering each texel with enough bilinear
    /// samples to cover the source pixels it spans.
    pub fn to_cubemap(&self, size: usize) -> CubeMap {
        // Angular size of a source pixel vs a cube texel at a face centre.
        let ratio = (2.0 / size as f64) / (PI / self.height as f64);
        let supersample = (ratio.ceil() as usize).clamp(1, 8);
        CubeMap::from_fn(size, supersample, |d| self.sample(d))
    }

    /// Downsamples by an integer factor with solid-angle weights (box filter).
    pub fn downsample(&self, factor: usize) -> Self {
        let factor = factor.max(1);
        let (w, h) = (self.width / factor, self.height / factor);
        let pixels = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let mut acc = [0.0f64; 3];
                let mut weight = 0.0;
                for sy in y * factor..(y + 1) * factor {
                    let sa = self.row_solid_angle(sy);
                    for sx in x * factor..(x + 1) * factor {
                        let p = self.pixels[sy * self.width + sx];
                        for c in 0..3 {
                            acc[c] += sa * p[c] as f64;
                        }
                        weight += sa;
                    }
                }
                acc.map(|a| (a / weight) as f32)
            })
            .collect();
        Self { width: w, height: h, pixels }
    }
}

/// A cube map of linear radiance, faces in wgpu/Vulkan order, each `size × size`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CubeMap {
    pub size: usize,
    /// `face * size² + y * size + x`.
    pub texels: Vec<Rgb>,
}

impl CubeMap {
    pub fn new(size: usize, texels: Vec<Rgb>) -> Self {
        assert_eq!(texels.len(), FACES * size * size, "texel count does not match 6x{size}x{size}");
        Self { size, texels }
    }

    /// Fills a cube map from a radiance function, averaging `supersample²` directions per texel
    /// (weighted by their solid angle).
    pub fn from_fn(size: usize, supersample: usize, f: impl Fn(DVec3) -> [f64; 3] + Sync) -> Self {
        let s = supersample.max(1);
        let texels = (0..FACES * size * size)
            .into_par_iter()
            .map(|i| {
                let face = i / (size * size);
                let (x, y) = (i % size, (i / size) % size);
                let mut acc = [0.0; 3];
                let mut weight = 0.0;
                for sy in 0..s {
                    for sx in 0..s {
                        let u = (x as f64 + (sx as f64 + 0.5) / s as f64) / size as f64;
                        let v = (y as f64 + (sy as f64 + 0.5) / s as f64) / size as f64;
                        let (a, b) = (2.0 * u - 1.0, 2.0 * v - 1.0);
                        // Jacobian of the face-to-sphere map: dω = dA / (1 + a² + b²)^{3/2}.
                        let w = (1.0 + a * a + b * b).powf(-1.5);
                        let value = f(face_uv_to_dir(face, u, v));
                        for c in 0..3 {
                            acc[c] += w * value[c];
                        }
                        weight += w;
                    }
                }
                acc.map(|a| (a / weight) as f32)
            })
            .collect();
        Self { size, texels }
    }

    pub fn texel(&self, face: usize, x: usize, y: usize) -> Rgb {
        self.texels[(face * self.size + y) * self.size + x]
    }

    /// Direction through the centre of a texel.
    pub fn texel_dir(&self, face: usize, x: usize, y: usize) -> DVec3 {
        let n = self.size as f64;
        face_uv_to_dir(face, (x as f64 + 0.5) / n, (y as f64 + 0.5) / n)
    }

    /// Bilinear lookup within the face the direction hits (clamped at face edges).
    pub fn sample(&self, dir: DVec3) -> [f64; 3] {
        let (face, u, v) = dir_to_face_uv(dir);
        let last = (self.size - 1) as f64;
        let fx = (u * self.size as f64 - 0.5).clamp(0.0, last);
        let fy = (v * self.size as f64 - 0.5).clamp(0.0, last);
        let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.size - 1), (y0 + 1).min(self.size - 1));
        let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
        let (a, b, c, d) =
            (self.texel(face, x0, y0), self.texel(face, x1, y0), self.texel(face, x0, y1), self.texel(face, x1, y1));
        let (w00, w10, w01, w11) = ((1.0 - tx) * (1.0 - ty), tx * (1.0 - ty), (1.0 - tx) * ty, tx * ty);
        [0, 1, 2].map(|k| a[k] as f64 * w00 + b[k] as f64 * w10 + c[k] as f64 * w01 + d[k] as f64 * w11)
    }

    /// Per-texel solid angles for one face (the same for all six).
    pub fn face_solid_angles(&self) -> Vec<f64> {
        (0..self.size * self.size).map(|i| texel_solid_angle(self.size, i % self.size, i / self.size)).collect()
    }

    /// Every texel as `(direction, solid angle, radiance)`.
    pub fn samples(&self) -> impl Iterator<Item = (DVec3, f64, [f64; 3])> + '_ {
        let solid_angles = self.face_solid_angles();
        let n = self.size;
        (0..FACES * n * n).map(move |i| {
            let (face, x, y) = (i / (n * n), i % n, (i / n) % n);
            (self.texel_dir(face, x, y), solid_angles[y * n + x], self.texels[i].map(f64::from))
        })
    }

    /// Box-filters down to faces of `size` (a divisor of this size), each new texel the
    /// solid-angle-weighted mean of the texels it covers, so every region keeps its energy
    /// (a prefilter: later point lookups see the area average, not a lucky or missed sun).
    pub fn box_downsampled(&self, size: usize) -> Self {
        if size >= self.size || size == 0 || !self.size.is_multiple_of(size) {
            return self.clone();
        }
        let factor = self.size / size;
        let solid = self.face_solid_angles();
        let texels = (0..FACES * size * size)
            .map(|i| {
                let (face, x, y) = (i / (size * size), i % size, (i / size) % size);
                let (mut acc, mut weight) = ([0.0f64; 3], 0.0);
                for sy in y * factor..(y + 1) * factor {
                    for sx in x * factor..(x + 1) * factor {
                        let w = solid[sy * self.size + sx];
                        let t = self.texel(face, sx, sy);
                        for c in 0..3 {
                            acc[c] += w * t[c] as f64;
                        }
                        weight += w;
                    }
                }
                acc.map(|a| (a / weight) as f32)
            })
            .collect();
        Self { size, texels }
    }

    /// Resamples to an equirectangular image (supersampled box filter).
    pub fn to_equirect(&self, width: usize, height: usize) -> Equirect {
        let ratio = (PI / height as f64) / (2.0 / self.size as f64);
        let supersample = (ratio.ceil() as usize).clamp(1, 8);
        Equirect::from_fn(width, height, supersample, |d| self.sample(d))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{random_unit_vector, test_rng};

    #[test]
    fn face_lookup_of_axes_and_known_texels() {
        let axes = [DVec3::X, -DVec3::X, DVec3::Y, -DVec3::Y, DVec3::Z, -DVec3::Z];
        for (face, axis) in axes.iter().enumerate() {
            let (f, u, v) = dir_to_face_uv(*axis);
            assert_eq!(f, face);
            assert!((u - 0.5).abs() < 1e-15 && (v - 0.5).abs() < 1e-15);
        }
        // Vulkan: on +X, u grows towards -Z and v grows towards -Y.
        let (f, u, v) = dir_to_face_uv(DVec3::new(1.0, -0.5, -0.5));
        assert_eq!((f, u, v), (0, 0.75, 0.75));
        // On +Y, v grows towards +Z; on -Y, towards -Z.
        assert_eq!(dir_to_face_uv(DVec3::new(0.0, 1.0, 0.5)), (2, 0.5, 0.75));
        assert_eq!(dir_to_face_uv(DVec3::new(0.0, -1.0, 0.5)), (3, 0.5, 0.25));
        // On -Z, u grows towards -X.
        assert_eq!(dir_to_face_uv(DVec3::new(-0.5, 0.0, -1.0)), (5, 0.75, 0.5));
    }

    #[test]
    fn box_downsampling_keeps_the_energy_of_every_region() {
        let cube = CubeMap::from_fn(32, 1, |d| {
            [if d.dot(DVec3::new(0.3, 0.9, 0.1).normalize()) > 0.999 { 1e4 } else { 1.0 }, d.x.abs(), 0.5]
        });
        let small = cube.box_downsampled(8);
        let energy = |c: &CubeMap| {
            c.samples().fold([0.0; 3], |acc, (_, w, l)| [acc[0] + w * l[0], acc[1] + w * l[1], acc[2] + w * l[2]])
        };
        let (a, b) = (energy(&cube), energy(&small));
        for c in 0..3 {
            assert!((a[c] - b[c]).abs() < 1e-6 * a[c], "channel {c}: {} vs {}", a[c], b[c]);
        }
        // Each coarse texel holds the energy of its 4×4 block.
        let solid = cube.face_solid_angles();
        let block: f64 = (0..4)
            .flat_map(|y| (0..4).map(move |x| (x, y)))
            .map(|(x, y)| solid[y * 32 + x] * cube.texel(2, x, y)[1] as f64)
            .sum();
        assert!((small.texel(2, 0, 0)[1] as f64 * small.face_solid_angles()[0] - block).abs() < 1e-6);
    }

    #[test]
    fn face_uv_round_trip() {
        let mut rng = test_rng(11);
        for _ in 0..1000 {
            let d = random_unit_vector(&mut rng);
            let (f, u, v) = dir_to_face_uv(d);
            assert!((face_uv_to_dir(f, u, v) - d).length() < 1e-12);
        }
    }

    #[test]
    fn texel_solid_angles_sum_to_the_sphere_and_match_quadrature() {
        for size in [1, 2, 7, 64] {
            let total: f64 = (0..size * size).map(|i| texel_solid_angle(size, i % size, i / size)).sum::<f64>() * 6.0;
            assert!((total - 4.0 * PI).abs() < 1e-12, "size {size}: {total}");
        }
        // A corner texel by midpoint quadrature of the Jacobian.
        let (size, n) = (8, 400);
        let mut brute = 0.0;
        for i in 0..n {
            for j in 0..n {
                let a = -1.0 + (i as f64 + 0.5) / n as f64 * (2.0 / size as f64);
                let b = -1.0 + (j as f64 + 0.5) / n as f64 * (2.0 / size as f64);
                brute += (1.0 + a * a + b * b).powf(-1.5) * (2.0 / size as f64 / n as f64).powi(2);
            }
        }
        assert!((texel_solid_angle(size, 0, 0) - brute).abs() < 1e-7);
    }

    #[test]
    fn equirect_known_directions_and_round_trip() {
        assert_eq!(dir_to_equirect_uv(-DVec3::Z), (0.5, 0.5));
        assert_eq!(dir_to_equirect_uv(DVec3::X), (0.75, 0.5));
        assert_eq!(dir_to_equirect_uv(-DVec3::X), (0.25, 0.5));
        assert_eq!(dir_to_equirect_uv(DVec3::Y).1, 0.0);
        assert_eq!(dir_to_equirect_uv(-DVec3::Y).1, 1.0);
        let mut rng = test_rng(12);
        for _ in 0..1000 {
            let d = random_unit_vector(&mut rng);
            let (u, v) = dir_to_equirect_uv(d);
            assert!((equirect_uv_to_dir(u, v) - d).length() < 1e-12);
        }
        let img = Equirect::new(8, 4, vec![[1.0; 3]; 32]);
        let total: f64 = (0..4).map(|y| img.row_solid_angle(y) * 8.0).sum();
        assert!((total - 4.0 * PI).abs() < 1e-12);
    }

    #[test]
    fn resampling_preserves_smooth_functions_and_the_integral() {
        // A smooth, low-frequency radiance: resampled values match it and the integral of the
        // cube map equals the integral of the source.
        let f = |d: DVec3| [1.0 + 0.5 * d.x, 2.0 + d.y * d.z, (1.5 * d.z).exp()];
        let src = Equirect::from_fn(256, 128, 2, f);
        let cube = src.to_cubemap(32);
        let mut rng = test_rng(13);
        for _ in 0..200 {
            let d = random_unit_vector(&mut rng);
            let (got, want) = (cube.sample(d), f(d));
            for c in 0..3 {
                assert!((got[c] - want[c]).abs() < 0.03 * want[c].abs().max(1.0), "{d}: {got:?} vs {want:?}");
            }
        }
        let integral = |s: &mut dyn Iterator<Item = (DVec3, f64, [f64; 3])>| s.map(|(_, w, v)| w * v[2]).sum::<f64>();
        // ∫ e^{1.5 z} dω = 2π (e^{1.5} - e^{-1.5}) / 1.5
        let exact = 2.0 * PI * (1.5f64.exp() - (-1.5f64).exp()) / 1.5;
        assert!((integral(&mut src.samples()) - exact).abs() < 1e-3 * exact);
        assert!((integral(&mut cube.samples()) - exact).abs() < 3e-3 * exact);
        let back = cube.to_equirect(128, 64);
        for (y, x) in [(10, 3), (32, 64), (50, 120)] {
            let d = back.pixel_dir(x, y);
            assert!((back.pixels[y * 128 + x][0] as f64 - f(d)[0]).abs() < 0.03);
        }
        let half = src.downsample(2);
        assert!((integral(&mut half.samples()) - integral(&mut src.samples())).abs() < 1e-4 * exact);
    }
}
