//! All-frequency relighting by triple products in each receiver's local frame (Ma et al.,
//! "triple product relighting in a spherical local frame", eq. 7):
//! `B(x, ω_o) = ∫ L^x(ω) V^x(ω) ρ̃^{ω_o}(ω) dω` with `L^x(ω) = L(M_x ω)` the lighting in the
//! frame `M_x = [t, b, n]`, `V^x` the visibility and `ρ̃ = ρ·cos θ` the BRDF.
//!
//! Top-only truncation to `n = 20·4^k` icosahedral Haar coefficients (Ma's 80 and 320) is a box
//! filter onto the level-`k` cells (see `wavelet::spherical`), so the triple product of the
//! truncated functions is the cell sum `Σ_c ΔΩ_c L_c V_c ρ̃_c` with cell averages — exact for
//! cell-constant functions, with the true solid angles `ΔΩ_c` folded in (the notes' fix for the
//! paper's parametric measure). The sum splits into a per-receiver product
//! `P_c = ΔΩ_c L_c V_c` (lighting × visibility, rebuilt when either changes) and per-material
//! tables: `D_c`, the cell average of `cos θ/π` (diffuse), and `S_c(ω_o)`, the cell average of
//! the specular lobe times `cos θ` on a grid of outgoing directions. A frame is then
//! `B = albedo Σ P_c D_c + specular Σ P_c S_c(ω_o)`, evaluated in WGSL per vertex.

use crate::cubemap::CubeMap;
use crate::engine::{CancelToken, StageError};
use crate::transport::{Receivers, SphericalTransport};
use crate::wavelet::SparseVector;
use crate::wavelet::spherical::SphericalHaar;
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

mod brdf_table;
mod cell_light;
pub mod details;
mod frame_table;
pub mod packing;
pub mod relight;

pub use brdf_table::{
    BrdfTable, PHI_STEPS, SPECULAR_DROPPED_MASS, THETA_STEPS, grid_position, outgoing_direction, significant_cells,
    specular_row, tabulate_brdf,
};
use frame_table::table_products;
pub use frame_table::{FRAME_TABLE_THRESHOLD, FrameTable, table_products_packed};

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(
    BrdfTable,
    "local-frame BRDF table",
    |v| (v.diffuse.len() + v.specular.len() + v.node_energy.len()) * 4 + v.fine_specular.len() * 2,
    numbers = |v| {
        v.diffuse.iter().chain(&v.specular).map(|x| f64::from(*x)).chain(v.fine_specular.iter().map(|x| f64::from(*x)))
    }
);
crate::stage_type!(
    LocalProducts,
    "local-frame lighting × visibility",
    encoding = 1,
    |v| v.values.len() * 4,
    numbers = |v| v.values.iter().map(|x| f64::from(*x))
);
crate::stage_type!(
    LocalVisibility,
    "local-frame visibility cells",
    encoding = 1,
    |v| v.values.len() * 4,
    numbers = |v| v.values.iter().map(|x| f64::from(*x))
);
crate::stage_type!(
    TexelVisibility,
    "per-texel local-frame visibility",
    encoding = 1,
    |v| v.visibility.values.len() * 4 + v.receivers.len() * 36,
    numbers = |v| v.visibility.values.iter().map(|x| f64::from(*x))
);
crate::stage_type!(FrameTable, "pre-rotated lighting table", encoding = 1, |v| v.approx_bytes());
crate::stage_type!(
    relight::RelitReceivers,
    "relit receivers",
    encoding = 1,
    |v| v.approx_bytes(),
    numbers = |v| v.irradiance.iter().flatten().map(|x| f64::from(*x))
);

/// Sub-cell levels below a cell used to average functions over it (16 samples per cell).
const SUBLEVELS: usize = 2;

/// The level-`k` cells of the local-frame sphere with sub-samples for cell averages.
#[derive(Clone, Debug)]
pub struct CellGrid {
    pub level: usize,
    pub solid_angles: Vec<f64>,
    /// Per cell: sub-cell centroid directions (local frame) and their solid angles.
    pub samples: Vec<Vec<(DVec3, f64)>>,
}

