//! Rotatable square lights (Xu, Jia, Hu and Tai 2006, §4.1): the environment's cube map is
//! merged bottom-up into regions, each fitted with a square light of uniform intensity that
//! may turn freely about its centre.
//!
//! - **Fit (§4.1.1, Eq. 7).** A region `S` is fitted by a square of centre `c` (a texel
//!   centre) and half-diagonal `r`, minimising `|S'| · E_θ[∫_{S'} (T − F_θ)² dω]` over
//!   `S' = S ∪ O_r` (`O_r` the disc the square sweeps), with `T = L` on `S` and `F_θ = I` on
//!   the square turned by `θ` (four turns in `[0, π/2)`). The penalty multiplies the error,
//!   so bright regions stay small. Integrals are over solid angle (texels weighted by their
//!   exact solid angle); the square's geometry is measured in texels of its face, its solid
//!   angle is the exact one of the square on the face's plane, and a texel cut by the
//!   square's rim counts by the part inside (a linear ramp across the texel).
//! - **Intensity.** `I = ∫_S L dω / Ω` per RGB channel, so `Σ I Ω` equals the environment's
//!   energy exactly (notes §1.7: store the solid angle `Ω`).
//! - **Decomposition (§4.1.2, Fig. 5).** Every texel starts as a region; the pair of
//!   4-connected regions on one face whose *merged* region fits with the smallest error is
//!   merged, until `K` remain. The merge order does not depend on `K` (notes §9), so the
//!   whole sequence is computed once ([`MergeSequence`]) and any `K` is a cut of it
//!   ([`MergeSequence::cut`]). Ties break by `(error, lower id, higher id)`; a priority
//!   queue with lazy invalidation replaces the paper's full rescan with the same result.
//! - The fit runs on luminance; the objective scales with the square of a global exposure,
//!   so exposure does not change the partition (notes §1.4).
//!
//! Submodules: [`plane`] (the equal-area hemisphere-to-disc map of §5), [`brdf_sat`] (the
//! BRDF integral over a square by summed-area tables, §4.2 Eq. 8), [`vdt`] (visibility by
//! distance tables, §4.3 Eqs. 9–10) and [`shade`] (per-vertex shading, Eq. 5).

pub mod brdf_sat;
pub mod compress;
pub mod ovdf;
pub mod plane;
pub mod shade;
pub mod vdt;

#[cfg(test)]
mod experiment;

use crate::cubemap::{CubeMap, FACES, face_rect_solid_angle, face_uv_to_dir, texel_solid_angle};
use crate::engine::CancelToken;
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::cmp::Reverse;
use std::collections::BinaryHeap;

crate::stage_type!(MergeSequence, "rsl_merge_sequence", |v| v.merges.len() * 8 + 64);
crate::stage_type!(SquareLights, "square_lights", |v| v.lights.len() * 64 + v.labels.len() * 4);
crate::stage_type!(WorldLights, "world_square_lights", |v| v.lights.len() * 64);

/// The square lights in the world frame, after exposure, tint and the environment's rotation:
/// what shading reads each frame, and what export writes as directional lights with an
/// angular size.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct WorldLights {
    pub lights: Vec<SquareLight>,
}

/// Turns of the square averaged by the fit (the paper's 0, π/8, π/4, 3π/8).
pub const ROTATION_SAMPLES: usize = 4;

/// One rotatable square light.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SquareLight {
    /// Unit direction of the square's centre (environment frame).
    pub direction: [f64; 3],
    /// The square's solid angle, sr.
    pub solid_angle: f64,
    /// Radiance per RGB channel (`∫_S L dω / Ω`).
    pub intensity: [f64; 3],
    /// Half-diagonal in texels of its face.
    pub half_diagonal_texels: f64,
    /// The fit's `E_θ[∫ (T − F)² dω]` on luminance.
    pub fit_error: f64,
    /// Texels of its region.
    pub texels: usize,
}

/// The lights of one cut, with each texel's region (an index into `lights`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SquareLights {
    pub size: usize,
    pub lights: Vec<SquareLight>,
    /// Per texel (`face · size² + y · size + x`): its light.
    pub labels: Vec<u32>,
}

/// The full merge order of a cube map: `(kept, absorbed)` region ids, where a region's id
/// is its lowest texel index.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MergeSequence {
    pub size: usize,
    pub merges: Vec<(u32, u32)>,
}

