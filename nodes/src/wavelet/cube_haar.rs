//! 2D non-standard Haar wavelets on each cube face, and the triple product integral of three
//! sparse wavelet vectors through tripling coefficients (Ng, Ramamoorthi & Hanrahan 2004;
//! Sun 2008 §2.2 eqs. 2.14–2.16 and §4.3.1).
//!
//! # Layout and normalisation
//!
//! The transform is orthonormal on each face's `n × n` texel grid (n a power of two). A
//! face's coefficients sit in the usual quad-tree layout: `(0, 0)` is the scaling
//! coefficient; a level-`l` node `(i, j)` (`h = 2^l`, `i, j < h`) stores its three wavelets at
//! `(i + h, j)` (type 0, `+` on the left half), `(i, j + h)` (type 1, `+` on the top half) and
//! `(i + h, j + h)` (type 2, `+` on the diagonal). The index of a coefficient is
//! `face · n² + y · n + x`.
//!
//! Because the basis is orthonormal over texels, double products are dot products and the
//! triple product computes `Σ_texels a b c` exactly. For an integral over the sphere, fold the
//! texel solid angles into exactly one of the three functions (Ng et al. fold them into the
//! transport); [`CubeHaar::area_weight`] gives the area weighting for coefficient selection.

use super::{SparseVector, node_triple};
use crate::cubemap::{FACES, face_rect_solid_angle};
use rustc_hash::FxHashMap as HashMap;

/// Haar transform and products for cube maps of one face size.
#[derive(Clone, Debug)]
pub struct CubeHaar {
    size: usize,
    /// Area weight per in-face coefficient position (same on every face).
    weights: Vec<f64>,
}

/// A wavelet node: face, level, and position `(i, j)` at that level.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct Node {
    face: u32,
    level: u32,
    i: u32,
    j: u32,
}

/// What one coefficient index denotes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Coefficient {
    Scaling { face: u32 },
    Wavelet { node: Node, kind: usize },
}

impl CubeHaar {
    /// `size` must be a power of two (1 is allowed: only scaling coefficients).
    pub fn new(size: usize) -> Self {
        assert!(size.is_power_of_two(), "cube face size {size} is not a power of two");
        let mut haar = Self { size, weights: Vec::new() };
        haar.weights = (0..size * size).map(|p| haar.support_weight(p)).collect();
        haar
    }

    pub fn size(&self) -> usize {
        self.size
    }

    /// Total coefficient count, `6 n²`.
    pub fn len(&self) -> usize {
        FACES * self.size * self.size
    }

    pub fn is_empty(&self) -> bool {
        false
    }

    /// Forward transform of a cube map channel (`face · n² + y · n + x`).
    pub fn forward(&self, values: &[f64]) -> Vec<f64> {
        assert_eq!(values.len(), self.len(), "expected 6x{0}x{0} values", self.size);
        let mut out = values.to_vec();
        let n2 = self.size * self.size;
        for face in out.chunks_mut(n2) {
            forward_face(face, self.size);
        }
        out
    }

    /// Inverse transform.
    pub fn inverse(&self, coeffs: &[f64]) -> Vec<f64> {
        assert_eq!(coeffs.len(), self.len(), "expected 6x{0}x{0} coefficients", self.size);
        let mut out = coeffs.to_vec();
        let n2 = self.size * self.size;
        for face in out.chunks_mut(n2) {
            inverse_face(face, self.size);
        }
        out
    }

    /// Area weight of a coefficient: `sqrt` of the mean texel solid angle over its support, so
    /// that `|c| · weight` is the coefficient's L² norm over the sphere (up to the variation of
    /// the texel solid angle inside its support).
    pub fn area_weight(&self, index: usize) -> f64 {
        self.weights[index % (self.size * self.size)]
    }

    /// Forward transform and nonlinear approximation keeping the `keep` largest area-weighted
    /// coefficients.
    pub fn approximate(&self, values: &[f64], keep: usize) -> SparseVector {
        let coeffs = self.forward(values);
        SparseVector::largest(&coeffs, keep, |i| self.area_weight(i))
    }

    fn support_weight(&self, position: usize) -> f64 {
        let n = self.size;
        let (x0, y0, side) = match self.decode(position) {
            Coefficient::Scaling { .. } => (0, 0, n),
            Coefficient::Wavelet { node, .. } => {
                let side = n >> node.level;
                (node.i as usize * side, node.j as usize * side, side)
            }
        };
        let s = 2.0 / n as f64;
        let f = |t: usize| -1.0 + t as f64 * s;
        let solid_angle = face_rect_solid_angle(f(x0), f(y0), f(x0 + side), f(y0 + side));
        (solid_angle / (side * side) as f64).sqrt()
    }

