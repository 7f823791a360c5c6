//! Visibility by distance tables (Xu et al. 2006 §4.3, Eqs. 9–10).
//!
//! A visibility map over the equal-area plane ([`super::plane`]) becomes a table of signed
//! distances `D(p)` to the nearest visibility boundary (positive where visible). The visible
//! fraction of a square of edge `e` centred on `p` is then one lookup and a ramp:
//!
//! - [`Ramp::StraightEdge`] (default): `clamp(½ + D/e)`, exact for a straight boundary parallel
//!   to a side of the square (notes §3.1);
//! - [`Ramp::Printed`]: the paper's Eq. 9 as printed, `clamp(1 + D/e)`, which reads a square
//!   whose centre is visible as wholly visible (biased towards light; the tests measure it).
//!
//! Distances come from an exact Euclidean distance transform (Felzenszwalb and Huttenlocher's
//! lower envelope of parabolas, which gives what Danielsson's mapping in the paper
//! approximates): for each texel, the distance to the nearest texel of the other value, less
//! half a texel, so a straight texel-aligned boundary is at its true distance.
//!
//! Self-visibility ([`Svdf`], Eq. 10) is ray-traced at each vertex on a 32² grid in the
//! vertex's local frame of its object's object space, so moving or turning the object needs
//! no recompute. Texels outside the unit disc are below the horizon; they are stored as
//! *visible*: the horizon is already in the BRDF mean (`ρ cos θ` is zero there), and storing it
//! in both would count it twice in the product of means (`ρ̄ V̄` of a square straddling the
//! horizon would be about ¼ instead of ½; the white-furnace test measures this). The notes
//! (§3.2) suggest occluded; the paper does not say. Distances are stored as 8-bit fixed point over `±D_MAX` plane units: a square
//! light's edge is at most about one plane unit, so the ramp saturates well inside the range.

use super::plane::{from_plane, from_texels, to_texels};
use crate::engine::{CancelToken, StageError};
use crate::raycast::RayScene;
use crate::transport::Receivers;
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

crate::stage_type!(Svdf, "self-visibility distance tables", encoding = 2, |v| v.distances.len() + v.frames.len() * 24);
crate::stage_type!(Vec<ObjectSvdf>, "per-object self-visibility", |v| v
    .iter()
    .map(|o| o.svdf.distances.len() + 160)
    .sum());

/// One scene object's self-visibility tables and where the object is now.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObjectSvdf {
    pub name: String,
    /// Column-major 4×4.
    pub world_from_object: [f64; 16],
    pub svdf: Svdf,
}

/// Texels per side of a visibility distance table (the paper's 32).
pub const VDT_SIZE: usize = 32;
/// What the self-visibility tables hold below the horizon (see the module doc).
pub const BELOW_HORIZON_VISIBLE: bool = true;

/// Largest stored distance, plane units (the plane's `[-1, 1]²` spans 2).
pub const D_MAX: f64 = 1.0;

/// Which form of Eq. 9 turns a distance into a visible fraction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ramp {
    StraightEdge,
    Printed,
}

/// Visible fraction of a square of edge `edge` (plane units) whose centre is at signed
/// distance `d` from the visibility boundary.
pub fn visible_fraction(d: f64, edge: f64, ramp: Ramp) -> f64 {
    let edge = edge.max(1e-9);
    match ramp {
        Ramp::StraightEdge => (0.5 + d / edge).clamp(0.0, 1.0),
        Ramp::Printed => (1.0 + d / edge).clamp(0.0, 1.0),
    }
}

/// A value larger than any squared distance on a table, standing in for "no feature".
const FAR: f64 = 1e12;

/// One row of the lower-envelope transform: `out[q] = min_p (q − p)² + f[p]`.
pub(crate) fn transform_1d(f: &[f64], out: &mut [f64], v: &mut [usize], z: &mut [f64]) {
    let n = f.len();
    let mut k = 0;
    v[0] = 0;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    for q in 1..n {
        loop {
            let p = v[k];
            let s = ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * (q as f64 - p as f64));
            if s <= z[k] {
                k -= 1;
                continue;
            }
            k += 1;
            v[k] = q;
            z[k] = s;
            z[k + 1] = f64::INFINITY;
            break;
        }
    }
    k = 0;
    for (q, o) in out.iter_mut().enumerate() {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let d = q as f64 - v[k] as f64;
        *o = d * d + f[v[k]];
    }
}

