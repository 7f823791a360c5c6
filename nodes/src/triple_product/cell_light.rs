//! The lighting cell integrals `ΔΩ_c L_c = Σ_s w_s L(M d_s)` (the cell's 16 sub-cell
//! directions `d_s` with solid angles `w_s`, in a receiver's frame `M`) in f32, the 16 samples
//! of a cell laid out for SIMD: the CPU twin of `shaders/wavelet_relight.wgsl`'s sampling.
//! Each sample reads the environment bilinearly within a cube face, clamped at its edges
//! (`CubeMap::sample`).

use super::{CellGrid, SUBLEVELS};
use crate::cubemap::CubeMap;
use glam::DMat3;

/// Sub-cell samples per cell.
pub(crate) const SAMPLES: usize = 1 << (2 * SUBLEVELS);

/// A prefiltered environment and a grid's sample directions, ready to light cells.
pub(crate) struct CellSampler {
    size: usize,
    /// `face · size² + y · size + x`, RGB and a pad.
    texels: Vec<[f32; 4]>,
    /// Per cell its samples' directions, by axis.
    directions: Vec<[[f32; SAMPLES]; 3]>,
    weights: Vec<[f32; SAMPLES]>,
}

impl CellSampler {
    pub(crate) fn new(grid: &CellGrid, environment: &CubeMap) -> Self {
        let directions = grid
            .samples
            .iter()
            .map(|s| {
                assert_eq!(s.len(), SAMPLES, "every cell has {SAMPLES} sub-cell samples");
                std::array::from_fn(|axis| std::array::from_fn(|k| s[k].0[axis] as f32))
            })
            .collect();
        let weights = grid.samples.iter().map(|s| std::array::from_fn(|k| s[k].1 as f32)).collect();
        Self {
            size: environment.size,
            texels: environment.texels.iter().map(|t| [t[0], t[1], t[2], 0.0]).collect(),
            directions,
            weights,
        }
    }