    fn decode(&self, index: usize) -> Coefficient {
        let n = self.size;
        let face = (index / (n * n)) as u32;
        let p = index % (n * n);
        let (x, y) = ((p % n) as u32, (p / n) as u32);
        if x == 0 && y == 0 {
            return Coefficient::Scaling { face };
        }
        let level = 31 - x.max(y).leading_zeros();
        let h = 1u32 << level;
        let (kind, i, j) = match (x >= h, y >= h) {
            (true, false) => (0, x - h, y),
            (false, true) => (1, x, y - h),
            _ => (2, x - h, y - h),
        };
        Coefficient::Wavelet { node: Node { face, level, i, j }, kind }
    }

    /// `Σ_texels a · b · c` of three functions given as sparse Haar vectors, by the tripling
    /// coefficient rules: (1) three scaling functions; (2) three distinct wavelet types of one
    /// node, `∫ψ_0ψ_1ψ_2 = 2^l / n`; (3) two identical wavelets times the third function's
    /// coarser reconstruction on their support (its "parent value"). Cost: O(k log n) for `k`
    /// stored coefficients.
    pub fn triple_product(&self, a: &SparseVector, b: &SparseVector, c: &SparseVector) -> f64 {
        let n = self.size as f64;
        let mut scaling = [[0.0f64; 3]; FACES];
        let mut nodes: HashMap<Node, NodeCoefficients> = HashMap::default();
        for (f, v) in [a, b, c].into_iter().enumerate() {
            for &(index, value) in &v.entries {
                match self.decode(index as usize) {
                    Coefficient::Scaling { face } => scaling[face as usize][f] = value,
                    Coefficient::Wavelet { node, kind } => {
                        let entry = nodes.entry(node).or_insert(([[0.0; 3]; 3], 0));
                        entry.0[f][kind] = value;
                        entry.1 |= 1 << f;
                    }
                }
            }
        }
        let mut sum: f64 = scaling.iter().map(|s| s[0] * s[1] * s[2] / n).sum();
        for (node, (w, mask)) in &nodes {
            if mask.count_ones() < 2 {
                continue;
            }
            let parents = self.parent_values(node, &scaling, &nodes);
            let amplitude = (1u64 << node.level) as f64 / n;
            sum += node_triple([&w[0], &w[1], &w[2]], parents, 1.0, amplitude);
        }
        sum
    }

    /// Value of each function's reconstruction from all coarser coefficients on `node`'s support.
    fn parent_values(
        &self,
        node: &Node,
        scaling: &[[f64; 3]; FACES],
        nodes: &HashMap<Node, NodeCoefficients>,
    ) -> [f64; 3] {
        let n = self.size as f64;
        let mut p = scaling[node.face as usize].map(|s| s / n);
        for level in 0..node.level {
            let shift = node.level - level;
            let ancestor = Node { face: node.face, level, i: node.i >> shift, j: node.j >> shift };
            if let Some((w, _)) = nodes.get(&ancestor) {
                let (qx, qy) = ((node.i >> (shift - 1)) & 1, (node.j >> (shift - 1)) & 1);
                let signs = quadrant_signs(qx, qy);
                let amplitude = (1u64 << level) as f64 / n;
                for f in 0..3 {
                    p[f] += amplitude * (signs[0] * w[f][0] + signs[1] * w[f][1] + signs[2] * w[f][2]);
                }
            }
        }
        p
    }
}

/// The three functions' three wavelet coefficients at one node, and which are present.
type NodeCoefficients = ([[f64; 3]; 3], u8);

/// Signs of the three wavelet types on child quadrant `(qx, qy)` (0 = left/top).
fn quadrant_signs(qx: u32, qy: u32) -> [f64; 3] {
    let s = |b: bool| if b { 1.0 } else { -1.0 };
    [s(qx == 0), s(qy == 0), s(qx == qy)]
}

fn forward_face(data: &mut [f64], n: usize) {
    let mut tmp = vec![0.0; n * n];
    let mut s = n;
    while s > 1 {
        let h = s / 2;
        for j in 0..h {
            for i in 0..h {
                let a = data[2 * j * n + 2 * i];
                let b = data[2 * j * n + 2 * i + 1];
                let c = data[(2 * j + 1) * n + 2 * i];
                let d = data[(2 * j + 1) * n + 2 * i + 1];
                tmp[j * n + i] = 0.5 * (a + b + c + d);
                tmp[j * n + i + h] = 0.5 * (a - b + c - d);
                tmp[(j + h) * n + i] = 0.5 * (a + b - c - d);
                tmp[(j + h) * n + i + h] = 0.5 * (a - b - c + d);
            }
        }
        for y in 0..s {
            data[y * n..y * n + s].copy_from_slice(&tmp[y * n..y * n + s]);
        }
        s = h;
    }
}