/// Exact squared Euclidean distance (in texels) from each texel centre of an `n × n` grid to
/// the nearest texel centre where `feature` holds; `None` where there is no such texel.
pub fn squared_distances(feature: &[bool], n: usize) -> Vec<Option<f64>> {
    assert_eq!(feature.len(), n * n);
    let mut grid: Vec<f64> = feature.iter().map(|&f| if f { 0.0 } else { FAR }).collect();
    let (mut line, mut out, mut v, mut z) = (vec![0.0; n], vec![0.0; n], vec![0usize; n], vec![0.0; n + 1]);
    for x in 0..n {
        for y in 0..n {
            line[y] = grid[y * n + x];
        }
        transform_1d(&line, &mut out, &mut v, &mut z);
        for y in 0..n {
            grid[y * n + x] = out[y];
        }
    }
    for y in 0..n {
        line.copy_from_slice(&grid[y * n..(y + 1) * n]);
        transform_1d(&line, &mut out, &mut v, &mut z);
        grid[y * n..(y + 1) * n].copy_from_slice(&out);
    }
    grid.into_iter().map(|d| (d < FAR * 0.5).then_some(d)).collect()
}

/// Signed distances (plane units, positive where visible) of a visibility map on `n × n`
/// texels over `[-1, 1]²`: the distance to the nearest texel of the other value less half a
/// texel. Beyond the table, visibility is `outside` (the disc touches the table's edges, so
/// the horizon there is the table's edge). A map with no boundary reads as far from one
/// (`±D_MAX`).
pub fn signed_distances(visible: &[bool], n: usize, outside: bool) -> Vec<f64> {
    // One ring of `outside` texels around the table.
    let m = n + 2;
    let padded: Vec<bool> = (0..m * m)
        .map(|i| {
            let (x, y) = (i % m, i / m);
            if x == 0 || y == 0 || x == m - 1 || y == m - 1 { outside } else { visible[(y - 1) * n + x - 1] }
        })
        .collect();
    let occluded: Vec<bool> = padded.iter().map(|v| !v).collect();
    let to_occluded = squared_distances(&occluded, m);
    let to_visible = squared_distances(&padded, m);
    let texel = 2.0 / n as f64;
    (0..n * n)
        .map(|k| {
            let i = (k / n + 1) * m + k % n + 1;
            let (d, sign) = if padded[i] { (to_occluded[i], 1.0) } else { (to_visible[i], -1.0) };
            match d {
                Some(d2) => sign * ((d2.sqrt() - 0.5) * texel).min(D_MAX),
                None => sign * D_MAX,
            }
        })
        .collect()
}

/// Bilinear lookup of a table of texel-centre signed distances at plane point `p`. Beyond the
/// outermost texel centres the distance grows (`outside` visible) or falls (occluded) with the
/// distance travelled out of the table, where visibility is `outside` everywhere.
pub fn lookup(values: impl Fn(usize) -> f64, n: usize, p: DVec2, outside: bool) -> f64 {
    let half_texel = 1.0 / n as f64;
    let q = p.clamp(DVec2::splat(-1.0 + half_texel), DVec2::splat(1.0 - half_texel));
    let beyond = (p - q).length() * if outside { 1.0 } else { -1.0 };
    let coord = |c: f64| (to_texels(c, n) - 0.5).clamp(0.0, (n - 1) as f64);
    let (u, v) = (coord(q.x), coord(q.y));
    let (i, j) = ((u.floor() as usize).min(n - 2), (v.floor() as usize).min(n - 2));
    let (fu, fv) = (u - i as f64, v - j as f64);
    let at = |x: usize, y: usize| values(y * n + x);
    let inside = (at(i, j) * (1.0 - fu) + at(i + 1, j) * fu) * (1.0 - fv)
        + (at(i, j + 1) * (1.0 - fu) + at(i + 1, j + 1) * fu) * fv;
    inside + beyond
}