    /// Cell `c`'s integral in `frame` (columns: where the local axes point in the
    /// environment).
    pub(crate) fn cell(&self, frame: &DMat3, c: usize) -> [f32; 3] {
        let m = [frame.x_axis, frame.y_axis, frame.z_axis].map(|a| a.as_vec3().to_array());
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            return unsafe { self.cell_avx2(&m, c) };
        }
        Self::sum(&self.samples_portable(&m, c))
    }

    /// Cell `c`'s samples' solid angles.
    pub(crate) fn weights(&self, c: usize) -> &[f32; SAMPLES] {
        &self.weights[c]
    }

    /// Each of cell `c`'s samples `w_s L(M d_s)` in `frame` (RGB and a pad), in the grid's
    /// order: the finer levels' values the detail terms read.
    pub(crate) fn samples(&self, frame: &DMat3, c: usize) -> [[f32; 4]; SAMPLES] {
        let m = [frame.x_axis, frame.y_axis, frame.z_axis].map(|a| a.as_vec3().to_array());
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            return unsafe { self.samples_avx2(&m, c) };
        }
        self.samples_portable(&m, c)
    }

    pub(crate) fn sum(samples: &[[f32; 4]; SAMPLES]) -> [f32; 3] {
        let mut sum = [0.0f32; 4];
        for v in samples {
            for k in 0..4 {
                sum[k] += v[k];
            }
        }
        [sum[0], sum[1], sum[2]]
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn cell_avx2(&self, m: &[[f32; 3]; 3], c: usize) -> [f32; 3] {
        Self::sum(&self.samples_portable(m, c))
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn samples_avx2(&self, m: &[[f32; 3]; 3], c: usize) -> [[f32; 4]; SAMPLES] {
        self.samples_portable(m, c)
    }

    #[inline(always)]
    fn samples_portable(&self, m: &[[f32; 3]; 3], c: usize) -> [[f32; 4]; SAMPLES] {
        let [dx, dy, dz] = &self.directions[c];
        let size = self.size as f32;
        let last = size - 1.0;
        let face_texels = (self.size * self.size) as u32;
        let mut corners = [[0u32; 4]; SAMPLES];
        let mut fractions = [[0.0f32; 2]; SAMPLES];
        // Directions to faces, texels and bilinear fractions: branch-free, so it vectorises.
        for s in 0..SAMPLES {
            let x = m[0][0] * dx[s] + m[1][0] * dy[s] + m[2][0] * dz[s];
            let y = m[0][1] * dx[s] + m[1][1] * dy[s] + m[2][1] * dz[s];
            let z = m[0][2] * dx[s] + m[1][2] * dy[s] + m[2][2] * dz[s];
            let (ax, ay, az) = (x.abs(), y.abs(), z.abs());
            let on_x = ax >= ay && ax >= az;
            let on_y = !on_x && ay >= az;
            let (face, sc, tc, ma) = if on_x {
                if x >= 0.0 { (0, -z, -y, ax) } else { (1, z, -y, ax) }
            } else if on_y {
                if y >= 0.0 { (2, x, z, ay) } else { (3, x, -z, ay) }
            } else if z >= 0.0 {
                (4, x, -y, az)
            } else {
                (5, -x, -y, az)
            };
            let u = 0.5 * (sc / ma + 1.0);
            let v = 0.5 * (tc / ma + 1.0);
            let fx = (u * size - 0.5).clamp(0.0, last);
            let fy = (v * size - 0.5).clamp(0.0, last);
            let (x0, y0) = (fx.floor(), fy.floor());
            let (x1, y1) = ((x0 + 1.0).min(last), (y0 + 1.0).min(last));
            let base = face as u32 * face_texels;
            let row = |y: f32| base + y as u32 * self.size as u32;
            corners[s] = [row(y0) + x0 as u32, row(y0) + x1 as u32, row(y1) + x0 as u32, row(y1) + x1 as u32];
            fractions[s] = [fx - x0, fy - y0];
        }
        let weights = &self.weights[c];
        let mut out = [[0.0f32; 4]; SAMPLES];
        for s in 0..SAMPLES {
            let [tx, ty] = fractions[s];
            let texel = |i: u32| self.texels[i as usize];
            let (a, b, c, d) = (texel(corners[s][0]), texel(corners[s][1]), texel(corners[s][2]), texel(corners[s][3]));
            let (w00, w10, w01, w11) = ((1.0 - tx) * (1.0 - ty), tx * (1.0 - ty), (1.0 - tx) * ty, tx * ty);
            for k in 0..4 {
                out[s][k] = (a[k] * w00 + b[k] * w10 + c[k] * w01 + d[k] * w11) * weights[s];
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// The f32 sampler against the plain f64 sum of `CubeMap::sample` over the same samples,
    /// on random frames and a sunlit environment: within 1e-4 of the cell's largest channel
    /// but for samples that change face within rounding of a face edge (under 1% of cells).
    #[test]
    fn cells_equal_the_plain_f64_sum() {
        let grid = CellGrid::for_coefficients(320).unwrap();
        let sun = DVec3::new(0.2, 0.9, 0.3).normalize();
        let environment = super::super::prefiltered(
            &CubeMap::from_fn(64, 1, |d| {
                let glow = if d.dot(sun) > 0.998 { 900.0 } else { 0.0 };
                [0.3 + glow + d.x.abs(), 0.5 + d.y.max(0.0) + 0.4 * glow, 0.7 - 0.2 * d.z]
            }),
            grid,
        );
        let sampler = CellSampler::new(grid, &environment);
        let mut state = 3u64;
        let mut uniform = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut cells, mut off) = (0, 0);
        for _ in 0..40 {
            let frame = DMat3::from_euler(glam::EulerRot::ZYZ, uniform() * 6.3, uniform() * 3.1, uniform() * 6.3);
            for c in 0..grid.len() {
                let plain: DVec3 =
                    grid.samples[c].iter().map(|(d, w)| DVec3::from(environment.sample(frame * *d)) * *w).sum();
                let fast = sampler.cell(&frame, c);
                let error = (0..3).map(|k| (fast[k] as f64 - plain[k]).abs()).fold(0.0, f64::max) / plain.max_element();
                assert!(error < 0.05, "cell {c}: {fast:?} against {plain}");
                cells += 1;
                off += usize::from(error > 1e-4);
            }
        }
        assert!(off * 100 < cells, "{off} of {cells} cells off by more than 1e-4");
    }
}