impl CellGrid {
    /// The grid of `coefficients = 20·4^level` cells (20, 80, 320, 1280), built once per
    /// process.
    pub fn for_coefficients(coefficients: usize) -> Result<&'static Self, String> {
        static GRIDS: [std::sync::OnceLock<CellGrid>; 4] = [const { std::sync::OnceLock::new() }; 4];
        let level = match coefficients {
            20 => 0,
            80 => 1,
            320 => 2,
            1280 => 3,
            n => return Err(format!("{n} coefficients is not 20·4^k for k ≤ 3 (use 20, 80, 320 or 1280)")),
        };
        Ok(GRIDS[level].get_or_init(|| Self::build(level)))
    }

    fn build(level: usize) -> Self {
        let fine = SphericalHaar::new(level + SUBLEVELS);
        let areas = fine.cell_solid_angles();
        let per = 1 << (2 * SUBLEVELS);
        let cells = 20 << (2 * level);
        let samples: Vec<Vec<(DVec3, f64)>> = (0..cells)
            .map(|c| {
                (c * per..(c + 1) * per)
                    .map(|f| {
                        let [a, b, d] = fine.triangle(level + SUBLEVELS, f);
                        ((a + b + d).normalize(), areas[f])
                    })
                    .collect()
            })
            .collect();
        let solid_angles = samples.iter().map(|s| s.iter().map(|(_, w)| w).sum()).collect();
        Self { level, solid_angles, samples }
    }

    pub fn len(&self) -> usize {
        self.solid_angles.len()
    }

    pub fn is_empty(&self) -> bool {
        self.solid_angles.is_empty()
    }

    /// Solid-angle-weighted average of `f` over each cell.
    pub fn average(&self, f: impl Fn(DVec3) -> f64) -> Vec<f64> {
        self.samples
            .iter()
            .zip(&self.solid_angles)
            .map(|(s, area)| s.iter().map(|(d, w)| f(*d) * w).sum::<f64>() / area)
            .collect()
    }
}

/// Level-`level` cell values of a visibility vector truncated top-only (coefficients below
/// `20·4^level`), i.e. the box filter of `V` onto those cells.
pub fn visibility_cells(visibility: &SparseVector, level: usize) -> Vec<f64> {
    visibility_cells_in(&SphericalHaar::new(level), visibility)
}

/// Per receiver its top-only visibility box-filtered onto the grid's cells, `V_c ∈ [0, 1]`
/// (`receiver·cells + c`): the lighting-independent factor of `P_c = ΔΩ_c L_c V_c`. The
/// viewport multiplies the lighting in on the GPU, so a new or rotated environment rebuilds
/// none of it.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LocalVisibility {
    pub cells: usize,
    pub values: Vec<f32>,
}

impl LocalVisibility {
    pub fn receivers(&self) -> usize {
        self.values.len() / self.cells.max(1)
    }

    pub fn of(&self, receiver: usize) -> &[f32] {
        &self.values[receiver * self.cells..(receiver + 1) * self.cells]
    }
}

/// [`LocalVisibility`] of every receiver of `transport` on `grid`'s cells.
pub fn local_visibility(
    grid: &CellGrid,
    transport: &SphericalTransport,
    cancel: &CancelToken,
) -> Result<LocalVisibility, StageError> {
    if transport.depth < grid.level {
        return Err(StageError::Failed(format!(
            "local-frame visibility depth {} is coarser than {} cells need (depth {})",
            transport.depth,
            grid.len(),
            grid.level
        )));
    }
    let basis = SphericalHaar::new(grid.level);
    let chunks: Vec<Result<Vec<f32>, StageError>> = transport
        .visibility
        .par_chunks(256)
        .map(|chunk| {
            cancel.check()?;
            Ok(chunk
                .iter()
                .flat_map(|v| visibility_cells_in(&basis, v).into_iter().map(|v| v.clamp(0.0, 1.0) as f32))
                .collect())
        })
        .collect();
    let mut values = Vec::with_capacity(transport.visibility.len() * grid.len());
    for c in chunks {
        values.extend(c?);
    }
    Ok(LocalVisibility { cells: grid.len(), values })
}