/// Luminance (Rec. 709), the channel the fit runs on.
fn luminance(c: [f32; 3]) -> f64 {
    0.2126 * f64::from(c[0]) + 0.7152 * f64::from(c[1]) + 0.0722 * f64::from(c[2])
}

/// Per-texel data the fits read.
struct Texels {
    size: usize,
    /// Luminance.
    lum: Vec<f64>,
    /// Solid angle.
    omega: Vec<f64>,
}

impl Texels {
    fn new(cube: &CubeMap) -> Self {
        let n = cube.size;
        let mut omega = Vec::with_capacity(cube.texels.len());
        for _ in 0..FACES {
            for y in 0..n {
                for x in 0..n {
                    omega.push(texel_solid_angle(n, x, y));
                }
            }
        }
        Self { size: n, lum: cube.texels.iter().map(|&t| luminance(t).max(0.0)).collect(), omega }
    }

    fn xy(&self, t: u32) -> (usize, usize, usize) {
        let n = self.size;
        let t = t as usize;
        (t / (n * n), t % n, (t / n) % n)
    }
}

/// Solid angle of the square of `edge` texels centred on texel `centre` of a `size²` face,
/// exact for the unturned square on the face's plane (turns change it by under 1% for
/// squares up to a third of the face, 1.6% for large ones near a corner).
fn square_solid_angle(size: usize, centre: (usize, usize), edge: usize) -> f64 {
    let texel = 2.0 / size as f64;
    let half = 0.5 * edge as f64 * texel;
    let (x, y) = (-1.0 + (centre.0 as f64 + 0.5) * texel, -1.0 + (centre.1 as f64 + 0.5) * texel);
    face_rect_solid_angle(x - half, y - half, x + half, y + half)
}

/// A fitted square on one face: centre texel, half-edge in texels, and the objective.
#[derive(Clone, Copy, Debug)]
struct Fit {
    objective: f64,
    centre: (usize, usize),
    /// Edge in texels (the half-edge steps by half a texel).
    edge: usize,
    error: f64,
}

