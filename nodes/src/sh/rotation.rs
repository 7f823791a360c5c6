//! SH rotation by per-band matrices (Ivanic & Ruedenberg 1996, with their 1998 errata):
//! band `l` is built from band `l-1` and the 3×3 rotation, so any 3D rotation costs
//! O(L³) to set up and O(L³) to apply. Rotation mixes only coefficients of one band
//! (Sun 2008 eq. 2.11).

use super::coeff_count;
use glam::DMat3;

/// Block-diagonal rotation of SH coefficient vectors. For a rotation `R`,
/// [`ShRotation::apply`] maps the coefficients of `f` to those of `f ∘ R⁻¹`
/// (the function turned by `R`: `g(R ω) = f(ω)`).
#[derive(Clone, Debug)]
pub struct ShRotation {
    bands: usize,
    /// `blocks[l]` is `(2l+1)²`, row-major, rows/columns indexed by `m + l`.
    blocks: Vec<Vec<f64>>,
}

impl ShRotation {
    pub fn new(bands: usize, rotation: DMat3) -> Self {
        let mut blocks: Vec<Vec<f64>> = Vec::with_capacity(bands);
        blocks.push(vec![1.0]);
        if bands > 1 {
            // Band 1 transforms like (y, z, x).
            let axis = [1usize, 2, 0];
            let mut r1 = vec![0.0; 9];
            for i in 0..3 {
                for j in 0..3 {
                    // glam matrices are column-major: col(j)[i] = R[i][j].
                    r1[i * 3 + j] = rotation.col(axis[j])[axis[i]];
                }
            }
            blocks.push(r1);
        }
        for l in 2..bands {
            let block = band_block(l, &blocks[1], &blocks[l - 1]);
            blocks.push(block);
        }
        Self { bands, blocks }
    }

    pub fn bands(&self) -> usize {
        self.bands
    }

    /// Entry `(m, n)` of band `l`.
    pub fn entry(&self, l: usize, m: i64, n: i64) -> f64 {
        let size = 2 * l + 1;
        self.blocks[l][(m + l as i64) as usize * size + (n + l as i64) as usize]
    }

    /// Rotates a scalar coefficient vector (its band count may be at most `bands`).
    pub fn apply(&self, coeffs: &[f64]) -> Vec<f64> {
        let bands = super::bands_of_len(coeffs.len());
        assert!(bands <= self.bands, "rotation built for {} bands, vector has {bands}", self.bands);
        let mut out = vec![0.0; coeff_count(bands)];
        for l in 0..bands {
            let size = 2 * l + 1;
            let base = l * l;
            let block = &self.blocks[l];
            for row in 0..size {
                let mut acc = 0.0;
                for col in 0..size {
                    acc += block[row * size + col] * coeffs[base + col];
                }
                out[base + row] = acc;
            }
        }
        out
    }

    /// Rotates each channel of an RGB expansion.
    pub fn apply_rgb(&self, sh: &super::ShRgb) -> super::ShRgb {
        let channels: Vec<Vec<f64>> = (0..3).map(|c| self.apply(&sh.channel(c))).collect();
        super::ShRgb::from_channels([&channels[0], &channels[1], &channels[2]])
    }
}

fn band_block(l: usize, r1: &[f64], prev: &[f64]) -> Vec<f64> {
    let li = l as i64;
    let size = 2 * l + 1;
    let prev_size = (2 * l - 1) as i64;
    let r1_at = |i: i64, j: i64| r1[((i + 1) * 3 + (j + 1)) as usize];
    let prev_at = |a: i64, b: i64| prev[((a + li - 1) * prev_size + (b + li - 1)) as usize];
    // Ivanic & Ruedenberg's helper P.
    let p = |i: i64, a: i64, b: i64| -> f64 {
        if b == li {
            r1_at(i, 1) * prev_at(a, li - 1) - r1_at(i, -1) * prev_at(a, -li + 1)
        } else if b == -li {
            r1_at(i, 1) * prev_at(a, -li + 1) + r1_at(i, -1) * prev_at(a, li - 1)
        } else {
            r1_at(i, 0) * prev_at(a, b)
        }
    };
    let mut block = vec![0.0; size * size];
    for m in -li..=li {
        for n in -li..=li {
            let d = if m == 0 { 1.0 } else { 0.0 };
            let denom = if n.abs() == li { (2 * li * (2 * li - 1)) as f64 } else { ((li + n) * (li - n)) as f64 };
            let am = m.abs();
            let u = (((li + m) * (li - m)) as f64 / denom).sqrt();
            let v = 0.5 * ((1.0 + d) * ((li + am - 1) * (li + am)) as f64 / denom).sqrt() * (1.0 - 2.0 * d);
            let w = -0.5 * (((li - am - 1) * (li - am)) as f64 / denom).sqrt() * (1.0 - d);
            let mut value = 0.0;
            if u != 0.0 {
                value += u * p(0, m, n);
            }
            if v != 0.0 {
                let big_v = if m == 0 {
                    p(1, 1, n) + p(-1, -1, n)
                } else if m > 0 {
                    let d1: f64 = if m == 1 { 1.0 } else { 0.0 };
                    p(1, m - 1, n) * (1.0 + d1).sqrt() - p(-1, -m + 1, n) * (1.0 - d1)
                } else {
                    let d1: f64 = if m == -1 { 1.0 } else { 0.0 };
                    p(1, m + 1, n) * (1.0 - d1) + p(-1, -m - 1, n) * (1.0 + d1).sqrt()
                };
                value += v * big_v;
            }
            if w != 0.0 {
                let big_w = if m > 0 { p(1, m + 1, n) + p(-1, -m - 1, n) } else { p(1, m - 1, n) - p(-1, -m + 1, n) };
                value += w * big_w;
            }
            block[(m + li) as usize * size + (n + li) as usize] = value;
        }
    }
    block
}