/// [`visibility_cells`] on a basis built once by the caller.
fn visibility_cells_in(basis: &SphericalHaar, visibility: &SparseVector) -> Vec<f64> {
    let count = basis.len();
    let mut dense = vec![0.0; count];
    for &(k, v) in &visibility.entries {
        if (k as usize) < count {
            dense[k as usize] = v;
        }
    }
    basis.inverse(&dense)
}

/// The lighting the wavelet modes see: an unrotated environment, its rotation `R` (the
/// lit world sees `L(R⁻¹ d)`), and optionally its pre-rotated [`FrameTable`] (built once per
/// environment content, reused across rotations; for big meshes).
pub struct Lighting<'a> {
    pub environment: &'a CubeMap,
    pub rotation: DMat3,
    pub table: Option<&'a FrameTable>,
}

/// Per receiver `P_c = ΔΩ_c L^x_c V^x_c` (RGB interleaved, `(receiver·cells + c)·3 + channel`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LocalProducts {
    pub cells: usize,
    pub values: Vec<f32>,
}

/// Builds `P` for every receiver: lighting averaged over each cell rotated into the receiver's
/// frame, times the receiver's top-only visibility. The cell average takes 16 bilinear lookups
/// (sub-cell centroids) into the environment box-filtered to about the sub-cell size, so a
/// small bright source (a sun) contributes its energy to the cells it lies in instead of being
/// hit or missed by point samples.
pub fn local_products(
    grid: &CellGrid,
    lighting: &Lighting,
    receivers: &Receivers,
    visibility: &LocalVisibility,
    cancel: &CancelToken,
) -> Result<LocalProducts, StageError> {
    let none = details::DetailWeights::default();
    Ok(local_products_with_details(grid, lighting, receivers, visibility, &none, cancel)?.0)
}

