//! Haar wavelets: the one wavelet module every technique uses.
//!
//! - [`cube_haar`]: the 2D non-standard Haar transform on each cube face (Ng et al. 2003/2004,
//!   summarised in Sun 2008 §2.2 eqs. 2.14–2.16) with the triple product integral by
//!   tripling coefficients.
//! - [`affine`]: affine double and triple products of 1D and 2D Haar functions, the light
//!   propagation of near-field area lights (Sun 2008 ch. 4).
//! - [`spherical`]: Ma et al.'s spherical Haar basis on the subdivided icosahedron
//!   (`ma-triple-product-local-frame.txt` §3.1) with its tripling coefficient theorem.
//!
//! Both store nonlinear approximations as [`SparseVector`]s: the `N` coefficients of largest
//! area-weighted magnitude.

pub mod affine;
pub mod cube_haar;
pub mod spherical;

use serde::{Deserialize, Serialize};

/// A sparse coefficient vector: `(index, value)` sorted by index, no duplicates.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SparseVector {
    pub entries: Vec<(u32, f64)>,
}

impl SparseVector {
    /// All nonzero entries of a dense vector.
    pub fn from_dense(dense: &[f64]) -> Self {
        let entries = dense.iter().enumerate().filter(|(_, v)| **v != 0.0).map(|(i, v)| (i as u32, *v)).collect();
        Self { entries }
    }

    /// The `keep` entries with the largest `|value| · weight(index)` (nonlinear approximation).
    /// Ties are broken by index so the selection is deterministic.
    pub fn largest(dense: &[f64], keep: usize, weight: impl Fn(usize) -> f64) -> Self {
        let mut ranked: Vec<(f64, u32)> = dense
            .iter()
            .enumerate()
            .filter(|(_, v)| **v != 0.0)
            .map(|(i, v)| (v.abs() * weight(i), i as u32))
            .collect();
        if ranked.len() > keep {
            ranked.select_nth_unstable_by(keep, |a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
            ranked.truncate(keep);
        }
        let mut entries: Vec<(u32, f64)> = ranked.into_iter().map(|(_, i)| (i, dense[i as usize])).collect();
        entries.sort_unstable_by_key(|e| e.0);
        Self { entries }
    }

    /// The first `keep` coefficients (coarsest first, "top-only" in Ma et al. §3.3).
    pub fn top(dense: &[f64], keep: usize) -> Self {
        Self::from_dense(&dense[..keep.min(dense.len())])
    }

    pub fn len(&self) -> usize {
        self.entries.len()
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Value at `index` (zero where not stored), by binary search.
    pub fn get(&self, index: u32) -> f64 {
        self.entries.binary_search_by_key(&index, |e| e.0).map(|k| self.entries[k].1).unwrap_or(0.0)
    }

    /// Scatters into a dense vector of length `len`.
    pub fn to_dense(&self, len: usize) -> Vec<f64> {
        let mut out = vec![0.0; len];
        for &(i, v) in &self.entries {
            out[i as usize] = v;
        }
        out
    }

    /// Sparse dot product (the double product integral in an orthonormal basis).
    pub fn dot(&self, other: &SparseVector) -> f64 {
        let (mut a, mut b) = (self.entries.iter().peekable(), other.entries.iter().peekable());
        let mut sum = 0.0;
        while let (Some(x), Some(y)) = (a.peek(), b.peek()) {
            match x.0.cmp(&y.0) {
                std::cmp::Ordering::Less => {
                    a.next();
                }
                std::cmp::Ordering::Greater => {
                    b.next();
                }
                std::cmp::Ordering::Equal => {
                    sum += x.1 * y.1;
                    a.next();
                    b.next();
                }
            }
        }
        sum
    }
}

/// Sum over the six permutations `σ` of `a[σ0] b[σ1] c[σ2]` (the three-distinct-wavelets term
/// of the tripling rules).
pub(crate) fn permutation_sum(a: &[f64; 3], b: &[f64; 3], c: &[f64; 3]) -> f64 {
    a[0] * (b[1] * c[2] + b[2] * c[1]) + a[1] * (b[0] * c[2] + b[2] * c[0]) + a[2] * (b[0] * c[1] + b[1] * c[0])
}

/// Per-node contribution shared by both Haar bases: for three functions with wavelet
/// coefficients `w*` at one node and parent values `p*` (their coarser reconstructions on the
/// node's support), `Σ_t (p_a b_t c_t + p_b a_t c_t + p_c a_t b_t)·e + amp · Σ_σ a_σ0 b_σ1 c_σ2`,
/// where `e = ∫ψ²` and `amp = ∫ψ_0 ψ_1 ψ_2`.
pub(crate) fn node_triple(w: [&[f64; 3]; 3], p: [f64; 3], norm: f64, distinct: f64) -> f64 {
    let [a, b, c] = w;
    let mut same = 0.0;
    for t in 0..3 {
        same += p[0] * b[t] * c[t] + p[1] * a[t] * c[t] + p[2] * a[t] * b[t];
    }
    norm * same + distinct * permutation_sum(a, b, c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn largest_keeps_the_heaviest_and_stays_sorted() {
        let dense = [0.1, -5.0, 0.0, 3.0, -0.2, 4.0];
        let s = SparseVector::largest(&dense, 3, |_| 1.0);
        assert_eq!(s.entries, vec![(1, -5.0), (3, 3.0), (5, 4.0)]);
        // A weight that favours index 0 changes the choice.
        let w = SparseVector::largest(&dense, 1, |i| if i == 0 { 100.0 } else { 1.0 });
        assert_eq!(w.entries, vec![(0, 0.1)]);
        assert_eq!(s.get(3), 3.0);
        assert_eq!(s.get(2), 0.0);
        assert_eq!(s.to_dense(6), vec![0.0, -5.0, 0.0, 3.0, 0.0, 4.0]);
        let all = SparseVector::from_dense(&dense);
        assert_eq!(all.dot(&s), 25.0 + 9.0 + 16.0);
        assert_eq!(SparseVector::top(&dense, 2).entries, vec![(0, 0.1), (1, -5.0)]);
    }
}
