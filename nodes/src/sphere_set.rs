//! Sphere-set approximation of a solid, for blocker sphere sets fitted to a model.
//!
//! The greedy cover by medial spheres of Stolpner, Kry & Siddiqi ("Medial spheres for shape
//! approximation", 2012), on a voxel grid:
//! 1. voxel centres are classified inside or outside the closed mesh (the first surface a ray
//!    meets faces away from it when the ray starts inside; five rays vote);
//! 2. inside voxels are centres of candidate spheres of the largest radius that stays inside:
//!    the exact Euclidean distance to the nearest outside voxel (a separable lower-envelope
//!    transform along x, y and z) less half a voxel. Only medial candidates are kept: those
//!    whose sphere no neighbour's sphere contains;
//! 3. spheres are chosen greedily by how many still-uncovered inside voxels they cover; the
//!    gain only falls as spheres are chosen (submodular), so stale gains are re-evaluated
//!    lazily from a priority queue.
//!
//! The coverage error is the fraction of the inside volume no chosen sphere covers; the
//! spheres are inscribed, so they cover almost nothing outside (reported too).

use crate::engine::{CancelToken, StageError};
use crate::mesh::MeshSet;
use glam::{DVec3, Vec3A};
use serde::{Deserialize, Serialize};

/// A fitted set and how well it covers the solid.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SphereSetFit {
    /// Centre and radius, in the mesh's frame.
    pub spheres: Vec<([f64; 3], f64)>,
    /// Fraction of the inside volume left uncovered.
    pub uncovered: f64,
    /// Volume of the spheres outside the solid, as a fraction of the inside volume.
    pub outside: f64,
    /// Inside voxels the fractions are counted on, and the voxel edge.
    pub inside_voxels: usize,
    pub voxel: f64,
}
crate::stage_type!(SphereSetFit, "fitted sphere set", encoding = 1, |v| v.spheres.len() * 32 + 48);

/// Voxels along the longest side at most.
const MAX_RESOLUTION: usize = 160;

/// Fits `count` spheres to the closed meshes `meshes` on a grid of `resolution` voxels along
/// the longest side of their bounds.
pub fn fit_spheres(
    meshes: &MeshSet,
    count: usize,
    resolution: usize,
    cancel: &CancelToken,
) -> Result<SphereSetFit, StageError> {
    let resolution = resolution.clamp(8, MAX_RESOLUTION);
    let normals: Vec<DVec3> = meshes
        .meshes
        .iter()
        .flat_map(|m| {
            m.indices.chunks_exact(3).map(move |t| {
                let p = |i: u32| DVec3::from(m.positions.get(i as usize).copied().unwrap_or_default().map(f64::from));
                (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]))
            })
        })
        .collect();
    if normals.is_empty() {
        return Err(StageError::Failed("the model has no triangles to fit spheres to".into()));
    }
    let (lo, hi) = meshes.bounds();
    let (lo, hi) = (DVec3::from(lo.map(f64::from)), DVec3::from(hi.map(f64::from)));
    let voxel = (hi - lo).max_element() / resolution as f64;
    if !(voxel > 0.0 && voxel.is_finite()) {
        return Err(StageError::Failed("the model is flat or empty: no volume to fit spheres to".into()));
    }
    // One voxel of margin on each side, so the outside surrounds the solid.
    let dims = ((hi - lo) / voxel).ceil().as_uvec3().to_array().map(|d| d as usize + 2);
    let origin = lo - DVec3::splat(voxel * 0.5);
    let centre = |x: usize, y: usize, z: usize| origin + DVec3::new(x as f64, y as f64, z as f64) * voxel;
    let index = |x: usize, y: usize, z: usize| (z * dims[1] + y) * dims[0] + x;
    let scene = crate::raycast::RayScene::build(meshes);
    // Five rays in directions no mesh is likely aligned with (axis rays run along the seams
    // and through the poles of generated meshes, where a ray can slip between triangles).
    let directions = [
        DVec3::new(1.0, 0.3137, 0.1713),
        DVec3::new(-0.2371, 1.0, 0.4129),
        DVec3::new(0.3719, -0.1931, 1.0),
        DVec3::new(-1.0, -0.4421, 0.2683),
        DVec3::new(0.1459, -1.0, -0.3547),
    ]
    .map(DVec3::normalize);
    let inside_of = |p: DVec3| {
        let votes = directions
            .iter()
            .filter(|&&d| {
                scene
                    .closest(Vec3A::from(p.as_vec3()), Vec3A::from(d.as_vec3()))
                    .is_some_and(|(_, t)| normals.get(t as usize).is_some_and(|n| n.dot(d) > 0.0))
            })
            .count();
        votes >= 3
    };
    use rayon::prelude::*;
    let inside: Vec<bool> = (0..dims[0] * dims[1] * dims[2])
        .into_par_iter()
        .map(|i| {
            let (x, y, z) = (i % dims[0], (i / dims[0]) % dims[1], i / (dims[0] * dims[1]));
            inside_of(centre(x, y, z))
        })
        .collect();
    cancel.check()?;
    let inside_count = inside.iter().filter(|&&b| b).count();
    if inside_count == 0 {
        return Err(StageError::Failed(
            "no voxel lies inside the model: it must be a closed (watertight) mesh, or finer than the grid".into(),
        ));
    }
    let distance = squared_distances_3d(&inside, dims);
    let radius_of = |i: usize| (distance[i].sqrt() - 0.5).max(0.5) * voxel;
    // Medial candidates: a sphere inside a neighbour's (d_j ≥ d_i + |i − j|) is never needed.
    let medial = |i: usize| {
        let (x, y, z) = (i % dims[0], (i / dims[0]) % dims[1], i / (dims[0] * dims[1]));
        let d = distance[i].sqrt();
        for (dx, dy, dz) in NEIGHBOURS {
            let (u, v, w) = (x as isize + dx, y as isize + dy, z as isize + dz);
            if u < 0 || v < 0 || w < 0 || u as usize >= dims[0] || v as usize >= dims[1] || w as usize >= dims[2] {
                continue;
            }
            let j = index(u as usize, v as usize, w as usize);
            let step = ((dx * dx + dy * dy + dz * dz) as f64).sqrt();
            if inside[j] && distance[j].sqrt() >= d + step - 1e-9 {
                return false;
            }
        }
        true
    };
    let cells: Vec<usize> = (0..inside.len()).into_par_iter().filter(|&i| inside[i] && medial(i)).collect();
    // Voxels a sphere covers: the inside ones whose centre it contains.
    // Voxels a sphere covers: the inside ones whose centre it contains.
    let covered_by = |i: usize, covered: &[bool]| -> usize {
        let mut n = 0;
        for_ball(i, dims, radius_of(i) / voxel, |j| n += usize::from(inside[j] && !covered[j]));
        n
    };
    // Starting gains are upper bounds (a ball's volume in voxels, grown by half a diagonal),
    // so the lazy greedy never passes over a better sphere.
    let bound = |i: usize| {
        let r = radius_of(i) / voxel + 0.87;
        (4.0 / 3.0 * std::f64::consts::PI * r * r * r).ceil() as usize
    };
    let mut heap: std::collections::BinaryHeap<(usize, usize)> = cells.iter().map(|&i| (bound(i), i)).collect();
    let mut covered = vec![false; inside.len()];
    let mut chosen: Vec<usize> = Vec::new();
    while chosen.len() < count {
        cancel.check()?;
        let Some((_, i)) = heap.pop() else { break };
        let gain = covered_by(i, &covered);
        if gain == 0 {
            continue;
        }
        if heap.peek().is_some_and(|&(next, _)| next > gain) {
            heap.push((gain, i));
            continue;
        }
        for_ball(i, dims, radius_of(i) / voxel, |j| covered[j] = true);
        chosen.push(i);
    }
    let covered_inside = covered.iter().zip(&inside).filter(|(c, i)| **c && **i).count();
    let covered_outside = covered.iter().zip(&inside).filter(|(c, i)| **c && !**i).count();
    Ok(SphereSetFit {
        spheres: chosen
            .iter()
            .map(|&i| {
                let (x, y, z) = (i % dims[0], (i / dims[0]) % dims[1], i / (dims[0] * dims[1]));
                (centre(x, y, z).to_array(), radius_of(i))
            })
            .collect(),
        uncovered: 1.0 - covered_inside as f64 / inside_count as f64,
        outside: covered_outside as f64 / inside_count as f64,
        inside_voxels: inside_count,
        voxel,
    })
}