/// Fits a square to the region `texels` (all on one face), Eq. 7.
fn fit(t: &Texels, texels: &[u32]) -> Fit {
    let n = t.size;
    let (face, ..) = t.xy(texels[0]);
    let energy: f64 = texels.iter().map(|&i| t.lum[i as usize] * t.omega[i as usize]).sum();
    let squared: f64 = texels.iter().map(|&i| t.lum[i as usize].powi(2) * t.omega[i as usize]).sum();
    let area: f64 = texels.iter().map(|&i| t.omega[i as usize]).sum();
    // Centroid, by energy (by area for a black region).
    let (mut sx, mut sy, mut sw) = (0.0, 0.0, 0.0);
    for &i in texels {
        let (_, x, y) = t.xy(i);
        let w = if energy > 0.0 { t.lum[i as usize] * t.omega[i as usize] } else { t.omega[i as usize] };
        sx += w * x as f64;
        sy += w * y as f64;
        sw += w;
    }
    let (cx, cy) = ((sx / sw).round() as i64, (sy / sw).round() as i64);
    let extent = texels
        .iter()
        .map(|&i| {
            let (_, x, y) = t.xy(i);
            (x as i64 - cx).abs().max((y as i64 - cy).abs())
        })
        .max()
        .unwrap_or(0);
    // Edges 1 ..= max_edge texels (half-edge in half-texel steps).
    let max_edge = (2 * extent as usize + 3).min(2 * n + 1);
    let mut best = Fit { objective: f64::INFINITY, centre: (0, 0), edge: 1, error: 0.0 };
    let _ = face;
    let mut inside = vec![0.0; max_edge + 2];
    let mut partial = vec![0.0; max_edge + 2];
    let mut in_disc = vec![0.0; max_edge + 2];
    let mut error_sum = vec![0.0; max_edge + 1];
    for oy in -1..=1 {
        for ox in -1..=1 {
            let (px, py) = (cx + ox, cy + oy);
            if px < 0 || py < 0 || px >= n as i64 || py >= n as i64 {
                continue;
            }
            let omega_c = texel_solid_angle(n, px as usize, py as usize);
            let square_omega: Vec<f64> =
                (0..=max_edge).map(|edge| square_solid_angle(n, (px as usize, py as usize), edge)).collect();
            error_sum.iter_mut().for_each(|e| *e = 0.0);
            for k in 0..ROTATION_SAMPLES {
                let (s, c) = (k as f64 * std::f64::consts::FRAC_PI_2 / ROTATION_SAMPLES as f64).sin_cos();
                // The part of a texel inside the square of edge `e`, with `h` its centre's
                // rotated offset (max of both axes) and `w` the texel's half-extent along
                // them: a ramp from 0 at `e/2 = h − w` to 1 at `e/2 = h + w` (exact along an
                // edge of the unturned square). Whole texels accumulate in `inside` from the
                // first edge covering them; partial ones add to `partial` edge by edge.
                inside.iter_mut().for_each(|v| *v = 0.0);
                partial.iter_mut().for_each(|v| *v = 0.0);
                let w = 0.5 * (c.abs() + s.abs());
                for &i in texels {
                    let (_, x, y) = t.xy(i);
                    let (dx, dy) = ((x as i64 - px) as f64, (y as i64 - py) as f64);
                    let h = (dx * c + dy * s).abs().max((-dx * s + dy * c).abs());
                    let weight = t.lum[i as usize] * t.omega[i as usize];
                    let (lo, hi) = (2.0 * (h - w), 2.0 * (h + w));
                    let full = ((hi - 1e-9).ceil().max(1.0) as usize).min(max_edge + 1);
                    inside[full] += weight;
                    for (edge, slot) in
                        partial.iter_mut().enumerate().take(full).skip((lo.floor().max(0.0) as usize) + 1)
                    {
                        *slot += weight * ((edge as f64 - lo) / (hi - lo)).clamp(0.0, 1.0);
                    }
                }
                let mut whole = 0.0;
                for edge in 1..=max_edge {
                    whole += inside[edge];
                    let covered = whole + partial[edge];
                    let omega_sq = square_omega[edge];
                    let eta = (squared - 2.0 * energy * covered / omega_sq + energy * energy / omega_sq).max(0.0);
                    error_sum[edge] += eta;
                }
            }
            // |S ∩ O_r|: texels within the square's half-diagonal r = edge / √2.
            in_disc.iter_mut().for_each(|v| *v = 0.0);
            for &i in texels {
                let (_, x, y) = t.xy(i);
                let d = ((x as i64 - px) as f64).hypot((y as i64 - py) as f64);
                let bucket = ((std::f64::consts::SQRT_2 * d - 1e-9).ceil().max(1.0) as usize).min(max_edge + 1);
                in_disc[bucket] += t.omega[i as usize];
            }
            let mut overlap = 0.0;
            for edge in 1..=max_edge {
                overlap += in_disc[edge];
                let r = edge as f64 / std::f64::consts::SQRT_2;
                let extended = area + (std::f64::consts::PI * r * r * omega_c - overlap).max(0.0);
                let error = error_sum[edge] / ROTATION_SAMPLES as f64;
                let objective = extended * error;
                if objective < best.objective {
                    best = Fit { objective, centre: (px as usize, py as usize), edge, error };
                }
            }
        }
    }
    best
}

/// The square light fitted to a region.
fn light(t: &Texels, cube: &CubeMap, texels: &[u32]) -> SquareLight {
    let n = t.size;
    let f = fit(t, texels);
    let (face, ..) = t.xy(texels[0]);
    let solid_angle = square_solid_angle(n, f.centre, f.edge);
    let mut energy = [0.0; 3];
    for &i in texels {
        for (c, e) in energy.iter_mut().enumerate() {
            *e += f64::from(cube.texels[i as usize][c]) * t.omega[i as usize];
        }
    }
    let u = (f.centre.0 as f64 + 0.5) / n as f64;
    let v = (f.centre.1 as f64 + 0.5) / n as f64;
    SquareLight {
        direction: face_uv_to_dir(face, u, v).to_array(),
        solid_angle,
        intensity: energy.map(|e| e / solid_angle),
        half_diagonal_texels: f.edge as f64 / std::f64::consts::SQRT_2,
        fit_error: f.error,
        texels: texels.len(),
    }
}

