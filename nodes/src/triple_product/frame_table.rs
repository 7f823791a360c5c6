//! Ma et al.'s pre-rotated lighting for the CPU relight of big meshes: the lighting cells of
//! frames on a grid of Euler angles, built once per environment, and each receiver's products
//! blended from the table's rows around its frame.

use super::{CellGrid, LocalProducts, LocalVisibility};
use crate::cubemap::CubeMap;
use crate::engine::{CancelToken, StageError};
use crate::transport::Receivers;
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Receivers above which lighting comes from a [`FrameTable`] (whose build costs about as
/// much as this many direct frames; it measured 0.8–1.1 points of relative RMSE worse than
/// direct on the default project at 320 coefficients, no different on the glossy scene).
pub const FRAME_TABLE_THRESHOLD: usize = 2 * FRAME_ALPHA * FRAME_BETA * FRAME_GAMMA;
const FRAME_ALPHA: usize = 32;
const FRAME_BETA: usize = 17;
const FRAME_GAMMA: usize = 32;

/// Lighting cell integrals `ΔΩ_c L_c` for frames `R = Rz(α) Ry(β) Rz(γ)` on a grid of
/// 32 × 17 × 32 Euler angles (11.25° steps; `n = R ẑ`, `γ` turns the tangent about `n`), read
/// back by trilinear interpolation: Ma et al.'s pre-rotated lighting (their 32×16 normals ×
/// 32 tangent angles). Interpolating between rotated copies blurs a sharp light by up to half
/// a step, about the size of a 320-cell cell.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameTable {
    cells: usize,
    /// RGB per cell, `cells` per frame.
    values: Vec<f32>,
}

impl FrameTable {
    pub fn approx_bytes(&self) -> usize {
        self.values.len() * 4
    }

    /// The table for an (unrotated) environment, prefiltered for the grid.
    pub fn build(grid: &CellGrid, environment: &CubeMap) -> Self {
        let sampler = &super::cell_light::CellSampler::new(grid, &super::prefiltered(environment, grid));
        let frames = FRAME_ALPHA * FRAME_BETA * FRAME_GAMMA;
        let values = (0..frames)
            .into_par_iter()
            .flat_map_iter(|f| {
                let (a, b, g) = (f / (FRAME_BETA * FRAME_GAMMA), (f / FRAME_GAMMA) % FRAME_BETA, f % FRAME_GAMMA);
                let frame = Self::frame(a as f64, b as f64, g as f64);
                (0..grid.len()).flat_map(|c| sampler.cell(&frame, c)).collect::<Vec<_>>()
            })
            .collect();
        Self { cells: grid.len(), values }
    }

    /// The rotation at (fractional) grid coordinates.
    fn frame(a: f64, b: f64, g: f64) -> DMat3 {
        let alpha = a / FRAME_ALPHA as f64 * 2.0 * PI;
        let beta = b / (FRAME_BETA - 1) as f64 * PI;
        let gamma = g / FRAME_GAMMA as f64 * 2.0 * PI;
        DMat3::from_rotation_z(alpha) * DMat3::from_rotation_y(beta) * DMat3::from_rotation_z(gamma)
    }

    /// ZYZ Euler angles of a rotation (columns `t, b, n`), in grid units.
    fn grid_coordinates(frame: DMat3) -> (f64, f64, f64) {
        let (t, b, n) = (frame.x_axis, frame.y_axis, frame.z_axis);
        let beta = n.z.clamp(-1.0, 1.0).acos();
        let (alpha, gamma) = if beta.sin() > 1e-9 {
            (n.y.atan2(n.x), b.z.atan2(-t.z))
        } else if n.z > 0.0 {
            (0.0, t.y.atan2(t.x))
        } else {
            (0.0, t.y.atan2(-t.x))
        };
        (
            alpha.rem_euclid(2.0 * PI) / (2.0 * PI) * FRAME_ALPHA as f64,
            beta / PI * (FRAME_BETA - 1) as f64,
            gamma.rem_euclid(2.0 * PI) / (2.0 * PI) * FRAME_GAMMA as f64,
        )
    }

