//! What the viewport shades a normal-mapped pixel with: the texel NDF's first two moments
//! (its SH to `l = 2`, Sun 2008 eq. 5.6 truncated), MIP-mapped by averaging and rotated into
//! the world by the surface frame, and the vMF lobes of [`super::vmf_pyramid`] packed per
//! level. The shaders in `shaders/normal_map.wgsl` are the GPU twins of the functions here.
//!
//! The moments `m = E[n]` and `S = E[n nᵀ]` span exactly the NDF's SH bands 0–2: every
//! `Y_lm` with `l ≤ 2` is a quadratic polynomial in `n`, so `E[Y_lm(n)]` is linear in `m` and
//! `S`. Irradiance from the environment, `E(n) = Σ Â_l L_lm Y_lm(n)` (eq. 2.20), is then
//! filtered exactly on those bands by `Σ_{l≤2} E_lm E[Y_lm]`; the higher bands take Toksvig's
//! lobe's attenuation (eq. 5.7 with a vMF NDF).

use super::{MAX_KAPPA, NormalMap, Vmf};
use glam::{DMat3, DVec3};
use serde::{Deserialize, Serialize};

crate::stage_type!(MomentPyramid, "NDF moment pyramid", |v| v.levels.iter().map(|l| l.texels.len() * 32).sum());
crate::stage_type!(VmfPyramid, "vMF lobe pyramid", |v| v.levels.iter().map(|l| l.lobes.len() * 16).sum());

/// `E[n]` and `E[n nᵀ]` of a texel's normals (unit normals: `tr S = 1`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NdfMoments {
    pub mean: DVec3,
    pub second: DMat3,
}

/// `√(1/4π)`, `√(3/4π)`, `√(15/4π)`, `√(5/16π)`, `√(15/16π)`: the factors of the real SH to
/// `l = 2` as polynomials in `(x, y, z)`, in `crate::sh`'s order and signs (no Condon–Shortley
/// phase: `Y_{1,−1} ∝ y`, `Y_{1,0} ∝ z`, `Y_{1,1} ∝ x`).
const SH_C: [f64; 5] = [
    0.282_094_791_773_878_1,
    0.488_602_511_902_919_9,
    1.092_548_430_592_079,
    0.315_391_565_252_520,
    0.546_274_215_296_039_5,
];

impl NdfMoments {
    /// A single normal: a delta NDF.
    pub fn of_normal(n: DVec3) -> Self {
        Self { mean: n, second: DMat3::from_cols(n * n.x, n * n.y, n * n.z) }
    }

    /// `E[Y_lm(n)]` for `l ≤ 2` (the NDF's SH coefficients on those bands).
    pub fn sh(&self) -> [f64; 9] {
        let (m, s) = (self.mean, self.second);
        let (xx, yy, zz) = (s.x_axis.x, s.y_axis.y, s.z_axis.z);
        let (xy, yz, xz) = (s.y_axis.x, s.z_axis.y, s.z_axis.x);
        [
            SH_C[0],
            SH_C[1] * m.y,
            SH_C[1] * m.z,
            SH_C[1] * m.x,
            SH_C[2] * xy,
            SH_C[2] * yz,
            SH_C[3] * (3.0 * zz - (xx + yy + zz)),
            SH_C[2] * xz,
            SH_C[4] * (xx - yy),
        ]
    }

    /// The moments of the NDF turned by `frame` (tangent space to world: `F m`, `F S Fᵀ`).
    pub fn rotated(&self, frame: DMat3) -> Self {
        Self { mean: frame * self.mean, second: frame * self.second * frame.transpose() }
    }

    /// The texel layout the viewport samples: `(m, S_xx)`, `(S_yy, S_xy, S_xz, S_yz)`
    /// (`S_zz = tr S − S_xx − S_yy` with `tr S = 1`).
    pub fn packed(&self) -> [f32; 8] {
        let (m, s) = (self.mean, self.second);
        [m.x, m.y, m.z, s.x_axis.x, s.y_axis.y, s.y_axis.x, s.z_axis.x, s.z_axis.y].map(|v| v as f32)
    }

    pub fn unpacked(p: [f32; 8]) -> Self {
        let p = p.map(f64::from);
        let zz = 1.0 - p[3] - p[4];
        Self {
            mean: DVec3::new(p[0], p[1], p[2]),
            second: DMat3::from_cols(
                DVec3::new(p[3], p[5], p[6]),
                DVec3::new(p[5], p[4], p[7]),
                DVec3::new(p[6], p[7], zz),
            ),
        }
    }