/// The 26 neighbours of a voxel.
const NEIGHBOURS: [(isize, isize, isize); 26] = {
    let mut out = [(0, 0, 0); 26];
    let mut k = 0;
    let mut i = 0;
    while i < 27 {
        let (dx, dy, dz) = (i % 3 - 1, (i / 3) % 3 - 1, i / 9 - 1);
        if !(dx == 0 && dy == 0 && dz == 0) {
            out[k] = (dx, dy, dz);
            k += 1;
        }
        i += 1;
    }
    out
};

/// Calls `f` with every voxel whose centre lies within `r` voxels of voxel `i`'s centre.
fn for_ball(i: usize, dims: [usize; 3], r: f64, mut f: impl FnMut(usize)) {
    let (x, y, z) = (i % dims[0], (i / dims[0]) % dims[1], i / (dims[0] * dims[1]));
    let reach = r.floor() as isize;
    for dz in -reach..=reach {
        for dy in -reach..=reach {
            for dx in -reach..=reach {
                if ((dx * dx + dy * dy + dz * dz) as f64) > r * r {
                    continue;
                }
                let (u, v, w) = (x as isize + dx, y as isize + dy, z as isize + dz);
                if u >= 0
                    && v >= 0
                    && w >= 0
                    && (u as usize) < dims[0]
                    && (v as usize) < dims[1]
                    && (w as usize) < dims[2]
                {
                    f((w as usize * dims[1] + v as usize) * dims[0] + u as usize);
                }
            }
        }
    }
}

/// Exact squared Euclidean distance (in voxels) from each voxel centre to the nearest voxel
/// centre outside (`inside` false), by the lower-envelope transform along each axis.
fn squared_distances_3d(inside: &[bool], dims: [usize; 3]) -> Vec<f64> {
    const FAR: f64 = 1e12;
    let mut grid: Vec<f64> = inside.iter().map(|&i| if i { FAR } else { 0.0 }).collect();
    let longest = dims.iter().copied().max().unwrap_or(1);
    let (mut line, mut out, mut v, mut z) =
        (vec![0.0; longest], vec![0.0; longest], vec![0usize; longest], vec![0.0; longest + 1]);
    let strides = [1, dims[0], dims[0] * dims[1]];
    for axis in 0..3 {
        let n = dims[axis];
        let others: Vec<usize> = (0..3).filter(|&a| a != axis).collect();
        for a in 0..dims[others[0]] {
            for b in 0..dims[others[1]] {
                let start = a * strides[others[0]] + b * strides[others[1]];
                for k in 0..n {
                    line[k] = grid[start + k * strides[axis]];
                }
                crate::rsl::vdt::transform_1d(&line[..n], &mut out[..n], &mut v[..n], &mut z[..n + 1]);
                for k in 0..n {
                    grid[start + k * strides[axis]] = out[k];
                }
            }
        }
    }
    grid
}

#[cfg(test)]
mod tests;
