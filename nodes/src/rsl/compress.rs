//! Clustered principal component analysis of distance tables (Xu et al. 2006 §5.1, after Sloan
//! et al. 2003's CPCA): the self-visibility tables of all vertices are clustered (k-means) and
//! each cluster keeps its mean and its first principal directions; a vertex stores its cluster
//! and one coefficient per direction. The occluder fields use the same code with fixed
//! clusters (their segments: each shell's faces split 2×2, 384 segments in all).
//!
//! Principal directions come from subspace iteration on the cluster's centred data (the
//! dominant eigenvectors of its covariance without forming the `dim × dim` matrix).

use rayon::prelude::*;

/// One cluster: its mean and orthonormal principal directions.
#[derive(Clone, Debug, PartialEq)]
pub struct Cluster {
    pub mean: Vec<f32>,
    pub basis: Vec<Vec<f32>>,
}

/// Compressed tables.
#[derive(Clone, Debug, PartialEq)]
pub struct Compressed {
    pub dim: usize,
    pub vectors: usize,
    pub clusters: Vec<Cluster>,
    /// Per table: its cluster.
    pub assignment: Vec<u32>,
    /// Per table: `vectors` coefficients.
    pub coefficients: Vec<f32>,
}

fn dot(a: &[f32], b: &[f32]) -> f64 {
    a.iter().zip(b).map(|(x, y)| f64::from(*x) * f64::from(*y)).sum()
}

fn squared_distance(a: &[f32], b: &[f32]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2)).sum()
}

/// The first `count` principal directions of `rows` (already centred), by subspace iteration.
fn principal_directions(rows: &[&[f32]], dim: usize, count: usize) -> Vec<Vec<f32>> {
    let count = count.min(rows.len()).min(dim);
    if count == 0 {
        return Vec::new();
    }
    // Deterministic start: coordinate-like vectors with a little mixing.
    let mut basis: Vec<Vec<f64>> = (0..count)
        .map(|k| (0..dim).map(|i| if i % count == k { 1.0 } else { ((i * 7 + k * 13) % 17) as f64 * 1e-3 }).collect())
        .collect();
    for _ in 0..12 {
        // Z = Xᵀ (X Q), one column at a time.
        let mut next: Vec<Vec<f64>> = basis
            .par_iter()
            .map(|q| {
                let mut z = vec![0.0; dim];
                for row in rows {
                    let t: f64 = row.iter().zip(q).map(|(x, y)| f64::from(*x) * y).sum();
                    for (zi, x) in z.iter_mut().zip(row.iter()) {
                        *zi += t * f64::from(*x);
                    }
                }
                z
            })
            .collect();
        // Gram–Schmidt, twice for stability.
        for k in 0..next.len() {
            for _ in 0..2 {
                for j in 0..k {
                    let p: f64 = next[k].iter().zip(&next[j]).map(|(a, b)| a * b).sum();
                    let prev = next[j].clone();
                    for (a, b) in next[k].iter_mut().zip(&prev) {
                        *a -= p * b;
                    }
                }
            }
            let norm = next[k].iter().map(|a| a * a).sum::<f64>().sqrt();
            if norm > 1e-12 {
                next[k].iter_mut().for_each(|a| *a /= norm);
            }
        }
        basis = next;
    }
    basis.into_iter().map(|b| b.into_iter().map(|v| v as f32).collect()).collect()
}

/// Compresses `tables` (`n × dim`, row-major) into clusters given per table (`assignment`, ids
/// below `clusters`), keeping `vectors` principal directions per cluster.
pub fn compress_with(tables: &[f32], dim: usize, assignment: Vec<u32>, clusters: usize, vectors: usize) -> Compressed {
    let n = tables.len() / dim;
    let row = |i: usize| &tables[i * dim..(i + 1) * dim];
    let members: Vec<Vec<usize>> = {
        let mut m = vec![Vec::new(); clusters];
        for (i, &c) in assignment.iter().enumerate() {
            m[c as usize].push(i);
        }
        m
    };
    let clusters: Vec<Cluster> = members
        .par_iter()
        .map(|members| {
            let mut mean = vec![0.0f64; dim];
            for &i in members {
                for (m, x) in mean.iter_mut().zip(row(i)) {
                    *m += f64::from(*x);
                }
            }
            let count = members.len().max(1) as f64;
            let mean: Vec<f32> = mean.iter().map(|m| (m / count) as f32).collect();
            let centred: Vec<Vec<f32>> =
                members.iter().map(|&i| row(i).iter().zip(&mean).map(|(x, m)| x - m).collect()).collect();
            let rows: Vec<&[f32]> = centred.iter().map(|r| r.as_slice()).collect();
            let mut basis = principal_directions(&rows, dim, vectors);
            basis.resize(vectors, vec![0.0; dim]);
            Cluster { mean, basis }
        })
        .collect();
    let coefficients: Vec<f32> = (0..n)
        .into_par_iter()
        .flat_map_iter(|i| {
            let c = &clusters[assignment[i] as usize];
            let centred: Vec<f32> = row(i).iter().zip(&c.mean).map(|(x, m)| x - m).collect();
            c.basis.iter().map(move |b| dot(&centred, b) as f32).collect::<Vec<_>>()
        })
        .collect();
    Compressed { dim, vectors, clusters, assignment, coefficients }
}