/// [`local_products`] and each receiver's kept detail terms ([`details`]; none when
/// `weights.kept` is 0). With details the lighting is sampled directly, never read from a
/// [`FrameTable`], as the relight kernel does.
pub fn local_products_with_details(
    grid: &CellGrid,
    lighting: &Lighting,
    receivers: &Receivers,
    visibility: &LocalVisibility,
    weights: &details::DetailWeights,
    cancel: &CancelToken,
) -> Result<(LocalProducts, details::LocalDetails), StageError> {
    if visibility.cells != grid.len() || visibility.receivers() != receivers.len() {
        return Err(StageError::Failed(format!(
            "local-frame visibility has {} receivers of {} cells, the scene {} receivers of {} cells",
            visibility.receivers(),
            visibility.cells,
            receivers.len(),
            grid.len()
        )));
    }
    let kept = weights.kept;
    if kept > 0 && weights.squared.len() != details::node_count(grid.len()) {
        return Err(StageError::Failed(format!(
            "detail weights for {} nodes on a grid of {} cells",
            weights.squared.len(),
            grid.len()
        )));
    }
    // The rotated environment seen in frame M is the unrotated one in frame R⁻¹M.
    let inverse_rotation = lighting.rotation.transpose();
    let no_details = || details::LocalDetails { kept: 0, nodes: Vec::new(), values: Vec::new() };
    if let Some(table) = lighting.table.filter(|_| kept == 0) {
        return Ok((table_products(table, inverse_rotation, receivers, visibility, cancel)?, no_details()));
    }
    // With details, every cell is sampled and its samples scored.
    let sampler = &cell_light::CellSampler::new(grid, &prefiltered(lighting.environment, grid));
    type Samples = [[f32; 4]; cell_light::SAMPLES];
    /// A chunk's products, kept nodes and their details.
    type Chunk = (Vec<f32>, Vec<u32>, Vec<[f32; 9]>);
    // Per thread, the cells (and with details the samples) of each distinct frame in a chunk,
    // kept between chunks so they are not allocated and cleared again for every receiver.
    type Slots = Vec<(Vec<DVec3>, Vec<Samples>)>;
    let chunks: Vec<Result<Chunk, StageError>> = (0..receivers.len().div_ceil(256))
        .into_par_iter()
        .map_init(Slots::new, |slots, chunk| {
            cancel.check()?;
            let mut out = Vec::with_capacity(256 * grid.len() * 3);
            let (mut nodes, mut values) = (Vec::with_capacity(256 * kept), Vec::with_capacity(256 * kept));
            // Receivers with the same frame (every texel of a flat floor, the faces of a box)
            // share their lighting cells, each computed once, and only where some receiver
            // sees it (half the cells lie below every horizon). With details a cell keeps its
            // samples too.
            let mut cache: rustc_hash::FxHashMap<[u64; 9], (DMat3, usize)> = Default::default();
            for i in chunk * 256..((chunk + 1) * 256).min(receivers.len()) {
                let frame = receivers.frame(i);
                let next = cache.len();
                let (frame, slot) = cache.entry(frame.to_cols_array().map(f64::to_bits)).or_insert_with(|| {
                    let frame = inverse_rotation * frame;
                    if slots.len() <= next {
                        let samples =
                            if kept > 0 { vec![[[0.0; 4]; cell_light::SAMPLES]; grid.len()] } else { Vec::new() };
                        slots.push((vec![DVec3::NAN; grid.len()], samples));
                    }
                    // NaN cells are not lit yet (their samples are then stale too).
                    slots[next].0.fill(DVec3::NAN);
                    (frame, next)
                });
                let (cells, samples) = &mut slots[*slot];
                let mut best = details::Kept::new(kept);
                for (c, v) in visibility.of(i).iter().enumerate() {
                    let p = if *v > 0.0 {
                        if cells[c].x.is_nan() {
                            if kept > 0 {
                                samples[c] = sampler.samples(frame, c);
                                cells[c] = DVec3::from(cell_light::CellSampler::sum(&samples[c]).map(f64::from));
                            } else {
                                cells[c] = DVec3::from(sampler.cell(frame, c).map(f64::from));
                            }
                        }
                        if kept > 0 {
                            details::offer_cell(&mut best, weights, c, &samples[c], sampler.weights(c), *v);
                        }
                        cells[c] * f64::from(*v)
                    } else {
                        DVec3::ZERO
                    };
                    out.extend([p.x as f32, p.y as f32, p.z as f32]);
                }
                if kept > 0 {
                    for &node in best.nodes() {
                        nodes.push(node);
                        values.push(if node == details::NO_NODE {
                            [0.0; 9]
                        } else {
                            let c = details::cell_of(node, grid.len());
                            let v = visibility.of(i)[c];
                            details::details_of(node, grid.len(), c, &samples[c], sampler.weights(c), v)
                        });
                    }
                }
            }
            Ok((out, nodes, values))
        })
        .collect();
    let mut products = Vec::with_capacity(receivers.len() * grid.len() * 3);
    let mut kept_details = details::LocalDetails { kept, nodes: Vec::new(), values: Vec::new() };
    for c in chunks {
        let (p, n, v) = c?;
        products.extend(p);
        kept_details.nodes.extend(n);
        kept_details.values.extend(v);
    }
    Ok((LocalProducts { cells: grid.len(), values: products }, kept_details))
}

/// Per receiver the diffuse transfer `E = Σ_c P_c D_c` (RGB) with `D_c` the cell averages of
/// `cos⁺/π`: a diffuse surface's exit radiance is `albedo · E` (the CPU twin of the viewport's
/// relight kernel, `shaders/wavelet_relight.wgsl`).
pub fn diffuse_transfer(products: &LocalProducts, diffuse: &[f32]) -> Vec<[f32; 3]> {
    products
        .values
        .par_chunks_exact(products.cells * 3)
        .map(|p| {
            let mut e = [0.0f64; 3];
            for (c, d) in diffuse.iter().enumerate() {
                for k in 0..3 {
                    e[k] += f64::from(p[c * 3 + k]) * f64::from(*d);
                }
            }
            e.map(|v| v as f32)
        })
        .collect()
}