fn inverse_face(data: &mut [f64], n: usize) {
    let mut tmp = vec![0.0; n * n];
    let mut s = 2;
    while s <= n {
        let h = s / 2;
        for j in 0..h {
            for i in 0..h {
                let avg = data[j * n + i];
                let w0 = data[j * n + i + h];
                let w1 = data[(j + h) * n + i];
                let w2 = data[(j + h) * n + i + h];
                tmp[2 * j * n + 2 * i] = 0.5 * (avg + w0 + w1 + w2);
                tmp[2 * j * n + 2 * i + 1] = 0.5 * (avg - w0 + w1 - w2);
                tmp[(2 * j + 1) * n + 2 * i] = 0.5 * (avg + w0 - w1 - w2);
                tmp[(2 * j + 1) * n + 2 * i + 1] = 0.5 * (avg - w0 - w1 + w2);
            }
        }
        for y in 0..s {
            data[y * n..y * n + s].copy_from_slice(&tmp[y * n..y * n + s]);
        }
        s *= 2;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::test_rng;
    use rand::Rng;

    fn random_map(haar: &CubeHaar, rng: &mut impl Rng) -> Vec<f64> {
        (0..haar.len()).map(|_| rng.random_range(-1.0..2.0)).collect()
    }

    #[test]
    fn perfect_reconstruction_and_parseval() {
        let mut rng = test_rng(21);
        for size in [1, 2, 4, 32] {
            let haar = CubeHaar::new(size);
            let values = random_map(&haar, &mut rng);
            let coeffs = haar.forward(&values);
            let back = haar.inverse(&coeffs);
            let err = values.iter().zip(&back).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            assert!(err < 1e-12, "size {size}: reconstruction error {err}");
            let e_pixels: f64 = values.iter().map(|v| v * v).sum();
            let e_coeffs: f64 = coeffs.iter().map(|v| v * v).sum();
            assert!((e_pixels - e_coeffs).abs() < 1e-10 * e_pixels, "Parseval: {e_pixels} vs {e_coeffs}");
        }
    }

    #[test]
    fn basis_functions_have_the_documented_shape() {
        // Inverse of a unit coefficient is the basis function itself.
        let haar = CubeHaar::new(4);
        let mut unit = vec![0.0; haar.len()];
        unit[16 + 2] = 1.0; // face 1, (x=2, y=0): level 1, node (0,0), type 0.
        let f = haar.inverse(&unit);
        let face1 = &f[16..32];
        // + on the left column pair of the top-left 2x2 block, - on the right.
        assert_eq!(&face1[0..4], &[0.5, -0.5, 0.0, 0.0]);
        assert_eq!(&face1[4..8], &[0.5, -0.5, 0.0, 0.0]);
        assert!(face1[8..].iter().all(|v| *v == 0.0));
        assert!(f[..16].iter().chain(&f[32..]).all(|v| *v == 0.0));
    }

    #[test]
    fn triple_product_equals_the_texel_domain_triple_integral() {
        let mut rng = test_rng(22);
        for size in [1, 2, 8, 32] {
            let haar = CubeHaar::new(size);
            for _ in 0..3 {
                let maps: Vec<Vec<f64>> = (0..3).map(|_| random_map(&haar, &mut rng)).collect();
                let direct: f64 = (0..haar.len()).map(|p| maps[0][p] * maps[1][p] * maps[2][p]).sum();
                let sparse: Vec<SparseVector> =
                    maps.iter().map(|m| SparseVector::from_dense(&haar.forward(m))).collect();
                let via = haar.triple_product(&sparse[0], &sparse[1], &sparse[2]);
                assert!((via - direct).abs() < 1e-6 * direct.abs().max(1.0), "size {size}: {via} vs {direct}");
            }
        }
    }

    #[test]
    fn truncated_triple_product_equals_the_triple_integral_of_the_truncations() {
        // Keeping N coefficients: the result must equal Σ a' b' c' of the reconstructed
        // approximations, whatever was dropped.
        let mut rng = test_rng(23);
        let haar = CubeHaar::new(16);
        for keep in [16, 64, 256] {
            let maps: Vec<Vec<f64>> = (0..3).map(|_| random_map(&haar, &mut rng)).collect();
            let sparse: Vec<SparseVector> = maps.iter().map(|m| haar.approximate(m, keep)).collect();
            let recon: Vec<Vec<f64>> = sparse.iter().map(|s| haar.inverse(&s.to_dense(haar.len()))).collect();
            let direct: f64 = (0..haar.len()).map(|p| recon[0][p] * recon[1][p] * recon[2][p]).sum();
            let via = haar.triple_product(&sparse[0], &sparse[1], &sparse[2]);
            assert!(sparse.iter().all(|s| s.len() == keep));
            assert!((via - direct).abs() < 1e-6 * direct.abs().max(1.0), "keep {keep}: {via} vs {direct}");
        }
    }

    #[test]
    fn area_weights_are_texel_solid_angles_at_the_finest_level() {
        let haar = CubeHaar::new(8);
        let total: f64 = haar.area_weight(0).powi(2) * 64.0 * 6.0;
        assert!((total - 4.0 * std::f64::consts::PI).abs() < 1e-12);
        // Finest type-2 wavelet of node (0,0) at level 2 covers texels (0..2, 0..2).
        let index = 4 * 8 + 4;
        let expected =
            ((0..2).flat_map(|y| (0..2).map(move |x| crate::cubemap::texel_solid_angle(8, x, y))).sum::<f64>() / 4.0)
                .sqrt();
        assert!((haar.area_weight(index) - expected).abs() < 1e-15);
    }
}