/// Total order on `f64` costs for the queue (NaN last).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Cost(f64);
impl Eq for Cost {}
impl PartialOrd for Cost {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Cost {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

/// Region ids adjacent (4-connected, same face) to the region `texels`.
fn neighbours(t: &Texels, labels: &[u32], id: u32, texels: &[u32]) -> Vec<u32> {
    let n = t.size;
    let mut out = Vec::new();
    for &i in texels {
        let (face, x, y) = t.xy(i);
        let base = face * n * n;
        let mut look = |xx: usize, yy: usize| {
            let l = labels[base + yy * n + xx];
            if l != id && !out.contains(&l) {
                out.push(l);
            }
        };
        if x > 0 {
            look(x - 1, y);
        }
        if x + 1 < n {
            look(x + 1, y);
        }
        if y > 0 {
            look(x, y - 1);
        }
        if y + 1 < n {
            look(x, y + 1);
        }
    }
    out
}

/// Which pair of regions merges next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MergeRule {
    /// The paper's (§4.1.2): the pair whose merged region fits with the smallest error.
    MergedError,
    /// The notes' extension: the pair whose merge adds the least error to the total
    /// (`E(a ∪ b) − E(a) − E(b)`), the greedy step towards §3's stated goal of a small sum.
    ErrorIncrease,
}

impl MergeSequence {
    /// Merges the cube map's texels down to one region per face (Fig. 5 run to the end) with
    /// the paper's rule, reporting progress; `Err` when cancelled.
    pub fn compute(cube: &CubeMap, cancel: &CancelToken, progress: &dyn Fn(f64)) -> Result<Self, String> {
        Self::compute_with(cube, MergeRule::MergedError, cancel, progress)
    }

    /// [`Self::compute`] with a choice of merge rule.
    pub fn compute_with(
        cube: &CubeMap,
        rule: MergeRule,
        cancel: &CancelToken,
        progress: &dyn Fn(f64),
    ) -> Result<Self, String> {
        let t = Texels::new(cube);
        let n = cube.size;
        let count = FACES * n * n;
        let mut labels: Vec<u32> = (0..count as u32).collect();
        let mut members: Vec<Vec<u32>> = (0..count as u32).map(|i| vec![i]).collect();
        let mut version = vec![0u32; count];
        let mut heap = BinaryHeap::new();
        let union = |a: &[u32], b: &[u32]| -> Vec<u32> { a.iter().chain(b).copied().collect() };
        // Each region's own fit objective (read by the error-increase rule).
        let mut own: Vec<f64> = match rule {
            MergeRule::MergedError => vec![0.0; count],
            MergeRule::ErrorIncrease => (0..count as u32).map(|i| fit(&t, &[i]).objective).collect(),
        };
        for i in 0..count as u32 {
            let (_, x, y) = t.xy(i);
            for (ok, j) in [(x + 1 < n, i + 1), (y + 1 < n, i + n as u32)] {
                if ok {
                    let cost = fit(&t, &[i, j]).objective - own[i as usize] - own[j as usize];
                    heap.push(Reverse((Cost(cost), i, j, 0u32, 0u32)));
                }
            }
        }
        let total = count - FACES;
        let mut merges = Vec::with_capacity(total);
        while let Some(Reverse((_, a, b, va, vb))) = heap.pop() {
            if version[a as usize] != va || version[b as usize] != vb || members[b as usize].is_empty() {
                continue;
            }
            if merges.len() % 64 == 0 {
                if cancel.is_cancelled() {
                    return Err("cancelled".into());
                }
                progress(merges.len() as f64 / total as f64);
            }
            // `a < b`: the merged region keeps the lower id.
            let absorbed = std::mem::take(&mut members[b as usize]);
            for &i in &absorbed {
                labels[i as usize] = a;
            }
            members[a as usize].extend(absorbed);
            version[a as usize] += 1;
            version[b as usize] += 1;
            merges.push((a, b));
            if rule == MergeRule::ErrorIncrease {
                own[a as usize] = fit(&t, &members[a as usize]).objective;
            }
            for k in neighbours(&t, &labels, a, &members[a as usize]) {
                let (lo, hi) = (a.min(k), a.max(k));
                let merged = fit(&t, &union(&members[lo as usize], &members[hi as usize])).objective;
                let cost = merged - own[lo as usize] - own[hi as usize];
                heap.push(Reverse((Cost(cost), lo, hi, version[lo as usize], version[hi as usize])));
            }
        }
        progress(1.0);
        Ok(Self { size: n, merges })
    }