/// The local direction through each texel centre of an `n × n` table over the plane, or `None`
/// outside the unit disc (below the horizon); what the tables are ray-traced along.
pub fn texel_directions(n: usize) -> Vec<Option<DVec3>> {
    (0..n * n)
        .map(|i| {
            let p = DVec2::new(from_texels((i % n) as f64 + 0.5, n), from_texels((i / n) as f64 + 0.5, n));
            (p.length_squared() < 1.0).then(|| from_plane(p))
        })
        .collect()
}

/// Quantises a signed distance to 8-bit fixed point over `±D_MAX`.
pub(super) fn quantise(d: f64) -> i8 {
    (d / D_MAX * 127.0).round().clamp(-127.0, 127.0) as i8
}

pub(super) fn dequantise(q: i8) -> f64 {
    f64::from(q) * D_MAX / 127.0
}

/// Self-visibility distance tables of one object's vertices (object space).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Svdf {
    pub size: usize,
    pub vertices: usize,
    /// `vertices × size²` signed distances, 8-bit fixed point over `±D_MAX`.
    pub distances: Arc<Vec<i8>>,
    /// Per vertex: the object-space normal and tangent of the frame the table is in.
    pub frames: Arc<Vec<[[f32; 3]; 2]>>,
    /// Per vertex: its object-space position.
    pub positions: Arc<Vec<[f32; 3]>>,
}

impl Svdf {
    /// Ray-traces each receiver's visibility on a `size²` grid over its local plane (texel
    /// centres; outside the unit disc is below the horizon) and converts it to distances.
    pub fn compute(
        scene: &RayScene,
        receivers: &Receivers,
        size: usize,
        cancel: &CancelToken,
        progress: &(dyn Fn(f64) + Sync),
    ) -> Result<Self, StageError> {
        let directions = texel_directions(size);
        let done = std::sync::atomic::AtomicUsize::new(0);
        let count = receivers.len();
        let tables: Vec<Vec<i8>> = (0..count)
            .into_par_iter()
            .map(|r| {
                cancel.check()?;
                let (p, n) = receivers.point(r);
                let frame = receivers.frame(r);
                let origin = scene.leave_surface(p, n);
                let visible: Vec<bool> = directions
                    .iter()
                    .map(|d| match d {
                        Some(d) => {
                            let w = frame * *d;
                            w.dot(n) > 0.0 && !scene.occluded(origin, w.as_vec3().into(), f32::INFINITY)
                        }
                        None => BELOW_HORIZON_VISIBLE,
                    })
                    .collect();
                let finished = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                if finished.is_multiple_of(256) {
                    progress(finished as f64 / count as f64);
                }
                Ok(signed_distances(&visible, size, BELOW_HORIZON_VISIBLE).into_iter().map(quantise).collect())
            })
            .collect::<Result<_, StageError>>()?;
        let frames = (0..count).map(|r| [receivers.normals[r], receivers.tangents[r]]).collect();
        Ok(Self {
            size,
            vertices: count,
            distances: Arc::new(tables.concat()),
            frames: Arc::new(frames),
            positions: Arc::new(receivers.positions.clone()),
        })
    }

    /// Signed distance at plane point `p` of vertex `vertex`'s table (bilinear).
    pub fn distance(&self, vertex: usize, p: DVec2) -> f64 {
        let n = self.size;
        let table = &self.distances[vertex * n * n..(vertex + 1) * n * n];
        lookup(|i| dequantise(table[i]), n, p, BELOW_HORIZON_VISIBLE)
    }

    /// The local frame `[t, n × t, n]` (columns, object space) of vertex `vertex`'s table.
    pub fn frame(&self, vertex: usize) -> glam::DMat3 {
        let [n, t] = self.frames[vertex];
        let n = DVec3::from(n.map(f64::from)).normalize_or(DVec3::Y);
        let t = DVec3::from(t.map(f64::from));
        let t = (t - n * n.dot(t)).try_normalize().unwrap_or_else(|| n.any_orthonormal_vector());
        glam::DMat3::from_cols(t, n.cross(t), n)
    }

    /// The tables as floats (plane units), one row per vertex.
    pub fn tables(&self) -> Vec<f32> {
        self.distances.iter().map(|&q| dequantise(q) as f32).collect()
    }