    /// Trilinearly interpolated cell integrals for a frame.
    pub fn lighting(&self, frame: DMat3) -> Vec<DVec3> {
        let corners = self.corners(frame);
        (0..self.cells).map(|c| self.cell(&corners, c)).collect()
    }

    /// The table rows around a frame (first cell's index) and their trilinear weights.
    fn corners(&self, frame: DMat3) -> [(usize, f64); 8] {
        let (a, b, g) = Self::grid_coordinates(frame);
        let (a0, b0, g0) = (a.floor(), b.floor().min((FRAME_BETA - 2) as f64), g.floor());
        let (fa, fb, fg) = (a - a0, b - b0, g - g0);
        std::array::from_fn(|k| {
            let (da, db, dg) = (k >> 2, (k >> 1) & 1, k & 1);
            let w = [1.0 - fa, fa][da] * [1.0 - fb, fb][db] * [1.0 - fg, fg][dg];
            let ia = (a0 as usize + da) % FRAME_ALPHA;
            let ib = b0 as usize + db;
            let ig = (g0 as usize + dg) % FRAME_GAMMA;
            (((ia * FRAME_BETA + ib) * FRAME_GAMMA + ig) * self.cells * 3, w)
        })
    }

    /// Every cell's integral interpolated between `corners`, into `out` (RGB interleaved).
    fn lighting_into(&self, corners: &[(usize, f64); 8], out: &mut [f32]) {
        out.fill(0.0);
        let stride = out.len();
        for &(start, w) in corners.iter().filter(|(_, w)| *w != 0.0) {
            let w = w as f32;
            for (out, value) in out.iter_mut().zip(&self.values[start..start + stride]) {
                *out += w * value;
            }
        }
    }

    /// Blends the lighting of `frame` (seen through `inverse_rotation`) into `light`, unless the
    /// frame blended there last (`last`) was the same: runs of receivers sharing a frame (a
    /// floor's texels) blend once.
    fn blend_into(&self, frame: DMat3, inverse_rotation: DMat3, light: &mut [f32], last: &mut Option<[u64; 9]>) {
        let bits = frame.to_cols_array().map(f64::to_bits);
        if *last != Some(bits) {
            self.lighting_into(&self.corners(inverse_rotation * frame), light);
            *last = Some(bits);
        }
    }

    /// Cell `c`'s integral interpolated between `corners`.
    fn cell(&self, corners: &[(usize, f64); 8], c: usize) -> DVec3 {
        corners
            .iter()
            .filter(|(_, w)| *w != 0.0)
            .map(|(row, w)| {
                let rgb = &self.values[row + 3 * c..row + 3 * c + 3];
                DVec3::new(rgb[0].into(), rgb[1].into(), rgb[2].into()) * *w
            })
            .sum()
    }
}

/// [`super::local_products`] from a [`FrameTable`]: each receiver's lighting is the table's rows
/// around its frame, blended over every cell at once (f32, in SIMD lanes), then times its
/// visibility. Receivers in a row with the same frame (a floor's texels) blend once.
pub(super) fn table_products(
    table: &FrameTable,
    inverse_rotation: DMat3,
    receivers: &Receivers,
    visibility: &LocalVisibility,
    cancel: &CancelToken,
) -> Result<LocalProducts, StageError> {
    const CHUNK: usize = 256;
    let stride = table.cells * 3;
    let mut values = vec![0.0f32; receivers.len() * stride];
    values.par_chunks_mut(CHUNK * stride).enumerate().try_for_each_init(
        || (vec![0.0f32; stride], None),
        |(light, last), (chunk, out)| {
            cancel.check()?;
            for (k, out) in out.chunks_exact_mut(stride).enumerate() {
                let i = chunk * CHUNK + k;
                table.blend_into(receivers.frame(i), inverse_rotation, light, last);
                for ((out, light), v) in out.chunks_exact_mut(3).zip(light.chunks_exact(3)).zip(visibility.of(i)) {
                    // Closed (or not a number) is unlit.
                    let v = v.max(0.0);
                    out.copy_from_slice(&[light[0] * v, light[1] * v, light[2] * v]);
                }
            }
            Ok::<_, StageError>(())
        },
    )?;
    Ok(LocalProducts { cells: table.cells, values })
}