    /// One vMF lobe about the mean direction whose concentration matches the NDF's spread
    /// about it: `κ` from the mean normal's length (Toksvig's filter, [`Vmf::toksvig`]).
    pub fn toksvig(&self) -> Vmf {
        Vmf::toksvig(self.mean)
    }

    /// `E[max(0, n·l)]`, the NDF's diffuse response to one direction: with `n·l` taken as
    /// Gaussian of the moments' mean `μ = m·l` and variance `σ² = lᵀSl − μ²`, the closed form
    /// `μ Φ(μ/σ) + σ φ(μ/σ)`; `max(0, n·l)` exactly for a single normal.
    pub fn direct_diffuse(&self, l: DVec3) -> f64 {
        let mu = self.mean.dot(l);
        let variance = (l.dot(self.second * l) - mu * mu).max(0.0);
        let sigma = variance.sqrt();
        if sigma < 1e-6 {
            return mu.max(0.0);
        }
        let t = mu / sigma;
        mu * normal_cdf(t) + sigma * (-0.5 * t * t).exp() / (2.0 * std::f64::consts::PI).sqrt()
    }

    /// Irradiance from SH irradiance coefficients `E_lm` (`e`, RGB, index `l(l+1)+m`) averaged
    /// over the NDF (world frame): bands 0–2 exactly, higher bands at the mean direction
    /// attenuated as Toksvig's lobe (`e^{−l(l+1)/2κ}`). A single normal gives `E(n)`.
    pub fn filtered_irradiance(&self, e: &[[f64; 3]]) -> [f64; 3] {
        let low = self.sh();
        let lobe = self.toksvig();
        let bands = crate::sh::band_of(e.len().max(1) - 1) + 1;
        let high = crate::sh::ShBasis::new(bands).eval_vec(lobe.mean);
        let mut out = [0.0; 3];
        for (i, c) in e.iter().enumerate() {
            let attenuation = match lobe.kappa >= MAX_KAPPA {
                true => 1.0,
                false => lobe.band_attenuation(crate::sh::band_of(i)),
            };
            let y = if i < 9 { low[i] } else { high[i] * attenuation };
            for k in 0..3 {
                out[k] += c[k] * y;
            }
        }
        out
    }
}

/// The standard normal CDF `Φ(t)`, `erfc` by Abramowitz–Stegun 7.1.26 (within 1.5e-7), as
/// its shader twin.
pub fn normal_cdf(t: f64) -> f64 {
    let x = t.abs() / std::f64::consts::SQRT_2;
    let k = 1.0 / (1.0 + 0.327_591_1 * x);
    let poly =
        k * (0.254_829_592 + k * (-0.284_496_736 + k * (1.421_413_741 + k * (-1.453_152_027 + k * 1.061_405_429))));
    let erfc = poly * (-x * x).exp();
    if t >= 0.0 { 1.0 - 0.5 * erfc } else { 0.5 * erfc }
}

/// One level of a [`MomentPyramid`]: [`NdfMoments::packed`] per texel, row by row.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MomentLevel {
    pub width: usize,
    pub height: usize,
    pub texels: Vec<[f32; 8]>,
}

/// A normal map's NDF moments from its texels to one texel, at the GPU's MIP sizes
/// (`max(1, ⌊w/2⌋)`): each texel the plain average of the texels it covers, an odd level's
/// last row and column joining the last texel before them. Trilinear and anisotropic sampling
/// of these levels stays an average of NDFs, so the hardware filters them correctly.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MomentPyramid {
    pub levels: Vec<MomentLevel>,
}