/// The environment box-filtered so its texels are about as large as the grid's sub-cells
/// (`4π/6N²` ≈ the sub-cell solid angle), on a power-of-two divisor of its size: what the
/// cell averages sample, so a small bright source (a sun) gives its energy to the cells it
/// lies in instead of being hit or missed by point samples. Filtering its own output again
/// changes nothing.
pub fn prefiltered(environment: &CubeMap, grid: &CellGrid) -> CubeMap {
    let sub_cell = 4.0 * PI / (grid.len() * (1 << (2 * SUBLEVELS))) as f64;
    let wanted = (4.0 * PI / (6.0 * sub_cell)).sqrt();
    let mut size = environment.size;
    while size.is_multiple_of(2) && (size / 2) as f64 >= wanted {
        size /= 2;
    }
    environment.box_downsampled(size)
}

/// The visibility textures' texels as receivers of Ma et al.'s per-pixel triple product
/// (§3.4): every texel slot of `layers × size²` (layer-major, rows at increasing `v`) with its
/// frame and visibility cells. The viewport lights them as it lights vertices and filters
/// the diffuse transfer `E` and the products `P` bilinearly per pixel.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TexelVisibility {
    pub size: usize,
    /// One per slot (only the frames are read).
    pub receivers: Receivers,
    pub visibility: LocalVisibility,
    /// Per mesh of the scene: its layer, or -1 without a visibility texture.
    pub mesh_layers: Vec<i32>,
}

impl TexelVisibility {
    pub fn slots(&self) -> usize {
        self.receivers.len()
    }
}

/// Builds [`TexelVisibility`] from texel receivers and their local-frame transport. Slots no
/// triangle covers take their covered 8-neighbours' mean visibility and the first such
/// neighbour's frame, four rings out, so bilinear filtering at UV seams does not darken;
/// slots further out see nothing.
pub fn texel_visibility(
    grid: &CellGrid,
    texels: &crate::transport::TexelReceivers,
    transport: &SphericalTransport,
    mesh_count: usize,
    cancel: &CancelToken,
) -> Result<TexelVisibility, StageError> {
    let visibility = local_visibility(grid, transport, cancel)?;
    if visibility.receivers() != texels.receivers.len() {
        return Err(StageError::Failed(format!(
            "texel transport has {} receivers, the visibility textures {}",
            visibility.receivers(),
            texels.receivers.len()
        )));
    }
    let mut mesh_layers = vec![-1i32; mesh_count];
    let mut layers = 0usize;
    for &(mesh, ..) in &texels.texels {
        let layer = mesh_layers.get_mut(mesh as usize).ok_or_else(|| {
            StageError::Failed(format!("a texel belongs to mesh {mesh} of a scene with {mesh_count} meshes"))
        })?;
        if *layer < 0 {
            *layer = layers as i32;
            layers += 1;
        }
    }
    let (size, cells) = (texels.size, grid.len());
    let slots = layers * size * size;
    let mut slot_visibility = vec![0.0f32; slots * cells];
    let mut frames = vec![([0.0f32; 3], [0.0f32, 0.0, 1.0], [1.0f32, 0.0, 0.0]); slots];
    let mut covered = vec![false; slots];
    for (i, &(mesh, x, y)) in texels.texels.iter().enumerate() {
        let at = (mesh_layers[mesh as usize] as usize * size + y as usize) * size + x as usize;
        slot_visibility[at * cells..(at + 1) * cells].copy_from_slice(visibility.of(i));
        let r = &texels.receivers;
        frames[at] = (r.positions[i], r.normals[i], r.tangents[i]);
        covered[at] = true;
    }
    dilate(&mut slot_visibility, &mut frames, cells, &mut covered, size);
    let receivers = Receivers {
        positions: frames.iter().map(|f| f.0).collect(),
        normals: frames.iter().map(|f| f.1).collect(),
        tangents: frames.iter().map(|f| f.2).collect(),
        mesh_offsets: vec![0],
    };
    Ok(TexelVisibility { size, receivers, visibility: LocalVisibility { cells, values: slot_visibility }, mesh_layers })
}