/// k-means clusters of the tables (deterministic start: evenly spaced tables), `iterations`
/// rounds.
pub fn kmeans(tables: &[f32], dim: usize, clusters: usize, iterations: usize) -> Vec<u32> {
    let n = tables.len() / dim;
    let clusters = clusters.clamp(1, n.max(1));
    let row = |i: usize| &tables[i * dim..(i + 1) * dim];
    let mut centres: Vec<Vec<f32>> = (0..clusters).map(|c| row(c * n / clusters).to_vec()).collect();
    let mut assignment = vec![0u32; n];
    for _ in 0..iterations.max(1) {
        assignment = (0..n)
            .into_par_iter()
            .map(|i| {
                let r = row(i);
                (0..clusters)
                    .map(|c| (squared_distance(r, &centres[c]), c))
                    .min_by(|a, b| a.0.total_cmp(&b.0))
                    .map_or(0, |(_, c)| c as u32)
            })
            .collect();
        let mut sums = vec![vec![0.0f64; dim]; clusters];
        let mut counts = vec![0usize; clusters];
        for (i, &c) in assignment.iter().enumerate() {
            counts[c as usize] += 1;
            for (s, x) in sums[c as usize].iter_mut().zip(row(i)) {
                *s += f64::from(*x);
            }
        }
        for c in 0..clusters {
            if counts[c] > 0 {
                centres[c] = sums[c].iter().map(|s| (s / counts[c] as f64) as f32).collect();
            }
        }
    }
    assignment
}

impl Compressed {
    /// Table `i` rebuilt from its cluster's mean and directions.
    pub fn reconstruct(&self, i: usize) -> Vec<f32> {
        let c = &self.clusters[self.assignment[i] as usize];
        let coefficients = &self.coefficients[i * self.vectors..(i + 1) * self.vectors];
        let mut out = c.mean.clone();
        for (b, w) in c.basis.iter().zip(coefficients) {
            for (o, x) in out.iter_mut().zip(b) {
                *o += w * x;
            }
        }
        out
    }

    /// `‖X − X̂‖ / ‖X‖` over all tables.
    pub fn relative_error(&self, tables: &[f32]) -> f64 {
        let n = tables.len() / self.dim;
        let (num, den) = (0..n)
            .into_par_iter()
            .map(|i| {
                let original = &tables[i * self.dim..(i + 1) * self.dim];
                (squared_distance(original, &self.reconstruct(i)), dot(original, original))
            })
            .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        (num / den.max(1e-300)).sqrt()
    }

    /// Bytes stored at the paper's precision: FP16 means, directions and coefficients (its
    /// tables are FP16 textures), and a 16-bit cluster id per table.
    pub fn bytes(&self) -> usize {
        self.clusters.len() * (self.vectors + 1) * self.dim * 2 + self.assignment.len() * (2 + self.vectors * 2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::CancelToken;
    use crate::mesh::{self, MeshSet};
    use crate::raycast::RayScene;
    use crate::rsl::vdt::{Svdf, VDT_SIZE};
    use crate::transport::Receivers;

    #[test]
    fn reconstruction_error_falls_as_directions_are_added_and_ratios_are_near_the_papers() {
        // Real self-visibility tables: a torus over a floor, as one object.
        let lift = glam::DMat4::from_translation(glam::DVec3::new(0.0, 0.35, 0.0)) * glam::DMat4::from_rotation_x(0.5);
        let meshes = MeshSet { meshes: vec![mesh::plane(3.0, 24), mesh::torus(0.6, 0.22, 32).transformed(lift)] };
        let receivers = Receivers::from_meshes(&meshes);
        let svdf =
            Svdf::compute(&RayScene::build(&meshes), &receivers, VDT_SIZE, &CancelToken::default(), &|_| {}).unwrap();
        let dim = VDT_SIZE * VDT_SIZE;
        let tables: Vec<f32> = svdf.distances.iter().map(|&q| f32::from(q) / 127.0).collect();
        let clusters = 32;
        let assignment = kmeans(&tables, dim, clusters, 4);
        let mut errors = Vec::new();
        for vectors in [0, 1, 2, 4, 8, 16] {
            let compressed = compress_with(&tables, dim, assignment.clone(), clusters, vectors);
            errors.push((vectors, compressed.relative_error(&tables)));
        }
        println!("{} tables, {clusters} clusters: relative error by directions kept {errors:.4?}", svdf.vertices);
        for pair in errors.windows(2) {
            assert!(pair[1].1 <= pair[0].1 + 1e-6, "error rose with more directions: {errors:?}");
        }
        assert!(errors[4].1 < 0.5 * errors[0].1, "8 directions should more than halve the error: {errors:?}");
        // What these tables take compressed against FP32 (the paper's measure).
        let compressed = compress_with(&tables, dim, assignment, clusters, 8);
        let raw = svdf.vertices * dim * 4;
        println!(
            "{} KiB FP32 -> {} KiB ({clusters} clusters x 8 directions, FP16): 1:{:.1}",
            raw >> 10,
            compressed.bytes() >> 10,
            raw as f64 / compressed.bytes() as f64
        );
    }
}
