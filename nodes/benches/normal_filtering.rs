//! Normal-map filtering: pyramid build time per megapixel of normal map, for the NDF's SH
//! (3 bands for diffuse, 8 for gloss) and for 6-lobe vMF mixtures fitted by EM.
//! Run with `cargo bench -p lightloom-nodes --bench normal_filtering`.

use glam::DVec3;
use lightloom_nodes::normal_filtering::{NdfPyramid, NormalMap, vmf_pyramid};
use std::time::Instant;

fn main() {
    let size = 512;
    // Bumps four texels across: every level's texels hold spread normals.
    let normals = (0..size * size)
        .map(|i| {
            let (x, y) = ((i % size) as f64, (i / size) as f64);
            let k = std::f64::consts::PI / 2.0;
            DVec3::new(-0.9 * (k * x).cos() * (0.5 * k * y).sin(), -0.7 * (k * y).cos(), 1.0).normalize()
        })
        .collect();
    let map = NormalMap { width: size, height: size, normals };
    let megapixels = (size * size) as f64 / 1e6;
    println!("normal-map filtering, a {size}×{size} map:");
    for bands in [3, 8] {
        let start = Instant::now();
        let pyramid = NdfPyramid::build(&map, bands);
        let ms = start.elapsed().as_secs_f64() * 1e3;
        println!("  NDF SH, {bands} bands: {:.0} ms per megapixel ({} levels)", ms / megapixels, pyramid.levels.len());
    }
    let start = Instant::now();
    let mixtures = vmf_pyramid(&map, 6, 20, 256);
    let ms = start.elapsed().as_secs_f64() * 1e3;
    println!(
        "  vMF mixtures, 6 lobes, 20 EM rounds, at most 256 normals a texel: {:.0} ms per megapixel ({} levels)",
        ms / megapixels,
        mixtures.len()
    );
}
