//! Normal-map filtering: pyramid build time per megapixel of normal map, for the NDF's SH
//! (3 bands for diffuse, 8 for gloss), for 6-lobe vMF mixtures fitted by EM, and for what the
//! BRDF editor's stages build for the viewport: the moment pyramid (`ndf_moments`) and the
//! packed vMF pyramid (`vmf_lobes`, 30 EM rounds over at most 1024 normals of the map's
//! bilinear field a texel).
//! Run with `cargo bench -p lightloom-nodes --bench normal_filtering`.

use glam::DVec3;
use lightloom_nodes::normal_filtering::{MomentPyramid, NdfPyramid, NormalMap, VmfPyramid, vmf_pyramid};
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
    let moments = MomentPyramid::build(&map);
    let ms = start.elapsed().as_secs_f64() * 1e3;
    println!(
        "  ndf_moments (the viewport's moment pyramid): {:.0} ms per megapixel ({} levels)",
        ms / megapixels,
        moments.levels.len()
    );
    let start = Instant::now();
    let packed = VmfPyramid::build(&map, &Default::default()).expect("within the size limit");
    let ms = start.elapsed().as_secs_f64() * 1e3;
    println!(
        "  vmf_lobes (the viewport's vMF pyramid): {:.0} ms per megapixel ({} levels)",
        ms / megapixels,
        packed.levels.len()
    );
    let start = Instant::now();
    let mixtures = vmf_pyramid(&map, 6, 20, 256);
    let ms = start.elapsed().as_secs_f64() * 1e3;
    println!(
        "  vMF mixtures, 6 lobes, 20 EM rounds, at most 256 normals a texel: {:.0} ms per megapixel ({} levels)",
        ms / megapixels,
        mixtures.len()
    );
}