    /// The first merges that leave `k` regions (at least one per face), each fitted.
    pub fn cut(&self, cube: &CubeMap, k: usize) -> SquareLights {
        assert_eq!(cube.size, self.size, "the merge sequence is of another cube map");
        let t = Texels::new(cube);
        let count = cube.texels.len();
        let steps = count.saturating_sub(k.max(FACES)).min(self.merges.len());
        let mut members: Vec<Vec<u32>> = (0..count as u32).map(|i| vec![i]).collect();
        for &(a, b) in &self.merges[..steps] {
            let absorbed = std::mem::take(&mut members[b as usize]);
            members[a as usize].extend(absorbed);
        }
        let mut labels = vec![0u32; count];
        let mut lights = Vec::new();
        for region in members.iter().filter(|m| !m.is_empty()) {
            for &i in region {
                labels[i as usize] = lights.len() as u32;
            }
            lights.push(light(&t, cube, region));
        }
        SquareLights { size: self.size, lights, labels }
    }
}

impl SquareLights {
    /// `Σ I Ω` per channel: the lights' total energy.
    pub fn energy(&self) -> [f64; 3] {
        let mut e = [0.0; 3];
        for l in &self.lights {
            for (c, v) in e.iter_mut().enumerate() {
                *v += l.intensity[c] * l.solid_angle;
            }
        }
        e
    }

    /// The lights with intensities scaled per channel and directions turned by `rotation`
    /// (exposure, tint and environment rotation: O(K), no new decomposition).
    pub fn transformed(&self, scale: [f64; 3], rotation: glam::DQuat) -> Vec<SquareLight> {
        self.lights
            .iter()
            .map(|l| SquareLight {
                direction: (rotation * DVec3::from(l.direction)).to_array(),
                intensity: [0, 1, 2].map(|c| l.intensity[c] * scale[c]),
                ..l.clone()
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::SQRT_2;

    fn cube_from(size: usize, mut f: impl FnMut(usize, usize, usize) -> [f32; 3]) -> CubeMap {
        let mut texels = Vec::new();
        for face in 0..FACES {
            for y in 0..size {
                for x in 0..size {
                    texels.push(f(face, x, y));
                }
            }
        }
        CubeMap::new(size, texels)
    }

    /// A reproducible pseudo-random environment with a few bright spots.
    fn random_cube(size: usize, seed: u64) -> CubeMap {
        let mut state = seed;
        let mut next = move || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 33) as f64 / (1u64 << 31) as f64) as f32
        };
        cube_from(size, |_, _, _| {
            let base = next();
            let spike = if next() > 0.97 { 40.0 * next() } else { 0.0 };
            [base + spike, 0.5 * base + spike, 0.2 + spike * 0.8]
        })
    }

    fn no_progress(_: f64) {}

    fn texel_energy(cube: &CubeMap) -> [f64; 3] {
        let t = Texels::new(cube);
        let mut e = [0.0; 3];
        for (i, texel) in cube.texels.iter().enumerate() {
            for c in 0..3 {
                e[c] += f64::from(texel[c]) * t.omega[i];
            }
        }
        e
    }

    #[test]
    fn regions_partition_the_texels_connected_on_one_face_exactly_k() {
        let cube = random_cube(8, 7);
        let sequence = MergeSequence::compute(&cube, &CancelToken::default(), &no_progress).unwrap();
        assert_eq!(sequence.merges.len(), 6 * 64 - 6, "merging runs down to one region per face");
        let t = Texels::new(&cube);
        for k in [6, 10, 30, 100] {
            let cut = sequence.cut(&cube, k);
            assert_eq!(cut.lights.len(), k);
            assert_eq!(cut.labels.len(), cube.texels.len());
            assert_eq!(cut.lights.iter().map(|l| l.texels).sum::<usize>(), cube.texels.len(), "a partition");
            for region in 0..k as u32 {
                let texels: Vec<u32> =
                    (0..cube.texels.len() as u32).filter(|&i| cut.labels[i as usize] == region).collect();
                let faces: std::collections::BTreeSet<usize> = texels.iter().map(|&i| t.xy(i).0).collect();
                assert_eq!(faces.len(), 1, "region {region} spans faces {faces:?}");
                // 4-connected: a flood fill from one texel reaches them all.
                let mut seen = vec![texels[0]];
                let mut stack = vec![texels[0]];
                while let Some(i) = stack.pop() {
                    for j in &texels {
                        let ((_, x0, y0), (_, x1, y1)) = (t.xy(i), t.xy(*j));
                        if x0.abs_diff(x1) + y0.abs_diff(y1) == 1 && !seen.contains(j) {
                            seen.push(*j);
                            stack.push(*j);
                        }
                    }
                }
                assert_eq!(seen.len(), texels.len(), "region {region} is not connected");
            }
        }
    }