/// Fills uncovered slots (visibility vectors of `stride` floats, and frames) from covered
/// 8-neighbours, a few rings out.
fn dilate<F: Copy>(visibility: &mut [f32], frames: &mut [F], stride: usize, covered: &mut [bool], size: usize) {
    let mut sum = vec![0.0f32; stride];
    for _ in 0..4 {
        let snapshot: Vec<bool> = covered.to_vec();
        for i in 0..frames.len() {
            if snapshot[i] {
                continue;
            }
            let (layer, y, x) = (i / (size * size), (i / size) % size, i % size);
            sum.fill(0.0);
            let (mut n, mut first) = (0, None);
            for (dx, dy) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1), (-1, -1), (1, 1), (-1, 1), (1, -1)] {
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                if nx < 0 || ny < 0 || nx >= size as i64 || ny >= size as i64 {
                    continue;
                }
                let j = (layer * size + ny as usize) * size + nx as usize;
                if snapshot[j] {
                    for (s, v) in sum.iter_mut().zip(&visibility[j * stride..(j + 1) * stride]) {
                        *s += v;
                    }
                    n += 1;
                    first.get_or_insert(j);
                }
            }
            if let Some(j) = first {
                for (v, s) in visibility[i * stride..(i + 1) * stride].iter_mut().zip(&sum) {
                    *v = s / n as f32;
                }
                frames[i] = frames[j];
                covered[i] = true;
            }
        }
    }
}

/// Exit radiance of receiver `i` towards world direction `to_eye` (CPU twin of the shader).
pub fn shade(products: &LocalProducts, table: &BrdfTable, i: usize, frame: DMat3, to_eye: DVec3) -> DVec3 {
    let p = &products.values[i * products.cells * 3..(i + 1) * products.cells * 3];
    let cell = |c: usize| DVec3::new(p[c * 3] as f64, p[c * 3 + 1] as f64, p[c * 3 + 2] as f64);
    let mut diffuse = DVec3::ZERO;
    for c in 0..products.cells {
        diffuse += cell(c) * table.diffuse[c] as f64;
    }
    let mut out = diffuse * DVec3::from(table.albedo.map(f64::from));
    let wo = frame.transpose() * to_eye;
    if !table.specular.is_empty() && wo.z > 0.0 {
        let s = specular_row(table, wo);
        let mut spec = DVec3::ZERO;
        for (c, s) in s.iter().enumerate() {
            spec += cell(c) * *s;
        }
        out += spec * DVec3::from(table.specular_color.map(f64::from));
    }
    out
}

