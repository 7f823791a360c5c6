//! The relight of the wavelet modes on the CPU (Ma et al. eq. 7 in top-only cell form): each
//! receiver's products `P_c = ΔΩ_c L_c V_c`, its diffuse transfer `E = Σ_c P_c D_c` and its
//! kept detail terms, packed as the GPU kernel (`shaders/wavelet_relight.wgsl`) writes them, so
//! a viewport on a CPU adapter uploads them instead of running the kernel.

use super::details::{DetailWeights, LocalDetails};
use super::{
    BrdfTable, CellGrid, FRAME_TABLE_THRESHOLD, FrameTable, Lighting, LocalProducts, LocalVisibility, diffuse_transfer,
    local_products_with_details, packing, table_products_packed,
};
use crate::cubemap::CubeMap;
use crate::engine::{CancelToken, StageError};
use crate::transport::Receivers;
use glam::DMat3;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// One receiver set relit, as the relight kernel writes its buffers (shared: a copy costs
/// nothing).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RelitReceivers {
    /// `P_c` per receiver and cell, RGB9E5 ([`packing::rgb9e5`]).
    pub products: Arc<Vec<u32>>,
    /// `E = Σ_c P_c D_c` per receiver, `[r, g, b, 0]`.
    pub irradiance: Arc<Vec<[f32; 4]>>,
    /// The kept detail terms, five words per receiver and slot ([`packing::detail_words`]);
    /// empty when none are kept.
    pub details: Arc<Vec<u32>>,
}

impl RelitReceivers {
    pub fn approx_bytes(&self) -> usize {
        (self.products.len() + self.details.len()) * 4 + self.irradiance.len() * 16
    }
}

/// What a relight reads besides the receivers: the cells, the environment prefiltered for them
/// and its rotation `R`, the diffuse table `D_c` and the detail weights.
pub struct Relight<'a> {
    pub grid: &'a CellGrid,
    pub environment: &'a CubeMap,
    pub rotation: DMat3,
    pub diffuse_table: &'a [f32],
    pub details: &'a DetailWeights,
}

impl Relight<'_> {
    /// Whether `receivers` many read their lighting from a [`FrameTable`] (big sets, and only
    /// where no detail terms are kept: those sample the lighting directly).
    pub fn uses_frame_table(&self, receivers: usize) -> bool {
        receivers > FRAME_TABLE_THRESHOLD && self.details.kept == 0
    }

    /// A hash of everything [`Self::packed`] of `receivers` and `visibility` reads, by value:
    /// equal for equal results, whatever edit upstream led here (an albedo edit relights
    /// nothing).
    pub fn content_key(&self, receivers: &Receivers, visibility: &LocalVisibility) -> u128 {
        let mut hasher = xxhash_rust::xxh3::Xxh3::new();
        let mut add = |bytes: &[u8]| {
            hasher.update(&(bytes.len() as u64).to_le_bytes());
            hasher.update(bytes);
        };
        add(&(self.grid.len() as u64).to_le_bytes());
        add(bytemuck::cast_slice(&self.environment.texels));
        add(bytemuck::cast_slice(&self.rotation.to_cols_array()));
        add(bytemuck::cast_slice(self.diffuse_table));
        add(&(self.details.kept as u64).to_le_bytes());
        add(bytemuck::cast_slice(&self.details.squared));
        add(bytemuck::cast_slice(&receivers.normals));
        add(bytemuck::cast_slice(&receivers.tangents));
        add(&(visibility.cells as u64).to_le_bytes());
        add(bytemuck::cast_slice(&visibility.values));
        hasher.digest128()
    }

    /// `P` and the kept detail terms of one receiver set, unpacked, with the lighting from
    /// `table` when given.
    pub fn products(
        &self,
        receivers: &Receivers,
        visibility: &LocalVisibility,
        table: Option<&FrameTable>,
        cancel: &CancelToken,
    ) -> Result<(LocalProducts, LocalDetails), StageError> {
        let lighting = Lighting { environment: self.environment, rotation: self.rotation, table };
        local_products_with_details(self.grid, &lighting, receivers, visibility, self.details, cancel)
    }

    /// One receiver set relit and packed. A set read from `table` goes from the table to the
    /// packed words in one pass.
    pub fn packed(
        &self,
        receivers: &Receivers,
        visibility: &LocalVisibility,
        table: Option<&FrameTable>,
        cancel: &CancelToken,
    ) -> Result<RelitReceivers, StageError> {
        if let Some(table) = table.filter(|_| self.details.kept == 0) {
            let (products, irradiance) = table_products_packed(
                table,
                self.rotation,
                receivers,
                visibility,
                self.diffuse_table,
                packing::rgb9e5,
                cancel,
            )?;
            return Ok(RelitReceivers {
                products: Arc::new(products),
                irradiance: Arc::new(irradiance),
                details: Arc::default(),
            });
        }
        let (products, details) = self.products(receivers, visibility, None, cancel)?;
        let irradiance =
            diffuse_transfer(&products, self.diffuse_table).into_iter().map(|e| [e[0], e[1], e[2], 0.0]).collect();
        let details =
            if details.kept > 0 { packing::detail_words(&details.nodes, &details.values) } else { Vec::new() };
        Ok(RelitReceivers {
            products: Arc::new(packing::rgb9e5_all(&products.values)),
            irradiance: Arc::new(irradiance),
            details: Arc::new(details),
        })
    }
}

/// The detail weights of the materials' tables coarsened to the cells (`tables`), each
/// weighed by the largest channel of its specular colour times `attenuation` (what reaches
/// surfaces through fog), keeping up to `kept` terms per receiver.
pub fn material_detail_weights(
    grid: &CellGrid,
    tables: &[BrdfTable],
    attenuation: [f64; 3],
    kept: usize,
) -> DetailWeights {
    let weighted: Vec<(&BrdfTable, f64)> = tables
        .iter()
        .map(|t| {
            let weight = if t.specular.is_empty() {
                0.0
            } else {
                let c: [f64; 3] = std::array::from_fn(|i| f64::from(t.specular_color[i]) * attenuation[i]);
                c[0].max(c[1]).max(c[2])
            };
            (t, weight)
        })
        .collect();
    DetailWeights::new(grid, &weighted, kept)
}