    #[test]
    fn energy_is_conserved_per_channel() {
        for (size, seed) in [(8, 1), (16, 2)] {
            let cube = random_cube(size, seed);
            let sequence = MergeSequence::compute(&cube, &CancelToken::default(), &no_progress).unwrap();
            let truth = texel_energy(&cube);
            for k in [6, 12, 40] {
                let lights = sequence.cut(&cube, k).energy();
                for c in 0..3 {
                    assert!(
                        (lights[c] - truth[c]).abs() <= 1e-6 * truth[c],
                        "K={k} channel {c}: {lights:?} vs {truth:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn exposure_leaves_the_partition_unchanged_and_scales_intensity() {
        let cube = random_cube(8, 3);
        let brighter = CubeMap::new(8, cube.texels.iter().map(|t| t.map(|c| c * 4.0)).collect());
        let a = MergeSequence::compute(&cube, &CancelToken::default(), &no_progress).unwrap();
        let b = MergeSequence::compute(&brighter, &CancelToken::default(), &no_progress).unwrap();
        assert_eq!(a, b, "the merge order does not depend on exposure");
        let (la, lb) = (a.cut(&cube, 20), b.cut(&brighter, 20));
        assert_eq!(la.labels, lb.labels);
        for (x, y) in la.lights.iter().zip(&lb.lights) {
            for c in 0..3 {
                assert!((y.intensity[c] - 4.0 * x.intensity[c]).abs() <= 1e-9 * y.intensity[c].max(1e-12));
            }
        }
    }

    /// Fit recovery (notes §6.5): a uniform square region of known centre and edge, fitted
    /// alone (Eq. 7), gives its centre within one texel and its half-diagonal within half a
    /// texel, wherever it sits on the face (edges odd and even, near the rim).
    #[test]
    fn a_uniform_square_region_is_fitted_by_itself() {
        let size = 32;
        for (x0, y0, edge) in [(9, 14, 6), (3, 20, 5), (12, 12, 8), (0, 0, 3), (22, 2, 9), (14, 15, 1)] {
            let cube = cube_from(size, |face, x, y| {
                let lit = face == 2 && (x0..x0 + edge).contains(&x) && (y0..y0 + edge).contains(&y);
                if lit { [20.0; 3] } else { [0.0; 3] }
            });
            let t = Texels::new(&cube);
            let region: Vec<u32> =
                (0..cube.texels.len() as u32).filter(|&i| cube.texels[i as usize][0] > 0.0).collect();
            let f = fit(&t, &region);
            let (cx, cy) = (x0 as f64 + edge as f64 / 2.0, y0 as f64 + edge as f64 / 2.0);
            let (fx, fy) = (f.centre.0 as f64 + 0.5, f.centre.1 as f64 + 0.5);
            assert!(
                (fx - cx).abs() <= 1.0 && (fy - cy).abs() <= 1.0,
                "square at ({x0}, {y0}) edge {edge}: centre ({fx}, {fy}) vs ({cx}, {cy})"
            );
            let (r_fit, r_true) = (f.edge as f64 / SQRT_2, edge as f64 / SQRT_2);
            assert!((r_fit - r_true).abs() <= 0.5, "square at ({x0}, {y0}) edge {edge}: r {r_fit} vs {r_true}");
        }
    }

    /// `E_θ η` as the fit rasterises it (each texel by the ramp of its part inside the square)
    /// agrees with a supersampled computation of `E_θ ∫ (T − F)² dω` over the same region and
    /// square, within 8% at every size (texels wholly in or out by their centres, with the
    /// square's solid angle taken as `edge² ω(c)`, were 5%, 38% and 70% off).
    #[test]
    fn the_rasterised_fit_error_agrees_with_supersampling() {
        let size = 32;
        for edge in [4usize, 8, 16] {
            // A bright disc of radius 0.45 edge in a dim face: not a square, so η > 0.
            let (cx, cy) = (16.0, 16.0);
            let radius = 0.45 * edge as f64;
            let cube = cube_from(size, |face, x, y| {
                let d = (x as f64 + 0.5 - cx).hypot(y as f64 + 0.5 - cy);
                if face == 0 && d <= radius { [10.0; 3] } else { [0.0; 3] }
            });
            let t = Texels::new(&cube);
            let region: Vec<u32> = (0..size * size).map(|i| i as u32).collect();
            let f = fit(&t, &region);
            // Supersample each texel 16×16, the square centred on the fitted texel centre.
            let (px, py) = (f.centre.0 as f64 + 0.5, f.centre.1 as f64 + 0.5);
            let energy: f64 = region.iter().map(|&i| t.lum[i as usize] * t.omega[i as usize]).sum();
            let intensity = energy / square_solid_angle(size, f.centre, f.edge);
            let sub = 16;
            let mut supersampled = 0.0;
            for k in 0..ROTATION_SAMPLES {
                let (s, c) = (k as f64 * std::f64::consts::FRAC_PI_2 / ROTATION_SAMPLES as f64).sin_cos();
                for &i in &region {
                    let (_, x, y) = t.xy(i);
                    let mut acc = 0.0;
                    for sy in 0..sub {
                        for sx in 0..sub {
                            let ux = x as f64 + (sx as f64 + 0.5) / sub as f64 - px;
                            let uy = y as f64 + (sy as f64 + 0.5) / sub as f64 - py;
                            let h = (ux * c + uy * s).abs().max((-ux * s + uy * c).abs());
                            let lit = if h <= f.edge as f64 / 2.0 { intensity } else { 0.0 };
                            acc += (t.lum[i as usize] - lit).powi(2);
                        }
                    }
                    supersampled += acc / (sub * sub) as f64 * t.omega[i as usize];
                }
            }
            supersampled /= ROTATION_SAMPLES as f64;
            let relative = (f.error - supersampled).abs() / supersampled;
            assert!(relative < 0.08, "edge {edge}: rasterised {} vs supersampled {supersampled}", f.error);
        }
    }

    /// A synthetic square light. Where the cut leaves it one region (K = 7: one region per
    /// face plus the square), it is recovered: its texels exactly, the centre within a texel
    /// and the half-diagonal within half a texel. Finer cuts split it (its inner merges are
    /// the costliest, as bright regions stay small), and then the brightest light sits on it
    /// and the lights on it keep its energy centre within a texel.
    #[test]
    fn a_square_light_is_recovered() {
        let (size, x0, y0, edge) = (32, 9, 14, 6);
        let lit =
            |face: usize, x: usize, y: usize| face == 4 && (x0..x0 + edge).contains(&x) && (y0..y0 + edge).contains(&y);
        let cube = cube_from(size, |face, x, y| if lit(face, x, y) { [50.0; 3] } else { [0.05; 3] });
        let (cx, cy) = (x0 as f64 + edge as f64 / 2.0, y0 as f64 + edge as f64 / 2.0);
        let texel_xy = |light: &SquareLight| {
            let (face, u, v) = crate::cubemap::dir_to_face_uv(DVec3::from(light.direction));
            (face, u * size as f64, v * size as f64)
        };
        let sequence = MergeSequence::compute(&cube, &CancelToken::default(), &no_progress).unwrap();
        let whole = sequence.cut(&cube, 7);
        let square_label = whole.labels[4 * size * size + y0 * size + x0];
        let region: Vec<usize> = (0..whole.labels.len()).filter(|&i| whole.labels[i] == square_label).collect();
        let lit_texels: Vec<usize> =
            (0..whole.labels.len()).filter(|&i| lit(i / (size * size), i % size, (i / size) % size)).collect();
        assert_eq!(region, lit_texels, "K=7: the square is one region");
        let light = &whole.lights[square_label as usize];
        let (face, x, y) = texel_xy(light);
        assert_eq!(face, 4);
        assert!((x - cx).abs() <= 1.0 && (y - cy).abs() <= 1.0, "K=7: centre ({x:.2}, {y:.2}) vs ({cx}, {cy})");
        let r_true = edge as f64 / SQRT_2;
        assert!(
            (light.half_diagonal_texels - r_true).abs() <= 0.5,
            "K=7: r {} vs {r_true}",
            light.half_diagonal_texels
        );
        for k in [12, 30, 60] {
            let cut = sequence.cut(&cube, k);
            let brightest = cut.lights.iter().max_by(|a, b| a.intensity[0].total_cmp(&b.intensity[0])).unwrap();
            let (face, x, y) = texel_xy(brightest);
            assert_eq!(face, 4, "K={k}");
            assert!(
                (x0 as f64..(x0 + edge) as f64).contains(&x) && (y0 as f64..(y0 + edge) as f64).contains(&y),
                "K={k}: the brightest light is centred at ({x:.1}, {y:.1}), outside the square"
            );
            let on_square: Vec<&SquareLight> = cut
                .lights
                .iter()
                .enumerate()
                .filter(|&(l, _)| lit_texels.iter().any(|&i| cut.labels[i] as usize == l))
                .map(|(_, light)| light)
                .collect();
            let (mut ex, mut ey, mut e) = (0.0, 0.0, 0.0);
            for light in &on_square {
                let (_, x, y) = texel_xy(light);
                let power = light.intensity[0] * light.solid_angle;
                (ex, ey, e) = (ex + power * x, ey + power * y, e + power);
            }
            let (ex, ey) = (ex / e, ey / e);
            assert!(
                (ex - cx).abs() <= 1.0 && (ey - cy).abs() <= 1.0,
                "K={k}: {} lights on the square, energy centre ({ex:.2}, {ey:.2}) vs ({cx}, {cy})",
                on_square.len()
            );
        }
    }

    /// The queue picks what the paper's full rescan picks: at every step, the pair of
    /// adjacent regions whose merged region fits best (ties by lower, then higher id); and
    /// with the error-increase rule, the pair whose merge adds the least error.
    #[test]
    fn the_merge_order_equals_a_brute_force_rescan() {
        for rule in [MergeRule::MergedError, MergeRule::ErrorIncrease] {
            let cube = random_cube(4, 11);
            let sequence = MergeSequence::compute_with(&cube, rule, &CancelToken::default(), &no_progress).unwrap();
            let t = Texels::new(&cube);
            let count = cube.texels.len();
            let own = |members: &[u32]| if rule == MergeRule::ErrorIncrease { fit(&t, members).objective } else { 0.0 };
            let mut labels: Vec<u32> = (0..count as u32).collect();
            let mut members: Vec<Vec<u32>> = (0..count as u32).map(|i| vec![i]).collect();
            for step in 0..count - FACES {
                let mut best: Option<(f64, u32, u32)> = None;
                for a in 0..count as u32 {
                    if members[a as usize].is_empty() {
                        continue;
                    }
                    for b in neighbours(&t, &labels, a, &members[a as usize]) {
                        if b <= a {
                            continue;
                        }
                        let merged: Vec<u32> =
                            members[a as usize].iter().chain(&members[b as usize]).copied().collect();
                        let cost = fit(&t, &merged).objective - own(&members[a as usize]) - own(&members[b as usize]);
                        if best.is_none_or(|(c, ..)| cost.total_cmp(&c).is_lt()) {
                            best = Some((cost, a, b));
                        }
                    }
                }
                let (_, a, b) = best.expect("a pair to merge");
                assert_eq!(sequence.merges[step], (a, b), "{rule:?}, step {step}");
                let absorbed = std::mem::take(&mut members[b as usize]);
                for &i in &absorbed {
                    labels[i as usize] = a;
                }
                members[a as usize].extend(absorbed);
            }
        }
    }

    #[test]
    fn bright_regions_stay_small() {
        // Sun plus sky: the sun's region is among the smallest.
        let size = 16;
        let cube = cube_from(size, |face, x, y| {
            if face == 2 && (7..9).contains(&x) && (7..9).contains(&y) { [400.0; 3] } else { [0.3, 0.4, 0.6] }
        });
        let sequence = MergeSequence::compute(&cube, &CancelToken::default(), &no_progress).unwrap();
        let cut = sequence.cut(&cube, 20);
        let sun = cut.lights.iter().max_by(|a, b| a.intensity[0].total_cmp(&b.intensity[0])).unwrap();
        let smaller = cut.lights.iter().filter(|l| l.texels < sun.texels).count();
        assert!(smaller <= 2, "the sun's region ({} texels) is among the smallest", sun.texels);
        assert!(DVec3::from(sun.direction).dot(DVec3::Y) > 0.99, "the sun is straight up: {:?}", sun.direction);
    }
}