    /// The tables compressed by clustered PCA (`clusters` k-means clusters, `vectors`
    /// principal directions each; the paper uses 256 × 8), with its relative error.
    pub fn compressed(&self, clusters: usize, vectors: usize) -> (super::compress::Compressed, f64) {
        let tables = self.tables();
        let dim = self.size * self.size;
        let assignment = super::compress::kmeans(&tables, dim, clusters, 2);
        let clusters = assignment.iter().max().map_or(1, |m| *m as usize + 1);
        let compressed = super::compress::compress_with(&tables, dim, assignment, clusters, vectors);
        let error = compressed.relative_error(&tables);
        (compressed, error)
    }

    /// Bytes per vertex, as stored.
    pub fn bytes_per_vertex(&self) -> usize {
        self.size * self.size
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::test_rng;
    use rand::Rng;

    #[test]
    fn distance_transform_equals_brute_force() {
        let mut rng = test_rng(8);
        for n in [1, 2, 7, 32] {
            for density in [0.02, 0.3, 0.9] {
                let feature: Vec<bool> = (0..n * n).map(|_| rng.random::<f64>() < density).collect();
                let got = squared_distances(&feature, n);
                for i in 0..n * n {
                    let (x, y) = ((i % n) as f64, (i / n) as f64);
                    let brute = (0..n * n)
                        .filter(|&j| feature[j])
                        .map(|j| ((j % n) as f64 - x).powi(2) + ((j / n) as f64 - y).powi(2))
                        .fold(None, |m: Option<f64>, d| Some(m.map_or(d, |m| m.min(d))));
                    assert_eq!(got[i], brute, "n {n}, texel {i}");
                }
            }
        }
    }

    /// Exact visible fraction of the axis-aligned square of edge `e` centred on `c` for the
    /// half-plane `x·cos a + y·sin a > t` (polygon clipping by fine quadrature of one axis).
    fn exact_fraction(c: DVec2, e: f64, a: f64, t: f64) -> f64 {
        let (ca, sa) = (a.cos(), a.sin());
        let steps = 4000;
        let mut visible = 0.0;
        for k in 0..steps {
            let x = c.x - e / 2.0 + e * (k as f64 + 0.5) / steps as f64;
            // Along y: the visible length of [c.y − e/2, c.y + e/2] where x ca + y sa > t.
            let (y0, y1) = (c.y - e / 2.0, c.y + e / 2.0);
            let len = if sa.abs() < 1e-12 {
                if x * ca > t { e } else { 0.0 }
            } else {
                let y_star = (t - x * ca) / sa;
                if sa > 0.0 { (y1 - y_star.max(y0)).clamp(0.0, e) } else { (y_star.min(y1) - y0).clamp(0.0, e) }
            };
            visible += len;
        }
        visible / steps as f64 / e
    }

    #[test]
    fn ramps_against_exact_fractions_of_straight_boundaries() {
        let mut rng = test_rng(9);
        let (mut worst_parallel, mut straight_sum, mut printed_sum, mut straight_worst) = (0.0f64, 0.0, 0.0, 0.0f64);
        let trials = 400;
        for k in 0..trials {
            let e = rng.random_range(0.05..0.5);
            let c = DVec2::new(rng.random_range(-0.3..0.3), rng.random_range(-0.3..0.3));
            let parallel = k % 4 == 0;
            let a = if parallel {
                (rng.random_range(0..4) as f64) * std::f64::consts::FRAC_PI_2
            } else {
                rng.random_range(0.0..std::f64::consts::TAU)
            };
            let d = rng.random_range(-0.7..0.7) * e;
            // The boundary line at signed distance d from the centre (visible side positive).
            let t = c.x * a.cos() + c.y * a.sin() - d;
            let exact = exact_fraction(c, e, a, t);
            let straight = visible_fraction(d, e, Ramp::StraightEdge);
            let printed = visible_fraction(d, e, Ramp::Printed);
            if parallel {
                worst_parallel = worst_parallel.max((straight - exact).abs());
            }
            straight_sum += straight - exact;
            printed_sum += printed - exact;
            straight_worst = straight_worst.max((straight - exact).abs());
        }
        let (straight_bias, printed_bias) = (straight_sum / trials as f64, printed_sum / trials as f64);
        println!(
            "straight-edge ramp: bias {straight_bias:+.4}, worst {straight_worst:.3}; printed Eq. 9: bias {printed_bias:+.4}"
        );
        assert!(worst_parallel < 1e-3, "parallel boundaries are exact: {worst_parallel}");
        assert!(straight_bias.abs() < 0.02 && straight_worst < 0.13, "{straight_bias} {straight_worst}");
        assert!(printed_bias > 0.2, "the printed ramp is biased towards light: {printed_bias}");
    }

    #[test]
    fn rasterised_half_plane_distances_match_the_analytic_distance() {
        // A straight boundary at a random angle, rasterised at texel centres: the table's
        // distances are within a texel of the true signed distance, and exact near an
        // axis-aligned one.
        let n = 32;
        let texel = 2.0 / n as f64;
        let mut rng = test_rng(10);
        for trial in 0..20 {
            let a = if trial == 0 { 0.0 } else { rng.random_range(0.0..std::f64::consts::TAU) };
            let t = if trial == 0 { 0.0 } else { rng.random_range(-0.5..0.5) };
            let centre =
                |i: usize| DVec2::new(from_texels((i % n) as f64 + 0.5, n), from_texels((i / n) as f64 + 0.5, n));
            let signed = |p: DVec2| p.x * a.cos() + p.y * a.sin() - t;
            let visible: Vec<bool> = (0..n * n).map(|i| signed(centre(i)) > 0.0).collect();
            let table = signed_distances(&visible, n, true);
            for i in 0..n * n {
                let truth = signed(centre(i)).clamp(-D_MAX, D_MAX);
                // The visible border stands in for more of the map: skip texels it is nearest.
                let border = (1.0 - centre(i).x.abs().max(centre(i).y.abs())) + 0.5 * texel;
                if border < truth.abs() + texel {
                    continue;
                }
                let tolerance = if trial == 0 { 1e-9 } else { texel };
                assert!((table[i] - truth).abs() <= tolerance, "trial {trial} texel {i}: {} vs {truth}", table[i]);
            }
        }
    }

    #[test]
    fn a_floor_sees_its_upper_hemisphere_and_a_ceiling_blocks_part_of_it() {
        use crate::mesh;
        let floor = mesh::plane(4.0, 1);
        // Off the roof's centre, so no ray runs exactly along its triangles' shared edge.
        let receivers = Receivers {
            positions: vec![[0.013, 0.0, 0.007]],
            normals: vec![[0.0, 1.0, 0.0]],
            tangents: vec![[1.0, 0.0, 0.0]],
            mesh_offsets: vec![0],
        };
        let open = RayScene::build(&crate::mesh::MeshSet { meshes: vec![floor.clone()] });
        let svdf = Svdf::compute(&open, &receivers, VDT_SIZE, &CancelToken::default(), &|_| {}).unwrap();
        // Nothing blocks the open floor (the horizon is left to the BRDF): no boundary anywhere.
        for p in [DVec2::ZERO, DVec2::new(1.0, 0.0), DVec2::new(-0.7, 0.7)] {
            let d = svdf.distance(0, p);
            assert!(d > 0.9, "{p}: {d}");
        }
        // A roof of half-width 1 at height 1 hides directions within 45° of the zenith.
        let roof = mesh::plane(2.0, 1).transformed(glam::DMat4::from_translation(DVec3::new(0.0, 1.0, 0.0)));
        let covered = RayScene::build(&crate::mesh::MeshSet { meshes: vec![floor, roof] });
        let svdf = Svdf::compute(&covered, &receivers, VDT_SIZE, &CancelToken::default(), &|_| {}).unwrap();
        let centre = svdf.distance(0, DVec2::ZERO);
        assert!(centre < -0.3, "{centre}");
        let at = |theta_deg: f64| {
            super::super::plane::to_plane(DVec3::new(theta_deg.to_radians().sin(), 0.0, theta_deg.to_radians().cos()))
        };
        assert!(svdf.distance(0, at(70.0)) > 0.0 && svdf.distance(0, at(30.0)) < 0.0);
    }
}
