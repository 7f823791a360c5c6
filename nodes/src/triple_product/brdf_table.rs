//! Materials tabulated in the receivers' local frame for the triple product (Ma et al. eq.
//! 7): per cell the diffuse `D_c` and, on a grid of outgoing directions, the glossy lobe times
//! `cos θ`, `S_c(ω_o)`, with its two finer levels for the detail terms; the cells a lobe's
//! sum must read; the grid's interpolation (the CPU twin of the mesh shader's).

use super::{CellGrid, details};
use crate::brdf::Brdf;
use crate::engine::{CancelToken, StageError};
use glam::DVec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// A fine lobe table's entry, clamped to half's range.
fn to_half(v: f32) -> half::f16 {
    half::f16::from_f32(v.clamp(-65504.0, 65504.0))
}

/// Outgoing-direction grid of the BRDF table: `θ_o` in `THETA_STEPS` steps over `[0, π/2]`
/// (sample points at both ends), `φ_o` in `PHI_STEPS` steps over `[0, 2π)` (periodic).
pub const THETA_STEPS: usize = 31;
pub const PHI_STEPS: usize = 64;

/// Direction of grid node `(i, j)` in the local frame.
pub fn outgoing_direction(i: usize, j: usize) -> DVec3 {
    let theta = (i as f64 / (THETA_STEPS - 1) as f64) * (PI / 2.0 - 1e-3);
    let phi = j as f64 / PHI_STEPS as f64 * 2.0 * PI;
    DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
}

/// A material tabulated in the local frame for the triple product.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BrdfTable {
    pub cells: usize,
    /// `D_c`: cell average of `max(cos θ, 0)/π`.
    pub diffuse: Vec<f32>,
    /// `S_c(ω_o)`: cell average of `lobe(ω, ω_o)·max(cos θ, 0)`, `(i·PHI_STEPS + j)·cells + c`.
    pub specular: Vec<f32>,
    /// Per row of `specular`, the lobe on the two levels below the cells that the detail
    /// terms read ([`details`]): `4·cells` averages over the cells' children, then its value at
    /// each of the `16·cells` sub-cell samples (in a coarsened table, the finer grid's averages
    /// over four samples). Entry `4n + k` is detail node `n`'s child `k`.
    /// Half floats (clamped to their range: a lobe sharp enough to exceed it is far sharper
    /// than the samples resolve). Empty without a lobe.
    pub fine_specular: std::sync::Arc<Vec<half::f16>>,
    /// Per detail node, the lobe's largest detail energy over the rows
    /// ([`details::lobe_detail_energy`]). Empty without a lobe.
    pub node_energy: Vec<f32>,
    pub albedo: [f32; 3],
    pub specular_color: [f32; 3],
    /// Fraction of the lobe's directional albedo at normal incidence the cell table keeps
    /// (1 when the cells resolve it; a sharp lobe on coarse cells still integrates right, but
    /// its shape is blurred to the cell size).
    pub lobe_albedo: f64,
}

impl BrdfTable {
    /// The table on the coarser top-only grid of `cells` (merging children by solid angle:
    /// a parent's average is the area-weighted mean of its children's).
    pub fn coarsened(&self, cells: usize) -> Result<BrdfTable, String> {
        if cells == self.cells {
            return Ok(self.clone());
        }
        if cells * 4 != self.cells {
            return Err(format!("cannot merge a {}-cell table into {cells} cells", self.cells));
        }
        let fine = CellGrid::for_coefficients(self.cells)?;
        // The coarse grid's two finer levels are this grid's cells and their children.
        let fine_specular: Vec<half::f16> = self
            .specular
            .chunks(self.cells)
            .zip(self.fine_specular.chunks(20 * self.cells))
            .flat_map(|(cells, fine)| cells.iter().map(|v| to_half(*v)).chain(fine[..4 * self.cells].iter().copied()))
            .collect();
        let merge = |values: &[f32]| -> Vec<f32> {
            values
                .chunks(self.cells)
                .flat_map(|row| {
                    (0..cells).map(|c| {
                        let kids = 4 * c..4 * c + 4;
                        let area: f64 = fine.solid_angles[kids.clone()].iter().sum();
                        (kids.map(|k| row[k] as f64 * fine.solid_angles[k]).sum::<f64>() / area) as f32
                    })
                })
                .collect()
        };
        let coarse = CellGrid::for_coefficients(cells)?;
        Ok(BrdfTable {
            cells,
            diffuse: merge(&self.diffuse),
            specular: merge(&self.specular),
            node_energy: details::lobe_detail_energy(coarse, &fine_specular),
            fine_specular: std::sync::Arc::new(fine_specular),
            albedo: self.albedo,
            specular_color: self.specular_color,
            lobe_albedo: self.lobe_albedo,
        })
    }
}