/// The renderer's CPU relight from a [`FrameTable`] in one pass: per receiver its products
/// packed by `pack` (`cells` words) and its diffuse transfer `E = Σ_c P_c D_c` (RGB, then 0),
/// without the f32 products in between. The products are [`super::local_products`]' (as
/// [`table_products`] computes them), `E` is [`super::diffuse_transfer`]'s summed in f32.
#[allow(clippy::too_many_arguments)]
pub fn table_products_packed(
    table: &FrameTable,
    rotation: DMat3,
    receivers: &Receivers,
    visibility: &LocalVisibility,
    diffuse: &[f32],
    pack: impl Fn([f32; 3]) -> u32 + Sync,
    cancel: &CancelToken,
) -> Result<(Vec<u32>, Vec<[f32; 4]>), StageError> {
    const CHUNK: usize = 256;
    let (cells, inverse_rotation) = (table.cells, rotation.transpose());
    if visibility.cells != cells || visibility.receivers() != receivers.len() || diffuse.len() != cells {
        return Err(StageError::Failed(format!(
            "a lighting table of {cells} cells for visibility of {} cells and {} receivers ({} diffuse cells)",
            visibility.cells,
            visibility.receivers(),
            diffuse.len()
        )));
    }
    let mut packed = vec![0u32; receivers.len() * cells];
    let mut irradiance = vec![[0.0f32; 4]; receivers.len()];
    packed.par_chunks_mut(CHUNK * cells).zip(irradiance.par_chunks_mut(CHUNK)).enumerate().try_for_each_init(
        || (vec![0.0f32; cells * 3], None),
        |(light, last), (chunk, (packed, irradiance))| {
            cancel.check()?;
            for (k, (packed, e)) in packed.chunks_exact_mut(cells).zip(irradiance).enumerate() {
                let i = chunk * CHUNK + k;
                table.blend_into(receivers.frame(i), inverse_rotation, light, last);
                let mut sum = [0.0f32; 3];
                for (((word, light), v), d) in
                    packed.iter_mut().zip(light.chunks_exact(3)).zip(visibility.of(i)).zip(diffuse)
                {
                    let v = v.max(0.0);
                    let p = [light[0] * v, light[1] * v, light[2] * v];
                    *word = pack(p);
                    for c in 0..3 {
                        sum[c] += p[c] * d;
                    }
                }
                *e = [sum[0], sum[1], sum[2], 0.0];
            }
            Ok::<_, StageError>(())
        },
    )?;
    Ok((packed, irradiance))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::triple_product::{Lighting, diffuse_transfer, local_products};
    use rand::Rng;
    use rand::rngs::SmallRng;

    /// A frame table at 80 cells of a lopsided environment, the receivers of a sphere and a
    /// floor (whose texels share frames), visibility 0 for 30% of cells and drawn by `open`
    /// for the rest, and a random rotation; and the generator, to draw more.
    struct Fixture {
        environment: CubeMap,
        grid: &'static CellGrid,
        table: FrameTable,
        receivers: Receivers,
        visibility: LocalVisibility,
        rotation: DMat3,
    }

    fn fixture(seed: u64, open: impl Fn(&mut SmallRng) -> f32) -> (Fixture, SmallRng) {
        let mut rng = crate::sampling::test_rng(seed);
        let environment = CubeMap::from_fn(32, 2, |d| [2.0 + d.x, 0.5 + d.y.max(0.0) * 40.0, 1.0 + d.z * d.z]);
        let grid = CellGrid::for_coefficients(80).unwrap();
        let table = FrameTable::build(grid, &environment);
        let meshes = crate::mesh::MeshSet { meshes: vec![crate::mesh::sphere(1.0, 10), crate::mesh::plane(2.0, 4)] };
        let receivers = Receivers::from_meshes(&meshes);
        let values: Vec<f32> = (0..receivers.len() * grid.len())
            .map(|_| if rng.random_bool(0.3) { 0.0 } else { open(&mut rng) })
            .collect();
        let visibility = LocalVisibility { cells: grid.len(), values };
        let rotation = crate::sampling::random_rotation(&mut rng);
        (Fixture { environment, grid, table, receivers, visibility, rotation }, rng)
    }

    #[test]
    fn frame_table_angles_round_trip_and_interpolate_towards_direct_averages() {
        let mut rng = crate::sampling::test_rng(9);
        for _ in 0..200 {
            let r = crate::sampling::random_rotation(&mut rng);
            let (a, b, g) = FrameTable::grid_coordinates(r);
            let back = FrameTable::frame(a, b, g);
            assert!((back - r).to_cols_array().iter().all(|d| d.abs() < 1e-9), "{r} vs {back}");
        }
        // A smooth environment: table lookups match direct cell integrals closely.
        let environment = CubeMap::from_fn(32, 2, |d| [1.0 + d.x + 0.5 * d.z * d.y, 0.5, 1.0]);
        let grid = CellGrid::for_coefficients(80).unwrap();
        let table = FrameTable::build(grid, &environment);
        for _ in 0..20 {
            let frame = crate::sampling::random_rotation(&mut rng);
            let looked_up = table.lighting(frame);
            for (c, samples) in grid.samples.iter().enumerate() {
                let direct: f64 = samples.iter().map(|(d, w)| environment.sample(frame * *d)[0] * w).sum();
                assert!((looked_up[c].x - direct).abs() < 0.02 * grid.solid_angles[c], "cell {c}");
            }
        }
    }

    /// The products from a frame table (every cell blended at once in f32) equal the table's
    /// per-cell interpolation (f64) times the visibility, for random visibility (some of it
    /// closed or negative) under a rotation, receivers sharing frames included.
    #[test]
    fn table_products_equal_the_tables_cells_times_visibility() {
        let (Fixture { environment, grid, table, receivers, visibility, rotation }, _) =
            fixture(10, |rng| rng.random_range(-0.2..1.0));
        let lighting = Lighting { environment: &environment, rotation, table: Some(&table) };
        let products = local_products(grid, &lighting, &receivers, &visibility, &CancelToken::default()).unwrap();
        let largest = products.values.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        assert!(largest > 0.0);
        for i in 0..receivers.len() {
            let cells = table.lighting(rotation.transpose() * receivers.frame(i));
            for (c, v) in visibility.of(i).iter().enumerate() {
                let expected = cells[c] * f64::from(v.max(0.0));
                let got = &products.values[(i * grid.len() + c) * 3..][..3];
                for k in 0..3 {
                    assert!(
                        (f64::from(got[k]) - expected[k]).abs() <= 1e-5 * f64::from(largest),
                        "receiver {i}, cell {c}"
                    );
                }
            }
        }
    }

    /// The one-pass packed relight equals packing the table's products and summing their
    /// diffuse transfer apart.
    #[test]
    fn packed_table_products_equal_the_products_packed() {
        let (Fixture { environment, grid, table, receivers, visibility, rotation }, mut rng) =
            fixture(11, |rng| rng.random());
        let diffuse: Vec<f32> = (0..grid.len()).map(|_| rng.random_range(0.0..0.05)).collect();
        // Any packing will do: the words are compared, not decoded.
        let pack = |p: [f32; 3]| (p[0] * 1000.0) as u32 ^ ((p[1] * 1000.0) as u32).rotate_left(11) ^ p[2].to_bits();
        let cancel = CancelToken::default();
        let (packed, irradiance) =
            table_products_packed(&table, rotation, &receivers, &visibility, &diffuse, pack, &cancel).unwrap();
        let lighting = Lighting { environment: &environment, rotation, table: Some(&table) };
        let products = local_products(grid, &lighting, &receivers, &visibility, &cancel).unwrap();
        let expected: Vec<u32> = products.values.chunks_exact(3).map(|p| pack([p[0], p[1], p[2]])).collect();
        assert_eq!(packed, expected);
        let transfer = diffuse_transfer(&products, &diffuse);
        let largest = transfer.iter().flatten().fold(0.0f32, |m, v| m.max(*v));
        assert!(largest > 0.0);
        for (a, b) in irradiance.iter().zip(&transfer) {
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() <= 1e-5 * largest, "{a:?} vs {b:?}");
            }
        }
        let wrong = LocalVisibility { cells: 320, values: Vec::new() };
        assert!(table_products_packed(&table, rotation, &receivers, &wrong, &diffuse, pack, &cancel).is_err());
    }
}
