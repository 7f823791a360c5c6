//! Visibility precompute figures: BVH build time, rays per second, total precompute time and
//! transport memory per receiver, for `2CylinderEngine.glb` (from ../shared/assets, when
//! present) and a ~100k-triangle procedural mesh, at 256 and 1024 rays per receiver.
//! Run with `cargo bench -p lightloom-nodes --bench transport`.

use glam::DVec3;
use lightloom_nodes::engine::CancelToken;
use lightloom_nodes::mesh::{self, MeshSet};
use lightloom_nodes::raycast::RayScene;
use lightloom_nodes::transport::{self, Receivers};
use std::path::Path;
use std::time::Instant;

fn subset(all: &Receivers, count: usize) -> Receivers {
    let step = (all.len() / count).max(1);
    let pick = |v: &Vec<[f32; 3]>| v.iter().step_by(step).copied().collect::<Vec<_>>();
    Receivers {
        positions: pick(&all.positions),
        normals: pick(&all.normals),
        tangents: pick(&all.tangents),
        mesh_offsets: vec![0],
    }
}

/// The rays alone (no projection), one at a time and as one bundle per receiver, over the
/// receivers' upper hemispheres of 1024 Fibonacci directions; both must agree.
fn rays_alone(scene: &RayScene, sample: &Receivers) {
    use glam::Vec3A;
    use rayon::prelude::*;
    let directions: Vec<Vec3A> = transport::fibonacci_directions(1024).iter().map(|d| d.as_vec3().into()).collect();
    let bundle = |i: usize| {
        let (p, n) = sample.point(i);
        let origin = scene.leave_surface(p, n);
        let rays: Vec<u32> = (0..1024).filter(|&k| directions[k as usize].dot(n.as_vec3().into()) > 0.0).collect();
        (origin, rays)
    };
    let t = Instant::now();
    let single: Vec<Vec<bool>> = (0..sample.len())
        .into_par_iter()
        .map(|i| {
            let (origin, rays) = bundle(i);
            rays.iter().map(|&k| scene.occluded(origin, directions[k as usize], f32::INFINITY)).collect()
        })
        .collect();
    let single_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let bundled: Vec<Vec<bool>> = (0..sample.len())
        .into_par_iter()
        .map(|i| {
            let (origin, rays) = bundle(i);
            let mut blocked = vec![false; directions.len()];
            scene.occlude_bundle(origin, &directions, &rays, f32::INFINITY, &mut blocked);
            rays.iter().map(|&k| blocked[k as usize]).collect()
        })
        .collect();
    let bundled_s = t.elapsed().as_secs_f64();
    let cast: usize = single.iter().map(Vec::len).sum();
    let differ: usize = single.iter().zip(&bundled).map(|(a, b)| a.iter().zip(b).filter(|(a, b)| a != b).count()).sum();
    let blocked: usize = bundled.iter().map(|b| b.iter().filter(|b| **b).count()).sum();
    println!(
        "  rays alone, {cast} rays ({:.0}% blocked): single rays {:.2} M rays/s, bundles {:.2} M rays/s ({:.1}×); {differ} differ ({:.4}%)",
        100.0 * blocked as f64 / cast as f64,
        cast as f64 / single_s / 1e6,
        cast as f64 / bundled_s / 1e6,
        single_s / bundled_s,
        100.0 * differ as f64 / cast as f64
    );
}

fn run(name: &str, meshes: MeshSet) {
    let triangles = meshes.triangle_count();
    let t = Instant::now();
    let scene = RayScene::build(&meshes);
    let build_ms = t.elapsed().as_secs_f64() * 1e3;
    let receivers = Receivers::from_meshes(&meshes);
    println!("{name}: {triangles} triangles, {} receivers, BVH build {build_ms:.0} ms", receivers.len());
    let sample = subset(&receivers, 3000);
    rays_alone(&scene, &sample);
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
    let small = subset(&receivers, 300);
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
        .join("../../shared/assets/gltf/assimp-glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb");
    match lightloom_nodes::gltf_import::import(&engine) {
        Ok(scene) => run("2CylinderEngine.glb", MeshSet { meshes: scene.meshes }),
        Err(e) => println!("2CylinderEngine.glb skipped: {e}"),
    }
    // ~100k triangles: a finely tessellated torus knot of shapes over a floor.
    let mut meshes = vec![mesh::plane(6.0, 40)];
    meshes.push(mesh::torus(1.2, 0.4, 110).transformed(glam::DMat4::from_translation(DVec3::new(0.0, 0.6, 0.0))));
    meshes.push(mesh::sphere(0.5, 110).transformed(glam::DMat4::from_translation(DVec3::new(0.0, 0.5, 0.0))));
    run("procedural torus + sphere + floor", MeshSet { meshes });
}