pub fn tabulate_brdf(brdf: &Brdf, grid: &CellGrid, cancel: &CancelToken) -> Result<BrdfTable, StageError> {
    let diffuse = grid.average(|d| d.z.max(0.0) / PI).into_iter().map(|v| v as f32).collect();
    let (specular, fine_specular) = if brdf.specular == DVec3::ZERO {
        (Vec::new(), Vec::new())
    } else {
        let samples: Vec<(DVec3, f64)> = grid.samples.iter().flatten().copied().collect();
        // Per row: the cells' averages and the fine entries.
        type Row = (Vec<f32>, Vec<half::f16>);
        let rows: Vec<Result<Row, StageError>> = (0..THETA_STEPS * PHI_STEPS)
            .into_par_iter()
            .map(|k| {
                cancel.check()?;
                let wo = outgoing_direction(k / PHI_STEPS, k % PHI_STEPS);
                let at: Vec<f64> = samples.iter().map(|(wi, _)| brdf.lobe_value(*wi, wo) * wi.z.max(0.0)).collect();
                // Solid-angle-weighted means over runs of `n` samples: cells (16), children (4).
                let means = |n: usize| {
                    at.chunks(n).zip(samples.chunks(n)).map(|(v, s)| {
                        let area: f64 = s.iter().map(|(_, w)| w).sum();
                        (v.iter().zip(s).map(|(v, (_, w))| v * w).sum::<f64>() / area) as f32
                    })
                };
                let cells = means(at.len() / grid.len()).collect();
                let fine =
                    means(at.len() / (4 * grid.len())).chain(at.iter().map(|v| *v as f32)).map(to_half).collect();
                Ok((cells, fine))
            })
            .collect();
        let mut out = Vec::with_capacity(THETA_STEPS * PHI_STEPS * grid.len());
        let mut fine = Vec::with_capacity(THETA_STEPS * PHI_STEPS * grid.len() * 20);
        for r in rows {
            let (cells, children) = r?;
            out.extend(cells);
            fine.extend(children);
        }
        (out, fine)
    };
    let lobe_albedo = if specular.is_empty() {
        1.0
    } else {
        specular[..grid.len()].iter().zip(&grid.solid_angles).map(|(s, a)| *s as f64 * a).sum()
    };
    Ok(BrdfTable {
        cells: grid.len(),
        diffuse,
        specular,
        node_energy: details::lobe_detail_energy(grid, &fine_specular),
        fine_specular: std::sync::Arc::new(fine_specular),
        albedo: brdf.diffuse.as_vec3().to_array(),
        specular_color: brdf.specular.as_vec3().to_array(),
        lobe_albedo,
    })
}

/// Share of each patch's specular mass [`significant_cells`] may leave out.
pub const SPECULAR_DROPPED_MASS: f64 = 1e-3;

/// The cells that carry a glossy lobe, per patch of the outgoing grid: for the patch between
/// rows `(i, j)` and `(i + 1, j + 1)` (`i·PHI_STEPS + j`), the fewest cells whose mass
/// `max over the patch's four rows of S_c ΔΩ_c` reaches all but [`SPECULAR_DROPPED_MASS`] of
/// the patch's total, in increasing order. A sharp lobe's sum `Σ P_c S_c(ω_o)` then reads a
/// few dozen of the 320 cells (Ma et al. keep the BRDF's largest coefficients the same way);
/// the terms dropped are under that share of the sum for lighting no brighter than the kept
/// cells'. Returns `[first, count]` per patch into the concatenated list.
pub fn significant_cells(specular: &[f32], grid: &CellGrid) -> (Vec<[u32; 2]>, Vec<u32>) {
    let cells = grid.len();
    let mut ranges = Vec::with_capacity((THETA_STEPS - 1) * PHI_STEPS);
    let mut list = Vec::new();
    let mut mass: Vec<(f64, u32)> = Vec::with_capacity(cells);
    for i in 0..THETA_STEPS - 1 {
        for j in 0..PHI_STEPS {
            let rows = [(i, j), (i, (j + 1) % PHI_STEPS), (i + 1, j), (i + 1, (j + 1) % PHI_STEPS)];
            mass.clear();
            for c in 0..cells {
                let s = rows.iter().map(|(a, b)| specular[(a * PHI_STEPS + b) * cells + c]).fold(0.0f32, f32::max);
                mass.push((f64::from(s) * grid.solid_angles[c], c as u32));
            }
            let total: f64 = mass.iter().map(|m| m.0).sum();
            mass.sort_by(|a, b| b.0.total_cmp(&a.0));
            let first = list.len();
            let mut kept = 0.0;
            for &(m, c) in &mass {
                if kept >= total * (1.0 - SPECULAR_DROPPED_MASS) || m <= 0.0 {
                    break;
                }
                kept += m;
                list.push(c);
            }
            list[first..].sort_unstable();
            ranges.push([first as u32, (list.len() - first) as u32]);
        }
    }
    (ranges, list)
}

/// `S(ω_o)` bilinearly interpolated on the grid (CPU twin of the shader).
pub fn specular_row(table: &BrdfTable, wo: DVec3) -> Vec<f64> {
    let (i, j, fi, fj) = grid_position(wo);
    let row = |i: usize, j: usize| &table.specular[(i * PHI_STEPS + j % PHI_STEPS) * table.cells..][..table.cells];
    let (a, b, c, d) = (row(i, j), row(i, j + 1), row(i + 1, j), row(i + 1, j + 1));
    (0..table.cells)
        .map(|k| {
            let top = a[k] as f64 * (1.0 - fj) + b[k] as f64 * fj;
            let bottom = c[k] as f64 * (1.0 - fj) + d[k] as f64 * fj;
            top * (1.0 - fi) + bottom * fi
        })
        .collect()
}

/// Grid cell `(i, j)` below `ω_o` and the fractions towards `(i+1, j+1)`.
pub fn grid_position(wo: DVec3) -> (usize, usize, f64, f64) {
    let theta = wo.z.clamp(0.0, 1.0).acos().min(PI / 2.0 - 1e-3);
    let t = theta / (PI / 2.0 - 1e-3) * (THETA_STEPS - 1) as f64;
    let i = (t.floor() as usize).min(THETA_STEPS - 2);
    let phi = wo.y.atan2(wo.x).rem_euclid(2.0 * PI);
    let p = phi / (2.0 * PI) * PHI_STEPS as f64;
    let j = (p.floor() as usize).min(PHI_STEPS - 1);
    (i, j, t - i as f64, p - j as f64)
}