/// [`shade`] plus receiver `i`'s kept detail terms (CPU twin of the mesh shader).
pub fn shade_with_details(
    products: &LocalProducts,
    kept: &details::LocalDetails,
    table: &BrdfTable,
    i: usize,
    frame: DMat3,
    to_eye: DVec3,
) -> DVec3 {
    let mut out = shade(products, table, i, frame, to_eye);
    let wo = frame.transpose() * to_eye;
    if !table.fine_specular.is_empty() && wo.z > 0.0 {
        let slots = i * kept.kept..(i + 1) * kept.kept;
        let glossy: DVec3 = kept.nodes[slots.clone()]
            .iter()
            .zip(&kept.values[slots])
            .take_while(|(node, _)| **node != details::NO_NODE)
            .map(|(node, d)| details::detail_glossy(table, *node, d, wo))
            .sum();
        out += glossy * DVec3::from(table.specular_color.map(f64::from));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::Brdf;
    use crate::brdf::Material;
    use crate::quadrature::SphereQuadrature;

    #[test]
    fn cell_grid_covers_the_sphere() {
        for n in [20, 80, 320] {
            let grid = CellGrid::for_coefficients(n).unwrap();
            assert_eq!(grid.len(), n);
            let total: f64 = grid.solid_angles.iter().sum();
            assert!((total - 4.0 * PI).abs() < 1e-9, "{n}: {total}");
        }
        assert!(CellGrid::for_coefficients(100).is_err());
    }

    #[test]
    fn top_only_visibility_is_the_box_filter_of_the_finest_cells() {
        let fine = SphericalHaar::new(3);
        let cells: Vec<f64> = (0..fine.len()).map(|c| ((c * 7919) % 13) as f64 / 12.0).collect();
        let all = SparseVector::from_dense(&fine.forward(&cells));
        let coarse = visibility_cells(&all, 2);
        for (c, v) in coarse.iter().enumerate() {
            let mean = cells[4 * c..4 * c + 4].iter().sum::<f64>() / 4.0;
            assert!((v - mean).abs() < 1e-12);
        }
    }

    #[test]
    fn cell_sum_matches_the_triple_integral_for_smooth_functions() {
        // B = ∫ L V ρ̃ dω for smooth L, V, ρ̃ converges as cells shrink: compare the cell sum
        // with quadrature, and check the error falls from 80 to 320 cells.
        let l = |d: DVec3| 1.0 + 0.8 * d.x + 0.5 * d.z * d.z;
        let v = |d: DVec3| if d.z > 0.0 { 0.5 + 0.5 * (3.0 * d.y).sin().abs() } else { 0.0 };
        let brdf = Brdf::from_material(&Material {
            model: crate::brdf::Model::Phong,
            exponent: 4.0,
            f0: 1.0,
            albedo: [0.0; 3],
            ..Default::default()
        });
        let wo = DVec3::new(0.3, 0.1, 0.95).normalize();
        let rho = |d: DVec3| brdf.lobe_value(d, wo) * d.z.max(0.0);
        let exact = SphereQuadrature::new(800, 1600).integrate(|d| l(d) * v(d) * rho(d));
        let errors: Vec<f64> = [80, 320]
            .iter()
            .map(|&n| {
                let grid = CellGrid::for_coefficients(n).unwrap();
                let (lc, vc, rc) = (grid.average(l), grid.average(v), grid.average(rho));
                let sum: f64 = (0..n).map(|c| grid.solid_angles[c] * lc[c] * vc[c] * rc[c]).sum();
                (sum - exact).abs() / exact
            })
            .collect();
        assert!(errors[1] < errors[0], "{errors:?}");
        assert!(errors[1] < 0.03, "{errors:?}");
    }

    #[test]
    fn a_coarsened_table_equals_tabulating_on_the_coarse_grid() {
        // Merging keeps each row's integral Σ ΔΩ_c S_c exactly, and agrees with tabulating at
        // 80 cells directly up to the sub-cell quadrature (16 samples per cell there, 64 here).
        let brdf = Brdf::from_material(&Material {
            model: crate::brdf::Model::Phong,
            exponent: 3.0,
            f0: 1.0,
            ..Default::default()
        });
        let cancel = CancelToken::default();
        let fine = tabulate_brdf(&brdf, CellGrid::for_coefficients(320).unwrap(), &cancel).unwrap();
        let coarse = tabulate_brdf(&brdf, CellGrid::for_coefficients(80).unwrap(), &cancel).unwrap();
        let merged = fine.coarsened(80).unwrap();
        let (g80, g320) = (CellGrid::for_coefficients(80).unwrap(), CellGrid::for_coefficients(320).unwrap());
        let integral =
            |row: &[f32], g: &CellGrid| row.iter().zip(&g.solid_angles).map(|(v, a)| *v as f64 * a).sum::<f64>();
        for (m, f) in merged.specular.chunks(80).zip(fine.specular.chunks(320)) {
            assert!((integral(m, g80) - integral(f, g320)).abs() < 1e-5 * integral(f, g320).max(1e-3));
        }
        for (a, b) in merged.specular.iter().zip(&coarse.specular).chain(merged.diffuse.iter().zip(&coarse.diffuse)) {
            assert!((a - b).abs() < 0.08 * b.abs().max(0.05), "{a} vs {b}");
        }
        // The coarse grid's two finer levels are the fine grid's cells and their children, row
        // by row, and agree with tabulating at 80 cells directly (whose finest level samples
        // where the fine grid averages four samples).
        assert_eq!(merged.fine_specular.len(), coarse.fine_specular.len());
        for (row, (m, f)) in merged.fine_specular.chunks(20 * 80).zip(fine.fine_specular.chunks(20 * 320)).enumerate() {
            let cells = &fine.specular[row * 320..(row + 1) * 320];
            for (a, b) in m[..320].iter().zip(cells) {
                assert!((f32::from(*a) - b).abs() <= 1e-3 * b.abs() + 1e-6, "row {row}: {a} against the cell {b}");
            }
            assert_eq!(&m[320..], &f[..1280], "row {row}: the children");
        }
        let (mut worst, mut scale) = (0.0f32, 0.0f32);
        for (a, b) in merged.fine_specular.iter().zip(coarse.fine_specular.iter()) {
            worst = worst.max((f32::from(*a) - f32::from(*b)).abs());
            scale = scale.max(f32::from(*b).abs());
        }
        assert!(worst < 0.15 * scale, "the fine levels: {worst} off, largest {scale}");
        assert!(fine.coarsened(100).is_err());
    }

    #[test]
    fn lambert_under_constant_light_without_occluders_is_the_furnace() {
        // Constant L, no occluders, white Lambert: B = L, because Σ ΔΩ_c D_c = ∫ cos⁺/π = 1
        // whatever the cells (up to the 16-point sub-cell quadrature of the cosine).
        let grid = CellGrid::for_coefficients(80).unwrap();
        let table = tabulate_brdf(
            &Brdf::from_material(&Material { albedo: [1.0; 3], ..Default::default() }),
            grid,
            &CancelToken::default(),
        )
        .unwrap();
        let b: f64 = (0..grid.len()).map(|c| grid.solid_angles[c] * 2.0 * table.diffuse[c] as f64).sum();
        assert!((b - 2.0).abs() < 2.0 * 2e-3, "{b}");
    }

    /// The shader's glossy sum over a patch's significant cells against the sum over all
    /// cells (`specular_row`), for lobes from sharp to rough under lighting that varies by a
    /// factor of three across the cells: within the dropped mass's share, and reading few cells
    /// for a sharp lobe.
    #[test]
    fn glossy_sums_over_the_significant_cells_equal_the_full_sums() {
        let grid = CellGrid::for_coefficients(320).unwrap();
        let mut state = 11u64;
        let mut uniform = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let light: Vec<f64> = (0..grid.len()).map(|c| grid.solid_angles[c] * (1.0 + 2.0 * uniform())).collect();
        for (model, exponent, roughness, most_cells) in
            [("phong", 200.0, 0.5, 40.0), ("phong", 20.0, 0.5, 80.0), ("ggx", 1.0, 0.4, 200.0)]
        {
            let material =
                Material { model: model.parse().unwrap(), exponent, roughness, f0: 0.5, ..Default::default() };
            let table = tabulate_brdf(&Brdf::from_material(&material), grid, &CancelToken::default()).unwrap();
            let (ranges, list) = significant_cells(&table.specular, grid);
            let mean = ranges.iter().map(|r| r[1] as f64).sum::<f64>() / ranges.len() as f64;
            assert!(mean <= most_cells, "{model} {exponent}: {mean:.0} cells a patch");
            for _ in 0..200 {
                let (theta, phi) = (uniform() * 1.5, uniform() * 2.0 * PI);
                let wo = DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
                let row = specular_row(&table, wo);
                let (i, j, ..) = grid_position(wo);
                let [first, count] = ranges[i * PHI_STEPS + j];
                let full: f64 = row.iter().zip(&light).map(|(s, l)| s * l).sum();
                let sparse: f64 = list[first as usize..(first + count) as usize]
                    .iter()
                    .map(|&c| row[c as usize] * light[c as usize])
                    .sum();
                assert!(
                    (full - sparse).abs() <= 3.0 * SPECULAR_DROPPED_MASS * full + 1e-9,
                    "{model} {exponent} at θ {theta:.2} φ {phi:.2}: {sparse} of {full}"
                );
            }
            eprintln!("{model} {exponent}/{roughness}: {mean:.1} of 320 cells a patch");
        }
    }
}
