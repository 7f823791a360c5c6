//! The wavelet modes' CPU relight (`triple_product::local_products`, what a CPU-only machine
//! runs after an environment rotation), on the synthetic 101k-vertex sphere of
//! `lightloom bench --only synthetic` with random visibility (70% of cells open): per cell
//! count, the rotation with and without the frame table, and the diffuse transfer.
//! Run with `cargo bench -p lightloom-nodes --bench relight`.

use glam::DMat3;
use lightloom_nodes::cubemap::CubeMap;
use lightloom_nodes::engine::CancelToken;
use lightloom_nodes::mesh::{self, MeshSet};
use lightloom_nodes::transport::{Receivers, SphericalTransport};
use lightloom_nodes::triple_product::{self, CellGrid, FrameTable, Lighting};
use lightloom_nodes::wavelet::SparseVector;
use lightloom_nodes::wavelet::spherical::SphericalHaar;
use rand::{Rng, SeedableRng};
use std::time::Instant;

/// Best of three runs, in ms.
fn best_ms<T>(mut f: impl FnMut() -> T) -> (T, f64) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..3 {
        let start = Instant::now();
        out = Some(f());
        best = best.min(start.elapsed().as_secs_f64() * 1e3);
    }
    (out.expect("ran"), best)
}

fn main() {
    let meshes = MeshSet { meshes: vec![mesh::sphere(1.0, 224)] };
    let receivers = Receivers::from_meshes(&meshes);
    let environment = CubeMap::from_fn(64, 1, |d| [1.0 + d.y, 0.8, 0.5 + d.x.abs()]);
    let cancel = CancelToken::default();
    let mut rng = rand::rngs::SmallRng::seed_from_u64(7);
    println!("CPU relight, {} receivers (a sphere), 70% of cells open:", receivers.len());
    for terms in [80usize, 320] {
        let depth = if terms == 80 { 2 } else { 3 };
        let cells = 20usize << (2 * depth);
        let basis = SphericalHaar::new(depth);
        let visibility = (0..receivers.len())
            .map(|_| {
                let dense: Vec<f64> = (0..cells).map(|_| if rng.random::<f64>() < 0.7 { 1.0 } else { 0.0 }).collect();
                SparseVector::largest(&basis.forward(&dense), terms, |_| 1.0)
            })
            .collect();
        let transport = SphericalTransport { depth, keep: terms, visibility };
        let grid = CellGrid::for_coefficients(terms).unwrap();
        let cell_visibility = triple_product::local_visibility(grid, &transport, &cancel).unwrap();
        let prefiltered = triple_product::prefiltered(&environment, grid);
        let (table, table_ms) = best_ms(|| FrameTable::build(grid, &prefiltered));
        let rotation = DMat3::from_rotation_y(0.7);
        let relight = |table: Option<&FrameTable>| {
            let lighting = Lighting { environment: &prefiltered, rotation, table };
            triple_product::local_products(grid, &lighting, &receivers, &cell_visibility, &cancel).unwrap()
        };
        let (products, table_rotation_ms) = best_ms(|| relight(Some(&table)));
        let (_, direct_rotation_ms) = best_ms(|| relight(None));
        let diffuse = vec![1.0 / grid.len() as f32; grid.len()];
        let (_, transfer_ms) = best_ms(|| triple_product::diffuse_transfer(&products, &diffuse));
        println!(
            "  {terms} cells: rotation {table_rotation_ms:.0} ms from the frame table (built in {table_ms:.0} ms), \
             {direct_rotation_ms:.0} ms sampled directly; diffuse transfer {transfer_ms:.0} ms"
        );
    }
}