impl MomentPyramid {
    pub fn build(map: &NormalMap) -> Self {
        if map.normals.is_empty() {
            return Self::default();
        }
        let mut level = MomentLevel {
            width: map.width,
            height: map.height,
            texels: map.normals.iter().map(|n| NdfMoments::of_normal(*n).packed()).collect(),
        };
        // Averaged in f64 from the level below (f32 storage keeps each level to 1e-7).
        let mut sums: Vec<[f64; 8]> = level.texels.iter().map(|t| t.map(f64::from)).collect();
        let mut levels = Vec::new();
        while level.width > 1 || level.height > 1 {
            let (width, height) = ((level.width / 2).max(1), (level.height / 2).max(1));
            // Parent `i` of `parents` covers children `2i, 2i + 1`, the last parent the rest.
            let span = |i: usize, size: usize, parents: usize| {
                let start = (2 * i).min(size - 1);
                start..if i + 1 == parents { size } else { 2 * i + 2 }
            };
            let mut next = vec![[0.0f64; 8]; width * height];
            for y in 0..height {
                let rows = span(y, level.height, height);
                for x in 0..width {
                    let cols = span(x, level.width, width);
                    let count = (rows.len() * cols.len()) as f64;
                    let out = &mut next[y * width + x];
                    for cy in rows.clone() {
                        for cx in cols.clone() {
                            for (o, v) in out.iter_mut().zip(&sums[cy * level.width + cx]) {
                                *o += v / count;
                            }
                        }
                    }
                }
            }
            levels.push(std::mem::replace(
                &mut level,
                MomentLevel { width, height, texels: next.iter().map(|t| t.map(|v| v as f32)).collect() },
            ));
            sums = next;
        }
        levels.push(level);
        Self { levels }
    }
}

/// Most lobes a texel of a [`VmfPyramid`] holds (the thesis's six).
pub const VMF_LOBES: usize = 6;

/// The largest normal map whose vMF pyramid is fitted (its lobes take 128 bytes a texel over
/// all levels).
pub const MAX_VMF_PIXELS: usize = 2048 * 2048;

/// One level of a [`VmfPyramid`]: per texel `lobes_per_texel` lobes `(κμ, weight)` (unused
/// lobes weigh 0): [`VMF_LOBES`], or the most any of its texels holds (up to twice that) at a
/// level of [`super::VMF_COARSE_SPAN`] map texels a side or more that took the larger fits
/// ([`super::vmf_pyramid`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct VmfLevel {
    pub width: usize,
    pub height: usize,
    pub lobes_per_texel: usize,
    pub lobes: Vec<[f32; 4]>,
}

/// The vMF mixtures of [`super::vmf_pyramid`], every level, packed for the viewport.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct VmfPyramid {
    pub levels: Vec<VmfLevel>,
}

impl VmfPyramid {
    /// Fits every level (EM of at most 30 rounds over at most 1024 normals a texel). Maps
    /// beyond [`MAX_VMF_PIXELS`] are refused with the reason.
    pub fn build(map: &NormalMap, cancel: &crate::engine::CancelToken) -> Result<Self, String> {
        if map.normals.len() > MAX_VMF_PIXELS {
            return Err(format!(
                "the vMF filter fits maps up to 2048 × 2048 texels, and this one has {} × {}; choose the SH or Toksvig filter",
                map.width, map.height
            ));
        }
        if map.normals.is_empty() {
            return Ok(Self::default());
        }
        let fitted = super::vmf_pyramid_cancellable(map, VMF_LOBES, 30, 1024, cancel).ok_or("cancelled")?;
        let levels = fitted
            .into_iter()
            .enumerate()
            .map(|(level, texels)| {
                let (width, height) = (map.width.div_ceil(1 << level), map.height.div_ceil(1 << level));
                // Six lobes a texel, or twelve at a coarse level that took them.
                let per_texel = texels.iter().map(Vec::len).max().unwrap_or(0).max(VMF_LOBES);
                let mut lobes = vec![[0.0f32; 4]; width * height * per_texel];
                for (slot, mixture) in lobes.chunks_exact_mut(per_texel).zip(&texels) {
                    for (s, lobe) in slot.iter_mut().zip(mixture) {
                        let km = lobe.mean * lobe.kappa.min(MAX_KAPPA);
                        *s = [km.x as f32, km.y as f32, km.z as f32, lobe.weight as f32];
                    }
                }
                VmfLevel { width, height, lobes_per_texel: per_texel, lobes }
            })
            .collect();
        Ok(Self { levels })
    }

    /// The lobes of texel `(x, y)` of level `level` (0: the map's own texels).
    pub fn lobes(&self, level: usize, x: usize, y: usize) -> Vec<Vmf> {
        let l = &self.levels[level];
        l.lobes[(y * l.width + x) * l.lobes_per_texel..][..l.lobes_per_texel]
            .iter()
            .filter(|p| p[3] > 0.0)
            .map(|p| {
                let km = DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
                Vmf { weight: f64::from(p[3]), kappa: km.length(), mean: km.normalize_or(DVec3::Z) }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests;
