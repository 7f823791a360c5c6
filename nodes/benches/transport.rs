//! Visibility precompute figures: BVH build time, rays per second, total precompute time and
//! transport memory per receiver, for `2CylinderEngine.glb` (from the repository's
//! assets/) and a ~100k-triangle procedural mesh, at 256 and 1024 rays per receiver.
//! Run with `cargo bench -p lightloom-nodes --bench transport`. The rays alone, one at a time
//! and in bundles beside Embree: `lightloom bench --only rays`.

use glam::DVec3;
use lightloom_nodes::engine::CancelToken;
use lightloom_nodes::mesh::{self, MeshSet};
use lightloom_nodes::raycast::RayScene;
use lightloom_nodes::transport::{self, Receivers};
use std::path::Path;
use std::time::Instant;

fn run(name: &str, meshes: MeshSet) {
    let triangles = meshes.triangle_count();
    let t = Instant::now();
    let scene = RayScene::build(&meshes);
    let build_ms = t.elapsed().as_secs_f64() * 1e3;
    let receivers = Receivers::from_meshes(&meshes);
    println!("{name}: {triangles} triangles, {} receivers, BVH build {build_ms:.0} ms", receivers.len());
    let sample = receivers.every_nth(3000);
    for rays in [256usize, 1024] {
        let directions = transport::fibonacci_directions(rays);
        // Rays actually cast: directions above each receiver's tangent plane.
        let cast: usize = (0..sample.len())
            .map(|i| {
                let n = DVec3::from(sample.normals[i].map(f64::from));
                directions.iter().filter(|d| d.dot(n) > 0.0).count()
            })
            .sum();
        let t = Instant::now();
        let sh = transport::sh_transport(&scene, &sample, 6, rays, &CancelToken::default(), &|_| {}).unwrap();
        let secs = t.elapsed().as_secs_f64();
        let per_receiver = secs / sample.len() as f64;
        println!(
            "  {rays:>5} rays/receiver: {:.2} M rays/s ({} rays in {:.2} s over {} receivers); full precompute ≈ {:.1} s; SH transport {} B/receiver",
            cast as f64 / secs / 1e6,
            cast,
            secs,
            sample.len(),
            per_receiver * receivers.len() as f64,
            (sh.visibility.len() + sh.transfer.len()) * 4 / sample.len()
        );
    }
    let small = receivers.every_nth(300);
    let t = Instant::now();
    let haar = transport::haar_transport(&scene, &small, 16, 128, &CancelToken::default(), &|_| {}).unwrap();
    let haar_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let local = transport::spherical_transport(&scene, &small, 3, 320, &CancelToken::default(), &|_| {}).unwrap();
    let local_s = t.elapsed().as_secs_f64();
    let bytes =
        |v: &[lightloom_nodes::wavelet::SparseVector]| v.iter().map(|s| s.len() * 16).sum::<usize>() / v.len().max(1);
    println!(
        "  Haar 6x16x16, 128 terms: {:.2} ms/receiver, {} B/receiver (V and T); local frame depth 3, 320 terms: {:.2} ms/receiver, {} B/receiver",
        haar_s * 1e3 / small.len() as f64,
        bytes(&haar.visibility) + bytes(&haar.transfer),
        local_s * 1e3 / small.len() as f64,
        bytes(&local.visibility)
    );
}

fn main() {
    let engine = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../assets/gltf/assimp-glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb");
    let scene = lightloom_nodes::gltf_import::import(&engine).unwrap_or_else(|e| panic!("{e}"));
    run("2CylinderEngine.glb", MeshSet { meshes: scene.meshes });
    // ~100k triangles: a finely tessellated torus knot of shapes over a floor.
    let mut meshes = vec![mesh::plane(6.0, 40)];
    meshes.push(mesh::torus(1.2, 0.4, 110).transformed(glam::DMat4::from_translation(DVec3::new(0.0, 0.6, 0.0))));
    meshes.push(mesh::sphere(0.5, 110).transformed(glam::DMat4::from_translation(DVec3::new(0.0, 0.5, 0.0))));
    run("procedural torus + sphere + floor", MeshSet { meshes });
}
